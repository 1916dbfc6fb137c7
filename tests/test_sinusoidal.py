"""The sinusoidal co-simulation through the built FMUs (fmpy master), against models/."""
import json
import math

import pytest

from driftfmu.models import adxl203, harmonic
from driftfmu.simulations import sinusoidal
from driftfmu.simulations.cli import main

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def fmu_dir(built_fmus):
    return built_fmus["Excitation"].parent


@pytest.fixture(scope="module")
def harmonic_run(fmu_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("sinusoidal")
    return out, sinusoidal.run_sinusoidal(out=out, X=1.0, f=150.0, n=2000, fmu_dir=fmu_dir)


def test_fmus_equal_models_and_all_outputs_are_written(harmonic_run):
    out, res = harmonic_run
    s = res["summary"]
    assert s["validation"]["passed"]
    assert max(s["validation"]["max_abs_diff"].values()) == 0.0
    assert {p.name for p in out.iterdir()} == {"results.csv", "summary.json", "drift.png"}
    header = (out / "results.csv").read_text().splitlines()[0]
    assert header == ",".join(("time", "x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3",
                               "dc_empirical", "dc_realised", "dc_expected", "z_comp"))
    assert json.loads((out / "summary.json").read_text())["process"] == "harmonic"


def test_harmonic_ekf1_within_1_percent_of_a2_X2_over_2(harmonic_run):
    _, res = harmonic_run
    f = res["summary"]["final"]
    assert f["dc_expected"] == 0.01 * 1.0 / 2
    assert f["dc_ekf1"] == pytest.approx(f["dc_expected"], rel=0.01)
    assert res["summary"]["whole_periods"] == {"samples": 2000, "periods": 300.0}


def test_x_is_the_sinusoid_at_the_sample_times(harmonic_run):
    _, res = harmonic_run
    c = res["columns"]
    for k in (1, 2, 777, 2000):
        assert c["time"][k - 1] == pytest.approx((k - 1) * 1e-3)
        assert c["x"][k - 1] == pytest.approx(math.sin(2 * math.pi * 150.0 * (k - 1) * 1e-3),
                                              abs=1e-12)


def test_gauss_markov_filter_is_selectable_and_validates(fmu_dir):
    res = sinusoidal.run_sinusoidal(X=1.0, f=50.0, n=1000, process=harmonic.GAUSS_MARKOV,
                                    fmu_dir=fmu_dir, plot=False)
    s = res["summary"]
    assert s["process"] == "Gauss-Markov" and s["validation"]["passed"]
    assert s["final"]["dc_ekf1"] == pytest.approx(0.005, rel=0.05)


def test_frequency_at_or_above_nyquist_is_refused_and_nothing_written(fmu_dir, tmp_path):
    for f in (500.0, 800.0):
        with pytest.raises(ValueError, match=r"allowed: 0 < f < 1/\(2 Ts\) = 500"):
            sinusoidal.run_sinusoidal(out=tmp_path / "o", f=f, n=100, fmu_dir=fmu_dir)
    assert not (tmp_path / "o").exists()


def test_fmu_refuses_a_harmonic_filter_above_nyquist(fmu_dir):
    from driftfmu.simulations.cosim import CoSimulationError, cosimulate
    with pytest.raises(CoSimulationError, match="Nyquist"):
        cosimulate({"DriftEstimator": fmu_dir / "DriftEstimator.fmu"}, (), 3, 1e-3,
                   start_values={"DriftEstimator": dict(process=2, f=600.0, Ts=1e-3)})


def test_cli_run_sinusoidal(fmu_dir, tmp_path, capsys):
    rc = main(["run", "sinusoidal", "--n", "600", "--f", "100", "--X", "1.2",
               "--out", str(tmp_path), "--fmu-dir", str(fmu_dir)])
    text = capsys.readouterr().out
    assert rc == 0 and "harmonic filter" in text and "validation: FMU outputs equal" in text
    # the references in the order of run gaussian's line (cli.cmd_run_gaussian)
    import re
    assert re.search(r"^final drift \[V\]: EKF1 \S+, EKF2 \S+, EKF3 \S+ \| realised \S+, "
                     r"empirical over \d+ whole periods \S+, expected \S+$", text, re.M), text
    rc = main(["run", "sinusoidal", "--f", "700", "--out", str(tmp_path / "x"),
               "--fmu-dir", str(fmu_dir)])
    assert rc == 2 and "Nyquist" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_state_restore_replays_the_preset_accelerometer(fmu_dir, tmp_path):
    """The low-pass state is hidden state: a restored FMU repeats the same outputs."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    path = str(fmu_dir / "Accelerometer.fmu")
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(path, unzipdir=tmp_path),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="a")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    p = dict(adxl203.ADXL203, Ts=1e-4)
    fmu.setReal([vr[k] for k in p if k not in ("bits", "axes")],
                [float(v) for k, v in p.items() if k not in ("bits", "axes")])
    fmu.setInteger([vr["bits"], vr["axes"]], [12, 2])
    fmu.exitInitializationMode()

    def run(k0, steps):
        out = []
        for i in range(steps):
            fmu.setReal([vr["x"]], [math.sin(0.3 * (k0 + i))])
            out.append(fmu.getReal([vr["z"], vr["z_y"]]))
            fmu.doStep(currentCommunicationPoint=(k0 + i) * 1e-4, communicationStepSize=2e-4)
        return out

    run(0, 5)
    state = fmu.getFMUstate()
    first = run(5, 10)
    fmu.setFMUstate(state)
    assert run(5, 10) == first
    fmu.freeFMUstate(state)
    fmu.terminate()
    fmu.freeInstance()
