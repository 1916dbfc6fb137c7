"""The time each long command announces before it starts (``driftfmu: note: ... about 4 min
(estimates)``, simulations/budget.py) against the time the same command then takes, in the
same run: the goal is a ratio between 1/2 and 2.

For each command, just before it runs, the estimate is computed as the command computes it
(the same function of simulations/budget.py, with this moment's load average); the command then
runs as a new process, and its wall time and CPU time (its own and its workers') are measured.
Printed per command: the estimate, the wall time, their ratio, and the CPU seconds (which grow
much less with the machine's load than the wall time: what the estimate's constants are
calibrated from).  Run it from the project root after ``driftfmu build --native``; not a pytest
test:

    python benchmarks/bench_estimates.py [--only NAME ...] [--fmu-dir build/fmus] [--no-record]
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

from driftfmu.simulations import budget

import figures


def commands(fmu_dir):
    """(name, argv of ``driftfmu``, the estimate as the command computes it) of each command
    that announces its time."""
    fmus = ["--fmu-dir", fmu_dir]
    return [
        ("run gaussian", ["run", "gaussian", "--n", "20000"] + fmus,
         lambda: budget.check_run("gaussian", 20000, None, announce=False)),
        ("run gaussian native", ["run", "gaussian", "--n", "100000", "--backend", "native"] + fmus,
         lambda: budget.check_run("gaussian", 100000, None, "native", announce=False)),
        ("montecarlo gaussian", ["montecarlo", "gaussian", "--runs", "4000", "--n", "2000"],
         lambda: budget.check_montecarlo("gaussian", 4000, 2000, None, None, announce=False)),
        ("montecarlo gaussian fmu", ["montecarlo", "gaussian", "--engine", "fmu", "--runs", "16",
                                     "--n", "5000"] + fmus,
         lambda: budget.check_montecarlo("gaussian", 16, 5000, None, None, announce=False,
                                         engine="fmu")),
        ("sweep", ["sweep", "--runs", "1000", "--n", "3000"],
         lambda: budget.check_sweep(30, 1000, 3000, None, None, announce=False)),
        ("experiment adxl203", ["experiment", "adxl203", "--sets", "6", "--held-out", "1",
                                "--n", "60000"] + fmus,
         lambda: budget.check_adxl203((100, 125, 150, 175, 200), 6, 60000, None, None,
                                      announce=False)),
        ("experiment adxl203 native", ["experiment", "adxl203", "--backend", "native"] + fmus,
         lambda: budget.check_adxl203((100, 125, 150, 175, 200), 30, 60000, None, None,
                                      "native", announce=False)),
        ("experiment dual-axis", ["experiment", "dual-axis"] + fmus,
         lambda: budget.check_dual_axis(9, 4, 4000, "fmu", None, None, announce=False)),
        ("experiment dual-axis native", ["experiment", "dual-axis", "--backend", "native"]
         + fmus, lambda: budget.check_dual_axis(9, 4, 4000, "fmu", None, None, "native",
                                                announce=False)),
        ("experiment dual-axis batch", ["experiment", "dual-axis", "--engine", "batch",
                                        "--runs", "2000"],
         lambda: budget.check_dual_axis(9, 2000, 4000, "batch", None, None, announce=False)),
    ]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", default=None, help="only the commands named so")
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    load_before = os.getloadavg()
    rows = []
    print("%-28s %9s %9s %7s %9s %6s  %s" % ("command", "estimate", "wall", "ratio", "CPU",
                                             "load", "within 1/2..2"))
    worst = 1.0
    with tempfile.TemporaryDirectory() as tmp:
        for name, command, estimate in commands(args.fmu_dir):
            if args.only and name not in args.only:
                continue
            load = os.getloadavg()[0]
            seconds = estimate()["seconds"]
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "driftfmu"] + command
                           + ["--out", os.path.join(tmp, name.replace(" ", "_"))],
                           check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            wall = time.perf_counter() - t0
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            ratio = seconds / wall
            worst = max(worst, ratio, 1 / ratio)
            print("%-28s %8.1fs %8.1fs %7.2f %8.1fs %6.2f  %s"
                  % (name, seconds, wall, ratio, cpu, load,
                     "yes" if 0.5 <= ratio <= 2 else "NO"), flush=True)
            rows.append(figures.row("`driftfmu %s`: the announced time, %.1f s at a load of "
                                    "%.1f, over the run's"
                                    % (" ".join(command[:command.index("--fmu-dir")]
                                                if "--fmu-dir" in command else command),
                                       seconds, load),
                                    round(ratio, 3), "×", "the wall time of the run, %.1f s "
                                    "(CPU %.1f s)" % (wall, cpu), None, "1/2 to 2",
                                    0.5 <= ratio <= 2))
    print("the worst ratio (estimate / wall, or its inverse): %.2f (goal: at most 2)" % worst)
    figures.record(__file__, argv, rows, load_before,
                   "Each estimate computed as its command computes it, just before the run, "
                   "at the load of that moment; the machine is shared, so the load changes "
                   "during a run.")
    return 0 if worst <= 2 else 1


if __name__ == "__main__":
    sys.exit(main())
