"""FMUs and SSPs that someone else made (issue 40): the campaign's edits (tests/tampering.py:
value references swapped or shared, variables removed or added, start values out of range or
not the FMU's, types, causalities, the GUID, the model identifier and name, the FMI version, a
model description cut or twice, binaries cut, zeroed, renamed or gone, a zip bomb), each at
every entry point: ``simulate`` (both masters), ``driftfmu run``, the API's experiments,
``driftfmu doctor``, the SSP runner and ``driftfmu inputs``.  Each gives the right numbers or
one line naming the file, the part and what is expected (exit status 2), no traceback, no
signal.  The everyday loop runs every edit once (its FMU kind and model in turn) and the cut
binary in a separate process; the qualification runs every edit on every kind and model."""
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import driftfmu
import tampering as T
from driftfmu.simulations import doctor, fmucheck
from driftfmu.simulations.cli import main
from driftfmu.simulations.errors import FileProblem

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parent.parent
KINDS = ("python", "native-fmi2", "native-fmi3")
MODELS = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")
CHAIN = ("Excitation", "Accelerometer", "DriftEstimator")
#: Every column an input of the FMUs may take (its own name or the output wired to it).
RESULT_COLUMNS = ("x", "y", "z", "z_y", "u", "u_in", "z_x", "theta", "T")


@pytest.fixture(scope="module")
def good(python_fmus, native_fmus):
    return {"python": python_fmus, "native-fmi2": native_fmus[2],
            "native-fmi3": native_fmus[3]}


def _folder(kind):
    return Path() if kind == "python" else Path("native") / ("fmi%s" % kind[-1])


def layout(tmp_path, good, kind, model, make):
    """An ``fmu_dir`` holding the FMUs of ``kind`` (links to the good ones) where ``model`` is
    the file ``make(src, dst)`` writes; returns ``(fmu_dir, path of that file)``."""
    fmu_dir = tmp_path / "fmus"
    for k in ("python", "native-fmi2", "native-fmi3"):
        (fmu_dir / _folder(k)).mkdir(parents=True, exist_ok=True)
        for name, path in good[k].items():
            target = fmu_dir / _folder(k) / ("%s.fmu" % name)
            if not target.exists():
                target.symlink_to(path)
    path = fmu_dir / _folder(kind) / ("%s.fmu" % model)
    path.unlink()
    make(good[kind][model], path)
    return fmu_dir, path


def _backend(kind):
    return ("python", 2) if kind == "python" else ("native", int(kind[-1]))


def one_line(text, path):
    """``text`` is one line naming ``path`` (the file someone else made)."""
    lines = [line for line in text.strip().splitlines() if line.strip()]
    assert len(lines) == 1, text
    assert str(path) in lines[0], (path, text)
    assert "Traceback" not in text
    return lines[0]


def api_simulate(fmu_dir, kind, model, path):
    backend, version = _backend(kind)
    try:
        return driftfmu.simulate(fmus=[model], stop_time=0.004, fmu_dir=fmu_dir,
                                 backend=backend, fmi_version=version)
    except ValueError as exc:  # (FileProblem, UsageError: ValueErrors of one line)
        return exc


def check_api(outcome, harmless, reference, path, why=None):
    if harmless:
        assert not isinstance(outcome, Exception), outcome
        assert outcome.dtype == reference.dtype and all(
            np.array_equal(outcome[f], reference[f]) for f in outcome.dtype.names)
        return
    assert isinstance(outcome, FileProblem), (type(outcome), outcome)
    line = one_line(str(outcome), path)
    if why:
        assert re.search(why, line), line


def result_file(folder, n=4, Ts=1e-3):
    """A result CSV with every column an input may take."""
    path = folder / "upstream.csv"
    rows = ["time," + ",".join(RESULT_COLUMNS)]
    rows += ["%r,%s" % (k * Ts, ",".join(repr(0.1 * (k + 1) + j) for j in
                                         range(len(RESULT_COLUMNS)))) for k in range(n)]
    path.write_text("\n".join(rows) + "\n")
    return path


def cli_inputs(path, folder, capsys):
    out = folder / "in.csv"
    rc = main(["inputs", str(path), str(result_file(folder)), "--output-file", str(out)])
    captured = capsys.readouterr()
    return rc, captured.out + captured.err, out


