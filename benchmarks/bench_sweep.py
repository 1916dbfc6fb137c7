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
import re
import statistics
import subprocess
import sys
import tempfile
import time

import figures


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
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    from driftfmu.simulations import kernel
    if kernel.library() is None:
        sys.exit("bench_sweep: no compiled kernel here (no C compiler, or DRIFTFMU_KERNEL=numpy)")
    env = dict(os.environ)
    env.pop("DRIFTFMU_KERNEL", None)
    numpy_env = dict(env, DRIFTFMU_KERNEL="numpy")
    load = os.getloadavg()
    measured = {"start-up": [], "kernel": [], "kernel runs": [], "numpy": [], "numpy runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        sweep = [sys.executable, "-m", "driftfmu", "sweep", "--out", os.path.join(tmp, "s")]
        start = [sys.executable, "-c", "import driftfmu.simulations.cli, driftfmu.simulations.sweep"]
        for _ in range(args.repeats):
            measured["start-up"].append(timed(start, env)[0])
            wall, out = timed(sweep, env)
            measured["kernel"].append(wall)
            measured["kernel runs"].append(runs_seconds(out))
            wall, out = timed(sweep, numpy_env)
            measured["numpy"].append(wall)
            measured["numpy runs"].append(runs_seconds(out))
    med = {k: statistics.median(v) for k, v in measured.items()}
    print("machine: %s" % figures.machine())
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
                 rest - med["start-up"], " ".join("%.2f" % v for v in measured[engine])))
    print("kernel / NumPy command: %.2f x faster; goal: the command in <= 1 s wall (%s here)"
          % (med["numpy"] / med["kernel"], "met" if med["kernel"] <= 1.0 else "NOT met"))
    figures.record(__file__, argv, [
        figures.row("`driftfmu sweep`, the compiled kernel: the whole command", med["kernel"],
                    "s", "the same command with the NumPy engine", med["kernel"] / med["numpy"],
                    "<= 1 s", med["kernel"] <= 1.0),
        figures.row("of it, the runs (3e7 sample-runs)", med["kernel runs"], "s",
                    "the NumPy engine's runs", med["kernel runs"] / med["numpy runs"]),
        figures.row("of it, the start-up (interpreter, NumPy, the command's modules)",
                    med["start-up"], "s"),
        figures.row("the same command with the NumPy engine", med["numpy"], "s"),
    ], load[0], "Median of %d." % args.repeats)


if __name__ == "__main__":
    main()
