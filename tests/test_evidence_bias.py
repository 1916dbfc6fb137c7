"""Evidence for the bias state of the DriftEstimator's filter from outside the code under test.

- With ``a2 = a3 = a4 = 0`` the filter over ``[x, b]`` is a linear Kalman filter: its
  steady-state covariance is scipy's discrete algebraic Riccati solution for the same model
  (random-walk and Gauss-Markov bias), and its estimates are filterpy's ``KalmanFilter``'s,
  sample by sample (with the known input ``B u``).
- With the nonlinearity on, over Monte-Carlo runs of the batch engine (``batch.estimate`` over
  outputs simulated here with NumPy's generator, fixed seeds) the normalised estimation error
  squared of ``[x, b]`` lies within its two-sided chi-square band, at several ``Qb``, ``a2`` and
  ``Ts`` (``Qb = K^2 Ts``), with random-walk and Gauss-Markov biases.
- What the filter separates: ``[x, b]`` is observable unless the bias has the state's own
  dynamics (``F_b = A``), and then the filter says so through its covariance; a constant ``b``
  and the constant ``a2 E[x^2]`` are told apart only through the model's ``a2``: the filter
  attributes ``a2 (x-^2 + P-)`` to the state, the rest to ``b`` (a first-order EKF, which
  expects ``h(x-)``, puts the whole drift of a white state into ``b``), and with ``a2`` wrong
  the split moves while the sum ``dc + b_hat`` stays the offset (docs/method.md, section 11).
"""
import math

import numpy as np
import pytest
from scipy import linalg, stats

from driftfmu.models import bias, chain
from driftfmu.simulations import batch


def _dare(A, Fb, a1, Q, Qb, R):
    """Prior and posterior steady-state covariance of [x, b] from scipy's DARE."""
    F = np.diag([A, Fb])
    H = np.array([[a1, 1.0]])
    prior = linalg.solve_discrete_are(F.T, H.T, np.diag([Q, Qb]), np.array([[R]]))
    S = (H @ prior @ H.T)[0, 0] + R
    return prior, prior - prior @ H.T @ H @ prior / S


@pytest.mark.parametrize("A,tau_b,Ts,a1,Q,Qb,R", [
    (0.0, 0.0, 1e-3, 1.0, 0.01, 1e-6, 1e-4),        # white state, random-walk bias
    (0.9, 0.0, 1e-3, 1.3, 0.02, 1e-5, 1e-3),        # correlated state
    (-0.5, 0.05, 1e-3, 0.8, 0.01, 1e-6, 1e-2),      # Gauss-Markov bias
    (0.95, 2e-3, 1e-4, 1.0, 0.001, 1e-4, 1e-4),     # a fast Gauss-Markov bias
])
def test_steady_state_covariance_is_the_riccati_solution(A, tau_b, Ts, a1, Q, Qb, R):
    Fb = bias.factor(tau_b, Ts)
    prior, post = _dare(A, Fb, a1, Q, Qb, R)
    st, b = chain.estimator_init(0.0, 1.0), bias.init(0.0, 1.0)
    for z in np.sin(np.arange(20000) * 0.37):  # (the covariance does not depend on z)
        st, b = bias.estimator_step(st, b, float(z), 0.0, a1, 0.0, A, Q, R, Fb, Qb)
    scale = 1e-12 * np.abs(prior).max()  # (a zero cross-covariance comes out as 1e-20)
    assert (st.P, b.Pxb, b.Pbb) == pytest.approx((post[0, 0], post[0, 1], post[1, 1]),
                                                 rel=1e-9, abs=scale)
    x_pred, P_pred, b_pred = bias.predict(st.x, st.P, b, A, Q, Fb, Qb)
    assert (P_pred, b_pred.Pxb, b_pred.Pbb) == pytest.approx(
        (prior[0, 0], prior[0, 1], prior[1, 1]), rel=1e-9, abs=scale)