def check_inputs(rc, text, out, harmless, path):
    if harmless:
        assert rc == 0 and out.is_file(), text
        return
    assert rc == 2 and not out.exists(), text
    one_line(text, path)


def cli_doctor(path, capsys):
    rc = doctor.report(path)
    return rc, capsys.readouterr().out


def check_doctor(rc, out, harmless, guid=False):
    verdict = [line for line in out.splitlines() if line.startswith("verdict:")]
    assert len(verdict) == 1, out
    if harmless:
        assert rc == 0 and "will run" in verdict[0], out
    else:
        assert rc == 1 and "will NOT run" in verdict[0], out
        if guid:  # the FMU's own reason, from the instantiation trial
            assert "does not match" in verdict[0], out


#: The fields of the reference results, per (kind, model).
_REFERENCE = {}


def reference(good, kind, model, tmp_path_factory):
    if (kind, model) not in _REFERENCE:
        backend, version = _backend(kind)
        fmu_dir = tmp_path_factory.mktemp("reference")
        (fmu_dir / _folder(kind)).mkdir(parents=True, exist_ok=True)
        for name, path in good[kind].items():
            (fmu_dir / _folder(kind) / ("%s.fmu" % name)).symlink_to(path)
        _REFERENCE[kind, model] = driftfmu.simulate(fmus=[model], stop_time=0.004,
                                                    fmu_dir=fmu_dir, backend=backend,
                                                    fmi_version=version)
    return _REFERENCE[kind, model]


def _cases(everything):
    """(edit, kind, model): every applicable one, or each edit once with its kind and model in
    turn (the loop)."""
    cases = []
    for i, edit in enumerate(T.EDITS):
        options = [(k, m) for k in KINDS for m in MODELS
                   if T.applies(edit, m, 3 if k == "native-fmi3" else 2)]
        if everything:
            cases += [(edit, k, m) for k, m in options]
        else:
            cases.append((edit,) + options[(7 * i) % len(options)])
    return cases


def _guid(edit):
    return edit in ("the GUID changed", "the instantiation token changed")


def _run_edit(edit, kind, model, good, tmp_path, capsys, tmp_path_factory, with_doctor):
    make, _, harmless = T.EDITS[edit]
    fmu_dir, path = layout(tmp_path, good, kind, model, make)
    ref = reference(good, kind, model, tmp_path_factory)
    why = "does not match" if _guid(edit) else None
    check_api(api_simulate(fmu_dir, kind, model, path), harmless, ref, path, why)
    if _guid(edit):
        return  # (the file is well-formed: refused when the FMU is instantiated)
    check_inputs(*cli_inputs(path, tmp_path, capsys), harmless, path)
    if with_doctor:
        check_doctor(*cli_doctor(path, capsys), harmless)


@pytest.mark.parametrize("edit, kind, model", _cases(False))
def test_each_edit_gives_the_right_numbers_or_one_line(edit, kind, model, good, tmp_path,
                                                       capsys, tmp_path_factory):
    """Every edit of the campaign once (its FMU kind and model in turn): ``simulate`` gives
    the untampered numbers (a harmless edit) or one FileProblem line naming the file;
    ``driftfmu inputs`` writes its file or exits 2 with one line; the doctor's verdict agrees."""
    _run_edit(edit, kind, model, good, tmp_path, capsys, tmp_path_factory,
              with_doctor=T.EDITS[edit][2] or edit in (
                  "swapped value references", "the model identifier changed",
                  "the binary cut in half", "A = 1.5", "R = -1"))


@pytest.mark.qualification
@pytest.mark.parametrize("edit, kind, model", _cases(True))
def test_every_edit_of_every_fmu_gives_the_right_numbers_or_one_line(
        edit, kind, model, good, tmp_path, capsys, tmp_path_factory):
    _run_edit(edit, kind, model, good, tmp_path, capsys, tmp_path_factory,
              with_doctor=kind == "python" or model == "DriftEstimator")


# -- in a process of its own: no signal, no traceback ------------------------------------------

def _command(argv, **kw):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "driftfmu"] + argv, capture_output=True,
                          text=True, timeout=600, env=env, **kw)


