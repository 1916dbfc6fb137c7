"""Cost per sample-run of the batch engine, of the FMU path and of filterpy's EKF in a loop.

All three run the letter's Gaussian chain (a1 = 1, a2 = 0.01, Q = 0.01, R = 1e-4, A = 0): the
scalar EKF and the three drift estimators.

- batch engine, one process: :func:`driftfmu.simulations.batch.simulate` on ``--runs`` runs of ``--n``
  samples at once (noise, excitation, sensor, EKF, estimators, references); and the same with
  a quartic term ``a4 = 0.05`` (the general sensor of issue 16: ``h``, ``h'`` and the 3rd/4th
  moments of the estimators), printed beside it with the ratio;
- batch engine, the default ``driftfmu sweep`` (6 x 5 grid, 1000 runs of 1000 samples) on all
  local cores, wall time;
- FMU path: one run co-simulated with the three FMUs (:func:`driftfmu.simulations.batch.fmu_simulate`),
  ``--fmu-n`` samples with the instantiation included, and per additional sample;
- filterpy: ``filterpy.kalman.ExtendedKalmanFilter`` (1 state, 1 measurement) in a Python loop,
  ``predict`` + ``update`` with the same ``h`` and Jacobian, plus the three drift estimators in
  Python; the measurements are generated beforehand and not timed (which favours filterpy).

Each figure is the best of ``--repeats``.  Not a pytest test:

    python benchmarks/bench_batch.py [--runs 4096] [--n 1000] [--fmu-n 500] [--filterpy-n 20000]
"""
import argparse
import os
import platform
import time

import numpy as np

from driftfmu.models import drift
from driftfmu.simulations import batch, sweep

from machine import cpu

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


def bench_batch(runs, n, repeats, params=P):
    seeds = batch.run_seeds(1, runs)
    return best(lambda: batch.simulate(n, seeds, **params), repeats) / (runs * n)


def bench_sweep(repeats):
    res = []
    best(lambda: res.append(sweep.sweep()), repeats)
    t = min(r["seconds"] for r in res)
    return t, t / (6 * 5 * 1000 * 1000)


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
    args = ap.parse_args(argv)
    from driftfmu.simulations.gaussian import fmu_paths
    fmu_paths(args.fmu_dir)

    t_batch = bench_batch(args.runs, args.n, args.repeats)
    t_batch4 = bench_batch(args.runs, args.n, args.repeats, P4)
    t_sweep_wall, t_sweep = bench_sweep(args.repeats)
    t_fmu, t_fmu_step = bench_fmu(args.fmu_n, args.fmu_dir, args.repeats)
    t_fp, diff = bench_filterpy(args.filterpy_n, args.repeats)

    print("machine: %s, %s, %d cores, Python %s, NumPy %s"
          % (platform.machine(), cpu(), os.cpu_count() or 0, platform.python_version(),
             np.__version__))
    print("%-58s %12s" % ("", "ns/sample-run"))
    print("%-58s %12.1f" % ("batch engine, 1 process (%d runs x %d samples)"
                            % (args.runs, args.n), t_batch * 1e9))
    print("%-58s %12.1f" % ("batch engine, 1 process, a4 = %g (general sensor; %.2f x)"
                            % (P4["a4"], t_batch4 / t_batch), t_batch4 * 1e9))
    print("%-58s %12.1f" % ("batch engine, default sweep on %d cores (wall, %.2f s)"
                            % (batch.workers_default(), t_sweep_wall), t_sweep * 1e9))
    print("%-58s %12.0f" % ("FMU path, 1 run of %d samples (instantiation included)"
                            % args.fmu_n, t_fmu * 1e9))
    print("%-58s %12.0f" % ("FMU path, per additional sample (runs of %d and %d)"
                            % (args.fmu_n, 5 * args.fmu_n), t_fmu_step * 1e9))
    print("%-58s %12.0f" % ("filterpy ExtendedKalmanFilter loop (%d samples)"
                            % args.filterpy_n, t_fp * 1e9))
    print("filterpy / batch (1 process): %.0f x   filterpy / batch (sweep wall): %.0f x   "
          "(goal >= 300)" % (t_fp / t_batch, t_fp / t_sweep))
    print("FMU (per additional sample) / batch (1 process): %.0f x;  filterpy and the batch "
          "engine agree on the final drift estimates to %.1e V" % (t_fmu_step / t_batch, diff))


if __name__ == "__main__":
    main()
