"""An I/O error (EIO) or a full disk (ENOSPC) at every system call of a results commit
(simulations/output.py), injected by ``strace -e inject=SYSCALL:error=E:when=N``: the calls are
enumerated from a trace of the same commit (between two marker calls), not guessed.  After each
run: its exit status is what happened (0: every new file in place; 1: the destination as it
was, or the message says where the files of before are kept), every staging folder it left is
named on its standard error and keeps the bookkeeping the next run needs (its lock file; a file
of before only beside the journal or its done mark), and the next run there leaves the
destination whole (new after 0, old after 1), nothing hidden, no folder emptied or made and
left.  Both a new destination (folders to make) and an existing one (files of before to move
aside, a file of the user's among them).

The everyday loop injects EIO into every call that changes the file system and into the first
and last of every other kind of call; the qualification (``--qualification``) injects EIO and
ENOSPC into every call."""
import os
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from waiting import BOUND

from driftfmu.simulations import folders, output

ROOT = Path(__file__).resolve().parent.parent
STRACE = shutil.which("strace")
pytestmark = [pytest.mark.skipif(STRACE is None or not sys.platform.startswith("linux"),
                                 reason="needs strace(1) on Linux"),
              pytest.mark.skipif(folders.fcntl is None, reason="no flock on this platform")]

OLD = {"a.csv": "old a", "sub/b.json": "old b", "notes.txt": "the user's"}
NEW = {"a.csv": "new a", "sub/b.json": "new b", "sub/deeper/c.png": "new c", "d.txt": "new d"}
BEGIN, END = "/driftfmu-commit-begins", "/driftfmu-commit-ends"

#: Stages NEW for argv[1] and commits; a stat of BEGIN and of END around the commit (the
#: markers in the trace).  Exit 0 (committed), 1 (OSError: failed), 130 (KeyboardInterrupt),
#: else a traceback; the warnings and the error on standard error, one line each.
COMMITTER = """
import json, os, sys, warnings
from pathlib import Path
from driftfmu.simulations import output
NEW = json.loads(sys.argv[2])
lines = []
warnings.showwarning = lambda m, c, *a, **k: lines.append("%s: %s" % (c.__name__, m))
warnings.simplefilter("always")
staging = output.Staging()
staging.__enter__()
stage = staging.path(sys.argv[1])
for name, text in NEW.items():
    path = stage / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
os.path.exists("@BEGIN@")
try:
    staging.__exit__(None, None, None)
    status = 0
except OSError as exc:
    lines.append("error: %s" % exc)
    status = 1
except KeyboardInterrupt:
    lines.append("interrupted")
    status = 130
os.path.exists("@END@")
sys.stderr.write("".join(line + "\\n" for line in lines))
sys.exit(status)
""".replace("@BEGIN@", BEGIN).replace("@END@", END)

#: System calls that cannot answer EIO or ENOSPC.
NEVER_FAILS = {"geteuid", "getuid", "getpid", "gettid", "getrandom"}
#: The calls that change the file system (each of them is injected in the everyday loop).
CHANGES = {"rename", "renameat", "renameat2", "unlink", "unlinkat", "rmdir", "mkdir",
           "mkdirat", "fsync", "fdatasync", "write", "pwrite64", "ftruncate", "flock"}
LINE = re.compile(r"^\d+\s+(\w+)\(")


def tree(folder):
    """Every file under ``folder`` but the staging folders -> its text; None if missing."""
    folder = Path(folder)
    if not folder.exists():
        return None
    return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file() and not any(part.startswith(".driftfmu-")
                                       for part in p.relative_to(folder).parts)}


def folders_under(place):
    return sorted(str(p.relative_to(place)) for p in Path(place).rglob("*") if p.is_dir()
                  and not any(part.startswith(".driftfmu-") for part in p.parts))


