"""The Accelerometer FMU's slow errors (issue 42), on the slave class (no FMU built): its output
is models/' (so tests/test_errors.py's evidence is the FMU's), sample by sample and through any
communication step and FMU state restore; the error state is in the FMU state and a state whose
error part cannot be this sensor's is refused; bad parameters and inputs get one line each and
change nothing."""
import copy
import json
import math
import random

import numpy as np
import pytest

from driftfmu.fmu_src.Accelerometer import ERROR_SWITCHES, Accelerometer
from driftfmu.models import adxl203, chain, errors, excitation

ALL_ON = dict(bias_on=0.05, random_walk=0.02, bias_gm=0.03, tau_gm=0.02, flicker=0.01,
              tau_min=0.003, tau_max=3.0, d_inf=0.04, E_tau=0.5, T0=290.0, kT_bias=0.002,
              kT_scale=-0.003, range=1.8)


def vr(slave, name):
    return next(i for i, s in enumerate(slave.VARIABLES) if s["name"] == name)


def put(slave, name, value):
    spec = slave.VARIABLES[vr(slave, name)]
    call = slave.set_real if spec["type"] == "Real" else slave.set_integer
    return call([vr(slave, name)], [value])


def get(slave, name):
    return slave.get_real([vr(slave, name)])[0]


def messages(slave):
    out = [m.msg for m in slave.log_queue]
    slave.log_queue.clear()
    return out


def slave(**values):
    s = Accelerometer(instance_name="a")
    for name, value in values.items():
        setattr(s, name, value)
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    return s


def initialised(**values):
    s = slave(**values)
    assert s._initialised, messages(s)
    return s


def snapshot(s):
    values = [s.get_real([i])[0] if spec["type"] == "Real" else s.get_integer([i])[0]
              for i, spec in enumerate(s.VARIABLES)]
    return json.dumps(s._get_fmu_state(), sort_keys=True), values


# -- the FMU's output is models/' ------------------------------------------------------------------

def test_every_sample_equals_models_with_every_term_on_and_the_inputs_moving():
    """The slave stepped sample by sample with x, theta and T changing: z equals
    adxl203.measure_errors with errors.draws, bit for bit (the ADC over the range too)."""
    values = dict(ALL_ON, a0=0.4, a1=1.2, a2=0.03, a3=0.01, R=1e-5, seed=77, Ts=1e-3, bits=14)
    s = initialised(**values)
    cfg = adxl203.config(**values)
    ecfg = errors.config(**values)
    state = errors.initial_state(77, ecfg)
    rng = random.Random(5)
    lp = None
    for k in range(1, 3001):
        x, theta, T = rng.uniform(-2, 2), rng.uniform(-1, 1), rng.uniform(250, 330)
        for name, v in (("x", x), ("theta", theta), ("T", T)):
            put(s, name, v)
        lp, state, z = adxl203.measure_errors(lp, state, x, 0.0, adxl203.noise(77, k), errors.draws(
            77, k, ecfg), theta, T, cfg, ecfg)
        assert get(s, "z") == z, k
        assert s.do_step((k - 1) * 1e-3, 1e-3) is not False
    assert s._committed["_err"] == state


@pytest.mark.parametrize("values", [dict(random_walk=0.02), dict(bias_gm=0.1, tau_gm=1.0),
                                    dict(flicker=0.01, tau_min=0.1, tau_max=100.0),
                                    dict(bias_on=0.3), dict(d_inf=0.2)])
def test_the_fmu_output_is_the_series_of_the_statistical_evidence(values):
    """x = 0, no measurement noise, a0 = a2 = 0, a1 = 1: the slave's z is
    chain.SensorErrors' (what tests/test_errors.py measures the Allan deviation of) for the
    same seed, bit for bit."""
    Ts = 0.01
    s = initialised(a0=0.0, a1=1.0, a2=0.0, noise=0, seed=3, Ts=Ts, **values)
    se = chain.SensorErrors(3, 0.0, 1.0, 0.0, 1e-4, 0.0, 0.0, Ts, values)
    for k in range(1, 2001):
        put(s, "x", 0.25 if k % 7 else -0.5)
        assert get(s, "z") == se.measure(0.25 if k % 7 else -0.5, 0.0, k), k
        s.do_step((k - 1) * Ts, Ts)


