"""One writer at a time per destination, and the locks that make it so, in fresh processes
(simulations/output.py's destinations' locks, simulations/folders.py's work folders' locks).

Two results commits into one place: the second waits for the first (one line saying so), at
most ``output.WAIT`` seconds, and refuses in one line after it; both exit 0 and each left its
complete result when it ended, never a mix.  The window is made wide by a checkpoint hook
(``folders.checkpoint``), which stops the first writer at each step of its commit in turn, not
by sleeping; then many writers released at once by a barrier.  The work folders' lock holds
under the same kind of stress."""
import hashlib
import json
import os
import queue
import subprocess
import sys
import textwrap
import threading
import warnings
from pathlib import Path

import pytest
from waiting import BOUND

from driftfmu.simulations import folders, output

ROOT = Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.skipif(folders.fcntl is None, reason="no flock on this platform")

USER = {"notes.txt": "the user's"}
NAMES = ("a.csv", "sub/b.json", "sub/deeper/c.png", "d.txt")

#: A writer: stages NAMES (each file's text names the writer) for argv[1] and commits.
#: argv[3]: the checkpoint of its commit to stop at ("-": none; "ready": before the commit,
#: until released); it prints "step <name>" at each checkpoint, "paused" where it stops (then
#: waits for a line on standard input), its warnings as "<category>: <text>", then "done" or
#: "error: <text>".
WRITER = textwrap.dedent("""
    import os, sys, warnings
    from driftfmu.simulations import folders, output
    out, ident, pause = sys.argv[1], sys.argv[2], sys.argv[3]
    def say(line):
        sys.stdout.write(line + "\\n")
        sys.stdout.flush()
    warnings.showwarning = lambda m, c, *a, **k: say("%s: %s" % (c.__name__, m))
    warnings.simplefilter("always")
    count = [0]
    def checkpoint(what):
        say("step %s" % what)
        if str(count[0]) == pause:
            say("paused")
            sys.stdin.readline()
        count[0] += 1
    try:
        with output.Staging() as staging:
            stage = staging.path(out)
            for name in @NAMES@:
                path = stage / name
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text("%s by %s" % (name, ident))
            if pause == "ready":
                say("ready")
                sys.stdin.readline()
            folders.checkpoint = checkpoint
        say("done")
    except OSError as exc:
        say("error: %s" % exc)
        sys.exit(1)
""").replace("@NAMES@", repr(NAMES))


def expected(ident):
    return {**USER, **{name: "%s by %s" % (name, ident) for name in NAMES}}


def tree(folder):
    folder = Path(folder)
    return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file() and not any(part.startswith(".driftfmu-")
                                       for part in p.relative_to(folder).parts)}


class Writer:
    def __init__(self, out, ident, pause="-", env=None):
        self.start([sys.executable, "-c", WRITER, str(out), ident, pause], env,
                   subprocess.PIPE)

    def start(self, command, env, stderr):
        self.p = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                  stderr=stderr, text=True, env=env)
        self.lines = []
        self.queue = queue.Queue()

        def read():  # (a thread: a line is waited for with a bound, never half read)
            for line in self.p.stdout:
                self.queue.put(line.rstrip("\n"))
            self.queue.put(None)
        threading.Thread(target=read, daemon=True).start()

    def line(self):
        """The writer's next line (None when it ended)."""
        try:
            line = self.queue.get(timeout=BOUND)
        except queue.Empty:
            raise AssertionError("no line from the writer within the bound: %s"
                                 % self.lines) from None
        if line is None:
            self.queue.put(None)
            return None
        self.lines.append(line)
        return line

    def until(self, *starts):
        """Read up to the first line starting with one of ``starts``; that line (None when
        the writer ended first)."""
        while True:
            line = self.line()
            if line is None or line.startswith(starts):
                return line

    def release(self):
        self.p.stdin.write("\n")
        self.p.stdin.flush()

    def end(self):
        while self.line() is not None:
            pass
        self.p.stdin.close()
        err = self.p.stderr.read() if self.p.stderr is not None else ""
        assert self.p.wait(timeout=BOUND) is not None
        return self.p.returncode, err


