"""Internal (not a stable API; use driftfmu.experiment_dual_axis instead).

Drift from axis cross-correlation: the dual-axis experiment (the letter's conclusion, built).

The chain Excitation (two axes) -> Accelerometer (``dual = 1``: ``z_x = a0 + a1 x + a2 x^2 +
bx x y + v_x``, ``z_y`` likewise with ``by``) -> DualDriftEstimator (both outputs, EKF1), with a
single-axis DriftEstimator on each output beside it (EKF1 on that axis's polynomial, blind to the
cross term), co-simulated through the FMUs over two sweeps:

* ``dphi``: sinusoids ``x = X sin(theta + phi)``, ``y = Xy sin(theta + phi - dphi)`` at the same
  frequency, ``dphi`` from 0 to pi; both filters use the harmonic process model at ``f``;
  ``E[x y] = X Xy cos(dphi) / 2``;
* ``rho``: 2-D Gauss-Markov excitation with process-noise correlation ``rho`` from -0.9 to 0.9;
  both filters use the Gauss-Markov model (the dual one knows ``rho``);
  ``E[x y] = rho sigma_x sigma_y``.

At every sweep point ``runs`` runs (run ``r`` with FMU seed ``seed + r``) give, per axis, the true
drift of the run (realised: ``a2 mean(x^2) + bx mean(x y)`` over its samples, which for whole
periods of the sinusoid is the closed form), the EKF1 estimates at the last sample and their
errors.  Per point and axis: the mean errors ``err_single``, ``err_dual`` with their standard
errors over the runs, the cross-term drift ``cross = b mean(x y)`` that the single-axis
estimator cannot see, and the drift's ``scale = |a2| E[x^2] + |b| max |E[x y]|`` (``|a2| X^2/2 +
|bx| X Xy / 2`` for the sinusoids, ``|a2| sigma_x^2 + |bx| sigma_x sigma_y`` for the Gaussian
sweep), against which the errors are judged, so a drift that crosses zero is not judged by a
relative error.

Engines: ``fmu`` (default) co-simulates every run with the five FMU instances and checks every
recorded output against :func:`driftfmu.models.dualaxis.simulate` on the same seeds, bit for bit;
``batch`` runs many runs at once through the same models/ functions
(:func:`driftfmu.simulations.batch.dual_simulate`), for Monte-Carlo error bars.
"""
import math
import os
import time
from concurrent.futures import as_completed
from pathlib import Path

import numpy as np

from driftfmu.models import drift, dualaxis, excitation, harmonic, parameters
from driftfmu.simulations import batch, output
from driftfmu.simulations.gaussian import ValidationError
from driftfmu.simulations.sinusoidal import check_frequency

#: The five instances of the chain and their FMUs.
INSTANCES = {"Excitation": "Excitation", "Accelerometer": "Accelerometer",
             "DualDriftEstimator": "DualDriftEstimator", "SingleX": "DriftEstimator",
             "SingleY": "DriftEstimator"}
CONNECTIONS = (("Excitation", "x", "Accelerometer", "x"),
               ("Excitation", "y", "Accelerometer", "y"),
               ("Accelerometer", "z", "DualDriftEstimator", "z_x"),
               ("Accelerometer", "z_y", "DualDriftEstimator", "z_y"),
               ("Accelerometer", "z", "SingleX", "z"),
               ("Accelerometer", "z_y", "SingleY", "z"))
#: Recorded FMU outputs -> the column of :func:`driftfmu.models.dualaxis.simulate` they must equal.
RECORD = {"Excitation": {"x": "x", "y": "y"},
          "Accelerometer": {"z": "z_x", "z_y": "z_y"},
          "DualDriftEstimator": {v: v for v in ("x_hat", "y_hat", "P_xx", "P_xy", "P_yy",
                                                "dc_ekf1_x", "dc_ekf2_x", "dc_ekf3_x",
                                                "dc_ekf1_y", "dc_ekf2_y", "dc_ekf3_y",
                                                "z_comp_x", "z_comp_y")},
          "SingleX": {"dc_ekf1": "single_dc_ekf1_x"},
          "SingleY": {"dc_ekf1": "single_dc_ekf1_y"}}

