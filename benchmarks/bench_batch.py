"""Cost per sample-run of the batch engine, of the FMU path and of filterpy's EKF in a loop.

All three run the letter's Gaussian chain (a1 = 1, a2 = 0.01, Q = 0.01, R = 1e-4, A = 0): the
scalar EKF and the three drift estimators.

- batch engine, one process: :func:`driftfmu.simulations.batch.simulate` on ``--runs`` runs of ``--n``
  samples at once (noise, excitation, sensor, EKF, estimators, references), with NumPy (the
  baseline) and with the compiled kernel (:mod:`driftfmu.simulations.kernel`), same bits;
- the default ``driftfmu sweep`` (6 x 5 grid, 1000 runs of 1000 samples) on all local cores,
  the runs alone and with its files and figures, NumPy against the kernel; and the command
  itself (``driftfmu sweep``, a new process: start-up, runs, files, figures), wall time;
- the NumPy engine with a quartic term ``a4 = 0.05`` (the general sensor of issue 16:
  ``h``, ``h'`` and the 3rd/4th moments of the estimators; the kernel has the quadratic
  sensor only), printed beside the NumPy figure with the ratio;
- FMU path: one run co-simulated with the three FMUs (:func:`driftfmu.simulations.batch.fmu_simulate`),
  ``--fmu-n`` samples with the instantiation included, and per additional sample;
- filterpy: ``filterpy.kalman.ExtendedKalmanFilter`` (1 state, 1 measurement) in a Python loop,
  ``predict`` + ``update`` with the same ``h`` and Jacobian, plus the three drift estimators in
  Python; the measurements are generated beforehand and not timed (which favours filterpy).

Each figure is the best of ``--repeats``.  Not a pytest test:

    python benchmarks/bench_batch.py [--runs 4096] [--n 1000] [--fmu-n 500] [--filterpy-n 20000]

Without a C compiler the kernel's lines are left out.
"""
import argparse
import os
import time

import numpy as np

from driftfmu.models import drift
from driftfmu.simulations import batch, sweep

import figures

P = dict(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4)
#: The general sensor (issue 16): a quartic term in the sensor, the filter and the estimators.
P4 = dict(P, a4=0.05)


