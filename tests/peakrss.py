"""The peak memory of a ``driftfmu`` command, measured in the process that runs it.

The child runs the command in-process and reports on its last line of standard error its
``VmHWM`` (Linux's high-water mark of the resident set, /proc/self/status): the peak of that
process alone.  (``getrusage(RUSAGE_SELF).ru_maxrss`` would not do in a child of pytest:
Linux carries the peak of the image a child was forked from over its ``exec``, so a child of a
200 MB pytest worker starts at 200 MB.)"""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

CHILD = """import sys
from driftfmu.simulations.cli import main


def hwm():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return -1


try:
    rc = main(sys.argv[1:])
except SystemExit as exc:
    rc = exc.code
sys.stdout.flush()
sys.stderr.write("peak rss %d\\n" % hwm())
sys.exit(rc)
"""


def run(argv, timeout=3600):
    """``(exit status, stdout, stderr without the report, peak RSS in bytes)`` of ``driftfmu
    argv`` run in a child process."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, "-c", CHILD] + [str(a) for a in argv],
                          capture_output=True, text=True, timeout=timeout, env=env)
    assert done.returncode >= 0, "killed by signal %d: %s" % (-done.returncode, done.stderr)
    *rest, last = done.stderr.strip().splitlines()
    assert last.startswith("peak rss "), done.stderr
    return done.returncode, done.stdout, "\n".join(rest), int(last.split()[-1])
