"""Random call sequences against the Python slaves, valid and invalid, with a replay oracle.

Each sequence mixes good and bad calls (unknown and 2^31+ value references, non-finite and
overflowing values, outputs and fixed parameters set, steps of every size and kind, foreign and
crafted FMU states, calls after terminate).  After every call:

* no exception leaves the slave (pythonfmu would turn it into fmi2Fatal or a crash);
* a call that logged an error changed nothing: the FMU state and every variable are as before;
* a call that logged nothing left every Real output finite.

At the end a fresh instance replays only the calls that were accepted and must reach the same
state and outputs bit for bit: the rejected calls had no hidden effect either.
(The C-host fuzz harness of the loader shim is harden-c's; this one covers the Python side.)

CI runs 10 seeds per slave; a longer run: ``DRIFTFMU_PYFUZZ_SEEDS=500 python -m pytest
tests/test_callfuzz.py``.
"""
import json
import math
import os
import random

import pytest

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation

SLAVES = (Excitation, Accelerometer, DriftEstimator)
TS = 1e-3
REALS = [0.0, 0.5, -1.3, 2.0, 1e-3, 1e200, -1e200, 1e308, math.nan, math.inf, -math.inf, 5e-324]
STEPS = [TS, TS, TS, 2 * TS, 2.5 * TS, 0.3 * TS, 0.25 * TS, 1e-12, 0.0, -TS, math.nan,
         math.inf, 1e300, 2000 * TS]


def observe(s):
    values = []
    for spec in s.VARIABLES:
        values.append(getattr(s, spec["name"]))
    return json.dumps(s._get_fmu_state(), sort_keys=True), values


def random_call(rng, s, others, saved):
    """One random FMI call on slave ``s``: (name, args) with args ready to apply."""
    specs = s.VARIABLES
    n = len(specs)
    pick = rng.random()
    if pick < 0.30:
        vrs = [rng.randrange(n) for _ in range(rng.choice((1, 1, 2, 3)))]
        if rng.random() < 0.15:
            vrs[rng.randrange(len(vrs))] = rng.choice((999, -1, -2 ** 31, n))
        values = [rng.choice(REALS) if rng.random() < 0.4 else rng.uniform(-2, 2) for _ in vrs]
        return "set_real", (vrs, values)
    if pick < 0.40:
        vrs = [rng.randrange(n) for _ in range(rng.choice((1, 2)))]
        return "set_integer", (vrs, [rng.choice((0, 1, 2, 3, 7, -5, 2 ** 31 - 1)) for _ in vrs])
    if pick < 0.50:
        return "get_real", ([rng.randrange(n + 2) for _ in range(rng.choice((1, 3)))],)
    if pick < 0.75:
        return "do_step", (0.0, rng.choice(STEPS))
    if pick < 0.80:
        return "get_state", ()
    if pick < 0.88:
        choice = rng.random()
        if saved and choice < 0.5:
            return "set_state", (json.loads(json.dumps(rng.choice(saved))),)
        if choice < 0.7:
            return "set_state", (rng.choice(others)._get_fmu_state(),)
        if saved and choice < 0.9:
            bad = json.loads(json.dumps(rng.choice(saved)))
            key = rng.choice(sorted(bad))
            bad[key] = rng.choice((None, "x", -1, [1], {"a": 1}, 1e309, True))
            return "set_state", (bad,)
        return "set_state", ({"k": 1, rng.choice(("_call", "get_real", "do_step")): 0},)
    if pick < 0.883 and len(saved) > 20:  # late: a terminated instance refuses most calls
        return "terminate", ()
    if pick < 0.89:
        return "enter_initialization_mode", ()
    if pick < 0.90:
        return "exit_initialization_mode", ()
    return "do_step", (0.0, rng.choice(STEPS[:7]))


def apply(s, name, args, saved):
    if name == "get_state":
        saved.append(s._get_fmu_state())
        return None
    if name == "set_state":
        return s._set_fmu_state(args[0])
    return getattr(s, name)(*args)


def fresh(cls):
    s = cls(instance_name="fuzz")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    return s


@pytest.mark.parametrize("cls", SLAVES, ids=lambda c: c.__name__)
@pytest.mark.parametrize("seed", range(int(os.environ.get("DRIFTFMU_PYFUZZ_SEEDS", "10"))))
def test_random_call_sequences_against_a_replay_oracle(cls, seed):
    rng = random.Random(1000 * seed + len(cls.__name__))
    s = fresh(cls)
    others = [other(instance_name="o") for other in SLAVES if other is not cls]
    saved, accepted = [], []
    for i in range(400):
        name, args = random_call(rng, s, others, saved)
        before = observe(s)
        s.log_queue.clear()
        result = apply(s, name, args, saved)      # an exception fails the test right here
        errors = [m.msg for m in s.log_queue]
        s.log_queue.clear()
        context = (i, name, args, errors)
        if errors:
            if name == "get_real":  # a refused refresh: nothing may have moved
                assert observe(s) == before, context
            elif name != "get_state":
                assert observe(s) == before, context
            assert result in (None, False, True) or isinstance(result, list), context
            if name == "do_step":
                assert result is False, context
        else:
            if name == "do_step":
                assert result is True, context
            outs = [spec["name"] for spec in s.VARIABLES if spec["causality"] == "output"]
            assert all(math.isfinite(getattr(s, o)) for o in outs), context
            if name not in ("get_real", "get_state"):
                accepted.append((name, args))
            elif name == "get_real":
                accepted.append((name, args))
    # the oracle: the accepted calls alone give the same instance
    replay, replay_saved = fresh(cls), []
    for name, args in accepted:
        apply(replay, name, args, replay_saved)
        assert not replay.log_queue, (name, args, [m.msg for m in replay.log_queue])
    assert observe(replay) == observe(s)
    steps = sum(1 for name, _ in accepted if name == "do_step")
    assert steps > 10 and len(accepted) > 40, (steps, len(accepted))  # it did run the model
