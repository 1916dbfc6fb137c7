"""Wall time of the default ``driftfmu sweep`` command, files and figures included, and where it
goes; the same command with the NumPy engine (``DRIFTFMU_KERNEL=numpy``) is the baseline of
the same run.

The default grid is 6 x 5 points x 1000 runs x 1000 samples (3e7 sample-runs) on all local
cores.  Each repeat runs, as new processes, alternating so that drifts of a shared machine hit
all of them:

- ``python -c "import driftfmu.simulations.cli, driftfmu.simulations.sweep"``: the start-up
  (interpreter, NumPy, the command's modules);
- ``driftfmu sweep --out DIR`` with the compiled kernel, and with NumPy: the whole command.
  Its last lines say how long the runs took; the rest of the command's wall time is start-up,
  the worker pool, the files and the figures.

Each figure is the median of ``--repeats``.  The kernel is compiled (or found) once before
the first timed run.  Not a pytest test:

    python benchmarks/bench_sweep.py [--repeats 5]
"""
import argparse
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time

from machine import cpu


def timed(command, env):
    """(wall seconds, stdout) of ``command`` as a new process."""
    t0 = time.perf_counter()
    done = subprocess.run(command, env=env, check=True, capture_output=True, text=True)
    return time.perf_counter() - t0, done.stdout


def runs_seconds(stdout):
    """The seconds of the runs, from the command's summary line."""
    m = re.search(r"sample-runs in ([0-9.]+) s", stdout)
    return float(m.group(1)) if m else float("nan")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    from driftfmu.simulations import kernel
    if kernel.library() is None:
        sys.exit("bench_sweep: no compiled kernel here (no C compiler, or DRIFTFMU_KERNEL=numpy)")
    env = dict(os.environ)
    env.pop("DRIFTFMU_KERNEL", None)
    numpy_env = dict(env, DRIFTFMU_KERNEL="numpy")
    load = os.getloadavg()
    figures = {"start-up": [], "kernel": [], "kernel runs": [], "numpy": [], "numpy runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        sweep = [sys.executable, "-m", "driftfmu", "sweep", "--out", os.path.join(tmp, "s")]
        start = [sys.executable, "-c", "import driftfmu.simulations.cli, driftfmu.simulations.sweep"]
        for _ in range(args.repeats):
            figures["start-up"].append(timed(start, env)[0])
            wall, out = timed(sweep, env)
            figures["kernel"].append(wall)
            figures["kernel runs"].append(runs_seconds(out))
            wall, out = timed(sweep, numpy_env)
            figures["numpy"].append(wall)
            figures["numpy runs"].append(runs_seconds(out))
    med = {k: statistics.median(v) for k, v in figures.items()}
    print("machine: %s, %s, %d cores, Python %s" % (platform.machine(), cpu(),
                                                    os.cpu_count() or 0,
                                                    platform.python_version()))
    print("load average before: %s, after: %s" % (" ".join("%.2f" % v for v in load),
                                                  " ".join("%.2f" % v for v in os.getloadavg())))
    print("default `driftfmu sweep` (6 x 5 grid, 1000 runs x 1000 samples, files and figures), "
          "median of %d:" % args.repeats)
    for engine in ("kernel", "numpy"):
        rest = med[engine] - med[engine + " runs"]
        print("  %-22s %6.2f s wall: runs %.2f s, start-up %.2f s, the rest (pool, files, "
              "figures) %.2f s   (runs: %s)"
              % ("compiled kernel" if engine == "kernel" else "NumPy engine (baseline)",
                 med[engine], med[engine + " runs"], med["start-up"],
                 rest - med["start-up"], " ".join("%.2f" % v for v in figures[engine])))
    print("kernel / NumPy command: %.2f x faster; goal: the command in <= 1 s wall (%s here)"
          % (med["numpy"] / med["kernel"], "met" if med["kernel"] <= 1.0 else "NOT met"))


if __name__ == "__main__":
    main()