def _check_command(done, path, harmless):
    assert done.returncode >= 0, "killed by signal %d: %s" % (-done.returncode, done.stderr)
    assert "Traceback" not in done.stderr, done.stderr
    if harmless:
        assert done.returncode == 0, done.stderr
    else:
        assert done.returncode == 2, (done.returncode, done.stderr)
        assert one_line(done.stderr, path).startswith("driftfmu: error: ")


@pytest.mark.parametrize("kind", ["python", "native-fmi2"])
@pytest.mark.parametrize("edit", ["the binary cut in half", "the binary's headers only"])
def test_a_cut_binary_is_one_line_not_sigbus_in_run(edit, kind, good, tmp_path):
    """``driftfmu run`` with a cut DriftEstimator binary stopped with SIGBUS (exit 135): now
    one line naming the binary (its loaded segments reach past its end), exit 2."""
    fmu_dir, path = layout(tmp_path, good, kind, "DriftEstimator", T.EDITS[edit][0])
    done = _command(["run", "gaussian", "--n", "10", "--fmu-dir", str(fmu_dir), "--backend",
                     _backend(kind)[0], "--out", str(tmp_path / "out")])
    _check_command(done, path, False)
    assert "binaries/linux64/DriftEstimator.so: truncated" in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


def _ssp(good, kind, tmp_path, model, make):
    """The chain's SSP of ``kind`` (FMI 2.0) with ``model``'s FMU made by ``make``."""
    from driftfmu.fmu_src.ssp import build_ssp
    fmus = {n: good[kind][n] for n in CHAIN}
    ssp = build_ssp(fmus, tmp_path / "good.ssp", n=5)
    edited = tmp_path / ("%s.fmu" % model)
    make(good[kind][model], edited)
    out = tmp_path / "chain.ssp"
    T.rewrite(ssp, out, members={"resources/%s.fmu" % model: lambda _: edited.read_bytes()})
    return out


def _entry_points(edit, kind, model, good, tmp_path):
    """The command-line entry points and the API's experiment on one edited FMU, each in a
    process of its own where it loads the FMU."""
    make, _, harmless = T.EDITS[edit]
    fmu_dir, path = layout(tmp_path, good, kind, model, make)
    backend = _backend(kind)[0]
    out = tmp_path / "out"
    if model in CHAIN:
        done = _command(["run", "gaussian", "--n", "10", "--fmu-dir", str(fmu_dir),
                         "--backend", backend, "--out", str(out)])
        _check_command(done, path, harmless)
        assert out.exists() == harmless
    # the API's experiment that loads all four FMUs (both estimators)
    code = ("import sys, driftfmu\ntry:\n    driftfmu.experiment_dual_axis(points=2, runs=1, "
            "n=30, fmu_dir=sys.argv[1], backend=sys.argv[2], workers=1)\nexcept ValueError "
            "as exc:\n    print(exc, file=sys.stderr); sys.exit(2)\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, "-c", code, str(fmu_dir), backend],
                          capture_output=True, text=True, timeout=600, env=env)
    assert done.returncode >= 0 and "Traceback" not in done.stderr, done.stderr
    assert done.returncode == (0 if harmless else 2), done.stderr
    if not harmless:
        one_line(done.stderr, path)
    done = _command(["doctor", str(path)])
    assert done.returncode == (0 if harmless else 1), done.stdout + done.stderr
    done = _command(["inputs", str(path), str(result_file(tmp_path)), "--output-file",
                     str(tmp_path / "in.csv")])
    _check_command(done, path, harmless or _guid(edit))
    if model in CHAIN and kind != "native-fmi3":  # the SSP runner (fmpy's simulate_ssp)
        ssp = _ssp(good, kind, tmp_path, model, make)
        code = ("import sys\nfrom driftfmu.fmu_src import ssp\ntry:\n    ssp.simulate("
                "sys.argv[1], 5)\nexcept (ValueError, RuntimeError) as exc:\n    "
                "print(exc, file=sys.stderr); sys.exit(2)\n")
        done = subprocess.run([sys.executable, "-c", code, str(ssp)], capture_output=True,
                              text=True, timeout=600, env=env)
        assert done.returncode >= 0 and "Traceback" not in done.stderr, done.stderr
        assert done.returncode == (0 if harmless else 2), done.stderr
        if not harmless:
            line = one_line(done.stderr, ssp)
            assert "resources/%s.fmu" % model in line or _guid(edit), line


@pytest.mark.parametrize("edit, kind", [("swapped value references", "python"),
                                        ("the GUID changed", "native-fmi2")])
