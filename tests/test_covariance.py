"""No OK carries a negative variance (issue 31): the covariance rule of models/covariance.py, the
FMUs' refusal of a sample that leaves it (Python slaves in-process here; every twin through raw
calls in test_covariance_twins.py), a restored state checked by it, and the batch engines
stopping a run there (NumPy and the compiled kernel alike).

The issue's cases: the DriftEstimator with the harmonic filter, ``P0 = 1e154``, ``x0 = 3e8``,
``z = 0`` and steps of 0.1 s showed ``P = -3.67e106`` with OK; ``P0 = 1e16`` gave small negative
variances; the DualDriftEstimator's hidden ``P44`` went to -0.49999999.
"""
import json
import math
import random

import numpy as np
import pytest

from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.DualDriftEstimator import DualDriftEstimator
from driftfmu.models import adxl203, chain, covariance, dualaxis, ekf, excitation, harmonic
from driftfmu.simulations import batch, kernel

from test_hardening import messages, put, ready, snapshot, vr

CAUSE = "the inputs and parameters exceed what double precision can carry"


# -- the rule ---------------------------------------------------------------------------------

def _lower(M):
    return [[float(M[i, j]) for j in range(i + 1)] for i in range(M.shape[0])]


def _min_eig_shifted(M):
    """The least eigenvalue of the correlation matrix of ``M`` plus SLACK on its diagonal (the
    rule asks it to be positive), over the rows of nonzero variance."""
    s = np.sqrt(np.diag(M))
    keep = s > 0
    C = M[np.ix_(keep, keep)] / np.outer(s[keep], s[keep])
    return np.linalg.eigvalsh(C + covariance.SLACK * np.eye(C.shape[0]))[0] if keep.any() \
        else 1.0


def _random_covariance(rng, n):
    """A random symmetric matrix near the PSD boundary: ``B B^T`` of a random rank, scaled,
    with a perturbation of random size (often far outside the slack, sometimes inside)."""
    rank = rng.randint(1, n)
    B = np.array([[rng.gauss(0, 1) for _ in range(rank)] for _ in range(n)])
    M = B @ B.T * 10.0 ** rng.uniform(-6, 6)
    E = np.array([[rng.gauss(0, 1) for _ in range(n)] for _ in range(n)])
    M = M + (E + E.T) * 10.0 ** rng.uniform(-12, 0) * np.abs(M).max()
    if rng.random() < 0.2:  # a row of zero variance, with or without covariances
        i = rng.randrange(n)
        M[i, :] = M[:, i] = 0.0 if rng.random() < 0.5 else M[i, :] * 0.0
        if rng.random() < 0.5:
            j = (i + 1) % n
            M[i, j] = M[j, i] = 1e-300
    return M


@pytest.mark.parametrize("n", [2, 4])
def test_the_rule_is_the_slackened_correlation_matrix_positive_definite(n):
    """valid() answers as the eigenvalues of the correlation matrix plus SLACK on its
    diagonal do (away from the boundary, where rounding decides), with a negative variance and
    a covariance beside a zero variance refused."""
    rng = random.Random(31 + n)
    seen = {True: 0, False: 0}
    for _ in range(1500):
        M = _random_covariance(rng, n)
        got = covariance.valid(_lower(M))
        if (np.diag(M) < 0).any():
            assert got is False
        elif any(M[i, j] != 0.0 for i in range(n) for j in range(n)
                 if i != j and M[i, i] * M[j, j] == 0.0):
            assert got is False
        else:
            least = _min_eig_shifted(M)
            if abs(least) < 1e-9:
                continue
            assert got is bool(least > 0.0), (M, least)
        seen[got] += 1
    assert min(seen.values()) > 150, seen


