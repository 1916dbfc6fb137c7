"""Internal (not a stable API; use driftfmu.sweep instead).

The letter's Figs. 2 and 3: drift error over a grid of a2 and R, averaged over many runs.

For every grid point ``(a2_i, R_j)`` and run ``r`` (FMU seed ``seed + r``, the same seeds at every
grid point) the Gaussian chain runs ``n`` samples; the final-sample drift estimates of EKF1-3 are
compared with the three drift references (``docs/method.md``, section 4):

- empirical ``z̄_n - a0`` (the letter's reference; carries the linear term ``a1 x̄_n``),
- realised ``a2 (1/n) sum x_k^2`` (simulation only),
- expected ``a2 Q / (1 - A^2)``.

The whole grid runs as one batch (``len(a2) * len(R) * runs`` runs on the leading axis, ``a2``
and ``R`` per run), split over local workers (threads in the compiled kernel, else processes)
or a Dask cluster.

The general sensor (issue 16, docs/method.md section 9): ``a3, a4, B`` and the known input
``drive, Qu, Xu, fu`` are shared by every grid point; the realised drift is then
``mean(a2 x^2 + a3 x^3 + a4 x^4)`` and the expected ``a2 E[x^2] + a4 E[x^4]``
(:func:`driftfmu.models.chain.expected_drift`).  Several values of ``a4`` make the sweep one
over ``a4`` instead of ``a2`` (``a2`` then takes one value): the grid is ``(a4, R)``, the
figures show the errors against ``a4`` beside the drift ``a2 sigma_x^2 + 3 a4 sigma_x^4``
(eq. 5 for ``u = 0``).
"""
import functools
import time

import numpy as np

from driftfmu.models import chain, errors, excitation, parameters
from driftfmu.simulations import batch, budget, checks, output
from driftfmu.simulations.errors import UsageError

DEFAULT_A2 = tuple(np.logspace(-3, -0.5, 6))
DEFAULT_R = tuple(np.logspace(-6, -2, 5))
ESTIMATORS = ("ekf1", "ekf2", "ekf3")
REFERENCES = ("empirical", "realised", "expected")
#: Columns of ``sweep.csv``.
CSV_COLUMNS = (("a2", "R", "dc_expected")
               + tuple("mean_dc_%s" % e for e in ESTIMATORS)
               + tuple("mae_%s_%s" % (e, ref) for e in ESTIMATORS for ref in REFERENCES))
#: Columns of ``sweep.csv`` of a sweep over ``a4``.
A4_CSV_COLUMNS = ("a4",) + CSV_COLUMNS[1:]
#: The general model's parameters shared by all grid points, off by default (``a4`` may also
#: be a grid), and the sensor's slow errors (issue 42: chain.SENSOR_ERRORS_OFF).
GENERAL_OFF = dict(dict(a3=0.0, a4=0.0, B=0.0, drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0,
                        fu=0.0), **chain.SENSOR_ERRORS_OFF)


def check_grid(name, values):
    """The grid of ``name`` as a 1-D float array; ValueError when empty, not numbers (text
    and True/False are not, though NumPy reads them as such) or out of range."""
    items = values if isinstance(values, np.ndarray) else np.asarray(values, dtype=object)
    for v in np.ravel(items):
        if not checks.is_number(v):
            checks.refuse([checks.number_problem(name, v)])
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    if arr.ndim != 1 or arr.size == 0:
        raise UsageError("the %s grid is empty; allowed: one or more values of %s"
                         % (name, name))
    batch.check_parameters({name: arr})
    values, counts = np.unique(arr, return_counts=True)
    if (counts > 1).any():
        raise UsageError("the %s grid has %s more than once; allowed: distinct values of %s"
                         % (name, ", ".join("%r" % float(v) for v in values[counts > 1]), name))
    return arr