def test_the_entry_points_in_processes_of_their_own(edit, kind, good, tmp_path):
    _entry_points(edit, kind, "DriftEstimator", good, tmp_path)


#: The edits the native FMUs' entry points run too in the qualification (the ones whose path
#: through a native library differs: its binary, its instantiation, its value references).
NATIVE_EDITS = ("swapped value references", "the GUID changed", "the binary cut in half",
                "the binary's headers only", "the binary zeroed", "the binary renamed",
                "re-packed by another tool", "A = 1.5")


@pytest.mark.qualification
@pytest.mark.parametrize("edit, kind", [(e, "python") for e in T.EDITS
                                        if T.applies(e, "DriftEstimator", 2)]
                         + [(e, "native-fmi2") for e in NATIVE_EDITS])
def test_every_edit_at_every_entry_point_in_processes_of_their_own(edit, kind, good, tmp_path):
    _entry_points(edit, kind, "DriftEstimator", good, tmp_path)


# -- what the issue saw, by name ---------------------------------------------------------------

def test_swapped_value_references_no_longer_give_swapped_columns(good, tmp_path):
    fmu_dir, path = layout(tmp_path, good, "python", "DriftEstimator",
                           T.EDITS["swapped value references"][0])
    with pytest.raises(FileProblem) as info:
        driftfmu.simulate(stop_time=0.01, fmu_dir=fmu_dir)
    assert str(info.value) == (
        "%s: modelDescription.xml: x_hat has the value reference 15, which is P's; expected: "
        "14, as in driftfmu's DriftEstimator: a host reads and writes by value reference, so "
        "it would get another variable's values (1 more difference from the table); the file "
        "as driftfmu build writes it (rebuild it: driftfmu build)" % path)


@pytest.mark.parametrize("name, value, allowed", [
    ("A", "1.5", "A >= -0.9999999999999999 and A <= 0.9999999999999999 (driftfmu's rule for "
                 "A: A > -1 and A < 1)"),
    ("R", "-1", "R >= 5e-324 (driftfmu's rule for R: R > 0)"),
    ("Ts", "0", "Ts >= 1e-09"),
    ("estimator", "7", "estimator >= 1 and estimator <= 3")])
def test_start_values_outside_their_declared_range_are_named(name, value, allowed, good,
                                                             tmp_path):
    fmu_dir, path = layout(tmp_path, good, "native-fmi3", "DriftEstimator",
                           T.EDITS["%s = %s" % (name, value)][0])
    with pytest.raises(FileProblem) as info:
        driftfmu.simulate(fmus=["DriftEstimator"], stop_time=0.01, fmu_dir=fmu_dir,
                          backend="native", fmi_version=3)
    assert str(info.value) == ("%s: modelDescription.xml: the start value of %s is %s, "
                               "outside its declared range; expected: %s"
                               % (path, name, value, allowed))


@pytest.mark.parametrize("edge", [-1, 0, 1])
def test_a_start_value_at_and_beside_its_declared_bound(edge, good, tmp_path):
    """Both sides of a declared bound: ``min`` itself is accepted (FMI 2.0's bounds are
    closed), the double below it is not; a driftfmu table's start value must be its own."""
    from driftfmu.models.parameters import next_float
    low = 5e-324  # R's declared min
    value = {-1: 0.0, 0: low, 1: next_float(low, 1.0)}[edge]
    src = good["python"]["Accelerometer"]
    desc = T.model_of(src)
    edited = T.rewrite(src, tmp_path / "Accelerometer.fmu",
                       lambda t: T.edit_variable(t, desc.fmi, "R", "start", repr(value)))
    desc = T.model_of(edited)
    ranges = fmucheck.range_problems(desc)
    assert bool(ranges) == (edge < 0), ranges
    # (in range, but not the value the FMU's code starts R at: the table says so)
    assert fmucheck.table_problems(desc)[0][0] == "the start value of R is %r" % value


