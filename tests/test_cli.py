"""The command line as a newcomer meets it: one exit convention (usage 2, failed run 1, Ctrl-C
130), one readable line per error, Ctrl-C that stops worker processes at once and leaves no
temporary files, no empty folders after a failed build, the SSP overwrite rule, and outputs that
say "never" or "none" instead of None or a meaningless percentage."""
import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from driftfmu.simulations import cli
from driftfmu.simulations.adxl203 import default_held_out
from driftfmu.simulations.cli import main
from waiting import BOUND, sigint_default, wait_for

ROOT = Path(__file__).resolve().parent.parent


def _one_error_line(err):
    """The one line of an error; a long run's estimate and progress lines before it are not
    errors and do not count."""
    lines = [line for line in err.strip().splitlines() if line.strip()
             and not line.startswith(("driftfmu: note: ", "driftfmu: progress: "))]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


# -- usage errors: 2 ----------------------------------------------------------------------------

@pytest.mark.parametrize("argv,words", [
    (["run", "sinusoidal", "--f", "600"], ("f = 600.0 Hz", "Nyquist")),
    (["run", "sinusoidal", "--f", "0"], ("0 < f < 1/(2 Ts)",)),
    (["montecarlo", "sinusoidal", "--f", "600", "--runs", "2"], ("Nyquist",)),
    (["experiment", "adxl203", "--sets", "6", "--held-out", "5"],
     ("held_out <= 4, or sets >= 7",)),
    (["experiment", "adxl203", "--sets", "2"], ("sets >= 3",)),
    (["experiment", "adxl203", "--freqs", "100,6000"], ("f = 6000.0 Hz",)),
    (["sweep", "--R", "0"], ("R",)),
    (["run", "gaussian", "--A", "1"], ("A",)),
])
def test_a_setting_the_run_cannot_start_with_is_a_usage_error(argv, words, tmp_path, capsys):
    out = tmp_path / "out"
    rc = _status(argv + ["--out", str(out), "--fmu-dir", str(tmp_path / "fmus")])
    line = _one_error_line(capsys.readouterr().err)
    assert rc == 2, line
    for w in words:
        assert w in line
    assert not out.exists() and not (tmp_path / "fmus").exists()


def _status(argv):
    """main's exit status, whether it returns it or argparse raises SystemExit."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def test_out_naming_an_existing_file_is_one_line_and_exit_2(tmp_path, capsys):
    f = tmp_path / "results.txt"
    f.write_text("mine\n")
    with pytest.raises(SystemExit) as exc:
        main(["run", "gaussian", "--out", str(f)])
    assert exc.value.code == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "is an existing file" in line and "Errno" not in line
    assert f.read_text() == "mine\n"


@pytest.mark.parametrize("where, words", [
    ("file", "--fmu-dir {d}/afile is an existing file; allowed: a folder"),
    ("under a file", "--fmu-dir {d}/afile/sub cannot be created: {d}/afile is a file"),
    ("empty", "--fmu-dir '' is empty; allowed: a folder path"),
])
def test_fmu_dir_naming_a_file_is_one_line_and_exit_2(where, words, tmp_path, capsys):
    (tmp_path / "afile").write_text("mine\n")
    value = {"file": tmp_path / "afile", "under a file": tmp_path / "afile" / "sub",
             "empty": ""}[where]
    assert _status(["run", "gaussian", "--n", "10", "--out", str(tmp_path / "out"),
                    "--fmu-dir", str(value)]) == 2
    assert _one_error_line(capsys.readouterr().err).startswith(
        "driftfmu: error: " + words.format(d=tmp_path))
    assert sorted(os.listdir(tmp_path)) == ["afile"]


@pytest.mark.integration
@pytest.mark.parametrize("backend", ["python", "native"])
def test_a_damaged_fmu_in_fmu_dir_is_named_in_one_line(backend, built_fmus, native_fmus,
                                                       tmp_path, capsys):
    """An FMU of --fmu-dir that is not a zip archive (a download cut short): the error names
    the file and what to do, not fmpy's "File is not a zip file"; no result is written."""
    fmus = tmp_path / "fmus"
    folder = fmus if backend == "python" else fmus / "native" / "fmi2"
    folder.mkdir(parents=True)
    for name, path in (built_fmus if backend == "python" else native_fmus[2]).items():
        (folder / Path(path).name).write_bytes(Path(path).read_bytes())
    (folder / "Accelerometer.fmu").write_bytes(b"PK\x03\x04 cut short")
    rc = _status(["run", "gaussian", "--n", "10", "--out", str(tmp_path / "out"), "--fmu-dir",
                  str(fmus), "--backend", backend])
    assert rc == 2
    assert _one_error_line(capsys.readouterr().err) == (
        "driftfmu: error: %s is not an FMU (not a zip archive: damaged or cut short); allowed: "
        "an FMU as driftfmu build writes it (remove this one and it is built again)"
        % (folder / "Accelerometer.fmu"))
    assert not (tmp_path / "out").exists()


