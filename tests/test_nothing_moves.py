"""Nothing else moves: with every parameter of the sensor's drift taxonomy (issue 42) at its
default, every number the project computed before is the same, bit for bit.

tests/data/baseline_outputs.json holds SHA-256 digests of the outputs of every slave (the FMUs'
Python classes over parameter sets, inputs, communication steps and a state restore of their
own), of models/' chains, of the batch engine (NumPy and the compiled kernel) and of the public
montecarlo and sweep, computed from main's code before the change (tests/baseline_outputs.py
says how).  The native twins equal the slaves bit for bit (tests/test_native_models.py).
"""
import json
from pathlib import Path

import baseline_outputs

RECORDED = json.loads((Path(__file__).parent / "data" / "baseline_outputs.json").read_text())


def test_the_recorded_digests_cover_every_slave_chain_engine_and_function():
    names = " ".join(RECORDED)
    for part in ("slave Excitation", "slave Accelerometer", "slave DriftEstimator",
                 "slave DualDriftEstimator", "chain", "adxl203", "batch", "montecarlo",
                 "sweep"):
        assert part in names, part


def test_every_output_has_the_bits_recorded_before_the_drift_taxonomy():
    now = baseline_outputs.digests()
    moved = sorted(name for name in RECORDED if now.get(name) != RECORDED[name])
    assert not moved, "these outputs changed bits: %s" % ", ".join(moved)
    assert sorted(now) == sorted(RECORDED)