#: Settings of the experiment (sensor, drive, filter); every one can be given to
#: :func:`run_dual_axis`.
DEFAULTS = dict(n=4000, Ts=1e-3, f=150.0, X=1.0, Xy=0.8, phi=0.3, A=0.0, Q=0.01, Qy=0.01,
                a0=0.0, a1=1.0, a2=0.01, bx=0.01, R=1e-4, a0y=0.0, a1y=1.0, a2y=0.008,
                by=-0.006, Ry=1e-4, Qh=parameters.PARAMETERS["Qh"].default)
#: Sweep ranges: dphi over [0, pi] (sinusoids), rho over [-0.9, 0.9] (Gaussian).
DPHI_RANGE = (0.0, math.pi)
RHO_RANGE = (-0.9, 0.9)
POINTS = 9
RUNS = {"fmu": 4, "batch": 1000}
#: The dual-axis estimator's error must stay within this fraction of the drift's scale.
DUAL_BAND = 0.02
#: The single-axis estimator's error must equal ``-cross`` within this many standard errors
#: (or within ``DUAL_BAND`` of the scale, the accuracy the dual-axis estimator is held to).
SE_FACTOR = 3.0
SWEEPS = ("dphi", "rho")
#: CSV columns: sweep (1 dphi, 2 rho), its parameter, axis (1 x, 2 y), the true (realised)
#: and expected drift, the single-axis and dual-axis EKF1 estimates (means over the runs) [V].
CSV_COLUMNS = ("sweep", "parameter", "axis", "dc_true", "dc_expected", "dc_single", "dc_dual")


def sweep_values(sweep, points):
    """The ``points`` parameter values of ``sweep``, ends included."""
    lo, hi = DPHI_RANGE if sweep == "dphi" else RHO_RANGE
    return [lo + (hi - lo) * i / (points - 1) for i in range(points)]


def start_values(sweep, value, s):
    """``(excitation, sensor, estimator)`` start values (seeds not set) of one sweep point."""
    sensor = {k: s[k] for k in ("a0", "a1", "a2", "bx", "R", "a0y", "a1y", "a2y", "by", "Ry")}
    if sweep == "dphi":
        ex = dict(kind=excitation.SINUSOIDAL, X=s["X"], Xy=s["Xy"], f=s["f"], phi=s["phi"],
                  phiy=s["phi"] - value)
        es = dict(sensor, process=harmonic.HARMONIC, f=s["f"], Qh=s["Qh"], P0=s["X"] ** 2 / 2,
                  P0y=s["Xy"] ** 2 / 2)
    else:
        ex = dict(kind=excitation.GAUSSIAN, A=s["A"], Q=s["Q"], Qy=s["Qy"], rho=value)
        es = dict(sensor, process=harmonic.GAUSS_MARKOV, A=s["A"], Q=s["Q"], Qy=s["Qy"],
                  rho=value, P0=s["Q"] / (1 - s["A"] ** 2), P0y=s["Qy"] / (1 - s["A"] ** 2))
    return ex, dict(sensor, dual=1, noise=1), es


def moments(sweep, value, s):
    """``(E[x^2], E[x y], E[y^2], max |E[x y]|)`` of a sweep point."""
    if sweep == "dphi":
        Exx, Eyy = s["X"] ** 2 / 2, s["Xy"] ** 2 / 2
        Exy = dualaxis.cross_moment(excitation.SINUSOIDAL, X=s["X"], Xy=s["Xy"], dphi=value)
    else:
        Exx, Eyy = (excitation.stationary_variance(excitation.GAUSSIAN, A=s["A"], Q=q)
                    for q in (s["Q"], s["Qy"]))
        Exy = dualaxis.cross_moment(excitation.GAUSSIAN, Q=s["Q"], Qy=s["Qy"], rho=value,
                                    A=s["A"])
    return Exx, Exy, Eyy, math.sqrt(Exx * Eyy)


def check_settings(s, points, runs, engine):
    """UsageError naming every bad setting and what is allowed."""
    from driftfmu.simulations import checks
    checks.refuse([checks.number_problem(k, v) for k, v in s.items()
                   if k in parameters.PARAMETERS]
                  + [checks.choice_problem("engine", engine, tuple(RUNS)),
                     checks.count_problem("points", points, 2),
                     checks.count_problem("runs", runs, 1)])
    check_frequency(s["f"], s["Ts"])


