"""A results commit (simulations/output.py) killed by SIGKILL at every one of its steps, then the
next run there: the destination holds its complete old files or its complete new ones, never a
silent mix (while it is a mix, a journal says so); no file is lost; the next run says in one
line what it recovered.  The commits run in forked children of the test process (a few
milliseconds each), each stopped by ``folders.checkpoint`` at its N-th step."""
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from driftfmu.simulations import folders, output
from driftfmu.simulations.errors import UsageError

pytestmark = [pytest.mark.skipif(folders.fcntl is None, reason="no flock on this platform"),
              pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")]

OLD = {"a.csv": "old a", "sub/b.json": "old b", "notes.txt": "the user's"}
NEW = {"a.csv": "new a", "sub/b.json": "new b", "sub/deeper/c.png": "new c", "d.txt": "new d"}
OLD_SSP, NEW_SSP = "old ssp", "new ssp"


def tree(folder):
    """Every file under ``folder`` but the staging folders -> its text; None if it is
    missing."""
    folder = Path(folder)
    if not folder.exists():
        return None
    return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*"))
            if p.is_file() and not any(part.startswith(output.STAGE)
                                       for part in p.relative_to(folder).parts)}


def texts(folder):
    """The text of every file under ``folder``, the staging folders' too."""
    return sorted(p.read_text() for p in Path(folder).rglob("*")
                  if p.is_file() and not p.name.startswith(".driftfmu-"))


def write(folder, files):
    for name, text in files.items():
        path = Path(folder) / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


#: A small process that runs the commits and the next runs, each in a forked child that a
#: checkpoint stops by SIGKILL; it answers each job (a JSON line) with the child's exit status
#: (a negative signal number), the steps the child passed and the lines it said.  (Forking
#: this small process costs a few milliseconds, the test process ten times as much.)
SERVER = """
import json, os, signal, sys, warnings
from pathlib import Path
from driftfmu.simulations import folders, output
from driftfmu.simulations.errors import UsageError
# no fsync: a process killed outright loses nothing the kernel has (3 ms a file here);
# where the commit syncs is tested on its own
output._sync = lambda fd: None
NEW, NEW_SSP = json.loads(sys.argv[1])

def write(folder, files):
    for name, text in files.items():
        path = Path(folder) / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)

def commit(job, stop):
    with output.Staging() as staging:
        write(staging.path(job["out"]), NEW)
        if job["ssp"]:
            staging.path(job["ssp"], folder=False).write_text(NEW_SSP)
        if job.get("fail_move") is not None:
            real, moves = os.replace, []
            def replace(src, dst):
                if len(moves) == job["fail_move"]:
                    raise OSError("the disk broke")
                moves.append(dst)
                real(src, dst)
            output.os.replace = replace
        folders.checkpoint = stop

def next_run(job, stop):  # stages for the places given and fails: commits nothing
    folders.checkpoint = stop
    with output.Staging() as staging:
        places = [(job["out"], True), (job["ssp"], False)]
        for place, folder in places[::-1] if job.get("ssp first") else places:
            if place:
                staging.path(place, folder=folder)
        raise RuntimeError("the job failed")

for line in sys.stdin:
    job = json.loads(line)
    read, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        def note(kind, what):
            os.write(write_end, (json.dumps([kind, what]) + "\\n").encode())
        def stop(what, count=[0]):
            note("step", what)
            if count[0] == job["kill_at"]:
                os.kill(os.getpid(), signal.SIGKILL)
            count[0] += 1
        def shown(message, category, *args, **kwargs):
            if issubclass(category, output.CommitRecovered):
                note("said", str(message))
        warnings.showwarning = shown
        warnings.simplefilter("always")
        status = 0
        try:
            {"commit": commit, "next run": next_run}[job["do"]](job, stop)
        except RuntimeError as exc:
            status = 0 if str(exc) == "the job failed" else 3
        except BaseException:
            status = 3
        os._exit(status)
    os.close(write_end)
    with os.fdopen(read) as fh:
        lines = [json.loads(l) for l in fh]
    _, status = os.waitpid(pid, 0)
    status = -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)
    print(json.dumps({"status": status, "steps": [l[1] for l in lines if l[0] == "step"],
                      "said": [l[1] for l in lines if l[0] == "said"]}), flush=True)
"""


