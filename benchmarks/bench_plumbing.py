"""Cost of the native FMUs' FMI plumbing per sample: this tree's against a baseline revision's.

The plumbing (fmu_src/native/cosimulation.c, cosimulation.h, model.h, fmi2Functions.c,
fmi3Functions.c) is taken from ``--baseline`` (default ``main``, through ``git show``) and from
the working tree; each set of native FMUs is built from it with the same models and the same
compiler flags (x86-64 Linux only), and both run, in one process and alternating run by run,
through the fast master (simulations.fastcosim.cosimulate_fast, a C loop calling fmi2DoStep /
fmi2SetReal / fmi2GetReal directly):

1. the ADXL203 held-out chain (Excitation -> Accelerometer -> DriftEstimator, the stand-in's
   settings, EKF1 with the harmonic process model at 150 Hz, the values of
   simulations/adxl203.py ``_run_set``; 60,000 samples at Ts = 1e-4 s);
2. the letter's Gaussian chain (simulations/gaussian.py's start values, 60,000 samples).

A figure is the wall time of the stepping loop (loading excluded: from the master's first
progress call to its last) divided by the samples, the median of ``--repeats`` runs; beside it
the best run and the median of the process's CPU time over the same stretch (which the load of
a shared machine changes less).  The two
builds must give the same bits (checked on every recorded column): a speed-up that changed a
result would be refused here.

    python benchmarks/bench_plumbing.py [--baseline main] [--samples 60000] [--repeats 7]
                                        [--fmi 2]
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import figures  # noqa: E402

from driftfmu.fmu_src import native_build  # noqa: E402
from driftfmu.models import adxl203 as adxl203_model  # noqa: E402
from driftfmu.simulations import adxl203, gaussian  # noqa: E402
from driftfmu.simulations.fastcosim import cosimulate_fast  # noqa: E402

PLUMBING = ("cosimulation.c", "cosimulation.h", "model.h", "fmi2Functions.c",
            "fmi3Functions.c")
REPO = HERE.parent


def baseline_plumbing(revision, folder):
    """Write the plumbing files of git ``revision`` into ``folder`` (the models come from the
    working tree, as for the other build)."""
    folder.mkdir(parents=True)
    for name in PLUMBING:
        text = subprocess.run(["git", "show", "%s:./%s" % (revision, name)],
                              cwd=native_build.NATIVE_DIR, capture_output=True, check=True)
        (folder / name).write_bytes(text.stdout)


def build(native_dir, out, fmi_version):
    """The three native FMUs of ``fmi_version`` with the plumbing of ``native_dir`` (checked:
    each FMU's sources/ hold exactly those files)."""
    saved = native_build.NATIVE_DIR
    native_build.NATIVE_DIR = Path(native_dir)
    try:
        paths = native_build.build_native_fmus(out, fmi_versions=(fmi_version,),
                                               platforms=["x86_64-linux"],
                                               log=lambda *a: None)[fmi_version]
    finally:
        native_build.NATIVE_DIR = saved
    for path in paths.values():
        with zipfile.ZipFile(path) as z:
            for name in PLUMBING:
                if name.startswith("fmi") and name != "fmi%dFunctions.c" % fmi_version:
                    continue
                if z.read("sources/" + name) != (Path(native_dir) / name).read_bytes():
                    raise SystemExit("%s: sources/%s is not %s's" % (path, name, native_dir))
    return paths


def chains(samples):
    """(label, connections, start values, record, Ts) of the two chains."""
    f, Ts, seed = 150.0, adxl203.TS, 1234
    model = dict(a0=2.5, a1=adxl203_model.SENSITIVITY_5V, a2=0.01, R=1e-4)  # ~ a fit (order 2)
    ex = dict(adxl203.set_drive(seed, f), Ts=Ts)
    sp = dict(adxl203_model.ADXL203, seed=seed, Ts=Ts, noise=1)
    es = adxl203.estimator_values(model, f, Ts)
    return [
        ("ADXL203 held-out chain", adxl203.CONNECTIONS,
         {"Excitation": ex, "Accelerometer": sp, "DriftEstimator": es}, adxl203.RECORD, Ts),
        ("Gaussian chain", gaussian.CONNECTIONS, gaussian.start_values(),
         {"Excitation": ["x"], "Accelerometer": ["z"],
          "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}, 1e-3),
    ]


def run(fmus, chain, samples):
    """(wall ns, CPU ns per sample of the stepping loop, the recorded columns)."""
    _, connections, values, record, Ts = chain
    stamps = []
    out = cosimulate_fast({k: str(v) for k, v in fmus.items()}, connections, samples, Ts,
                          start_values=values, record=record, arrays=True,
                          progress=lambda done: stamps.append(
                              (done, time.perf_counter(), time.process_time())))
    (k0, t0, c0), (k1, t1, c1) = stamps[0], stamps[-1]
    return 1e9 * (t1 - t0) / (k1 - k0), 1e9 * (c1 - c0) / (k1 - k0), out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="main", help="git revision of the baseline plumbing")
    ap.add_argument("--samples", type=int, default=60000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--fmi", type=int, choices=(2, 3), default=2)
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    load = figures.load()
    with tempfile.TemporaryDirectory(prefix="bench_plumbing_") as tmp:
        tmp = Path(tmp)
        base_dir = tmp / "baseline_native"
        baseline_plumbing(args.baseline, base_dir)
        builds = {"baseline (%s)" % args.baseline: build(base_dir, tmp / "base", args.fmi),
                  "this tree": build(native_build.NATIVE_DIR, tmp / "new", args.fmi)}
        measured = {}
        for chain in chains(args.samples):
            for r in range(args.repeats):
                outs = {}
                for label, fmus in builds.items():
                    wall, cpu_ns, outs[label] = run(fmus, chain, args.samples)
                    measured.setdefault((chain[0], label), []).append((wall, cpu_ns))
                a, b = outs.values()
                for key in a:
                    if not np.array_equal(a[key], b[key], equal_nan=True) or \
                            a[key].tobytes() != b[key].tobytes():
                        raise SystemExit("%s: %s differs between the builds" % (chain[0], key))
    print("machine: %s; load average %s"
          % (figures.machine(), " ".join("%.1f" % x for x in os.getloadavg())))
    print("native FMI %d.0 FMUs through the fast master, %d samples; median of %d runs; the "
          "builds' recorded columns equal bit for bit" % (args.fmi, args.samples, args.repeats))
    labels = list(builds)
    rows = []
    for chain in chains(args.samples):
        stats = {}
        for label in labels:
            runs = measured[(chain[0], label)]
            walls, cpus = [w for w, _ in runs], [c for _, c in runs]
            stats[label] = (statistics.median(walls), min(walls), statistics.median(cpus))
            print("  %-24s %-16s %7.3f us per sample of all three (best %.3f; CPU %.3f)   "
                  "(runs: %s)" % (chain[0], label, stats[label][0] / 1e3, stats[label][1] / 1e3,
                                  stats[label][2] / 1e3, ", ".join("%.0f" % w for w in walls)))
        (m0, b0, c0), (m1, b1, c1) = stats[labels[0]], stats[labels[1]]
        print("  %-24s ratio baseline / this tree: %.2f (best %.2f, CPU %.2f)"
              % (chain[0], m0 / m1, b0 / b1, c0 / c1))
        rows.append(figures.row("%s, native FMI %d.0 FMUs, fast master" % (chain[0], args.fmi),
                                m1 / 1e3, "µs a sample of all three",
                                "the same FMUs with the plumbing of %s" % args.baseline,
                                m1 / m0))
    figures.record(__file__, argv, rows, load,
                   "Median of %d alternating runs of %d samples; the two builds' recorded "
                   "columns are equal bit for bit." % (args.repeats, args.samples))


if __name__ == "__main__":
    main()