def test_any_communication_step_and_a_restored_state_give_the_same_bits():
    """Whole, multiple and fractional steps (the hold between communication points advances
    every process by the samples it spans, with the inputs held) and an FMU state restored and
    stepped again: every sample a master sees equals the sample-by-sample run's."""
    values = dict(ALL_ON, seed=9, Ts=1e-3, fc=200.0)
    inputs = dict(x=0.6, theta=0.2, T=310.0)
    ref = initialised(**values)
    zs = {}
    for k in range(1, 601):
        for name, v in inputs.items():
            put(ref, name, v)
        zs[k] = get(ref, "z")
        ref.do_step((k - 1) * 1e-3, 1e-3)
    rng = random.Random(2)
    s = initialised(**values)
    for name, v in inputs.items():
        put(s, name, v)
    t, seen, saved = 0.0, 0, None
    while s.k < 560:
        if s._at_sample:
            assert get(s, "z") == zs[s.k], s.k
            seen += 1
        if saved is None and s.k > 200 and s._at_sample:
            saved = (copy.deepcopy(s._get_fmu_state()), s.k)
        h = 1e-3 * rng.choice((1, 1, 2, 5, 0.5, 0.25, 1.5))
        assert s.do_step(t, h) is not False
        t += h
    assert seen > 100
    state, k = saved
    s._set_fmu_state(state)
    assert not messages(s) and s.k == k
    assert get(s, "z") == zs[k]
    s.do_step(0.0, 7e-3)
    assert get(s, "z") == zs[k + 7]


HELD_ALONE = [dict(bias_on=0.05), dict(random_walk=0.02), dict(bias_gm=0.03, tau_gm=0.02),
              dict(flicker=0.01, tau_min=0.003, tau_max=3.0), dict(d_inf=0.04, E_tau=0.05),
              dict(kT_bias=0.002, T0=290.0)]


@pytest.mark.parametrize("alone", HELD_ALONE + [dict(kv for d in HELD_ALONE for kv in d.items())],
                         ids=lambda d: "+".join(k for k in d if k in ERROR_SWITCHES))
def test_steps_of_several_samples_advance_each_process_alone_by_the_samples_they_span(alone):
    """Each slow error alone, and all of them, in steps of 1 to 9 samples (and across a block's
    end of draws): the z a master sees after each step is adxl203.measure_errors' of that
    sample, the held samples between advanced by the ones they span (errors.hold_run over the
    blocks' runs, or errors.advance_state), bit for bit."""
    values = dict(alone, seed=17, Ts=1e-3, R=1e-6, a2=0.05)
    x = 0.8
    want = _reference(values, lambda k: (x, 0.0, 300.0), 4200)
    s = initialised(**values)
    put(s, "x", x)
    put(s, "T", 300.0)
    rng, t, k = random.Random(5), 0.0, 1
    sizes = [rng.randint(1, 9) for _ in range(300)]
    sizes += [4100 - 1 - sum(sizes), 7, 1]  # (one long step to past the first block's end)
    for m in sizes:
        assert get(s, "z") == want[k], (k, m)
        assert s.do_step(t, m * 1e-3) is not False
        t, k = t + m * 1e-3, k + m
    assert get(s, "z") == want[k] and k > 4096


def test_held_inputs_over_a_long_step_equal_single_samples():
    """One step of 50 samples equals 50 steps of one with the inputs held (errors.hold's
    loop, with the filter on and off)."""
    for fc in (0.0, 100.0):
        values = dict(ALL_ON, seed=4, Ts=1e-3, fc=fc)
        a, b = initialised(**values), initialised(**values)
        for s in (a, b):
            put(s, "x", 0.7)
            put(s, "T", 301.0)
        a.do_step(0.0, 0.05)
        for k in range(50):
            b.do_step(k * 1e-3, 1e-3)
        assert get(a, "z") == get(b, "z") and a._committed["_err"] == b._committed["_err"]


