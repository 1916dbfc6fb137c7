"""One long step of the Python DualDriftEstimator against the Python DriftEstimator's.

A host whose step spans many sample periods (``fmi2DoStep`` of up to 1,000,000 samples, the
most one step may process) has the FMU predict through every sample of the step after the
first.  Each FMU is loaded by fmpy from ``build/fmus`` (as a host loads it), initialised with
``process`` 1 (Gauss-Markov) or 2 (harmonic oscillators) and stepped once from t = 0 over
``--samples`` sample periods; the step's wall time is taken around ``doStep`` alone.  The two
FMUs alternate run by run; the medians are compared, per process model.

    python benchmarks/bench_long_step.py [--samples 1000000] [--repeats 3]
"""
import argparse
import os
import statistics
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import figures  # noqa: E402

#: The goal: the dual-axis filter's long step within this many times the single-axis one's.
GOAL = 3.0
MODELS = ("DriftEstimator", "DualDriftEstimator")


def step_time(path, process, samples):
    """Wall time [s] of one ``doStep`` over ``samples`` sample periods of the FMU at ``path``
    (loading, initialising and freeing it excluded)."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(str(path))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    folder = extract(str(path))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    try:
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.setInteger([vrs["process"]], [process])
        fmu.exitInitializationMode()
        Ts = 1e-3
        t0 = time.perf_counter()
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=samples * Ts)
        wall = time.perf_counter() - t0
        fmu.terminate()
    finally:
        fmu.freeInstance()
        import shutil
        shutil.rmtree(folder, ignore_errors=True)
    return wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1000000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    load = os.getloadavg()
    from driftfmu.fmu_src.builder import build_fmus
    paths = {n: Path(args.fmu_dir) / ("%s.fmu" % n) for n in MODELS}
    if not all(p.is_file() for p in paths.values()):
        build_fmus(args.fmu_dir, names=MODELS, log=lambda line: None)
    rows, medians = [], {}
    print("machine: %s" % figures.machine())
    for process, label in ((1, "Gauss-Markov"), (2, "harmonic")):
        times = {n: [] for n in MODELS}
        for _ in range(args.repeats):  # alternate, so that drifts of the machine hit both
            for name in MODELS:
                times[name].append(step_time(paths[name], process, args.samples))
        single, dual = (statistics.median(times[n]) for n in MODELS)
        medians[process] = (single, dual)
        ratio = dual / single
        print("one step of %d samples, process %d (%s), median of %d runs: DriftEstimator "
              "%.3f s, DualDriftEstimator %.3f s, ratio %.2f (goal <= %g); per-run ratios %s"
              % (args.samples, process, label, args.repeats, single, dual, ratio, GOAL,
                 " ".join("%.2f" % (d / s) for s, d in zip(times[MODELS[0]],
                                                            times[MODELS[1]]))))
        base = "the Python DriftEstimator's step of %d samples, process %d" % (args.samples,
                                                                             process)
        rows += [
            figures.row("one step of %d samples of the Python DriftEstimator, process %d "
                        "(%s)" % (args.samples, process, label), single, "s"),
            figures.row("one step of %d samples of the Python DualDriftEstimator, process %d "
                        "(%s)" % (args.samples, process, label), dual, "s", base, ratio,
                        "<= %g" % GOAL, ratio <= GOAL)]
    figures.record(__file__, argv, rows, load, "Median of %d alternating runs; each FMU loaded "
                   "by fmpy from %s." % (args.repeats, args.fmu_dir))
    if any(d / s > GOAL for s, d in medians.values()):
        sys.exit("the goal is not met")


if __name__ == "__main__":
    main()