def sweep(a2=None, R=DEFAULT_R, a0=0.0, a1=1.0, Q=0.01, A=0.0, runs=1000, n=1000,
          seed=1, Ts=1e-3, engine="batch", scheduler=None, client=None, workers=None,
          chunk=None, fmu_dir="build/fmus", out=None, plot=True, progress=None, a4=0.0,
          **general):
    """Run the grid; return the arrays of ``sweep.npz`` and the rows of ``sweep.csv``.

    Parameters
    ----------
    a2, R : sequence of float
        The grid (defaults: ``logspace(-3, -0.5, 6)`` and ``logspace(-6, -2, 5)``; in a sweep
        over ``a4``, ``a2`` is one value, default 0.01).
    a4 : float or sequence of float
        The sensor's 4th-order coefficient: one value for every grid point (default 0, the
        letter's sensor), or several: a sweep over ``(a4, R)`` at one ``a2``.
    **general
        The general model's ``a3, B, drive, Qu, Xu, fu`` (the names and checks of
        ``driftfmu run gaussian``) and the sensor's slow errors and range (``bias_on,
        random_walk, bias_gm, tau_gm, flicker, tau_min, tau_max, d_inf, E_tau, theta, T, T0,
        kT_bias, kT_scale, range, bits``: docs/method.md section 10), shared by every grid
        point; off by default.
    a0, a1, Q, A, Ts : float
        The other model parameters, shared by all grid points (the letter: a1 = 1, Q = 0.01).
    runs, n, seed : int
        Monte-Carlo runs per grid point, samples per run; run ``r`` uses FMU seed ``seed + r``.
    engine : {"batch", "fmu"}
        The batch engine, or the FMUs co-simulated run by run.
    scheduler : str, optional
        Address of a Dask scheduler; by default local workers (``workers``, one per core by
        default: threads for runs in the compiled kernel, processes otherwise).
    out : path, optional
        Folder for ``sweep.npz``, ``sweep.csv``, ``fig2.png``, ``fig3.png`` (all or none).
    progress : callable, optional
        Called with the number of runs done.

    Returns
    -------
    dict
        ``grid_a2`` (``grid_a4`` in a sweep over ``a4``), ``grid_R``, ``grid_dc1``,
        ``grid_dc2``, ``grid_dc3``, ``grid_zbar``, ``grid_x2bar`` (each ``(len(a2), len(R),
        runs)``; with the general sensor also ``grid_dc_realised``), ``axis`` (``"a2"`` or
        ``"a4"``), ``table`` (CSV columns -> arrays of one value per grid point) and
        ``seconds`` (wall time of the runs).
    """
    checks.check_keywords("sweep()", general, checks.keywords_of(sweep, GENERAL_OFF))
    a4s = check_grid("a4", a4)
    axis = "a4" if a4s.size > 1 else "a2"
    if a2 is None:
        a2 = DEFAULT_A2 if axis == "a2" else parameters.PARAMETERS["a2"].default
    a2 = check_grid("a2", a2)
    if axis == "a4" and a2.size > 1:
        raise UsageError("a sweep over a4 (%d values) and a2 (%d values) at once is not "
                         "allowed; allowed: several values of a2 with one of a4, or several "
                         "of a4 with one of a2" % (a4s.size, a2.size))
    R = check_grid("R", R)
    batch.check_runs(runs)
    batch.check_parameters(dict(a0=a0, a1=a1, Q=Q, A=A, n=n, Ts=Ts))
    on = {k: v for k, v in general.items() if v != GENERAL_OFF[k]}
    batch.check_parameters(on)
    checks.refuse(errors.problems(on))
    checks.refuse([checks.choice_problem("engine", engine, batch.ENGINES)])
    xs = a4s if axis == "a4" else a2
    points = len(xs) * len(R)
    # before anything is allocated: a sweep too large for the machine is refused, not killed
    budget.check_sweep(points, runs, n, workers, out, announce=False, api=True, engine=engine)
    seeds1 = batch.run_seeds(seed, runs)
    seeds = np.tile(seeds1, points)
    per_run = {axis: np.repeat(xs, len(R) * runs), "R": np.tile(np.repeat(R, runs), len(xs))}
    common = dict(a0=a0, a1=a1, Q=Q, A=A, Ts=Ts, **on)
    if axis == "a4":
        common["a2"] = float(a2[0])
    elif a4s[0] != 0.0:
        common["a4"] = float(a4s[0])
    higher = "a4" in common or axis == "a4" or on.get("a3", 0.0) != 0.0
    if engine == "fmu":
        from driftfmu.simulations.gaussian import fmu_paths
        fmu_paths(fmu_dir)  # build once here, not in every worker
    total = len(seeds)
    if chunk is None:
        chunk = default_chunk(total, engine, workers)
    tasks = batch.make_tasks(n, seeds, per_run, common, chunk=chunk, engine=engine,
                             fmu_dir=fmu_dir)
    t0 = time.perf_counter()
    res = batch.gather(batch.run_tasks(tasks, scheduler=scheduler, client=client,
                                       workers=workers, progress=progress,
                                       meanwhile=_import_matplotlib if out is not None and plot
                                       else None))
    seconds = time.perf_counter() - t0
    shape = (len(xs), len(R), runs)
    result = {"grid_%s" % axis: xs, "grid_R": R,
              "grid_dc1": res["final_dc_ekf1"].reshape(shape),
              "grid_dc2": res["final_dc_ekf2"].reshape(shape),
              "grid_dc3": res["final_dc_ekf3"].reshape(shape),
              "grid_zbar": res["final_zbar"].reshape(shape),
              "grid_x2bar": res["final_x2bar"].reshape(shape)}
    if higher:  # mean(a2 x^2 + a3 x^3 + a4 x^4), not a2 mean(x^2)
        result["grid_dc_realised"] = res["final_dc_realised"].reshape(shape)
    result["axis"] = axis
    result["parameters"] = dict(a0=a0, a1=a1, Q=Q, A=A, runs=runs, n=n, seed=seed, Ts=Ts,
                                engine=engine, **on)
    if axis == "a4":
        result["parameters"]["a2"] = common["a2"]
    elif "a4" in common:
        result["parameters"]["a4"] = common["a4"]
    result["table"] = table(result, Q=Q, A=A)
    result["seconds"] = seconds
    if out is not None:
        write(out, result, plot=plot)
    return result


