"""Evidence for the filters from outside the code under test.

- filterpy's ``ExtendedKalmanFilter`` (a second implementation, dense matrices) with the same
  model, sample by sample, where the linearisation matters: ``A != 0`` (so the predicted state
  is not 0 and ``H = a1 + 2 a2 x-`` moves) and ``a2`` large; for the scalar filter
  (:mod:`driftfmu.models.ekf`) and for the 2-state harmonic filter (:mod:`driftfmu.models.harmonic`).
- Joseph's covariance update where it differs from the simple form ``(1 - K H) P-``: at a
  suboptimal gain (against the Monte-Carlo error variance of that gain) and at a tiny ``R``
  (where the simple form cancels to 0).
- The Riccati fixed point at ``A != 0`` (scipy's discrete algebraic Riccati solver).
- Consistency over many seeds: the normalised estimation error squared ``(x+ - x)^2 / P+``
  against its chi-square band, and the mean error against its standard error.
"""
import math

import numpy as np
import pytest
from scipy import linalg, stats

from driftfmu.models import chain, drift, ekf, harmonic, noise, sensor
from driftfmu.simulations import batch

#: A strongly nonlinear, correlated case: sd(x) = 0.51, so H = a1 + 2 a2 x- spans about 0.5..1.5.
NONLINEAR = dict(a0=0.2, a1=1.0, a2=0.5, A=0.9, Q=0.05, R=1e-2)
#: filterpy and models/ agree to this (relative) at every sample: rounding only.
TIGHT = 1e-12


def _filterpy_scalar(zs, a0, a1, a2, A, Q, R, x0, P0):
    from filterpy.kalman import ExtendedKalmanFilter
    f = ExtendedKalmanFilter(dim_x=1, dim_z=1)
    f.x = np.array([[x0]])
    f.P = np.array([[P0]])
    f.F = np.array([[A]])
    f.Q = np.array([[Q]])
    f.R = np.array([[R]])
    xs, Ps, Hs = [], [], []

    def jacobian(x):
        H = a1 + 2.0 * a2 * x[0, 0]
        Hs.append(H)
        return np.array([[H]])

    def hx(x):
        v = x[0, 0]
        return np.array([[a0 + a1 * v + a2 * v * v]])

    for z in zs:
        f.predict()
        f.update(np.array([[z]]), jacobian, hx)
        xs.append(f.x[0, 0])
        Ps.append(f.P[0, 0])
    return np.array(xs), np.array(Ps), np.array(Hs)


def test_scalar_ekf_equals_filterpy_sample_by_sample_where_the_linearisation_matters():
    n = 600
    p = NONLINEAR
    P0 = p["Q"] / (1 - p["A"] ** 2)
    r = chain.simulate(n, 3, x0=0.0, P0=P0, **p)
    xs, Ps, Hs = _filterpy_scalar(r["z"], x0=0.0, P0=P0, **p)
    # the case is one where the nonlinear part of the filter is exercised
    assert Hs.min() < 0.7 and Hs.max() > 1.3
    assert np.max(np.abs(np.array(r["x_hat"]) - xs)) <= TIGHT * np.max(np.abs(xs))
    assert np.max(np.abs(np.array(r["P"]) / Ps - 1.0)) <= TIGHT
    # and the drift estimators fed with filterpy's posterior give the same estimates
    st = drift.initial_state()
    for x, P in zip(xs, Ps):
        st = drift.update(st, x, P, p["a2"])
    for got, want in zip((r["dc_ekf1"][-1], r["dc_ekf2"][-1], r["dc_ekf3"][-1]),
                         drift.estimates(st, p["a2"])):
        assert got == pytest.approx(want, rel=TIGHT, abs=0)


