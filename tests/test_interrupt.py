"""No command waits for ever on its workers after an interrupt (issue 19).

The hang seen: SIGTERM while worker processes were sending large results and many tasks were
queued; the pool's manager thread then read half a message for ever (this process held the
pipe's write end) or its feeder thread wrote a task nobody read, and the interpreter's exit
joined them.  ``batch.stop_pool`` closes those pipe ends; ``cli.exit_watchdog`` ends the process
if anything else still holds it.
"""
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from waiting import BOUND

ROOT = Path(__file__).resolve().parent.parent

#: Many queued tasks, each sending back 200 MB: a stop catches a worker in the middle of
#: sending (the case that hung about one time in three before the fix).
SCRIPT = textwrap.dedent("""
    import signal, sys
    import numpy as np
    from driftfmu.simulations import batch

    def work(a):
        return np.ones(25_000_000)

    def stop(signum, frame):
        raise KeyboardInterrupt

    if __name__ == "__main__":
        signal.signal(signal.SIGTERM, stop)
        big = np.ones(200_000)  # 1.6 MB per queued task: more than a pipe holds
        try:
            with batch.process_pool(2) as pool:
                futs = [pool.submit(work, big) for _ in range(300)]
                print("submitted", flush=True)
                for f in futs:
                    f.result()
        except KeyboardInterrupt:
            sys.exit(130)
""")


def _stop_after(script, delay, env=None):
    """Run ``script``; SIGTERM it ``delay`` s after it printed its first line; return its exit
    status, or None when it still ran :data:`waiting.BOUND` seconds after the signal (its 300
    tasks of 200 MB each take far longer)."""
    p = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                         start_new_session=True,
                         env=dict(os.environ, PYTHONPATH=str(ROOT), **(env or {})))
    try:
        p.stdout.readline()
        time.sleep(delay)  # where in the run the signal lands, not a deadline
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(timeout=BOUND)
        except subprocess.TimeoutExpired:
            return None
        return p.returncode
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


@pytest.mark.parametrize("delay", [pytest.param(0.5, marks=pytest.mark.qualification), 1.5,
                                   pytest.param(2.5, marks=pytest.mark.qualification)])
def test_a_stop_with_many_queued_tasks_and_large_results_ends_the_process(delay):
    rc = _stop_after(SCRIPT, delay)
    assert rc == 130, "the process still ran %g s after SIGTERM" % BOUND if rc is None else rc


def test_the_exit_watchdog_ends_a_process_that_something_holds():
    # a non-daemon thread that never ends would keep the interpreter's exit waiting for ever
    script = textwrap.dedent("""
        import threading, time, sys
        from driftfmu.simulations import cli
        print("started", flush=True)
        threading.Thread(target=lambda: time.sleep(3600)).start()
        cli.exit_watchdog(130, seconds=0.5)
        sys.exit(130)
    """)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert p.returncode == 130, p.stderr


def test_main_as_the_program_arms_the_watchdog_after_an_interrupt(monkeypatch):
    from driftfmu.simulations import cli
    armed = []
    monkeypatch.setattr(cli, "exit_watchdog", lambda status: armed.append(status))
    monkeypatch.setattr(cli, "_main", lambda argv, previous: cli.EXIT_INTERRUPTED)
    assert cli.main() == 130 and armed == [130]
    monkeypatch.setattr(cli, "_main", lambda argv, previous: 0)
    assert cli.main() == 0 and armed == [130]
    monkeypatch.setattr(cli, "_main", lambda argv, previous: cli.EXIT_INTERRUPTED)
    assert cli.main(["sweep"]) == 130 and armed == [130]  # called by a test: not armed


@pytest.mark.parametrize("interrupted", [False, True])
def test_the_command_ends_as_the_interpreter_would_without_its_teardown(interrupted):
    # cli.end_process: os._exit after what the interpreter's exit does that a command relies
    # on: non-daemon threads joined (not after an interrupt), exit handlers, streams flushed
    script = textwrap.dedent("""
        import atexit, sys, threading, time
        from driftfmu.simulations import cli
        def late():
            time.sleep(%s)
            sys.stdout.write("thread ended\\n")
        threading.Thread(target=late).start()
        atexit.register(lambda: sys.stdout.write("exit handler ran\\n"))
        sys.stdout.write("buffered, no newline; ")
        cli.end_process(%d, join_threads=%s)
    """ % ("3600" if interrupted else "0.3", 130 if interrupted else 3, not interrupted))
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       timeout=BOUND, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert p.returncode == (130 if interrupted else 3), p.stderr
    want = "buffered, no newline; %sexit handler ran\n" % ("" if interrupted else
                                                           "thread ended\n")
    assert p.stdout == want


def test_a_profiled_command_still_reports_after_it_ends(tmp_path):
    # python -m cProfile -m driftfmu ...: the profiler prints when the program returns, which
    # os._exit would skip; with a profiler (or a tracer) the command exits through sys.exit
    p = subprocess.run([sys.executable, "-m", "cProfile", "-m", "driftfmu", "sweep", "--runs",
                        "2", "--n", "10", "--a2", "0.01", "--R", "1e-4", "--out", "s"],
                       capture_output=True, text=True, timeout=BOUND, cwd=tmp_path,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert p.returncode == 0, p.stderr
    assert "wrote" in p.stdout and "function calls" in p.stdout