class Place:
    """A fresh destination for ``case`` ("new": nothing of it there; "existing": OLD in it)
    and a fresh temporary folder (its private folder made, as a run before this one left it),
    under ``work``."""

    def __init__(self, work, case):
        self.base = Path(work) / "run"
        if self.base.exists():
            shutil.rmtree(self.base)
        self.place = self.base / "place"
        self.out = self.place / "results" / "run1"
        self.place.mkdir(parents=True)
        self.tmp = self.base / "tmp"
        locks = self.tmp / ("driftfmu-%d" % os.geteuid()) / output.LOCKS
        locks.mkdir(parents=True)
        for folder in (locks.parent, locks):
            folder.chmod(0o700)
        self.old = None
        if case == "existing":
            for name, text in OLD.items():
                path = self.out / name
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
            self.old = dict(OLD)
        self.new = {**(self.old or {}), **NEW}
        self.dirs_before = folders_under(self.place)

    def commit(self, strace=(), log=None):
        import json
        env = dict(os.environ, TMPDIR=str(self.tmp), PYTHONPATH=str(ROOT),
                   PYTHONDONTWRITEBYTECODE="1", PYTHONHASHSEED="0")
        command = [sys.executable, "-c", COMMITTER, str(self.out), json.dumps(NEW)]
        if strace or log:
            command = [STRACE, "-f", "-o", str(log or os.devnull), *strace, *command]
        return subprocess.run(command, env=env, capture_output=True, text=True,
                              timeout=BOUND)


def parse(log):
    """The calls of the trace ``log``: [(name, its ordinal among the calls of that name,
    the line)] and the indices of the two markers."""
    calls, seen, marks = [], {}, []
    for line in Path(log).read_text().splitlines():
        m = LINE.match(line)
        if not m:
            continue
        name = m.group(1)
        seen[name] = seen.get(name, 0) + 1
        if '"%s"' % BEGIN in line or '"%s"' % END in line:
            marks.append(len(calls))
        calls.append((name, seen[name], line))
    assert len(marks) == 2, "the markers were not traced"
    return calls, marks


def enumerate_calls(work, case):
    """The system calls of the commit of ``case``: [(name, ordinal from the process's start,
    its position among the window's calls of that name, the traced line, True when it comes
    before the decision: the last move of a new file into place)]."""
    place = Place(work, case)
    log = Path(work) / "enumerate.log"
    r = place.commit(strace=("-e", "trace=all"), log=log)
    assert r.returncode == 0 and tree(place.out) == place.new, r.stderr
    calls, (begin, end) = parse(log)
    moves_in = [i for i, (name, _, line) in enumerate(calls[begin + 1:end])
                if name == "rename" and '"%s/' % place.out in line.split(", ")[-1]
                and ".driftfmu-" not in line.split(", ")[-1]]
    assert moves_in, "no move into place traced"
    window, count = [], {}
    for i, (name, ordinal, line) in enumerate(calls[begin + 1:end]):
        count[name] = count.get(name, 0) + 1
        if name not in NEVER_FAILS:
            window.append((name, ordinal, count[name], line, i <= moves_in[-1]))
    return window


