"""Every process driftfmu starts ends when the process that started it is gone, whatever ended
that one (issue 41: SIGKILL, the out-of-memory killer), and the next run removes what was left
(simulations/lifetime.py).

Each test starts its process in a session of its own, waits for the event that shows its
workers (or the program it runs) at work, kills the process with SIGKILL and then waits, within
:data:`waiting.BOUND`, until no process of the session is left.  Without the parent-death
signal the workers of a pool would wait for ever on their task queue (they hold its write end
themselves) and a program would run its task to its end (here: an hour)."""
import os
import queue
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from driftfmu.simulations import lifetime
from leftovers import copy_libraries, left_in
from waiting import BOUND, session_processes, wait_for

ROOT = Path(__file__).resolve().parent.parent

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the parent-death signal and /proc are Linux's")


def _start(argv, tmp_path, env=None, python=(), **kwargs):
    """Start ``python [python] argv`` (``driftfmu argv`` when ``python`` is empty) in a session
    of its own with ``TMPDIR`` = ``tmp_path/tmp`` (holding the compiled caches of this test
    run's temporary folder's private folder, if any: they are not compiled again); its standard error lines go
    to a queue."""
    import tempfile
    tmp = tmp_path / "tmp"
    tmp.mkdir(exist_ok=True)
    copy_libraries(tempfile.gettempdir(), tmp)
    full = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT), DRIFTFMU_PROGRESS_EVERY="0")
    full.update(env or {})
    command = [sys.executable] + (list(python) or ["-m", "driftfmu"]) + list(argv)
    p = subprocess.Popen(command, cwd=tmp_path, env=full, start_new_session=True,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         **kwargs)
    p.lines = queue.Queue()
    p.seen = []

    def read():
        for line in p.stderr:
            p.lines.put(line.rstrip("\n"))
        p.lines.put(None)
    threading.Thread(target=read, daemon=True).start()
    return p


def _wait_for_line(p, start):
    """The first standard error line of ``p`` that starts with ``start``."""
    while True:
        try:
            line = p.lines.get(timeout=BOUND)
        except queue.Empty:
            raise AssertionError("no line %r within %g s: %s" % (start, BOUND, p.seen))
        assert line is not None, "ended (%s) before a line %r: %s" % (p.wait(), start, p.seen)
        p.seen.append(line)
        if line.startswith(start):
            return line


def _kill(p):
    """SIGKILL ``p`` alone (not its session), then wait until no process of its session is
    left; the processes that were there when it was killed."""
    there = session_processes(p.pid)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    wait_for(lambda: not session_processes(p.pid), "end of every process of the killed run "
             "(left: %s)" % session_processes(p.pid), poll=0.05)
    return there


def _stop_all(p):
    """After a test, whatever it found: no process of ``p``'s session is left running."""
    for pid, _ in session_processes(p.pid):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    if p.poll() is None:
        p.wait()


def _left_in(tmp):
    """What is left in the temporary folder ``tmp`` besides what driftfmu keeps there by
    design (its private folder's compiled libraries)."""
    return left_in(tmp)


# -- the helper ---------------------------------------------------------------------------------

def test_a_program_run_has_the_parent_death_signal():
    code = ("import ctypes; s = ctypes.c_int(-1); "
            "ctypes.CDLL(None).prctl(2, ctypes.byref(s), 0, 0, 0); print(s.value)")
    r = lifetime.run([sys.executable, "-c", code], capture_output=True, text=True,
                     timeout=BOUND)
    assert r.returncode == 0 and r.stdout.split() == [str(int(signal.SIGKILL))], r
    # a caller's own preexec_fn is kept
    r = lifetime.run([sys.executable, "-c", code], capture_output=True, text=True,
                     timeout=BOUND, preexec_fn=lambda: None)
    assert r.stdout.split() == ["0"], r


def test_a_program_run_in_a_work_folder_writes_its_temporary_files_there(tmp_path):
    """A compiler ended by the signal cannot remove its temporary files: run with ``work``,
    they are in the work folder (removed with it), not in the temporary folder."""
    work = tmp_path / "work"
    work.mkdir()
    r = lifetime.run(["sh", "-c", 'touch "$TMPDIR/cc1.s"; echo "$KEPT"'], work=work,
                     env=dict(os.environ, KEPT="kept"), capture_output=True, text=True,
                     timeout=BOUND)
    assert r.stdout.strip() == "kept" and os.listdir(work) == ["cc1.s"]