@pytest.mark.parametrize("case", [
    dict(theta=-0.3), dict(theta=1.0), dict(axes=2, noise=1), dict(axes=2, noise=0),
    dict(axes=2, noise=1, kT_scale=-0.003, T0=290.0, range=1.2, theta=-0.2)],
    ids=lambda d: ",".join("%s=%s" % kv for kv in d.items()))
def test_a_step_of_several_samples_with_the_filter_equals_single_samples(case):
    """With the output filter on, one step of 23 samples equals 23 steps of one (which run
    Accelerometer.sample, not the hold), z and z_y and the filters' states bit for bit: the
    tilt alone (negative, and exactly 1.0 rad), the second axis with and without the
    measurement noise, and the second axis with the slow errors' class 2 and range."""
    values = dict(seed=6, Ts=1e-3, fc=150.0, R=1e-4, a2=0.05,
                  **{k: v for k, v in case.items() if k != "theta"})
    a, b = initialised(**values), initialised(**values)
    for s in (a, b):
        put(s, "x", 0.7)
        put(s, "y", -0.4) if "axes" in case else None
        put(s, "theta", case.get("theta", 0.0))
        put(s, "T", 301.0)
    assert a.do_step(0.0, 0.023) is not False, messages(a)
    for k in range(23):
        assert b.do_step(k * 1e-3, 1e-3) is not False, messages(b)
    names = ["z", "z_y"] if "axes" in case else ["z"]
    assert [get(a, n) for n in names] == [get(b, n) for n in names]
    assert (a._committed["_lp"], a._committed["_lpy"]) == \
        (b._committed["_lp"], b._committed["_lpy"])
    assert a._committed["_lp"] is not None
    if "axes" in case:
        assert a._committed["_lpy"] is not None


def test_with_every_term_off_the_state_has_no_error_part_and_the_tilt_still_acts():
    s = initialised()
    assert s._committed["_err"] is None and s._get_fmu_state()["_err"] is None
    put(s, "x", 0.5)
    plain = get(s, "z")
    put(s, "theta", math.pi / 6)  # sin = 1/2: the sensor senses 1 g
    assert get(s, "z") == pytest.approx(adxl203.sensor.h(1.0, 0.0, 1.0, 0.01) +
                                        (plain - adxl203.sensor.h(0.5, 0.0, 1.0, 0.01)),
                                        abs=1e-15)
    s.do_step(0.0, 1e-3)
    assert s._committed["_err"] is None
    # dual = 1 ignores the tilt and the temperature (documented: inputs of the first axis)
    d = initialised(dual=1)
    put(d, "x", 0.5)
    z = get(d, "z")
    put(d, "theta", 1.0)
    put(d, "T", 400.0)
    assert get(d, "z") == z


# -- the runs of the input-independent processes (Accelerometer._row, errors.run) -----------------

def _reference(values, inputs, n):
    """z of samples 1 .. n of adxl203.measure_errors with errors.draws, ``inputs(k)`` the
    sample's (x, theta, T)."""
    cfg, ecfg = adxl203.config(**values), errors.config(**values)
    seed = values["seed"]
    lp, state, out = None, errors.initial_state(seed, ecfg), {}
    for k in range(1, n + 1):
        x, theta, T = inputs(k)
        lp, state, out[k] = adxl203.measure_errors(lp, state, x, 0.0, adxl203.noise(seed, k),
                                                   errors.draws(seed, k, ecfg), theta, T, cfg,
                                                   ecfg)
    return out


def _inputs(k):
    return (math.sin(0.01 * k) * 1.5, 0.1 if k % 50 else -0.2, 290.0 + (k % 17))


def _put_inputs(s, k):
    for name, v in zip(("x", "theta", "T"), _inputs(k)):
        put(s, name, v)


def _checked_step(s, want, k):
    """Sample k with the inputs of _inputs(k): z is ``want[k]``; then the step to sample k + 1."""
    _put_inputs(s, k)
    assert get(s, "z") == want[k], k
    assert s.do_step((k - 1) * 1e-3, 1e-3) is not False


RUN_VALUES = dict(ALL_ON, a0=0.2, a1=1.1, a2=0.02, R=1e-5, seed=31, Ts=1e-3, bits=14)