def inject(work, case, name, ordinal, position, error, before):
    """Run the commit of ``case`` with ``error`` injected into the ``ordinal``-th ``name``
    call (the ``position``-th of the commit's; ``before`` the decision), then the next run's
    recovery; the problems found (empty when every claim holds)."""
    place = Place(work, case)
    log = Path(work) / "inject.log"
    traced = name if name == "newfstatat" else "%s,newfstatat" % name
    r = place.commit(strace=("-e", "trace=" + traced, "-e",
                             "inject=%s:error=%s:when=%d" % (name, error, ordinal)), log=log)
    try:
        calls, (begin, end) = parse(log)
    except AssertionError:
        return ["the process did not reach its end (exit status %d): %s"
                % (r.returncode, r.stderr.strip()[-1500:])]
    hit = [i for i, (_, _, line) in enumerate(calls) if line.endswith("(INJECTED)")]
    of_name = [i for i, call in enumerate(calls[begin + 1:end], begin + 1)
               if call[0] == name]
    if hit != [of_name[position - 1]]:
        return ["the error was not injected into the commit's call %d of %s (traced: %s)"
                % (position, name, [calls[i][2] for i in hit])]
    problems = []
    err = r.stderr
    if r.returncode not in (0, 1) or "Traceback" in err:
        return ["exit status %d: %s" % (r.returncode, err.strip()[-2000:])]
    status = r.returncode
    now = tree(place.out)
    back_failed = "moving the files of before back failed too" in err
    if status == 0 and now != place.new:
        problems.append("exit 0, but the destination is not the new files: %s" % now)
    if status == 1 and not back_failed and now != place.old:
        problems.append("exit 1, but the destination is not as it was: %s" % now)
    if status == 1 and not err.strip().splitlines()[-1].startswith("error: "):
        problems.append("exit 1 without its error line: %s" % err)
    if name in ("fsync", "fdatasync") and before and status != 1:
        problems.append("an fsync that failed before the decision, and exit %d" % status)
    if not before and status != 0:
        problems.append("an error after the decision (every new file in place), and exit %d"
                        % status)
    for stage in place.place.rglob(output.STAGE + "*"):
        names = set(os.listdir(stage))
        if str(stage) not in err:
            problems.append("%s is left and not named: %s" % (stage, err))
        if names and folders.LOCK not in names:
            problems.append("%s is left without its lock file: %s" % (stage, sorted(names)))
        if any(n.startswith(".replaced-") for n in names) and not names & {
                output.JOURNAL, output.DONE}:
            problems.append("%s holds a file of before without the journal: %s"
                            % (stage, sorted(names)))
    # the next run there
    folders._SWEPT.clear()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        output.recover(place.out)
    want = place.new if status == 0 or "completes this commit" in err else place.old
    if tree(place.out) != want:
        problems.append("after the next run the destination is %s, not %s (said: %s)"
                        % (tree(place.out), want, [str(w.message) for w in said]))
    left = [str(p) for p in place.place.rglob(".driftfmu-*")]
    if left:
        problems.append("after the next run %s is left (said: %s)"
                        % (left, [str(w.message) for w in said]))
    made = {"results", "results/run1", "results/run1/sub", "results/run1/sub/deeper"}
    want_dirs = sorted(set(place.dirs_before) | (made if want == place.new else set()))
    if folders_under(place.place) != want_dirs:
        problems.append("after the next run the folders are %s, not %s"
                        % (folders_under(place.place), want_dirs))
    return problems


@pytest.fixture
def work(tmp_path):
    """Where the runs work: a folder in memory (/dev/shm) where there is one, so that the
    commit's fsync calls cost nothing; else ``tmp_path``."""
    import tempfile
    shm = Path("/dev/shm")
    if shm.is_dir() and os.access(shm, os.W_OK | os.X_OK):
        folder = Path(tempfile.mkdtemp(prefix="driftfmu-test-", dir=shm))
        yield folder
        shutil.rmtree(folder)
    else:
        yield tmp_path


def survey(work, case, errors, select):
    """Inject each of ``errors`` into the calls of the commit of ``case`` that ``select``
    keeps; assert that no run broke a claim (every broken one listed)."""
    window = enumerate_calls(work, case)
    chosen = select(window)
    assert chosen, window
    problems = []
    for name, ordinal, position, line, before in chosen:
        for error in errors:
            for problem in inject(work, case, name, ordinal, position, error, before):
                problems.append("%s at %s #%d (%s): %s" % (error, name, position, line[:160],
                                                            problem))
    assert not problems, "\n".join(problems)
    return chosen


def loop_selection(window):
    """Every call that changes the file system, and the first and the last of each other
    kind."""
    chosen = [c for c in window if c[0] in CHANGES]
    for name in sorted({c[0] for c in window} - CHANGES):
        of_name = [c for c in window if c[0] == name]
        chosen += of_name[:1] + of_name[-1:][len(of_name) == 1:]
    return chosen


def folder_selection(window):
    """The calls that make, move or remove: the folders made for a new destination."""
    return [c for c in window if c[0] in ("mkdir", "rename", "rmdir", "unlink", "unlinkat")]


@pytest.mark.parametrize("case", ["existing", "new"])
def test_an_io_error_at_a_call_of_the_commit_is_told_and_loses_nothing(case, work, report):
    chosen = survey(work, case, ["EIO"], loop_selection if case == "existing"
                    else folder_selection)
    report("%s destination: EIO injected at %d calls of the commit (%s)"
           % (case, len(chosen), ", ".join(sorted({c[0] for c in chosen}))))


