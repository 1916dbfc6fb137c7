"""Wall time of ``driftfmu experiment adxl203`` (the letter's Sec. IV at paper size: 5
frequencies x 30 sets x 60,000 samples) against the way it ran before, in the same run.

- now: :func:`driftfmu.simulations.adxl203.run_adxl203` as it is (the fast master with the FMUs'
  libraries kept loaded in each worker; every held-out set checked against the C port of
  ``models.adxl203.simulate`` in the compiled kernel), files and figures written;
- baseline: the same function with the worker of before (:func:`baseline_run_set`: fmpy's
  wrappers for the Python FMUs, the fast master without reuse for the native ones, lists, and
  every held-out set checked against ``models.adxl203.simulate`` run sample by sample in pure
  Python), files and figures written.

Both must give the same summary, bit for bit (checked here, times aside).  Prints where the time
goes (from the summary's ``timing``), the CPU seconds of this process and of the workers (CPU
time grows much less with the load than wall time: CPU / cores is what the run needs of an
idle machine), the start-up of the command (a new Python importing the CLI) and the goals: at
most 5 s (native FMUs), 60 s (Python FMUs).

With the Python FMUs it also measures their floor: the experiment's co-simulations alone (the same
sets, sizes, workers, fast master, connections and recorded values) through pass-through
pythonfmu FMUs built with stock pythonfmu in this run (``passthrough/PassPair``, ``PassTwo``,
``PassThree``: the driftfmu FMUs' variables, no model).  That is what pythonfmu's calls cost
before any FMU computes anything; the goal leaves the driftfmu FMUs what is above it.  Not a
pytest test:

    python benchmarks/bench_adxl203.py [--backend native|python] [--sets 30] [--n 60000]
                                       [--freqs 100,125,150,175,200] [--no-baseline]
                                       [--no-floor]
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

from pythonfmu import FmuBuilder

from driftfmu.models import adxl203, identify
from driftfmu.simulations import adxl203 as experiment
from driftfmu.simulations import batch
from driftfmu.simulations.gaussian import fmu_paths, master
from driftfmu.simulations.sinusoidal import CONNECTIONS

import figures

GOALS = {"native": 5.0, "python": 60.0}
HERE = os.path.dirname(os.path.abspath(__file__))
#: The pass-through FMUs of the floor, by role.
FLOOR = {"Excitation": "PassPair", "Accelerometer": "PassTwo", "DriftEstimator": "PassThree"}


def baseline_run_set(task):
    """The experiment's worker as it was before the speed-up (same results, slower)."""
    paths, f, seed, n, Ts, model, validate, backend, order = task
    t0 = time.perf_counter()
    cosimulate = master(backend)
    ex = dict(experiment.set_drive(seed, f), Ts=Ts)
    sp = dict(adxl203.ADXL203, seed=seed, Ts=Ts, noise=1)
    if model is None:
        fmus = {k: paths[k] for k in ("Excitation", "Accelerometer")}
        raw = cosimulate(fmus, CONNECTIONS[:2], n, Ts, start_values={
            "Excitation": ex, "Accelerometer": sp}, record={"Excitation": ["x"],
                                                          "Accelerometer": ["z"]})
        t1 = time.perf_counter()
        fit = identify.fit_set(raw["time"], raw["Excitation.x"], raw["Accelerometer.z"], f,
                               skip=adxl203.settling_samples(sp["fc"], Ts), order=order)
        return {"fit": fit._asdict(), "seconds": {"simulation": t1 - t0,
                                                  "identification": time.perf_counter() - t1}}
    es = experiment.estimator_values(model, f, Ts)
    record = experiment.RECORD
    raw = cosimulate(paths, CONNECTIONS, n, Ts, start_values={
        "Excitation": ex, "Accelerometer": sp, "DriftEstimator": es}, record=record)
    t1 = time.perf_counter()
    z = raw["Accelerometer.z"]
    m = identify.whole_periods(n, f, Ts)
    res = {"dc_empirical": sum(z[:m]) / m - model["a0"],
           "dc_ekf1": raw["DriftEstimator.dc_ekf1"][-1],
           "dc_true": experiment.true_drift(ex, sp),
           "trace": [(k, raw["DriftEstimator.dc_ekf1"][k - 1])
                     for k in experiment._log_samples(n)]}
    t2 = time.perf_counter()
    if validate:
        ref = adxl203.simulate(n, ex, sp, es, Ts)
        res["max_abs_diff"] = max(max(abs(a - b) for a, b in zip(raw["%s.%s" % (fmu, v)],
                                                                 ref[v]))
                                  for fmu, names in record.items() for v in names)
    res["seconds"] = {"simulation": t1 - t0, "identification": t2 - t1,
                      "validation": time.perf_counter() - t2}
    return res