def fmu_paths(fmu_dir, backend="python"):
    """Paths of the FMUs the chain needs in ``fmu_dir`` (``backend`` python: the pythonfmu
    FMUs; native: their FMI 2.0 C twins in ``fmu_dir/native/fmi2``), by instance; built first
    when any is missing."""
    from driftfmu.simulations.gaussian import check_backend
    check_backend(backend)
    if backend == "native":
        from driftfmu.fmu_src.native_build import native_fmu_paths
        paths = native_fmu_paths(fmu_dir, 2)
    else:
        fmu_dir = Path(fmu_dir)
        paths = {n: fmu_dir / ("%s.fmu" % n) for n in set(INSTANCES.values())}
        if not all(p.is_file() for p in paths.values()):
            from driftfmu.fmu_src.builder import build_fmus, check_fmu_folder
            check_fmu_folder(fmu_dir, sorted(p.name for p in paths.values() if not p.is_file()))
            build_fmus(fmu_dir)
    return {inst: str(paths[fmu]) for inst, fmu in INSTANCES.items()}


# -- workers ------------------------------------------------------------------------------------

def _fmu_task(task):
    """Worker: co-simulate one run of one sweep point; the recorded columns by models/ name."""
    from driftfmu.simulations.gaussian import master
    paths, ex, sp, es, n, Ts, seed, backend = task
    cosimulate = master(backend)
    start = {"Excitation": dict(ex, Ts=Ts, seed=seed), "Accelerometer": dict(sp, Ts=Ts, seed=seed),
             "DualDriftEstimator": dict(es, Ts=Ts),
             "SingleX": dict(dualaxis.single_values(dualaxis.estimator_values(**es), 1), Ts=Ts),
             "SingleY": dict(dualaxis.single_values(dualaxis.estimator_values(**es), 2), Ts=Ts)}
    raw = cosimulate(paths, CONNECTIONS, n, Ts, start_values=start,
                     record={k: list(v) for k, v in RECORD.items()})
    return {col: raw["%s.%s" % (inst, var)] for inst, names in RECORD.items()
            for var, col in names.items()}


def _finals_of_columns(cols):
    """The finals and realised moments of one FMU run (as :func:`driftfmu.models.dualaxis.simulate`)."""
    mxx = mxy = myy = 0.0
    for k, (x, y) in enumerate(zip(cols["x"], cols["y"]), start=1):
        mxx = drift.running_mean(mxx, x * x, k)
        mxy = drift.running_mean(mxy, x * y, k)
        myy = drift.running_mean(myy, y * y, k)
    out = {"final_" + c: v[-1] for c, v in cols.items()}
    out.update(mean_xx=mxx, mean_xy=mxy, mean_yy=myy)
    return out


# -- the experiment -----------------------------------------------------------------------------