def test_a_changed_model_identifier_names_the_real_problem(good, tmp_path, capsys):
    """It said "no binary for this platform (linux64); it has: linux64"."""
    path = T.EDITS["the model identifier changed"][0](good["python"]["Accelerometer"],
                                                       tmp_path / "Accelerometer.fmu")
    desc = T.model_of(path)
    with zipfile.ZipFile(path) as z:
        problem = fmucheck.binary_presence_problem(path, desc, set(z.namelist()))
    assert problem[0] == ("its modelIdentifier 'Renamed' names binaries/linux64/Renamed.so, "
                          "which the archive does not have; binaries/linux64/ holds "
                          "Accelerometer.so, Accelerometer_pythonfmu.so")
    assert doctor.report(path) == 1
    out = capsys.readouterr().out
    assert "it has: linux64" not in out and "names binaries/linux64/Renamed.so" in out, out


def test_a_removed_variable_is_named_not_a_bare_key_error(good, tmp_path):
    for kind in ("python", "native-fmi3"):
        path = T.EDITS["a variable removed"][0](good[kind]["DriftEstimator"],
                                                tmp_path / ("%s.fmu" % kind))
        with pytest.raises(FileProblem, match="it has no variable dc_class2; expected: every "
                           "variable of driftfmu's DriftEstimator \\(dc_class2: Real output, "
                           "value reference 38\\)"):
            fmucheck.check_fmu(path)


@pytest.mark.parametrize("kind", ["python", "native-fmi2", "native-fmi3"])
def test_a_changed_guid_says_the_fmus_own_reason(kind, good, tmp_path):
    edit = "the instantiation token changed" if kind == "native-fmi3" else "the GUID changed"
    fmu_dir, path = layout(tmp_path, good, kind, "Accelerometer", T.EDITS[edit][0])
    backend, version = _backend(kind)
    with pytest.raises(FileProblem) as info:
        driftfmu.simulate(fmus=["Accelerometer"], stop_time=0.01, fmu_dir=fmu_dir,
                          backend=backend, fmi_version=version)
    line = one_line(str(info.value), path)
    assert "the FMU could not be instantiated on this host: " in line
    assert "does not match" in line and "Failed to instantiate model" not in line, line


# -- SSPs ---------------------------------------------------------------------------------------

def test_doctor_tells_the_truth_about_our_own_ssp(good, tmp_path, capsys):
    """It said "will NOT run ... no modelDescription.xml" for the SSP driftfmu build writes."""
    from driftfmu.fmu_src.ssp import build_ssp
    ssp = build_ssp({n: good["python"][n] for n in CHAIN}, tmp_path / "chain.ssp", n=5)
    assert doctor.report(ssp) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == "verdict: this SSP will run on this host", out
    checked = [line for line in out.splitlines() if line.startswith("[  ok  ] ")
               and ("] checked: " in line or ".fmu: checked: " in line)]
    assert len(checked) == 4, out  # the SSP's, and each FMU's
    assert "SystemStructure.ssd: system 'DriftChain', 3 components" in checked[-1]
    assert "no modelDescription.xml" not in out


SSD = "SystemStructure.ssd"
ACC, DE = "resources/Accelerometer.ssv", "resources/DriftEstimator.ssv"


def _ssd(ssp, edit, member=SSD):
    """``ssp`` with ``edit`` applied to its ``member``: the system structure, or the parameter
    set (resources/<Component>.ssv) that holds a component's values."""
    return T.rewrite(ssp, ssp.with_name("edited.ssp"), members={
        member: lambda data: edit(data.decode()).encode()})