def place(tmp_path):
    out = tmp_path / "results"
    if out.exists():
        import shutil
        shutil.rmtree(out)
    out.mkdir()
    for name, text in {**USER, **{n: "%s by a run before" % n for n in NAMES[:2]}}.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)
    return out


def commit_steps(tmp_path):
    """The checkpoints of a writer's commit, in order."""
    out = place(tmp_path)
    w = Writer(out, "alone")
    assert w.until("done") == "done"
    assert w.end()[0] == 0 and tree(out) == expected("alone")
    return [line[5:] for line in w.lines if line.startswith("step ")]


def test_a_second_writer_waits_for_the_first_at_every_step_of_its_commit(tmp_path, report):
    """The first writer stopped at each step of its commit in turn; the second writer, started
    then, waits (saying so) exactly while the first holds the destination (from its journal to
    the journal done), commits after it otherwise; both exit 0, the destination holds the
    second one's complete files, nothing of either is left.  (Without the lock the second
    moved its files among the first one's half-done moves.)"""
    steps = commit_steps(tmp_path)
    inside = steps.index("journal done")
    assert steps[0] == "write " + output.JOURNAL and inside < len(steps) - 1
    waited = 0
    for i, step in enumerate(steps):
        out = place(tmp_path)
        first = Writer(out, "first", pause=str(i))
        assert first.until("paused", "done") == "paused", first.lines
        second = Writer(out, "second")
        said = second.until("DestinationBusy", "done", "error")
        if i <= inside:  # the first holds the destination: the second waits, and says so
            assert said and said.startswith("DestinationBusy: %s: another driftfmu run "
                                            "(process %d) is moving its results into it; "
                                            "this one waits for it" % (out, first.p.pid)), \
                (i, step, second.lines)
            waited += 1
        else:
            assert said == "done", (i, step, second.lines)
        first.release()
        assert first.end()[0] == 0 and "done" in first.lines, (i, step, first.lines)
        status, err = second.end()
        assert status == 0 and "done" in second.lines, (i, step, second.lines, err)
        assert tree(out) == expected("second"), (i, step)
        assert not list(out.rglob(".driftfmu-*")), (i, step, list(out.rglob(".d*")))
    assert waited == inside + 1
    report("the first writer stopped at each of its %d steps; the second waited at %d"
           % (len(steps), waited))


def test_a_writer_refuses_in_one_line_when_the_wait_is_over(tmp_path, monkeypatch):
    """Both sides of the bound on the wait: with the bound at 0 a commit into a destination
    that another writer holds is refused at once, in one line, nothing of it written, nothing
    left; with a bound, the commit waits (one warning line) and goes in when the other lets go
    (the other side: here a thread that lets go when it sees the warning)."""
    out = place(tmp_path)
    before = tree(out)
    monkeypatch.setattr(output, "WAIT", 0.0)
    with output.destinations_locked([out]):
        with pytest.raises(output.CommitFailed) as err:
            with output.staged(out) as stage:
                (stage / "a.csv").write_text("refused")
    text = str(err.value)
    assert "\n" not in text and text.startswith(
        "%s: another driftfmu run (process %d) is moving its results into it; this run's "
        "results are not written" % (out, os.getpid())), text
    assert tree(out) == before and not list(out.rglob(".driftfmu-*"))

    monkeypatch.setattr(output, "WAIT", 600.0)
    busy, let_go = threading.Event(), threading.Event()

    def holder():
        with output.destinations_locked([out]):
            busy.set()
            let_go.wait(BOUND)
    thread = threading.Thread(target=holder)
    thread.start()
    busy.wait(BOUND)
    said = []

    def shown(message, category, *args, **kwargs):
        said.append(str(message))
        let_go.set()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            warnings.showwarning = shown
            with output.staged(out) as stage:
                (stage / "a.csv").write_text("waited")
    finally:
        let_go.set()
        thread.join(BOUND)
    assert said == ["%s: another driftfmu run (process %d) is moving its results into it; "
                    "this one waits for it (at most 10 min)" % (out, os.getpid())]
    assert tree(out)["a.csv"] == "waited" and not list(out.rglob(".driftfmu-*"))


