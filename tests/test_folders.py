"""Work folders of a process killed outright (SIGKILL, or SIGTERM to a script without a handler)
are removed by the next process that makes one in the same place, and only those that are
provably its: a live process's folders (also one an exec'd child still uses, or one seen through
an overlay's layer), copies and renamed folders, folders without driftfmu's lock, other users'
and other names stay; folders half made or half removed by a killed process go
(simulations/folders.py)."""
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import textwrap
import time

import pytest

from driftfmu.simulations import folders, output
from waiting import BOUND, wait_for

pytestmark = pytest.mark.skipif(folders.fcntl is None, reason="no flock on this platform")

#: A child that makes a folder (in argv[2], or "-": the private folder of TMPDIR), prints it
#: and then: "die" (SIGKILL), "live" (waits for its standard input to close), "exec" (starts a
#: program with exec that waits for that input, then SIGKILL), "make N" (SIGKILL at the N-th
#: checkpoint of make), "remove N" (writes a file, then SIGKILL at the N-th checkpoint of the
#: folder's removal).
CHILD = """
import os, signal, subprocess, sys
from driftfmu.simulations import folders
prefix, where, mode = sys.argv[1:4]

def stop_at(n):
    count = [n]
    def checkpoint(what):
        count[0] -= 1
        if count[0] < 0:
            os.kill(os.getpid(), signal.SIGKILL)
    folders.checkpoint = checkpoint

if mode.startswith("make "):
    stop_at(int(mode.split()[1]))
folder = folders.make(prefix, dir=None if where == "-" else where)
print(folder, flush=True)
if mode == "exec":  # a program of its own (exec), inheriting the descriptors
    subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], close_fds=False)
if mode.startswith("remove "):
    os.mkdir(os.path.join(folder, "sub"))
    for name in ("a.txt", "sub/b.txt"):
        with open(os.path.join(folder, name), "w") as fh:
            fh.write("work")
    stop_at(int(mode.split()[1]))
    folders.remove(folder)
if mode in ("die", "exec") or mode.startswith(("make ", "remove ")):
    os.kill(os.getpid(), signal.SIGKILL)
sys.stdin.read()
"""


def run_child(prefix, where, mode, tmp_path=None):
    """Run CHILD to its SIGKILL; the folder it printed (None if it printed none)."""
    env = dict(os.environ, TMPDIR=str(tmp_path)) if tmp_path is not None else None
    r = subprocess.run([sys.executable, "-c", CHILD, prefix, str(where), mode],
                       capture_output=True, text=True, timeout=BOUND, env=env)
    assert r.returncode == -signal.SIGKILL, r.stderr
    return r.stdout.strip() or None


def killed(prefix, where="-", tmp_path=None):
    """The folder made by a child killed outright ("-": in the private folder of TMPDIR =
    ``tmp_path``)."""
    folder = run_child(prefix, where, "die", tmp_path)
    assert os.path.isfile(os.path.join(folder, folders.LOCK))
    return folder


