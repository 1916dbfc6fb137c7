"""Work folders of a process killed outright (SIGKILL, or SIGTERM to a script without a handler)
are removed by the next process that makes one in the same place, and only those: a live
process's folders, folders without driftfmu's lock, other users' and other names stay
(simulations/folders.py)."""
import os
import signal
import subprocess
import sys
import time

import pytest

from driftfmu.simulations import folders, output

pytestmark = pytest.mark.skipif(folders.fcntl is None, reason="no flock on this platform")

#: A child that makes a folder, prints it and then dies by SIGKILL ("die") or waits for its
#: standard input to close ("live").
CHILD = """
import os, signal, sys
from driftfmu.simulations import folders
print(folders.make(sys.argv[1], dir=sys.argv[2]), flush=True)
if sys.argv[3] == "die":
    os.kill(os.getpid(), signal.SIGKILL)
sys.stdin.read()
"""


def killed(prefix, where):
    """The folder made by a child killed outright."""
    r = subprocess.run([sys.executable, "-c", CHILD, prefix, str(where), "die"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == -signal.SIGKILL, r.stderr
    folder = r.stdout.strip()
    assert os.path.isfile(os.path.join(folder, folders.LOCK))
    return folder


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
        child.wait(timeout=60)


def test_sweep_removes_the_folders_of_killed_processes_and_only_those(tmp_path, live):
    # FMUs extracted by the masters and the fast master, the kernel's and a build's work
    dead = [killed(prefix, tmp_path) for prefix in ("driftfmu_fmu_", "driftfmu_fast_",
                                                    "driftfmu_kernel_", "driftfmu_Excitation_")]
    running, child = live("driftfmu_fmu_")
    unlocked = tmp_path / "driftfmu_fmu_without_lock"  # being made, or not made by make()
    unlocked.mkdir()
    other = killed("someone_else_", tmp_path)
    assert folders.stale(dead[0]) and not folders.stale(running)
    assert not folders.stale(str(unlocked))

    removed = folders.sweep(folders.TEMPORARY, dir=tmp_path)

    assert sorted(removed) == sorted(dead)
    assert not any(os.path.exists(d) for d in dead)
    assert os.path.isdir(running) and unlocked.is_dir() and os.path.isdir(other)
    assert folders.sweep(folders.TEMPORARY, dir=tmp_path) == []  # once per process and place
    child.stdin.close()
    child.wait(timeout=60)
    assert folders.stale(running)  # its process has ended: the next process removes it


def test_temporary_sweeps_first_and_removes_its_folder_at_the_end(tmp_path, monkeypatch):
    monkeypatch.setattr(folders.tempfile, "tempdir", str(tmp_path))
    dead = killed("driftfmu_doctor_", tmp_path)
    with folders.temporary("driftfmu_doctor_") as folder:
        assert os.path.dirname(folder) == str(tmp_path) and not folders.stale(folder)
        assert not os.path.exists(dead)
    assert not os.path.exists(folder) and folder not in folders._HELD
    assert list(tmp_path.iterdir()) == []


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

    with output.staged(tmp_path / "results") as stage:
        (stage / "a.csv").write_text("1\n")

    assert not os.path.exists(dead)
    assert (tmp_path / holding / ".replaced-0").read_text().startswith("the only copy")
    assert (tmp_path / "results" / "a.csv").read_text() == "1\n"
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted([os.path.basename(holding), "results"])


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

    def extracted():
        return sorted(p for p in tmp_path.glob("driftfmu_fmu_*")
                      if (p / "modelDescription.xml").exists())

    deadline = time.monotonic() + 120
    while len(extracted()) < 3 and time.monotonic() < deadline and script.poll() is None:
        time.sleep(0.05)
    time.sleep(0.5)  # stepping by now
    script.send_signal(signal.SIGTERM)
    script.communicate(timeout=60)
    assert script.returncode == -signal.SIGTERM
    left = extracted()
    assert len(left) == 3 and all(folders.stale(str(p)) for p in left)

    r = subprocess.run([sys.executable, "-c", SCRIPT, "0.01", fmu_dir], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == "done", r.stderr
    assert not any(p.exists() for p in left)
    assert not list(tmp_path.glob("driftfmu_*")), list(tmp_path.iterdir())
