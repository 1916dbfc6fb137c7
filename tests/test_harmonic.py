"""The harmonic process model: closed forms, the 2x2 algebra against matrices, batch = scalar."""
import math

import numpy as np
import pytest

from driftfmu.models import _ops, adxl203, chain, drift, harmonic


def test_rotation_is_cos_and_sin_of_the_step_angle():
    for f, Ts in ((150.0, 1e-3), (100.0, 1e-4), (333.3, 1e-3), (0.0, 1e-3)):
        C, S = harmonic.rotation(f, Ts)
        assert C == pytest.approx(math.cos(2 * math.pi * f * Ts), abs=1e-15)
        assert S == pytest.approx(math.sin(2 * math.pi * f * Ts), abs=1e-15)


def _matrix_step(s, P, z, a0, a1, a2, C, S, Qh, R):
    F = np.array([[C, S], [-S, C]])
    s = F @ s
    P = F @ P @ F.T + Qh * np.eye(2)
    H = np.array([[a1 + 2 * a2 * s[0], 0.0]])
    K = P @ H.T / (H @ P @ H.T + R)
    s = s + (K * (z - (a0 + a1 * s[0] + a2 * s[0] ** 2))).ravel()
    M = np.eye(2) - K @ H
    P = M @ P @ M.T + R * K @ K.T
    return s, P


def test_scalar_algebra_equals_the_matrix_form_to_1e12():
    rng = np.random.default_rng(3)
    C, S = harmonic.rotation(123.0, 1e-3)
    s, P = np.array([0.3, -0.8]), np.array([[0.5, 0.1], [0.1, 0.4]])
    x, d, p11, p12, p22 = 0.3, -0.8, 0.5, 0.1, 0.4
    for _ in range(200):
        z = rng.normal()
        s, P = _matrix_step(s, P, z, 0.1, 1.2, 0.05, C, S, 1e-4, 1e-2)
        x, d, p11, p12, p22 = harmonic.step(x, d, p11, p12, p22, z, 0.1, 1.2, 0.05, C, S,
                                            1e-4, 1e-2)
        assert np.allclose([x, d, p11, p12, p22], [s[0], s[1], P[0, 0], P[0, 1], P[1, 1]],
                           rtol=0, atol=1e-12)
        assert p11 > 0 and p22 > 0 and p11 * p22 - p12 * p12 > 0


def test_noise_free_filter_locks_onto_the_sinusoid():
    X, f, Ts, phi = 1.3, 50.0, 1e-3, 0.4
    C, S = harmonic.rotation(f, Ts)
    st = (0.0, 0.0, 2.0, 0.0, 2.0)
    for k in range(1, 2001):
        x = X * math.sin(2 * math.pi * f * (k - 1) * Ts + phi)
        st = harmonic.step(*st, x, 0.0, 1.0, 0.0, C, S, 0.0, 1e-6)
    assert st[0] == pytest.approx(x, abs=1e-5)
    assert math.hypot(st[0], st[1]) == pytest.approx(X, rel=1e-5)


@pytest.mark.parametrize("X,f,a2", [(1.0, 50.0, 0.01), (1.5, 150.0, 0.01), (0.5, 20.0, 0.05)])
def test_ekf1_lands_within_1_percent_of_a2_X2_over_2_on_a_pure_sinusoid(X, f, a2):
    n = 4000
    cols = adxl203.simulate(n, dict(kind=2, X=X, f=f, phi=0.7, seed=5),
                            dict(a2=a2, R=1e-4, seed=5),
                            dict(a2=a2, R=1e-4, process=harmonic.HARMONIC, f=f, P0=X * X),
                            1e-3)
    expected = a2 * X * X / 2
    assert cols["dc_ekf1"][-1] == pytest.approx(expected, rel=0.01)


def test_gauss_markov_process_is_the_letters_filter_bit_for_bit():
    ref = chain.simulate(300, 4)
    cols = adxl203.simulate(300, dict(seed=4), dict(seed=4), dict(P0=0.01), 1e-3)
    for c in ("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"):
        assert cols[c] == ref[c], c


def test_batch_equals_single_runs_bit_for_bit():
    seeds = np.array([1, 2, 3], dtype=np.uint64)
    phis = np.array([0.0, 1.0, 2.0])
    ex = dict(kind=2, X=1.5, f=100.0, Xy=0.075, phiy=0.3)
    es = dict(a0=2.5, a2=0.01, R=2e-5, process=harmonic.HARMONIC, f=100.0, P0=2.89)
    b = adxl203.simulate(500, dict(ex, seed=seeds, phi=phis), dict(adxl203.ADXL203, seed=seeds),
                         es, 1e-4)
    for i in range(3):
        s = adxl203.simulate(500, dict(ex, seed=int(seeds[i]), phi=float(phis[i])),
                             dict(adxl203.ADXL203, seed=int(seeds[i])), es, 1e-4)
        for c in s:
            assert np.array_equal(b[c][i], np.array(s[c])), c


def test_predict_only_keeps_the_drift_and_rotates_the_state():
    st = harmonic.HarmonicState(1.0, 0.0, 0.1, 0.0, 0.1, drift.initial_state())
    C, S = harmonic.rotation(250.0, 1e-3)  # a quarter turn per sample
    nxt = harmonic.estimator_predict(st, process=harmonic.HARMONIC, C=C, S=S, Qh=0.0)
    assert nxt.x == pytest.approx(0.0, abs=1e-15) and nxt.d == pytest.approx(-1.0)
    assert nxt.drift == st.drift


def test_state_round_trips_through_its_json_form():
    from driftfmu.fmu_src.slave_base import _plain
    for st in (harmonic.estimator_init(1, 0.2, 0.5), harmonic.estimator_init(2, 0.2, 0.5)):
        assert harmonic.from_plain(_plain(st)) == st


def test_unknown_process_is_refused_with_the_allowed_values():
    with pytest.raises(ValueError, match="allowed: 1 Gauss-Markov, 2 harmonic"):
        harmonic.estimator_init(3, 0.0, 1.0)


def test_ops_where_used_by_quantiser_is_elementwise():
    assert _ops.where(np.array([True, False]), 1.0, 2.0).tolist() == [1.0, 2.0]
