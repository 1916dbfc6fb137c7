"""The known input u (eq. 1) carried by every master when ``B != 0`` (issue 16).

The filter's prediction is ``x-_k = A x+_{k-1} + B u_k``: the DriftEstimator must get the
Excitation's ``u``.  For each way of running the chain (the public ``driftfmu.simulate``, the
fmpy master and the fast master, the sinusoidal master, the batch engine's FMU path, the SSP
export) a run with ``B != 0`` equals models/ bit for bit, and the same run without the
connection does not (so each test fails when the wiring is dropped).
"""
import numpy as np
import pytest

import driftfmu
from driftfmu.models import chain, excitation

N = 200
#: A run where the input matters: B u is of the order of the process noise.
GENERAL = dict(a0=0.1, a2=0.05, A=0.6, Q=0.05, R=1e-3, a3=0.02, a4=0.03, B=0.8)
INPUT = dict(drive=excitation.GAUSSIAN, Qu=0.3)
COLUMNS = ("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")


@pytest.fixture(scope="module")
def fmu_dir(fmus_in_build_layout):
    """A folder in the layout build_fmus writes, linking the session's FMUs."""
    return fmus_in_build_layout


@pytest.fixture(scope="module")
def unwired(python_fmus):
    """The Gaussian run of :data:`GENERAL` without the u connection (the filter predicts with
    u = 0): what a master that drops the wiring shows."""
    from driftfmu.simulations.cosim import cosimulate
    from driftfmu.simulations.gaussian import CONNECTIONS, FMU_NAMES, start_values
    raw = cosimulate({n: python_fmus[n] for n in FMU_NAMES}, CONNECTIONS, N, 1e-3,
                     start_values=start_values(seed=4, P0=0.2, **GENERAL, **INPUT))
    return {c: raw["DriftEstimator.%s" % c] for c in ("x_hat", "P", "dc_ekf1")}


def _reference(seed=4, P0=0.2, **kw):
    p = dict(GENERAL, **INPUT)
    p.update(kw)
    return chain.simulate(N, seed, x0=0.0, P0=P0, **p)


@pytest.mark.integration
@pytest.mark.parametrize("backend, fmi_version", [("python", 2), ("native", 2), ("native", 3)])
def test_simulate_carries_u_to_the_filter(fmu_dir, unwired, backend, fmi_version):
    ref = _reference()
    start = dict(GENERAL, **INPUT, seed=4, P0=0.2)
    result = driftfmu.simulate(stop_time=(N - 1) * 1e-3, start_values=start, backend=backend,
                               fmi_version=fmi_version, fmu_dir=fmu_dir)
    for c in COLUMNS:
        np.testing.assert_array_equal(result[c], np.asarray(ref[c]), err_msg=c)
    assert np.any(result["u"] != 0.0)
    assert np.any(np.asarray(unwired["x_hat"]) != result["x_hat"])  # the test can fail


#: The sinusoidal master with a shaker's commanded motion as the known input: the filter
#: (Gauss-Markov, A = 0, B = 1) predicts the commanded u = X sin(2 pi f t).
SINE = dict(X=1.0, f=40.0, a2=0.05, R=1e-3, A=0.0, Q=1e-3, P0=1e-3)
SINE_INPUT = dict(B=1.0, drive=excitation.SINUSOIDAL, Xu=1.0, fu=40.0)


def _sine_reference(B):
    """models/adxl203.simulate with the filter's ``B`` given here (not taken from the master's
    start values), the Excitation's u the commanded sinusoid."""
    from driftfmu.models import adxl203, harmonic
    p = SINE
    ex = dict(kind=excitation.SINUSOIDAL, X=p["X"], f=p["f"], seed=2, drive=excitation.SINUSOIDAL,
              Xu=1.0, fu=40.0)
    sp = dict(a0=0.0, a1=1.0, a2=p["a2"], R=p["R"], seed=2, Ts=1e-3, noise=1)
    es = dict(a0=0.0, a1=1.0, a2=p["a2"], R=p["R"], A=p["A"], Q=p["Q"], P0=p["P0"], x0=0.0,
              process=harmonic.GAUSS_MARKOV, f=p["f"], B=B)
    return adxl203.simulate(N, ex, sp, es, 1e-3)


@pytest.mark.integration
@pytest.mark.parametrize("backend", ["python", "native"])
def test_sinusoidal_master_carries_u_to_the_filter(fmu_dir, backend):
    from driftfmu.simulations import sinusoidal
    res = sinusoidal.run_sinusoidal(n=N, seed=2, process=1, fmu_dir=fmu_dir, plot=False,
                                    backend=backend, **SINE, **SINE_INPUT)
    assert res["summary"]["validation"]["passed"]
    ref, blind = _sine_reference(1.0), _sine_reference(0.0)
    for c in COLUMNS:
        assert list(res["columns"][c]) == list(ref[c]), c
    assert list(res["columns"]["x_hat"]) != list(blind["x_hat"])  # the test can fail
    # the commanded motion is the motion here: the filter's error is the noise's, not x's
    err = np.abs(np.asarray(res["columns"]["x_hat"]) - np.asarray(res["columns"]["x"]))
    err_blind = np.abs(np.asarray(blind["x_hat"]) - np.asarray(blind["x"]))
    assert err.mean() < 0.5 * err_blind.mean()