@pytest.mark.integration
@pytest.mark.parametrize("backend", ["python", "native"])
def test_another_fmu_under_an_expected_name_is_named_in_one_line(backend, built_fmus,
                                                                 native_fmus, tmp_path, capsys):
    """The DriftEstimator saved as Excitation.fmu in --fmu-dir: the error names the file, what
    it is and what to do (it was "driftfmu: error: 'x'", exit 1); nothing is written; the API
    raises the same."""
    import driftfmu
    fmus = tmp_path / "fmus"
    folder = fmus if backend == "python" else fmus / "native" / "fmi2"
    folder.mkdir(parents=True)
    for name, path in (built_fmus if backend == "python" else native_fmus[2]).items():
        (folder / Path(path).name).write_bytes(Path(path).read_bytes())
    (folder / "Excitation.fmu").write_bytes((folder / "DriftEstimator.fmu").read_bytes())
    rc = _status(["run", "gaussian", "--n", "10", "--out", str(tmp_path / "out"), "--fmu-dir",
                  str(fmus), "--backend", backend])
    line = _one_error_line(capsys.readouterr().err)
    assert rc == 2
    assert line.startswith("driftfmu: error: %s has no variable " % (folder / "Excitation.fmu"))
    assert line.endswith("(its model is DriftEstimator): it is not driftfmu's Excitation; "
                         "allowed: driftfmu's Excitation.fmu, as driftfmu build writes it "
                         "(remove this one and it is built again)"), line
    assert not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="it is not driftfmu's Excitation"):
        driftfmu.simulate(stop_time=0.01, fmu_dir=fmus, backend=backend)


@pytest.mark.integration
def test_the_variable_check_skips_values_for_fmus_not_in_the_run(built_fmus):
    """Start values and recorded names for an FMU the run does not load are skipped by both
    masters, as before the check of the variables (which raised a bare KeyError for them)."""
    from driftfmu.simulations.cosim import cosimulate
    from driftfmu.simulations.fastcosim import cosimulate_fast
    fmus = {"Excitation": str(built_fmus["Excitation"])}
    extra = {"Excitation": {"seed": 2}, "DriftEstimator": {"a2": 0.1}}
    for master in (cosimulate, cosimulate_fast):
        out = master(fmus, [], 3, 1e-3, start_values=extra)
        assert len(out["time"]) == 3 and len(out["Excitation.x"]) == 3


@pytest.mark.integration
def test_an_fmu_error_s_reason_is_on_the_one_line(built_fmus, tmp_path, capsys):
    """Values the command accepts but the model overflows with: the line says why the FMU
    refused (it said only "fmi2GetReal failed with status 3 (error).")."""
    rc = _status(["run", "gaussian", "--Q", "1e160", "--n", "20", "--out", str(tmp_path / "o"),
                  "--fmu-dir", str(Path(built_fmus["Excitation"]).parent)])
    line = _one_error_line(capsys.readouterr().err)
    assert rc == 1 and line.startswith("driftfmu: error: fmi2GetReal failed with status 3 "
                                       "(error): DriftEstimator: dc_ekf1 would be inf"), line
    assert "would be inf at sample 1" in line and "overflow the model" in line, line
    assert not (tmp_path / "o").exists()


