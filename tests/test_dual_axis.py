"""Drift from axis cross-correlation (issue 11): the dual-axis model, its FMUs and the experiment.

From strongest to weakest: closed forms (noise-free sinusoids), the written-out algebra against
the matrix form of the joint EKF, bit equality with the single-axis filters for b = 0, FMUs
against models/ bit for bit, and the experiment's seeded Monte-Carlo bands.
"""
import csv
import json
import math

import numpy as np
import pytest

from driftfmu.models import chain, drift, dualaxis, excitation, harmonic, sensor
from driftfmu.simulations import dual_axis
from driftfmu.simulations.cli import main
from driftfmu.simulations.cosim import CoSimulationError, Instance, cosimulate

AX = dualaxis.Axis(0.1, 1.2, 0.05, 0.03, 1e-2)
AY = dualaxis.Axis(-0.2, 0.9, 0.02, -0.04, 2e-2)


# -- the model ----------------------------------------------------------------------------------

def _h(s):
    return np.array([AX.a0 + AX.a1 * s[0] + AX.a2 * s[0] ** 2 + AX.b * s[0] * s[1],
                     AY.a0 + AY.a1 * s[1] + AY.a2 * s[1] ** 2 + AY.b * s[0] * s[1]])


def _H(s):
    return np.array([[AX.a1 + 2 * AX.a2 * s[0] + AX.b * s[1], AX.b * s[0]],
                     [AY.b * s[1], AY.a1 + 2 * AY.a2 * s[1] + AY.b * s[0]]])


def _joint_update(s, P, z, H, hs):
    """The textbook joint EKF update with the 2 x n Jacobian, 2 x 2 inverse and Joseph form."""
    Rm = np.diag([AX.R, AY.R])
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + Rm)
    M = np.eye(len(s)) - K @ H
    return s + K @ (z - hs), M @ P @ M.T + K @ Rm @ K.T


def test_gauss_markov_filter_equals_the_matrix_form_of_the_joint_ekf():
    rng = np.random.default_rng(1)
    A, Q, Qy, rho = 0.7, 0.02, 0.03, 0.5
    m = dualaxis.model(dualaxis.GAUSS_MARKOV, A=A, Q=Q, Qy=Qy, rho=rho)
    Qm = np.array([[Q, rho * math.sqrt(Q * Qy)], [rho * math.sqrt(Q * Qy), Qy]])
    s, P = np.array([0.1, -0.2]), np.array([[0.3, 0.05], [0.05, 0.2]])
    st = dualaxis.DualState(0.1, -0.2, 0.3, 0.05, 0.2, dualaxis.drift_init())
    for _ in range(300):
        z = rng.normal(size=2)
        s, P = A * s, A * A * P + Qm
        s, P = _joint_update(s, P, z, _H(s), _h(s))
        st = dualaxis.estimator_step(st, z[0], z[1], AX, AY, m)
        assert np.allclose([st.x, st.y, st.Pxx, st.Pxy, st.Pyy],
                           [s[0], s[1], P[0, 0], P[0, 1], P[1, 1]], rtol=0, atol=1e-12)
        assert st.Pxx > 0 and st.Pyy > 0 and st.Pxx * st.Pyy - st.Pxy ** 2 > 0