def test_the_lock_of_a_destination_names_it_by_its_real_path(tmp_path):
    """The same place through a link, a relative path or ``..``, new or existing: one lock;
    another place: another."""
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    key = output.destination_key(tmp_path / "real" / "run1")
    assert output.destination_key(tmp_path / "link" / "run1") == key
    assert output.destination_key(str(tmp_path / "real" / "x" / ".." / "run1")) == key
    (tmp_path / "real" / "run1").mkdir()
    assert output.destination_key(tmp_path / "link" / "run1") == key
    assert output.destination_key(tmp_path / "real" / "run2") != key


@pytest.mark.parametrize("round_", range(6))
def test_writers_released_at_once_each_leave_a_whole_result(round_, tmp_path):
    """Four writers, each in a fresh process, staged and released together by a barrier (all
    ready, then all let go): every one exits 0, the destination holds one writer's complete
    files, nothing is left."""
    out = place(tmp_path)
    writers = [Writer(out, "writer%d" % i, pause="ready") for i in range(4)]
    for w in writers:
        assert w.until("ready") == "ready", w.lines
    for w in writers:
        w.release()
    ends = [w.end() for w in writers]
    assert [e[0] for e in ends] == [0] * 4, [(w.lines, e) for w, e in zip(writers, ends)]
    now = tree(out)
    assert now in [expected("writer%d" % i) for i in range(4)], now
    assert not list(out.rglob(".driftfmu-*"))


#: A process holding three work folders: made, "ready", released, then sweeps (again and
#: again) and says which of its folders are still there.
SWEEPER = textwrap.dedent("""
    import os, sys
    from driftfmu.simulations import folders
    mine = [folders.make("driftfmu_fmu_") for _ in range(3)]
    print("ready", flush=True)
    sys.stdin.readline()
    for _ in range(20):
        folders._SWEPT.clear()
        folders.sweep(folders.TEMPORARY)
    print(sum(os.path.isdir(f) for f in mine), flush=True)
    for f in mine:
        folders.remove(f)
""")


def test_work_folders_of_live_processes_survive_each_others_sweeps(tmp_path):
    """Six fresh processes, each holding three work folders in one private folder, released
    together to sweep it twenty times: no live folder is removed (each is locked by its
    process); and afterwards none is left."""
    env = dict(os.environ, TMPDIR=str(tmp_path), PYTHONPATH=str(ROOT))
    procs = [subprocess.Popen([sys.executable, "-c", SWEEPER], env=env, text=True,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE) for _ in range(6)]
    for p in procs:
        assert p.stdout.readline().strip() == "ready"
    for p in procs:
        p.stdin.write("\n")
        p.stdin.flush()
    kept = [int(p.stdout.readline()) for p in procs]
    for p in procs:
        p.stdin.close()
        assert p.wait(timeout=BOUND) == 0
    assert kept == [3] * 6
    private = tmp_path / ("driftfmu-%d" % os.geteuid())
    assert not private.exists() or not [p for p in private.iterdir()
                                        if p.name.startswith(folders.TEMPORARY)]


# -- the commands ------------------------------------------------------------------------------

#: ``driftfmu`` with a hook: it prints the staged files' SHA-256 when its commit writes its
#: journal ("staged <path below the destination> <sha256>"), and stops (printing "paused",
#: until a line on standard input) at the checkpoint argv[1] ("-": none).
CLI_WRITER = textwrap.dedent("""
    import hashlib, os, sys
    from pathlib import Path
    from driftfmu.simulations import cli, folders, output
    pause, argv = sys.argv[1], sys.argv[2:]
    paused = []
    def checkpoint(what):
        if what == "write " + output.JOURNAL:
            for stage in [s for s in folders._HELD if os.path.basename(s).startswith(
                    output.STAGE)]:
                for p in sorted(Path(stage).rglob("*")):
                    rel = p.relative_to(stage)
                    if p.is_file() and not rel.parts[0].startswith(".driftfmu-"):
                        print("staged %s %s" % ("/".join(rel.parts[1:]) or rel,
                              hashlib.sha256(p.read_bytes()).hexdigest()), flush=True)
        if what == pause and not paused:
            paused.append(what)
            print("paused", flush=True)
            sys.stdin.readline()
    folders.checkpoint = checkpoint
    status = cli.main(argv)
    print("status %d" % status, flush=True)
    sys.exit(status)
""")