def test_a_bad_source_date_epoch_is_a_usage_error_of_build(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "abc")
    assert _status(["build", "--out", str(tmp_path / "fmus")]) == 2
    assert _one_error_line(capsys.readouterr().err).startswith(
        "driftfmu: error: SOURCE_DATE_EPOCH='abc' is not a time; allowed: a whole number")
    assert os.listdir(tmp_path) == []


def test_version(capsys):
    from driftfmu import __version__
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == "driftfmu " + __version__


def test_help_states_the_frequency_range_that_is_accepted(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "sinusoidal", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "0 < f < 1/(2 Ts)" in text and "f >= 0" not in text


# -- failed runs: 1 -----------------------------------------------------------------------------

def test_a_failed_run_is_one_line_and_exit_1(tmp_path, capsys):
    bad = tmp_path / "r.csv"
    bad.write_text("time,x\n0,1\n0.001,2\n0.002,3\n")
    assert main(["identify", str(bad), "--f", "50", "--out", str(tmp_path / "o")]) == 1
    assert "missing column(s) z" in _one_error_line(capsys.readouterr().err)
    assert not (tmp_path / "o").exists()


def test_a_failed_build_leaves_no_empty_folder(tmp_path, monkeypatch, capsys):
    from driftfmu.fmu_src import builder

    def fail(out_dir, *a, **k):
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        raise builder.BuildError("the compiler broke")
    monkeypatch.setattr(builder, "build_fmus", fail)
    assert main(["build", "--out", str(tmp_path / "a" / "b" / "fmus")]) == 1
    assert "the compiler broke" in _one_error_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


# -- the SSP archive: kept unless --force, mode 0644 ----------------------------------------------

@pytest.mark.integration
def test_build_ssp_keeps_an_existing_file_unless_force(tmp_path, capsys):
    ssp = tmp_path / "chain.ssp"
    ssp.write_bytes(b"not yours to replace")
    with pytest.raises(SystemExit) as exc:
        main(["build", "--out", str(tmp_path / "fmus"), "--ssp", str(ssp)])
    assert exc.value.code == 2
    assert "--force" in _one_error_line(capsys.readouterr().err)
    assert ssp.read_bytes() == b"not yours to replace"
    assert not (tmp_path / "fmus").exists()  # refused before anything was built
    assert main(["build", "--out", str(tmp_path / "fmus"), "--ssp", str(ssp), "--force"]) == 0
    import zipfile
    assert "SystemStructure.ssd" in zipfile.ZipFile(ssp).namelist()
    assert stat.S_IMODE(ssp.stat().st_mode) == 0o644
    fmu = tmp_path / "fmus" / "Excitation.fmu"
    assert stat.S_IMODE(fmu.stat().st_mode) == stat.S_IMODE(ssp.stat().st_mode)


# -- results that would be silently wrong, and "never" -------------------------------------------

@pytest.mark.integration
def test_no_whole_period_gives_no_empirical_percentage(built_fmus, tmp_path, capsys):
    fmu_dir = Path(built_fmus["Excitation"]).parent
    rc = main(["run", "sinusoidal", "--f", "0.3", "--out", str(tmp_path / "o"),
               "--fmu-dir", str(fmu_dir)])
    cap = capsys.readouterr()
    assert rc == 0
    assert "vs empirical n/a" in cap.out and "-99" not in cap.out
    assert "no whole period" in _one_error_line(cap.err)
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["whole_periods"]["samples"] == 0
    assert s["ekf1_rel_error"]["vs_empirical_whole_periods"] is None


@pytest.mark.integration
def test_one_sample_prints_never_and_no_warning(built_fmus, tmp_path, capsys):
    fmu_dir = Path(built_fmus["Excitation"]).parent
    assert main(["run", "gaussian", "--n", "1", "--out", str(tmp_path / "o"),
                 "--fmu-dir", str(fmu_dir)]) == 0
    cap = capsys.readouterr()
    assert "None" not in cap.out and "never" in cap.out
    assert cap.err == ""


def test_montecarlo_says_never_for_runs_that_never_settle(capsys):
    s = {"runs": 4, "n": 10, "seconds": 0.1, "band": 0.1, "settle_by": 250,
         "settled_fraction": {"realised": {e: 0.0 for e in ("ekf1", "ekf2", "ekf3")}},
         "median_settled_from": {"realised": {e: 11.0 for e in ("ekf1", "ekf2", "ekf3")}},
         "ekf1_ekf2_gap_db": {"mean": 0.0, "std": 0.0, "max_abs": 0.0, "of_means": 0.0}}
    from driftfmu.simulations.montecarlo import print_summary
    print_summary(s)
    out = capsys.readouterr().out
    assert "never" in out and "median k     11" not in out


def test_default_held_out_is_the_letters_share():
    assert default_held_out(30) == 5
    assert default_held_out(6) == 1
    assert default_held_out(3) == 1


def test_progress_bars_name_their_unit(monkeypatch):
    import tqdm
    seen = {}

    class Bar:
        n = 0

        def __init__(self, total, desc, unit, leave):
            seen["unit"] = unit

        def update(self, k):
            pass

        def close(self):
            pass
    monkeypatch.setattr(tqdm, "tqdm", Bar)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    with cli.progress(10, "sets", "set") as update:
        update(1)
    assert seen["unit"].strip() == "set"


# -- Ctrl-C: 130 --------------------------------------------------------------------------------

def _group(pgid, python_only=False):
    """Live (not zombie) processes of process group ``pgid``; ``python_only``: the Python
    processes only (the command and its workers, not a C compiler building the batch kernel)."""
    r = subprocess.run(["ps", "-e", "-o", "pid=,pgid=,stat=,comm="], capture_output=True,
                       text=True)
    live = []
    for line in r.stdout.splitlines():
        pid, group, st, *comm = line.split()
        if int(group) == pgid and not st.startswith("Z") and (
                not python_only or "".join(comm).startswith("python")):
            live.append(int(pid))
    return live


#: Work that lasts far beyond :data:`waiting.BOUND`: a command that ends within the bound after
#: the signal ended because of it.  The experiment's sets never end (:data:`SETS_FOREVER`: each
#: worker runs its real set, co-simulation and all, again and again); the sweep's own estimate
#: is 50 h.
ENDLESS_EXPERIMENT = ["experiment", "adxl203", "--freqs", "100", "--sets", "6", "--held-out",
                      "1", "--workers", "2", "--out", "res"]
HOURS_OF_SWEEP = ["sweep", "--runs", "20000", "--n", "6000000", "--out", "res"]

#: A module on the command's PYTHONPATH (so that a worker, forked or started by a fork server,
#: finds it by name) whose set runs for ever, and the command with it in place.
SETS_FOREVER = """
from driftfmu.simulations import adxl203
real_run_set = adxl203._run_set

def run_set_forever(task):
    while True:
        real_run_set(task)
"""
ENDLESS_COMMAND = """
import sys
import sets_forever
from driftfmu.simulations import adxl203, cli
adxl203._run_set = sets_forever.run_set_forever
sys.argv[0] = "driftfmu"
cli.run_program()
"""


def _interrupt(argv, tmp_path, after, wait_for_workers=0, send=None, wait_for_main=False):
    """Start ``driftfmu argv`` in its own session, send SIGINT to its whole process group (as a
    terminal's Ctrl-C does; or call ``send(pid)``) ``after`` seconds in, counted from when
    main() has started (``wait_for_main``) or ``wait_for_workers`` children run (each waited
    for, up to :data:`waiting.BOUND`); return (exit status, stderr, live processes left, files
    left in TMPDIR, workers that ran when the signal was sent).  ``argv`` must be work that
    lasts far longer than the bound, so that its end within the bound shows the signal's
    effect."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    modules = tmp_path / "modules"
    modules.mkdir()
    (modules / "sets_forever.py").write_text(SETS_FOREVER)
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=os.pathsep.join([str(modules), str(ROOT)]),
               DRIFTFMU_PROGRESS_EVERY="3600")  # stderr: the interrupt's line only
    command = (["-c", ENDLESS_COMMAND] if argv[:2] == ENDLESS_EXPERIMENT[:2]
               else ["-m", "driftfmu"])
    p = subprocess.Popen([sys.executable, *command, *argv], cwd=tmp_path, env=env,
                         start_new_session=True, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, preexec_fn=sigint_default)
    try:
        if wait_for_main:
            wait_for(lambda: _main_started(p.pid), "start of main()", p, poll=0.002)
        if wait_for_workers:
            wait_for(lambda: len(_group(p.pid, python_only=True)) >= 1 + wait_for_workers,
                     "%d worker processes" % wait_for_workers, p, poll=0.05)
        time.sleep(after)  # where in the run the signal lands, not a deadline
        workers = len(_group(p.pid, python_only=True)) - 1
        if send is None:
            os.killpg(p.pid, signal.SIGINT)
        else:
            send(p.pid)
        _, err = p.communicate(timeout=BOUND)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.communicate()
    # the group's last processes may take a moment to go
    try:
        wait_for(lambda: not _group(p.pid), "end of the process group", poll=0.05)
    except AssertionError:
        pass
    left = _group(p.pid)
    # the compiled batch kernel (simulations/kernel.py) and the fast master's compiled loop
    # (simulations/fastcosim.py) are kept in the private folder's libraries by design, and
    # the folder of the destinations' locks stays (empty); anything else left in TMPDIR is a
    # temporary file the interrupt should have removed
    private = "driftfmu-%d" % os.geteuid()
    kept = {private, os.path.join(private, "libraries"), os.path.join(private, "locks")}
    files = sorted(os.path.relpath(os.path.join(top, f), tmp)
                   for top, dirs, names in os.walk(tmp) for f in dirs + names
                   if os.path.relpath(os.path.join(top, f), tmp) not in kept
                   and os.path.relpath(top, tmp) != os.path.join(private, "libraries"))
    return p.returncode, err, left, files, workers


@pytest.mark.integration
def test_ctrl_c_stops_the_experiment_and_its_workers(built_fmus, tmp_path):
    fmu_dir = Path(built_fmus["Excitation"]).parent
    rc, err, left, files, workers = _interrupt(
        ENDLESS_EXPERIMENT + ["--fmu-dir", str(fmu_dir)], tmp_path, after=0.5,
        wait_for_workers=2)
    assert workers >= 2  # it was interrupted while the sets ran on the workers
    assert rc == 130, err  # within the bound, of hours of work: stopped by the signal
    assert "interrupted" in _one_error_line(err)
    assert left == [] and files == []
    assert not (tmp_path / "res").exists()


def _main_started(pid):
    """True once the command's main() runs: it then catches SIGTERM (bit 15 of SigCgt in
    /proc/PID/status), which the interpreter's own start-up does not."""
    try:
        with open("/proc/%d/status" % pid) as fh:
            caught = next(int(line.split()[1], 16) for line in fh if line.startswith("SigCgt"))
    except (OSError, StopIteration):
        return False
    return bool(caught & (1 << (signal.SIGTERM - 1)))


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs /proc")
@pytest.mark.parametrize("after", [0.0, 0.3])
def test_ctrl_c_early_is_one_line_and_130(tmp_path, after):
    # "early": as soon as main() has started (while NumPy, matplotlib and the plugins are still
    # being imported), and 0.3 s later; a signal in the interpreter's own start-up, before any
    # of the project's code runs, is Python's to report
    rc, err, left, files, _ = _interrupt(HOURS_OF_SWEEP, tmp_path, after=after,
                                         wait_for_main=True)
    assert rc == 130, err
    assert "interrupted" in _one_error_line(err)
    assert left == [] and files == []
    assert not (tmp_path / "res").exists()