def test_valid2_and_the_array_path_give_valid_s_answers():
    rng = random.Random(3)
    cases = []
    for _ in range(4000):
        a = 10.0 ** rng.uniform(-300, 300) * rng.choice([1.0, 1.0, 1.0, -1.0, 0.0])
        c = 10.0 ** rng.uniform(-300, 300) * rng.choice([1.0, 1.0, 1.0, 0.0])
        r = rng.choice([rng.uniform(-1.5, 1.5), 1.0, -1.0, covariance.BOUND,
                        1.0 + covariance.SLACK * rng.uniform(0.5, 1.5), 0.0])
        b = r * math.sqrt(abs(a)) * math.sqrt(c)
        cases.append((a, b, c))
    cases += [(1.0, math.nan, 1.0), (math.nan, 0.0, 1.0), (1.0, 0.0, -0.0), (5e-324, 5e-324, 1.0)]
    floats = [covariance.valid2(*p) for p in cases]
    assert floats == [covariance.valid(((a,), (b, c))) for a, b, c in cases]
    arrays = covariance.valid2(*(np.array(v) for v in zip(*cases)))
    assert arrays.tolist() == floats
    assert 0 < sum(floats) < len(floats)


def test_a_variance_of_zero_and_the_boundary():
    assert covariance.valid2(0.0, 0.0, 0.0) and covariance.valid2(0.0, 0.0, 1.0)
    assert not covariance.valid2(0.0, 1e-300, 1.0)          # a covariance beside no variance
    assert covariance.valid2(1.0, 1.0, 1.0)                  # singular: within the slack
    assert covariance.valid2(1.0, 1.0 + covariance.SLACK / 2, 1.0)
    assert not covariance.valid2(1.0, 1.0 + 2 * covariance.SLACK, 1.0)
    assert not covariance.valid2(-5e-324, 0.0, 1.0)         # a variance is never negative


# -- filters that work are far inside the rule; the scalar filter cannot leave it --------------

def _pivots(lower):
    """The L D L^T pivots of the correlation matrix (no slack) of ``lower``."""
    M = np.array([[lower[max(i, j)][min(i, j)] for j in range(len(lower))]
                  for i in range(len(lower))])
    s = np.sqrt(np.diag(M))
    C = M / np.outer(s, s)
    return np.linalg.eigvalsh(C)[0]


def test_the_experiments_filters_stay_far_inside_the_rule():
    """The settings of the experiments keep the least eigenvalue of every correlation matrix
    above 0.4 (the harmonic filter of the ADXL203 stand-in and of the dual-axis sweep), and a
    singular covariance (the dual filter with rho = 1 and A = 0.999: the two axes' noises are
    one) within 1e-11 of it after 1500 samples, 1e4 times inside the slack."""
    cols = adxl203.simulate(1500, dict(kind=excitation.SINUSOIDAL, X=1.0, f=150.0),
                            dict(seed=4), dict(process=harmonic.HARMONIC, f=150.0, P0=0.5,
                                               Qh=1e-8), 1e-3)
    assert len(cols["P"]) == 1500  # (no CovarianceError)
    least = {}
    es = dualaxis.estimator_values(process=harmonic.HARMONIC, P0=0.5, P0y=0.32, bx=0.01,
                                   by=-0.006)
    fx, fy = dualaxis.axes(es)
    for label, process, rho, A in (("harmonic", 2, 0.0, 0.0), ("rho = 0.9", 1, 0.9, 0.0),
                                   ("rho = 1", 1, 1.0, 0.999)):
        m = dualaxis.model(process, A=A, Q=0.01, Qy=0.01, rho=rho, f=150.0, Ts=1e-3, Qh=1e-8)
        st = dualaxis.estimator_init(process, 0.0, 0.0, 0.5 if process == 2 else 0.0,
                                     0.32 if process == 2 else 0.0)
        x = y = 0.0
        worst = math.inf
        for k in range(1, 1501):
            if process == 1:
                x, y = excitation.gaussian_pair(x, y, A, 0.01, 0.01, rho, 7, k)
            else:
                x, y = excitation.sine(k, 1.0, 150.0, 1e-3, 0.3), excitation.sine(
                    k, 0.8, 150.0, 1e-3, -0.7)
            zx, zy = dualaxis.measure(x, y, fx, fy, *dualaxis.noise(7, k))
            st = dualaxis.estimator_step(st, zx, zy, fx, fy, m)
            assert dualaxis.valid(st), (label, k)
            worst = min(worst, _pivots(dualaxis.covariance_of(st)[1]))
        least[label] = worst
    assert least["harmonic"] > 0.4 and least["rho = 0.9"] > 0.4, least
    assert abs(least["rho = 1"]) < 1e-11 and covariance.SLACK > 1e4 * 1e-11, least