@pytest.fixture
def private(tmp_path, monkeypatch):
    """The temporary folder is ``tmp_path``: its private folder of work folders."""
    monkeypatch.setattr(folders.tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(folders, "_SWEPT", set())
    return tmp_path / ("driftfmu-%d" % os.geteuid())


@pytest.fixture
def live(tmp_path):
    """make(prefix) -> the folder of a child that is still running (stopped at the end)."""
    children = []

    def make(prefix, where=tmp_path):
        child = subprocess.Popen([sys.executable, "-c", CHILD, prefix, str(where), "live"],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        children.append(child)
        return child.stdout.readline().strip(), child
    yield make
    for child in children:
        child.stdin.close()
        child.wait(timeout=BOUND)


def test_sweep_removes_the_folders_of_killed_processes_and_only_those(tmp_path, live):
    # FMUs extracted by the masters and the fast master, the kernel's and a build's work
    dead = [killed(prefix, tmp_path) for prefix in ("driftfmu_fmu_", "driftfmu_fast_",
                                                    "driftfmu_kernel_", "driftfmu_Excitation_")]
    running, child = live("driftfmu_fmu_")
    unlocked = tmp_path / "driftfmu_fmu_without_lock"  # not made by make(), a file inside
    unlocked.mkdir()
    (unlocked / "notes.txt").write_text("mine")
    other = killed("someone_else_", tmp_path)
    assert folders.stale(dead[0]) and not folders.stale(running)
    assert not folders.stale(str(unlocked))

    removed = folders.sweep(folders.TEMPORARY, dir=tmp_path)

    assert sorted(removed) == sorted(dead)
    assert not any(os.path.exists(d) for d in dead)
    assert os.path.isdir(running) and unlocked.is_dir() and os.path.isdir(other)
    assert (unlocked / "notes.txt").read_text() == "mine"
    assert folders.sweep(folders.TEMPORARY, dir=tmp_path) == []  # once per process and place
    child.stdin.close()
    child.wait(timeout=BOUND)
    assert folders.stale(running)  # its process has ended: the next process removes it


def test_temporary_sweeps_first_and_removes_its_folder_at_the_end(tmp_path, private):
    dead = killed("driftfmu_doctor_", tmp_path=tmp_path)
    assert os.path.dirname(dead) == str(private)
    with folders.temporary("driftfmu_doctor_") as folder:
        assert os.path.dirname(folder) == str(private) and not folders.stale(folder)
        assert not os.path.exists(dead)
    assert not os.path.exists(folder) and folder not in folders._HELD
    assert list(tmp_path.iterdir()) == []  # the private folder goes with its last folder


def test_work_folders_live_in_a_private_folder_of_the_user(tmp_path, private):
    """Made by driftfmu with mode 0700 (also under a umask that would take the owner's bits),
    owned by the user; nothing else of the temporary folder is swept."""
    beside = tmp_path / "driftfmu_fmu_beside"  # a dead work folder's look-alike, elsewhere
    beside.mkdir()
    old = os.umask(0o777)
    try:
        folder = folders.make("driftfmu_fmu_")
    finally:
        os.umask(old)
    st = private.stat()
    assert os.path.dirname(folder) == str(private)
    assert (st.st_mode & 0o777, st.st_uid) == (0o700, os.geteuid())
    assert folders.sweep(folders.TEMPORARY) == [] and beside.is_dir()
    folders.remove(folder)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["driftfmu_fmu_beside"]


@pytest.mark.parametrize("case", ["symbolic link", "file", "mode 0755", "another user's"])
def test_an_unsafe_private_folder_is_refused_in_one_line(case, tmp_path, private):
    from driftfmu.simulations.errors import UsageError
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(mode=0o700)
    if case == "symbolic link":
        private.symlink_to(elsewhere)
    elif case == "file":
        private.write_text("a file")
    else:
        private.mkdir(mode=0o700)
        if case == "mode 0755":
            private.chmod(0o755)
        else:
            if os.geteuid() != 0:
                pytest.skip("only root can give a folder to another user")
            os.chown(private, 4242, 4242)
    want = {"symbolic link": "is a symbolic link", "file": "is not a folder",
            "mode 0755": "has mode 0755", "another user's": "is owned by uid 4242"}[case]
    for call in (lambda: folders.make("driftfmu_fmu_"),
                 lambda: folders.sweep(folders.TEMPORARY)):
        with pytest.raises(UsageError) as err:
            call()
        text = str(err.value)
        assert "\n" not in text and want in text and "allowed: a folder of this user's" in text
    assert list(elsewhere.iterdir()) == []


#: Each permission bit of the private folder on its own: any permission for its group or for
#: others is refused; setgid (inherited from a setgid temporary folder) and sticky give no one
#: access to a folder of mode 0700 and are taken.
PRIVATE_MODES = {0o700: None, 0o2700: None, 0o1700: None, 0o3700: None}
PRIVATE_MODES.update({0o700 | bit: "has mode %04o: others may use it" % (0o700 | bit)
                      for bit in (0o040, 0o020, 0o010, 0o004, 0o002, 0o001)})
PRIVATE_MODES.update({0o770: "has mode 0770", 0o750: "has mode 0750",
                      0o707: "has mode 0707", 0o2770: "has mode 2770"})


@pytest.mark.parametrize("mode", sorted(PRIVATE_MODES), ids=lambda m: "%04o" % m)
def test_each_permission_bit_of_the_private_folder_is_told_apart(mode, tmp_path, private):
    from driftfmu.simulations.errors import UsageError
    private.mkdir(mode=0o700)
    private.chmod(mode)
    want = PRIVATE_MODES[mode]
    if want is None:
        folder = folders.make("driftfmu_fmu_")
        assert os.path.dirname(folder) == str(private)
        folders.remove(folder)
        return
    with pytest.raises(UsageError, match=want):
        folders.make("driftfmu_fmu_")
    assert os.listdir(private) == []


@pytest.mark.parametrize("case", ["sticky, every user may write it (/tmp)",
                                  "every user may write it", "another user's"])
def test_the_temporary_folder_around_the_private_folder_is_checked(case, tmp_path,
                                                                   monkeypatch):
    """Another user who can rename the private folder out of the temporary folder (not
    sticky), or who owns the temporary folder, could put a folder of theirs in its place
    between driftfmu's check and its use: refused in one line.  A sticky folder (/tmp) keeps
    this user's entries."""
    from driftfmu.simulations.errors import UsageError
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    tmp.chmod(0o1777 if case.startswith("sticky") else 0o777)
    if case == "another user's":
        if os.geteuid() != 0:
            pytest.skip("only root can give a folder to another user")
        tmp.chmod(0o755)
        os.chown(tmp, 4242, 4242)
    monkeypatch.setattr(folders.tempfile, "tempdir", str(tmp))
    monkeypatch.setattr(folders, "_SWEPT", set())
    if case.startswith("sticky"):
        folder = folders.make("driftfmu_fmu_")
        assert os.path.dirname(folder) == str(tmp / ("driftfmu-%d" % os.geteuid()))
        folders.remove(folder)
        return
    want = ("%s can be written by every user (mode 0777)" % tmp if case != "another user's"
            else "%s is owned by uid 4242" % tmp)
    for call in (lambda: folders.make("driftfmu_fmu_"),
                 lambda: folders.sweep(folders.TEMPORARY)):
        with pytest.raises(UsageError) as err:
            call()
        assert "\n" not in str(err.value) and want in str(err.value), str(err.value)
    assert os.listdir(tmp) == []


def other_host(folder):
    """Rewrite the record in ``folder``'s lock file as made on another machine (the same path,
    device and inode: a shared file system mounted at the same place)."""
    lock = os.path.join(folder, folders.LOCK)
    with open(lock) as fh:
        record = json.load(fh)
    assert record["host"] != "another-machine"
    record["host"] = "another-machine"
    with open(lock, "w") as fh:
        json.dump(record, fh)


def test_a_folder_recorded_on_another_machine_is_never_swept(tmp_path, private):
    """A dead work folder whose record names another host (a shared file system: that host's
    process may be alive, and its lock is not seen here), and a half-made one whose complete
    record does: never removed, never claimed; the same folder with this host's record is."""
    theirs, mine = (killed("driftfmu_fmu_", tmp_path=tmp_path) for _ in range(2))
    other_host(theirs)
    half = private / "driftfmu_fmu_half"
    half.mkdir()
    shutil.copy(os.path.join(theirs, folders.LOCK), half / folders.PART)
    record = json.loads((half / folders.PART).read_text())
    st = os.lstat(half)
    record.update(path=str(half), dev=st.st_dev, ino=st.st_ino)
    (half / folders.PART).write_text(json.dumps(record))
    assert folders.made_here(theirs)[0] is False and folders.made_here(mine)[0] is True
    assert folders.claim(theirs) is None and not folders.stale(theirs)
    assert not folders.stale(str(half))

    assert folders.sweep(folders.TEMPORARY) == [mine]

    assert os.path.isfile(os.path.join(theirs, folders.LOCK))
    assert (half / folders.PART).is_file()
    record["host"] = socket.gethostname()  # the other side: this host's half-made folder goes
    (half / folders.PART).write_text(json.dumps(record))
    folders._SWEPT.clear()
    assert folders.sweep(folders.TEMPORARY) == [str(half)]


def test_a_copy_or_a_rename_of_a_work_folder_is_never_removed(tmp_path, private):
    """A user's ``cp -a`` copy and a renamed work folder of a killed process, each with a file
    of the user's inside, stay; the original of the copy goes.  (Before: both were removed, as
    any ``driftfmu_*`` folder holding a lock file that nobody locked.)"""
    copied, renamed = (killed("driftfmu_fmu_", tmp_path=tmp_path) for _ in range(2))
    where = os.path.dirname(copied)  # the private folder
    copy = os.path.join(where, "driftfmu_fmu_kept")
    subprocess.run(["cp", "-a", copied, copy], check=True)
    moved = os.path.join(where, "driftfmu_fmu_mine")
    os.rename(renamed, moved)
    for folder in (copy, moved):
        with open(os.path.join(folder, "notes.txt"), "w") as fh:
            fh.write("my notes")
    assert not folders.stale(copy) and not folders.stale(moved) and folders.stale(copied)

    removed = folders.sweep(folders.TEMPORARY)

    assert removed == [copied]
    for folder in (copy, moved):
        with open(os.path.join(folder, "notes.txt")) as fh:
            assert fh.read() == "my notes"


def test_the_sweep_leaves_other_users_folders_alone(tmp_path, private):
    """A dead work folder given to another user, in this user's private folder, and another
    user's private folder with a dead work folder: both stay (issue 32)."""
    if os.geteuid() != 0:
        pytest.skip("only root can give a folder to another user")
    theirs = killed("driftfmu_fmu_", tmp_path=tmp_path)
    mine = killed("driftfmu_fmu_", tmp_path=tmp_path)
    other_private = tmp_path / "driftfmu-4242"
    other_private.mkdir(mode=0o700)
    other = killed("driftfmu_fmu_", other_private)
    for folder in (theirs, other, str(other_private)):
        for top, dirs, files in os.walk(folder):
            for path in [top] + [os.path.join(top, f) for f in files]:
                os.chown(path, 4242, 4242)

    removed = folders.sweep(folders.TEMPORARY)

    assert removed == [mine]
    assert os.path.isfile(os.path.join(theirs, folders.LOCK))
    assert os.path.isfile(os.path.join(other, folders.LOCK))
    assert folders.sweep(folders.TEMPORARY, dir=other_private) == []


def test_a_program_started_with_exec_keeps_the_folder_of_its_killed_parent(tmp_path, private):
    """The lock is inherited by a program its process starts with ``exec``: killed, the
    process leaves a folder that is still in use and stays until that program ends.
    (Before: the lock's descriptor was closed on exec, and the folder went under it.)"""
    maker = subprocess.Popen([sys.executable, "-c", CHILD, "driftfmu_fmu_", "-", "exec"],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                             env=dict(os.environ, TMPDIR=str(tmp_path)))
    try:
        folder = maker.stdout.readline().strip()
        assert maker.wait(timeout=BOUND) == -signal.SIGKILL
        assert not folders.stale(folder)
        assert folders.sweep(folders.TEMPORARY) == [] and os.path.isdir(folder)
    finally:
        maker.stdin.close()  # the program ends
    maker.stdout.read()  # until the program has closed its descriptors
    deadline = time.monotonic() + 60
    while not folders.stale(folder) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert folders.stale(folder)


#: The checkpoints of folders.make: before the folder, before the lock file, before its
#: record, before its name.
MAKE_STEPS = 4


@pytest.mark.parametrize("step", range(MAKE_STEPS))
def test_a_folder_left_by_a_process_killed_inside_make_is_swept(step, tmp_path, private):
    assert run_child("driftfmu_fmu_", "-", "make %d" % step, tmp_path) is None
    left = sorted(os.listdir(private))
    assert len(left) == (step > 0)  # killed before the folder: none
    removed = folders.sweep(folders.TEMPORARY)
    assert len(removed) == len(left) and os.listdir(private) == []


@pytest.mark.parametrize("content", ["empty", "an unlocked half-made lock file"])
def test_a_half_made_folder_is_swept(content, tmp_path):
    """What a process killed inside make leaves, made directly; a folder being made by a
    live process (its half-made lock file locked) stays.  (Before: neither was swept.)"""
    part = folders.LOCK + ".part"
    half = tmp_path / "driftfmu_fmu_half"
    half.mkdir()
    if content != "empty":
        (half / part).write_bytes(b"")
    busy = tmp_path / "driftfmu_fmu_busy"
    busy.mkdir()
    fd = os.open(busy / part, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        folders.fcntl.flock(fd, folders.fcntl.LOCK_EX)
        assert folders.stale(str(half)) and not folders.stale(str(busy))
        assert folders.sweep(folders.TEMPORARY, dir=tmp_path) == [str(half)]
    finally:
        os.close(fd)
    assert busy.is_dir() and not half.exists()


def test_a_folder_half_removed_by_a_killed_process_is_swept(tmp_path, private):
    """Killed at any point of removing its folder (files, lock file last, then the folder),
    a process leaves one that the next sweep removes."""
    for steps in range(50):
        folder = run_child("driftfmu_fmu_", "-", "remove %d" % steps, tmp_path)
        if not os.path.exists(folder):
            break  # removed before the step: every step is tried
        folders._SWEPT.clear()
        assert folders.sweep(folders.TEMPORARY) == [folder], steps
    assert 4 <= steps < 50  # a.txt, sub, the lock file, the folder


OVERLAY = """
import json, os, subprocess, sys, tempfile
base = sys.argv[1]
for d in ("lower", "upper", "work", "merged"):
    os.mkdir(os.path.join(base, d))
subprocess.run(["mount", "-t", "overlay", "overlay", "-o",
                "lowerdir={0}/lower,upperdir={0}/upper,workdir={0}/work".format(base),
                os.path.join(base, "merged")], check=True)
from driftfmu.simulations import folders
seen = {}
for made, swept in (("merged", "upper"), ("upper", "merged")):
    child = subprocess.Popen([sys.executable, "-c", sys.argv[2], "driftfmu_fmu_", "-", "live"],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                             env=dict(os.environ, TMPDIR=os.path.join(base, made)))
    folder = child.stdout.readline().strip()
    there = os.path.join(base, swept, os.path.relpath(folder, os.path.join(base, made)))
    tempfile.tempdir = os.path.join(base, swept)
    seen[made] = [os.path.isdir(there), there in folders.sweep(folders.TEMPORARY),
                  os.path.isdir(folder)]
    child.stdin.close()
    child.wait()
print(json.dumps(seen))
"""


def test_a_live_folder_seen_through_another_layer_of_an_overlay_stays(tmp_path):
    """A live process's folder in an overlay file system, swept through its upper layer (and
    the other way round): flock does not see the other view's lock there, so the folder's
    record (its path and device) tells it is not this view's.  (Before: removed.)"""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        pytest.skip("needs root and unshare(1) to mount an overlay in a mount namespace")
    probe = subprocess.run(["unshare", "--mount", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip("no mount namespace here: %s" % probe.stderr.decode().strip())
    r = subprocess.run(["unshare", "--mount", sys.executable, "-c", OVERLAY, str(tmp_path),
                        CHILD], capture_output=True, text=True, timeout=BOUND)
    if "mount" in r.stderr and r.returncode != 0 and "overlay" in r.stderr:
        pytest.skip("no overlay file system here: %s" % r.stderr.strip().splitlines()[-1])
    assert r.returncode == 0, r.stderr
    seen = json.loads(r.stdout)
    # seen through the other view, swept there, still in place for its live process
    assert seen == {"merged": [True, False, True], "upper": [True, False, True]}


def test_a_forked_child_keeps_its_parents_folder_locked(tmp_path):
    folder = folders.make("driftfmu_fmu_", dir=tmp_path)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: holds the inherited lock until the parent writes
        os.close(write)
        os.read(read, 1)
        os._exit(0)
    os.close(read)
    try:
        fd = folders._HELD.pop(folder)
        os.close(fd)  # the parent lets go: the child still holds it
        assert not folders.stale(folder)
    finally:
        os.write(write, b"x")
        os.close(write)
        os.waitpid(pid, 0)
    assert folders.stale(folder)
    folders.remove(folder)
    assert not os.path.exists(folder)


def test_a_staging_folder_of_a_killed_master_goes_with_the_next_staging(tmp_path):
    dead = killed(output.STAGE, tmp_path)
    holding = killed(output.STAGE, tmp_path)  # killed while it moved results into place
    (tmp_path / holding / ".replaced-0").write_text("the only copy of a file of before")

    with pytest.warns(output.CommitRecovered, match="kept .*%s: it holds files that a "
                      "results commit moved aside" % os.path.basename(holding)):
        with output.staged(tmp_path / "results") as stage:
            (stage / "a.csv").write_text("1\n")

    assert not os.path.exists(dead)
    assert (tmp_path / holding / ".replaced-0").read_text().startswith("the only copy")
    assert (tmp_path / "results" / "a.csv").read_text() == "1\n"
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([os.path.basename(holding), "results"])


def test_a_copy_or_a_rename_of_a_staging_folder_is_never_removed(tmp_path):
    """A staging folder of a killed run that a user copied or renamed, with a file of theirs
    inside, stays; the original of the copy goes with the next staging there.  (Before: every
    one was removed.)"""
    copied, renamed = killed(output.STAGE, tmp_path), killed(output.STAGE, tmp_path)
    copy, moved = tmp_path / ".driftfmu-stage-copy", tmp_path / ".driftfmu-stage-mine"
    subprocess.run(["cp", "-a", copied, str(copy)], check=True)
    os.rename(renamed, moved)
    for folder in (copy, moved):
        (folder / "notes.txt").write_text("my notes")

    with output.staged(tmp_path / "results") as stage:
        (stage / "a.csv").write_text("1\n")

    assert not os.path.exists(copied)
    assert [(f / "notes.txt").read_text() for f in (copy, moved)] == ["my notes"] * 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        ".driftfmu-stage-copy", ".driftfmu-stage-mine", "results"]


SCRIPT = """
import sys, driftfmu
driftfmu.simulate(stop_time=float(sys.argv[1]), fmu_dir=sys.argv[2])
print("done", flush=True)
"""


@pytest.mark.integration
def test_an_api_script_stopped_by_sigterm_leaves_nothing_for_good(python_fmus, tmp_path):
    """SIGTERM to a script that set no handler ends it at once, with its FMUs extracted; the
    next script that extracts FMUs removes them."""
    fmu_dir = str(python_fmus["Excitation"].parent)
    env = dict(os.environ, TMPDIR=str(tmp_path))
    script = subprocess.Popen([sys.executable, "-c", SCRIPT, "1000", fmu_dir], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)

    def extracted():  # in the private folder of the temporary folder
        return sorted(p for p in tmp_path.glob("driftfmu-%d/driftfmu_fmu_*" % os.geteuid())
                      if (p / "modelDescription.xml").exists())

    deadline = time.monotonic() + 120
    while len(extracted()) < 3 and time.monotonic() < deadline and script.poll() is None:
        time.sleep(0.05)
    time.sleep(0.5)  # stepping by now
    script.send_signal(signal.SIGTERM)
    script.communicate(timeout=BOUND)
    assert script.returncode == -signal.SIGTERM
    left = extracted()
    assert len(left) == 3 and all(folders.stale(str(p)) for p in left)

    r = subprocess.run([sys.executable, "-c", SCRIPT, "0.01", fmu_dir], env=env,
                       capture_output=True, text=True, timeout=BOUND)
    assert r.returncode == 0 and r.stdout.strip() == "done", r.stderr
    assert not any(p.exists() for p in left)
    assert not list(tmp_path.glob("driftfmu*")), list(tmp_path.iterdir())


#: A pool's worker that makes a work folder and then does not stop on SIGTERM (busy in code
#: that holds the signal back): stop_pool kills it, and its folder must go with it.
STUCK_WORKER = textwrap.dedent("""
    import os, signal, sys, time
    from pathlib import Path
    from driftfmu.simulations import batch, folders

    def stuck(note):
        folder = folders.make("driftfmu_stuck_")
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        Path(note).write_text(folder)
        time.sleep(3600)

    if __name__ == "__main__":
        note = Path(sys.argv[1])
        try:
            with batch.process_pool(1) as pool:
                pool.submit(stuck, str(note))
                while not note.exists():
                    time.sleep(0.01)
                raise KeyboardInterrupt
        except KeyboardInterrupt:
            pass
        print(note.read_text())
""")


def test_the_folders_of_workers_killed_by_stop_pool_are_removed(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r = subprocess.run([sys.executable, "-c", STUCK_WORKER, str(tmp_path / "note")],
                       capture_output=True, text=True, timeout=BOUND,
                       env=dict(os.environ, TMPDIR=str(tmp)))
    assert r.returncode == 0, r.stderr
    folder = r.stdout.strip()
    assert folder.startswith(str(tmp)) and "driftfmu_stuck_" in folder
    assert not os.path.exists(folder)
    assert os.listdir(tmp) == []  # the private folder too, left empty


#: A process that starts, at ``site``, a program working in one of its work folders (the
#: program is FAKE: it notes that it started, then waits for its standard input to close).
STARTER = textwrap.dedent("""
    import os, sys
    from pathlib import Path
    site, fake = sys.argv[1], sys.argv[2]
    os.environ["CC"] = fake
    os.environ["PATH"] = os.path.dirname(fake) + os.pathsep + os.environ["PATH"]
    from driftfmu.simulations import folders
    if site == "batch kernel":
        from driftfmu.simulations import kernel
        kernel.library()
    elif site == "fast loop":
        from driftfmu.simulations import fastcosim
        fastcosim.loop_library()
    elif site == "compiler version":  # (in a work folder of its own)
        from driftfmu.fmu_src import native_build
        native_build.compiler_version((fake,))
    elif site == "native compile":
        from driftfmu.fmu_src import native_build
        with folders.temporary("driftfmu_native_Excitation_") as work:
            sources = Path(work) / "sources"
            c_files = native_build.stage_sources("Excitation", 3, sources)
            native_build.compile_library("x86_64-linux", sources, c_files,
                                         Path(work) / "x86_64-linux" / "Excitation.so")
    elif site in ("loader shim", "patchelf"):
        from driftfmu.fmu_src import builder
        with folders.temporary("driftfmu_loader_") as work:
            if site == "loader shim":
                builder._make_loader(Path(work), print)
            else:
                builder._linux_binaries("X", b"a library", ("dt_needed", None), Path(work))
    elif site == "doctor's trial host":
        from driftfmu.simulations import doctor
        sys.executable = fake
        doctor._run_instantiate("", "X.fmu")
    sys.exit("the program ended")
""")

#: The program: answers --version (a compiler asked what it is) at once; otherwise notes its
#: start in STARTED and waits until its standard input (the test's pipe) closes.
FAKE_PROGRAM = """#!/bin/sh
for a; do [ "$a" = --version ] && [ "$STOP_AT_VERSION" != 1 ] && { echo "fake 1"; exit 0; }; done
echo $$ >> "$STARTED"
cat > /dev/null
"""

PROGRAM_SITES = ["batch kernel", "fast loop", "native compile", "compiler version",
                 "loader shim", "patchelf", "doctor's trial host"]


@pytest.mark.parametrize("site", PROGRAM_SITES)
def test_a_program_started_in_a_work_folder_keeps_it_after_its_parent_is_killed(site,
                                                                                 tmp_path,
                                                                                 private):
    """Each place where driftfmu starts a program that works in a work folder (a compiler, the
    doctor's trial host): the parent killed outright while the program runs, the next sweep
    leaves the folder (the program holds its lock: ``subprocess``'s pass_fds), and removes it
    once the program has ended.  (Before: subprocess closed the lock's descriptor and the
    folder went under the running program.)"""
    fake = tmp_path / "bin" / ("patchelf" if site == "patchelf" else "fakecc")
    fake.parent.mkdir()
    fake.write_text(FAKE_PROGRAM)
    fake.chmod(0o755)
    started = tmp_path / "started"
    env = dict(os.environ, TMPDIR=str(tmp_path), STARTED=str(started),
               STOP_AT_VERSION="1" if site == "compiler version" else "0")
    env.pop("DRIFTFMU_KERNEL", None)  # (the kernel switched off compiles nothing)
    if site == "patchelf":
        env["CC"] = "no-such-compiler"
    parent = subprocess.Popen([sys.executable, "-c", STARTER, site, str(fake)], env=env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE)
    try:
        wait_for(lambda: started.exists() and started.read_text().strip(),
                 "the program started at %s" % site, process=parent)
        program = int(started.read_text().split()[0])
        work, = [p for p in private.iterdir() if p.name.startswith(folders.TEMPORARY)]
        parent.kill()
        parent.wait(timeout=BOUND)
        assert os.path.exists("/proc/%d" % program)  # still running: its parent is gone
        assert not folders.stale(str(work))
        assert folders.sweep(folders.TEMPORARY) == [] and work.is_dir()
    finally:
        parent.stdin.close()  # the program's standard input: it ends
        parent.kill()
        parent.wait(timeout=BOUND)
    wait_for(lambda: not os.path.exists("/proc/%d" % program), "the program's end")
    wait_for(lambda: folders.stale(str(work)), "the folder's lock released")
    folders._SWEPT.clear()
    assert folders.sweep(folders.TEMPORARY) == [str(work)]