def test_sinusoidal_master_refuses_B_with_the_harmonic_filter_and_fu_over_nyquist():
    from driftfmu.simulations import sinusoidal
    from driftfmu.simulations.errors import UsageError
    with pytest.raises(UsageError, match=r"B = 1.0 is not allowed with process = 2"):
        sinusoidal.run_sinusoidal(n=10, process=2, B=1.0, drive=2, Xu=1.0, fu=40.0)
    with pytest.raises(UsageError, match=r"fu = 600.0 Hz is not allowed at Ts = 0.001 s"):
        sinusoidal.run_sinusoidal(n=10, process=1, B=1.0, drive=2, Xu=1.0, fu=600.0)
    with pytest.raises(TypeError, match="a3"):
        sinusoidal.run_sinusoidal(n=10, a3=0.1)
    assert sinusoidal.connections(0.0) == sinusoidal.CONNECTIONS
    assert sinusoidal.connections(0.5)[-1] == ("Excitation", "u", "DriftEstimator", "u")


@pytest.mark.integration
@pytest.mark.parametrize("backend", ["python", "native"])
def test_fmu_engine_equals_the_batch_engine_with_the_input(fmu_dir, backend):
    from driftfmu.simulations import batch
    general = dict(a3=0.02, a4=0.03, B=0.8, drive=excitation.GAUSSIAN, Qu=0.3)
    p = dict(a0=0.1, a2=0.05, A=0.6, Q=0.05, R=1e-3)
    one = batch.fmu_simulate(N, 9, fmu_dir=fmu_dir, record=("x_hat",), backend=backend, **p,
                             **general)
    many = batch.simulate(N, np.array([9], dtype=np.uint64), record=("x_hat",), kernel="numpy",
                          **p, **general)
    for key in batch.FINALS:
        assert one["final_" + key] == many["final_" + key][0], key
    np.testing.assert_array_equal(one["x_hat"], many["x_hat"][0])
    without = batch.simulate(N, np.array([9], dtype=np.uint64), kernel="numpy", **p,
                             **dict(general, B=0.0))
    assert one["final_x_hat"] != without["final_x_hat"][0]  # the input matters here


def test_fmu_engine_refuses_the_input_with_the_sinusoid():
    from driftfmu.simulations import batch
    from driftfmu.simulations.errors import UsageError
    with pytest.raises(UsageError, match=r"B, drive with the Gaussian excitation only"):
        batch.fmu_simulate(10, 1, kind=excitation.SINUSOIDAL, B=0.5, drive=1)
    with pytest.raises(TypeError, match="Bx"):
        batch.fmu_simulate(10, 1, Bx=0.5)


@pytest.mark.integration
@pytest.mark.parametrize("backend, fmi_version", [("python", 2), ("native", 2), ("native", 3)])
def test_excitation_takes_u_from_the_host(fmu_dir, backend, fmi_version):
    """drive = 0: the Excitation's u is the host's input u_in.  Fed the samples its own
    Gaussian drive would make, the chain gives models/' run with that drive bit for bit."""
    ref = _reference(seed=6)
    u = [excitation.input_sample(INPUT["drive"], 6, k, INPUT["Qu"]) for k in range(1, N + 1)]
    signal = np.zeros(N, dtype=[("time", float), ("u_in", float)])
    signal["time"] = np.arange(N) * 1e-3
    signal["u_in"] = u
    result = driftfmu.simulate(stop_time=(N - 1) * 1e-3, input=signal,
                               start_values=dict(GENERAL, seed=6, P0=0.2), backend=backend,
                               fmi_version=fmi_version, fmu_dir=fmu_dir)
    np.testing.assert_array_equal(result["u"], np.asarray(u))
    for c in COLUMNS:
        np.testing.assert_array_equal(result[c], np.asarray(ref[c]), err_msg=c)
    # without the host's input (u_in = 0) the state and the filter differ
    assert not np.array_equal(result["x"], np.asarray(_reference(seed=6, Qu=0.0)["x"]))


@pytest.mark.integration
def test_host_input_is_a_feedthrough_of_the_excitation(python_fmus, native_fmus):
    """u_in set at a communication point moves x (by B u) and u at that point, in the Python
    FMU and its native twins alike, and the model description declares the dependency."""
    from fmpy import read_model_description
    from driftfmu.simulations.cosim import cosimulate
    start = {"Excitation": dict(A=0.5, Q=0.01, B=2.0, seed=3)}
    u = [0.0, 1.0, -0.5, 0.25, 3.0]
    runs = {}
    for name, path in (("python", python_fmus["Excitation"]),
                       ("fmi2", native_fmus[2]["Excitation"]),
                       ("fmi3", native_fmus[3]["Excitation"])):
        md = read_model_description(str(path))
        vr = {v.name: v for v in md.modelVariables}
        assert vr["u_in"].causality == "input"
        deps = {o.variable.name: [d.name for d in o.dependencies] for o in md.outputs}
        assert deps["x"] == ["u_in"] and deps["u"] == ["u_in"], deps
        runs[name] = cosimulate({"Excitation": path}, [], len(u), 1e-3, start_values=start,
                                inputs={"Excitation": {"u_in": u}})
        assert runs[name]["Excitation.u"] == u
    assert runs["python"] == runs["fmi2"] == runs["fmi3"]
    x, w = 0.0, []
    for k, uk in enumerate(u, start=1):
        x = excitation.gaussian_sample(x, 0.5, 0.01, 3, k, 2.0, uk)
        w.append(x)
    assert runs["python"]["Excitation.x"] == w