@pytest.mark.parametrize("member, edit, words", [
    (ACC, lambda t: t.replace('<ssv:Parameter name="R">\n', '<ssv:Parameter name="R">', 1)
     .replace('name="R"><ssv:Real value="0.0001"', 'name="R"><ssv:Real value="-1"', 1),
     "component Accelerometer: R = -1 is out of range; expected: R > 0"),
    (ACC, lambda t: t.replace('<ssv:Parameter name="a2">', '<ssv:Parameter name="a22">', 1),
     "component Accelerometer has no variable 'a22' to set; expected: one of its parameters"),
    (DE, lambda t: t.replace('<ssv:Parameter name="estimator">',
                             '<ssv:Parameter name="z_comp">', 1),
     "component DriftEstimator: z_comp is an output variable, which a parameter set cannot "
     "set"),
    (SSD, lambda t: t.replace('endConnector="z"', 'endConnector="zz"', 1),
     "a connection's end is DriftEstimator.zz, which that FMU does not have"),
    (SSD, lambda t: t.replace('source="resources/Excitation.fmu"', 'source="resources/E.fmu"',
                              1),
     "component Excitation has the source 'resources/E.fmu', which the archive does not "
     "have"),
])
def test_ssp_parameters_and_connections_are_checked_by_component_and_name(member, edit, words,
                                                                          good, tmp_path,
                                                                          capsys):
    """An SSP parameter out of range said "fmi2ExitInitializationMode failed with status 3",
    an unknown one a bare KeyError: now the SSP runner and the doctor name the component and
    the parameter, and the member that holds it (the parameters are in the parameter sets the
    components bind)."""
    from driftfmu.fmu_src import ssp as ssp_module
    ssp = ssp_module.build_ssp({n: good["python"][n] for n in CHAIN}, tmp_path / "c.ssp", n=5,
                               start_values={"Accelerometer": {"a2": 0.02, "R": 1e-4},
                                             "DriftEstimator": {"estimator": 2}})
    text = zipfile.ZipFile(ssp).read(member).decode()
    edited = _ssd(ssp, lambda t: edit(re.sub(r">\s+<", "><", t)), member)
    assert zipfile.ZipFile(edited).read(member).decode() != text
    words = "%s: %s" % (member, words)
    with pytest.raises(FileProblem) as info:
        ssp_module.simulate(edited, 5)
    line = one_line(str(info.value), edited)
    assert words in line, line
    problems, _, _ = fmucheck.inspect_ssp(edited, tmp_path)  # (what the doctor lists)
    assert any(words in p for p in problems), problems


def test_the_doctor_names_an_ssp_parameter_out_of_range(good, tmp_path, capsys):
    from driftfmu.fmu_src import ssp as ssp_module
    ssp = ssp_module.build_ssp({n: good["python"][n] for n in CHAIN}, tmp_path / "c.ssp", n=5)
    edited = _ssd(ssp, lambda t: t.replace('<ssv:Real value="0.0001" />', '<ssv:Real '
                                           'value="-1" />', 1), ACC)
    assert doctor.report(edited) == 1
    verdict = capsys.readouterr().out.splitlines()[-1]
    assert verdict.startswith("verdict: this SSP will NOT run on this host as it is: %s: "
                              "resources/Accelerometer.ssv: component Accelerometer: R = -1 is "
                              "out of range; expected: R > 0" % edited), verdict


def test_the_ssp_runner_runs_our_ssp_after_its_checks(good, tmp_path):
    from driftfmu.fmu_src import ssp as ssp_module
    ssp = ssp_module.build_ssp({n: good["python"][n] for n in CHAIN}, tmp_path / "c.ssp", n=5)
    rows = ssp_module.simulate(ssp, 5)
    ref = ssp_module.jacobi_reference(5)
    assert np.array_equal(rows["DriftEstimator.x_hat"], ref["DriftEstimator.x_hat"])


# -- a zip bomb ---------------------------------------------------------------------------------

def _peak_rss(argv):
    """(exit status, stdout, stderr, peak RSS in bytes) of ``driftfmu argv`` in a child."""
    import peakrss
    return peakrss.run(argv)


#: The memory bound of issue 40.
MEMORY_BOUND = 200 * 2 ** 20


def test_a_3_gib_zip_bomb_is_refused_by_its_declaration_within_200_mb(good, tmp_path, report):
    """A 3 MB FMU with a member that declares (and holds) 3 GiB of zeros: the doctor read every
    member whole (3.2 GB, then MemoryError); now the doctor and the masters refuse it by what
    it declares, in one line, the process's peak RSS under 200 MB."""
    fmu_dir, bomb = layout(tmp_path, good, "python", "Excitation", T.zip_bomb)
    assert bomb.stat().st_size < 8 * 2 ** 20
    with zipfile.ZipFile(bomb) as z:
        assert z.getinfo("resources/bomb.bin").file_size == 3 << 30
    rc, out, err, peak = _peak_rss(["doctor", str(bomb)])
    assert rc == 1 and "resources/bomb.bin: the member declares 3 GiB uncompressed" in out, out
    assert peak < MEMORY_BOUND, peak
    rc, out, err, peak2 = _peak_rss(["run", "gaussian", "--n", "10", "--fmu-dir",
                                     str(fmu_dir), "--out", str(tmp_path / "out")])
    assert rc == 2 and "resources/bomb.bin: the member declares 3 GiB" in one_line(err, bomb)
    assert peak2 < MEMORY_BOUND, peak2
    report("a 3 GiB zip bomb (%.1f MB on disk): doctor's peak RSS %.0f MB, run's %.0f MB"
           % (bomb.stat().st_size / 2 ** 20, peak / 2 ** 20, peak2 / 2 ** 20))


