"""Cost of one co-simulation step of the three driftfmu FMUs against three pass-through FMUs.

Both sets run through the same master loop (simulations.cosim.cosimulate: 3 doSteps, 2 values
copied along connections, 8 outputs recorded per step), alternately, several times; the best
time of each is kept.  The baseline FMUs are built with stock pythonfmu in this run.

    python benchmarks/bench_step.py [--steps 5000] [--repeats 5]
"""
import argparse
import platform
import tempfile
import time
from pathlib import Path

from pythonfmu import FmuBuilder

from simulations.cosim import cosimulate
from simulations.gaussian import CONNECTIONS, fmu_paths

from machine import cpu

HERE = Path(__file__).parent
RECORD = {"Excitation": ["x"], "Accelerometer": ["z"],
          "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}


def build_baseline(dest):
    names = {"Excitation": "PassSource", "Accelerometer": "PassOne", "DriftEstimator": "PassSix"}
    return {role: Path(FmuBuilder.build_FMU(HERE / "passthrough" / ("%s.py" % n), dest=dest))
            for role, n in names.items()}


def per_step(fmus, steps, Ts=1e-3):
    rename = {"Excitation": "Excitation", "Accelerometer": "Accelerometer",
              "DriftEstimator": "DriftEstimator"}
    t0 = time.perf_counter()
    cosimulate({rename[k]: v for k, v in fmus.items()}, CONNECTIONS, steps, Ts, record=RECORD)
    return (time.perf_counter() - t0) / steps


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fmu-dir", default="build/fmus")
    args = ap.parse_args(argv)
    ours = fmu_paths(args.fmu_dir)
    with tempfile.TemporaryDirectory() as tmp:
        base = build_baseline(tmp)
        t_ours, t_base = [], []
        for _ in range(args.repeats):
            t_base.append(per_step(base, args.steps))
            t_ours.append(per_step(ours, args.steps))
    b, o = min(t_base), min(t_ours)
    print("machine: %s, %s, Python %s" % (platform.machine(), cpu(), platform.python_version()))
    print("pass-through pythonfmu FMUs: %8.1f us per co-simulation step" % (b * 1e6))
    print("driftfmu FMUs:               %8.1f us per co-simulation step" % (o * 1e6))
    print("ratio driftfmu / pass-through: %.2f (goal <= 1.5)" % (o / b))


if __name__ == "__main__":
    main()
