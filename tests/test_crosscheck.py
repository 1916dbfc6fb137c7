"""FMI cross-check artifacts: layout by the cross-check rules, references checked against models/
and regenerated through two other importers (JavaFMI and libcosim) within the stated tolerance."""
import pytest

from driftfmu.fmu_src import crosscheck
from importers import drivers
from driftfmu import __version__ as VERSION
from driftfmu.simulations.cli import main

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def tree(built_fmus, tmp_path_factory):
    root = tmp_path_factory.mktemp("cross-check")
    dirs = crosscheck.write_cross_check(built_fmus, root, version=VERSION)
    return root, {d.name: d for d in dirs}


def _files(d, name):
    return {"fmu": d / ("%s.fmu" % name), "in": d / ("%s_in.csv" % name),
            "ref": d / ("%s_ref.csv" % name), "opt": d / ("%s_ref.opt" % name),
            "readme": d / "ReadMe.txt"}


def test_layout_follows_the_cross_check_rules(tree):
    from fmpy.cross_check.validate_vendor_repo import validate_test_fmu
    root, dirs = tree
    assert sorted(dirs) == sorted(crosscheck.FMU_NAMES)
    for name, d in dirs.items():
        assert d == root / "fmus" / "2.0" / "cs" / "linux64" / "driftfmu" / VERSION / name
        f = _files(d, name)
        assert f["fmu"].is_file() and f["ref"].is_file() and f["opt"].is_file()
        assert f["readme"].is_file()
        # an input file for the chain's inputs, or for inputs held at their start values
        # (the Excitation's u_in, the DriftEstimator's u)
        assert f["in"].is_file() == bool(crosscheck.INPUTS[name]
                                         or crosscheck.other_inputs(f["fmu"], name))
        assert validate_test_fmu(str(d)) == []   # fmpy's validator of the cross-check repo


def test_options_and_readme_state_the_settings(tree):
    from fmpy.util import read_ref_opt_file
    _, dirs = tree
    for name, d in dirs.items():
        opts = read_ref_opt_file(str(_files(d, name)["opt"]))
        assert opts == {"StartTime": 0.0, "StopTime": 0.199, "StepSize": 1e-3,
                        "RelTol": crosscheck.REL_TOL}
        text = _files(d, name)["readme"].read_text()
        assert "absolute tolerance of 1e-12" in text and "Timing" in text


def test_references_equal_models_under_the_cross_check_timing(tree):
    _, dirs = tree
    master = crosscheck.chain_columns(crosscheck.N_SAMPLES)
    for name, d in dirs.items():
        f = _files(d, name)
        inputs = crosscheck.read_csv(f["in"]) if f["in"].is_file() else {}
        inputs.pop("time", None)
        for c in crosscheck.INPUTS[name]:
            assert inputs[c] == master[c]      # the inputs are the chain's signals, exactly
        ref = crosscheck.read_csv(f["ref"])
        expected = crosscheck.held_input_reference(name, inputs, crosscheck.N_SAMPLES)
        cols = ("time",) + crosscheck.OUTPUTS[name]
        assert list(ref) == list(cols)
        diffs = crosscheck.max_abs_diff(ref, expected, cols)
        assert max(diffs.values()) <= crosscheck.TOLERANCE, (name, diffs)
    # where the timing allows it, the references are our master's rows themselves
    ex = crosscheck.read_csv(_files(dirs["Excitation"], "Excitation")["ref"])
    assert ex["x"] == master["x"]
    est = crosscheck.read_csv(_files(dirs["DriftEstimator"], "DriftEstimator")["ref"])
    assert abs(est["x_hat"][0] - master["x_hat"][0]) <= crosscheck.TOLERANCE


def _regenerate(importer, name, d, classpath=None, workdir=None):
    f = _files(d, name)
    inputs = crosscheck.read_csv(f["in"]) if f["in"].is_file() else {}
    inputs.pop("time", None)
    n = crosscheck.N_SAMPLES
    outputs = crosscheck.OUTPUTS[name]
    if importer == "JavaFMI":
        cols, _ = drivers.run_javafmi(
            classpath, workdir, {name: f["fmu"]}, n, 1e-3,
            inputs={(name, c): v for c, v in inputs.items()}, record={name: outputs},
            order="read-set")
        return {c.split(".", 1)[-1]: v for c, v in cols.items()}
    return drivers.run_libcosim(f["fmu"], name, n, 1e-3, inputs=inputs, record=outputs)


def _check_regenerated(importer, tree, report, **kw):
    _, dirs = tree
    worst = 0.0
    for name, d in dirs.items():
        got = _regenerate(importer, name, d, **kw)
        ref = crosscheck.read_csv(_files(d, name)["ref"])
        diffs = crosscheck.max_abs_diff(got, ref, list(ref))
        assert max(diffs.values()) <= crosscheck.TOLERANCE, (importer, name, diffs)
        worst = max(worst, max(diffs.values()))
    report("CROSS-CHECK %s: regenerated the _ref.csv of %s from _in.csv and _ref.opt, "
           "%d steps each, max |diff| = %.3g (stated tolerance %g)"
           % (importer, ", ".join(dirs), crosscheck.N_SAMPLES, worst, crosscheck.TOLERANCE))


def test_references_regenerated_through_javafmi(tree, tmp_path, report):
    try:
        classpath = drivers.build_javafmi_host()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    _check_regenerated("JavaFMI", tree, report, classpath=classpath, workdir=tmp_path)


def test_references_regenerated_through_libcosim(tree, report):
    try:
        drivers.libcosim()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    _check_regenerated("libcosim", tree, report)


def test_cli_build_writes_the_cross_check_tree(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["build", "--out", "fmus", "--cross-check"]) == 0
    base = tmp_path / "build" / "cross-check" / "fmus" / "2.0" / "cs" / "linux64" / "driftfmu"
    for name in crosscheck.FMU_NAMES:
        assert (base / VERSION / name / ("%s_ref.csv" % name)).is_file()
    assert "cross-check" in capsys.readouterr().out