# -- without FMUs: what the mutation check can run --------------------------------------------

def test_every_wiring_has_the_input_connection_when_B_is_set():
    from driftfmu import _api
    from driftfmu.fmu_src import ssp
    from driftfmu.simulations import gaussian, sinusoidal
    u = ("Excitation", "u", "DriftEstimator", "u")
    assert u in _api.CONNECTIONS
    assert gaussian.connections(0.5)[-1] == u and u not in gaussian.connections(0.0)
    assert sinusoidal.connections(0.5)[-1] == u and u not in sinusoidal.connections(0.0)
    assert ssp.connections(ssp.chain_start_values(**dict(GENERAL, **INPUT)))[-1] == u
    assert ssp.connections(ssp.chain_start_values(**dict(GENERAL, B=0.0))) == ssp.CONNECTIONS


def test_the_jacobi_reference_with_the_input_delays_u_by_one_step():
    """With u held in the filter (and everything else as the chain's), the Jacobi reference's
    estimator takes u_{i+1} at row i: the first row's filter sees u = 0 (fmpy's connectors start
    at 0), the next ones the Excitation's u of the row before."""
    from driftfmu.fmu_src import ssp
    p = dict(GENERAL, **INPUT, seed=3)
    ref = ssp.jacobi_reference(6, **p)
    assert ref["DriftEstimator.u"] == ref["Excitation.u"]
    u = [excitation.input_sample(1, 3, k, INPUT["Qu"]) for k in range(1, 8)]
    assert ref["Excitation.u"] == u[1:7]
    # row 0: the estimator updated with z = 0 and u = 0 (twice: committed, then shown)
    from driftfmu.models import chain as ch
    q = {k: p[k] for k in ("a0", "a2", "A", "Q", "R", "a3", "a4", "B")}
    args = lambda s, z, uk: ch.estimator_step(s, z, q["a0"], 1.0, q["a2"], q["A"], q["Q"],
                                              q["R"], q["a3"], q["a4"], q["B"], uk)
    s0 = ch.estimator_init(0.0, p["Q"] / (1 - p["A"] ** 2))
    assert ref["DriftEstimator.x_hat"][0] == args(args(s0, 0.0, 0.0), 0.0, 0.0).x
    z0 = ref["DriftEstimator.z"][0]
    c1 = args(args(s0, 0.0, 0.0), z0, u[1])
    assert ref["DriftEstimator.x_hat"][1] == args(c1, z0, u[1]).x


def test_the_excitation_slave_takes_u_in_when_drive_is_0():
    """The Python slave (no FMU built): u_in moves u and, by B u, x at the same sample."""
    from driftfmu.fmu_src.Excitation import Excitation
    e = Excitation(instance_name="e")
    vr = {s["name"]: i for i, s in enumerate(Excitation.VARIABLES)}
    e.set_real([vr["A"], vr["Q"], vr["B"]], [0.5, 0.01, 2.0])
    e.enter_initialization_mode()
    e.exit_initialization_mode()
    e.set_real([vr["u_in"]], [1.5])
    x, u = e.get_real([vr["x"], vr["u"]])
    assert u == 1.5
    assert x == excitation.gaussian_sample(0.0, 0.5, 0.01, 1, 1, 2.0, 1.5)
    e.do_step(0.0, 1e-3)
    e.set_real([vr["u_in"]], [-0.25])
    x2, u2 = e.get_real([vr["x"], vr["u"]])
    assert (u2, x2) == (-0.25, excitation.gaussian_sample(x, 0.5, 0.01, 1, 2, 2.0, -0.25))


def test_the_sinusoidal_reference_predicts_with_the_commanded_input():
    """models/adxl203.simulate (the sinusoidal master's reference) with B = 1, A = 0 and u the
    commanded sinusoid: the filter's prediction is u_k, sample by sample."""
    from driftfmu.models import chain as ch
    ref = _sine_reference(1.0)
    p = SINE
    s = ch.estimator_init(0.0, p["P0"])
    for k in range(1, 30):
        uk = excitation.sine(k, 1.0, 40.0, 1e-3)
        assert ref["x"][k - 1] == excitation.sine(k, p["X"], p["f"], 1e-3)
        s = ch.estimator_step(s, ref["z"][k - 1], 0.0, 1.0, p["a2"], p["A"], p["Q"], p["R"],
                              B=1.0, u=uk)
        assert ref["x_hat"][k - 1] == s.x, k