@pytest.fixture(scope="module")
def server():
    """run(do, out, ssp, kill_at=None, fail_move=None, ssp_first=False) -> (status, steps,
    said) of a job
    ("commit": stage NEW for ``out`` and NEW_SSP for ``ssp``, then commit; "next run": stage
    for the places given and fail, so that only the recovery acts), stopped by SIGKILL at its
    ``kill_at``-th step (counted from the commit in a commit; from the start in a next run);
    with ``fail_move``, that move of the commit raises OSError; with ``ssp_first`` a next run
    stages for ``ssp`` before ``out``."""
    proc = subprocess.Popen([sys.executable, "-c", SERVER, json.dumps([NEW, NEW_SSP])],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def run(do, out, ssp, kill_at=None, fail_move=None, ssp_first=False):
        proc.stdin.write(json.dumps({"do": do, "out": out and str(out),
                                     "ssp": ssp and str(ssp), "kill_at": kill_at,
                                     "fail_move": fail_move, "ssp first": ssp_first}) + "\n")
        proc.stdin.flush()
        answer = proc.stdout.readline()
        assert answer, "the server ended"
        answer = json.loads(answer)
        return answer["status"], answer["steps"], answer["said"]
    yield run
    proc.stdin.close()
    proc.wait(timeout=60)


def setup(tmp_path, case):
    """(out, ssp, its folder, old tree, new tree, old ssp, new ssp) of a case."""
    base = tmp_path / "place"
    if base.exists():
        shutil.rmtree(base)
    base.mkdir()
    out = base / "results" / "run1"
    ssp = base / "other" / "chain.ssp" if case == "two places" else None
    old = None
    if case != "new":
        write(out, OLD)
        old = dict(OLD)
    if ssp is not None:
        ssp.parent.mkdir()
        ssp.write_text(OLD_SSP)
    new = {**(old or {}), **NEW}
    return base, out, ssp, old, new


def counted(server, tmp_path, case):
    """The names of the steps of a case's commit, run to its end."""
    base, out, ssp, old, new = setup(tmp_path, case)
    status, steps, said = server("commit", out, ssp)
    assert status == 0 and said == []
    assert tree(out) == new and not list(base.rglob(".driftfmu-*"))
    return steps


@pytest.mark.parametrize("case", ["new", "existing", "two places"])
def test_a_commit_killed_at_every_step_is_completed_by_the_next_run(case, server, tmp_path):
    """``new``: --out not there yet (folders to make); ``existing``: an --out with files of a
    run before and a file of the user's; ``two places``: the build's case, an existing --out
    and a file elsewhere (--ssp), two staging folders, one commit."""
    steps = counted(server, tmp_path, case)
    decided = steps.index("name " + output.JOURNAL)
    done = steps.index("journal done")
    assert steps[decided + 1:done] and all(s in ("mkdir", "aside", "in")
                                           for s in steps[decided + 1:done])
    assert steps.count("in") == len(NEW) + (case == "two places"), steps
    assert steps.count("aside") == {"new": 0, "existing": 2, "two places": 3}[case], steps

    for i in range(len(steps)):
        base, out, ssp, old, new = setup(tmp_path, case)
        before = texts(base)
        status, passed, _ = server("commit", out, ssp, kill_at=i)
        assert status == -signal.SIGKILL and passed == steps[:i + 1], i
        mid = tree(out)
        if mid not in (old, new):  # a mix: never silent
            assert list(base.rglob(output.JOURNAL)), (i, steps[i], mid)
        if i <= decided:  # nothing lost: every file of before is somewhere
            assert set(before) <= set(texts(base)), (i, steps[i])
        else:  # every new file is somewhere, and so is the user's
            assert set(NEW.values()) <= set(texts(base)), (i, steps[i])
            assert case == "new" or "the user's" in texts(base), (i, steps[i])

        # the same command again (finding the second staging folder first, every other time)
        status, _, said = server("next run", out, ssp, ssp_first=i % 2 == 1)

        assert status == 0
        want = old if i <= decided else new
        assert tree(out) == want, (i, steps[i])
        if ssp is not None:
            assert ssp.read_text() == (OLD_SSP if i <= decided else NEW_SSP), (i, steps[i])
        assert not list(base.rglob(".driftfmu-*")), (i, steps[i], list(base.rglob(".d*")))
        if decided < i <= done:
            assert len(said) == 1 and said[0].startswith(
                "completed the results commit of %s" % out), (i, steps[i], said)
            # the moves the kill left (from the step it stopped, which did not happen), of all
            moves = [s for s in steps[decided + 1:done] if s != "mkdir"]
            left = sum(s != "mkdir" for s in steps[i:done])
            assert said[0].endswith(
                ": %d of its %d moves were left; every new file is in place" % (left, len(moves))
                if left else ": every new file was in place already"), (i, steps[i], said)
        else:
            assert said == [], (i, steps[i], said)

    # and the place takes the next commit as any other
    with output.staged(out) as stage:
        write(stage, {"a.csv": "newest a"})
    assert tree(out) == {**new, "a.csv": "newest a"}


def test_a_recovery_killed_at_every_step_is_finished_by_the_run_after(server, tmp_path):
    """The next run's recovery, killed at each of its steps too (a run that touches only the
    place of the second staging folder, which finds the first through it): the run after
    finishes it."""
    first_in = counted(server, tmp_path, "two places").index("in")  # killed after: a mix
    kills = 0
    for j in range(200):
        base, out, ssp, old, new = setup(tmp_path, "two places")
        assert server("commit", out, ssp, kill_at=first_in + 1)[0] == -signal.SIGKILL
        assert tree(out) not in (old, new)
        status, passed, _ = server("next run", None, ssp, kill_at=j)
        if status != -signal.SIGKILL:
            break  # the recovery has no step j
        kills += 1
        status, _, said = server("next run", out, ssp)
        assert status == 0 and len(said) <= 1
        assert tree(out) == new and ssp.read_text() == NEW_SSP, (j, passed)
        assert not list(base.rglob(".driftfmu-*")), (j, passed, list(base.rglob(".d*")))
    assert kills >= 8


def test_a_roll_back_killed_at_every_step_is_finished_by_the_next_run(server, tmp_path):
    """A move that fails rolls the commit back at once; killed during that, the commit is
    rolled back (or, killed before the journal says so, completed) by the next run."""
    said_back = 0
    for j in range(200):
        base, out, ssp, old, new = setup(tmp_path, "existing")
        status, passed, _ = server("commit", out, ssp, kill_at=j, fail_move=3)
        if status != -signal.SIGKILL:
            assert status == 3  # the commit raised, rolled back: as it was
            assert tree(out) == old and not list(base.rglob(".driftfmu-*"))
            break
        status, _, said = server("next run", out, ssp)
        assert status == 0
        assert tree(out) in (old, new), (j, passed)
        assert not list(base.rglob(".driftfmu-*")), (j, passed, list(base.rglob(".d*")))
        if said and said[0].startswith("rolled back"):
            assert tree(out) == old
            said_back += 1
    assert j >= 10 and said_back >= 3


def test_a_commit_that_cannot_be_completed_keeps_every_file_and_says_so(server, tmp_path):
    """A file put where the journal moves a new one, after the kill: the recovery stops,
    touches nothing more and keeps the staging folders, in one line."""
    first_in = counted(server, tmp_path, "existing").index("in")
    base, out, ssp, old, new = setup(tmp_path, "existing")
    assert server("commit", out, ssp, kill_at=first_in + 1)[0] == -signal.SIGKILL
    (out / "d.txt").write_text("the user's newer file")
    before = texts(base)
    status, _, said = server("next run", out, ssp)
    assert status == 0
    assert len(said) == 1 and said[0].startswith("kept the staging folders") and "d.txt" in said[0]
    assert texts(base) == before  # nothing moved, nothing removed
    assert list(base.rglob(output.JOURNAL))


def test_an_unfinished_commit_moved_or_copied_elsewhere_is_left_as_it_is_and_said(server,
                                                                                  tmp_path):
    """A results folder holding an unfinished commit (its staging folder inside), copied
    (``cp -a``) and moved by the user after the kill: a run there says so and touches nothing
    (the journal names the place it was made); the copy's original, where a run finishes it,
    is completed."""
    first_in = counted(server, tmp_path, "existing").index("in")
    base, out, ssp, old, new = setup(tmp_path, "existing")
    assert server("commit", out, ssp, kill_at=first_in + 1)[0] == -signal.SIGKILL
    copy, moved = out.parent / "copy", out.parent / "moved"
    subprocess.run(["cp", "-a", str(out), str(copy)], check=True)
    before = {p: texts(p) for p in (copy, out)}
    for place in (copy, moved):
        if place == moved:
            out.rename(moved)
        status, _, said = server("next run", place, None)
        assert status == 0 and len(said) == 1, said
        assert said[0].startswith("left %s/%s" % (place, output.STAGE)), said
        assert "made as %s/%s" % (out, output.STAGE) in said[0]
        assert texts(place) == before[copy if place == copy else out]
        assert list(place.glob(output.STAGE + "*/" + output.JOURNAL))
    moved.rename(out)  # back where it was made: the next run there completes it
    status, _, said = server("next run", out, None)
    assert said and said[0].startswith("completed") and tree(out) == new


def test_the_commit_writes_to_disk_what_each_step_needs_before_it(tmp_path, monkeypatch):
    """fsync: the staged files and the staging folders' records before the journal is named,
    the journal and its folder before the first move, every folder a move changed before the
    journal is marked done (so that a power loss, too, leaves a commit the next run can finish),
    and the journal's folder after it is marked done (the mark's name; were it lost, the next
    run would find the journal with every move done).
    """
    events = []
    monkeypatch.setattr(output, "_sync", lambda fd: events.append(
        ("sync", os.path.realpath("/proc/self/fd/%d" % fd))))
    monkeypatch.setattr(folders, "checkpoint", lambda what: events.append(("step", what)))
    base, out, ssp, old, new = setup(tmp_path, "two places")
    with output.Staging() as staging:
        staged = [staging.path(out), staging.path(ssp, folder=False)]
        write(staged[0], NEW)
        staged[1].write_text(NEW_SSP)
        stages = [os.path.realpath(p.parent) for p in staged]
        del events[:]
    assert tree(out) == new and ssp.read_text() == NEW_SSP
    steps = [e[1] for e in events]
    named = steps.index("name " + output.JOURNAL)
    first_move = next(i for i, e in enumerate(events) if e[1] in ("mkdir", "aside", "in"))
    done = steps.index("journal done")
    before = {e[1] for e in events[:named] if e[0] == "sync"}
    files = {os.path.realpath(os.path.join(stages[0], out.name, f)) for f in NEW}
    files.add(os.path.realpath(os.path.join(stages[1], ssp.name)))
    records = {os.path.join(s, folders.LOCK) for s in stages}
    assert files | records | set(stages) <= before, sorted(files | records - before)
    assert os.path.join(stages[0], output.JOURNAL + ".part") in before  # its text
    assert stages[0] in {e[1] for e in events[named:first_move] if e[0] == "sync"}  # its name
    changed = {str(out), str(out / "sub"), str(out / "sub" / "deeper"), str(ssp.parent),
               stages[0], stages[1]}
    assert changed <= {e[1] for e in events[first_move:done] if e[0] == "sync"}
    assert [e[1] for e in events[done:] if e[0] == "sync"] == [stages[0]]


@pytest.mark.parametrize("kind", ["a folder for a file", "a file for a folder",
                                  "a file under a file", "a folder under a file"])
def test_a_destination_of_the_other_kind_is_refused_before_anything_is_staged(kind, tmp_path):
    """A file asked for where a folder of the user's is (the commit would move the folder aside
    and remove it with its files), a folder where a file is, or either under a file: one
    UsageError from Staging.path, nothing staged, the user's files as they were."""
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("my notes\n")
    (tmp_path / "file.csv").write_text("my data\n")
    target, folder = {"a folder for a file": ("mine", False),
                      "a file for a folder": ("file.csv", True),
                      "a file under a file": ("file.csv/x.csv", False),
                      "a folder under a file": ("file.csv/out", True)}[kind]
    before = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*"))
    with pytest.raises(UsageError, match="is an existing (folder|file); allowed: "):
        with output.Staging() as staging:
            staged = staging.path(tmp_path / target, folder=folder)
            (staged.mkdir() if folder else staged.write_text("new\n"))
    assert sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*")) == before
    assert (tmp_path / "mine" / "notes.txt").read_text() == "my notes\n"
    assert (tmp_path / "file.csv").read_text() == "my data\n"


def test_an_unfinished_commit_recorded_on_another_machine_is_left_as_it_is(server, tmp_path):
    """A shared file system: the staging folder of an unfinished commit whose record names
    another host, at this very path (its process may be alive there, its lock unseen here):
    a run here says so and touches nothing; with this host's record it is completed."""
    first_in = counted(server, tmp_path, "existing").index("in")
    base, out, ssp, old, new = setup(tmp_path, "existing")
    assert server("commit", out, ssp, kill_at=first_in + 1)[0] == -signal.SIGKILL
    stage, = out.glob(output.STAGE + "*")
    lock = stage / folders.LOCK
    record = json.loads(lock.read_text())
    lock.write_text(json.dumps(dict(record, host="another-machine")))
    before = texts(base)
    status, _, said = server("next run", out, None)
    assert status == 0 and len(said) == 1, said
    assert said[0].startswith("left %s as it is" % stage) and "on another-machine" in said[0]
    assert texts(base) == before and (stage / output.JOURNAL).exists()
    lock.write_text(json.dumps(record))  # the other side: this host's
    status, _, said = server("next run", out, None)
    assert said and said[0].startswith("completed") and tree(out) == new


#: A process that tries whether a folder can be written (the command line's check of --out,
#: output.probe) and is killed at the N-th step of it.
PROBE_KILLED = """
import os, signal, sys
from driftfmu.simulations import cli, folders
count = [int(sys.argv[2])]
def checkpoint(what):
    count[0] -= 1
    if count[0] < 0:
        os.kill(os.getpid(), signal.SIGKILL)
folders.checkpoint = checkpoint
cli.check_folder("--out", sys.argv[1])
print("done", flush=True)
"""


def test_a_process_killed_while_it_tries_an_output_folder_leaves_nothing_for_good(tmp_path):
    """The check of --out makes a staging folder and removes it; killed at any step of that,
    it leaves at most a staging folder, which the next run there removes (before: an empty
    ``.driftfmu-write-test-*`` folder stayed for good)."""
    for step in range(20):
        place = tmp_path / ("place%d" % step)
        place.mkdir()
        r = subprocess.run([sys.executable, "-c", PROBE_KILLED, str(place / "out"), str(step)],
                           capture_output=True, text=True, timeout=120)
        if r.returncode == 0:
            assert r.stdout.strip() == "done" and os.listdir(place) == []
            break
        assert r.returncode == -signal.SIGKILL, r.stderr
        left = os.listdir(place)
        assert all(name.startswith(output.STAGE) for name in left), left
        with output.staged(place / "out") as stage:
            (stage / "a.csv").write_text("1\n")
        assert os.listdir(place) == ["out"], (step, os.listdir(place))
    assert 5 <= step < 20  # the folder, its lock file (made, written, named); the removal
