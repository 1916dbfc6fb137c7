"""Issue 19: checks before the work, help for a bare command, reasons in the messages.

Every usage error exits 2 with one line naming the value and what is allowed, before anything
is built, run or written."""
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from driftfmu.simulations.cli import main
from waiting import BOUND, sigint_default, wait_for

ROOT = Path(__file__).resolve().parent.parent


def _status(argv):
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _last_line(err):
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert lines and "Traceback" not in err, err
    return lines[-1]


def _one_line(err):
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# -- help ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv,commands", [
    ([], ("build", "run", "doctor", "sweep", "montecarlo", "experiment", "identify")),
    (["run"], ("gaussian", "sinusoidal")),
    (["experiment"], ("adxl203", "dual-axis")),
    (["montecarlo"], ("gaussian", "sinusoidal")),
])
def test_a_bare_command_prints_its_usage_and_names_its_choices(argv, commands, capsys):
    assert _status(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: driftfmu")
    last = _last_line(err)
    assert last.startswith("driftfmu: error:") and "needs one of" in last
    for c in commands:
        assert c in last


def test_the_help_names_both_fmi_versions(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "FMI 2.0 and 3.0" in " ".join(out.split())


# -- checks before the work ------------------------------------------------------------------------

@pytest.mark.parametrize("argv,words", [
    (["sweep", "--scheduler", "nonsense"], ("scheduler = 'nonsense'", "HOST:PORT")),
    (["sweep", "--scheduler", "tcp://host:99999"], ("99999", "HOST:PORT")),
    (["montecarlo", "gaussian", "--scheduler", "tcp//x"], ("tcp//x",)),
    (["experiment", "dual-axis", "--scheduler", "x y"], ("'x y'",)),
    (["sweep", "--out", ""], ("--out ''", "is empty")),
    (["run", "gaussian", "--out", " "], ("is empty",)),
    (["build", "--out", ""], ("is empty",)),
    (["build", "--ssp", ""], ("--ssp", "is empty")),
    (["experiment", "adxl203", "--freqs", "100,100"], ("100 Hz more than once", "distinct")),
    (["experiment", "adxl203", "--freqs", "100,200,100.0"], ("100 Hz more than once",)),
])
def test_a_bad_setting_is_a_usage_error_before_anything_runs(argv, words, tmp_path, capsys,
                                                             monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc = _status(argv)
    line = _one_line(capsys.readouterr().err)
    assert rc == 2, line
    for w in words:
        assert w in line, line
    assert os.listdir(tmp_path) == []  # nothing built, run or written


def test_a_cross_check_path_that_is_a_file_is_refused_before_the_build(tmp_path, capsys):
    f = tmp_path / "afile.txt"
    f.write_text("x")
    rc = _status(["build", "--out", str(tmp_path / "fmus"), "--cross-check", str(f)])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2 and "--cross-check" in line and "existing file" in line
    assert not (tmp_path / "fmus").exists()


@pytest.mark.parametrize("argv", [
    ["sweep", "--runs", "10"],
    ["run", "gaussian", "--n", "10"],
    ["build"],
])
def test_an_out_folder_that_cannot_be_written_is_refused_before_the_run(argv, tmp_path, capsys):
    # /proc/1 cannot take a new folder, not even for root; a file as a parent cannot either
    parent_file = tmp_path / "file"
    parent_file.write_text("x")
    for out in ("/proc/1/driftfmu-out", str(parent_file / "sub")):
        rc = _status(argv + ["--out", out])
        line = _one_line(capsys.readouterr().err)
        assert rc == 2, line
        assert "--out %s cannot be" % out in line and "allowed:" in line, line
    assert sorted(os.listdir(tmp_path)) == ["file"]


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write into a read-only folder")
def test_a_read_only_out_folder_is_refused_before_the_run(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        rc = _status(["sweep", "--runs", "10", "--out", str(ro / "res")])
        line = _one_line(capsys.readouterr().err)
        assert rc == 2 and "cannot be written" in line
    finally:
        ro.chmod(0o700)


def test_the_scheduler_check_accepts_real_addresses():
    pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] is not installed")
    from driftfmu.simulations.batch import scheduler_address
    for ok in ("tcp://127.0.0.1:8786", "localhost:8786", "tls://host.example:1",
               "tcp://[::1]:8786", "inproc://abc"):
        assert scheduler_address(ok) == ok


# -- dependencies ----------------------------------------------------------------------------------

#: Make these imports fail, as in a default install without the extras.
WITHOUT_EXTRAS = ("import sys\n"
                  "for m in ('dask', 'distributed', 'scipy'):\n"
                  "    sys.modules[m] = None\n"
                  "from driftfmu.simulations.cli import main\n")


def test_the_main_jobs_run_without_the_extras(tmp_path):
    script = WITHOUT_EXTRAS + ("rc = main(['sweep', '--runs', '20', '--n', '50', '--out', 'sw'])\n"
                               "rc = rc or main(['montecarlo', 'gaussian', '--runs', '8', '--n', "
                               "'40', '--out', 'mc'])\n"
                               "sys.exit(rc)\n")
    r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True,
                       text=True, timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "sw" / "sweep.npz").exists() and (tmp_path / "mc" / "fig1.png").exists()


def test_scheduler_without_dask_names_the_extra_to_install(tmp_path):
    script = WITHOUT_EXTRAS + "sys.exit(main(['sweep', '--scheduler', 'tcp://127.0.0.1:8786']))\n"
    r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True,
                       text=True, timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 2
    line = _one_line(r.stderr)
    assert "needs Dask" in line and "pip install 'driftfmu[dask]'" in line
    assert os.listdir(tmp_path) == []


def test_the_default_install_leaves_the_extras_out():
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = [d.split(">")[0].split("=")[0].split("[")[0].split(";")[0].strip().lower()
             for d in project["dependencies"]]
    assert "dask" not in names and "scipy" not in names, names
    assert any(d.startswith("dask[distributed]") for d in project["optional-dependencies"]["dask"])
    assert any(d.startswith("scipy") for d in project["optional-dependencies"]["dev"])


# -- input files ---------------------------------------------------------------------------------

@pytest.mark.parametrize("content,words", [
    (bytes(range(256)) * 4, ("not a text CSV file", "time, x, z")),       # not UTF-8
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", ("not a text CSV file",)),  # a picture
    (b"time,x,z\n0,0,0\n\x00\x01,1,1\n", ("line 3", "not a finite number")),  # NUL bytes
])
def test_identify_on_a_binary_file_names_the_file(content, words, tmp_path, capsys):
    f = tmp_path / "rec.bin"
    f.write_bytes(content)
    rc = _status(["identify", str(f), "--f", "50", "--out", str(tmp_path / "o")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 1, line
    assert str(f) in line and "allowed:" in line, line
    for w in words:
        assert w in line, line
    assert not (tmp_path / "o").exists()


# -- size checks before a run ----------------------------------------------------------------------

@pytest.mark.parametrize("argv,words", [
    (["montecarlo", "gaussian", "--runs", "1000000"],
     ("montecarlo gaussian --runs 1000000 --n 1000 needs about", "of memory",
      "at most --runs", "--summary-only")),
    (["montecarlo", "sinusoidal", "--runs", "300000", "--n", "5000"], ("at most --runs",)),
    (["run", "gaussian", "--n", "100000000"], ("run gaussian --n 100000000", "at most --n")),
    (["run", "sinusoidal", "--n", "100000000"], ("at most --n",)),
])
def test_a_run_that_cannot_fit_the_memory_is_refused_before_it_starts(argv, words, tmp_path):
    # under an address-space limit of 3 GB, as `ulimit -v 3000000` sets it
    script = ("import resource, sys\n"
              "resource.setrlimit(resource.RLIMIT_AS, (3 * 10**9, resource.RLIM_INFINITY))\n"
              "from driftfmu.simulations.cli import main\n"
              "sys.exit(main(%r))\n" % (argv + ["--out", "res", "--fmu-dir", "fmus"]))
    r = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True,
                       text=True, timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    line = _one_line(r.stderr)
    assert r.returncode == 2, line
    for w in words:
        assert w in line, line
    assert os.listdir(tmp_path) == []


def test_a_run_that_cannot_fit_the_disk_is_refused(tmp_path, capsys, monkeypatch):
    from driftfmu.simulations import budget
    monkeypatch.setattr(budget, "free_disk", lambda out: 2_000_000)
    rc = _status(["montecarlo", "gaussian", "--runs", "100", "--n", "1000",
                  "--out", str(tmp_path / "res")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2, line
    assert "5.6 MB of disk" in line and "2 MB free at" in line and "at most --runs 35 " in line
    assert not (tmp_path / "res").exists()


def test_a_long_run_is_announced_before_it_starts(tmp_path, capsys, monkeypatch):
    from driftfmu.simulations import budget
    monkeypatch.setattr(budget, "LONG", 0.0)
    rc = _status(["montecarlo", "gaussian", "--runs", "8", "--n", "50", "--workers", "1",
                  "--out", str(tmp_path / "res")])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert err.startswith("driftfmu: note: montecarlo gaussian --runs 8 --n 50: about "), err
    assert (tmp_path / "res" / "montecarlo.npz").exists()


def test_the_size_estimates_hold_for_the_default_montecarlo_run(tmp_path):
    # the estimate of what is written is what montecarlo.npz weighs (within 5 %)
    from driftfmu.simulations import budget
    assert _status(["montecarlo", "gaussian", "--runs", "200", "--n", "500", "--workers", "1",
                    "--out", str(tmp_path)]) == 0
    written = (tmp_path / "montecarlo.npz").stat().st_size
    assert abs(written / (budget.MONTECARLO_DISK * 200 * 500) - 1) < 0.05


# -- build: no half-built folders ------------------------------------------------------------------

def test_build_native_with_a_missing_compiler_names_it_before_building(tmp_path, capsys,
                                                                      monkeypatch):
    monkeypatch.setenv("CC", "no-such-cc")
    out = tmp_path / "x"
    rc = _status(["build", "--native", "--out", str(out)])
    captured = capsys.readouterr()
    line = _one_line(captured.err)
    assert rc == 2, line
    assert "CC='no-such-cc' is not an installed program" in line and "allowed:" in line
    assert captured.out == "" and not out.exists()


def _fake_python_build(out_dir, log=print, **kw):
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log("warning: the loader shim could not be compiled")
    paths = []
    for name in ("Excitation", "Accelerometer", "DriftEstimator"):
        (out / ("%s.fmu" % name)).write_bytes(b"fmu")
        log("built %s" % (out / ("%s.fmu" % name)))
        paths.append(str(out / ("%s.fmu" % name)))
    return paths


def _fake_ssp(fmus, out, **kw):
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_bytes(b"ssp of " + b",".join(sorted(n.encode() for n in fmus)))
    return Path(out)


def _tree(folder):
    """Every file under ``folder`` (hidden ones too) -> its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes()
            for p in sorted(Path(folder).rglob("*")) if p.is_file()}


@pytest.mark.parametrize("stop,status", [(RuntimeError("gcc broke"), 1),
                                         (KeyboardInterrupt(), 130)])
@pytest.mark.parametrize("existing", [False, True])
def test_a_failed_or_stopped_native_build_leaves_every_path_as_it_was(stop, status, existing,
                                                                     tmp_path, capsys,
                                                                     monkeypatch):
    """All or nothing: the Python FMUs and the SSP archive (written from them before the
    native build starts) appear only once the native build has succeeded too; an existing
    folder keeps its old FMUs and an existing ``--ssp`` file (``--force``) its old bytes."""
    from driftfmu.fmu_src import builder, native_build, ssp

    def half_native(out_dir, **kw):
        for v in (2, 3):
            (Path(out_dir) / ("fmi%d" % v)).mkdir(parents=True, exist_ok=True)
            (Path(out_dir) / ("fmi%d" % v) / "Excitation.fmu").write_bytes(b"half")
        raise stop
    monkeypatch.setattr(builder, "build_fmus", _fake_python_build)
    monkeypatch.setattr(ssp, "build_ssp", _fake_ssp)
    monkeypatch.setattr(native_build, "build_native_fmus", half_native)
    monkeypatch.setattr(native_build, "compiler_problem", lambda platform: None)
    out = tmp_path / "new" / "fmus"
    chain = tmp_path / "new" / "chain.ssp"
    if existing:
        out.mkdir(parents=True)
        (out / "mine.txt").write_text("keep")
        (out / "Excitation.fmu").write_bytes(b"the previous build's")
        chain.write_bytes(b"the previous SSP")
    before = _tree(tmp_path)
    rc = _status(["build", "--native", "--out", str(out), "--ssp", str(chain), "--force"])
    captured = capsys.readouterr()
    assert rc == status, captured.err
    assert _tree(tmp_path) == before  # no SSP, no FMU of this run, no staging folder
    assert "built" not in captured.out  # no line names a file that is not there
    if not existing:
        assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("existing", [False, True])
def test_a_build_that_succeeds_moves_every_output_into_place(existing, tmp_path, capsys,
                                                            monkeypatch):
    from test_api import _fake_native

    from driftfmu.fmu_src import builder, native_build, ssp
    monkeypatch.setattr(builder, "build_fmus", _fake_python_build)
    monkeypatch.setattr(ssp, "build_ssp", _fake_ssp)
    monkeypatch.setattr(native_build, "build_native_fmus", _fake_native)
    monkeypatch.setattr(native_build, "compiler_problem", lambda platform: None)
    out = tmp_path / "fmus"
    chain = tmp_path / "chain.ssp"
    if existing:
        out.mkdir()
        (out / "mine.txt").write_text("keep")
        (out / "Excitation.fmu").write_bytes(b"the previous build's")
        chain.write_bytes(b"the previous SSP")
    rc = _status(["build", "--native", "--out", str(out), "--ssp", str(chain), "--force"])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    tree = _tree(tmp_path)
    assert tree.pop("fmus/mine.txt", b"keep") == b"keep"
    assert tree.pop("chain.ssp").startswith(b"ssp of ")
    expected = {"fmus/%s.fmu" % n: b"fmu"
                for n in ("Excitation", "Accelerometer", "DriftEstimator")}
    expected.update({"fmus/native/fmi%d/%s.fmu" % (v, n): b"fmu" for v in (2, 3)
                     for n in ("Excitation", "Accelerometer", "DriftEstimator",
                               "DualDriftEstimator")})
    from driftfmu.fmu_src import container  # the chain as one FMU: its description beside
    for folder in ("fmus", "fmus/native/fmi2", "fmus/native/fmi3"):
        assert tree.pop("%s/%s" % (folder, container.FILENAME)).startswith(b"{")
    assert tree == expected  # and no staging folder
    # the lines name where the files are now, not the staging folder they were built in
    assert "stage" not in captured.out and "built %s" % (out / "Excitation.fmu") in captured.out
    assert "built %s" % (out / "native" / "fmi3" / "Excitation.fmu") in captured.out
    assert str(chain) in captured.out


def test_the_build_lines_name_the_paths_as_given(tmp_path, capsys, monkeypatch):
    from driftfmu.fmu_src import builder
    monkeypatch.setattr(builder, "build_fmus", _fake_python_build)
    monkeypatch.chdir(tmp_path)
    assert _status(["build", "--out", "fmus"]) == 0
    out = capsys.readouterr().out
    assert "built %s\n" % os.path.join("fmus", "Excitation.fmu") in out, out
    assert sorted(os.listdir(tmp_path)) == ["fmus"]


def test_the_api_build_is_all_or_nothing_too(tmp_path, monkeypatch):
    """driftfmu.build_fmus: an SSP step that fails after the FMUs are built leaves the
    existing folder and file as they were."""
    import driftfmu
    from driftfmu.fmu_src import builder, ssp

    def broken_ssp(fmus, out, **kw):
        Path(out).write_bytes(b"half an archive")
        raise OSError("disk full")
    monkeypatch.setattr(builder, "build_fmus", _fake_python_build)
    monkeypatch.setattr(ssp, "build_ssp", broken_ssp)
    out = tmp_path / "fmus"
    out.mkdir()
    (out / "Excitation.fmu").write_bytes(b"the previous build's")
    (tmp_path / "chain.ssp").write_bytes(b"the previous SSP")
    before = _tree(tmp_path)
    with pytest.raises(OSError, match="disk full"):
        driftfmu.build_fmus(out, ssp=tmp_path / "chain.ssp", log=lambda line: None)
    assert _tree(tmp_path) == before


@pytest.mark.parametrize("fail_at", [0, 1, 2])
def test_staging_puts_everything_back_when_a_move_fails(fail_at, tmp_path, monkeypatch):
    """The moves into place are all or nothing too: a move that fails (or is interrupted)
    takes back the files already moved and restores the ones they replaced."""
    from driftfmu.simulations import output
    (tmp_path / "fmus").mkdir()
    (tmp_path / "fmus" / "A.fmu").write_bytes(b"old A")
    before = _tree(tmp_path)
    real, moves = os.replace, []

    def replace(src, dst):
        if Path(src).name in ("A.fmu", "B.fmu", "c.ssp") and len(moves) == fail_at:
            raise KeyboardInterrupt
        moves.append(dst)
        real(src, dst)
    monkeypatch.setattr(output.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        with output.Staging() as staging:
            out = staging.path(tmp_path / "fmus")
            (out / "sub").mkdir(parents=True)
            (out / "A.fmu").write_bytes(b"new A")
            (out / "sub" / "B.fmu").write_bytes(b"new B")
            staging.path(tmp_path / "new" / "c.ssp", folder=False).write_bytes(b"ssp")
    assert _tree(tmp_path) == before and sorted(os.listdir(tmp_path)) == ["fmus"]


@pytest.mark.parametrize("case", ["block fails", "move fails", "interrupted move"])
@pytest.mark.parametrize("existing", [True, False])
def test_a_masters_result_folder_is_written_whole_or_left_as_it_was(case, existing, tmp_path,
                                                                    monkeypatch):
    """output.staged (every master's result folder): a job that fails, a move into place that
    fails or is interrupted after the first file, leave the folder as it was (a previous run's
    files back in place, a new folder not made) and no staging folder; a job that succeeds
    replaces the files it wrote and keeps the others."""
    from driftfmu.simulations import output
    out = tmp_path / "results" / "run1"
    if existing:
        out.mkdir(parents=True)
        (out / "summary.json").write_text("previous")
        (out / "notes.txt").write_text("the user's")
    before = _tree(tmp_path)
    real, moves = os.replace, []

    def replace(src, dst):
        if case != "block fails" and len(moves) == 1:
            raise KeyboardInterrupt if case == "interrupted move" else OSError("disk full")
        moves.append(dst)
        real(src, dst)
    monkeypatch.setattr(output.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt if case == "interrupted move" else OSError):
        with output.staged(out) as stage:
            (stage / "results.csv").write_text("new csv")
            (stage / "summary.json").write_text("new summary")
            if case == "block fails":
                raise OSError("the job failed")
    assert _tree(tmp_path) == before
    assert (tmp_path / "results").exists() == existing  # no folder made for a failed job
    monkeypatch.setattr(output.os, "replace", real)
    with output.staged(out) as stage:
        (stage / "results.csv").write_text("new csv")
        (stage / "summary.json").write_text("new summary")
    assert sorted(os.listdir(out)) == ["notes.txt", "results.csv", "summary.json"][not existing:]
    assert (out / "summary.json").read_text() == "new summary"
    assert not list(tmp_path.rglob(".*"))  # no staging folder anywhere


def test_a_result_folder_under_a_file_is_refused_before_the_job_runs(tmp_path):
    from driftfmu.simulations import output
    from driftfmu.simulations.errors import UsageError
    (tmp_path / "taken").write_text("a file")
    for out in (tmp_path / "taken", tmp_path / "taken" / "run1"):
        with pytest.raises(UsageError, match="taken is an existing file; allowed: a folder"):
            with output.staged(out):
                raise AssertionError("the job ran")
    assert os.listdir(tmp_path) == ["taken"]


_SIGNALLED_BUILD = """
import sys, time
from pathlib import Path
from driftfmu.fmu_src import builder, native_build, ssp
import test_cli_checks as t

def slow_native(out_dir, **kw):
    (Path(out_dir) / "fmi2").mkdir(parents=True)
    (Path(out_dir) / "fmi2" / "Excitation.fmu").write_bytes(b"half")
    Path(sys.argv[1]).write_text("native build started")
    time.sleep(3600)  # a build far longer than the tests' bound: the signal ends it

builder.build_fmus = t._fake_python_build
ssp.build_ssp = t._fake_ssp
native_build.build_native_fmus = slow_native
native_build.compiler_problem = lambda platform: None
from driftfmu.simulations.cli import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_the_native_build_leaves_every_path_as_it_was(signum, tmp_path):
    work = tmp_path / "work"
    (work / "fmus").mkdir(parents=True)
    (work / "fmus" / "Excitation.fmu").write_bytes(b"the previous build's")
    (work / "chain.ssp").write_bytes(b"the previous SSP")
    before = _tree(work)
    script = tmp_path / "signalled_build.py"
    script.write_text(_SIGNALLED_BUILD)
    started = tmp_path / "started"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT / "tests"), str(ROOT)]))
    p = subprocess.Popen([sys.executable, str(script), str(started), "build", "--native",
                          "--out", str(work / "fmus"), "--ssp", str(work / "chain.ssp"),
                          "--force"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, preexec_fn=sigint_default)
    try:
        wait_for(started.exists, "start of the native build", p)
        p.send_signal(signum)
        out, err = p.communicate(timeout=BOUND)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == 130, err
    assert "interrupted" in _last_line(err)
    assert _tree(work) == before  # no SSP, no FMU of this run, no staging folder


def test_a_failing_compiler_is_named_with_its_reason_on_the_error_line(tmp_path, monkeypatch):
    """The command prints the first line of a failed build: it names the compiler that was set
    and the compiler's own error, not only that compiling failed."""
    from driftfmu.fmu_src import native_build
    from driftfmu.simulations.cli import first_line
    cc = tmp_path / "my-cc"
    cc.write_text("#!/bin/sh\necho 'note: starting' >&2\necho 'my-cc: error: no licence' >&2\n"
                  "exit 3\n")
    cc.chmod(0o755)
    monkeypatch.setenv("CC", str(cc))
    (tmp_path / "a.c").write_text("int a;\n")
    with pytest.raises(native_build.NativeBuildError) as exc:
        native_build.compile_library("x86_64-linux", tmp_path, ["a.c"], tmp_path / "a.so")
    assert first_line(exc.value) == ("compiling a.so for x86_64-linux failed: my-cc exited with "
                                     "status 3: my-cc: error: no licence")
    assert not (tmp_path / "a.so").exists()


def test_build_warnings_go_to_stderr_with_the_prefix(tmp_path, capsys, monkeypatch):
    from driftfmu.fmu_src import builder
    monkeypatch.setattr(builder, "build_fmus", _fake_python_build)
    assert _status(["build", "--out", str(tmp_path / "fmus")]) == 0
    captured = capsys.readouterr()
    assert _one_line(captured.err) == "driftfmu: warning: the loader shim could not be compiled"
    assert "shim" not in captured.out and captured.out.count("built ") == 3


# -- words that match the code -------------------------------------------------------------------

def test_the_method_page_names_the_dual_axis_model_as_the_command_line_does():
    page = ROOT / "docs" / "method.md"
    if not page.exists():
        pytest.skip("not a source checkout")
    text = page.read_text()
    assert "## 8. The dual-axis model" in text and "driftfmu experiment dual-axis" in text
    assert "a_xy" not in text  # the cross term is bx (by), as --bx, --by and the FMU say
    from driftfmu.simulations.cli import make_parser
    dual = make_parser().parse_args(["experiment", "dual-axis"])
    for name in ("bx", "by", "a2y", "Ry", "Xy", "Qy"):
        assert hasattr(dual, name) and "`--%s`" % name in text, name


def test_the_refusal_names_summary_only_and_summary_only_fits(tmp_path, capsys, monkeypatch):
    from driftfmu.simulations import budget
    monkeypatch.setattr(budget, "available_memory", lambda: 4e9)
    rc = _status(["montecarlo", "gaussian", "--runs", "1000000", "--out", str(tmp_path / "r")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2 and "--summary-only" in line, line
    est = budget.check_montecarlo("gaussian", 1000000, 1000, 2, None, summary_only=True)
    assert est["memory"] < 0.8 * 4e9  # the same run fits with --summary-only
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("text, value", [("-1e-3", -1e-3), ("-1E+4", -1e4), ("-.5", -0.5),
                                         ("-5.", -5.0), ("-2", -2.0)])
def test_a_negative_number_in_any_float_form_is_a_value_not_an_option(text, value):
    """argparse alone reads ``--a0 -1e-3`` as an option ("expected one argument")."""
    from driftfmu.simulations.cli import make_parser
    args = make_parser().parse_args(["run", "gaussian", "--a0", text])
    assert args.a0 == value
    sweep = make_parser().parse_args(["sweep", "--a2", text, "0.01"])
    assert sweep.a2[0] == value


def test_minus_inf_is_refused_as_not_finite_and_an_unknown_option_still_is_one(capsys):
    from driftfmu.simulations.cli import make_parser
    for argv, said in ((["run", "gaussian", "--a0", "-inf"], "a0 = -inf is not finite"),
                       (["run", "gaussian", "--a0", "-x"], "expected one argument")):
        with pytest.raises(SystemExit) as exit:
            make_parser().parse_args(argv)
        assert exit.value.code == 2 and said in capsys.readouterr().err


def test_a_sweep_too_large_for_the_memory_is_refused_before_it_allocates(tmp_path, capsys,
                                                                        monkeypatch):
    """``sweep --runs 100000000`` took 24 GB and was killed by the kernel: now exit 2 with the
    estimate and the largest --runs that fits; the API raises; a sweep that fits runs."""
    import driftfmu
    from driftfmu.simulations import batch, budget
    monkeypatch.setattr(budget, "available_memory", lambda: 1e9)
    rc = _status(["sweep", "--runs", "1000000", "--n", "10", "--out", str(tmp_path / "r")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 2 and "sweep of 30 grid points x --runs 1000000" in line, line
    fits = int(re.search(r"at most --runs (\d+) for the 30 grid points", line).group(1))
    assert not (tmp_path / "r").exists()
    allocated = []
    monkeypatch.setattr(batch, "run_seeds", lambda *a: allocated.append(a))
    with pytest.raises(ValueError, match="needs about"):
        driftfmu.sweep(runs=1000000, n=10)
    assert allocated == []  # refused before the seeds were made
    monkeypatch.undo()
    monkeypatch.setattr(budget, "available_memory", lambda: 1e9)
    budget.check_sweep(30, fits, 10, 2, None)  # the figure it names fits
    with pytest.raises(ValueError):
        budget.check_sweep(30, 2 * fits, 10, 2, None)


def test_summary_only_too_large_names_the_largest_runs_that_fit(monkeypatch):
    """With --summary-only the memory grows with --runs: the refusal said "a smaller --n" at
    --n 1.  The --runs it names fits, twice that does not."""
    from driftfmu.simulations import budget
    monkeypatch.setattr(budget, "available_memory", lambda: 4e9)
    with pytest.raises(ValueError) as info:
        budget.check_montecarlo("gaussian", 100000000, 1, 2, None, summary_only=True)
    runs = int(re.search(r"at most --runs (\d+) at --n 1;", str(info.value)).group(1))
    budget.check_montecarlo("gaussian", runs, 1, 2, None, summary_only=True)
    with pytest.raises(ValueError):
        budget.check_montecarlo("gaussian", 2 * runs, 1, 2, None, summary_only=True)


# -- the report on standard output ------------------------------------------------------------

@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (a full disk)")
def test_a_report_that_cannot_be_written_before_any_result_is_a_failure(tmp_path):
    """Standard output on a full disk (/dev/full): a command whose product is its report
    fails, in one line on standard error."""
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "driftfmu", "--help"], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=BOUND,
                           env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 1
    assert _one_line(r.stderr) == "driftfmu: error: standard output: No space left on device"


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full (a full disk)")
def test_a_report_lost_after_the_results_are_in_place_is_a_warning(tmp_path):
    """Issue 39: the results in place (``identify``'s identify.json) and then standard output
    fails: the run succeeded, so exit 0, and one warning line says the report is lost and the
    results are in place (before: exit 1, as if nothing were written)."""
    import numpy as np
    t = np.arange(2000) * 1e-3
    x = np.sin(2 * np.pi * 10 * t)
    z = 0.1 + x + 0.01 * x * x + 1e-3 * np.random.default_rng(1).normal(size=t.size)
    recording = tmp_path / "rec.csv"
    np.savetxt(recording, np.column_stack([t, x, z]), delimiter=",", header="time,x,z",
               comments="")
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "driftfmu", "identify", str(recording),
                            "--f", "10", "--out", str(tmp_path / "out")], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=BOUND,
                           env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr
    assert _last_line(r.stderr) == ("driftfmu: warning: standard output: No space left on "
                                    "device; the results are in place (this report of them "
                                    "is lost)")
    assert json.loads((tmp_path / "out" / "identify.json").read_text())
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["identify.json"]


def test_standard_output_answers_as_its_stream_while_a_command_runs(monkeypatch, tmp_path):
    """While a command runs, standard output is wrapped (a failed write is told apart from a
    failed result); what a library asks of it besides writing (its encoding, whether it is a
    terminal, its file descriptor) is the stream's answer."""
    from driftfmu.simulations import cli
    seen = []

    def command(argv, previous):
        out = sys.stdout
        seen.append((out is not stream, out.encoding, out.isatty(), out.fileno()))
        print("a line of the report")
        return 0
    monkeypatch.setattr(cli, "_command", command)
    with open(tmp_path / "report.txt", "w", encoding="utf-8") as stream:
        monkeypatch.setattr(sys, "stdout", stream)
        assert main(["anything"]) == 0
        assert sys.stdout is stream
        assert seen == [(True, "utf-8", False, stream.fileno())]
    assert (tmp_path / "report.txt").read_text() == "a line of the report\n"


# -- a name nearly right: what was meant, as the API's keywords have it -------------------------

@pytest.mark.parametrize("argv, line", [
    (["run", "gausian"], "driftfmu: error: argument EXPERIMENT: invalid choice: 'gausian' "
                         "(choose from 'gaussian', 'sinusoidal') (did you mean 'gaussian'?)"),
    (["sweeep"], "(did you mean 'sweep'?)"),
    (["run", "gaussian", "--a22", "1", "--nn", "3"],
     "driftfmu: error: unrecognized arguments: --a22 1 --nn 3 (did you mean --a2 for --a22, "
     "--n for --nn?)"),
    (["experiment", "dual-axis", "--Xyy=1"], "(did you mean --Xy for --Xyy?)"),
    (["montecarlo", "gaussian", "--engine", "fmx"],
     "driftfmu: error: argument --engine: engine = 'fmx' is not allowed (did you mean "
     "'fmu'?); allowed: 'batch', 'fmu'"),
    (["run", "gaussian", "--backend", "natve"], "(did you mean 'native'?); allowed: "),
])
def test_a_name_nearly_right_is_refused_with_the_name_meant(argv, line, capsys):
    assert _status(argv) == 2
    got = _one_line(capsys.readouterr().err)
    assert got == line if line.startswith("driftfmu:") else line in got, got


@pytest.mark.parametrize("argv, line", [
    (["run", "xyz"], "driftfmu: error: argument EXPERIMENT: invalid choice: 'xyz' (choose from "
                     "'gaussian', 'sinusoidal')"),
    (["run", "gaussian", "--zzz", "1"], "driftfmu: error: unrecognized arguments: --zzz 1"),
    (["run", "gaussian", "--engine", "batch"], "driftfmu: error: unrecognized arguments: "
                                               "--engine batch"),
])
def test_a_name_far_from_any_gets_no_guess(argv, line, capsys):
    assert _status(argv) == 2
    assert _one_line(capsys.readouterr().err) == line


def test_the_api_names_the_choice_meant_as_the_command_line_does():
    import driftfmu
    with pytest.raises(ValueError) as info:
        driftfmu.montecarlo(runs=2, n=3, engine="fmx")
    assert str(info.value) == ("engine = 'fmx' is not allowed (did you mean 'fmu'?); allowed: "
                               "'batch', 'fmu'")


# -- the native build without zig: the extra that gives the missing platforms ----------------

def test_without_zig_the_warning_names_the_extra_that_gives_the_missing_platforms(monkeypatch):
    """``pip install -e .`` has no zig: the one warning names each missing platform and what
    gives it (the extra driftfmu[native], which installs ziglang; mingw-w64 for Windows)."""
    from driftfmu.fmu_src import native_build
    monkeypatch.setattr(native_build, "zig_command", lambda: None)
    monkeypatch.setenv("MINGW_CC", "no-such-mingw-gcc")
    lines = []
    assert native_build.available_platforms(lines.append) == ["x86_64-linux"]
    assert lines == [
        "warning: no compiler for x86_64-windows, aarch64-linux, aarch64-windows, "
        "x86_64-darwin, aarch64-darwin here, so the native FMUs carry no binary for them; to "
        "build them: x86_64-windows: Debian: apt-get install gcc-mingw-w64-x86-64, or the "
        "extra driftfmu[native] (pip install \"driftfmu[native]\": ziglang, a C compiler for "
        "every platform); aarch64-linux, aarch64-windows, x86_64-darwin, aarch64-darwin: the "
        "extra driftfmu[native] (pip install \"driftfmu[native]\": ziglang, a C compiler for "
        "every platform)"]
    project = ROOT / "pyproject.toml"
    if project.exists():  # a source checkout: the extra it names installs ziglang
        assert re.search(r'^native = \["ziglang>=[0-9.]+"\]$', project.read_text(), re.M)


@pytest.mark.parametrize("missing", [1, 2])
def test_the_warning_says_it_of_one_missing_platform_and_them_of_two(missing, monkeypatch):
    """The warning's pronouns follow the count of missing platforms, on both sides of one."""
    from driftfmu.fmu_src import native_build
    gone = [p for p in native_build.PLATFORMS if p.endswith("darwin")][:missing]
    monkeypatch.setattr(native_build, "compiler",
                        lambda p: None if p in gone else (["cc"], [], "cc"))
    lines = []
    assert native_build.available_platforms(lines.append) == \
        [p for p in native_build.PLATFORMS if p not in gone]
    word = "it" if missing == 1 else "them"
    assert lines == [
        "warning: no compiler for %s here, so the native FMUs carry no binary for %s; to "
        "build %s: %s: the extra driftfmu[native] (pip install \"driftfmu[native]\": ziglang, "
        "a C compiler for every platform)" % (", ".join(gone), word, word, ", ".join(gone))]
