"""The DriftEstimator's bias state and class-2 offset in the FMU (the slave class, and through
the ``make`` fixture the pythonfmu FMU and its native twin with the same calls and messages).

- bias = 1: the outputs are models/bias.py's (batch.estimate over the same measurements),
  predict-only samples inside a step too; z_comp = z - dc - b_hat;
- class 2: the offset models.errors.class2_offset of the tilt and temperature inputs is removed from z
  before filtering (both process models), shown as dc_class2; a tilt set back to 0 gives the
  letter's filter again;
- bad values get one line each and change nothing, on both sides of every bound; a covariance
  past double precision is refused at its sample; FMU states carry the bias part, and a state
  whose bias part does not fit its parameters is refused with the reason.
"""
import json
import math

import numpy as np
import pytest

from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.models import bias, chain, drift, errors, harmonic
from driftfmu.simulations import batch

from test_bias import PAST_PRECISION
from test_slaves import get, make, messages, set_var  # noqa: F401 (make: a fixture)

BIAS = dict(bias=1, Qb=1e-8, tau_b=0.05, b0=0.002, Pb0=1e-3, A=0.6, a2=0.05, a3=0.01, P0=0.02)


def start(s, values):
    """Initialise ``s`` with ``values``; whether it was accepted."""
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    for name, value in values.items():
        set_var(s, name, value)
    done = s.exit_initialization_mode()
    return s._initialised if done is None else done  # (the slave class returns None)


def slave(values=(), make_=None):
    s = (make_ or (lambda cls, name: cls(instance_name=name)))(DriftEstimator, "d")
    assert start(s, dict(values)), messages(s)
    assert not messages(s)
    return s


def measurements(n, seed=4501):
    rng = np.random.default_rng(seed)
    return 0.01 + 0.1 * rng.standard_normal(n)


def test_bias_outputs_equal_the_models_sample_by_sample():
    zs = measurements(300)
    s = slave(BIAS)
    ref = batch.estimate(zs[None, :], **{k: v for k, v in BIAS.items()},
                         record=batch.ESTIMATES)
    for k, z in enumerate(zs):
        set_var(s, "z", float(z))
        for name in batch.ESTIMATES:
            assert get(s, name) == ref[name][0, k], (k, name)
        dc = get(s, "dc")
        assert get(s, "z_comp") == bias.compensate(float(z), dc, get(s, "b_hat"))
        assert get(s, "z_comp") == float(z) - dc - get(s, "b_hat")
        assert s.do_step(k * 1e-3, 1e-3)
    assert get(s, "dc_class2") == 0.0


def test_predict_only_samples_inside_a_step_follow_the_models():
    s = slave(BIAS)
    set_var(s, "z", 0.05)
    assert s.do_step(0.0, 4e-3)  # sample 1 with z, samples 2..4 predict-only
    st, b = chain.estimator_init(0.0, 0.02), bias.init(0.002, 1e-3)
    Fb = bias.factor(0.05, 1e-3)
    st, b = bias.estimator_step(st, b, 0.05, 0.0, 1.0, 0.05, 0.6, 0.01, 1e-4, Fb, 1e-8, 0.01)
    for _ in range(3):
        st, b = bias.estimator_predict(st, b, 0.6, 0.01, Fb, 1e-8)
    state = s._get_fmu_state()
    assert state["_bias"] == list(b) and state["_state"][:2] == [st.x, st.P]


@pytest.mark.parametrize("process", [harmonic.GAUSS_MARKOV, harmonic.HARMONIC])
def test_the_class2_offset_is_removed_before_filtering(process):
    coeffs = dict(kT_bias=2e-3, kT_scale=5e-4, T0=300.0, a2=0.05, process=process, f=40.0)
    s = slave(coeffs)
    zs = measurements(120)
    est = harmonic.estimator_init(process, 0.0, 0.01)
    C, S = harmonic.rotation(40.0, 1e-3)
    for k, z in enumerate(zs):
        theta, T = 0.3 + 0.001 * k, 290.0 + 0.1 * k
        set_var(s, "z", float(z))
        set_var(s, "theta", theta)
        set_var(s, "T", T)
        offset = errors.class2_offset(theta, T, 1.0, 0.05, 300.0, 2e-3, 5e-4)
        g = (1 + 5e-4 * (T - 300)) * math.sin(theta)
        assert offset == pytest.approx(2e-3 * (T - 300) + g + 0.05 * g * g, rel=1e-13)
        est = harmonic.estimator_step(est, float(z) - offset, 0.0, 1.0, 0.05, 1e-4, process,
                                      0.0, 0.01, C, S, 1e-8)
        dcs = drift.estimates(est.drift, 0.05)
        assert get(s, "dc_class2") == offset
        assert (get(s, "x_hat"), get(s, "dc_ekf1")) == (est.x, dcs[0])
        assert get(s, "z_comp") == chain.compensate(float(z) - offset, dcs[0])
        assert (get(s, "b_hat"), get(s, "P_bb"), get(s, "P_xb")) == (0.0, 0.0, 0.0)
        assert s.do_step(k * 1e-3, 1e-3)


