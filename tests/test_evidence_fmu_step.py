"""FMU step logic at A != 0, where an extra or a missing predict changes the result.

The three slaves (in Python, without building FMUs) are stepped with communication steps of
several samples, ``h = m Ts`` with ``m`` varying, and compared with a reference written here
from the FMI timing rule alone: the Excitation propagates every sample; the Accelerometer
measures at communication points, its output filter runs every sample with the input held; the
DriftEstimator updates at communication points and only predicts (``m - 1`` times) in between,
the drift estimators folding in one posterior per update.
"""
import math

import pytest

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.models import adxl203, chain, drift, ekf, excitation, harmonic, noise, sensor

TS = 1e-3
STEPS = (1, 3, 2, 5, 1, 4, 3, 7, 2, 2, 6, 1, 3)  # samples per communication step


def _vr(slave, name):
    return next(v.value_reference for v in slave.vars.values() if v.name == name)


def _get(slave, name):
    v = slave.vars[_vr(slave, name)]
    getter = slave.get_real if type(v).__name__ == "Real" else slave.get_integer
    return getter([v.value_reference])[0]


def _set(slave, name, value):
    v = slave.vars[_vr(slave, name)]
    setter = slave.set_real if type(v).__name__ == "Real" else slave.set_integer
    setter([v.value_reference], [value])