@pytest.mark.parametrize("tau_b,B", [(0.0, 0.0), (0.02, 0.7)])
def test_estimates_equal_filterpys_kalman_filter_step_by_step(tau_b, B):
    from filterpy.kalman import KalmanFilter
    a0, a1, A, Q, R, Qb, Ts, n = 0.2, 1.1, 0.8, 0.02, 1e-3, 1e-6, 1e-3, 2000
    Fb = bias.factor(tau_b, Ts)
    rng = np.random.default_rng(4401)
    u = rng.standard_normal(n)
    x, b_true, zs = 0.0, 0.05, []
    for k in range(n):
        x = A * x + B * u[k] + math.sqrt(Q) * rng.standard_normal()
        b_true = Fb * b_true + math.sqrt(Qb) * rng.standard_normal()
        zs.append(a0 + a1 * x + b_true + math.sqrt(R) * rng.standard_normal())
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x = np.array([[0.1], [0.0]])
    kf.P = np.diag([0.05, 1e-2])
    kf.F = np.diag([A, Fb])
    kf.B = np.array([[B], [0.0]])
    kf.H = np.array([[a1, 1.0]])
    kf.Q = np.diag([Q, Qb])
    kf.R = np.array([[R]])
    st, b = chain.estimator_init(0.1, 0.05), bias.init(0.0, 1e-2)
    for k, z in enumerate(zs):
        kf.predict(u=np.array([[u[k]]]))
        kf.update(np.array([[z - a0]]))
        st, b = bias.estimator_step(st, b, z, a0, a1, 0.0, A, Q, R, Fb, Qb, B=B, u=u[k])
        assert (st.x, b.b) == pytest.approx((kf.x[0, 0], kf.x[1, 0]), rel=1e-10, abs=1e-13)
        assert (st.P, b.Pxb, b.Pbb) == pytest.approx((kf.P[0, 0], kf.P[0, 1], kf.P[1, 1]),
                                                     rel=1e-10, abs=1e-18)
    assert abs(b.b - b_true) < 4 * math.sqrt(b.Pbb)  # (and it tracks the bias)


# -- consistency over many runs ------------------------------------------------------------------

def _truth(seed, runs, n, a1, a2, A, Q, R, P0, Fb, Qb, Pb0):
    """State, bias and output of ``runs`` runs (NumPy's generator: independent of models/):
    x_0 ~ N(0, P0), b_0 ~ N(0, Pb0), as the filter's prior says."""
    rng = np.random.default_rng(seed)
    x = math.sqrt(P0) * rng.standard_normal(runs)
    b = math.sqrt(Pb0) * rng.standard_normal(runs)
    X, Bt, Z = (np.empty((runs, n)) for _ in range(3))
    for k in range(n):
        x = A * x + math.sqrt(Q) * rng.standard_normal(runs)
        b = Fb * b + math.sqrt(Qb) * rng.standard_normal(runs)
        X[:, k], Bt[:, k] = x, b
        Z[:, k] = a1 * x + a2 * x * x + b + math.sqrt(R) * rng.standard_normal(runs)
    return X, Bt, Z


RUNS = 6000
KS = (10, 100, 400)
#: (K [V/sqrt(s)], a2, Ts, A, tau_b, Q, R): Qb = K^2 Ts.
NEES_CASES = [(1e-2, 0.01, 1e-3, 0.0, 0.0, 0.01, 1e-4),
              (1e-1, 0.1, 1e-4, 0.8, 0.0, 0.01, 1e-3),
              (3e-3, 0.05, 1e-2, 0.5, 0.5, 0.02, 1e-4),
              (1e-2, 0.5, 1e-3, 0.0, 0.0, 0.05, 1e-3)]


@pytest.mark.parametrize("case", range(len(NEES_CASES)))
def test_nees_of_x_and_b_within_its_two_sided_chi_square_band(case):
    K, a2, Ts, A, tau_b, Q, R = NEES_CASES[case]
    Qb, Fb, P0, Pb0 = bias.qb_random_walk(K, Ts), bias.factor(tau_b, Ts), Q / (1 - A * A), 1e-4
    X, Bt, Z = _truth(4410 + case, RUNS, KS[-1], 1.0, a2, A, Q, R, P0, Fb, Qb, Pb0)
    out = batch.estimate(Z, a2=a2, A=A, Q=Q, R=R, P0=P0, Ts=Ts, bias=1, Qb=Qb, tau_b=tau_b,
                         Pb0=Pb0, record=("x_hat", "P", "b_hat", "P_bb", "P_xb"))
    # 99.9 % over every case and sample together (Bonferroni), both sides
    q = 0.001 / (2 * len(KS) * len(NEES_CASES))
    lo, hi = stats.chi2.ppf(q, 2 * RUNS) / RUNS, stats.chi2.ppf(1 - q, 2 * RUNS) / RUNS
    for k in KS:
        ex = out["x_hat"][:, k - 1] - X[:, k - 1]
        eb = out["b_hat"][:, k - 1] - Bt[:, k - 1]
        P, Pbb, Pxb = (out[n][:, k - 1] for n in ("P", "P_bb", "P_xb"))
        nees = np.mean((Pbb * ex * ex - 2 * Pxb * ex * eb + P * eb * eb) / (P * Pbb - Pxb * Pxb))
        assert lo <= nees <= hi, (case, k, nees, lo, hi)


# -- what the filter can and cannot separate -----------------------------------------------------