def test_the_scalar_filter_cannot_report_a_negative_variance():
    """Joseph's (1 - K H)^2 P + K^2 R and A^2 P + Q from P0 >= 0 are >= 0 (or not finite,
    which the overflow checks refuse) for any parameters: extreme ones drawn at random.  (The
    simple form (1 - K H) P goes negative on such draws: the fault ekf-simple-covariance.)"""
    rng = random.Random(5)
    negatives = finite = 0
    for _ in range(400):
        p = dict(a0=rng.uniform(-1e3, 1e3), a1=rng.choice([-1, 1]) * 10.0 ** rng.uniform(-5, 8),
                 a2=rng.uniform(-1, 1) * 10.0 ** rng.uniform(-5, 8), A=rng.uniform(-1, 1),
                 Q=rng.choice([0.0, 10.0 ** rng.uniform(-300, 300)]),
                 R=10.0 ** rng.uniform(-323, 300))
        x, P = rng.uniform(-1, 1) * 10.0 ** rng.uniform(0, 150), 10.0 ** rng.uniform(-300, 300)
        for k in range(30):
            z = rng.uniform(-1, 1) * 10.0 ** rng.uniform(-3, 150)
            with np.errstate(all="ignore"):
                try:
                    x, P = ekf.step(x, P, z, p["a0"], p["a1"], p["a2"], p["A"], p["Q"], p["R"])
                except (OverflowError, ZeroDivisionError):
                    break
            if math.isfinite(P):
                finite += 1
                negatives += P < 0.0
    assert finite > 5000 and negatives == 0


# -- the Python slaves refuse the sample and change nothing ------------------------------------

def _issue_instance():
    return ready(DriftEstimator, process=harmonic.HARMONIC, P0=1e154, x0=3e8)


def test_the_issues_harmonic_filter_is_refused_at_the_sample_that_leaves_the_rule():
    """P0 = 1e154, x0 = 3e8, z = 0, steps of 0.1 s (the issue): the first step's sample 76
    leaves P22 at -3.7e137 (the output P after it would have been 2.75e106, then -3.67e106);
    the step is refused naming it, nothing changes, and a state got before restores."""
    s = _issue_instance()
    put(s, "z", 0.0)
    P = s.get_real([vr(s, "P")])[0]
    assert P >= 0.0 and not messages(s)
    saved = json.loads(json.dumps(s._get_fmu_state()))
    before = snapshot(s)
    assert s.do_step(0.0, 0.1) is False
    assert messages(s) == [
        "s: hidden state _state.P22 would be -3.7214142683935073e+137 at sample 76 (t = 0.075 "
        "s), a negative variance: %s; allowed: values whose covariances stay positive "
        "semi-definite (nothing was changed)" % CAUSE]
    assert snapshot(s) == before
    s._set_fmu_state(saved)
    assert not messages(s) and snapshot(s) == before