def test_letters_settings_same_final_drift_estimates_as_filterpy_to_the_bit():
    # the README's benchmark claim (letter's settings, A = 0, seed 1): the same final drift
    # estimates to the bit (x+ is bit-equal there; P+ differs by rounding, ~1e-16 relative)
    p = dict(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4)
    r = chain.simulate(2000, 1, **p)
    xs, Ps, _ = _filterpy_scalar(r["z"], x0=0.0, P0=0.01, **p)
    assert np.array_equal(np.array(r["x_hat"]), xs)
    assert np.max(np.abs(np.array(r["P"]) / Ps - 1.0)) <= TIGHT
    st = drift.initial_state()
    for x, P in zip(xs, Ps):
        st = drift.update(st, x, P, p["a2"])
    assert (r["dc_ekf1"][-1], r["dc_ekf2"][-1], r["dc_ekf3"][-1]) == drift.estimates(st, p["a2"])


def test_harmonic_filter_equals_filterpy_two_state_ekf():
    from filterpy.kalman import ExtendedKalmanFilter
    a0, a1, a2, R, Qh = 0.1, 1.2, 0.25, 1e-2, 1e-4
    X, f, Ts, phi, n = 1.5, 37.0, 1e-3, 0.6, 800
    k = np.arange(1, n + 1)
    x = X * np.sin(2 * np.pi * f * (k - 1) * Ts + phi)
    zs = sensor.measure(x, a0, a1, a2, R, noise.normal(7, noise.STREAM_MEASUREMENT,
                                                        k.astype(np.uint64)))
    w = 2 * math.pi * f * Ts  # the rotation from numpy's cos and sin, not from models._ops
    kf = ExtendedKalmanFilter(dim_x=2, dim_z=1)
    kf.x = np.array([[0.0], [0.0]])
    kf.P = np.eye(2) * X * X
    kf.F = np.array([[math.cos(w), math.sin(w)], [-math.sin(w), math.cos(w)]])
    kf.Q = Qh * np.eye(2)
    kf.R = np.array([[R]])
    C, S = harmonic.rotation(f, Ts)
    st = (0.0, 0.0, X * X, 0.0, X * X)
    Hs = []
    for z in zs:
        kf.predict()
        Hs.append(a1 + 2 * a2 * kf.x[0, 0])
        kf.update(np.array([[z]]), lambda s: np.array([[a1 + 2 * a2 * s[0, 0], 0.0]]),
                  lambda s: np.array([[a0 + a1 * s[0, 0] + a2 * s[0, 0] ** 2]]))
        st = harmonic.step(*st, float(z), a0, a1, a2, C, S, Qh, R)
        want = (kf.x[0, 0], kf.x[1, 0], kf.P[0, 0], kf.P[0, 1], kf.P[1, 1])
        assert np.allclose(st, want, rtol=1e-10, atol=1e-13)
    assert min(Hs) < 0.6 and max(Hs) > 1.8  # the linearisation point moves over the sinusoid


# -- Joseph's form where it differs from the simple form ----------------------------------------

@pytest.mark.parametrize("gain_factor", [0.4, 1.7])
def test_joseph_form_is_the_error_variance_of_a_suboptimal_gain(gain_factor):
    # x ~ N(x-, P-), z = a0 + H x + v: the update x- + K (z - a0 - H x-) has error variance
    # (1 - K H)^2 P- + K^2 R for every K; estimated here from draws, independent of models/
    P_pred, H, R, a0, x_pred = 0.04, 1.3, 0.01, 0.2, 0.3
    K = gain_factor * P_pred * H / (H * H * P_pred + R)
    m = 400_000
    rng = np.random.default_rng(11)
    x = x_pred + math.sqrt(P_pred) * rng.standard_normal(m)
    z = a0 + H * x + math.sqrt(R) * rng.standard_normal(m)
    err = x_pred + K * (z - a0 - H * x_pred) - x
    mc = np.mean(err ** 2)
    tol = 5 * math.sqrt(2.0 / m)  # 5 standard errors of a Gaussian sample variance
    assert ekf.joseph(P_pred, K, H, R) == pytest.approx(mc, rel=tol, abs=0)
    assert abs((1 - K * H) * P_pred / mc - 1.0) > 10 * tol  # the simple form is far off here