# -- binaries of other platforms, read by their headers ----------------------------------------

@pytest.mark.parametrize("member, system", [("binaries/win64/DriftEstimator.dll", "Windows"),
                                            ("binaries/darwin64/DriftEstimator.dylib",
                                             "Darwin"),
                                            ("binaries/linux64/DriftEstimator.so", "Linux")])
def test_binaries_of_every_format_are_whole_or_named_as_cut(member, system, good):
    """ELF, PE and Mach-O (universal) libraries of the native FMU: whole, each is accepted for
    its platform; cut anywhere past its headers, each is named as truncated; zeroed, as not a
    library of its format."""
    with zipfile.ZipFile(good["native-fmi2"]["DriftEstimator"]) as z:
        if member not in z.namelist():
            pytest.skip("%s was not built here (no compiler for it)" % member)
        data = z.read(member)

    def problem(d):
        return fmucheck.binary_problem(lambda o, n: d[o:o + n], len(d), system, "x86_64")
    assert problem(data) is None
    for cut in (len(data) - 1, len(data) // 2, 4096, 200):
        assert problem(data[:cut]).startswith("truncated: the file has %d bytes" % cut), cut
    assert problem(bytes(len(data))).startswith("not ")
    assert problem(b"") == "an empty file"


# -- a property: random edits of the model description ------------------------------------------

_ATTRIBUTES = ("name", "valueReference", "causality", "variability", "start", "min", "max")
_VALUES = st.one_of(st.integers(-3, 40).map(str), st.floats(allow_nan=True).map(repr),
                    st.sampled_from(["", "x", "-0", "1e400", "nan", "inf", "parameter", "input",
                                     "output", "local", "fixed", "tunable", "discrete",
                                     "continuous", "z", "x_hat", "P", "Ts", "4294967295"]))


def _md_edit(draw_variable, attribute, value, delete):
    def edit(text):
        fmi = 3 if 'fmiVersion="3.0"' in text else 2
        names = re.findall(r'<(?:ScalarVariable|Float64|Int32)\s+name="([^"]+)"', text)
        name = names[draw_variable % len(names)]
        if delete:
            return T._variable_pattern(fmi, name).sub("", text, count=1)
        return T.edit_variable(text, fmi, name, attribute, value)
    return edit


def _property(kind, model, good, tmp_path_factory, variable, attribute, value, delete):
    folder = tmp_path_factory.mktemp("md_edit")
    make = (lambda s, d: T.rewrite(s, d, _md_edit(variable, attribute, value, delete)))
    fmu_dir, path = layout(folder, good, kind, model, make)
    outcome = api_simulate(fmu_dir, kind, model, path)
    if isinstance(outcome, Exception):
        assert isinstance(outcome, FileProblem), (type(outcome), outcome)
        one_line(str(outcome), path)
    else:  # (an edit that changed nothing a host relies on): the untampered numbers
        ref = reference(good, kind, model, tmp_path_factory)
        assert all(np.array_equal(outcome[f], ref[f]) for f in ref.dtype.names)
    shutil.rmtree(folder)


@settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
@given(variable=st.integers(0, 40), attribute=st.sampled_from(_ATTRIBUTES), value=_VALUES,
       delete=st.booleans())
def test_random_edits_of_the_model_description_give_the_numbers_or_one_line(
        good, tmp_path_factory, variable, attribute, value, delete):
    _property("python", "Accelerometer", good, tmp_path_factory, variable, attribute, value,
              delete)


@pytest.mark.qualification
@pytest.mark.parametrize("kind", KINDS)
@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(model=st.sampled_from(MODELS), variable=st.integers(0, 40),
       attribute=st.sampled_from(_ATTRIBUTES), value=_VALUES, delete=st.booleans())
def test_random_edits_of_every_model_description_give_the_numbers_or_one_line(
        kind, model, good, tmp_path_factory, variable, attribute, value, delete):
    _property(kind, model, good, tmp_path_factory, variable, attribute, value, delete)