def test_a_tilt_set_back_to_0_gives_the_letters_filter_again():
    zs = measurements(60)
    tilted, plain = slave(), slave()
    for k, z in enumerate(zs):
        for s in (tilted, plain):
            set_var(s, "z", float(z))
        set_var(tilted, "theta", 0.2 if k < 20 else 0.0)
        if k >= 20:  # from the same state, the same bits
            if k == 20:
                state = tilted._get_fmu_state()
                plain._set_fmu_state(json.loads(json.dumps(state)))
                set_var(plain, "z", float(z))
            assert [get(tilted, n) for n in DriftEstimator.OUTPUTS[:7]] == \
                [get(plain, n) for n in DriftEstimator.OUTPUTS[:7]]
            assert get(tilted, "dc_class2") == 0.0
        else:
            assert get(tilted, "dc_class2") == errors.class2_offset(0.2, 298.15, 1.0, 0.01, 298.15,
                                                                      0.0, 0.0)
        for s in (tilted, plain):
            assert s.do_step(k * 1e-3, 1e-3)


# -- bad values: one line, nothing changed, both sides of every bound ------------------------------

@pytest.mark.parametrize("name,bad,good,text", [
    ("Qb", -5e-324, 0.0, "Qb = -5e-324 is out of range; allowed: Qb >= 0"),
    ("Pb0", -1e-300, 0.0, "Pb0 = -1e-300 is out of range; allowed: Pb0 >= 0"),
    ("tau_b", -1e-9, 0.0, "tau_b = -1e-09 is out of range; allowed: tau_b >= 0"),
    ("T0", 0.0, 5e-324, "T0 = 0.0 is out of range; allowed: T0 > 0"),
    ("bias", 2, 1, "bias = 2 is out of range; allowed: an integer bias >= 0 and bias <= 1"),
    ("bias", -1, 0, "bias = -1 is out of range; allowed: an integer bias >= 0 and bias <= 1"),
])
def test_bad_parameters_are_refused_at_initialisation_and_the_bound_itself_is_not(
        make, name, bad, good, text):
    s = make(DriftEstimator, "d")
    assert start(s, {name: bad}) is False
    got = messages(s)
    assert len(got) == 1 and got[0].endswith(text) and "\n" not in got[0], got
    s = make(DriftEstimator, "d2")
    assert start(s, dict(BIAS, **{name: good}))
    assert not messages(s)


def test_a_bias_state_with_the_harmonic_filter_is_refused(make):
    s = make(DriftEstimator, "d")
    assert start(s, dict(bias=1, process=2)) is False
    assert messages(s) == ["d: bias = 1 is not allowed with process = 2; allowed: bias = 1 with "
                           "process = 1 (the harmonic filter has no bias state), or bias = 0"]
    assert start(make(DriftEstimator, "d2"), dict(bias=0, process=2))