def best(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bench_batch(runs, n, repeats, kernel, params=P):
    seeds = batch.run_seeds(1, runs)
    return best(lambda: batch.simulate(n, seeds, kernel=kernel, **params), repeats) / (runs * n)


def bench_sweep(repeats, kernel_on):
    """Default sweep in this process: (seconds of the runs, ns per sample-run, seconds with
    the files and figures written); ``kernel_on`` False runs the NumPy engine."""
    import tempfile
    old = os.environ.get("DRIFTFMU_KERNEL")
    if not kernel_on:
        os.environ["DRIFTFMU_KERNEL"] = "numpy"
    try:
        res = []
        with tempfile.TemporaryDirectory() as out:
            wall = best(lambda: res.append(sweep.sweep(out=os.path.join(out, "s"))), repeats)
    finally:
        os.environ.pop("DRIFTFMU_KERNEL", None)
        if old is not None:
            os.environ["DRIFTFMU_KERNEL"] = old
    t = min(r["seconds"] for r in res)
    return t, t / (6 * 5 * 1000 * 1000), wall


def bench_sweep_command(repeats, kernel_on):
    """Wall time of ``driftfmu sweep`` (default grid, files and figures) as a new process."""
    import subprocess
    import sys
    import tempfile
    env = dict(os.environ)
    env.pop("DRIFTFMU_KERNEL", None)
    if not kernel_on:
        env["DRIFTFMU_KERNEL"] = "numpy"
    with tempfile.TemporaryDirectory() as out:
        command = [sys.executable, "-m", "driftfmu", "sweep", "--out", os.path.join(out, "s")]
        return best(lambda: subprocess.run(command, env=env, check=True,
                                           stdout=subprocess.DEVNULL), repeats)


def bench_fmu(n, fmu_dir, repeats):
    """Per sample with the instantiation of the three FMUs included (``n`` samples), and per
    additional sample (from runs of ``n`` and ``5 n`` samples)."""
    t1 = best(lambda: batch.fmu_simulate(n, 1, fmu_dir=fmu_dir, **P), repeats)
    t5 = best(lambda: batch.fmu_simulate(5 * n, 1, fmu_dir=fmu_dir, **P), repeats)
    return t1 / n, max(t5 - t1, 0.0) / (4 * n)


def filterpy_run(zs, a0, a1, a2, A, Q, R):
    """The letter's scalar EKF with filterpy, and the EKF1-3 drift estimators; final estimates."""
    from filterpy.kalman import ExtendedKalmanFilter
    f = ExtendedKalmanFilter(dim_x=1, dim_z=1)
    f.x = np.array([[0.0]])
    f.P = np.array([[Q / (1.0 - A * A)]])
    f.F = np.array([[A]])
    f.Q = np.array([[Q]])
    f.R = np.array([[R]])

    def jacobian(x):
        return np.array([[a1 + 2.0 * a2 * x[0, 0]]])

    def hx(x):
        v = x[0, 0]
        return np.array([[a0 + a1 * v + a2 * v * v]])

    state = drift.initial_state()
    for z in zs:
        f.predict()
        f.update(np.array([[z]]), jacobian, hx)
        state = drift.update(state, f.x[0, 0], f.P[0, 0], a2)
    return drift.estimates(state, a2)


def bench_filterpy(n, repeats):
    zs = batch.simulate(n, batch.run_seeds(1, 1), record=("z",), **P)["z"][0]
    out = []
    t = best(lambda: out.append(filterpy_run(zs, **P)), repeats) / n
    ours = batch.simulate(n, batch.run_seeds(1, 1), **P)
    diff = max(abs(out[-1][i] - ours["final_dc_ekf%d" % (i + 1)][0]) for i in range(3))
    return t, diff


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4096, help="runs of the one-process batch")
    ap.add_argument("--n", type=int, default=1000, help="samples per run of the batch")
    ap.add_argument("--fmu-n", type=int, default=500, help="samples of the FMU run")
    ap.add_argument("--filterpy-n", type=int, default=20000, help="samples of the filterpy run")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    from driftfmu.simulations.gaussian import fmu_paths
    fmu_paths(args.fmu_dir)
    load = os.getloadavg()

    from driftfmu.simulations import kernel
    have_kernel = kernel.library() is not None
    t_batch = bench_batch(args.runs, args.n, args.repeats, "numpy")
    t_batch4 = bench_batch(args.runs, args.n, args.repeats, "numpy", P4)
    t_kernel = bench_batch(args.runs, args.n, args.repeats, "c") if have_kernel else None
    sweeps = {on: bench_sweep(args.repeats, on) for on in ((False, True) if have_kernel
                                                           else (False,))}
    commands = {on: bench_sweep_command(args.repeats, on) for on in sweeps}
    t_fmu, t_fmu_step = bench_fmu(args.fmu_n, args.fmu_dir, args.repeats)
    t_fp, diff = bench_filterpy(args.filterpy_n, args.repeats)

    print("machine: %s" % figures.machine())
    print("load average before: %s" % " ".join("%.2f" % v for v in load))
    print("%-58s %12s" % ("", "ns/sample-run"))
    print("%-58s %12.1f" % ("batch engine, NumPy, 1 process (%d runs x %d samples)"
                            % (args.runs, args.n), t_batch * 1e9))
    print("%-58s %12.1f" % ("batch engine, NumPy, 1 process, a4 = %g (general; %.2f x)"
                            % (P4["a4"], t_batch4 / t_batch), t_batch4 * 1e9))
    if t_kernel is not None:
        print("%-58s %12.1f" % ("batch engine, compiled kernel, 1 process", t_kernel * 1e9))
    for on, (t, per, wall) in sweeps.items():
        print("%-58s %12.1f" % ("default sweep, %s, %d cores (runs %.2f s wall)"
                                % ("kernel" if on else "NumPy", batch.workers_default(), t),
                                per * 1e9))
    print("%-58s %12.0f" % ("FMU path, 1 run of %d samples (instantiation included)"
                            % args.fmu_n, t_fmu * 1e9))
    print("%-58s %12.0f" % ("FMU path, per additional sample (runs of %d and %d)"
                            % (args.fmu_n, 5 * args.fmu_n), t_fmu_step * 1e9))
    print("%-58s %12.0f" % ("filterpy ExtendedKalmanFilter loop (%d samples)"
                            % args.filterpy_n, t_fp * 1e9))
    print("filterpy / batch (1 process): NumPy %.0f x%s   (goal >= 1000 per core)"
          % (t_fp / t_batch, "" if t_kernel is None else ", kernel %.0f x" % (t_fp / t_kernel)))
    if t_kernel is not None:
        print("kernel / NumPy engine, 1 process: %.2f x faster, same bits" % (t_batch / t_kernel))
    for on, (t, per, wall) in sweeps.items():
        print("default sweep with files and figures, %s: %.2f s in this process, %.2f s as "
              "the command `driftfmu sweep` (new process; goal <= 1 s)"
              % ("kernel" if on else "NumPy (baseline)", wall, commands[on]))
    print("load average after: %s" % " ".join("%.2f" % v for v in os.getloadavg()))
    print("FMU (per additional sample) / batch (1 process): %.0f x;  filterpy and the batch "
          "engine agree on the final drift estimates to %.1e V" % (t_fmu_step / t_batch, diff))
    numpy_engine = "the batch engine, NumPy, 1 process"
    fastest = t_batch if t_kernel is None else t_kernel
    rows = [figures.row("the batch engine, NumPy, 1 process (%d runs x %d samples)"
                        % (args.runs, args.n), t_batch * 1e9, "ns a sample-run"),
            figures.row("the same with the general sensor (a4 = %g)" % P4["a4"],
                        t_batch4 * 1e9, "ns a sample-run", numpy_engine, t_batch4 / t_batch)]
    if t_kernel is not None:
        rows.append(figures.row("the batch engine, compiled kernel, 1 process (same bits)",
                                t_kernel * 1e9, "ns a sample-run", numpy_engine,
                                t_kernel / t_batch))
    rows.append(figures.row(
        "filterpy's ExtendedKalmanFilter in a Python loop (%d samples)" % args.filterpy_n,
        t_fp * 1e9, "ns a sample", "the batch engine's fastest path, 1 process", t_fp / fastest,
        ">= 1000", t_fp / fastest >= 1000))
    rows.append(figures.row("one FMU co-simulation, per additional sample", t_fmu_step * 1e9,
                            "ns a sample", numpy_engine, t_fmu_step / t_batch))
    for on, (t, per, wall) in sweeps.items():
        rows.append(figures.row("the default sweep's runs (3e7 sample-runs), %s, %d cores"
                                % ("kernel" if on else "NumPy", batch.workers_default()), t,
                                "s"))
    for on in commands:
        rows.append(figures.row("the command `driftfmu sweep` (start-up, runs, files, figures), "
                                "%s" % ("kernel" if on else "NumPy"), commands[on], "s",
                                None if not on else "the same command with NumPy",
                                None if not on else commands[on] / commands[False],
                                "<= 1 s" if on else None, commands[on] <= 1.0 if on else None))
    figures.record(__file__, argv, rows, load, "Best of %d." % args.repeats)


if __name__ == "__main__":
    main()