@pytest.mark.qualification
@pytest.mark.parametrize("error", ["EIO", "ENOSPC"])
@pytest.mark.parametrize("case", ["existing", "new"])
def test_an_error_at_every_call_of_the_commit_is_told_and_loses_nothing(case, error, work,
                                                                        report):
    chosen = survey(work, case, [error], lambda window: window)
    report("%s destination: %s injected at each of the commit's %d calls"
           % (case, error, len(chosen)))


def test_the_enumeration_sees_every_kind_of_call_of_the_commit(work):
    """The trace between the markers is the commit: its renames are the moves and the
    journal's, its fsyncs those of the staged files and folders, and nothing is injected
    outside it (the checks above compare the injected call with the enumerated one)."""
    window = enumerate_calls(work, "existing")
    names = {c[0] for c in window}
    assert {"rename", "fsync", "openat", "flock", "unlink", "rmdir"} <= names, names
    renames = [c[3] for c in window if c[0] == "rename"]
    assert [c[4] for c in window] == sorted((c[4] for c in window), reverse=True)
    # the member-less commit: the journal named, 2 asides and 4 moves in, the journal done
    assert sum(".driftfmu-journal.part" in line for line in renames) == 1, renames
    assert sum(".replaced-" in line for line in renames) == 2, renames
    assert sum(output.DONE in line for line in renames) == 1, renames
    assert len(renames) == 1 + 2 + 4 + 1, renames


# -- a fault in the roll-back of a fault ----------------------------------------------------

def rollback_window(work, case="existing", move=2):
    """The first fault (EIO at the ``move``-th move of a new file into place: files of before
    are moved aside already) and the calls that follow it, the roll-back's and the clean-up's:
    (ordinal of the failing rename, [(name, ordinal, line)])."""
    window = enumerate_calls(work, case)
    moves = [c for c in window if c[0] == "rename" and c[4]
             and '"%s/' % Place(work, case).out in c[3].split(", ")[-1]
             and ".driftfmu-" not in c[3].split(", ")[-1]]
    first = moves[move - 1][1]
    place = Place(work, case)
    log = Path(work) / "rollback.log"
    r = place.commit(strace=("-e", "trace=all", "-e",
                             "inject=rename:error=EIO:when=%d" % first), log=log)
    assert r.returncode == 1 and tree(place.out) == place.old, r.stderr
    calls, (begin, end) = parse(log)
    hit = next(i for i, c in enumerate(calls) if c[2].endswith("(INJECTED)"))
    return first, [c for c in calls[hit + 1:end]]