def _floor_set(task):
    """Worker of the floor: one set's co-simulation as the experiment's worker runs it (training
    sets: Excitation and Accelerometer; held-out ones: all three), through the pass-through
    FMUs; returns the seconds it took."""
    from driftfmu.simulations.fastcosim import cosimulate_fast
    paths, held_out, n, Ts = task
    t0 = time.perf_counter()
    if held_out:
        cosimulate_fast(paths, CONNECTIONS, n, Ts, record=experiment.RECORD, reuse=True,
                        arrays=True)
    else:
        cosimulate_fast({k: paths[k] for k in ("Excitation", "Accelerometer")},
                        CONNECTIONS[:2], n, Ts, record={"Excitation": ["x"],
                                                        "Accelerometer": ["z"]},
                        reuse=True, arrays=True)
    return time.perf_counter() - t0


def floor(args, workers):
    """The experiment's co-simulations alone through the pass-through FMUs, in the same pool of
    ``workers`` (training sets first, then the held-out ones, as the experiment): (wall seconds,
    CPU seconds of the workers, the workers' seconds in co-simulation)."""
    held_out = experiment.default_held_out(args.sets)
    with tempfile.TemporaryDirectory() as tmp:
        paths = {role: str(FmuBuilder.build_FMU(os.path.join(HERE, "passthrough", name + ".py"),
                                                dest=tmp)) for role, name in FLOOR.items()}
        k0, t0 = children_cpu(), time.perf_counter()
        seconds = 0.0
        with batch.process_pool(workers) as pool:
            for kind, count in ((False, args.sets - held_out), (True, held_out)):
                tasks = [(paths, kind, args.n, experiment.TS)] * (count * len(args.freqs))
                seconds += sum(pool.map(_floor_set, tasks))
        return time.perf_counter() - t0, children_cpu() - k0, seconds