def _cosimulate(start, steps=STEPS):
    """Gauss-Seidel master over the three slaves; rows (k, x, z, x_hat, P, dc1, dc2, dc3)."""
    slaves = (Excitation(instance_name="e"), Accelerometer(instance_name="a"),
              DriftEstimator(instance_name="d"))
    for s, values in zip(slaves, start):
        for name, value in values.items():
            _set(s, name, value)
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        s.exit_initialization_mode()
        assert not [m.msg for m in s.log_queue], [m.msg for m in s.log_queue]
    e, a, d = slaves
    rows, k, t = [], 1, 0.0
    for m in steps + (None,):
        _set(a, "x", _get(e, "x"))
        _set(a, "y", _get(e, "y"))
        _set(d, "z", _get(a, "z"))
        rows.append((k, _get(e, "x"), _get(a, "z")) + tuple(
            _get(d, n) for n in ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3")))
        if m is None:
            break
        assert [s.do_step(t, m * TS) for s in slaves] == [True, True, True]
        k, t = k + m, t + m * TS
    return rows


def _points(steps=STEPS):
    ks = [1]
    for m in steps:
        ks.append(ks[-1] + m)
    return ks


GM = dict(a0=0.1, a1=1.0, a2=0.3, A=0.9, Q=0.05, R=1e-2)


def _gm_reference(extra_predicts=0):
    """x_k, z_k at the communication points and the estimator, written out with models.ekf."""
    ks = _points()
    n = ks[-1]
    c = chain.simulate(n, 5, **GM)  # every sample of x (and z) under seed 5
    x_post, P_post = 0.0, 0.5
    st = drift.initial_state()
    rows, prev = [], 0
    for k in ks:
        for _ in range(k - prev - 1 + (extra_predicts if prev else 0)):  # samples without z
            x_post, P_post = ekf.predict(x_post, P_post, GM["A"], GM["Q"])
        z = c["z"][k - 1]
        x_post, P_post = ekf.step(x_post, P_post, z, GM["a0"], GM["a1"], GM["a2"], GM["A"],
                                  GM["Q"], GM["R"])
        st = drift.update(st, x_post, P_post, GM["a2"])
        rows.append((k, c["x"][k - 1], z, x_post, P_post) + drift.estimates(st, GM["a2"]))
        prev = k
    return rows


def test_gauss_markov_chain_with_multi_sample_steps_equals_the_timing_rule():
    ex = dict(A=GM["A"], Q=GM["Q"], seed=5)
    acc = dict(a0=GM["a0"], a1=GM["a1"], a2=GM["a2"], R=GM["R"], seed=5)
    est = dict(GM, x0=0.0, P0=0.5)
    got = _cosimulate((ex, acc, est))
    want = _gm_reference()
    assert [r[0] for r in got] == [r[0] for r in want]
    for g, w in zip(got, want):
        assert g[1:] == pytest.approx(w[1:], rel=1e-14, abs=1e-300), g[0]
    # an extra predict per step (or one missing) changes every estimate after the first step
    for bad in (_gm_reference(extra_predicts=1), _gm_reference(extra_predicts=-1)):
        assert max(abs(b[3] - w[3]) for b, w in zip(bad[1:], want[1:])) > 1e-3
        assert max(abs(b[4] / w[4] - 1) for b, w in zip(bad[1:], want[1:])) > 1e-2


def test_harmonic_filter_with_multi_sample_steps_equals_the_timing_rule():
    f, X, phi, a2, R, Qh = 37.0, 1.2, 0.4, 0.2, 1e-3, 1e-5
    ex = dict(kind=excitation.SINUSOIDAL, X=X, f=f, phi=phi, seed=2)
    acc = dict(a2=a2, R=R, seed=2)
    est = dict(a2=a2, R=R, process=harmonic.HARMONIC, f=f, Qh=Qh, x0=0.0, P0=X * X)
    got = _cosimulate((ex, acc, est))
    C, S = math.cos(2 * math.pi * f * TS), math.sin(2 * math.pi * f * TS)
    s = (0.0, 0.0, X * X, 0.0, X * X)
    st = drift.initial_state()
    prev = 0
    for row in got:
        k = row[0]
        for _ in range(k - prev - 1):
            s = harmonic.predict(*s, C, S, Qh)
        x = X * math.sin(2 * math.pi * f * (k - 1) * TS + phi)
        z = sensor.measure(x, 0.0, 1.0, a2, R, noise.normal(2, noise.STREAM_MEASUREMENT, k))
        s = harmonic.step(*s, z, 0.0, 1.0, a2, C, S, Qh, R)
        st = drift.update(st, s[0], s[2], a2)
        assert row[1:] == pytest.approx((x, z, s[0], s[2]) + drift.estimates(st, a2),
                                        rel=1e-9, abs=1e-12), k
        prev = k


def test_accelerometer_output_filter_runs_every_sample_with_the_input_held():
    fc, Ts = 80.0, TS
    ex = dict(A=0.95, Q=0.02, seed=9)
    acc = dict(a0=0.5, a1=1.0, a2=0.05, a3=0.01, R=1e-4, fc=fc, seed=9)
    got = _cosimulate((ex, acc, {}))
    cfg = adxl203.config(a0=0.5, a1=1.0, a2=0.05, a3=0.01, R=1e-4, fc=fc, Ts=Ts)
    alpha = math.exp(-2 * math.pi * fc * Ts)
    ks = _points()
    e = None
    for j, k in enumerate(ks):
        x = got[j][1]
        v = noise.normal(9, noise.STREAM_MEASUREMENT, k)
        s = cfg.a1 * x + cfg.a2 * x * x + cfg.a3 * x ** 3 + math.sqrt(1e-4) * v
        e = s if e is None else alpha * e + (1 - alpha) * s
        assert got[j][2] == pytest.approx(0.5 + e, rel=1e-13, abs=0), k
        if j + 1 < len(ks):
            for kk in range(k + 1, ks[j + 1]):  # held input, fresh noise, every sample
                v = noise.normal(9, noise.STREAM_MEASUREMENT, kk)
                s = cfg.a1 * x + cfg.a2 * x * x + cfg.a3 * x ** 3 + math.sqrt(1e-4) * v
                e = alpha * e + (1 - alpha) * s


def test_excitation_propagates_every_sample_at_A_not_0():
    got = _cosimulate((dict(A=0.9, Q=0.05, seed=5), {}, {}))
    x = 0.0
    xs = []
    for k in range(1, _points()[-1] + 1):
        x = 0.9 * x + math.sqrt(0.05) * noise.normal(5, noise.STREAM_PROCESS, k)
        xs.append(x)
    assert [r[1] for r in got] == pytest.approx([xs[k - 1] for k in _points()], rel=1e-15, abs=0)


@pytest.mark.parametrize("estimator", [1, 2, 3])
def test_compensated_output_subtracts_the_selected_estimate(estimator):
    # z_comp = z - dc with dc the estimate of the chosen estimator (1 EKF1, 2 EKF2, 3 EKF3)
    e, a, d = (Excitation(instance_name="e"), Accelerometer(instance_name="a"),
               DriftEstimator(instance_name="d"))
    for s, values in ((e, dict(A=0.5, seed=4)), (a, dict(a2=0.2, seed=4)),
                      (d, dict(A=0.5, a2=0.2, estimator=estimator))):
        for name, value in values.items():
            _set(s, name, value)
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        s.exit_initialization_mode()
    t = 0.0
    for j, m in enumerate(STEPS):
        _set(a, "x", _get(e, "x"))
        _set(d, "z", _get(a, "z"))
        dcs = [_get(d, "dc_ekf%d" % i) for i in (1, 2, 3)]
        assert len(set(dcs)) == (2 if j == 0 else 3)  # EKF2 = EKF3 after one sample only
        assert _get(d, "dc") == dcs[estimator - 1]
        assert _get(d, "z_comp") == _get(a, "z") - dcs[estimator - 1]
        assert [s.do_step(t, m * TS) for s in (e, a, d)] == [True, True, True]
        t += m * TS