def _import_matplotlib():
    """matplotlib (Agg) and pyplot imported while the workers run: the figures start at once."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401


def default_chunk(total, engine, workers=None):
    """Runs per task: a few tasks per worker (batch), a few runs per task (FMU)."""
    if engine == "fmu":
        return max(1, min(8, total // (4 * batch.workers_default())))
    w = batch.workers_default() if workers is None else max(1, workers)
    return max(256, min(batch.CHUNK, -(-total // (2 * w))))


def references(result, Q, A):
    """The three drift references per grid point and run, each ``(len(a2), len(R), runs)``
    (``len(a4)`` first in a sweep over ``a4``): the empirical ``z̄ - a0``, the realised
    ``a2 mean(x^2)`` (``mean(a2 x^2 + a3 x^3 + a4 x^4)`` with the general sensor) and the
    expected :func:`driftfmu.models.chain.expected_drift` (``a2 Q / (1 - A^2)`` for the
    letter's sensor, ``+ 3 a4 sigma_x^4`` with ``a4``, the input's moments with ``B u``)."""
    axis = result.get("axis", "a2")
    p = dict(GENERAL_OFF, **{k: v for k, v in result.get("parameters", {}).items()
                             if k in GENERAL_OFF or k == "a2"})
    shape = result["grid_dc1"].shape
    if axis == "a4":
        a2, a4 = p["a2"], result["grid_a4"][:, None, None]
    else:
        a2, a4 = result["grid_a2"][:, None, None], p["a4"]
    expected = chain.expected_drift(a2, excitation.GAUSSIAN, A=A, Q=Q, a4=a4, B=p["B"],
                                    drive=p["drive"], Qu=p["Qu"], Xu=p["Xu"], fu=p["fu"],
                                    Ts=result.get("parameters", {}).get("Ts", 1e-3))
    realised = (result["grid_dc_realised"] if "grid_dc_realised" in result
                else a2 * result["grid_x2bar"])
    return {"empirical": result["grid_zbar"],
            "realised": realised,
            "expected": np.broadcast_to(expected, shape)}


def table(result, Q, A):
    """``sweep.csv`` as columns: one row per grid point, ``a2`` (``a4``) slowest."""
    refs = references(result, Q, A)
    axis = result.get("axis", "a2")
    xs = result["grid_" + axis]
    nx, nR = len(xs), len(result["grid_R"])
    cols = {axis: np.repeat(xs, nR), "R": np.tile(result["grid_R"], nx),
            "dc_expected": refs["expected"][:, :, 0].ravel()}
    for e, key in zip(ESTIMATORS, ("grid_dc1", "grid_dc2", "grid_dc3")):
        dc = result[key]
        cols["mean_dc_%s" % e] = dc.mean(axis=2).ravel()
        for ref in REFERENCES:
            cols["mae_%s_%s" % (e, ref)] = np.abs(dc - refs[ref]).mean(axis=2).ravel()
    return cols


def write(out, result, plot=True):
    """Write ``sweep.npz``, ``sweep.csv`` and the two figures into ``out``, all or none."""
    arrays = {k: v for k, v in result.items() if k.startswith("grid_")}
    with output.staged(out) as stage:
        np.savez(stage / "sweep.npz", **arrays)
        axis = result.get("axis", "a2")
        output.write_csv(stage / "sweep.csv", result["table"],
                         A4_CSV_COLUMNS if axis == "a4" else CSV_COLUMNS)
        if plot:
            p = result["parameters"]
            subtitle = "%s, %s, A = %g; %d runs of n = %d samples per point" % (
                output.value_text("a1", p["a1"]), output.value_text("Q", p["Q"]), p["A"],
                p["runs"], p["n"])
            fixed = output.general_text({k: p[k] for k in GENERAL_OFF
                                         if k in p and k != axis})
            if axis != "a2":
                fixed = ", ".join([output.value_text("a2", p["a2"])] + ([fixed] if fixed else []))
            if fixed:
                subtitle = "%s, %s" % (fixed, subtitle)
            figures = [(stage / "fig2.png", "ekf1"), (stage / "fig3.png", "ekf3")]
            # one scale for both figures: EKF1 against EKF3 at a glance
            ylim = grid_limits(result)
            drawn = {k: result[k] for k in ("table", "grid_" + axis, "grid_R", "axis",
                                            "parameters")}
            output.draw_beside(*[functools.partial(plot_grid, path, drawn, est, subtitle, ylim)
                                 for path, est in figures])


def grid_limits(result, estimators=("ekf1", "ekf3")):
    """Log-axis y limits that hold every curve of Figs. 2 and 3 (the errors of both
    estimators against both references, and the drift): the two figures share one scale."""
    t = result["table"]
    values = [np.asarray(t["dc_expected"], dtype=float)]
    for est in estimators:
        for ref in ("realised", "empirical"):
            values.append(np.asarray(t["mae_%s_%s" % (est, ref)], dtype=float))
    v = np.concatenate([np.ravel(a) for a in values])
    v = v[np.isfinite(v) & (v > 0)]
    if not v.size:
        return None
    return float(v.min()) / 1.6, float(v.max()) * 1.6


#: Line styles of the R curves, with hollow markers that shrink from curve to curve: curves
#: that lie on each other still show as concentric rings in distinct dashes.
R_STYLES = ("-", "--", ":", "-.", (0, (6, 2, 1, 2, 1, 2)))


def plot_grid(path, result, estimator, subtitle, ylim=None):
    """Mean absolute error of one estimator over the (a2, R) grid: against the realised drift
    (left) and against the letter's empirical drift ``z̄ - a0`` (right), one line per R (its
    own colour, dash and hollow marker, the markers shrinking from curve to curve, so lines
    that coincide stay distinguishable as concentric rings), and the drift itself (dotted
    black).  ``ylim``: the y range (:func:`grid_limits`, shared by Figs. 2 and 3).  Legend
    beside the axes."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = result["table"]
    axis = result.get("axis", "a2")
    a2, R = result["grid_" + axis], result["grid_R"]
    # a sweep over a4 starts at the letter's a4 = 0: a linear a4 axis; an a2 grid with 0 or
    # negative values: a symmetric log axis, linear within the smallest |a2| but 0, which shows
    # them all (a log axis dropped them, with a warning)
    xscale = "linear" if axis == "a4" else "log" if (a2 > 0).all() else "symlog"
    nonzero = np.abs(a2[a2 != 0])
    xscale_kw = {"linthresh": float(nonzero.min()) if nonzero.size else 1.0} \
        if xscale == "symlog" else {}
    # the drift and the errors are 0 at a2 = 0: a log y axis for what is above 0, a linear one
    # when nothing is (matplotlib's log axis cannot show that, and warns)
    yscale = "log" if ylim is not None else "linear"
    general = any(k in result.get("parameters", {}) for k in GENERAL_OFF)
    drift_label = ("drift a2σx²+3a4σx⁴" if axis == "a4" else "the expected drift"
                   if general else "the drift a2·Q/(1−A²)")
    markers = "osD^vPX*"
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), sharex=True)
    for ax, ref in zip(axes, ("realised", "empirical")):
        mae = t["mae_%s_%s" % (estimator, ref)].reshape(len(a2), len(R))
        for j, r in enumerate(R):
            if yscale == "log" and not (mae[:, j] > 0).any():
                continue  # 0 everywhere (a2 = 0 alone, no noise): nothing a log axis shows
            ax.plot(a2, mae[:, j], marker=markers[j % len(markers)],
                    ms=4.0 + 2.5 * (len(R) - 1 - j), mfc="none", mew=1.3,
                    ls=R_STYLES[j % len(R_STYLES)], lw=1.3,
                    color=plt.cm.viridis(0.9 * j / max(1, len(R) - 1)),
                    label="R = %.0e V²" % r)
        drift = t["dc_expected"].reshape(len(a2), len(R))[:, 0]
        if yscale == "linear" or (drift > 0).any():  # (the drift is 0 at a2 = 0)
            ax.plot(a2, drift, color="k", ls=":", lw=1.2, label=drift_label)
        ax.set_xscale(xscale, **xscale_kw)
        ax.set_yscale(yscale)
        ax.set_xlabel("a2 [V/g²]" if axis == "a2" else "a4 [V/g⁴]")
        ax.set_ylabel("mean |%s − %s drift| [V]" % (estimator.upper(), ref))
        ax.set_title("%s against the %s drift%s" % (
            estimator.upper(), ref, " " + output.drift_labels(
                dict(result.get("parameters", {}), **({"a4": 1} if axis == "a4" else {})))[0]
            if ref == "realised" else " z̄ − a0 (the letter's)"), fontsize=10)
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.grid(True, which="major", alpha=0.3)
        ax.minorticks_off()  # log-axis minor ticks are most of the drawing time
        if yscale == "log":
            output.decade_labels(ax.yaxis)
        if xscale == "log":
            output.decade_labels(ax.xaxis)
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9, frameon=False)
    output.caption(fig, "Fig. %s of the letter%s: mean absolute error of %s over a grid of %s "
                   "and R (%s); the y axes are those of Fig. %s, to compare EKF1 with EKF3"
                   % ("2" if estimator == "ekf1" else "3",
                      "" if axis == "a2" else ", over the 4th-order term a4 instead of a2",
                      estimator.upper(), axis, subtitle,
                      "3" if estimator == "ekf1" else "2"), width=130)
    fig.subplots_adjust(left=0.07, right=0.84, bottom=0.12, top=0.84, wspace=0.3)
    output.savefig(fig, path, dpi=110)
    plt.close(fig)