def test_a_sample_between_communication_points_is_checked_too():
    """P0 = 1e16, z = 0, steps of 10 Ts: sample 16, a predict-only sample inside the second step,
    leaves P22 at -0.49999999, and the step's last sample 20 is valid again, so only a check of
    every sample refuses the step (the issue's P = -0.49999999 with P0 = 1e16)."""
    s = ready(DriftEstimator, process=harmonic.HARMONIC, P0=1e16)
    assert s.do_step(0.0, 1e-2) is True and not messages(s)
    assert s.get_real([vr(s, "P")])[0] >= 0.0
    before = snapshot(s)
    assert s.do_step(1e-2, 1e-2) is False
    assert messages(s) == [
        "s: hidden state _state.P22 would be -0.49999999 at sample 16 (t = 0.015 s), a negative "
        "variance: %s; allowed: values whose covariances stay positive semi-definite (nothing "
        "was changed)" % CAUSE]
    assert snapshot(s) == before
    # models/ alone: invalid after sample 16, valid again after sample 20
    C, S = harmonic.rotation(150.0, 1e-3)
    st = harmonic.estimator_init(harmonic.HARMONIC, 0.0, 1e16)
    valid = []
    for k in range(1, 21):
        st = harmonic.estimator_step(st, 0.0, 0.0, 1.0, 0.01, 1e-4, harmonic.HARMONIC, C=C, S=S,
                                     Qh=1e-8) if k % 10 == 1 else \
            harmonic.estimator_predict(st, harmonic.HARMONIC, C=C, S=S, Qh=1e-8)
        valid.append(harmonic.valid(st))
    assert valid.index(False) == 15 and valid[-1] is True


def test_the_dual_filters_hidden_P44_is_refused():
    """P0y = 1e16, steps of 10 Ts, z = 0: the hidden P44 would be -0.49999999 after sample 16
    (the issue's DualDriftEstimator case; P11, P22 and P33 stay positive)."""
    s = ready(DualDriftEstimator, process=harmonic.HARMONIC, P0y=1e16)
    assert s.do_step(0.0, 1e-2) is True and not messages(s)
    before = snapshot(s)
    assert s.do_step(1e-2, 1e-2) is False
    assert messages(s)[-1].startswith(
        "s: hidden state _state.P44 would be -0.49999999 at sample 16 (t = 0.015 s), a "
        "negative variance: " + CAUSE), messages(s)
    assert snapshot(s) == before


def test_a_covariance_that_is_not_psd_is_refused_with_both_variances_positive():
    """The dual Gauss-Markov filter with rho = 1 and R = Ry = 1e-20 (the measurement 1e18 times
    finer than the process: beyond 53 bits) leaves the rule with Pxx, Pyy > 0."""
    s = ready(DualDriftEstimator, process=1, rho=1.0, R=1e-20, Ry=1e-20, A=0.99, P0=0.0,
              P0y=0.0, Qy=0.01, bx=0.01, by=-0.006)
    t, text = 0.0, None
    for k in range(1, 2000):
        put(s, "z_x", math.sin(k * 0.3))
        put(s, "z_y", math.cos(k * 0.2))
        if not s.do_step(t, 1e-3):
            text = messages(s)[-1]
            break
        t += 1e-3
    assert text is not None and "the covariance (Pxx, Pxy, Pyy) of hidden state _state would " \
        "be (" in text and "not positive semi-definite" in text, text


@pytest.mark.parametrize("cls, edit", [
    (DriftEstimator, lambda st: st.__setitem__(3, 2.0 * max(st[2], st[4]) + 1.0)),
    (DriftEstimator, lambda st: st.__setitem__(4, -1e-300)),
    (DualDriftEstimator, lambda st: st.__setitem__(13, -1.0)),   # P44
    (DualDriftEstimator, lambda st: st.__setitem__(10, 2.0 * max(st[4], st[7]) + 1.0))])  # P13
def test_a_restored_state_whose_covariance_is_not_valid_is_refused(cls, edit):
    s = ready(cls, process=harmonic.HARMONIC)
    s.do_step(0.0, 2e-3)
    state = json.loads(json.dumps(s._get_fmu_state()))
    edit(state["_state"])
    before = snapshot(s)
    s._set_fmu_state(state)
    text = messages(s)[-1]
    # a negative variance is refused by the check of every variance field (as in the native
    # twins), a covariance that is not PSD by the covariance rule
    assert "the state is refused and nothing was changed" in text and (
        "negative variance" in text or "not positive semi-definite" in text), text
    assert snapshot(s) == before


# -- the batch engines stop the run ------------------------------------------------------------