class CliWriter(Writer):
    """:data:`CLI_WRITER` with its standard error on its standard output (one stream of
    lines)."""

    def __init__(self, argv, pause="-"):
        self.start([sys.executable, "-c", CLI_WRITER, pause, *map(str, argv)],
                   dict(os.environ, PYTHONPATH=str(ROOT)), subprocess.STDOUT)

    def staged(self):
        return dict(line.split()[1:] for line in self.lines if line.startswith("staged "))


BUSY = "is moving its results into"


def two_commands(first_argv, second_argv, out):
    """The first command stopped at its first move into place, the second run whole: the
    second waits (its warning line), both exit 0, and ``out`` holds the second's staged files,
    every one (by SHA-256)."""
    first = CliWriter(first_argv, pause="in")
    assert first.until("paused", "status") == "paused", first.lines
    second = CliWriter(second_argv)
    while True:  # the second's line saying that it waits (or its end: a failure)
        line = second.line()
        if line is None or BUSY in line or line.startswith("status"):
            break
    assert line and line.startswith("driftfmu: warning: ") and BUSY in line and \
        "another driftfmu run (process %d)" % first.p.pid in line, second.lines
    first.release()
    assert first.end()[0] == 0, first.lines
    assert second.end()[0] == 0, second.lines
    assert "status 0" in first.lines and "status 0" in second.lines
    staged = second.staged()
    assert staged and staged != first.staged()
    for rel, digest in staged.items():
        path = Path(out) / rel if Path(out).is_dir() else Path(out)
        assert hashlib.sha256(path.read_bytes()).hexdigest() == digest, rel
    assert not list(Path(out).parent.rglob(".driftfmu-*"))
    return first, second


@pytest.mark.integration
def test_two_runs_into_one_out_never_tear_it(native_fmus, tmp_path):
    """Issue 39's finding: two ``driftfmu run gaussian`` into one --out; the first stopped
    between its moves, the second waits for it; both exit 0 and --out holds the second run's
    results.csv, summary.json and drift.png, all three."""
    fmu_dir = tmp_path / "fmus"
    for v, paths in native_fmus.items():
        (fmu_dir / "native" / ("fmi%d" % v)).mkdir(parents=True)
        for path in paths.values():
            (fmu_dir / "native" / ("fmi%d" % v) / path.name).symlink_to(path)
    out = tmp_path / "out"
    argv = ["run", "gaussian", "--backend", "native", "--n", "300", "--out", out,
            "--fmu-dir", fmu_dir]
    first, second = two_commands(argv + ["--seed", "1"], argv + ["--seed", "2"], out)
    assert sorted(second.staged()) == ["drift.png", "results.csv", "summary.json"]
    assert json.loads((out / "summary.json").read_text())["parameters"]["seed"] == 2


@pytest.mark.integration
def test_two_input_files_written_to_one_place_never_tear_it(python_fmus, tmp_path):
    """Two ``driftfmu inputs --force`` into one --output-file: the second waits for the
    first; both exit 0; the file is the second one's, whole."""
    results = []
    for i in (1, 2):
        csv = tmp_path / ("x%d.csv" % i)
        csv.write_text("time,x\n" + "".join("%g,%g\n" % (k * 0.001, i * k * 0.01)
                                           for k in range(50)))
        results.append(csv)
    target = tmp_path / "inputs.csv"
    target.write_text("the file of before\n")
    argv = ["inputs", python_fmus["Accelerometer"], "--output-file", target, "--force",
            "--hold", "y", "--hold", "theta", "--hold", "T"]  # (the results give x alone)
    two_commands(argv[:2] + [results[0]] + argv[2:], argv[:2] + [results[1]] + argv[2:],
                 target)


@pytest.mark.qualification
def test_two_builds_into_one_folder_never_tear_it(tmp_path):
    """Two ``driftfmu build`` into one --out: the second waits for the first; both exit 0;
    the folder holds the second build's four FMUs and its container recipe."""
    from driftfmu.fmu_src import container
    out = tmp_path / "fmus"
    first, second = two_commands(["build", "--out", out], ["build", "--out", out], out)
    assert sorted(second.staged()) == sorted(
        ["Accelerometer.fmu", "DriftEstimator.fmu", "DualDriftEstimator.fmu", "Excitation.fmu",
         container.FILENAME])
