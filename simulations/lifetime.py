"""Internal (not a stable API; use the functions of driftfmu instead).

Processes that end when the process that started them is gone.

driftfmu starts two kinds of processes: the worker processes of its pools
(:func:`driftfmu.simulations.batch.process_pool`: the experiments' sets and runs, the FMU
engine's runs, the batch engine's chunks when the compiled kernel is missing, a figure drawn
beside another) and the programs it runs (C compilers, the doctor's trial host).  Each of them
ends when the process that started it is gone, however that one ended (SIGKILL, the kernel's
out-of-memory killer), and the locks it held go with it, so that the next run removes the work
folders left behind (:mod:`driftfmu.simulations.folders`):

- **Linux**: the parent-death signal, ``prctl(PR_SET_PDEATHSIG, SIGKILL)``, set in the new
  process before it does any work (a worker: first thing in its initialiser; a program: between
  ``fork`` and ``exec``, kept across ``exec``).  The parent may have died before that: the new
  process then checks that it was started by the process it expects (its parent, or for a
  worker made by multiprocessing's fork server, its parent's parent) and ends at once if not.
- **A worker made by multiprocessing's fork server** (a pool started while this process runs
  threads) has the fork server as its parent, and the fork server lives as long as one of its
  workers holds its pipe: such a worker watches the process that asked for it from a thread
  (``pidfd_open``: woken when that process ends) and ends.
- **Other POSIX systems** (macOS): a worker watches its parent from a thread (:data:`WATCH`
  seconds apart) and ends; a program driftfmu runs (a compiler) ends with its one task.
- **Windows**: a worker watches its parent's process handle (multiprocessing's parent
  sentinel); a program ends with its one task.

A program that a program started (the assembler a compiler runs) is that program's: it ends
with its task.
"""
import os
import signal
import subprocess
import sys
import threading

#: ``prctl`` option: the signal this process gets when the thread that created it ends.
PR_SET_PDEATHSIG = 1
#: Seconds between two looks at the parent where no parent-death signal exists.
WATCH = 0.5

_PRCTL = []


def _prctl():
    """libc's ``prctl`` (Linux), None elsewhere; looked up once."""
    if not _PRCTL:
        function = None
        if sys.platform.startswith("linux"):
            import ctypes
            try:
                function = ctypes.CDLL(None, use_errno=True).prctl
                function.argtypes = [ctypes.c_int] + [ctypes.c_ulong] * 4
                function.restype = ctypes.c_int
            except (OSError, AttributeError):
                function = None
        _PRCTL.append(function)
    return _PRCTL[0]


def parent_of(pid):
    """The parent process id of ``pid`` (from /proc), None when unknown or gone."""
    try:
        with open("/proc/%d/stat" % pid, "rb") as fh:
            stat = fh.read()
        # pid (comm) state ppid ...: comm may hold spaces and parentheses
        return int(stat[stat.rindex(b")") + 2:].split()[1])
    except (OSError, ValueError, IndexError):
        return None


def started_by(owner):
    """True when ``owner`` (a process id) started this process: it is its parent, or its
    parent's parent (a worker forked by multiprocessing's fork server, which ``owner``
    started)."""
    parent = os.getppid()
    return parent == owner or parent_of(parent) == owner


def _end():
    os.kill(os.getpid(), signal.SIGKILL)


def end_with_parent(owner=None):
    """In a new process: end it (SIGKILL) when the process that started it is gone.

    ``owner`` is the process id of the process that asked for this one: its parent, or its
    parent's parent for a worker that multiprocessing's fork server made for it (default: the
    parent, as it is now).  When the owner is no longer there (it died before this was set),
    this process ends at once.

    The parent-death signal (Linux) follows the parent; an owner that is not the parent (the
    fork server's workers: the server itself lives as long as one of them holds its pipe) is
    watched from a thread, which ends this process when the owner ends (``pidfd_open``, or a
    look every :data:`WATCH` seconds); so is the parent where there is no such signal."""
    parent = os.getppid()
    owner = parent if owner is None else owner
    if parent != owner and parent_of(parent) not in (owner, None):  # gone already
        _end()
    prctl = _prctl()
    if prctl is not None and prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0 \
            and parent == owner:
        if os.getppid() != owner:  # gone before the signal was set: nobody sends it
            _end()
        return
    if os.name == "nt":
        _watch_sentinel()
        return
    _watch(owner)


def _watch(owner):
    """End this process from a thread when ``owner`` (its parent, or its parent's parent) is
    gone."""
    if os.getppid() == owner:
        def alive():
            return os.getppid() == owner
    elif os.path.exists("/proc/self/stat"):
        def alive():  # the fork server's parent: it is reparented when the owner ends
            return parent_of(os.getppid()) == owner
    else:
        def alive():
            try:
                os.kill(owner, 0)
            except ProcessLookupError:
                return False
            except OSError:
                pass
            return True
    pidfd = None
    try:
        pidfd = os.pidfd_open(owner)
    except (AttributeError, OSError):  # before Linux 5.3, or not Linux: look now and then
        pidfd = None
    if not alive():
        _end()

    def watch():
        if pidfd is not None:
            import select
            select.select([pidfd], [], [])  # readable once the owner has ended
        else:
            import time
            while alive():
                time.sleep(WATCH)
        _end()
    threading.Thread(target=watch, name="driftfmu-owner-watch", daemon=True).start()


def _watch_sentinel():
    """Windows: end this worker when its parent's process handle says it ended."""
    import multiprocessing
    parent = multiprocessing.parent_process()
    if parent is None or getattr(parent, "sentinel", None) is None:
        return

    def watch():
        from multiprocessing.connection import wait
        wait([parent.sentinel])
        os._exit(1)
    threading.Thread(target=watch, name="driftfmu-owner-watch", daemon=True).start()


def preexec():
    """A ``preexec_fn`` for :mod:`subprocess` that gives the program the parent-death signal
    (Linux; None elsewhere): it then ends when this process is gone, even while it runs."""
    prctl = _prctl()
    if prctl is None:
        return None
    parent = os.getpid()

    def child():  # between fork and exec: nothing but two system calls
        prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if os.getppid() != parent:
            os.kill(os.getpid(), signal.SIGKILL)
    return child


def run(args, work=None, **kwargs):
    """``subprocess.run(args, **kwargs)`` of a program that ends when this process is gone
    (:func:`preexec`).  ``work``: a work folder for the program's own temporary files
    (``TMPDIR``; a C compiler's ``cc*.s``, ``cc*.o``): a program ended by the signal cannot
    remove them, and there they go with the folder (its owner removes it, or the next run's
    sweep), not into the temporary folder for good."""
    kwargs.setdefault("preexec_fn", preexec())
    if work is not None:
        kwargs["env"] = dict(kwargs.get("env") or os.environ, TMPDIR=str(work))
    return subprocess.run(args, **kwargs)