# -- command line ---------------------------------------------------------------------------
def add_cli(groups):
    """``driftfmu sweep``."""
    from driftfmu.simulations import cli
    p = groups["top"].add_parser(
        "sweep", help="drift error over a grid of a2 and R, many runs per point "
                      "(the letter's Figs. 2 and 3)")
    p.add_argument("--a2", type=cli.param_type("a2"), nargs="+", default=None,
                   metavar="A2", help="grid of a2 [V/g2] (default: logspace(-3, -0.5, 6); "
                                      "0.01 in a sweep over --a4)")
    p.add_argument("--R", type=cli.param_type("R"), nargs="+", default=list(DEFAULT_R),
                   metavar="R", help="grid of R [V2]; allowed: R > 0 "
                                     "(default: logspace(-6, -2, 5))")
    p.add_argument("--a4", type=cli.param_type("a4"), nargs="+", default=[0.0], metavar="A4",
                   help="the sensor's 4th-order coefficient [V/g4], one value for every grid "
                        "point, or a grid of several: a sweep over a4 and R at one --a2 "
                        "(default 0.01), the figures against a4 (default: 0)")
    cli.add_params(p, ("a0", "a1", "A", "Q", "runs", "n", "seed", "Ts"), runs=1000, n=1000)
    cli.add_params(p, GENERAL_CLI)
    batch.add_engine_options(p)
    cli.add_out(p, "results/sweep")
    cli.add_fmu_dir(p)
    p.set_defaults(func=cmd_sweep)