def run_dual_axis(out=None, points=POINTS, runs=None, engine="fmu", seed=1, fmu_dir="build/fmus",
                  workers=None, scheduler=None, progress=None, plot=True, backend="python",
                  **settings):
    """Run both sweeps; with ``out`` write ``dual_axis.csv``, ``dual_axis.json`` and
    ``dual_axis.png`` (all or none).  Returns the summary (the JSON's content).

    Parameters
    ----------
    points : int
        Sweep points of each sweep (ends included).
    runs : int, optional
        Runs per sweep point (default 4 with the FMU engine, 1000 with the batch engine).
    engine : {"fmu", "batch"}
        Co-simulate every run through the FMUs (checked against models/ bit for bit), or run
        them at once through models/ (Monte-Carlo error bars), in chunks of
        ``batch.CHUNK`` runs on local worker processes or, with ``scheduler``, on a Dask cluster
        (:func:`driftfmu.simulations.batch.run_tasks`).
    backend : {"python", "native"}
        With the FMU engine: the pythonfmu FMUs or their native (C, FMI 2.0) twins, which give
        the same bits (the check against models/ holds for both).
    settings
        Overrides of :data:`DEFAULTS` (``n``, ``Ts``, ``f``, ``X``, ``Xy``, ``phi``, ``A``,
        ``Q``, ``Qy``, the sensor's ``a0 a1 a2 bx R a0y a1y a2y by Ry`` and ``Qh``).

    Raises
    ------
    ValueError
        A bad setting (before anything runs).
    ValidationError
        An FMU output differs from models/ run directly (nothing is written).
    """
    unknown = set(settings) - set(DEFAULTS)
    if unknown:
        from driftfmu.simulations import checks
        checks.check_keywords("run_dual_axis()", settings,
                              checks.keywords_of(run_dual_axis, DEFAULTS))
    s = dict(DEFAULTS, **settings)
    runs = RUNS.get(engine, 1) if runs is None else runs
    check_settings(s, points, runs, engine)
    seeds = batch.run_seeds(seed, runs)
    t0 = time.perf_counter()
    grid = [(sw, v) for sw in SWEEPS for v in sweep_values(sw, points)]
    workers = workers or os.cpu_count() or 1
    n, Ts = s["n"], s["Ts"]
    finals = {}
    worst = 0.0
    done = 0
    if engine == "fmu":
        paths = fmu_paths(fmu_dir, backend)
        with batch.process_pool(workers, "driftfmu.simulations.dual_axis") as pool:
            futs = {pool.submit(_fmu_task, (paths, *start_values(sw, v, s), n, Ts, int(sd), backend)):
                    (i, r) for i, (sw, v) in enumerate(grid) for r, sd in enumerate(seeds)}
            from driftfmu.simulations.cli import start_work
            start_work(progress, min(workers, len(futs)))  # the runs' pace counts from here
            cols = {}
            for fut in as_completed(futs):
                cols[futs[fut]] = fut.result()
                done += 1
                if progress is not None:
                    progress(done)
        from driftfmu.simulations.cli import start_phase
        start_phase(progress, "validation (FMU outputs against models/)", len(grid), "point")
        for i, (sw, v) in enumerate(grid):
            ex, sp, es = start_values(sw, v, s)
            ref = batch.dual_simulate(n, seeds, ex, sp, es, Ts, record=dualaxis.COLUMNS)
            for r in range(runs):
                for c, values in cols[(i, r)].items():
                    d = float(np.max(np.abs(np.asarray(values) - ref[c][r])))
                    worst = max(worst, d) if d == d else math.inf
            one = [_finals_of_columns(cols[(i, r)]) for r in range(runs)]
            finals[i] = {k: np.array([o[k] for o in one]) for k in one[0]}
            if progress is not None:
                progress(i + 1)
        if worst != 0.0:
            raise ValidationError("FMU outputs differ from models/ run directly by %.3g; "
                                  "allowed: equal bit for bit" % worst)
    else:
        chunks = [seeds[lo:lo + batch.CHUNK] for lo in range(0, runs, batch.CHUNK)]
        tasks = []
        for sw, v in grid:
            ex, sp, es = start_values(sw, v, s)
            tasks += [{"engine": "dual", "n": n, "seeds": ch, "record": (),
                       "kwargs": dict(excitation_values=ex, sensor_values=sp,
                                      estimator_values=es, Ts=Ts)} for ch in chunks]
        parts = batch.run_tasks(tasks, scheduler=scheduler, workers=workers, progress=progress)
        for i in range(len(grid)):
            finals[i] = batch.gather(parts[i * len(chunks):(i + 1) * len(chunks)])
    wall = time.perf_counter() - t0

    rows = [summarise_point(sw, v, s, finals[i]) for i, (sw, v) in enumerate(grid)]
    rows = [r for pair in rows for r in pair]
    summary = {
        "settings": dict(s, points=points, runs=runs, engine=engine, seed=seed,
                         seeds="run r uses FMU seed seed + r", dphi_range=list(DPHI_RANGE),
                         rho_range=list(RHO_RANGE),
                         filters={"dphi": "harmonic oscillators at f (Qh), P0 = X^2/2, "
                                          "P0y = Xy^2/2",
                                  "rho": "Gauss-Markov (A, Q, Qy, rho of the excitation), "
                                         "P0 = Q/(1-A^2), P0y = Qy/(1-A^2)"}),
        "definitions": {
            "dc_true": "realised drift of the run: a2 mean(x^2) + b mean(x y) over its samples "
                       "(per axis; mean over the runs)",
            "err_single": "mean over the runs of (single-axis EKF1 - dc_true) at the last sample",
            "err_dual": "mean over the runs of (dual-axis EKF1 - dc_true) at the last sample",
            "se_single, se_dual": "standard errors of those means over the runs (0 for 1 run)",
            "cross": "b mean(x y): the cross-term drift the single-axis estimator cannot see",
            "scale": "|a2| E[x^2] + |b| max|E[x y]| (|a2| X^2/2 + |b| X Xy/2 for the sinusoids, "
                     "|a2| sigma_x^2 + |b| sigma_x sigma_y for the Gaussian sweep)",
            "single_off_by_cross": "|err_single + cross| <= %g se_single or <= %g scale"
                                   % (SE_FACTOR, DUAL_BAND),
            "dual_within_band": "|err_dual| <= %g scale" % DUAL_BAND},
        "points": rows,
        "claims": {"single_off_by_cross_everywhere": all(r["single_off_by_cross"] for r in rows),
                   "dual_within_band_everywhere": all(r["dual_within_band"] for r in rows),
                   "max_dual_error_over_scale": max(abs(r["err_dual"]) / r["scale"]
                                                    for r in rows),
                   "max_single_error_over_scale": max(abs(r["err_single"]) / r["scale"]
                                                      for r in rows)},
        "validation": ({"reference": "models.dualaxis.simulate, same seeds (batch engine)",
                        "max_abs_diff": worst, "bit_identical": worst == 0.0}
                       if engine == "fmu" else None),
        "wall_time_s": wall, "workers": workers,
        "backend": backend if engine == "fmu" else None,
    }
    if out is not None:
        with output.staged(out) as stage:
            table = {c: [] for c in CSV_COLUMNS}
            for r in rows:
                table["sweep"].append(1 + SWEEPS.index(r["sweep"]))
                table["axis"].append(1 if r["axis"] == "x" else 2)
                for c in CSV_COLUMNS[3:] + ("parameter",):
                    table[c].append(r[c])
            output.write_csv(stage / "dual_axis.csv", table, CSV_COLUMNS)
            output.write_json(stage / "dual_axis.json", summary)
            if plot:
                plot_dual_axis(stage / "dual_axis.png", summary)
    return summary


