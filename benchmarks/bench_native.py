"""Cost of one co-simulation step of the three FMUs, native (C) against Python (pythonfmu).

In one run, all on the letter's Gaussian chain (Excitation -> Accelerometer -> DriftEstimator,
Gauss-Seidel, 2 values copied along the connections and 8 outputs read per step):

1. the C host tests/hosts/chain_host.c (no Python in the process) with the native FMUs, FMI 2.0
   and FMI 3.0 (goal: at most 1 us per step of all three);
2. the same C host with the Python FMUs (the loader shim starts a Python in the host): the
   ratio of 2 to 1 is the figure;
3. the fmpy master (simulations.cosim.cosimulate, fmpy's FMU2Slave wrappers) and the fast master
   (simulations.fastcosim.cosimulate_fast, direct FMI calls from a C loop) with each backend.

A step's time is the wall time of the stepping loop (loading excluded) divided by the steps;
each figure is the median of ``--repeats`` runs, the sets alternating run by run, so that drifts
of a shared machine hit all of them.

    python benchmarks/bench_native.py [--steps 200000] [--python-steps 5000] [--repeats 5]
"""
import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "hosts"))

import chain  # noqa: E402

from driftfmu.simulations.cosim import cosimulate  # noqa: E402
from driftfmu.simulations.fastcosim import cosimulate_fast  # noqa: E402
from driftfmu.simulations.gaussian import CONNECTIONS, fmu_paths, start_values  # noqa: E402

import figures  # noqa: E402

RECORD = {"Excitation": ["x"], "Accelerometer": ["z"],
          "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}


def c_host_step(host, fmus, steps, work, version=2, env=None):
    """ns per step of the chain in the C host (quiet: values read, not printed)."""
    unpacked = {name: chain.unpack(path, work / name) for name, path in fmus.items()}
    text, keys = chain.script(version, unpacked, start_values(), CONNECTIONS, RECORD, steps,
                              1e-3, quiet=True)
    _, ns, _ = chain.run(host, text, keys, work, env=env)
    return ns


def master_step(master, fmus, steps):
    """ns per step of a Python master, timed between its first and last progress calls."""
    stamps = []
    master(fmus, CONNECTIONS, steps, 1e-3, start_values=start_values(), record=RECORD,
           progress=lambda done: stamps.append((done, time.perf_counter())))
    (k0, t0), (k1, t1) = stamps[0], stamps[-1]
    return 1e9 * (t1 - t0) / (k1 - k0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200000, help="steps of the native runs")
    ap.add_argument("--python-steps", type=int, default=5000,
                    help="steps of the runs with the Python FMUs")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    load = figures.load()
    python = {k: str(v) for k, v in fmu_paths(args.fmu_dir, "python").items()}
    native = {2: {k: str(p) for k, p in fmu_paths(args.fmu_dir, "native").items()}}
    from driftfmu.fmu_src.native_build import native_fmu_paths
    native[3] = {k: str(p) for k, p in native_fmu_paths(args.fmu_dir, 3).items()}
    measured = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        host = chain.compile_host(tmp / "chain_host")
        sets = [
            ("C host, native FMI 2.0", lambda w: c_host_step(host, native[2], args.steps, w)),
            ("C host, native FMI 3.0", lambda w: c_host_step(host, native[3], args.steps, w, 3)),
            ("C host, Python FMUs", lambda w: c_host_step(host, python, args.python_steps, w,
                                                          env=chain.python_fmu_env())),
            ("fmpy master, native FMI 2.0",
             lambda w: master_step(cosimulate, native[2], args.python_steps * 4)),
            ("fmpy master, Python FMUs",
             lambda w: master_step(cosimulate, python, args.python_steps)),
            ("fast master, native FMI 2.0",
             lambda w: master_step(cosimulate_fast, native[2], args.steps)),
            ("fast master, native FMI 3.0",
             lambda w: master_step(cosimulate_fast, native[3], args.steps)),
            ("fast master, Python FMUs",
             lambda w: master_step(cosimulate_fast, python, args.python_steps)),
        ]
        for r in range(args.repeats):
            for i, (label, measure) in enumerate(sets):
                work = tmp / ("r%d_%d" % (r, i))
                work.mkdir()
                measured.setdefault(label, []).append(measure(work))
    print("machine: %s; load average %s"
          % (figures.machine(), " ".join("%.1f" % x for x in os.getloadavg())))
    print("steps: %d (native), %d (Python FMUs); median of %d runs"
          % (args.steps, args.python_steps, args.repeats))
    median = {label: statistics.median(v) for label, v in measured.items()}
    for label, _ in sets:
        print("  %-30s %10.1f ns per step of all three   (runs: %s)"
              % (label, median[label], ", ".join("%.0f" % x for x in measured[label])))
    goal = median["C host, native FMI 2.0"] <= 1000.0
    print("native in the C host: %.3f us per step (goal <= 1 us: %s)"
          % (median["C host, native FMI 2.0"] / 1e3, "met" if goal else "NOT met"))
    print("ratio Python / native FMUs in the same C host: %.0f"
          % (median["C host, Python FMUs"] / median["C host, native FMI 2.0"]))
    print("ratio Python / native FMUs in the fmpy master: %.1f"
          % (median["fmpy master, Python FMUs"] / median["fmpy master, native FMI 2.0"]))
    print("ratio fmpy master / fast master, native FMI 2.0: %.1f"
          % (median["fmpy master, native FMI 2.0"] / median["fast master, native FMI 2.0"]))
    native2 = "the native FMI 2.0 FMUs in the same host"
    rows = []
    for label, _ in sets:
        host, kind = label.split(", ", 1)
        against = None
        if kind == "Python FMUs":
            against = native2
        elif host != "C host" and kind == "native FMI 2.0":
            against = "the same FMUs in the C host"
        base = {native2: "%s, native FMI 2.0" % host,
                "the same FMUs in the C host": "C host, %s" % kind}.get(against)
        rows.append(figures.row("one step of the three FMUs: %s, %s" % (host, kind),
                                median[label] / 1e3, "µs", against,
                                median[label] / median[base] if base else None,
                                "<= 1 µs" if label == "C host, native FMI 2.0" else None,
                                goal if label == "C host, native FMI 2.0" else None))
    figures.record(__file__, argv, rows, load,
                   "Median of %d alternating runs; %d steps of the native FMUs, %d of the "
                   "Python FMUs." % (args.repeats, args.steps, args.python_steps))


if __name__ == "__main__":
    main()
