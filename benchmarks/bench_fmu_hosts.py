"""The Python FMUs' step in a C host against fmpy's master, each against the pythonfmu floor.

In one run, on the letter's Gaussian chain (Excitation -> Accelerometer -> DriftEstimator):

1. the C host tests/hosts/chain_host.c (no Python in the process; 3 doSteps, 2 values copied
   along the connections and 8 outputs read, one fmi2GetReal each, per step) with the driftfmu
   Python FMUs, and with three pass-through pythonfmu FMUs (benchmarks/passthrough) behind the
   same loader shim: the floor of a Python FMU in a C host;
2. the same C host with the stock pass-through FMUs (pythonfmu's own library, libpython
   preloaded): what every call cost before the loader shim kept one Python thread state per
   host thread (pythonfmu 0.7.0 creates and destroys one per call in a thread Python has not
   seen);
3. fmpy's master (simulations.cosim.cosimulate) with the driftfmu FMUs and the stock
   pass-through FMUs (the ratio of benchmarks/bench_step.py).

Goals: C host / fmpy master with the driftfmu FMUs <= 1.2; driftfmu / pass-through in fmpy's
master <= 1.3.  Each figure is the median of ``--repeats`` runs, the sets alternating run by
run.  A step's wall time and the process's CPU time are both printed: on a machine shared with
other work the wall time grows with the load, the CPU time much less.

With ``--compare-shim OLD.c`` the driftfmu FMUs also run in the C host with the loader shim
compiled from OLD.c (e.g. ``git show <commit>:fmu_src/loader/fmi2_shim.c > OLD.c``): a before
and after in one run.

    python benchmarks/bench_fmu_hosts.py [--steps 5000] [--repeats 5] [--fmu-dir build/fmus]
                                         [--compare-shim OLD.c]
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

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "hosts"))

import chain  # noqa: E402

from driftfmu.fmu_src import builder  # noqa: E402
from driftfmu.simulations.cosim import cosimulate  # noqa: E402
from driftfmu.simulations.gaussian import CONNECTIONS, fmu_paths, start_values  # noqa: E402

from bench_step import RECORD, build_baseline  # noqa: E402
import figures  # noqa: E402


def behind_shim(fmu, dest, loader):
    """A copy of the stock pythonfmu ``fmu`` in ``dest`` whose linux64 binary is the loader
    shim (``loader`` from the builder), with pythonfmu's library beside it as the build does."""
    with zipfile.ZipFile(fmu) as archive:
        entries = {i.filename: archive.read(i) for i in archive.infolist() if not i.is_dir()}
    library = entries.pop("binaries/linux64/%s.so" % fmu.stem)
    entries.update(builder._linux_binaries(fmu.stem, library, loader, dest))
    target = Path(dest) / fmu.name
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in sorted(entries.items()):
            archive.writestr(name, data)
    return target


def with_shim(fmu, dest, source):
    """A copy of the driftfmu ``fmu`` in ``dest`` whose loader shim is compiled from ``source``
    (as the builder compiles fmu_src/loader/fmi2_shim.c)."""
    shim = Path(dest) / ("%s.so" % fmu.stem)
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-fvisibility=hidden",
                    "-I%s" % builder._fmi2_headers(), "-I%s" % (builder.SRC_DIR / "native"),
                    '-DDRIFTFMU_BUILD_LIBPYTHON="%s"' % builder.libpython_soname(),
                    "-o", str(shim), str(source), "-ldl", "-lpthread"], check=True)
    with zipfile.ZipFile(fmu) as archive:
        entries = {i.filename: archive.read(i) for i in archive.infolist() if not i.is_dir()}
    entries["binaries/linux64/%s.so" % fmu.stem] = shim.read_bytes()
    target = Path(dest) / fmu.name
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in sorted(entries.items()):
            archive.writestr(name, data)
    return target


def c_host(host, fmus, steps, work, values, env):
    """(wall ns, CPU ns) per step of the chain in the C host."""
    unpacked = {name: chain.unpack(path, work / name) for name, path in fmus.items()}
    text, _ = chain.script(2, unpacked, values, CONNECTIONS, RECORD, steps, 1e-3, quiet=True)
    (work / "script.txt").write_text(text)
    result = subprocess.run([str(host), "script.txt"], cwd=work, env=env, capture_output=True,
                            text=True, timeout=600)
    figures = dict(line.split()[:2] for line in result.stdout.splitlines()
                   if line.startswith(("NS_PER_STEP", "CPU_NS_PER_STEP")))
    if "CPU_NS_PER_STEP" not in figures:  # (stock pythonfmu may crash at exit, after these)
        raise RuntimeError("chain host failed (%d):\n%s\n%s" % (
            result.returncode, result.stdout[-2000:], result.stderr[-2000:]))
    return float(figures["NS_PER_STEP"]), float(figures["CPU_NS_PER_STEP"])