@pytest.mark.parametrize("name", ["theta", "T"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_a_non_finite_tilt_or_temperature_is_refused_and_changes_nothing(make, name, value):
    s = make(DriftEstimator, "d")
    assert start(s, dict(BIAS, kT_bias=1e-3))
    set_var(s, "z", 0.1)
    assert s.do_step(0.0, 1e-3)
    before = [get(s, n) for n in DriftEstimator.OUTPUTS], s._get_fmu_state()
    set_var(s, name, value)
    got = messages(s)
    assert len(got) == 1 and "%s = %r is not finite; input accepts finite values only" % (
        name, value) in got[0], got
    assert ([get(s, n) for n in DriftEstimator.OUTPUTS], s._get_fmu_state()) == before


def test_a_covariance_past_double_precision_is_refused_at_its_sample(make):
    s = make(DriftEstimator, "d")
    assert start(s, dict(bias=1, tau_b=0.0, **PAST_PRECISION))
    set_var(s, "z", 0.0)
    assert get(s, "P_bb") > 0
    assert s.do_step(0.0, 1e-3)
    before = s._get_fmu_state()
    get(s, "P")  # (the read computes the pending sample 2, and refuses it)
    got = messages(s)
    assert len(got) == 1 and got[0].startswith(
        "d: P_bb would be -5.10552735385615") and "at sample 2 (t = 0.001 s), a negative " \
        "variance: the inputs and parameters exceed what double precision can carry" in got[0]
    assert s.do_step(1e-3, 1e-3) is False
    assert s._get_fmu_state() == before


def test_a_multi_sample_step_refuses_the_sample_inside_it_that_leaves_the_cone():
    # off the sample grid, a step's first instant takes the held z and the others predict:
    # sample 2 (the update that leaves the cone) is checked before sample 3 is computed from it
    s = slave(dict(bias=1, **PAST_PRECISION))
    set_var(s, "z", 0.0)
    assert s.do_step(0.0, 0.5e-3)
    before = s._get_fmu_state()
    assert s.do_step(0.5e-3, 3e-3) is False
    got = messages(s)
    assert len(got) == 1 and got[0].startswith("d: P_bb would be -5.10552735385615") and \
        "at sample 2 (t = 0.001 s), a negative variance" in got[0], got
    assert s._get_fmu_state() == before


# -- FMU states with the bias part ---------------------------------------------------------------

def test_a_state_with_the_bias_part_restores_the_same_bits():
    zs = measurements(80)
    s = slave(BIAS)
    rows, saved = [], None
    for k, z in enumerate(zs):
        set_var(s, "z", float(z))
        if k == 30:
            saved = json.loads(json.dumps(s._get_fmu_state()))
        rows.append([get(s, n) for n in DriftEstimator.OUTPUTS])
        assert s.do_step(k * 1e-3, 1e-3)
    other = slave(BIAS)
    other._set_fmu_state(saved)
    for k, z in enumerate(zs[30:], start=30):
        set_var(other, "z", float(z))
        assert [get(other, n) for n in DriftEstimator.OUTPUTS] == rows[k]
        assert other.do_step(k * 1e-3, 1e-3)


@pytest.mark.parametrize("change,text", [
    (lambda st: st.update(_bias=None),
     "the hidden state _bias of an initialised instance is missing (null)"),
    (lambda st: st.update(bias=0),
     "the hidden state _bias = [0.002, 0.0, 0.001] does not belong to bias = 0; allowed: null "
     "with bias = 0"),
    (lambda st: st["_bias"].__setitem__(2, -1e-3),
     "hidden state _bias.Pbb = -0.001 is a negative variance; allowed: _bias.Pbb >= 0"),
    (lambda st: st["_bias"].__setitem__(1, 0.5),
     "the covariance (P, Pxb, Pbb) of hidden states _state and _bias = (0.02, 0.5, 0.001) is "
     "not positive semi-definite"),
    (lambda st: st.update(_bias=[0.0, 0.0]), "is not valid (not a bias state [b, Pxb, Pbb])"),
    (lambda st: st["_bias"].__setitem__(0, "x"), "is not valid ('x' is not a finite number)"),
    (lambda st: st.update(process=2),
     "bias = 1 is not allowed with process = 2; allowed: bias = 1 with process = 1"),
])
def test_a_state_whose_bias_part_does_not_fit_is_refused(change, text):
    s = slave(BIAS)
    good = json.loads(json.dumps(s._get_fmu_state()))
    bad = json.loads(json.dumps(good))
    change(bad)
    s._set_fmu_state(bad)
    got = messages(s)
    assert got and text in got[-1], got
    assert s._get_fmu_state() == good


def test_a_state_of_the_letters_filter_restores_into_it_unchanged():
    s = slave()
    state = json.loads(json.dumps(s._get_fmu_state()))
    assert state["_bias"] is None
    other = slave(dict(bias=1))
    other._set_fmu_state(state)  # (a state carries its parameters: bias = 0)
    assert not messages(other) and other._get_fmu_state() == s._get_fmu_state()


#: The DriftEstimator's variables before the bias state, in value-reference order.
BEFORE = ("a0", "a1", "a2", "A", "Q", "R", "x0", "P0", "Ts", "estimator", "z", "process", "f",
          "Qh", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp", "a3", "a4", "B",
          "u")


def test_the_new_variables_are_appended_with_units_ranges_and_dependencies():
    rows = DriftEstimator.VARIABLES
    assert tuple(s["name"] for s in rows[:len(BEFORE)]) == BEFORE  # no value reference moves
    new = {s["name"]: s for s in rows[len(BEFORE):]}
    assert sorted(new) == sorted(("bias", "Qb", "tau_b", "b0", "Pb0", "theta", "T", "T0",
                                  "kT_bias", "kT_scale", "b_hat", "P_bb", "P_xb", "dc_class2"))
    assert (new["bias"]["type"], new["bias"]["min"], new["bias"]["max"], new["bias"]["start"]) \
        == ("Integer", 0, 1, 0)
    assert (new["Qb"]["min"], new["Pb0"]["min"], new["tau_b"]["min"]) == (0.0, 0.0, 0.0)
    assert new["T0"]["min"] == 5e-324 and new["T"]["start"] == new["T0"]["start"] == 298.15
    units = {n: new[n]["unit"] for n in new}
    assert units == dict(bias=None, Qb="V2", tau_b="s", b0="V", Pb0="V2", theta="rad", T="K",
                         T0="K", kT_bias="V/K", kT_scale="1/K", b_hat="V", P_bb="V2",
                         P_xb="g.V", dc_class2="V")
    assert (new["theta"]["causality"], new["theta"]["variability"]) == ("input", "discrete")
    for out in DriftEstimator.OUTPUTS:
        assert DriftEstimator.DEPENDENCIES[out] == ["z", "u", "theta", "T"]
