"""One long step of the Python DualDriftEstimator (issue 40: a million-sample step took 22.9 s,
the native twin 0.22 s): its predictions and covariance checks run on the state's fields
(``models/dualaxis.predict_run``, the 4x4 check written out in
``models/covariance._valid4_floats``) and must give the bits, and the refusals, of the sample
at a time loop they replace.  The speed is benchmarks/bench_long_step.py's."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from driftfmu.fmu_src.DualDriftEstimator import DualDriftEstimator
from driftfmu.models import covariance, dualaxis
from test_hardening import messages, put, ready

TS = 1e-3
SETTINGS = {1: dict(process=1, A=0.9, Q=0.01, Qy=0.02, rho=0.5, bx=0.03, by=-0.02),
            2: dict(process=2, f=150.0, Qh=1e-6, bx=0.03, by=-0.02)}


def _one_sample_at_a_time(state, model, k0, n):
    """The loop the FMU's hold ran before: the covariance after each sample checked, then the
    next sample predicted; ``("refused", k)`` at the first that is not valid."""
    for k in range(k0, k0 + n - 1):
        if not dualaxis.valid(state):
            return "refused", k
        state = dualaxis.estimator_predict(state, model)
    return state


@pytest.mark.parametrize("process", [1, 2])
@pytest.mark.parametrize("n", [2, 3, 2000])
def test_the_dual_estimators_long_step_gives_the_bits_of_one_sample_at_a_time(process, n):
    s = ready(DualDriftEstimator, **SETTINGS[process])
    put(s, "z_x", 0.31)
    put(s, "z_y", -0.17)
    before = s._committed["_state"]
    first = dualaxis.estimator_step(before, 0.31, -0.17, *s._axes, s._model)
    want = _one_sample_at_a_time(first, s._model, 1, n)
    assert s.do_step(0.0, n * TS) and not messages(s)
    got = s._committed["_state"]
    assert type(got) is type(want) and got == want
    assert all(a == b and math.copysign(1, a) == math.copysign(1, b)
               for a, b in zip(got[:-1], want[:-1]))


@pytest.mark.parametrize("process", [1, 2])
@pytest.mark.parametrize("bad_from", [2, 3, 17])
def test_a_covariance_that_turns_invalid_inside_a_long_step_is_refused_at_its_sample(
        process, bad_from, monkeypatch):
    """The check holds for every sample of the step, not only the last: a covariance made
    invalid (by a planted check) from sample ``bad_from`` on is refused at that sample, as the
    sample-at-a-time loop refuses it, and the instance is left as it was."""
    s = ready(DualDriftEstimator, **SETTINGS[process])
    put(s, "z_x", 0.31)
    put(s, "z_y", -0.17)
    first = dualaxis.estimator_step(s._committed["_state"], 0.31, -0.17, *s._axes, s._model)
    # the trace of the covariance after sample `bad_from`: it grows from sample to sample
    # (A^2 P + Q from the small posterior; a rotation keeps a trace and Qh adds to it)
    state = first
    for _ in range(bad_from - 1):
        state = dualaxis.estimator_predict(state, s._model)

    def trace(lower):
        return sum(row[-1] for row in lower)
    limit = trace(dualaxis.covariance_of(state)[1])
    real_valid, real_valid2 = covariance.valid, covariance.valid2
    monkeypatch.setattr(covariance, "valid", lambda lower: trace(lower) < limit and
                        real_valid(lower))
    monkeypatch.setattr(covariance, "valid2", lambda a, b, c: a + c < limit and
                        real_valid2(a, b, c))
    assert _one_sample_at_a_time(first, s._model, 1, 50) == ("refused", bad_from)
    before = s._committed
    assert not s.do_step(0.0, 50 * TS)
    said = messages(s)
    assert len(said) == 1 and "sample %d " % bad_from in said[0], said
    assert s._committed is before


_ENTRY = st.one_of(st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e300, math.inf, -math.inf,
                                    math.nan, 1.0, -1.0]),
                   st.floats(allow_nan=True, allow_infinity=True))


@settings(max_examples=400, deadline=None)
@given(st.lists(_ENTRY, min_size=10, max_size=10))
def test_the_written_out_4x4_check_is_the_general_one_on_any_floats(entries):
    """The same answer for any ten floats, and the same exception where the general one raises
    one (0/0 where an infinite variance meets a zero one)."""
    p11, p21, p22, p31, p32, p33, p41, p42, p43, p44 = entries
    lower = ((p11,), (p21, p22), (p31, p32, p33), (p41, p42, p43, p44))
    general = _outcome(covariance._valid_floats, lower)
    assert _outcome(covariance._valid4_floats, *entries) == general
    assert _outcome(covariance.valid, lower) == general


def _outcome(f, *args):
    try:
        return f(*args)
    except ArithmeticError as exc:
        return type(exc)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=16, max_size=16),
       st.sampled_from([0, 1, 2, 3, None]), st.floats(-1e-9, 1e-9))
def test_the_written_out_4x4_check_is_the_general_one_near_the_cone(a, zero, nudge):
    """Covariances ``A A^T`` (valid, some singular where a row of ``A`` is zero) and the same
    nudged off the cone: both checks answer alike, on both sides of the bound."""
    rows = [a[4 * i:4 * i + 4] for i in range(4)]
    if zero is not None:
        rows[zero] = [0.0] * 4
    P = [[sum(rows[i][k] * rows[j][k] for k in range(4)) for j in range(4)] for i in range(4)]
    P[1][0] += nudge * (abs(P[0][0] * P[1][1]) ** 0.5)
    lower = tuple(tuple(P[i][j] for j in range(i + 1)) for i in range(4))
    flat = [v for row in lower for v in row]
    assert covariance._valid4_floats(*flat) == covariance._valid_floats(lower)


_PAIRS = [(i, j) for i in range(4) for j in range(i)]


@pytest.mark.parametrize("i, j", _PAIRS)
@pytest.mark.parametrize("scale", [1.0, 1.0 + 2.0 ** -19])
def test_the_written_out_4x4_check_on_both_sides_of_each_correlation(i, j, scale):
    """A correlation of 1 between two components (singular, within the slack: valid) and one
    just past the slack (not valid), for each pair in turn, beside others that are not zero:
    every pivot's every term takes part, and both checks answer alike."""
    c = [[1.0 if a == b else 0.1 * ((a + b) % 3 - 1) for b in range(4)] for a in range(4)]
    base = [row[:] for row in c]
    base[i][j] = base[j][i] = 0.0
    for a in range(4):  # the pair's rows free of the others: the pair alone decides
        for b in range(4):
            if a != b and {a, b} & {i, j}:
                base[a][b] = 0.0
    base[i][j] = base[j][i] = scale * covariance.BOUND if scale > 1 else 1.0
    variances = (4.0, 0.25, 9.0, 1.0)
    s = [v ** 0.5 for v in variances]
    lower = tuple(tuple(base[a][b] * s[a] * s[b] for b in range(a + 1)) for a in range(4))
    flat = [v for row in lower for v in row]
    general = covariance._valid_floats(lower)
    assert general == (scale == 1.0), (i, j, scale)
    assert covariance._valid4_floats(*flat) == general