def test_a_long_run_takes_runs_of_doubling_size_with_the_bits_of_measure_errors():
    """Sample by sample for 9000 samples: z equals adxl203.measure_errors' bit for bit, the
    slave computes the walk, the Gauss-Markov and flicker biases in runs (errors.run) after
    RUN_AFTER samples, and each run it starts at the end of the last is twice as long, up to
    Blocks.SIZE."""
    from driftfmu.fmu_src import Accelerometer as module
    want = _reference(RUN_VALUES, _inputs, 9000)
    s = initialised(**RUN_VALUES)
    sizes, starts = [], []
    for k in range(1, 9001):
        _checked_step(s, want, k)
        if s._run and s._run_k0 not in starts:
            starts.append(s._run_k0)
            sizes.append(s._run_size)
    assert starts[0] == module.RUN_AFTER + 1
    expected = [min(module.RUN_FIRST * 2 ** i, module.Blocks.SIZE) for i in range(len(sizes))]
    assert sizes == expected and sizes[-1] == module.Blocks.SIZE


@pytest.mark.parametrize("values", [dict(random_walk=0.02), dict(bias_gm=0.03, tau_gm=0.02),
                                    dict(flicker=0.01, tau_min=0.01, tau_max=1.0),
                                    dict(d_inf=0.04, E_tau=0.5, kT_bias=0.002)])
def test_each_process_alone_takes_runs_and_the_others_do_not_need_them(values):
    """The walk, the Gauss-Markov bias or the flicker bias alone: the slave takes runs of it
    (errors.run); without any of them (the exposure drift and the temperature only) there is
    nothing to run; z equals the reference throughout."""
    values = dict(values, a0=0.2, a1=1.1, a2=0.02, R=1e-5, seed=8, Ts=1e-3)
    want = _reference(values, _inputs, 300)
    s = initialised(**values)
    for k in range(1, 301):
        _checked_step(s, want, k)
    assert bool(s._run) == ("d_inf" not in values)


def test_a_restore_at_every_step_starts_no_run_and_gives_the_same_bits():
    """A master that restores a serialised state before every step (a rollback master): every
    z equals the reference, and no run is ever started (each would be thrown away)."""
    want = _reference(RUN_VALUES, _inputs, 400)
    s = initialised(**RUN_VALUES)
    for k in range(1, 401):
        _checked_step(s, want, k)
        state = Accelerometer._fmu_state_to_bytes(s._get_fmu_state())
        s._set_fmu_state(Accelerometer._fmu_state_from_bytes(state))
        assert not messages(s)
    assert s._run == ()


@pytest.mark.parametrize("after", [0, 1, 2])
def test_a_run_starts_after_RUN_AFTER_samples_that_follow_one_another_and_not_before(after):
    """A restored state drops the run in store (prepare); then the samples that each start from
    the state the one before made are counted: with RUN_AFTER of them after the first the next
    sample starts a run, with one fewer it does not, and every z equals the reference."""
    from driftfmu.fmu_src import Accelerometer as module
    n0 = 3 * module.RUN_AFTER
    want = _reference(RUN_VALUES, _inputs, n0 + module.RUN_AFTER + 10)
    s = initialised(**RUN_VALUES)
    for k in range(1, n0 + 1):
        _put_inputs(s, k)
        s.do_step((k - 1) * 1e-3, 1e-3)
    assert s._run
    s._set_fmu_state(Accelerometer._fmu_state_from_bytes(
        Accelerometer._fmu_state_to_bytes(s._get_fmu_state())))
    assert s._run == ()
    k = n0 + 1
    for _ in range(module.RUN_AFTER + after):
        _checked_step(s, want, k)
        k += 1
    assert bool(s._run) == (after >= 1), after
    if after:
        assert s._run_k0 == n0 + module.RUN_AFTER + 1
    _put_inputs(s, k)
    assert get(s, "z") == want[k]