@pytest.mark.parametrize("A,Fb,H", [(0.0, 1.0, 1.0), (0.9, 1.0, 1.2), (0.5, 0.5, 1.0),
                                    (0.5, 0.9, 0.0)])
def test_x_and_b_are_observable_unless_the_bias_has_the_states_dynamics(A, Fb, H):
    # the observability matrix [H; H F] of the pair (F = diag(A, Fb), H = [H, 1])
    O = np.array([[H, 1.0], [H * A, Fb]])
    assert (np.linalg.matrix_rank(O) == 2) == (H * (Fb - A) != 0.0)


def test_with_the_states_own_dynamics_the_covariance_says_it_cannot_separate():
    # Fb = A: only a1 x + b is seen, and the bias's steady-state variance stays at half its
    # stationary variance; the slower the bias against the state, the better it is pinned down
    # (every bias here with the same stationary variance; DARE, a2 = 0)
    A, a1, Q, R, Ts = 0.9, 1.0, 0.01, 1e-4, 1e-3
    sigma2 = 0.01 / (1 - A * A)
    tau_same = -Ts / math.log(A)
    assert bias.factor(tau_same, Ts) == pytest.approx(A, rel=1e-12)
    ratios = []
    for tau_b in (tau_same, 0.1, 1.0, 10.0):
        F = bias.factor(tau_b, Ts)
        ratios.append(_dare(A, F, a1, Q, sigma2 * (1 - F * F), R)[1][1, 1] / sigma2)
    assert ratios[0] > 0.45 and ratios[-1] < 0.1, ratios
    assert ratios == sorted(ratios, reverse=True), ratios


def _first_order_filter(Z, a2, A, Q, R, P0, Pb0):
    """The textbook augmented EKF written here with dense matrices, predicting the
    measurement as h(x-) + b- (the letter's first-order EKF with a bias state)."""
    runs, n = Z.shape
    x, b = np.zeros(runs), np.zeros(runs)
    P = np.zeros((runs, 2, 2))
    P[:, 0, 0], P[:, 1, 1] = P0, Pb0
    F = np.diag([A, 1.0])
    for k in range(n):
        x = A * x
        P = F @ P @ F.T + np.diag([Q, 0.0])
        H = np.stack([1.0 + 2 * a2 * x, np.ones(runs)], axis=1)[:, None, :]
        S = (H @ P @ np.transpose(H, (0, 2, 1)))[:, 0, 0] + R
        K = (P @ np.transpose(H, (0, 2, 1)))[:, :, 0] / S[:, None]
        e = Z[:, k] - (x + a2 * x * x) - b
        x, b = x + K[:, 0] * e, b + K[:, 1] * e
        M = np.eye(2) - K[:, :, None] @ H
        P = M @ P @ np.transpose(M, (0, 2, 1)) + K[:, :, None] * K[:, None, :] * R
    return b


def test_a_constant_bias_and_the_state_dependent_drift_are_split_by_the_model():
    # a white state (A = 0): the drift a2 E[x^2] = a2 Q is a constant offset like b; the true
    # bias is 0 here
    a2, Q, R, runs, n = 0.2, 0.01, 1e-4, 2000, 2000
    X, Bt, Z = _truth(4420, runs, n, 1.0, a2, 0.0, Q, R, Q, 1.0, 0.0, 0.0)
    drift_true = a2 * Q
    common = dict(A=0.0, Q=Q, R=R, P0=Q, bias=1, Qb=0.0, Pb0=1e-4)

    def mean_and_error(values):
        return values.mean(), 4.5 * values.std() / math.sqrt(runs)

    out = batch.estimate(Z, a2=a2, **common)
    b_hat, err = mean_and_error(out["final_b_hat"])
    assert abs(b_hat) <= err < drift_true / 5          # b is not given the drift
    dc1, err1 = mean_and_error(out["final_dc_ekf1"])
    assert abs(dc1 - drift_true) <= err1               # EKF1 is
    # the textbook first-order EKF puts the whole drift of a white state into b
    first, err_f = mean_and_error(_first_order_filter(Z, a2, 0.0, Q, R, Q, 1e-4))
    assert abs(first - drift_true) <= err_f + 0.02 * drift_true
    # with a2 wrong in the filter the split follows the filter's a2, the sum does not move
    for a2_filter in (0.0, a2 / 2):
        out = batch.estimate(Z, a2=a2_filter, **common)
        b_hat, err = mean_and_error(out["final_b_hat"])
        assert abs(b_hat - (a2 - a2_filter) * Q) <= err
        total, err_t = mean_and_error(out["final_dc_ekf1"] + out["final_b_hat"])
        assert abs(total - drift_true) <= err_t
