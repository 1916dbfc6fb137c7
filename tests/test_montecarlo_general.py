"""``driftfmu montecarlo`` with the general sensor (issue 16): ``a3, a4, B`` and the known
input's settings, on the batch engine (NumPy: the compiled kernel has the letter's sensor only)
and the FMU engine.  Off, they give today's bits; on, each run is ``models.chain.simulate`` of
its seed and the FMUs' run; the summary's expected drift is the closed form."""
import json
import math

import numpy as np
import pytest

from driftfmu.models import chain, excitation
from driftfmu.simulations import batch, montecarlo
from driftfmu.simulations.cli import main

RUNS = 40
N = 200
#: The general model at values where every term counts (Gaussian input through B).
GENERAL = dict(a3=0.004, a4=0.003, B=0.8, drive=excitation.GAUSSIAN, Qu=0.2)
MODEL = dict(a0=0.2, a1=0.9, a2=0.02, A=0.4, Q=0.3, R=1e-3)


def test_explicit_zeros_are_todays_bits():
    kw = dict(runs=12, n=80, seed=5, workers=1)
    base = montecarlo.montecarlo_gaussian(**kw)
    zeros = montecarlo.montecarlo_gaussian(**kw, a3=0.0, a4=0.0, B=0.0, drive=0, Qu=0.0,
                                           Xu=0.0, fu=0.0)
    for key in montecarlo.GAUSSIAN_KEYS:
        assert np.array_equal(base[key], zeros[key]), key
    assert zeros["summary"]["dc_expected"] == base["summary"]["dc_expected"] == 0.01 * 0.01
    assert "a4" not in zeros["summary"]["parameters"]
    sine = montecarlo.montecarlo_sinusoidal(**kw)
    sine0 = montecarlo.montecarlo_sinusoidal(**kw, a3=0.0, a4=0.0)
    for key in montecarlo.SINE_KEYS:
        assert np.array_equal(sine[key], sine0[key]), key


@pytest.fixture(scope="module")
def general():
    return montecarlo.montecarlo_gaussian(runs=RUNS, n=N, seed=3, workers=2, **MODEL,
                                          **GENERAL)


def test_general_runs_are_the_chain_of_each_seed_bit_for_bit(general):
    want = chain.simulate(N, batch.run_seeds(3, RUNS), **MODEL, **GENERAL)
    for key, name in montecarlo.GAUSSIAN_KEYS.items():
        assert np.array_equal(general[key], want[name]), key
    # ... and not the letter's chain: the general terms reach every trajectory
    plain = chain.simulate(N, batch.run_seeds(3, RUNS), **MODEL)
    for name in ("x", "z", "dc_ekf1", "dc_realised"):
        assert not np.array_equal(plain[name], want[name]), name


def test_general_summary_expected_drift_is_the_closed_form(general):
    s = general["summary"]
    m2, m4 = excitation.state_moments(MODEL["A"], MODEL["Q"], GENERAL["B"], GENERAL["drive"],
                                      GENERAL["Qu"])
    # E[x^2] = Q/(1-A^2) + B^2 Qu/(1-A^2), E[x^4] = 3 E[x^2]^2 (x Gaussian): eq. 5 with u
    var = (MODEL["Q"] + GENERAL["B"] ** 2 * GENERAL["Qu"]) / (1 - MODEL["A"] ** 2)
    assert m2 == pytest.approx(var, rel=1e-15) and m4 == pytest.approx(3 * var * var,
                                                                      rel=1e-15)
    assert s["dc_expected"] == pytest.approx(MODEL["a2"] * var + 3 * GENERAL["a4"] * var ** 2,
                                             rel=1e-15)
    assert s["parameters"]["a4"] == GENERAL["a4"] and s["parameters"]["drive"] == 1
    assert "expected" not in s["ekf1_ekf2_gap_db"]  # the quadratic sensor's closed form
    # the realised drift mean(h(x) - a0 - a1 x) per run, at the last sample, over the runs:
    # its mean is the expected drift within 4 standard errors (x0 = 0 is not stationary, so
    # the first samples pull it low by about a2 var / (n (1 - A^2)): far inside the band)
    realised = general["fig1_dc_realised"][:, -1]
    se = realised.std(ddof=1) / math.sqrt(RUNS)
    assert abs(realised.mean() - s["dc_expected"]) <= 4 * se
    assert 4 * se < GENERAL["a4"] * m4  # the band tells a missing quartic term apart


