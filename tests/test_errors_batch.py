"""The sensor's slow errors (issue 42) in the batch engine, montecarlo and sweep: the NumPy path
and the compiled kernel give the same bits, run ``r`` of a batch is the chain of
models.chain.simulate (the FMU engine's reference) for its seed, bit for bit, montecarlo and
sweep take every new parameter (API and command line) and refuse bad values with one line."""
import subprocess
import sys

import numpy as np
import pytest

import driftfmu
from driftfmu.models import chain, excitation
from driftfmu.simulations import batch, kernel
from driftfmu.simulations.errors import UsageError

ALL_ON = dict(bias_on=0.05, random_walk=0.02, bias_gm=0.03, tau_gm=0.02, flicker=0.01,
              tau_min=0.003, tau_max=3.0, d_inf=0.04, E_tau=0.5, T0=290.0, kT_bias=0.002,
              kT_scale=-0.003, range=1.8, theta=0.1, T=300.0, bits=14)
CASES = {"all on": ALL_ON, "flicker": dict(flicker=0.02, tau_min=0.01, tau_max=100.0),
         "walk and exposure": dict(random_walk=0.05, d_inf=-0.03, E_tau=0.1),
         "tilt only": dict(theta=-0.4), "ADC over the range": dict(bits=6, range=2.0),
         "temperature": dict(T=310.0, kT_bias=0.01, kT_scale=0.002)}


def digest(res):
    return {k: np.asarray(v).tobytes() for k, v in res.items()}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_kernel_and_numpy_give_the_same_bits(case):
    if kernel.library() is None:
        pytest.skip("no C compiler: the compiled kernel is not available")
    seeds = batch.run_seeds(3, 19)
    values = CASES[case]
    for kw in (dict(), dict(a2=np.linspace(0.001, 0.2, 19), R=np.geomspace(1e-6, 1e-2, 19)),
               dict(kind=excitation.SINUSOIDAL, X=1.2, f=70.0, phi=batch.sine_phase(seeds)),
               dict(a3=0.01, a4=0.002, B=0.3, drive=1, Qu=0.01)):
        for record in ((), batch.TRAJECTORIES):
            a = batch.simulate(250, seeds, kernel="numpy", record=record, **kw, **values)
            b = batch.simulate(250, seeds, kernel="c", record=record, **kw, **values)
            assert digest(a) == digest(b), (case, kw, record)


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_batch_run_is_the_chain_of_its_seed(case):
    """run r of the batch = models.chain.simulate(seed r): the reference the FMU engine's
    co-simulation is checked against (simulations.gaussian.run_gaussian)."""
    seeds = batch.run_seeds(40, 6)
    values = CASES[case]
    res = batch.simulate(300, seeds, record=("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2",
                                             "dc_ekf3"), A=0.3, **values)
    for r, seed in enumerate(seeds):
        ref = chain.simulate(300, int(seed), A=0.3, **values)
        for col in ("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3"):
            assert np.asarray(ref[col]).tobytes() == res[col][r].tobytes(), (case, r, col)
    plain = batch.simulate(300, seeds, record=("z",), A=0.3)
    assert plain["z"].tobytes() != res["z"].tobytes()


def test_explicit_defaults_keep_the_bits_and_per_run_arrays_or_unknown_names_are_refused():
    seeds = batch.run_seeds(1, 8)
    a = batch.simulate(200, seeds, record=batch.TRAJECTORIES)
    b = batch.simulate(200, seeds, record=batch.TRAJECTORIES, **chain.SENSOR_ERRORS_OFF)
    assert digest(a) == digest(b)
    with pytest.raises(UsageError, match="bias_gm must be one value for all runs"):
        batch.simulate(10, seeds, bias_gm=np.full(8, 0.1))
    with pytest.raises(UsageError, match="unknown parameter.s. bias_walk; allowed: bias_on"):
        batch.simulate(10, seeds, bias_walk=0.1)