def test_joseph_form_keeps_the_posterior_variance_when_R_is_tiny():
    # R << H^2 P-: exactly P+ = R P- / (H^2 P- + R), about R / H^2; the simple form cancels
    for H_at in (0.0, 0.4):
        a1, a2, P_pred, R = 1.3, 0.2, 1.0, 1e-20
        H = a1 + 2 * a2 * H_at
        _, P = ekf.update(H_at, P_pred, 0.5, 0.0, a1, a2, R)
        assert P == pytest.approx(R * P_pred / (H * H * P_pred + R), rel=1e-9, abs=0)
    # the 2x2 Joseph form of the harmonic filter: P+ = P - P H^T H P / (H P H^T + R)
    P11, P12, P22 = 1.0, 0.5, 0.8
    H = 1.3
    got = harmonic.update(0.0, 0.0, P11, P12, P22, 0.5, 0.0, H, 0.2, R)[2:]
    want = (R * P11 / (H * H * P11 + R), P12 * R / (H * H * P11 + R),
            P22 - P12 * P12 * H * H / (H * H * P11 + R))
    assert got == pytest.approx(want, rel=1e-9, abs=0)


# -- closed form at A != 0 ------------------------------------------------------------------------

@pytest.mark.parametrize("A,a1,Q,R", [(0.9, 1.0, 0.01, 1e-3), (-0.6, 2.0, 0.05, 0.1)])
def test_posterior_variance_converges_to_the_riccati_solution(A, a1, Q, R):
    # linear sensor (a2 = 0): the prior variance solves the discrete algebraic Riccati equation
    P_prior = linalg.solve_discrete_are(np.array([[A]]), np.array([[a1]]), np.array([[Q]]),
                                        np.array([[R]]))[0, 0]
    x, P = 0.0, 5.0
    for z in np.linspace(-1, 1, 300):
        x, P = ekf.step(x, P, float(z), 0.0, a1, 0.0, A, Q, R)
    assert P == pytest.approx(P_prior * R / (a1 * a1 * P_prior + R), rel=1e-12, abs=0)
    assert ekf.predict(x, P, A, Q)[1] == pytest.approx(P_prior, rel=1e-12, abs=0)


# -- consistency over many seeds ----------------------------------------------------------------

RUNS = 10_000


@pytest.mark.parametrize("case,A,a2,Q,R", [(1, 0.8, 0.05, 0.01, 1e-3), (2, -0.5, 0.02, 0.01, 1e-2),
                                           (3, 0.0, 0.01, 0.01, 1e-4), (4, 0.95, 0.1, 0.002, 1e-3)])
def test_nees_within_its_chi_square_band(case, A, a2, Q, R):
    n, ks = 200, (20, 100, 200)
    out = batch.simulate(n, batch.run_seeds(100_000 * case, RUNS), a2=a2, A=A, Q=Q, R=R,
                         record=("x", "x_hat", "P"))
    lo_q, hi_q = 0.001 / (2 * len(ks)), 1 - 0.001 / (2 * len(ks))  # 99.9 % overall
    lo, hi = stats.chi2.ppf(lo_q, RUNS) / RUNS, stats.chi2.ppf(hi_q, RUNS) / RUNS
    for k in ks:
        e = out["x_hat"][:, k - 1] - out["x"][:, k - 1]
        P = out["P"][:, k - 1]
        nees = np.mean(e * e / P)  # chi2(RUNS) / RUNS for a consistent filter
        assert lo <= nees <= hi, (k, nees, lo, hi)
        # mean error: 0 within 4.5 standard errors sqrt(mean P / RUNS), plus the EKF's
        # first-order bias (the innovation has mean a2 P-, since E[x^2] = x-^2 + P-):
        # b = K a2 P- / (1 - A (1 - K H)) at the stationary gain, H ~ a1 = 1
        P_prior = A * A * P.mean() + Q
        K = P_prior / (P_prior + R)
        bias = K * a2 * P_prior / (1 - A * (1 - K))
        assert abs(e.mean()) <= 4.5 * math.sqrt(P.mean() / RUNS) + bias, k
