"""Cost of one co-simulation step of the three driftfmu FMUs against three pass-through FMUs.

Both sets run through the same master loop (simulations.cosim.cosimulate: 3 doSteps, 2 values
copied along the connections, 8 outputs read per step); the baseline FMUs are built with stock
pythonfmu in this run.  A step's wall time is taken between the first and the last 1 % of the
steps (loading the FMUs excluded), the two sets alternating run by run; the medians are
compared.  On a shared machine single runs scatter widely, so the per-run ratios are printed
too.  (Instruction counts under callgrind were tried as a steadier measure, but they varied by
10 % between identical runs of the Python host, so they are not used.)

    python benchmarks/bench_step.py [--steps 5000] [--repeats 9]
"""
import argparse
import statistics
import tempfile
import time
from pathlib import Path

from pythonfmu import FmuBuilder

from driftfmu.simulations.cosim import cosimulate
from driftfmu.simulations.gaussian import CONNECTIONS, fmu_paths

import figures

HERE = Path(__file__).parent
RECORD = {"Excitation": ["x"], "Accelerometer": ["z"],
          "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}
BASELINE = {"Excitation": "PassSource", "Accelerometer": "PassOne", "DriftEstimator": "PassSix"}


def build_baseline(dest):
    """The three pass-through FMUs, by role, built with stock pythonfmu into ``dest``."""
    return {role: Path(FmuBuilder.build_FMU(HERE / "passthrough" / ("%s.py" % n), dest=dest))
            for role, n in BASELINE.items()}


def step_time(fmus, steps, Ts=1e-3):
    """(wall, CPU) time of one co-simulation step, loading and freeing the FMUs excluded: timed
    between the master's first and last progress calls (every 1 % of the steps)."""
    stamps = []
    cosimulate(fmus, CONNECTIONS, steps, Ts, record=RECORD,
               progress=lambda done: stamps.append((done, time.perf_counter(),
                                                    time.process_time())))
    (k0, t0, c0), (k1, t1, c1) = stamps[0], stamps[-1]
    return (t1 - t0) / (k1 - k0), (c1 - c0) / (k1 - k0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    ours = fmu_paths(args.fmu_dir)
    load = figures.load()
    with tempfile.TemporaryDirectory() as tmp:
        base = build_baseline(tmp)
        times = {"base": [], "ours": []}
        for _ in range(args.repeats):  # alternate, so that drifts of the machine hit both
            for who, fmus in (("base", base), ("ours", ours)):
                times[who].append(step_time(fmus, args.steps))
    b = statistics.median(w for w, _ in times["base"])
    o = statistics.median(w for w, _ in times["ours"])
    bc = statistics.median(c for _, c in times["base"])
    oc = statistics.median(c for _, c in times["ours"])
    print("machine: %s" % figures.machine())
    print("wall time per co-simulation step (median of %d runs of %d steps):"
          % (args.repeats, args.steps))
    print("  pass-through pythonfmu FMUs: %8.1f us (CPU %.1f us)" % (b * 1e6, bc * 1e6))
    print("  driftfmu FMUs:               %8.1f us (CPU %.1f us)" % (o * 1e6, oc * 1e6))
    print("  ratio driftfmu / pass-through: %.2f wall, %.2f CPU (goal <= 1.3); per-run ratios %s"
          % (o / b, oc / bc, " ".join("%.2f" % (x[0] / y[0])
                                      for x, y in zip(times["ours"], times["base"]))))
    floor = "three pass-through pythonfmu FMUs (the floor: pythonfmu's calls, no model)"
    figures.record(__file__, argv, [
        figures.row("one step of the three pass-through FMUs, fmpy's master", b * 1e6, "µs"),
        figures.row("one step of the three driftfmu Python FMUs, fmpy's master", o * 1e6, "µs",
                    floor, o / b, "<= 1.3", o / b <= 1.3),
        figures.row("the same, CPU time", oc * 1e6, "µs", floor + ", CPU time", oc / bc),
    ], load, "Median of %d alternating runs of %d steps." % (args.repeats, args.steps))


if __name__ == "__main__":
    main()