@pytest.mark.parametrize("name", sorted(chain.SENSOR_ERRORS_OFF))
def test_montecarlo_and_sweep_take_every_new_parameter(name):
    """Each parameter, set away from its off value (with what it needs), moves montecarlo's
    and sweep's numbers; at its off value it changes nothing."""
    on = {"bias_on": 0.05, "random_walk": 0.05, "bias_gm": 0.05, "flicker": 0.05,
          "d_inf": 0.05, "theta": 0.3, "kT_bias": 0.01, "kT_scale": 0.05, "range": 0.05,
          "bits": 8}
    needs = {"tau_gm": dict(bias_gm=0.05), "tau_min": dict(flicker=0.05),
             "tau_max": dict(flicker=0.05), "E_tau": dict(d_inf=0.05),
             "T": dict(kT_bias=0.01), "T0": dict(kT_bias=0.01, T=300.0),
             "kT_bias": dict(T=300.0), "kT_scale": dict(T=300.0), "bits": dict(range=2.0)}
    change = {"tau_gm": 0.003, "tau_min": 0.01, "tau_max": 10.0, "E_tau": 1e-4, "T": 310.0,
              "T0": 280.0}
    base = dict(needs.get(name, {}))
    moved = dict(base, **{name: on.get(name, change.get(name))})
    off = dict(base, **{name: chain.SENSOR_ERRORS_OFF[name]})
    kw = dict(runs=6, n=120, workers=1)
    mc = {label: driftfmu.montecarlo("gaussian", **kw, **values)["fig1_dc1"]
          for label, values in (("base", base), ("moved", moved), ("off", off))}
    assert mc["off"].tobytes() == mc["base"].tobytes()
    assert mc["moved"].tobytes() != mc["base"].tobytes()
    sw = {label: driftfmu.sweep(a2=(0.01, 0.1), R=(1e-4,), **kw, **values)["grid_zbar"]
          for label, values in (("base", base), ("moved", moved))}
    assert sw["moved"].tobytes() != sw["base"].tobytes()
    if name not in ("theta", "T"):  # (inputs: a sinusoidal run holds them as well)
        mc = driftfmu.montecarlo("sinusoidal", **kw, **moved)
        assert mc["sine_dc1"].shape == (6, 120)
        assert mc["summary"]["parameters"][name] == moved[name]


@pytest.mark.parametrize("values, words", [
    (dict(bias_gm=-0.1), "bias_gm = -0.1 is out of range; allowed: bias_gm >= 0"),
    (dict(flicker=0.01, tau_min=3.0, tau_max=2.0),
     "tau_min = 3.0 s and tau_max = 2.0 s are not a band; allowed: tau_min < tau_max"),
    (dict(flicker=0.01, tau_min=1e-5, tau_max=1e3), "span more than 7 decades"),
    (dict(E_tau=0.0), "E_tau = 0.0 is out of range; allowed: E_tau > 0"),
    (dict(range=-2.0), "range = -2.0 is out of range; allowed: range >= 0"),
])
def test_montecarlo_and_sweep_refuse_bad_values_with_one_line(values, words):
    for call in (lambda: driftfmu.montecarlo("gaussian", runs=2, n=10, **values),
                 lambda: driftfmu.montecarlo("sinusoidal", runs=2, n=10, **values),
                 lambda: driftfmu.sweep(a2=(0.01,), R=(1e-4,), runs=2, n=10, **values)):
        with pytest.raises(ValueError) as info:
            call()
        assert words in str(info.value) and "\n" not in str(info.value)


def test_the_command_line_takes_them_and_refuses_bad_values(tmp_path):
    def run(*args):
        return subprocess.run([sys.executable, "-m", "driftfmu", *args], capture_output=True,
                              text=True)
    done = run("montecarlo", "gaussian", "--runs", "4", "--n", "80", "--workers", "1",
               "--flicker", "0.01", "--tau_min", "0.01", "--theta", "0.2", "--T", "301",
               "--kT_bias", "0.001", "--out", str(tmp_path / "mc"))
    assert done.returncode == 0, done.stderr
    import json
    params = json.loads((tmp_path / "mc" / "summary.json").read_text())["parameters"]
    assert (params["flicker"], params["tau_min"], params["theta"], params["T"]) == \
        (0.01, 0.01, 0.2, 301.0)
    for args, words in ((("montecarlo", "gaussian", "--bias_on", "-1"),
                         "bias_on = -1.0 is out of range; allowed: bias_on >= 0"),
                        (("sweep", "--flicker", "0.1", "--tau_min", "9", "--tau_max", "9"),
                         "are not a band")):
        done = run(*args, "--runs", "2", "--n", "10", "--out", str(tmp_path / "bad"))
        assert done.returncode == 2 and words in done.stderr, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1
        assert not (tmp_path / "bad").exists()


@pytest.mark.integration
def test_the_fmu_engine_gives_the_batch_engines_bits(fmus_in_build_layout):
    """montecarlo's FMU engine co-simulates the FMUs (their start values carry the slow errors,
    the tilt and temperature as start values of the Accelerometer's inputs) and checks them
    against models/: the same numbers as the batch engine."""
    values = dict(ALL_ON)
    kw = dict(runs=2, n=60, workers=1, fmu_dir=str(fmus_in_build_layout))
    fmu = driftfmu.montecarlo("gaussian", engine="fmu", **kw, **values)
    bat = driftfmu.montecarlo("gaussian", engine="batch", **kw, **values)
    for key in ("fig1_x", "fig1_z", "fig1_dc1", "fig1_dc3", "fig1_dc_empirical"):
        assert fmu[key].tobytes() == bat[key].tobytes(), key