@pytest.mark.parametrize("m, runs", [(2, True), (5, False)])
def test_steps_of_several_samples_give_the_same_bits_and_start_runs_only_where_used(m, runs):
    """Steps of m samples: with m = 2 each sample is computed on its own from the one before
    (runs start and are used); with m = 5 the samples before the last are held
    (Accelerometer.hold: errors.advance), so no sample starts from the state the one before made
    and no run is started (it would not be used).  z at every step equals the reference."""
    n = 200 * m + 1
    want = _reference(RUN_VALUES, lambda k: (0.4, 0.1, 300.0), n)
    s = initialised(**RUN_VALUES)
    for name, v in zip(("x", "theta", "T"), (0.4, 0.1, 300.0)):
        put(s, name, v)
    for j in range(200):
        assert s.do_step(m * 1e-3 * j, m * 1e-3) is not False
        assert get(s, "z") == want[m * (j + 1) + 1], j
    assert bool(s._run) == runs


def test_while_the_blocks_warm_up_no_run_starts_and_after_it_runs_do(monkeypatch):
    """In a host that has not imported NumPy (a C host) the blocks of draws run sample by
    sample for their warm-up (slave_base.Blocks.WARM_UP over the streams): a run cannot start
    then (Accelerometer._new_run finds no arrays), and it starts once they hold arrays; every z
    equals the reference."""
    from driftfmu.fmu_src import Accelerometer as module
    from driftfmu.fmu_src import slave_base
    monkeypatch.setattr(slave_base, "_numpy_imported", lambda: False)
    want = _reference(RUN_VALUES, _inputs, 1500)
    s = initialised(**RUN_VALUES)
    streams = (s._n_rw, s._n_gm) + s._n_fl
    first = None
    for k in range(1, 1501):
        _checked_step(s, want, k)
        if s._run and first is None:
            first = s._run_k0
            assert all(b._values is not None for b in streams)  # (arrays by then)
    # the samples followed one another from the start: without the warm-up the first run
    # would start at RUN_AFTER + 1 (test_a_long_run_takes_runs_of_doubling_size_...); each
    # attempt that finds no arrays starts the count again, so the next is RUN_AFTER samples on
    assert first is not None and first > module.RUN_AFTER + 1, first
    assert (first - 1) % module.RUN_AFTER == 0, first


def test_steps_of_several_samples_in_a_c_host_through_the_blocks_warm_up(monkeypatch):
    """In a host that has not imported NumPy the held samples of a step take their draws one by
    one while the blocks warm up (errors.advance_state), and runs of them afterwards
    (errors.hold_run): steps of 1 to 9 samples from the first sample to past the warm-up give
    every z of the reference, and both kinds of held samples occur."""
    from driftfmu.fmu_src import slave_base
    monkeypatch.setattr(slave_base, "_numpy_imported", lambda: False)
    values = dict(RUN_VALUES, seed=19)
    x = 0.9
    want = _reference(values, lambda k: (x, 0.1, 299.0), 2200)
    s = initialised(**values)
    for name, v in zip(("x", "theta", "T"), (x, 0.1, 299.0)):
        put(s, name, v)
    kinds = []
    hold_run, advance_state = errors.hold_run, errors.advance_state
    monkeypatch.setattr(errors, "hold_run", lambda *a: kinds.append("run") or hold_run(*a))
    monkeypatch.setattr(errors, "advance_state",
                        lambda *a: kinds.append("one") or advance_state(*a))
    rng, t, k = random.Random(23), 0.0, 1
    while k < 2100:
        m = rng.randint(1, 9)
        assert get(s, "z") == want[k], k
        assert s.do_step(t, m * 1e-3) is not False, messages(s)
        t, k = t + m * 1e-3, k + m
    assert get(s, "z") == want[k]
    assert "one" in kinds and "run" in kinds and kinds.index("run") > kinds.index("one")


def test_a_row_of_the_run_is_used_only_for_the_numbers_it_was_computed_from():
    """Accelerometer._row gives the run's row of sample k for the very state the run left at
    k - 1; for a state with equal numbers that are other objects, or with other numbers, it
    gives none (the sample is computed on its own); and a committed state changed under the run
    gives the z of measure_errors from that state, not the run's."""
    s = initialised(**RUN_VALUES)
    for k in range(1, 300):
        _put_inputs(s, k)
        s.do_step((k - 1) * 1e-3, 1e-3)
    k, err = s.k, s._committed["_err"]
    assert s._run and s._run_k0 < k < s._run_k0 + len(s._run)
    row = s._run[k - s._run_k0]
    assert s._row(err, k) is row
    copied = errors.ErrorState(*(float(repr(v)) for v in err[:3]),
                               tuple(float(repr(v)) for v in err.fl))
    assert copied == err and s._row(copied, k) is None
    moved = err._replace(rw=err.rw + 0.5)
    s._committed["_err"] = moved
    s._dirty = True
    _put_inputs(s, k)
    cfg, ecfg = adxl203.config(**RUN_VALUES), errors.config(**RUN_VALUES)
    x, theta, T = _inputs(k)
    z = adxl203.measure_errors(s._committed["_lp"], moved, x, 0.0, adxl203.noise(31, k),
                               errors.draws(31, k, ecfg), theta, T, cfg, ecfg)[2]
    assert get(s, "z") == z