#: The general model's options of ``driftfmu sweep`` besides ``--a4``.
GENERAL_CLI = ("a3", "B", "drive", "Qu", "Xu", "fu") + tuple(chain.SENSOR_ERRORS_OFF)


def cmd_sweep(args):
    """``driftfmu sweep``: :func:`driftfmu.sweep`."""
    import driftfmu
    a2 = args.a2
    if a2 is None:
        a2 = list(DEFAULT_A2) if len(args.a4) == 1 else [parameters.PARAMETERS["a2"].default]
    points = max(len(a2), len(args.a4)) * len(args.R)
    total = points * args.runs
    budget.check_sweep(points, args.runs, args.n, args.workers, args.out, engine=args.engine)
    t0 = time.perf_counter()
    from driftfmu.simulations import cli
    desc = "sweep (%s engine)" % args.engine
    with cli.progress(total, desc, "run", monitor=False) as update:
        res = driftfmu.sweep(a2=a2, R=args.R, a0=args.a0, a1=args.a1, Q=args.Q, A=args.A,
                    runs=args.runs, n=args.n, seed=args.seed, Ts=args.Ts, engine=args.engine,
                    scheduler=args.scheduler, workers=args.workers, fmu_dir=args.fmu_dir,
                    out=args.out, progress=update, a4=args.a4,
                    **{k: getattr(args, k) for k in GENERAL_CLI})
    wall = time.perf_counter() - t0
    print_table(res)
    sample_runs = total * args.n
    print("%d x %d grid, %d runs of n = %d: %.3g sample-runs in %.2f s (%.0f ns per "
          "sample-run; %.2f s wall with writing)" % (len(res["grid_" + res["axis"]]),
                                                     len(args.R), args.runs,
                                                     args.n, sample_runs, res["seconds"],
                                                     1e9 * res["seconds"] / sample_runs, wall))
    print("wrote %s/sweep.npz, sweep.csv, fig2.png, fig3.png" % args.out)


def print_table(res):
    """Mean absolute error of EKF1 and EKF3 per grid point against the three references."""
    t = res["table"]
    axis = res.get("axis", "a2")
    print("%9s %9s %10s | %-30s | %-30s" % (axis, "R", "expected", "EKF1 mean |error| [V] vs",
                                            "EKF3 mean |error| [V] vs"))
    print("%9s %9s %10s | %9s %9s %9s  | %9s %9s %9s"
          % ("[V/g^2]" if axis == "a2" else "[V/g^4]", "[V^2]", "drift [V]", "realised",
             "empirical", "expected", "realised", "empirical", "expected"))
    for i in range(len(t[axis])):
        print("%9.3g %9.3g %10.3g | %9.3g %9.3g %9.3g  | %9.3g %9.3g %9.3g"
              % (t[axis][i], t["R"][i], t["dc_expected"][i],
                 t["mae_ekf1_realised"][i], t["mae_ekf1_empirical"][i],
                 t["mae_ekf1_expected"][i], t["mae_ekf3_realised"][i],
                 t["mae_ekf3_empirical"][i], t["mae_ekf3_expected"][i]))