def test_a_batch_check_after_a_predict_only_sample():
    """harmonic.check after every sample, updates every 10th sample and predictions between (a
    step of 10 Ts in the FMU): sample 16, a prediction, leaves the rule, as in the FMU."""
    C, S = harmonic.rotation(150.0, 1e-3)
    st = harmonic.estimator_init(harmonic.HARMONIC, 0.0, 1e16)
    with pytest.raises(covariance.CovarianceError, match="P22 of the harmonic filter would be "
                       "-0.49999999 at sample 16, a negative variance"):
        for k in range(1, 30):
            if k % 10 == 1:
                st = harmonic.estimator_step(st, 0.0, 0.0, 1.0, 0.01, 1e-4, harmonic.HARMONIC,
                                             C=C, S=S, Qh=1e-8)
            else:
                st = harmonic.estimator_predict(st, harmonic.HARMONIC, C=C, S=S, Qh=1e-8)
            harmonic.check(st, k)


def test_harmonic_run_checks_every_sample():
    """harmonic.run (driftfmu identify's estimator over recordings) stops at the sample whose
    covariance leaves the rule (z = 1, a2 = 1, Qh = 0, P0 = 1e16)."""
    with pytest.raises(covariance.CovarianceError) as exc:
        harmonic.run([1.0] * 40, 0.0, 1.0, 1.0, 1e-4, x0=0.0, P0=1e16, Qh=0.0)
    assert "of the harmonic filter would be" in str(exc.value) and CAUSE in str(exc.value)
    assert "in run" not in str(exc.value)


@pytest.mark.parametrize("process, ex, es", [
    (harmonic.HARMONIC, dict(kind=excitation.SINUSOIDAL), dict(P0=1e154, x0=3e8, P0y=1e10)),
    (harmonic.GAUSS_MARKOV, dict(rho=1.0, A=0.99, Qy=0.01),
     dict(rho=1.0, A=0.99, Qy=0.01, R=1e-20, Ry=1e-20, P0=0.0, P0y=0.0, bx=0.01, by=-0.006))])
def test_the_dual_batch_stops_at_the_first_run_that_leaves_the_rule_in_numpy_and_the_kernel(
        process, ex, es):
    if kernel.library() is None:
        pytest.skip("no C compiler for the batch kernel")
    seeds = np.arange(1, 7, dtype=np.uint64)
    errors = []
    for engine in ("numpy", "c"):
        with pytest.raises(covariance.CovarianceError) as exc:
            batch.dual_simulate(1200, seeds, ex, {}, dict(es, process=process), 1e-3,
                                kernel=engine)
        errors.append(str(exc.value))
    assert errors[0] == errors[1] and " in run " in errors[0] and "(seed " in errors[0], errors
    assert "of the dual-axis filter would be" in errors[0] or "of the harmonic filter" in \
        errors[0], errors


def test_the_adxl203_chain_stops_alike_in_numpy_and_the_kernel():
    """models.adxl203.simulate (the ADXL203 experiment's reference) and its kernel port: the
    harmonic filter with P0 = 1e16 and a noiseless sensor leaves the rule at the same sample."""
    lib = kernel.library()
    if lib is None:
        pytest.skip("no C compiler for the batch kernel")
    args = (200, dict(kind=excitation.SINUSOIDAL, X=0.0), dict(noise=0, a0=1.0),
            dict(process=harmonic.HARMONIC, P0=1e16, Qh=0.0, a2=1.0), 1e-3)
    errors = []
    for run in (adxl203.simulate, lambda *a: kernel.adxl203_simulate(lib, *a)):
        with pytest.raises(covariance.CovarianceError) as exc:
            run(*args)
        errors.append(str(exc.value))
    assert errors[0] == errors[1] and CAUSE in errors[0], errors


def test_the_letters_batch_has_no_covariance_to_check():
    """The letter's chain (the scalar filter) is the same bits as before (its P >= 0 needs no
    test): the batch engine's finals equal models.chain.simulate's."""
    seeds = np.arange(1, 4, dtype=np.uint64)
    out = batch.simulate(300, seeds, kernel="numpy")
    ref = chain.simulate(300, seeds)
    assert np.array_equal(out["final_P"], ref["P"][:, -1]) and (out["final_P"] > 0).all()