def test_sinusoidal_with_a4_expected_drift_and_ekf1():
    res = montecarlo.montecarlo_sinusoidal(runs=20, n=600, seed=4, workers=1, a4=0.02, X=1.0)
    s = res["summary"]
    assert s["dc_expected"] == pytest.approx(0.01 * 0.5 + 0.02 * 3 / 8, rel=1e-15)
    want = batch.simulate(600, batch.run_seeds(4, 20), kind=excitation.SINUSOIDAL,
                          phi=res["sine_phi"], filter_A=0.0, filter_Q=0.5, a4=0.02,
                          record=("dc_ekf1", "dc_realised"))
    assert np.array_equal(res["sine_dc1"], want["dc_ekf1"])
    # over 90 whole periods of the sampled sinusoid (neither 2f nor 4f a multiple of 1/Ts) the
    # means of x^2 and x^4 are X^2/2 and 3 X^4/8 exactly: the realised drift is the closed form
    assert np.allclose(res["sine_dc_realised"][:, -1], s["dc_expected"], rtol=1e-12, atol=0)


def test_bad_general_parameters_are_refused():
    with pytest.raises(ValueError, match="drive = 5 is out of range; allowed: an integer "
                                         "drive >= 0 and drive <= 2"):
        montecarlo.montecarlo_gaussian(runs=2, n=5, drive=5)
    with pytest.raises(ValueError, match="unexpected keyword argument 'B'; allowed: runs, n, "
                                         ".*, summary_only, a3, a4, bias_on, .*, bits$"):
        montecarlo.montecarlo_sinusoidal(runs=2, n=5, B=1.0)
    with pytest.raises(SystemExit) as exc:
        main(["montecarlo", "gaussian", "--a4", "nan"])
    assert exc.value.code == 2


def test_fmu_engine_refuses_a_general_sinusoidal_population_before_building(tmp_path):
    with pytest.raises(ValueError, match="FMU engine runs the sinusoidal state with the "
                                         "letter's sensor only, not with a4 = 0.01"):
        montecarlo.montecarlo_sinusoidal(runs=1, n=5, a4=0.01, engine="fmu",
                                         fmu_dir=tmp_path / "nofmus")
    assert not (tmp_path / "nofmus").exists()


def test_cli_takes_the_general_parameters(tmp_path, capsys):
    out = tmp_path / "mc"
    assert main(["montecarlo", "gaussian", "--runs", "6", "--n", "260", "--a4", "0.003",
                 "--B", "0.8", "--drive", "1", "--Qu", "0.2", "--workers", "1", "--out",
                 str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["parameters"]["a4"] == 0.003 and s["parameters"]["Qu"] == 0.2
    want = montecarlo.montecarlo_gaussian(runs=6, n=260, workers=1, a4=0.003, B=0.8, drive=1,
                                          Qu=0.2)
    with np.load(out / "montecarlo.npz") as z:
        assert np.array_equal(z["fig1_dc1"], want["fig1_dc1"])
    assert main(["montecarlo", "sinusoidal", "--runs", "4", "--n", "260", "--a3", "0.01",
                 "--workers", "1", "--out", str(tmp_path / "s")]) == 0
    s = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert s["parameters"]["a3"] == 0.01


@pytest.mark.integration
def test_fmu_engine_equals_batch_engine_for_the_general_model(built_fmus):
    kw = dict(runs=2, n=40, seed=9, fmu_dir=built_fmus["Excitation"].parent, **MODEL,
              **GENERAL)
    fmu = montecarlo.montecarlo_gaussian(engine="fmu", workers=2, **kw)
    want = montecarlo.montecarlo_gaussian(**kw)
    for key in want:
        if isinstance(want[key], np.ndarray):
            assert np.array_equal(fmu[key], want[key]), key


def test_the_public_api_takes_the_general_parameters():
    import driftfmu
    kw = dict(runs=4, n=50, seed=6, workers=1)
    got = driftfmu.montecarlo("gaussian", a4=0.003, B=0.5, drive=1, Qu=0.1, **kw)
    want = montecarlo.montecarlo_gaussian(a4=0.003, B=0.5, drive=1, Qu=0.1, **kw)
    assert np.array_equal(got["fig1_dc1"], want["fig1_dc1"])
    assert not np.array_equal(got["fig1_dc1"], montecarlo.montecarlo_gaussian(**kw)["fig1_dc1"])
    sw = driftfmu.sweep(a2=[0.02], R=[1e-3], runs=4, n=50, a4=[0.0, 0.002], workers=1)
    assert sw["axis"] == "a4" and sw["grid_dc1"].shape == (2, 1, 4)