@pytest.mark.parametrize("i, j", _PAIRS)
@pytest.mark.parametrize("scale", [1.0, 1.0 + 2.0 ** -19], ids=["correlation 1", "past it"])
def test_a_long_step_checks_each_entry_of_the_harmonic_covariance_in_its_place(i, j, scale):
    """predict_run's check reads each of the ten entries of the 4x4 covariance where it
    belongs: a correlation of 1 between one pair (valid) is predicted as far as asked, one just
    past the slack is refused before the first update, as the sample-at-a-time loop does."""
    s = ready(DualDriftEstimator, **SETTINGS[2])
    names = (("P11",), ("P12", "P22"), ("P13", "P23", "P33"), ("P14", "P24", "P34", "P44"))
    variances = (4.0, 0.25, 9.0, 1.0)
    entries = {names[a][b]: variances[a] if a == b else 0.0
               for a in range(4) for b in range(a + 1)}
    entries[names[i][j]] = (scale * covariance.BOUND if scale > 1 else 1.0) * \
        math.sqrt(variances[i] * variances[j])
    state = s._committed["_state"]._replace(**entries)
    want, n = state, 0
    while n < 5 and dualaxis.valid(want):
        want, n = dualaxis.estimator_predict(want, s._model), n + 1
    assert n == (5 if scale == 1.0 else 0)
    assert dualaxis.predict_run(state, s._model, 5) == (want, n)