#: Each place that compiles, with a compiler that says where its temporary files would go
#: (and then fails: each place has its way on without it).
_COMPILES = textwrap.dedent("""
    import sys, tempfile
    from pathlib import Path
    from driftfmu.simulations import fastcosim, kernel
    from driftfmu.fmu_src import builder, native_build
    fastcosim.loop_library()
    kernel.library()
    sources = Path(tempfile.mkdtemp(dir=sys.argv[1]))
    (sources / "a.c").write_text("int a;")
    try:
        native_build.compile_library("x86_64-linux", sources, ["a.c"], sources / "out" / "a.so")
    except native_build.NativeBuildError:
        pass
    work = Path(tempfile.mkdtemp(dir=sys.argv[1]))
    builder._make_loader(work, lambda line: None)
    print(sources / "out", work)
""")


def test_every_compile_keeps_the_compilers_temporary_files_in_its_work_folder(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    record = tmp_path / "tmpdirs"
    cc = tmp_path / "cc"
    cc.write_text('#!/bin/sh\n[ "$1" = "--version" ] && { echo cc 1; exit 0; }\n'
                  'echo "$TMPDIR" >> %s\nexit 1\n' % record)
    cc.chmod(0o755)
    r = subprocess.run([sys.executable, "-c", _COMPILES, str(tmp_path)], capture_output=True,
                       text=True, timeout=BOUND,
                       env=dict(os.environ, TMPDIR=str(tmp), CC=str(cc), PYTHONPATH=str(ROOT),
                                DRIFTFMU_KERNEL="c"))
    assert r.returncode == 0, r.stderr
    seen = record.read_text().split()
    # the loop, the kernel (three sets of flags), the native library, the loader shim
    assert len(seen) == 6, seen
    private = str(tmp / ("driftfmu-%d" % os.geteuid()))
    assert [d.startswith(private + "/driftfmu_loop_") for d in seen[:1]] == [True], seen
    assert all(d.startswith(private + "/driftfmu_kernel_") for d in seen[1:4]), seen
    assert seen[4:] == r.stdout.split(), (seen, r.stdout)
    assert str(tmp) not in seen


def test_a_program_run_ends_with_the_process_that_ran_it(tmp_path):
    script = ("from driftfmu.simulations import lifetime\n"
              "lifetime.run(['sleep', '3600'])\n")
    p = _start([], tmp_path, python=["-c", script])
    try:
        wait_for(lambda: any(n == "sleep" for _, n in session_processes(p.pid)),
                 "the program at work", p)
        there = _kill(p)
        assert "sleep" in [n for _, n in there], there
    finally:
        _stop_all(p)


#: A process that forks a child which calls ``lifetime.end_with_parent(owner)`` for ``owner``
#: (argv[1]: "parent", "grandparent" or "another") and prints "alive" if it still lives; the
#: process prints how the child ended.
_OWNER = textwrap.dedent("""
    import os, sys
    from driftfmu.simulations import lifetime
    which = sys.argv[1]
    owner = {"parent": os.getpid(), "grandparent": os.getppid(),
             "another": os.getppid() + 1000000}[which]
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(r)
        lifetime.end_with_parent(owner)
        os.write(w, b"alive")
        os._exit(0)
    os.close(w)
    said = os.read(r, 100)
    _, status = os.waitpid(pid, 0)
    print(said.decode() or "-", os.WIFSIGNALED(status) and os.WTERMSIG(status))
""")


@pytest.mark.parametrize("owner, alive", [("parent", True), ("grandparent", True),
                                          ("another", False)])
def test_a_worker_started_for_a_process_that_is_gone_ends_at_once(owner, alive):
    """The parent can die before the new process has asked for the signal: the process that
    asked for it (its parent, or its grandparent through a fork server) must still be there."""
    r = subprocess.run([sys.executable, "-c", _OWNER, owner], capture_output=True, text=True,
                       timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == (["alive", "False"] if alive
                                else ["-", str(int(signal.SIGKILL))]), r.stdout


#: A process that forks a child which calls ``lifetime.end_with_parent(owner)`` (argv[1]:
#: "parent" or "grandparent") and prints the child's parent-death signal (PR_GET_PDEATHSIG)
#: and whether a thread of the child watches the owner.
_SIGNAL = textwrap.dedent("""
    import ctypes, os, sys, threading
    from driftfmu.simulations import lifetime
    owner = {"parent": os.getpid(), "grandparent": os.getppid()}[sys.argv[1]]
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(r)
        lifetime.end_with_parent(owner)
        signum = ctypes.c_int(-1)
        lifetime._prctl()(2, ctypes.addressof(signum), 0, 0, 0)
        watch = any(t.name == "driftfmu-owner-watch" for t in threading.enumerate())
        os.write(w, b"%d %s" % (signum.value, str(watch).encode()))
        os._exit(0)
    os.close(w)
    said = os.read(r, 100)
    os.waitpid(pid, 0)
    print(said.decode() or "-")
""")


@pytest.mark.parametrize("owner, watch", [("parent", False), ("grandparent", True)])
def test_a_worker_gets_the_parent_death_signal_and_watches_only_an_owner_not_its_parent(
        owner, watch):
    """The parent-death signal is SIGKILL in every worker; a thread watches the owner only
    where the owner is not the parent (a fork server's worker), whom the signal does not
    follow."""
    r = subprocess.run([sys.executable, "-c", _SIGNAL, owner], capture_output=True, text=True,
                       timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(int(signal.SIGKILL)), str(watch)], r.stdout


_PREEXEC = textwrap.dedent("""
    import os
    from driftfmu.simulations import lifetime
    child = lifetime.preexec()
    statuses = []
    for depth in (1, 2):  # run by this process (its parent), or by a process it started
        pid = os.fork()
        if pid == 0:
            if depth == 2 and os.fork() != 0:
                os._exit(os.waitstatus_to_exitcode(os.wait()[1]) & 0xff)
            child()
            os._exit(7)
        statuses.append(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
    print(*statuses)
""")


def test_a_program_whose_parent_is_another_than_the_one_that_ran_it_ends_at_once():
    r = subprocess.run([sys.executable, "-c", _PREEXEC], capture_output=True, text=True,
                       timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr
    # the parent it expects: it runs (7); another: it ends by SIGKILL (-9, as 247 of a byte)
    assert r.stdout.split() == ["7", str(-signal.SIGKILL & 0xff)], r.stdout


def test_every_process_the_package_starts_goes_through_the_helper():
    """No module of the package starts a program or a worker process other than through
    lifetime.run or batch.process_pool (whose workers call lifetime.end_with_parent)."""
    import ast
    starts = {("subprocess", n) for n in ("run", "Popen", "call", "check_call",
                                          "check_output", "getoutput", "getstatusoutput")}
    starts |= {("os", n) for n in ("fork", "forkpty", "system", "popen", "posix_spawn",
                                   "posix_spawnp", "spawnv", "spawnl", "spawnvp", "spawnlp",
                                   "execv", "execvp", "execl", "execlp")}
    starts |= {("multiprocessing", n) for n in ("Process", "Pool")}
    found = []
    for folder in ("driftfmu", "simulations", "fmu_src", "models"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            tree = ast.parse(path.read_text(), str(path))
            for node in ast.walk(tree):
                if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                        and isinstance(node.func.value, ast.Name) \
                        and (node.func.value.id, node.func.attr) in starts:
                    found.append("%s:%d %s.%s" % (path.relative_to(ROOT), node.lineno,
                                                  node.func.value.id, node.func.attr))
                if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                        node.func.id in ("ProcessPoolExecutor", "Popen", "Process", "Pool"):
                    found.append("%s:%d %s" % (path.relative_to(ROOT), node.lineno,
                                               node.func.id))
    assert found == ["simulations/lifetime.py:%d subprocess.run" % _line_of(
        "return subprocess.run(args, **kwargs)")], found


def _line_of(text):
    lines = (ROOT / "simulations" / "lifetime.py").read_text().splitlines()
    return next(i for i, line in enumerate(lines, start=1) if line.strip() == text)


#: A pool of two workers whose tasks run for ever; each task says on standard error that it
#: started.  With argv[1] == "thread" a thread runs while the pool starts, so its workers come
#: from multiprocessing's fork server (batch.mp_context), not from a fork of this process.
_POOL = textwrap.dedent("""
    import os, sys, threading, time
    from driftfmu.simulations import batch

    def forever(i):
        import ctypes
        from driftfmu.simulations import lifetime
        signum = ctypes.c_int(-1)  # the parent-death signal (PR_GET_PDEATHSIG) ...
        lifetime._prctl()(2, ctypes.addressof(signum), 0, 0, 0)
        watch = any(t.name == "driftfmu-owner-watch" for t in threading.enumerate())
        sys.stderr.write("started %d signal %d watch %s\\n" % (os.getpid(), signum.value, watch))
        sys.stderr.flush()
        while True:
            time.sleep(1)

    if __name__ == "__main__":
        if sys.argv[1] == "thread":
            threading.Thread(target=time.sleep, args=(3600,), daemon=True).start()
        sys.stderr.write("method %s\\n" % batch.mp_context().get_start_method())
        sys.stderr.flush()
        with batch.process_pool(2) as pool:
            futures = [pool.submit(forever, i) for i in range(2)]
            for f in futures:
                f.result()
""")


@pytest.mark.parametrize("threads, method", [("none", "fork"), ("thread", "forkserver")])
def test_the_workers_of_a_pool_end_with_the_process_that_made_it(threads, method, tmp_path):
    import tempfile
    script = tmp_path / "pool_forever.py"  # a file: a fork server's worker imports it
    script.write_text(_POOL)
    # a short TMPDIR: the fork server's socket is made there (at most 108 bytes of path)
    tmp = Path(tempfile.mkdtemp(prefix="lt-", dir=tempfile.gettempdir()))
    try:
        p = _start([threads], tmp_path, {"TMPDIR": str(tmp)}, python=[str(script)])
        try:
            assert _wait_for_line(p, "method ") == "method " + method
            for _ in range(2):  # ... SIGKILL in each worker, and a fork server's worker
                # watches the process that asked for it (the server is its parent)
                started = _wait_for_line(p, "started ").split()
                assert started[2:] == ["signal", str(int(signal.SIGKILL)), "watch",
                                       str(method == "forkserver")], started
            there = _kill(p)
            # the process and its two workers (and the fork server and multiprocessing's
            # resource tracker, which end once no worker holds their pipes)
            assert len(there) == (3 if method == "fork" else 5), there
        finally:
            _stop_all(p)
        # what the fork server left (its socket's folder) is a work folder: the next run
        # that makes one removes it
        r = subprocess.run([sys.executable, "-c", "from driftfmu.simulations import folders\n"
                            "with folders.temporary('driftfmu_x_'): pass"],
                           env=dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT)),
                           capture_output=True, text=True, timeout=BOUND)
        assert r.returncode == 0, r.stderr
        assert os.listdir(tmp) == [], (os.listdir(tmp), [
            os.listdir(os.path.join(tmp, d)) for d in os.listdir(tmp)])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


# -- every command that starts workers or programs ------------------------------------------------

def _commands(fmu_dir):
    """(the command, its environment, the next run: the same command, small) of each command
    that starts worker processes.  Each runs many tasks (the first progress line comes after
    the first), so it is still at work when the test kills it."""
    fmus = ["--fmu-dir", str(fmu_dir)]
    return {
        "experiment adxl203": (
            ["experiment", "adxl203", "--freqs", "100", "--sets", "1000", "--n", "20000",
             "--workers", "2", "--out", "res"] + fmus, {},
            ["experiment", "adxl203", "--freqs", "100", "--sets", "3", "--held-out", "1",
             "--n", "2000", "--workers", "2", "--out", "res"] + fmus),
        "montecarlo gaussian --engine fmu": (
            ["montecarlo", "gaussian", "--engine", "fmu", "--workers", "2", "--runs", "15",
             "--n", "4000", "--out", "res"] + fmus, {},
            ["montecarlo", "gaussian", "--engine", "fmu", "--workers", "2", "--runs", "2",
             "--n", "50", "--out", "res"] + fmus),
        "experiment dual-axis": (
            ["experiment", "dual-axis", "--points", "9", "--runs", "4", "--n", "2000",
             "--workers", "2", "--out", "res"] + fmus, {},
            ["experiment", "dual-axis", "--points", "2", "--runs", "1", "--n", "40",
             "--workers", "2", "--out", "res"] + fmus),
        # without the compiled kernel the batch engine runs its chunks in worker processes
        "sweep (NumPy batch engine)": (
            ["sweep", "--runs", "20000", "--n", "2000", "--workers", "2", "--out", "res"],
            {"DRIFTFMU_KERNEL": "numpy"},
            ["sweep", "--runs", "2", "--n", "10", "--workers", "2", "--out", "res"]),
    }


@pytest.mark.integration
@pytest.mark.parametrize("command", ["experiment adxl203", "montecarlo gaussian --engine fmu",
                                     "experiment dual-axis", "sweep (NumPy batch engine)"])
def test_a_killed_command_leaves_no_worker_and_the_next_run_no_folder(command, python_fmus,
                                                                      tmp_path):
    argv, env, again = _commands(python_fmus["Excitation"].parent)[command]
    p = _start(argv, tmp_path, env)
    try:
        _wait_for_line(p, "driftfmu: progress: ")  # the first work the workers did
        there = _kill(p)
    finally:
        _stop_all(p)
    assert len([n for _, n in there if n.startswith("python")]) >= 3, there  # and 2 workers
    # the next run sweeps what the killed one left (its workers' FMU folders, its staging)
    r = subprocess.run([sys.executable, "-m", "driftfmu"] + again, cwd=tmp_path,
                       env=dict(os.environ, TMPDIR=str(tmp_path / "tmp"), PYTHONPATH=str(ROOT),
                                **env), capture_output=True, text=True, timeout=BOUND)
    assert r.returncode == 0, r.stderr
    assert _left_in(tmp_path / "tmp") == []
    assert sorted(f.name for f in tmp_path.iterdir()) == ["res", "tmp"]
    assert not [f for f in (tmp_path / "res").iterdir() if f.name.startswith(".driftfmu")]


#: A compiler that says its version and otherwise compiles for an hour (``exec``: the program
#: that driftfmu started is the one that waits).
_SLOW_CC = """#!/bin/sh
if [ "$1" = "--version" ]; then echo "slow-cc 1.0"; exit 0; fi
exec sleep 3600
"""


@pytest.mark.integration
def test_a_killed_native_build_leaves_no_compiler_and_the_next_build_no_folder(tmp_path,
                                                                                python_fmus):
    cc = tmp_path / "slow-cc"
    cc.write_text(_SLOW_CC)
    cc.chmod(0o755)
    env = {"CC": str(cc)}
    p = _start(["build", "--native", "--no-cache", "--out", "fmus"], tmp_path, env)
    try:  # the event: the compiler's own program at work (not the script before its exec)
        wait_for(lambda: "sleep" in [n for _, n in session_processes(p.pid)],
                 "the compiler at work", p)
        there = _kill(p)
    finally:
        _stop_all(p)
    assert "sleep" in [n for _, n in there], there
    r = subprocess.run([sys.executable, "-m", "driftfmu", "build", "--out", "fmus"], cwd=tmp_path,
                       env=dict(os.environ, TMPDIR=str(tmp_path / "tmp"), PYTHONPATH=str(ROOT)),
                       capture_output=True, text=True, timeout=BOUND)
    assert r.returncode == 0, r.stderr
    assert _left_in(tmp_path / "tmp") == []
    from driftfmu.fmu_src import container
    assert sorted(f.name for f in (tmp_path / "fmus").iterdir()) == sorted(
        [p.name for p in python_fmus.values()] + [container.FILENAME])


#: The doctor's trial host (a Python that instantiates the FMU) made to take an hour.
_DOCTOR = textwrap.dedent("""
    import sys
    from driftfmu.simulations import doctor
    doctor._run_instantiate("import time; time.sleep(3600)", sys.argv[1])
""")


def test_a_killed_doctor_leaves_no_trial_host(tmp_path):
    p = _start([str(tmp_path / "some.fmu")], tmp_path, python=["-c", _DOCTOR])
    try:
        wait_for(lambda: len(session_processes(p.pid)) == 2, "the trial host at work", p)
        _kill(p)
    finally:
        _stop_all(p)
    # the next run (any that makes a work folder) removes the trial's
    r = subprocess.run([sys.executable, "-c", _DOCTOR.replace("time.sleep(3600)", "0"),
                        str(tmp_path / "some.fmu")], env=dict(
                            os.environ, TMPDIR=str(tmp_path / "tmp"), PYTHONPATH=str(ROOT)),
                       capture_output=True, text=True, timeout=BOUND)
    assert r.returncode == 0, r.stderr
    assert _left_in(tmp_path / "tmp") == []
