"""The Gaussian co-simulation through the built FMUs (fmpy master), against models/."""
import json
import math

import pytest

from driftfmu.models import chain, drift
from driftfmu.simulations import gaussian
from driftfmu.simulations.cli import main
from driftfmu.simulations.cosim import CoSimulationError, cosimulate

pytestmark = pytest.mark.integration

N = 2000  # the letter's run length


@pytest.fixture(scope="module")
def paper_run(built_fmus, tmp_path_factory):
    out = tmp_path_factory.mktemp("gaussian")
    res = gaussian.run_gaussian(out=out, n=N, fmu_dir=built_fmus["Excitation"].parent)
    return out, res


def test_fmu_outputs_equal_models_to_1e12(paper_run):
    _, res = paper_run
    ref = chain.simulate(N, 1)
    for c in chain.FMU_COLUMNS:
        got = res["columns"][c]
        assert len(got) == N
        assert max(abs(a - b) for a, b in zip(got, ref[c])) <= 1e-12, c


def test_samples_line_up_without_a_one_step_lag(paper_run):
    _, res = paper_run
    c = res["columns"]
    # z_k is the measurement of x_k: with the noise known, z_k - h(x_k) is exactly sqrt(R) v_k
    from driftfmu.models import sensor
    for k in (1, 2, 500, N):
        v = sensor.measurement_noise(1, k)
        assert c["z"][k - 1] == sensor.measure(c["x"][k - 1], 0.0, 1.0, 0.01, 1e-4, v)
    # the k-th update uses z_k: the first posterior is the update of the prior with z_1
    from driftfmu.models import ekf
    x1, P1 = ekf.step(0.0, 0.01, c["z"][0], 0.0, 1.0, 0.01, 0.0, 0.01, 1e-4)
    assert (c["x_hat"][0], c["P"][0]) == (x1, P1)


def test_letters_claims_at_the_paper_settings(paper_run):
    _, res = paper_run
    s = res["summary"]
    expected = drift.expected_gap_db(1.0, 0.01, 1e-4)
    assert s["ekf1_ekf2_gap_db"] == pytest.approx(expected, rel=0.10)
    assert s["settled_from_sample"]["ekf1"] <= 250


def test_files_written(paper_run):
    out, res = paper_run
    header = (out / "results.csv").read_text().splitlines()[0]
    assert header.split(",") == list(chain.COLUMNS)
    assert len((out / "results.csv").read_text().splitlines()) == N + 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["validation"]["passed"] is True
    assert summary["parameters"]["a2"] == 0.01
    assert (out / "drift.png").stat().st_size > 10_000
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no staging folder
    assert not list(out.parent.glob(".driftfmu-stage-*"))


def test_failed_validation_writes_nothing(built_fmus, tmp_path, monkeypatch):
    monkeypatch.setattr(gaussian, "TOLERANCE", -1.0)  # every comparison now fails
    with pytest.raises(gaussian.ValidationError, match="differ from models"):
        gaussian.run_gaussian(out=tmp_path / "o", n=20, fmu_dir=built_fmus["Excitation"].parent)
    assert not (tmp_path / "o").exists() or list((tmp_path / "o").iterdir()) == []


# -- bad input at the FMU boundary: fmi2Error with a log line, the host survives ---------------
def _run(built_fmus, start, n=5, step=1e-3):
    fmus = {k: built_fmus[k] for k in gaussian.FMU_NAMES}
    return cosimulate(fmus, gaussian.CONNECTIONS, n, step, start_values=start)


@pytest.mark.parametrize("start,text", [
    ({"DriftEstimator": {"R": -1.0}}, "R = -1.0 is out of range; allowed: R > 0"),
    ({"Accelerometer": {"a1": 0.0}}, "a1 = 0.0 is out of range; allowed: a1 != 0"),
    ({"Excitation": {"Q": -0.01}}, "Q = -0.01 is out of range; allowed: Q >= 0"),
    ({"DriftEstimator": {"estimator": 7}},
     "estimator = 7 is out of range; allowed: 1 <= estimator <= 3"),
    ({"Accelerometer": {"x": math.nan}}, "x = nan is not finite"),
])
def test_bad_value_gives_fmi2error_with_log_message(backend_fmus, start, text, report):
    with pytest.raises(CoSimulationError) as info:  # on every backend (tests/conftest.py)
        _run(backend_fmus, start)
    msg = str(info.value)
    report("refused, as it must be: %s -> %s" % (start, " | ".join(msg.splitlines())))
    assert "status 3 (error)" in msg
    assert text in msg


def test_step_that_is_not_finite_is_an_error(built_fmus, report):
    with pytest.raises(CoSimulationError) as info:
        _run(built_fmus, {}, step=math.nan)
    report("BAD STEP h = nan s -> %s" % " | ".join(str(info.value).splitlines()))
    assert "status 3 (error)" in str(info.value)
    assert "communication step h = nan s; allowed: a finite h > 0" in str(info.value)


# -- the command line ---------------------------------------------------------------------------
@pytest.mark.parametrize("argv,text", [
    (["run", "gaussian", "--R", "-1"], "argument --R: R = -1.0 is out of range; allowed: R > 0"),
    (["run", "gaussian", "--n", "many"], "argument --n: n = 'many' is not a number"),
    (["run", "gaussian", "--A", "1"], "allowed: A > -1 and A < 1"),
    (["run", "gaussian", "--bogus"], "unrecognized arguments: --bogus"),
    (["frobnicate"], "invalid choice: 'frobnicate'"),
])
def test_cli_bad_option_is_one_line_and_exit_2(argv, text, capsys, report):
    with pytest.raises(SystemExit) as info:
        main(argv)
    err = capsys.readouterr().err
    report("BAD OPTION driftfmu %s -> exit %s: %s" % (" ".join(argv), info.value.code,
                                                       err.strip()))
    assert info.value.code == 2
    assert len(err.strip().splitlines()) == 1
    assert text in err


def test_cli_run_writes_results(built_fmus, tmp_path, capsys):
    out = tmp_path / "new" / "folder"
    code = main(["run", "gaussian", "--n", "300", "--a2", "0.02", "--out", str(out),
                 "--fmu-dir", str(built_fmus["Excitation"].parent)])
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == ["drift.png", "results.csv", "summary.json"]
    assert json.loads((out / "summary.json").read_text())["parameters"]["a2"] == 0.02
    assert "validation: FMU outputs equal models/" in capsys.readouterr().out