def test_ctrl_c_inside_code_run_from_a_string_still_exits_130(tmp_path):
    # A Ctrl-C that lands in code run by exec/eval of a string (dataclasses and namedtuple
    # build their methods so while a module is imported) makes CPython end `python -m` by
    # re-raising SIGINT at exit (returncode -2), unless the program ends itself with its status
    (tmp_path / "interrupted_in_exec.py").write_text(
        "from driftfmu.simulations import cli\n"
        "def make_parser():\n"
        "    p = cli._Parser(prog='driftfmu')\n"
        "    p.set_defaults(func=lambda args: exec('raise KeyboardInterrupt'))\n"
        "    return p\n"
        "cli.make_parser = make_parser\n"
        "cli.run_program()\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(ROOT)]))
    p = subprocess.run([sys.executable, "-m", "interrupted_in_exec"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=BOUND)
    assert p.returncode == 130, (p.returncode, p.stderr)
    assert "interrupted" in _one_error_line(p.stderr)


@pytest.mark.integration
def test_sigterm_to_the_command_alone_stops_its_workers_too(built_fmus, tmp_path):
    # what `timeout` or `kill PID` do: SIGTERM to the main process, not to the group
    fmu_dir = Path(built_fmus["Excitation"]).parent
    rc, err, left, files, workers = _interrupt(
        ENDLESS_EXPERIMENT + ["--fmu-dir", str(fmu_dir)], tmp_path, after=0.5,
        wait_for_workers=2, send=lambda pid: os.kill(pid, signal.SIGTERM))
    assert workers >= 2
    assert rc == 130, err
    assert "interrupted" in _one_error_line(err)
    assert left == [] and files == []


@pytest.mark.qualification  # a Dask cluster of two worker processes
def test_ctrl_c_cancels_the_runs_on_a_dask_cluster(tmp_path):
    dd = pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] is not "
                             "installed")
    Client, LocalCluster = dd.Client, dd.LocalCluster
    import dask  # its scratch folder in this test's, not dask-scratch-space in TMPDIR
    with dask.config.set({"temporary-directory": str(tmp_path)}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         dashboard_address=None) as cluster, Client(cluster) as client:
        def busy():
            return sum(len(v) for v in client.processing().values())
        argv = HOURS_OF_SWEEP + ["--scheduler", cluster.scheduler_address]
        tmp = tmp_path / "tmp"
        tmp.mkdir()
        env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
        p = subprocess.Popen([sys.executable, "-m", "driftfmu", *argv], cwd=tmp_path, env=env,
                             start_new_session=True, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, preexec_fn=sigint_default)
        try:
            wait_for(busy, "runs of the sweep on the cluster", p, poll=0.05)
            os.killpg(p.pid, signal.SIGINT)
            _, err = p.communicate(timeout=BOUND)  # of hours of work: stopped by the signal
        finally:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.communicate()
        assert p.returncode == 130, err
        assert "interrupted" in err.strip().splitlines()[-1]
        wait_for(lambda: busy() == 0, "the cancelled runs to leave the cluster", poll=0.1)
    assert not (tmp_path / "res").exists()


@pytest.mark.integration
def test_doctor_leaves_no_temporary_files(built_fmus, tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r = subprocess.run([sys.executable, "-m", "driftfmu", "doctor", str(built_fmus["Excitation"])],
                       env=dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT)),
                       capture_output=True, text=True, timeout=BOUND)
    assert r.returncode == 0 and "will run on this host" in r.stdout, r.stdout + r.stderr
    assert os.listdir(tmp) == []
