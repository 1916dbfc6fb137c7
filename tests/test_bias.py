"""The bias state of the DriftEstimator's filter (models/bias.py) and the class-2 offset
(models/errors.py ``class2_offset``), against computations written here independently: dense
matrices with NumPy, Gauss-Hermite quadrature of the Gaussian prior, ``math.sin`` and
``math.exp``.
"""
import math
import random

import numpy as np
import pytest

from driftfmu.models import bias, chain, covariance, drift, errors, sensor
from driftfmu.simulations import batch
from driftfmu.simulations.errors import UsageError

#: NumPy's dense computation and the written-out scalars agree to this (relative): rounding.
TIGHT = 1e-12


def _dense_update(x, P, b, Pxb, Pbb, z, a0, a1, a2, R, a3=0.0, a4=0.0):
    """The update of models.bias written as matrices, with E[h] and the quadratic term's
    variance from 40-point Gauss-Hermite quadrature of N(x, P)."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(40)
    weights = weights / weights.sum()
    xs = x + math.sqrt(P) * nodes
    hs = a0 + a1 * xs + a2 * xs ** 2 + a3 * xs ** 3 + a4 * xs ** 4
    mean_h = float(weights @ hs)
    var_quadratic = float(weights @ (a2 * (xs - x) ** 2) ** 2) - (a2 * P) ** 2
    H = np.array([[a1 + 2 * a2 * x + 3 * a3 * x * x + 4 * a4 * x ** 3, 1.0]])
    Pm = np.array([[P, Pxb], [Pxb, Pbb]])
    Rp = R + var_quadratic
    S = (H @ Pm @ H.T)[0, 0] + Rp
    K = Pm @ H.T / S
    s = np.array([[x], [b]]) + K * (z - mean_h - b)
    M = np.eye(2) - K @ H
    Pp = M @ Pm @ M.T + K @ K.T * Rp
    return s[0, 0], s[1, 0], Pp


@pytest.mark.parametrize("a3,a4", [(0.0, 0.0), (0.02, -0.03)])
def test_update_equals_the_dense_gaussian_update(a3, a4):
    rng = random.Random(4301)
    for _ in range(300):
        x, P = rng.uniform(-1, 1), 10.0 ** rng.uniform(-4, -0.5)
        b, Pbb = rng.uniform(-0.1, 0.1), 10.0 ** rng.uniform(-6, -2)
        Pxb = rng.uniform(-0.9, 0.9) * math.sqrt(P * Pbb)
        z, R = rng.uniform(-1, 1), 10.0 ** rng.uniform(-5, -1)
        a0, a1, a2 = rng.uniform(-0.5, 0.5), rng.uniform(0.5, 2), rng.uniform(-0.5, 0.5)
        xp, Pp, bp = bias.update(x, P, bias.Bias(b, Pxb, Pbb), z, a0, a1, a2, R, a3, a4)
        want_x, want_b, want_P = _dense_update(x, P, b, Pxb, Pbb, z, a0, a1, a2, R, a3, a4)
        assert xp == pytest.approx(want_x, rel=1e-10, abs=1e-14)
        assert bp.b == pytest.approx(want_b, rel=1e-10, abs=1e-14)
        assert (Pp, bp.Pxb, bp.Pbb) == pytest.approx(
            (want_P[0, 0], want_P[0, 1], want_P[1, 1]), rel=1e-9, abs=1e-16)
        assert want_P[0, 1] == pytest.approx(want_P[1, 0], rel=1e-12)


def test_predict_is_F_P_F_transposed_plus_the_noises():
    rng = random.Random(4302)
    for _ in range(200):
        A, Fb = rng.uniform(-0.99, 0.99), rng.uniform(0.5, 1.0)
        Q, Qb, B, u = 10.0 ** rng.uniform(-4, 0), 10.0 ** rng.uniform(-12, -4), \
            rng.uniform(-1, 1), rng.uniform(-1, 1)
        x, b, P, Pbb = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0, 1), \
            rng.uniform(0, 1e-2)
        Pxb = rng.uniform(-0.9, 0.9) * math.sqrt(P * Pbb)
        xp, Pp, bp = bias.predict(x, P, bias.Bias(b, Pxb, Pbb), A, Q, Fb, Qb, B, u)
        F = np.diag([A, Fb])
        want = F @ np.array([[P, Pxb], [Pxb, Pbb]]) @ F.T + np.diag([Q, Qb])
        assert (xp, bp.b) == pytest.approx((A * x + B * u, Fb * b), rel=TIGHT)
        assert (Pp, bp.Pxb, bp.Pbb) == pytest.approx((want[0, 0], want[0, 1], want[1, 1]),
                                                     rel=TIGHT, abs=1e-300)


def test_expected_h_is_the_mean_of_h_under_the_gaussian_prior():
    nodes, weights = np.polynomial.hermite_e.hermegauss(30)
    weights = weights / weights.sum()
    for x, P, coeffs in ((0.3, 0.02, (0.1, 1.1, 0.4, 0.0, 0.0)),
                         (-0.7, 0.5, (0.0, 0.9, -0.2, 0.05, 0.03))):
        xs = x + math.sqrt(P) * nodes
        want = float(weights @ sensor.h(xs, *coeffs))
        assert bias.expected(x, P, *coeffs) == pytest.approx(want, rel=1e-13)
    # and not the letter's h(x-): they differ by a2 P (the mean of the quadratic term)
    assert bias.expected(0.0, 0.01, 0.0, 1.0, 0.01) - sensor.h(0.0, 0.0, 1.0, 0.01) == \
        pytest.approx(1e-4, rel=1e-12)
    assert bias.spread(1e-4, 0.5, 0.1) == pytest.approx(1e-4 + 2 * 0.25 * 0.01, rel=1e-15)


def test_factor_is_exp_of_minus_Ts_over_tau_and_1_for_a_random_walk():
    assert bias.factor(0.0, 1e-3) == 1.0
    for tau, Ts in ((1.0, 1e-3), (0.01, 1e-3), (3e-4, 1e-3), (1e5, 1e-4)):
        assert bias.factor(tau, Ts) == pytest.approx(math.exp(-Ts / tau), rel=4e-16)
    taus = np.array([0.0, 1.0, 0.01, 3e-4, 1e5])
    got = bias.factor(taus, 1e-3)
    assert got.tobytes() == np.array([bias.factor(float(t), 1e-3) for t in taus]).tobytes()


def test_class2_is_the_sensors_output_at_x_0_by_hand():
    a1, a2, a3, a4, T0 = 1.2, 0.03, 0.01, -0.02, 298.15
    for theta, T, kb, ks in ((0.4, 310.0, 2e-3, 5e-4), (-1.1, 280.0, -1e-3, 0.0),
                             (0.0, 330.0, 1e-3, 1e-3), (0.7, T0, 0.0, 0.0)):
        dT = T - T0
        g = (1 + ks * dT) * math.sin(theta)  # the sensed acceleration at x = 0
        want = kb * dT + a1 * g + a2 * g ** 2 + a3 * g ** 3 + a4 * g ** 4
        got = errors.class2_offset(theta, T, a1, a2, T0, kb, ks, a3, a4)
        assert got == pytest.approx(want, rel=1e-14, abs=1e-16)
    assert errors.class2_offset(0.0, 350.0, a1, a2, T0, 0.0, 0.0) == 0.0
    assert errors.tilt(0.0, math.pi / 6) == pytest.approx(0.5, rel=1e-15)
    thetas = np.linspace(-3, 3, 41)
    assert errors.class2_offset(thetas, 300.0, a1, a2, T0, 1e-3, 2e-4).tobytes() == np.array(
        [errors.class2_offset(float(t), 300.0, a1, a2, T0, 1e-3, 2e-4) for t in thetas]).tobytes()


def test_floats_and_arrays_give_the_same_bits():
    rng = np.random.default_rng(4303)
    runs, n = 16, 300
    zs = 0.05 + 0.1 * rng.standard_normal((runs, n))
    args = dict(a0=0.01, a1=1.1, a2=0.2, A=0.7, Q=0.02, R=1e-3, Fb=bias.factor(0.3, 1e-3),
                Qb=1e-7, a3=0.01, a4=0.02, B=0.4)
    us = rng.standard_normal(n)
    est = chain.estimator_init(np.zeros(runs), np.full(runs, 0.05))
    b = bias.init(np.zeros(runs), np.full(runs, 1e-3))
    one = [(chain.estimator_init(0.0, 0.05), bias.init(0.0, 1e-3)) for _ in range(runs)]
    for k in range(n):
        if k % 5 == 4:  # a predict-only sample now and then
            est, b = bias.estimator_predict(est, b, args["A"], args["Q"], args["Fb"],
                                            args["Qb"], args["B"], us[k])
            one = [bias.estimator_predict(e, bb, args["A"], args["Q"], args["Fb"], args["Qb"],
                                          args["B"], float(us[k])) for e, bb in one]
        else:
            est, b = bias.estimator_step(est, b, zs[:, k], u=us[k], **args)
            one = [bias.estimator_step(e, bb, float(zs[r, k]), u=float(us[k]), **args)
                   for r, (e, bb) in enumerate(one)]
    for r, (e, bb) in enumerate(one):
        assert (e.x, e.P, bb.b, bb.Pxb, bb.Pbb) == (est.x[r], est.P[r], b.b[r], b.Pxb[r],
                                                    b.Pbb[r])
        assert tuple(e.drift) == tuple(v[r] if np.ndim(v) else v for v in est.drift)


def test_compensate_removes_the_drift_and_the_bias():
    assert bias.compensate(1.0, 0.25, 0.125) == 0.625
    assert bias.compensate(1.0, 0.25, 0.0) == chain.compensate(1.0, 0.25)


def test_the_covariance_check_names_the_bias_filters_entries():
    state = chain.estimator_init(0.0, 1.0)
    bias.check(state, bias.Bias(0.0, 0.999, 1.0), 3)
    with pytest.raises(covariance.CovarianceError, match=r"the covariance \(P, P_xb, P_bb\) "
                       r"of the bias filter would be \(1.0, 1.5, 1.0\) at sample 7"):
        bias.check(state, bias.Bias(0.0, 1.5, 1.0), 7)
    with pytest.raises(covariance.CovarianceError, match="P_bb of the bias filter would be -1"):
        bias.check(state, bias.Bias(0.0, 0.0, -1.0), 2)


# -- guidance: Qb of a random walk and of a Gauss-Markov bias ------------------------------------

def test_qb_of_a_random_walk_gives_its_variance_K2_t():
    # a random walk of K V/sqrt(s) sampled every Ts, increments N(0, Qb): variance K^2 t at t
    K, Ts, n, runs = 3e-4, 1e-3, 2000, 4000
    Qb = bias.qb_random_walk(K, Ts)
    assert Qb == K * K * Ts
    rng = np.random.default_rng(4304)
    walk = np.cumsum(math.sqrt(Qb) * rng.standard_normal((runs, n)), axis=1)
    for k in (100, 2000):
        var = walk[:, k - 1].var()
        want = K * K * (k * Ts)
        assert abs(var / want - 1) <= 4 * math.sqrt(2 / runs), (k, var, want)


def test_qb_of_a_gauss_markov_bias_keeps_its_stationary_variance():
    for sigma, tau, Ts in ((1e-3, 0.5, 1e-3), (2e-2, 1e-3, 1e-4), (5e-4, 10.0, 1e-2)):
        Qb = bias.qb_gauss_markov(sigma, tau, Ts)
        F = bias.factor(tau, Ts)
        assert Qb / (1 - F * F) == pytest.approx(sigma * sigma, rel=1e-9)
    assert bias.qb_gauss_markov(1e-3, 0.0, 1e-3) == 0.0  # a random walk has no stationary one


def test_steady_variance_is_the_limit_of_the_filter_for_a_white_state():
    # A = 0, a2 = 0: the bias is filtered through the noise r = a1^2 Q + R
    a1, Q, R = 1.3, 0.01, 1e-4
    for Qb in (1e-8, 1e-6, 1e-4):  # (time constants sqrt(r / Qb): 1300, 130, 13 samples)
        st, b = chain.estimator_init(0.0, Q), bias.init(0.0, 1.0)
        for _ in range(20000):
            st, b = bias.estimator_step(st, b, 0.0, 0.0, a1, 0.0, 0.0, Q, R, 1.0, Qb)
        assert b.Pbb == pytest.approx(bias.steady_variance(Qb, a1 * a1 * Q + R), rel=1e-6)


# -- batch.estimate: the estimator over recordings ------------------------------------------------

def test_estimate_over_recordings_equals_the_models_run_by_run():
    rng = np.random.default_rng(4305)
    zs = 0.02 + 0.1 * rng.standard_normal((5, 120))
    kw = dict(a0=0.0, a1=1.0, a2=0.05, A=0.5, Q=0.01, R=1e-4, bias=1, Qb=1e-8, tau_b=0.2,
              b0=0.01, Pb0=1e-3)
    out = batch.estimate(zs, record=("b_hat", "x_hat"), **kw)
    Fb = bias.factor(0.2, 1e-3)
    for r in range(5):
        st, b = chain.estimator_init(0.0, 0.01 / 0.75), bias.init(0.01, 1e-3)
        for k in range(120):
            st, b = bias.estimator_step(st, b, float(zs[r, k]), 0.0, 1.0, 0.05, 0.5, 0.01, 1e-4,
                                        Fb, 1e-8)
            assert out["b_hat"][r, k] == b.b and out["x_hat"][r, k] == st.x
        dcs = drift.estimates(st.drift, 0.05)
        assert (out["final_P_bb"][r], out["final_P_xb"][r], out["final_dc_ekf1"][r]) == \
            (b.Pbb, b.Pxb, dcs[0])
    plain = batch.estimate(zs, **dict(kw, bias=0))
    assert "final_b_hat" not in plain
    st = chain.estimator_init(0.0, 0.01 / 0.75)
    for k in range(120):
        st = chain.estimator_step(st, float(zs[0, k]), 0.0, 1.0, 0.05, 0.5, 0.01, 1e-4)
    assert plain["final_x_hat"][0] == st.x


@pytest.mark.parametrize("bias_on", [0, 1])
def test_estimate_of_the_general_sensor_equals_the_models_run_by_run(bias_on):
    """a3 and a4 reach the filter (each changes its output), with the bias state and without."""
    rng = np.random.default_rng(4306)
    zs = 0.02 + 0.3 * rng.standard_normal((3, 80))
    kw = dict(a0=0.01, a1=1.1, a2=0.05, A=0.5, Q=0.04, R=1e-4, a3=0.02, a4=0.03, bias=bias_on,
              Qb=1e-8, tau_b=0.2, b0=0.01, Pb0=1e-3)
    out = batch.estimate(zs, record=("x_hat",), **kw)
    Fb = bias.factor(0.2, 1e-3)
    for r in range(3):
        st, b = chain.estimator_init(0.0, 0.04 / 0.75), bias.init(0.01, 1e-3)
        for k in range(80):
            z = float(zs[r, k])
            if bias_on:
                st, b = bias.estimator_step(st, b, z, 0.01, 1.1, 0.05, 0.5, 0.04, 1e-4, Fb,
                                            1e-8, 0.02, 0.03)
            else:
                st = chain.estimator_step(st, z, 0.01, 1.1, 0.05, 0.5, 0.04, 1e-4, 0.02, 0.03)
            assert out["x_hat"][r, k] == st.x
    for name in ("a3", "a4"):  # (each term changes the estimate: the check above can fail)
        other = batch.estimate(zs, **dict(kw, **{name: 0.0}))
        assert np.all(other["final_x_hat"] != out["final_x_hat"])


@pytest.mark.parametrize("kw,text", [
    (dict(Qb=-1e-9), "Qb = -1e-09 is out of range; allowed: Qb >= 0"),
    (dict(Pb0=-1.0), "Pb0 = -1.0 is out of range; allowed: Pb0 >= 0"),
    (dict(tau_b=-0.1), "tau_b = -0.1 is out of range; allowed: tau_b >= 0"),
    (dict(bias=2), "bias = 2 is out of range; allowed: an integer bias >= 0 and bias <= 1"),
    (dict(record=("b_hat",), bias=0), "cannot record ['b_hat']"),
])
def test_estimate_refuses_bad_values_in_one_line(kw, text):
    with pytest.raises(UsageError) as info:
        batch.estimate(np.zeros((2, 3)), **dict(dict(bias=1), **kw))
    assert text in str(info.value) and "\n" not in str(info.value)


#: Values past double precision: the covariance of [x, b] leaves the PSD cone at sample 2
#: (a "variance" P_bb of -5.1e106; exactly it stays >= 0).
PAST_PRECISION = dict(P0=1e124, Pb0=1e146, Q=2e8, Qb=2e24, a1=1.0, A=-0.84, R=1e-200, a2=0.0)


def test_estimate_stops_where_the_covariance_is_not_valid():
    zs = np.zeros((3, 4))
    with pytest.raises(covariance.CovarianceError, match=r"^P_bb of the bias filter would be "
                       r"-5.10552735385615\de\+106 at sample 2 in run 0, a negative variance"):
        batch.estimate(zs, bias=1, **PAST_PRECISION)
    batch.estimate(zs[:, :1], bias=1, **PAST_PRECISION)  # (sample 1 is still valid)