def summarise_point(sweep, value, s, f):
    """The two rows (axes x, y) of one sweep point from the runs' finals ``f`` (arrays)."""
    ax, ay = dualaxis.axes(s)
    Exx, Exy, Eyy, Exy_max = moments(sweep, value, s)
    expected = dualaxis.expected_drift(ax, ay, Exx, Exy, Eyy)
    scales = dualaxis.scale(ax, ay, Exx, Exy_max, Eyy)
    runs = len(f["mean_xy"])
    out = []
    for i, (name, a, mown) in enumerate((("x", ax, f["mean_xx"]), ("y", ay, f["mean_yy"]))):
        true = a.a2 * mown + a.b * f["mean_xy"]
        single = f["final_single_dc_ekf1_%s" % name]
        dual = f["final_dc_ekf1_%s" % name]
        es, ed = single - true, dual - true
        row = {"sweep": sweep, "parameter": value, "axis": name, "runs": runs,
               "dc_true": float(np.mean(true)), "dc_expected": expected[i],
               "dc_single": float(np.mean(single)), "dc_dual": float(np.mean(dual)),
               "err_single": float(np.mean(es)), "se_single": _se(es),
               "err_dual": float(np.mean(ed)), "se_dual": _se(ed),
               "cross": float(np.mean(a.b * f["mean_xy"])), "cross_expected": a.b * Exy,
               "scale": scales[i]}
        miss = abs(row["err_single"] + row["cross"])
        row["single_miss_over_se"] = miss / row["se_single"] if row["se_single"] else math.inf
        row["single_off_by_cross"] = bool(miss <= SE_FACTOR * row["se_single"]
                                          or miss <= DUAL_BAND * row["scale"])
        row["dual_within_band"] = bool(abs(row["err_dual"]) <= DUAL_BAND * row["scale"])
        out.append(row)
    return out


def _se(values):
    values = np.asarray(values, dtype=float)
    return float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else 0.0