def test_reading_the_outputs_again_with_other_inputs_keeps_the_runs_and_their_bits():
    """A master that sets the inputs, reads z, sets other inputs and reads z again before every
    step (the same sample again: no break in the chain): the runs start as without it, and each
    z equals measure_errors' for the inputs set last."""
    want = _reference(RUN_VALUES, _inputs, 600)
    s = initialised(**RUN_VALUES)
    for k in range(1, 601):
        put(s, "x", -3.0)
        put(s, "theta", 0.5)
        get(s, "z")
        _checked_step(s, want, k)
    from driftfmu.fmu_src import Accelerometer as module
    assert s._run and s._run_size > module.RUN_FIRST


# -- the error state in the FMU state -------------------------------------------------------------

def _stepped(**values):
    s = initialised(**dict(ALL_ON, seed=5, **values))
    for k in range(30):
        put(s, "x", 0.3)
        s.do_step(k * 1e-3, 1e-3)
    return s


def test_the_error_state_round_trips_through_serialised_bytes():
    s = _stepped()
    state = s._get_fmu_state()
    assert len(state["_err"]) == 4 and len(state["_err"][3]) == s._ecfg.fl_n == 4
    data = Accelerometer._fmu_state_to_bytes(state)
    other = _stepped()
    for k in range(5):
        other.do_step(0.03 + k * 1e-3, 1e-3)
    other._set_fmu_state(Accelerometer._fmu_state_from_bytes(data))
    assert not messages(other)
    assert snapshot(other) == snapshot(s)


@pytest.mark.parametrize("change, words", [
    (lambda e: e[3].pop(), "3 flicker components; allowed: 4"),
    (lambda e: e[3].append(0.1), "5 flicker components; allowed: 4"),
    (lambda e: e.__setitem__(2, -1e-12), "E = -1e-12 is a negative exposure"),
    (lambda e: e.__setitem__(1, math.inf), "inf is not a finite number"),
    (lambda e: e[3].__setitem__(0, math.nan), "nan is not a finite number"),
    (lambda e: e.__setitem__(0, "0.1"), "'0.1' is not a finite number"),
    (lambda e: e.pop(), "not [rw, gm, E, [flicker components]]"),
])
def test_an_error_state_that_cannot_be_this_sensors_is_refused_and_changes_nothing(change,
                                                                                  words):
    s = _stepped()
    before = snapshot(s)
    state = copy.deepcopy(s._get_fmu_state())
    change(state["_err"])
    s._set_fmu_state(state)
    log = messages(s)
    assert any(words in m for m in log) and "nothing was changed" in log[-1], log
    assert snapshot(s) == before


@pytest.mark.parametrize("off, name", [("random_walk", "rw"), ("bias_gm", "gm"),
                                       ("d_inf", "E")])
def test_a_process_that_is_off_must_have_a_zero_state(off, name):
    s = _stepped(**{off: 0.0})
    before = snapshot(s)
    state = copy.deepcopy(s._get_fmu_state())
    state["_err"][("rw", "gm", "E").index(name)] = 0.25
    s._set_fmu_state(state)
    log = messages(s)
    assert any("%s = 0.25 although %s = 0 (off)" % (name, off) in m for m in log), log
    assert snapshot(s) == before
    state["_err"][("rw", "gm", "E").index(name)] = 0.0  # the same state with 0: accepted
    s._set_fmu_state(state)
    assert not messages(s)