def inject_twice(work, first, second, case="existing"):
    """The commit with EIO at the ``first``-th rename and ``second`` (name, ordinal, the
    injection: "error=EIO" or "signal=SIGINT"); the problems found."""
    name, ordinal, how = second
    place = Place(work, case)
    log = Path(work) / "twice.log"
    if name == "rename":
        when = "%d..%d+%d" % (first, ordinal, ordinal - first) if ordinal > first else None
        assert when and how.startswith("error"), second
        rules = ["-e", "inject=rename:error=EIO:when=%s" % when]
    else:
        rules = ["-e", "inject=rename:error=EIO:when=%d" % first,
                 "-e", "inject=%s:%s:when=%d" % (name, how, ordinal)]
    traced = {"rename", name, "newfstatat"}
    r = place.commit(strace=("-e", "trace=" + ",".join(sorted(traced)), *rules), log=log)
    err, status = r.stderr, r.returncode
    calls, (begin, end) = parse(log)
    hits = [c for c in calls if "(INJECTED)" in c[2]
            or ("signal" in how and c[0] == name and c[1] == ordinal)]
    if len(hits) != 2:
        return ["not injected twice: %s" % [c[2] for c in hits]]
    problems = []
    # (a second Ctrl-C that lands in the clean-up after the roll-back may end the run as
    # interrupted or, where the standard library's rmtree swallows it, as failed)
    want_status = (130, 1) if "SIGINT" in how else (1,)
    if status not in want_status or "Traceback" in err:
        return ["exit status %d, not %s: %s" % (status, want_status, err.strip()[-1500:])]
    back_failed = "moving the files of before back failed too" in err
    if "SIGINT" in how and back_failed:
        problems.append("a second Ctrl-C broke the roll-back: %s" % err)
    if not back_failed and tree(place.out) != place.old:
        problems.append("the destination is not as it was: %s (%s)" % (tree(place.out), err))
    for stage in place.place.rglob(output.STAGE + "*"):
        names = set(os.listdir(stage))
        if names and folders.LOCK not in names:
            problems.append("%s is left without its lock file: %s" % (stage, sorted(names)))
        if any(n.startswith(".replaced-") for n in names) and not names & {
                output.JOURNAL, output.DONE}:
            problems.append("%s holds a file of before without the journal: %s"
                            % (stage, sorted(names)))
        if status == 1 and str(stage) not in err:
            problems.append("%s is left and not named: %s" % (stage, err))
    folders._SWEPT.clear()
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        output.recover(place.out)
    if tree(place.out) != place.old:
        problems.append("after the next run the destination is %s (said: %s)"
                        % (tree(place.out), [str(w.message) for w in said]))
    if list(place.place.rglob(".driftfmu-*")):
        problems.append("after the next run %s is left" % list(place.place.rglob(".d*")))
    if folders_under(place.place) != place.dirs_before:
        problems.append("after the next run the folders are %s" % folders_under(place.place))
    return problems


def survey_twice(work, how, select):
    first, window = rollback_window(work)
    # (a signal rides on a call of another kind than the failing rename: strace injects one
    # thing into one kind of call; a stat comes before each move back)
    chosen = select([c for c in window if (c[0] not in NEVER_FAILS or "signal" in how)
                     and not (c[0] == "rename" and "signal" in how)])
    assert chosen
    problems = []
    for name, ordinal, line in chosen:
        for problem in inject_twice(work, first, (name, ordinal, how)):
            problems.append("%s at %s #%d (%s): %s" % (how, name, ordinal, line[:160], problem))
    assert not problems, "\n".join(problems)
    return chosen


def rollback_selection(window):
    """Every call of the roll-back itself (up to its journal marked done), and in the clean-up
    after it the removals and the first and last call of each other kind."""
    done = next(i for i, c in enumerate(window) if output.DONE in c[2])  # (its rename)
    chosen = window[:done + 1]
    rest = window[done + 1:]
    chosen += [c for c in rest if c[0] in ("rmdir", "unlink", "unlinkat")]
    for name in sorted({c[0] for c in rest} - {c[0] for c in chosen}):
        of_name = [c for c in rest if c[0] == name]
        chosen += of_name[:1] + of_name[-1:][len(of_name) == 1:]
    return chosen


def test_an_io_error_in_the_roll_back_of_a_failed_move_loses_nothing(work, report):
    """A move into place fails (EIO), and then a call of the roll-back or of the clean-up
    fails too: exit 1; the files of before are in place, or (the roll-back itself failed) kept
    beside the journal, named in the error line, and put back by the next run."""
    chosen = survey_twice(work, "error=EIO", rollback_selection)
    report("EIO in the roll-back: %d calls after a failed move" % len(chosen))


def test_a_second_ctrl_c_during_the_roll_back_waits_until_it_is_done(work, report):
    """A move into place fails, and SIGINT (a second Ctrl-C) arrives at a call of the
    roll-back: the roll-back ends first, then the interrupt (exit 130); the files of before
    are in place at once."""
    chosen = survey_twice(work, "signal=SIGINT", rollback_selection)
    report("SIGINT in the roll-back: %d calls after a failed move" % len(chosen))


@pytest.mark.qualification
@pytest.mark.parametrize("how", ["error=EIO", "error=ENOSPC", "signal=SIGINT"])
def test_a_fault_at_every_call_of_the_roll_back_loses_nothing(how, work, report):
    chosen = survey_twice(work, how, lambda window: window)
    report("%s at each of the %d calls after a failed move" % (how, len(chosen)))