def plot_dual_axis(path, summary):
    """Top: the single-axis EKF1's error [mV] against the cross-term drift ``-b mean(xy)`` it
    cannot see; bottom: the dual-axis EKF1's error in % of the scale, with a note of the
    largest error (error bar included) and the 2 % criterion, far outside the range shown; left the ``dphi`` sweep, right the ``rho`` sweep; error bars:
    standard errors over the runs."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = summary["points"]
    st = summary["settings"]
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex="col")
    styles = {"x": dict(color="C0", marker="o"), "y": dict(color="C3", marker="s")}
    for col, sweep in enumerate(SWEEPS):
        top, bottom = axes[0, col], axes[1, col]
        for axis in ("x", "y"):
            rs = [r for r in rows if r["sweep"] == sweep and r["axis"] == axis]
            p = np.array([r["parameter"] for r in rs])
            st_ = styles[axis]
            top.plot(p, [-1e3 * r["cross"] for r in rs], color=st_["color"], lw=1.0, ls="--",
                     label="-b mean(xy), %s axis (what a single-axis filter misses)" % axis)
            top.errorbar(p, [1e3 * r["err_single"] for r in rs],
                         yerr=[1e3 * r["se_single"] for r in rs], ls="none", ms=6,
                         mfc="none", capsize=3, **st_, label="single-axis EKF1, %s axis" % axis)
            shift = 0.012 * (p[-1] - p[0]) * (1 if axis == "y" else -1)
            bottom.errorbar(p + shift, [100 * r["err_dual"] / r["scale"] for r in rs],
                            yerr=[100 * r["se_dual"] / r["scale"] for r in rs], capsize=3,
                            ms=5, lw=1.0, **st_, label="dual-axis EKF1, %s axis" % axis)
        worst = max(abs(r["err_dual"]) + r["se_dual"] for r in rows if r["sweep"] == sweep)
        worst = 100 * worst / min(r["scale"] for r in rows if r["sweep"] == sweep)
        bottom.set_ylim(-2.2 * worst, 2.2 * worst)  # the note above the largest point
        bottom.text(0.02, 0.95, "every point within ±%.2g %% of the scale (error bars\n"
                    "included); the criterion is ±%g %%" % (worst, 100 * DUAL_BAND),
                    transform=bottom.transAxes, fontsize=8, va="top")
        for ax in (top, bottom):
            ax.axhline(0.0, color="k", lw=0.6)
            ax.grid(True, alpha=0.3)
        top.set_ylabel("single-axis error [mV]")
        bottom.set_ylabel("dual-axis error [% of the scale]")
        if sweep == "dphi":
            bottom.set_xlabel("phase difference dphi [rad]")
            top.set_title("sinusoids, X = %g g, Xy = %g g, f = %g Hz" % (st["X"], st["Xy"],
                                                                        st["f"]), fontsize=9)
        else:
            bottom.set_xlabel("process-noise correlation rho [1]")
            top.set_title("Gauss-Markov, Q = %g g², Qy = %g g², A = %g" % (st["Q"], st["Qy"],
                                                                           st["A"]), fontsize=9)
    fig.suptitle("Drift from axis cross-correlation: bx = %g, by = %g V/g², a2 = %g, a2y = %g "
                 "V/g²; %d runs per point (%s engine), n = %d"
                 % (st["bx"], st["by"], st["a2"], st["a2y"], st["runs"], st["engine"], st["n"]),
                 fontsize=10)
    handles, labels = [], []
    for ax in (axes[0, 0], axes[1, 0]):
        h, l = ax.get_legend_handles_labels()
        handles += h
        labels += l
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False)
    output.layout(fig, rect=(0, 0.12, 1, 0.96))
    output.savefig(fig, path, dpi=120)
    plt.close(fig)


# -- command line -------------------------------------------------------------------------------

def add_cli(groups):
    """``driftfmu experiment dual-axis``."""
    from driftfmu.simulations import checks, cli
    g = groups["experiment"].add_parser(
        "dual-axis", help="drift from axis cross-correlation: dual-axis vs single-axis EKF1 "
        "over a dphi sweep (sinusoids) and a rho sweep (Gaussian)")
    g.add_argument("--points", type=checks.count_option("points", 2), default=POINTS,
                   help="points of each sweep, ends included (default: %d)" % POINTS)
    g.add_argument("--runs", type=checks.count_option("runs", 1), default=None,
                   help="runs per sweep point (default: %d with the fmu engine, %d with the "
                        "batch engine)" % (RUNS["fmu"], RUNS["batch"]))
    g.add_argument("--engine", type=checks.choice_option("engine", tuple(RUNS)),
                   choices=tuple(RUNS), default="fmu",
                   help="fmu: every run co-simulated through the FMUs and checked against "
                        "models/ bit for bit (default); batch: many runs at once through "
                        "models/, for Monte-Carlo error bars")
    cli.add_params(g, ("n", "Ts", "f", "X", "Xy", "phi", "A", "Q", "Qy", "a2", "bx", "R",
                       "a2y", "by", "Ry", "seed"),
                   **{k: DEFAULTS[k] for k in ("n", "Ts", "f", "X", "Xy", "phi", "A", "Q", "Qy",
                                               "a2", "bx", "R", "a2y", "by", "Ry")})
    g.add_argument("--workers", type=checks.count_option("workers", 1), default=None,
                   help="parallel processes (default: the number of cores)")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS", type=batch.scheduler_address,
                   help="batch engine: run on the Dask distributed cluster at ADDRESS (e.g. "
                        "tcp://host:8786; needs the extra driftfmu[dask]); default: local "
                        "worker processes")
    cli.add_out(g, "results/dual_axis")
    cli.add_fmu_dir(g)
    cli.add_backend(g)
    g.set_defaults(func=_cmd)


def _cmd(args):
    """``driftfmu experiment dual-axis``: :func:`driftfmu.experiment_dual_axis`."""
    import driftfmu
    from driftfmu.simulations import budget, cli
    runs = RUNS[args.engine] if args.runs is None else args.runs
    total = 2 * args.points * runs
    settings = {k: getattr(args, k) for k in ("n", "Ts", "f", "X", "Xy", "phi", "A", "Q", "Qy",
                                              "a2", "bx", "R", "a2y", "by", "Ry")}
    check_settings(dict(DEFAULTS, **settings), args.points, runs, args.engine)
    budget.check_dual_axis(args.points, runs, args.n, args.engine, args.workers, args.out,
                           args.backend, announce=True)
    with cli.progress(total, "runs", "run", monitor=False) as update:
        s = driftfmu.experiment_dual_axis(
                          out=args.out, points=args.points, runs=runs, engine=args.engine,
                          seed=args.seed, fmu_dir=args.fmu_dir, workers=args.workers,
                          backend=args.backend,
                          scheduler=args.scheduler, progress=update, **settings)
    print("wrote %s/dual_axis.csv, dual_axis.json, dual_axis.png" % args.out)
    print("%-5s %9s %4s | %11s %11s | %12s %12s | %11s %s"
          % ("sweep", "dphi|rho", "axis", "dc_true mV", "cross mV", "single err", "dual err",
             "scale mV", "(errors / scale)"))
    for r in s["points"]:
        print("%-5s %9.4f %4s | %11.5f %11.5f | %+11.4f%% %+11.4f%% | %11.5f"
              % (r["sweep"], r["parameter"], r["axis"], 1e3 * r["dc_true"], 1e3 * r["cross"],
                 100 * r["err_single"] / r["scale"], 100 * r["err_dual"] / r["scale"],
                 1e3 * r["scale"]))
    c = s["claims"]
    print("single-axis EKF1 off by the cross-term drift b mean(xy) at every point: %s; "
          "dual-axis EKF1 within %g %% of the scale at every point: %s (worst %.3f %%)"
          % ("yes" if c["single_off_by_cross_everywhere"] else "NO", 100 * DUAL_BAND,
             "yes" if c["dual_within_band_everywhere"] else "NO",
             100 * c["max_dual_error_over_scale"]))
    if s["validation"]:
        print("validation: FMU outputs equal models/ bit for bit: %s"
              % ("yes" if s["validation"]["bit_identical"] else "NO"))
    print("wall time %.1f s on %d worker(s), %s engine" % (s["wall_time_s"], s["workers"],
                                                         args.engine))