def children_cpu():
    """CPU seconds (user + system) of this process's finished child processes."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(args, worker):
    """One experiment with ``worker`` as the set worker: (wall seconds, summary, JSON, CPU
    seconds {"parent", "workers"}); the workers are joined at its end, so their CPU time is
    counted in this process's children's."""
    original = experiment._run_set
    experiment._run_set = worker  # workers are forked: they see this module as it is now
    try:
        with tempfile.TemporaryDirectory() as out:
            c0, k0 = time.process_time(), children_cpu()
            t0 = time.perf_counter()
            s = experiment.run_adxl203(out=out, freqs=args.freqs, sets=args.sets,
                                       held_out=experiment.default_held_out(args.sets),
                                       n=args.n, fmu_dir=args.fmu_dir, backend=args.backend)
            wall = time.perf_counter() - t0
            cpu = {"parent": time.process_time() - c0, "workers": children_cpu() - k0}
            with open(os.path.join(out, "adxl203.json")) as fh:
                js = json.load(fh)
    finally:
        experiment._run_set = original
    for key in ("wall_time_s", "workers", "backend", "timing"):
        js.pop(key)
    js["validation"].pop("reference")
    return wall, s, js, cpu


def startup():
    """Wall and CPU seconds of ``python -m driftfmu experiment adxl203 --help``: a new Python
    importing and parsing the command line, what the command pays before its first set (the
    median of three)."""
    runs = []
    for _ in range(3):
        k0, t0 = children_cpu(), time.perf_counter()
        subprocess.run([sys.executable, "-m", "driftfmu", "experiment", "adxl203", "--help"],
                       check=True, stdout=subprocess.DEVNULL)
        runs.append((time.perf_counter() - t0, children_cpu() - k0))
    return sorted(runs)[1]


def steps(args):
    """Co-simulation steps of the experiment: every set, training and held out."""
    return len(args.freqs) * args.sets * args.n


def cpu_line(cpu, wall, workers):
    total = cpu["parent"] + cpu["workers"]
    return ("CPU: this process %.2f s, the workers %.2f s, together %.2f s: %.2f s on %d "
            "cores of an idle machine (wall here %.2f s)"
            % (cpu["parent"], cpu["workers"], total, total / workers, workers, wall))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", choices=("native", "python"), default="native")
    ap.add_argument("--sets", type=int, default=experiment.SETS)
    ap.add_argument("--n", type=int, default=experiment.N)
    ap.add_argument("--freqs", type=lambda t: [float(v) for v in t.split(",")],
                    default=list(experiment.FREQS))
    ap.add_argument("--no-baseline", action="store_true", help="skip the run of before")
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--no-floor", action="store_true",
                    help="skip the floor (pass-through FMUs; Python FMUs only)")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    fmu_paths(args.fmu_dir, args.backend)
    from driftfmu.simulations import kernel
    kernel.library()
    load = os.getloadavg()
    wall, s, now, used = run(args, experiment._run_set)
    print("machine: %s; load average before %s"
          % (figures.machine(), " ".join("%.2f" % v for v in load)))
    print("experiment adxl203, %s FMUs, %d frequencies x %d sets x %d samples, %d workers"
          % (args.backend, len(args.freqs), args.sets, args.n, s["workers"]))
    print("now:      %.2f s wall (goal <= %g s at paper size); margins %s dB; max |FMU - "
          "reference| %g" % (wall, GOALS[args.backend], ", ".join(
              "%.2f" % p["margin_db"] for p in s["per_frequency"]),
              s["validation"]["max_abs_diff"]))
    print("          " + experiment.timing_line(s["timing"]))
    print("          " + cpu_line(used, wall, s["workers"]))
    letter_size = (len(args.freqs), args.sets, args.n) == (len(experiment.FREQS), experiment.SETS,
                                                     experiment.N)
    size = "%d frequencies x %d sets x %d samples" % (len(args.freqs), args.sets, args.n)
    total = used["parent"] + used["workers"]
    rows = [figures.row("`driftfmu experiment adxl203 --backend %s`, %s%s, %d workers: wall "
                        "time" % (args.backend, size, " (the letter's size)" if letter_size else "",
                                  s["workers"]), wall, "s",
                        goal="<= %g s" % GOALS[args.backend] if letter_size else None,
                        met=wall <= GOALS[args.backend] if letter_size else None),
            figures.row("the same, CPU time of the command and its workers", total, "s"),
            figures.row("the same, CPU time / workers: the wall time of an idle machine",
                        total / s["workers"], "s")]
    up_wall, up_cpu = startup()
    rows.append(figures.row("the command's start-up (`driftfmu experiment adxl203 --help`)",
                            up_wall, "s"))
    print("start-up of the command (python -m driftfmu experiment adxl203 --help): %.2f s wall, "
          "%.2f s CPU; the command: about %.2f s wall here"
          % (up_wall, up_cpu, wall + up_wall))
    if args.backend == "python" and not args.no_floor:
        f_wall, f_cpu, f_sim = floor(args, s["workers"])
        sim = s["timing"]["workers_s"]["simulation"]
        print("floor:    %.2f s wall: the same co-simulations through pass-through pythonfmu "
              "FMUs (no model; the same master, sets, workers and values); CPU of the workers "
              "%.2f s; their co-simulation %.2f s" % (f_wall, f_cpu, f_sim))
        n = steps(args)
        paper = len(experiment.FREQS) * experiment.SETS * experiment.N
        print("          now / floor: %.2f x wall, %.2f x co-simulation; a step of a worker: "
              "floor %.2f us, driftfmu FMUs %.2f us; the goal (%g s for %d steps on %d "
              "workers) allows %.2f us a step for everything: co-simulation, identification, "
              "validation, files"
              % (wall / f_wall, sim / f_sim, f_sim / n * 1e6, sim / n * 1e6, GOALS["python"],
                 paper, s["workers"], GOALS["python"] * s["workers"] / paper * 1e6))
        rows.append(figures.row(
            "the same co-simulations through pass-through pythonfmu FMUs (the floor)", f_wall,
            "s"))
        rows.append(figures.row("a step of a worker's co-simulation, driftfmu Python FMUs",
                                sim / n * 1e6, "µs", "the same step of the pass-through FMUs",
                                sim / f_sim))
    if not args.no_baseline:
        old_wall, old, before, old_cpu = run(args, baseline_run_set)
        print("baseline: %.2f s wall (the worker of before: %s, pure-Python check)"
              % (old_wall, "fmpy's wrappers" if args.backend == "python"
                 else "fast master, FMUs loaded per set"))
        print("          " + experiment.timing_line(old["timing"]))
        print("          " + cpu_line(old_cpu, old_wall, old["workers"]))
        print("baseline / now: %.1f x; summaries equal bit for bit (times aside): %s"
              % (old_wall / wall, now == before))
        rows.insert(1, figures.row(
            "the same experiment with the set worker of before (%s, a pure-Python check)"
            % ("fmpy's wrappers" if args.backend == "python"
               else "the fast master, FMUs loaded per set"), old_wall, "s",
            "the experiment as it is (first row)", old_wall / wall))
        if now != before:
            sys.exit(1)
    print("load average after: %s" % " ".join("%.2f" % v for v in os.getloadavg()))
    figures.record(__file__, argv, rows, load[0],
                   "Margins %s dB; the held-out sets' FMU outputs equal models/ (max |diff| %g)."
                   % (", ".join("%.2f" % p["margin_db"] for p in s["per_frequency"]),
                      s["validation"]["max_abs_diff"]), variant=args.backend)


if __name__ == "__main__":
    main()