def test_harmonic_filter_equals_the_matrix_form_of_the_joint_ekf():
    rng = np.random.default_rng(2)
    Qh = 1e-4
    C, S = harmonic.rotation(123.0, 1e-3)
    m = dualaxis.model(dualaxis.HARMONIC, f=123.0, Ts=1e-3, Qh=Qh)
    F = np.kron(np.eye(2), np.array([[C, S], [-S, C]]))
    s = np.array([0.3, -0.8, 0.2, 0.5])
    P = np.diag([0.5, 0.4, 0.3, 0.6])
    P[0, 1] = P[1, 0] = 0.1
    P[0, 2] = P[2, 0] = 0.05
    P[1, 3] = P[3, 1] = -0.02
    st = dualaxis.DualHarmonicState(*s, P[0, 0], P[0, 1], P[1, 1], P[2, 2], P[2, 3], P[3, 3],
                                    P[0, 2], P[0, 3], P[1, 2], P[1, 3], dualaxis.drift_init())
    for _ in range(300):
        z = rng.normal(size=2)
        s, P = F @ s, F @ P @ F.T + Qh * np.eye(4)
        H = np.zeros((2, 4))
        H[:, [0, 2]] = _H(s[[0, 2]])
        s, P = _joint_update(s, P, z, H, _h(s[[0, 2]]))
        st = dualaxis.estimator_step(st, z[0], z[1], AX, AY, m)
        got = [st.x, st.dx, st.y, st.dy, st.P11, st.P12, st.P22, st.P33, st.P34, st.P44,
               st.P13, st.P14, st.P23, st.P24]
        want = [*s, P[0, 0], P[0, 1], P[1, 1], P[2, 2], P[2, 3], P[3, 3], P[0, 2], P[0, 3],
                P[1, 2], P[1, 3]]
        assert np.allclose(got, want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("process", [dualaxis.GAUSS_MARKOV, dualaxis.HARMONIC])
def test_b_zero_is_the_single_axis_filter_on_each_axis_bit_for_bit(process):
    rng = np.random.default_rng(process)
    ax, ay = AX._replace(b=0.0), AY._replace(b=0.0)
    m = dualaxis.model(process, A=0.5, Q=0.01, Qy=0.02, rho=0.0, f=123.0, Ts=1e-3, Qh=1e-6)
    st = dualaxis.estimator_init(process, 0.1, -0.2, 0.3, 0.2)
    C, S = harmonic.rotation(123.0, 1e-3)
    mx = dict(process=process, A=0.5, Q=0.01, C=C, S=S, Qh=1e-6)
    my = dict(mx, Q=0.02)
    sx = harmonic.estimator_init(process, 0.1, 0.3)
    sy = harmonic.estimator_init(process, -0.2, 0.2)
    for k in range(500):
        z = 0.3 * rng.normal(size=2)
        if k % 7 == 3:  # samples without a measurement, too
            st = dualaxis.estimator_predict(st, m)
            sx, sy = harmonic.estimator_predict(sx, **mx), harmonic.estimator_predict(sy, **my)
            continue
        st = dualaxis.estimator_step(st, z[0], z[1], ax, ay, m)
        sx = harmonic.estimator_step(sx, z[0], AX.a0, AX.a1, AX.a2, AX.R, **mx)
        sy = harmonic.estimator_step(sy, z[1], AY.a0, AY.a1, AY.a2, AY.R, **my)
        xh, yh, Pxx, Pxy, Pyy = dualaxis.moments(st)
        dx, dy = dualaxis.estimates(st.drift, ax, ay)
        assert (xh, Pxx, dx) == (sx.x, sx.P, drift.estimates(sx.drift, AX.a2))
        assert (yh, Pyy, dy) == (sy.x, sy.P, drift.estimates(sy.drift, AY.a2))
        assert Pxy == 0.0


def test_b_zero_sensor_and_one_noise_axis_are_the_letters_sensor_bit_for_bit():
    x, y, v = np.linspace(-2, 2, 101), np.linspace(1, -1.5, 101), np.linspace(-3, 3, 101)
    got = sensor.measure_bilinear(x, y, 0.1, 1.2, 0.05, 0.0, 1e-3, v)
    assert np.array_equal(got, sensor.measure(x, 0.1, 1.2, 0.05, 1e-3, v))
    assert float(got[7]) == sensor.measure(float(x[7]), 0.1, 1.2, 0.05, 1e-3, float(v[7]))


def test_gaussian_pair_keeps_x_and_has_the_correlation_rho():
    n, rho, Q, Qy, A = 20000, -0.6, 0.01, 0.04, 0.5
    x = y = 0.0
    xs, ys, x1 = [], [], 0.0
    for k in range(1, n + 1):
        x, y = excitation.gaussian_pair(x, y, A, Q, Qy, rho, 9, k)
        x1 = excitation.gaussian_sample(x1, A, Q, 9, k)
        assert x == x1
        xs.append(x)
        ys.append(y)
    assert excitation.gaussian_pair(0.3, 0.0, A, Q, 0.0, rho, 9, 1)[1] == 0.0
    xs, ys = np.array(xs), np.array(ys)
    sxy = rho * math.sqrt(Q * Qy) / (1 - A * A)
    assert sxy == dualaxis.cross_moment(excitation.GAUSSIAN, Q=Q, Qy=Qy, rho=rho, A=A)
    # the correlation of the AR(1) pair is rho; its estimate has sd ~ (1 - rho^2) sqrt(
    # (1 + A^2) / (1 - A^2) / n) (Bartlett); 4 sd
    r = np.corrcoef(xs, ys)[0, 1]
    assert abs(r - rho) < 4 * (1 - rho * rho) * math.sqrt((1 + A * A) / (1 - A * A) / n)


@pytest.mark.parametrize("dphi", dual_axis.sweep_values("dphi", dual_axis.POINTS))
def test_noise_free_dual_ekf1_within_1_percent_of_the_closed_form(dphi):
    s = dual_axis.DEFAULTS
    ex, sp, es = dual_axis.start_values("dphi", dphi, s)
    r = dualaxis.simulate(s["n"], dict(ex, seed=5), dict(sp, seed=5, noise=0), es, s["Ts"],
                          record=())
    X, Y = s["X"], s["Xy"]
    want_x = s["a2"] * X * X / 2 + s["bx"] * X * Y * math.cos(dphi) / 2
    want_y = s["a2y"] * Y * Y / 2 + s["by"] * X * Y * math.cos(dphi) / 2
    assert r["final_dc_ekf1_x"] == pytest.approx(want_x, rel=0.01)
    assert r["final_dc_ekf1_y"] == pytest.approx(want_y, rel=0.01)
    # the single-axis EKF1 is off by the cross term b X Y cos(dphi) / 2 (to 1 % of the scale)
    scale_x = abs(s["a2"]) * X * X / 2 + abs(s["bx"]) * X * Y / 2
    assert abs(r["final_single_dc_ekf1_x"] - s["a2"] * X * X / 2) < 0.01 * scale_x


def test_batch_equals_single_runs_bit_for_bit():
    s = dual_axis.DEFAULTS
    ex, sp, es = dual_axis.start_values("rho", 0.6, s)
    seeds = np.array([3, 11, 12], dtype=np.uint64)
    many = dualaxis.simulate(80, dict(ex, seed=seeds), dict(sp, seed=seeds), es, s["Ts"])
    for r, sd in enumerate(seeds):
        one = dualaxis.simulate(80, dict(ex, seed=int(sd)), dict(sp, seed=int(sd)), es, s["Ts"])
        for c in dualaxis.COLUMNS:
            assert list(many[c][r]) == one[c], c


def test_state_round_trips_through_its_json_form():
    for process in (dualaxis.GAUSS_MARKOV, dualaxis.HARMONIC):
        st = dualaxis.estimator_step(dualaxis.estimator_init(process, 0.1, 0.2, 0.3, 0.4), 0.5,
                                     -0.1, AX, AY, dualaxis.model(process, Q=0.1, Qy=0.1))
        plain = json.loads(json.dumps(st))
        assert dualaxis.from_plain(plain) == st


def test_dual_sensor_refuses_the_adxl203_extras():
    assert dualaxis.sensor_problems(dict(dual=0, fc=100.0)) == []
    msg = dualaxis.sensor_problems(dict(dual=1, fc=100.0, bits=12))[0]
    assert "not allowed with fc = 100.0, bits = 12" in msg
    assert "allowed: dual = 1 with a3 = cross" in msg


# -- the FMUs -----------------------------------------------------------------------------------

ALL = {"Excitation": "Excitation", "Accelerometer": "Accelerometer",
       "DualDriftEstimator": "DualDriftEstimator", "SingleX": "DriftEstimator",
       "SingleY": "DriftEstimator"}
SINGLE_OUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")
DUAL_OF = {"x": ("x_hat", "P_xx", "dc_ekf1_x", "dc_ekf2_x", "dc_ekf3_x", "z_comp_x"),
           "y": ("y_hat", "P_yy", "dc_ekf1_y", "dc_ekf2_y", "dc_ekf3_y", "z_comp_y")}


def _chain_start(sweep, value, b, seed=4):
    s = dict(dual_axis.DEFAULTS, bx=b, by=-b)
    ex, sp, es = dual_axis.start_values(sweep, value, s)
    full = dualaxis.estimator_values(**es)
    return {"Excitation": dict(ex, seed=seed), "Accelerometer": dict(sp, seed=seed),
            "DualDriftEstimator": es, "SingleX": dualaxis.single_values(full, 1),
            "SingleY": dualaxis.single_values(full, 2)}


@pytest.mark.integration
@pytest.mark.parametrize("sweep,value", [("dphi", 0.7), ("rho", 0.0)])
def test_b_zero_dual_fmu_equals_the_single_axis_fmus_bit_for_bit(built_fmus, sweep, value):
    paths = {i: built_fmus[f] for i, f in ALL.items()}
    record = {"DualDriftEstimator": DUAL_OF["x"] + DUAL_OF["y"], "SingleX": SINGLE_OUTS,
              "SingleY": SINGLE_OUTS}
    raw = cosimulate(paths, dual_axis.CONNECTIONS, 300, 1e-3,
                     start_values=_chain_start(sweep, value, 0.0), record=record)
    for axis, single in (("x", "SingleX"), ("y", "SingleY")):
        for d, o in zip(DUAL_OF[axis], SINGLE_OUTS):
            assert raw["DualDriftEstimator." + d] == raw["%s.%s" % (single, o)], d


@pytest.mark.integration
def test_dual_chain_with_y_off_is_todays_chain_bit_for_bit(built_fmus):
    """Qy = 0, dual = 1, bx = 0: the letter's Gaussian chain (models.chain.simulate), unchanged."""
    paths = {i: built_fmus[f] for i, f in ALL.items() if i != "SingleY"}
    start = {"Excitation": dict(seed=1), "Accelerometer": dict(seed=1, dual=1),
             "DualDriftEstimator": dict(Qy=0.01), "SingleX": {}}
    raw = cosimulate(paths, dual_axis.CONNECTIONS[:5], 200, 1e-3, start_values=start,
                     record={"Excitation": ["x", "y"], "Accelerometer": ["z"],
                             "DualDriftEstimator": list(DUAL_OF["x"])})
    ref = chain.simulate(200, 1)
    assert raw["Excitation.x"] == ref["x"] and raw["Accelerometer.z"] == ref["z"]
    assert set(raw["Excitation.y"]) == {0.0}
    for d, o in zip(DUAL_OF["x"], SINGLE_OUTS):
        assert raw["DualDriftEstimator." + d] == ref[o], d


class DualWired:
    """The five instances wired as the experiment wires them, stepped by hand."""

    def __init__(self, built_fmus, start):
        self.inst = {i: Instance(i, built_fmus[f]) for i, f in ALL.items()}
        for name, i in self.inst.items():
            i.fmu.setupExperiment(startTime=0.0)
            i.fmu.enterInitializationMode()
            i.set(start.get(name, {}))
            i.fmu.exitInitializationMode()
        self.t = 0.0

    def propagate(self):
        for s, o, d, i in dual_axis.CONNECTIONS:
            src, dst = self.inst[s], self.inst[d]
            dst.fmu.setReal([dst.vrs[i]], src.fmu.getReal([src.vrs[o]]))
        d = self.inst["DualDriftEstimator"]
        return tuple(d.fmu.getReal([d.vrs[n] for n in DUAL_OF["x"] + DUAL_OF["y"]]))

    def step(self, h=1e-3):
        for i in self.inst.values():
            i.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h
        return self.propagate()

    def free(self):
        for i in self.inst.values():
            i.free()


def _reference(n, start):
    ex = start["Excitation"]
    ref = dualaxis.simulate(n, ex, start["Accelerometer"], start["DualDriftEstimator"], 1e-3)
    return [tuple(ref[c][k] for c in DUAL_OF["x"] + DUAL_OF["y"]) for k in range(n)]


@pytest.mark.integration
@pytest.mark.parametrize("serialise", [False, True])
def test_dual_fmu_state_and_reset_continue_bit_for_bit(built_fmus, serialise):
    start = _chain_start("dphi", 1.0, 0.01)
    w = DualWired(built_fmus, start)
    rows = [w.propagate()] + [w.step() for _ in range(59)]
    saved = {}
    for n, i in w.inst.items():
        st = i.fmu.getFMUstate()
        if serialise:
            blob = i.fmu.serializeFMUstate(st)
            i.fmu.freeFMUstate(st)
            st = i.fmu.deSerializeFMUstate(blob)
        saved[n] = st
    t = w.t
    after = [w.step() for _ in range(40)]
    for n, i in w.inst.items():
        i.fmu.setFMUstate(saved[n])
        i.fmu.freeFMUstate(saved[n])
    w.t = t
    assert [w.step() for _ in range(40)] == after
    assert rows + after == _reference(100, start)
    for name, i in w.inst.items():
        i.fmu.reset()
        i.fmu.setupExperiment(startTime=0.0)
        i.fmu.enterInitializationMode()
        i.set(start.get(name, {}))
        i.fmu.exitInitializationMode()
    w.t = 0.0
    assert [w.propagate()] + [w.step() for _ in range(59)] == rows
    w.free()


@pytest.mark.integration
def test_dual_fmu_steps_of_several_samples_predict_between_measurements(built_fmus):
    start = _chain_start("rho", 0.5, 0.01)
    w = DualWired(built_fmus, start)
    w.propagate()
    row = w.step(h=4e-3)  # samples 1 and 5 measured, 2..4 predicted only
    ref = dualaxis.simulate(5, start["Excitation"], start["Accelerometer"], {}, 1e-3,
                            record=("z_x", "z_y"))
    es = start["DualDriftEstimator"]
    full = dualaxis.estimator_values(**es)
    ax, ay = dualaxis.axes(full)
    m = dualaxis.model(full["process"], A=full["A"], Q=full["Q"], Qy=full["Qy"],
                       rho=full["rho"])
    st = dualaxis.estimator_init(full["process"], 0.0, 0.0, full["P0"], full["P0y"])
    st = dualaxis.estimator_step(st, ref["z_x"][0], ref["z_y"][0], ax, ay, m)
    for _ in range(3):
        st = dualaxis.estimator_predict(st, m)
    st = dualaxis.estimator_step(st, ref["z_x"][4], ref["z_y"][4], ax, ay, m)
    assert row[0] == st.x and row[6] == st.y and row[1] == st.Pxx
    w.free()


@pytest.mark.integration
@pytest.mark.parametrize("start,text", [
    ({"DualDriftEstimator": {"Ry": 0.0}}, "Ry = 0.0 is out of range; allowed: Ry > 0"),
    ({"DualDriftEstimator": {"a1y": 0.0}}, "a1y = 0.0 is out of range; allowed: a1y != 0"),
    ({"DualDriftEstimator": {"rho": 1.5}},
     "rho = 1.5 is out of range; allowed: rho >= -1 and rho <= 1"),
    ({"DualDriftEstimator": {"process": 2, "f": 600.0}}, "at or above the Nyquist rate"),
    ({"Accelerometer": {"dual": 1, "fc": 100.0}}, "dual = 1 is not allowed with fc = 100.0"),
    ({"Excitation": {"Qy": -1.0}}, "Qy = -1.0 is out of range; allowed: Qy >= 0"),
    ({"DualDriftEstimator": {"z_y": math.inf}}, "z_y = inf is not finite"),
])
def test_bad_dual_value_gives_fmi2error_with_log_message(built_fmus, start, text, report):
    paths = {i: built_fmus[f] for i, f in ALL.items()}
    with pytest.raises(CoSimulationError) as info:
        cosimulate(paths, dual_axis.CONNECTIONS, 5, 1e-3, start_values=start)
    msg = str(info.value)
    report("refused, as it must be: %s -> %s" % (start, " | ".join(msg.splitlines())))
    assert "status 3 (error)" in msg and text in msg


# -- the experiment -----------------------------------------------------------------------------

SMALL = dict(points=3, runs=2, n=600, seed=3, workers=2)  # 600 samples = 90 whole periods


@pytest.fixture(scope="module")
def experiment(built_fmus, tmp_path_factory):
    out = tmp_path_factory.mktemp("dual_axis")
    summary = dual_axis.run_dual_axis(out=out, fmu_dir=built_fmus["Excitation"].parent, **SMALL)
    return out, summary


def _check_rows(rows):
    for r in rows:
        # the single-axis EKF1 is off by the cross-term drift it cannot see, b mean(xy) ...
        miss = abs(r["err_single"] + r["cross"])
        assert miss <= dual_axis.SE_FACTOR * r["se_single"] or \
            miss <= dual_axis.DUAL_BAND * r["scale"], r
        # ... and that is a real error wherever the cross term is not 0
        if abs(r["cross_expected"]) > 0.1 * r["scale"]:
            assert abs(r["err_single"]) > 5 * dual_axis.DUAL_BAND * r["scale"], r
        # the dual-axis EKF1 is right to 2 % of the drift's scale
        assert abs(r["err_dual"]) <= dual_axis.DUAL_BAND * r["scale"], r


@pytest.mark.integration
def test_experiment_through_the_fmus(experiment):
    out, s = experiment
    assert s["validation"]["bit_identical"] is True and s["validation"]["max_abs_diff"] == 0.0
    assert len(s["points"]) == 2 * SMALL["points"] * 2
    _check_rows(s["points"])
    assert s["claims"]["single_off_by_cross_everywhere"]
    assert s["claims"]["dual_within_band_everywhere"]
    on_disk = json.loads((out / "dual_axis.json").read_text())
    assert on_disk["points"] == json.loads(json.dumps(s["points"]))
    for r in on_disk["points"]:
        assert {"err_single", "err_dual", "scale", "se_single", "se_dual", "cross"} <= set(r)
    with open(out / "dual_axis.csv") as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == list(dual_axis.CSV_COLUMNS) and len(table) == len(s["points"])
    assert float(table[0]["parameter"]) == 0.0 and float(table[-1]["parameter"]) == 0.9
    assert (out / "dual_axis.png").stat().st_size > 20_000
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no staging folder
    assert not list(out.parent.glob(".driftfmu-stage-*"))
    # the sinusoidal sweep's references are the closed forms (whole periods)
    for r in s["points"][:2 * SMALL["points"]]:
        assert r["dc_true"] == pytest.approx(r["dc_expected"], rel=1e-9, abs=1e-15)


@pytest.mark.integration
def test_native_backend_gives_the_python_fmus_numbers(experiment, native_fmus):
    _, s = experiment
    fmu_dir = native_fmus[2]["Excitation"].parent.parent.parent  # <dir>/native/fmi2/X.fmu
    n = dual_axis.run_dual_axis(fmu_dir=fmu_dir, backend="native", **SMALL)
    assert n["backend"] == "native" and s["backend"] == "python"
    assert n["validation"]["bit_identical"] is True
    assert n["points"] == s["points"]


@pytest.mark.integration
def test_batch_engine_gives_the_fmu_engines_numbers(experiment):
    _, s = experiment
    b = dual_axis.run_dual_axis(engine="batch", **SMALL)
    assert b["points"] == s["points"]


def test_batch_engine_over_many_seeds_meets_the_claims():
    s = dual_axis.run_dual_axis(engine="batch", points=3, runs=200, n=1200, workers=2)
    _check_rows(s["points"])
    # Gaussian sweep: the single-axis miss is statistical, within 3 standard errors
    for r in s["points"][6:]:
        assert r["single_miss_over_se"] <= dual_axis.SE_FACTOR, r


def test_failed_validation_writes_nothing(built_fmus, tmp_path, monkeypatch):
    real = dual_axis.batch.dual_simulate

    def off_by_one_ulp(*args, **kw):
        out = real(*args, **kw)
        if "x_hat" in out:
            out["x_hat"] = np.nextafter(out["x_hat"], np.inf)
        return out
    monkeypatch.setattr(dual_axis.batch, "dual_simulate", off_by_one_ulp)
    with pytest.raises(dual_axis.ValidationError, match="differ from models"):
        dual_axis.run_dual_axis(out=tmp_path / "o", points=2, runs=1, n=20, workers=1,
                                fmu_dir=built_fmus["Excitation"].parent)
    assert not (tmp_path / "o").exists() or list((tmp_path / "o").iterdir()) == []


@pytest.mark.parametrize("kwargs,text", [
    (dict(points=1), "points = 1 is out of range; allowed: an integer points >= 2"),
    (dict(runs=0), "runs = 0 is out of range; allowed: an integer runs >= 1"),
    (dict(engine="gpu"), "engine = 'gpu' is not allowed"),
    (dict(Ry=-1.0), "Ry = -1.0 is out of range; allowed: Ry > 0"),
    (dict(f=600.0), "Nyquist"),
    (dict(bogus=1), "got an unexpected keyword argument 'bogus'; allowed: out, points, "),
])
def test_bad_settings_fail_before_anything_runs(tmp_path, kwargs, text):
    with pytest.raises(ValueError) as info:
        dual_axis.run_dual_axis(out=tmp_path / "o", fmu_dir=tmp_path / "none", **kwargs)
    assert text in str(info.value)
    assert not (tmp_path / "o").exists() and not (tmp_path / "none").exists()


@pytest.mark.parametrize("argv,text", [
    (["experiment", "dual-axis", "--points", "1"], "points = 1 is out of range; allowed: "
                                                   "an integer points >= 2"),
    (["experiment", "dual-axis", "--rho", "0.5"], "unrecognized arguments: --rho"),
    (["experiment", "dual-axis", "--Ry", "0"], "Ry = 0.0 is out of range; allowed: Ry > 0"),
    (["experiment", "dual-axis", "--engine", "gpu"], "engine = 'gpu' is not allowed; allowed: "
                                                     "'fmu', 'batch'"),
])
def test_cli_bad_option_is_one_line_and_exit_2(argv, text, capsys):
    with pytest.raises(SystemExit) as info:
        main(argv)
    err = capsys.readouterr().err
    assert info.value.code == 2 and len(err.strip().splitlines()) == 1 and text in err


def test_cli_batch_run_writes_and_reports(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["experiment", "dual-axis", "--engine", "batch", "--runs", "3", "--points", "2",
                 "--n", "60", "--workers", "1", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "wrote %s/dual_axis.csv, dual_axis.json, dual_axis.png" % out in text
    assert "batch engine" in text
    assert sorted(p.name for p in out.iterdir()) == ["dual_axis.csv", "dual_axis.json",
                                                     "dual_axis.png"]


def test_the_table_codes_the_sweep_and_the_axis_as_the_results_say(tmp_path):
    """``dual_axis.csv``: ``sweep`` 1 for dphi, 2 for rho; ``axis`` 1 for x, 2 for y
    (docs/results.md), one row per point of the summary, in its order."""
    s = dual_axis.run_dual_axis(out=tmp_path / "o", engine="batch", points=2, runs=2, n=60,
                                workers=1, plot=False)
    with open(tmp_path / "o" / "dual_axis.csv") as fh:
        table = list(csv.DictReader(fh))
    codes = [(float(row["sweep"]), float(row["axis"])) for row in table]
    assert codes == [({"dphi": 1.0, "rho": 2.0}[p["sweep"]], {"x": 1.0, "y": 2.0}[p["axis"]])
                     for p in s["points"]]
    assert set(codes) == {(1.0, 1.0), (1.0, 2.0), (2.0, 1.0), (2.0, 2.0)}


def test_second_gauss_markov_axis_under_any_step_is_the_sample_by_sample_run():
    from driftfmu.fmu_src.Excitation import Excitation
    e = Excitation(instance_name="e")
    e.setup_experiment(0.0)
    e.enter_initialization_mode()
    vrs = {v.name: v.value_reference for v in e.vars.values()}
    e.set_real([vrs["Qy"], vrs["rho"], vrs["A"]], [0.02, -0.7, 0.6])
    e.exit_initialization_mode()
    x = y = 0.0
    want = []
    for k in range(1, 31):
        x, y = excitation.gaussian_pair(x, y, 0.6, 0.01, 0.02, -0.7, 1, k)
        want.append((x, y))
    checked, t = 1, 0.0
    assert tuple(e.get_real([vrs["x"], vrs["y"]])) == want[0]
    for h in [0.25e-3] * 8 + [2.5e-3, 0.5e-3] * 4 + [3e-3] * 3 + [1e-3] * 6:
        assert e.do_step(t, h)
        t += h
        k = t / 1e-3  # samples since the start: at an instant, sample k + 1 is out
        if abs(k - round(k)) < 1e-6:
            assert tuple(e.get_real([vrs["x"], vrs["y"]])) == want[round(k)], k
            checked += 1
    assert checked > 15


@pytest.mark.parametrize("process", [dualaxis.GAUSS_MARKOV, dualaxis.HARMONIC])
def test_b_zero_dual_slave_under_any_step_is_two_single_axis_slaves(process):
    """The step rule (zero-order hold, update at the first instant of a step, predict through
    the others, feedthrough at instants) is the single-axis estimator's on each axis."""
    import random
    from driftfmu.fmu_src.DriftEstimator import DriftEstimator
    from driftfmu.fmu_src.DualDriftEstimator import DualDriftEstimator

    def ready(cls, **start):
        s = cls(instance_name="s")
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        vrs = {v.name: v.value_reference for v in s.vars.values()}
        for name, value in start.items():
            (s.set_integer if name == "process" else s.set_real)([vrs[name]], [value])
        s.exit_initialization_mode()
        assert not s.log_queue, [m.msg for m in s.log_queue]
        return s, vrs

    common = dict(process=process, f=123.0, Qh=1e-6, A=0.4)
    d, dv = ready(DualDriftEstimator, a2=0.05, a2y=0.02, Q=0.02, Qy=0.03, P0=0.3, P0y=0.2,
                  **common)
    sx, xv = ready(DriftEstimator, a2=0.05, Q=0.02, P0=0.3, **common)
    sy, yv = ready(DriftEstimator, a2=0.02, Q=0.03, P0=0.2, **common)
    rng = random.Random(5)
    t = 0.0
    for i in range(120):
        zx, zy = rng.uniform(-1, 1), rng.uniform(-1, 1)
        d.set_real([dv["z_x"], dv["z_y"]], [zx, zy])
        sx.set_real([xv["z"]], [zx])
        sy.set_real([yv["z"]], [zy])
        for axis, s, vrs in (("x", sx, xv), ("y", sy, yv)):
            got = d.get_real([dv[n] for n in DUAL_OF[axis]])
            assert got == s.get_real([vrs[n] for n in SINGLE_OUTS]), (i, axis)
        h = rng.choice([0.25e-3, 1e-3, 2.5e-3, 0.3e-3, 3e-3, 1e-3 / 3])
        assert d.do_step(t, h) and sx.do_step(t, h) and sy.do_step(t, h)
        t += h


def test_batch_engine_on_an_unreachable_scheduler_fails_fast_and_writes_nothing(tmp_path):
    pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] is not installed")
    with pytest.raises(ConnectionError, match="no Dask scheduler answered"):
        dual_axis.run_dual_axis(out=tmp_path / "o", engine="batch", runs=2, points=2, n=10,
                                scheduler="tcp://127.0.0.1:1")
    assert not (tmp_path / "o").exists()


def test_new_parameters_are_appended_and_off_by_default():
    """Existing value references do not move, and the defaults are today's behaviour."""
    from driftfmu.fmu_src.Accelerometer import Accelerometer
    from driftfmu.fmu_src.Excitation import Excitation
    new = {Excitation: ("Qy", "rho"),
           Accelerometer: ("dual", "bx", "a0y", "a1y", "a2y", "by", "Ry")}
    later = ("a4", "B", "drive", "Qu", "Xu", "fu", "u", "u_in",  # appended after them (issue 16)
             "bias_on", "random_walk", "bias_gm", "tau_gm", "flicker", "tau_min", "tau_max",
             "d_inf", "E_tau", "T0", "kT_bias", "kT_scale", "range", "theta", "T")  # (issue 42)
    for cls, names in new.items():
        table = [s["name"] for s in cls.VARIABLES]
        while table[-1] in later:
            table.pop()
        assert tuple(table[-len(names):]) == names
        starts = {s["name"]: s["start"] for s in cls.VARIABLES}
    assert (starts["dual"], starts["bx"], starts["by"]) == (0, 0.0, 0.0)
    assert {s["name"]: s["start"] for s in Excitation.VARIABLES}["Qy"] == 0.0


def _plotted_summary():
    rows = []
    for sweep, values in (("dphi", (0.0, 0.5, 1.0)), ("rho", (0.0, 0.45, 0.9))):
        for v in values:
            for axis in ("x", "y"):
                rows.append({"sweep": sweep, "axis": axis, "parameter": v, "cross": -1e-3 * v,
                             "err_single": 1e-3 * v, "se_single": 1e-5, "err_dual": 1e-6,
                             "se_dual": 1e-6, "scale": 1e-2})
    settings = dict(dual_axis.DEFAULTS, runs=4, engine="batch")
    return {"points": rows, "settings": settings}


def test_dual_axis_figure_sets_the_axes_apart_with_capped_bars_and_one_legend(
        closed_figures, tmp_path):
    from matplotlib.container import ErrorbarContainer
    dual_axis.plot_dual_axis(tmp_path / "d.png", _plotted_summary())
    (fig,) = closed_figures
    axes = fig.axes
    assert len(axes) == 4
    for ax in axes:
        bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
        assert len(bars) == 2
        for c in bars:  # capsize 3: caps 6 points wide
            assert c.lines[1] and all(cap.get_markersize() == 6 for cap in c.lines[1])
    for ax in axes[2:]:  # bottom: the y axis's points shifted right, the x axis's left
        bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
        x = np.asarray(bars[0].lines[0].get_xdata())
        y = np.asarray(bars[1].lines[0].get_xdata())
        p = x + (y - x) / 2
        assert np.all(y - x > 0) and np.allclose(y - p, 0.012 * (p[-1] - p[0]))
    # one legend under the panels: handles and labels of the left column, in order
    (legend,) = fig.legends
    labels = [t.get_text() for t in legend.get_texts()]
    expected = []
    for ax in (axes[0], axes[2]):
        expected += ax.get_legend_handles_labels()[1]
    assert labels == expected and len(labels) == 6
    assert all(label.startswith(("-b mean(xy)", "single-axis", "dual-axis")) for label in labels)
    assert len(legend.legend_handles) == 6


def test_dual_axis_figure_titles_at_9_points_and_its_lines_1_point_wide(closed_figures,
                                                                         tmp_path):
    """The panels' titles at 9 pt under the 10-pt suptitle; the dashed cross-term lines and
    the lines joining the dual-axis points 1 pt wide (thinner than matplotlib's 1.5 default,
    so the error bars stand out)."""
    from matplotlib.container import ErrorbarContainer
    dual_axis.plot_dual_axis(tmp_path / "d.png", _plotted_summary())
    (fig,) = closed_figures
    top_left, top_right, bottom_left, bottom_right = fig.axes
    assert [ax.title.get_fontsize() for ax in (top_left, top_right)] == [9, 9]
    assert fig._suptitle.get_fontsize() == 10
    for ax in (top_left, top_right):
        dashed = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
        assert len(dashed) == 2 and all(line.get_linewidth() == 1.0 for line in dashed)
    for ax in (bottom_left, bottom_right):
        bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
        assert len(bars) == 2 and all(c.lines[0].get_linewidth() == 1.0 for c in bars)


def test_dual_axis_figure_draws_open_6_point_and_filled_5_point_markers(closed_figures,
                                                                         tmp_path):
    """Top: the single-axis EKF1's points open markers of 6 pt (the dashed line they miss
    shows through); bottom: the dual-axis EKF1's points filled markers of 5 pt."""
    from matplotlib.container import ErrorbarContainer
    dual_axis.plot_dual_axis(tmp_path / "d.png", _plotted_summary())
    (fig,) = closed_figures
    for row, (size, face) in ((fig.axes[:2], (6, "none")), (fig.axes[2:], (5, None))):
        for ax in row:
            points = [c.lines[0] for c in ax.containers if isinstance(c, ErrorbarContainer)]
            assert len(points) == 2
            for line in points:
                assert line.get_markersize() == size
                assert (line.get_markerfacecolor() == "none") == (face == "none")


def test_batch_engine_claims_no_fmu_validation_and_no_backend(monkeypatch):
    def no_fmus(*args, **kwargs):
        raise AssertionError("the batch engine went through the FMU path")
    monkeypatch.setattr(dual_axis, "fmu_paths", no_fmus)
    s = dual_axis.run_dual_axis(engine="batch", points=3, runs=2, n=200, workers=1, plot=False)
    assert s["validation"] is None and s["backend"] is None
    assert s["settings"]["engine"] == "batch"