def master(fmus, steps, values):
    """(wall ns, CPU ns) per step of fmpy's master, between its first and last progress calls."""
    stamps = []
    cosimulate(fmus, CONNECTIONS, steps, 1e-3, start_values=values, record=RECORD,
               progress=lambda done: stamps.append((done, time.perf_counter(),
                                                    time.process_time())))
    (k0, w0, c0), (k1, w1, c1) = stamps[0], stamps[-1]
    return 1e9 * (w1 - w0) / (k1 - k0), 1e9 * (c1 - c0) / (k1 - k0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--compare-shim", metavar="OLD.c",
                    help="also run the driftfmu FMUs with the loader shim compiled from OLD.c")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    load = figures.load()
    ours = {k: str(v) for k, v in fmu_paths(args.fmu_dir, "python").items()}
    shim_env = chain.python_fmu_env()
    libpython = os.path.join(shim_env["LD_LIBRARY_PATH"].split(":")[0],
                             builder.libpython_soname())
    stock_env = dict(shim_env, LD_PRELOAD=libpython)
    measured = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        host = chain.compile_host(tmp / "chain_host")
        stock = build_baseline(tmp / "stock")
        loader = builder._make_loader(tmp, log=print)
        if loader[0] != "shim":
            raise SystemExit("the loader shim does not compile here: %s" % (loader,))
        (tmp / "shimmed").mkdir()
        shimmed = {role: behind_shim(p, tmp / "shimmed", loader) for role, p in stock.items()}
        values = start_values()
        sets = [
            ("C host, driftfmu FMUs", lambda w: c_host(host, ours, args.steps, w, values,
                                                       shim_env)),
            ("C host, pass-through + shim", lambda w: c_host(host, shimmed, args.steps, w, {},
                                                             shim_env)),
            ("C host, pass-through stock", lambda w: c_host(host, stock, args.steps, w, {},
                                                            stock_env)),
            ("fmpy master, driftfmu FMUs", lambda w: master(ours, args.steps, values)),
            ("fmpy master, pass-through", lambda w: master(
                {k: str(v) for k, v in stock.items()}, args.steps, None)),
        ]
        if args.compare_shim:
            (tmp / "old").mkdir()
            old = {k: with_shim(Path(p), tmp / "old", args.compare_shim) for k, p in ours.items()}
            sets.insert(1, ("C host, driftfmu, OLD.c shim", lambda w: c_host(
                host, old, args.steps, w, values, shim_env)))
        for r in range(args.repeats):
            for i, (label, measure) in enumerate(sets):
                work = tmp / ("r%d_%d" % (r, i))
                work.mkdir()
                measured.setdefault(label, []).append(measure(work))
    print("machine: %s; load average %s"
          % (figures.machine(), " ".join("%.1f" % x for x in os.getloadavg())))
    print("%d steps per run; median of %d runs; us per step of all three FMUs"
          % (args.steps, args.repeats))
    wall = {k: statistics.median(w for w, _ in v) for k, v in measured.items()}
    cpu_ = {k: statistics.median(c for _, c in v) for k, v in measured.items()}
    print("  %-30s %9s %9s" % ("", "wall", "CPU"))
    for label, _ in sets:
        print("  %-30s %9.1f %9.1f" % (label, wall[label] / 1e3, cpu_[label] / 1e3))

    def ratio(a, b, goal=None):
        text = "%.2f wall, %.2f CPU" % (wall[a] / wall[b], cpu_[a] / cpu_[b])
        if goal is not None:
            text += " (goal <= %.1f: %s)" % (goal, "met" if wall[a] / wall[b] <= goal
                                             else "NOT met on wall time")
        return text
    print("C host / fmpy master, driftfmu FMUs:        %s"
          % ratio("C host, driftfmu FMUs", "fmpy master, driftfmu FMUs", 1.2))
    print("driftfmu / pass-through floor, C host:      %s"
          % ratio("C host, driftfmu FMUs", "C host, pass-through + shim"))
    print("driftfmu / pass-through floor, fmpy master: %s"
          % ratio("fmpy master, driftfmu FMUs", "fmpy master, pass-through", 1.3))
    print("stock pythonfmu / behind the shim, C host:  %s  (the per-call thread state)"
          % ratio("C host, pass-through stock", "C host, pass-through + shim"))
    if args.compare_shim:
        print("C host, driftfmu FMUs, OLD.c shim / this:   %s"
              % ratio("C host, driftfmu, OLD.c shim", "C host, driftfmu FMUs"))
    against = {
        "C host, driftfmu FMUs": ("fmpy master, driftfmu FMUs", "the same FMUs in fmpy's master",
                                  "<= 1.2"),
        "C host, driftfmu, OLD.c shim": ("C host, driftfmu FMUs", "this loader shim", None),
        "C host, pass-through + shim": (None, None, None),
        "C host, pass-through stock": ("C host, pass-through + shim",
                                       "the same FMUs behind the loader shim", None),
        "fmpy master, driftfmu FMUs": ("fmpy master, pass-through",
                                       "the pass-through FMUs (the floor) in fmpy's master",
                                       "<= 1.3"),
        "fmpy master, pass-through": (None, None, None),
    }
    rows = []
    for label, _ in sets:
        base, text, goal = against[label]
        r = wall[label] / wall[base] if base else None
        rows.append(figures.row("one step of the three FMUs: %s" % label, wall[label] / 1e3,
                                "µs", text, r, goal, None if goal is None else
                                r <= float(goal.split()[-1])))
    rows.append(figures.row("the driftfmu FMUs in the C host, over the floor in the C host",
                            wall["C host, driftfmu FMUs"] / wall["C host, pass-through + shim"],
                            "×", "the pass-through FMUs behind the shim in the C host"))
    figures.record(__file__, argv, rows, load,
                   "Median of %d alternating runs of %d steps; the Python FMUs; pass-through: "
                   "pythonfmu FMUs with the driftfmu FMUs' variables and no model."
                   % (args.repeats, args.steps))


if __name__ == "__main__":
    main()
