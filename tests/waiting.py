"""Waiting for events, never for the clock.

A test that needs a process to reach a point (a line printed, a file made, workers started, a
process gone) waits for that event with :data:`BOUND`, a bound generous enough that a machine
with a load of 15 on its two cores still sees the event: the bound only turns a hang into a
failure, it never measures speed.  Where a signal must arrive mid-run, the test gives the command
work that lasts far longer than :data:`BOUND` (hours), so that "stopped within the bound" can
only mean "stopped because of the signal".
"""
import time

#: Seconds any test waits for an event, or for a process to end, before it calls it a hang.
BOUND = 600.0


def wait_for(predicate, what, process=None, bound=BOUND, poll=0.02):
    """Return once ``predicate()`` is true; AssertionError naming ``what`` when ``process`` (a
    ``subprocess.Popen``) ends first or ``bound`` seconds pass."""
    deadline = time.monotonic() + bound
    while not predicate():
        if process is not None and process.poll() is not None:
            out, err = process.communicate()
            raise AssertionError("the process ended (status %s) before %s:\n%s%s"
                                 % (process.returncode, what, out or "", err or ""))
        if time.monotonic() > deadline:
            raise AssertionError("no %s within %g s" % (what, bound))
        time.sleep(poll)


def session_processes(session):
    """Live (not zombie) processes of the session ``session`` (the process id of a process
    started with ``start_new_session=True``): it and everything it started, by any path
    (forked, exec'd, started by a fork server), that did not start a session of its own.
    ``(pid, name)`` pairs, from /proc."""
    import os
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open("/proc/%s/stat" % entry, "rb") as fh:
                stat = fh.read()
        except OSError:
            continue
        name = stat[stat.index(b"(") + 1:stat.rindex(b")")].decode(errors="replace")
        fields = stat[stat.rindex(b")") + 2:].split()
        # state ppid pgrp session ...
        if int(fields[3]) == session and fields[0] != b"Z":
            found.append((int(entry), name))
    return found


def sigint_default():
    """``preexec_fn`` of a process a test will stop with Ctrl-C (SIGINT): the signal's default
    disposition, which Python turns into KeyboardInterrupt, whatever this process inherited (a
    test run under ``nohup ... &`` starts with SIGINT ignored, and its children would too)."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_DFL)