def test_an_error_state_with_every_term_off_or_missing_with_one_on_is_refused():
    plain = initialised()
    plain.do_step(0.0, 1e-3)
    state = copy.deepcopy(plain._get_fmu_state())
    before = snapshot(plain)
    state["_err"] = [0.0, 0.0, 0.0, []]
    plain._set_fmu_state(state)
    assert "every slow error is off" in messages(plain)[-1]
    assert snapshot(plain) == before
    s = _stepped()
    state = copy.deepcopy(s._get_fmu_state())
    before = snapshot(s)
    state["_err"] = None
    s._set_fmu_state(state)
    assert "_err of an initialised instance is missing" in messages(s)[-1]
    assert snapshot(s) == before


# -- bad values: one line, what is allowed, nothing changed -------------------------------------

@pytest.mark.parametrize("name", ["theta", "T"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_non_finite_tilt_or_temperature_is_refused_and_changes_nothing(name, value):
    s = _stepped()
    before = snapshot(s)
    put(s, name, value)
    log = messages(s)
    assert log == ["a: fmi2SetReal: %s = %r is not finite; input accepts finite values only"
                   % (name, value)]
    assert snapshot(s) == before
    assert s.do_step(0.03, 1e-3) is not False


@pytest.mark.parametrize("values, words", [
    (dict(bias_gm=-0.1), "bias_gm = -0.1 is out of range; allowed: bias_gm >= 0"),
    (dict(flicker=-1e-3), "flicker = -0.001 is out of range; allowed: flicker >= 0"),
    (dict(random_walk=-1.0), "random_walk = -1.0 is out of range; allowed: random_walk >= 0"),
    (dict(bias_on=-2.0), "bias_on = -2.0 is out of range; allowed: bias_on >= 0"),
    (dict(flicker=0.01, tau_min=3.0, tau_max=3.0),
     "tau_min = 3.0 s and tau_max = 3.0 s are not a band; allowed: tau_min < tau_max"),
    (dict(flicker=0.01, tau_min=4.0, tau_max=3.0), "are not a band"),
    (dict(tau_gm=0.0), "tau_gm = 0.0 is out of range; allowed: tau_gm > 0"),
    (dict(E_tau=-1.0), "E_tau = -1.0 is out of range; allowed: E_tau > 0"),
    (dict(range=-1.0), "range = -1.0 is out of range; allowed: range >= 0"),
    (dict(dual=1, flicker=0.01), "dual = 1 is not allowed with flicker = 0.01"),
    (dict(random_walk=1e308, Ts=100.0), "the slow errors' rw = inf"),
    (dict(bits=8, range=1e308, a1=1e10), "the ADC over a0 +- |a1| range gives lsb = inf"),
])
def test_a_bad_parameter_is_refused_with_one_line_saying_what_is_allowed(values, words):
    s = slave(**values)
    log = messages(s)
    assert not s._initialised and any(words in m for m in log), log
    assert all("allowed" in m for m in log)


def test_an_exposure_that_overflows_is_refused_and_changes_nothing():
    s = _stepped()
    before = snapshot(s)
    put(s, "x", 1e200)  # x^2 Ts overflows; the drift d_inf (1 - exp(-inf)) would not
    z = s.get_real([vr(s, "z")])
    log = messages(s)
    assert any("hidden state _err.E would be inf at sample 31" in m for m in log), log
    put(s, "x", 0.3)
    messages(s)
    assert snapshot(s)[0] == before[0]
    assert s.do_step(0.03, 1e-3) is not False


def test_a_state_restore_keeps_the_slow_errors_blocks_of_draws():
    # a master that rolls back every step pays no new block of the streams' draws: after a
    # restore each stream (walk, Gauss-Markov, every flicker component) has the same blocks,
    # as the measurement noise's do
    s = initialised(**ALL_ON)
    streams = [s._n_rw, s._n_gm, *s._n_fl]
    assert len(streams) >= 4 and len(set(map(id, streams))) == len(streams)
    state = s._get_fmu_state()
    s.do_step(0.0, 1e-3)
    s._set_fmu_state(state)
    assert [s._n_rw, s._n_gm, *s._n_fl] == streams
    assert all(a is b for a, b in zip([s._n_rw, s._n_gm, *s._n_fl], streams))
