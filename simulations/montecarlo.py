"""Internal (not a stable API; use driftfmu.montecarlo instead).

Monte-Carlo populations of whole trajectories: the letter's Fig. 1 claims over many runs.

``driftfmu montecarlo gaussian`` runs the Gaussian chain (Sec. III) ``runs`` times, run ``r`` with
FMU seed ``seed + r``, and keeps every trajectory; ``driftfmu montecarlo sinusoidal`` does the
same for ``x_k = X sin(2 pi f t_k + phi_r)`` with a random phase per run (the first draw of
stream ``STREAM_PHASE`` under the run's seed), estimated with the same scalar Gauss-Markov EKF
(filter model ``A = 0``, ``Q = X^2 / 2`` by default).

The summary gives, per estimator, the fraction of runs that have settled by sample 250 (within
10 % of the reference from that sample on, as in :func:`driftfmu.simulations.gaussian.settled_from`) and
the EKF1-EKF2 gap ``10 log10(dc1 / dc2)`` at the last sample over the runs.

``--summary-only`` has the workers send back, per run, only the settling samples and the final
drifts (:func:`reduce_chunk`), and whole trajectories of the first :data:`FIGURE_RUNS` runs for
the figure: the same summary, with memory and disk that grow with the runs, not with runs x n.
"""
import math
import time

import numpy as np

from driftfmu.models import _ops, chain, drift, errors, excitation
from driftfmu.simulations import batch, checks, output
from driftfmu.simulations.gaussian import GENERAL_OFF, SETTLE_BAND, plot_title, settle_hold
from driftfmu.simulations.sinusoidal import check_frequency
from driftfmu.simulations.errors import UsageError

#: The letter's claim: EKF1 and EKF2 settle in under 250 samples.
SETTLE_BY = 250
#: The references the estimates settle against, in the order of the summary and its table
#: (both kinds of population): the realised drift (the simulation's truth), then the
#: empirical drift ``z̄ - a0`` (the letter's).
REFERENCES = ("realised", "empirical")
RECORD = ("x", "z", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_empirical", "dc_realised")
#: ``montecarlo.npz`` keys: name in the file -> trajectory name.
GAUSSIAN_KEYS = {"fig1_x": "x", "fig1_z": "z", "fig1_dc1": "dc_ekf1", "fig1_dc2": "dc_ekf2",
                 "fig1_dc3": "dc_ekf3", "fig1_dc_empirical": "dc_empirical",
                 "fig1_dc_realised": "dc_realised"}
SINE_KEYS = {"sine_x": "x", "sine_z": "z", "sine_dc1": "dc_ekf1", "sine_dc2": "dc_ekf2",
             "sine_dc3": "dc_ekf3", "sine_dc_empirical": "dc_empirical",
             "sine_dc_realised": "dc_realised"}


def settled_from(estimate, reference, band=SETTLE_BAND):
    """First sample (1-based) from which ``|estimate - reference| <= band |reference|`` holds to
    the end, per run (rows of ``(runs, n)`` arrays); ``n + 1`` when it does not hold for the last
    :func:`driftfmu.simulations.gaussian.settle_hold` samples (the run has not shown that it
    stays inside).

    The batch form of :func:`driftfmu.simulations.gaussian.settled_from` (which returns None for
    ``n + 1``).
    """
    estimate, reference = np.atleast_2d(estimate), np.atleast_2d(reference)
    n = estimate.shape[1]
    outside = np.abs(estimate - reference) > band * np.abs(reference)
    # last sample outside the band (0 when none), from the reversed rows
    last_out = np.where(outside.any(axis=1), n - np.argmax(outside[:, ::-1], axis=1), 0)
    return np.where(last_out > n - settle_hold(n), n + 1, last_out + 1)


#: Runs whose whole trajectories ``--summary-only`` still keeps, for the figure.
FIGURE_RUNS = 1000


def reduce_chunk(traj, task):
    """What a worker sends back under ``--summary-only``: per run, the settling sample of each
    estimator against each reference and the final EKF1 and EKF2 drifts; whole trajectories
    only of the first ``task["keep"]`` runs of the chunk (the figure's)."""
    out = {"settled_%s_%s" % (ref, e): settled_from(traj["dc_%s" % e], traj["dc_%s" % ref])
           for ref in ("realised", "empirical") for e in ("ekf1", "ekf2", "ekf3")}
    out["final_dc_ekf1"] = traj["dc_ekf1"][:, -1].copy()
    out["final_dc_ekf2"] = traj["dc_ekf2"][:, -1].copy()
    keep = task["keep"]
    out.update({name: traj[name][:keep].copy() for name in RECORD})
    return out


def summarise(traj, references, a1=None, Q=None, R=None, A=None, settle_by=SETTLE_BY,
              band=SETTLE_BAND):
    """Fractions of runs settled by ``settle_by`` per estimator and reference; EKF1-EKF2 gap.

    ``traj`` holds the trajectories ``(runs, n)``, or (``--summary-only``, from
    :func:`reduce_chunk`) ``settled_<ref>_<estimator>`` and ``final_dc_ekf1/2`` per run, with
    ``n`` the trajectories' length."""
    reduced = "settled_realised_ekf1" in traj
    n = int(traj["dc_ekf1"].shape[1])
    runs = int(traj["final_dc_ekf1"].shape[0] if reduced else traj["dc_ekf1"].shape[0])
    summary = {"runs": runs, "n": n,
               "settle_by": settle_by, "band": band, "settled_fraction": {},
               "median_settled_from": {}}
    for ref in references:
        r = traj["dc_%s" % ref]
        summary["settled_fraction"][ref] = {}
        summary["median_settled_from"][ref] = {}
        for e in ("ekf1", "ekf2", "ekf3"):
            s = (traj["settled_%s_%s" % (ref, e)] if reduced
                 else settled_from(traj["dc_%s" % e], r, band))
            # n + 1: not settled by the last sample, whatever settle_by is
            summary["settled_fraction"][ref][e] = float(np.mean((s <= settle_by) &
                                                                (s <= summary["n"])))
            summary["median_settled_from"][ref][e] = float(np.median(s))
    d1, d2 = ((traj["final_dc_ekf1"], traj["final_dc_ekf2"]) if reduced
              else (traj["dc_ekf1"][:, -1], traj["dc_ekf2"][:, -1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.asarray(d1 / d2, dtype=float)
        of_means = float(np.mean(d1) / np.mean(d2))
    gaps = _db(ratios[np.isfinite(ratios) & (ratios > 0.0)])
    summary["ekf1_ekf2_gap_db"] = {"mean": float(np.mean(gaps)) if gaps.size else math.nan,
                                   "std": float(np.std(gaps)) if gaps.size else math.nan,
                                   "max_abs": float(np.max(np.abs(gaps))) if gaps.size
                                   else math.nan,
                                   "of_means": _db_of(of_means)}
    if A == 0.0 and None not in (a1, Q, R):
        summary["ekf1_ekf2_gap_db"]["expected"] = drift.expected_gap_db(a1, Q, R)
    return summary


def _db(ratios):
    """``10 log10`` of an array of finite positive ratios, by models._ops.log (arithmetic
    only): the same bits on every machine, where NumPy's log10 of an array takes the CPU's
    SIMD code (AVX-512 and AVX2 differ in the last bits)."""
    return 10.0 * (_ops.log(ratios) / errors.LN10) if ratios.size else ratios


def _db_of(ratio):
    """``10 log10`` of one ratio: :func:`_db`'s for a finite positive one; ``-inf`` for 0,
    ``inf`` for inf, nan for a negative one or nan (as log10)."""
    if ratio > 0.0 and ratio < math.inf:
        return 10.0 * (_ops.log(ratio) / errors.LN10)
    return -math.inf if ratio == 0.0 else math.inf if ratio == math.inf else math.nan


#: The general model's parameters of the sinusoidal population: the sensor's (a sinusoidal
#: state has no input term) and its slow errors (issue 42).
SINE_GENERAL = ("a3", "a4") + tuple(chain.SENSOR_ERRORS_OFF)


def general_on(general, allowed=tuple(GENERAL_OFF), function=None):
    """The general model's parameters given and not off (``a3, a4, B, drive, Qu, Xu, fu``, as
    ``driftfmu run gaussian`` takes them), checked; UsageError for an unknown name (naming
    every keyword of ``function`` too) or a value out of range."""
    if function is None:
        checks.check_keywords("montecarlo()", general, tuple(allowed))
    else:
        checks.check_keywords("%s()" % function.__name__, general,
                              checks.keywords_of(function, allowed))
    on = {k: v for k, v in general.items() if v != GENERAL_OFF[k]}
    batch.check_parameters(on)
    checks.refuse(errors.problems(on))
    return on


def _run(n, runs, seed, per_run, common, engine, scheduler, client, workers, fmu_dir,
         progress, backend="python", summary_only=False):
    seeds = batch.run_seeds(seed, runs)
    per_run = {k: v(seeds) if callable(v) else v for k, v in per_run.items()}
    checks.refuse([checks.choice_problem("engine", engine, batch.ENGINES)])
    if engine == "fmu":
        from driftfmu.simulations.gaussian import fmu_paths
        fmu_paths(fmu_dir, backend)
        chunk = max(1, min(8, runs // (4 * batch.workers_default())))
    else:
        w = batch.workers_default() if workers is None else max(1, workers)
        chunk = max(64, min(batch.CHUNK, -(-runs // (2 * w))))
    tasks = batch.make_tasks(n, seeds, per_run, common, record=RECORD, chunk=chunk,
                             engine=engine, fmu_dir=fmu_dir, backend=backend)
    if summary_only:  # the workers send back summaries, and the figure's first runs whole
        lo = 0
        for task in tasks:
            task["reduce"] = "driftfmu.simulations.montecarlo:reduce_chunk"
            task["keep"] = max(0, min(len(task["seeds"]), FIGURE_RUNS - lo))
            lo += len(task["seeds"])
    t0 = time.perf_counter()
    res = batch.gather(batch.run_tasks(tasks, scheduler=scheduler, client=client,
                                       workers=workers, progress=progress))
    seconds = time.perf_counter() - t0
    from driftfmu.simulations.cli import start_phase
    start_phase(progress, "the summary, the files and the figure", 0, "step")
    return res, seconds


def montecarlo_gaussian(runs=1000, n=1000, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4,
                        seed=1, Ts=1e-3, x0=0.0, P0=None, engine="batch", scheduler=None,
                        client=None, workers=None, fmu_dir="build/fmus", out=None, plot=True,
                        progress=None, backend="python", summary_only=False, **general):
    """``runs`` Gaussian runs of ``n`` samples (the letter's Fig. 1 as a population).

    ``general``: the general model's ``a3, a4`` (sensor and filter), ``B`` and the known
    input ``drive, Qu, Xu, fu`` (docs/method.md section 9), the names and checks of
    ``driftfmu run gaussian``; off by default (the letter's runs, same bits).  The batch engine
    runs them in the compiled kernel or NumPy (same results); the realised and expected drift
    are then the general ones, ``mean(a2 x^2 + a3 x^3 + a4 x^4)`` and ``a2 E[x^2] + a4
    E[x^4]``.

    Returns the ``montecarlo.npz`` arrays (``fig1_x``, ``fig1_z``, ``fig1_dc1``, ``fig1_dc2``,
    ``fig1_dc3``, ``fig1_dc_empirical``, ``fig1_dc_realised``, each ``(runs, n)``), ``summary``
    (settled fractions against the realised and empirical drift, EKF1-EKF2 gap) and
    ``seconds``.  With ``out``: ``montecarlo.npz``, ``summary.json`` and ``fig1.png``.
    """
    batch.check_runs(runs)
    params = dict(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, n=n, seed=seed, Ts=Ts, x0=x0, P0=P0)
    batch.check_parameters(params)
    on = general_on(general, function=montecarlo_gaussian)
    common = dict(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, Ts=Ts, x0=x0, P0=P0, **on)
    res, seconds = _run(n, runs, seed, {}, common, engine, scheduler, client, workers,
                        fmu_dir, progress, backend, summary_only)
    result = {key: res[name] for key, name in GAUSSIAN_KEYS.items()}
    result.update(_per_run(res))
    # the gap's closed form is the letter's quadratic sensor's
    summary = summarise(res, REFERENCES, a1=a1, Q=Q, R=R, A=None if on else A)
    summary["parameters"] = dict(params, runs=runs, engine=engine,
                                 P0=batch.default_P0(A, Q) if P0 is None else P0, **on)
    summary["dc_expected"] = chain.expected_drift(a2, excitation.GAUSSIAN, A=A, Q=Q, **{
        k: v for k, v in on.items() if k in ("a4", "B", "drive", "Qu", "Xu", "fu")}, Ts=Ts)
    summary["seconds"] = seconds
    summary["trajectories_kept"] = int(result["fig1_dc1"].shape[0])
    result["summary"] = summary
    if out is not None:
        _write(out, result, GAUSSIAN_KEYS, "fig1.png", plot_title(
            "Drift estimation error over %s" % _runs_text(runs, summary), on, a1=a1, a2=a2,
            Q=Q, R=R, A=A, n=n, runs=runs), plot, on)
    return result


def montecarlo_sinusoidal(runs=1000, n=1000, a0=0.0, a1=1.0, a2=0.01, R=1e-4, X=1.0, f=150.0,
                          Ts=1e-3, seed=1, A=0.0, Q=None, engine="batch", scheduler=None,
                          client=None, workers=None, fmu_dir="build/fmus", out=None, plot=True,
                          progress=None, backend="python", summary_only=False, **general):
    """``runs`` sinusoidal runs ``x_k = X sin(2 pi f (k-1) Ts + phi_r)`` of ``n`` samples.

    ``general``: the sensor's ``a3, a4`` (sensor and filter; :data:`SINE_GENERAL`), batch
    engine only (the FMU engine's sinusoidal run has the letter's sensor); the expected drift
    is then ``a2 X^2 / 2 + 3 a4 X^4 / 8``.

    ``phi_r`` is :func:`driftfmu.simulations.batch.sine_phase` of the run's seed; the filter is the
    scalar Gauss-Markov EKF with ``A`` (default 0) and ``Q`` (default ``X^2 / 2``).  Returns
    ``sine_dc1`` ``(runs, n)`` and the other ``sine_*`` trajectories, ``sine_phi``,
    ``summary`` and ``seconds``; with ``out``: ``montecarlo.npz``, ``summary.json`` and
    ``sine.png``.
    """
    batch.check_runs(runs)
    if Q is None:
        Q = excitation.stationary_variance(excitation.SINUSOIDAL, X=X)
    params = dict(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, n=n, seed=seed, Ts=Ts, X=X, f=f)
    batch.check_parameters(params)
    on = general_on(general, SINE_GENERAL, montecarlo_sinusoidal)
    if on and engine == "fmu":  # before anything is built or run
        raise UsageError("the FMU engine runs the sinusoidal state with the letter's sensor "
                         "only, not with %s; allowed: engine 'batch' for these, or %s = 0"
                         % (", ".join("%s = %r" % kv for kv in sorted(on.items())),
                            " = ".join(sorted(on))))
    check_frequency(f, Ts)
    common = dict(a0=a0, a1=a1, a2=a2, R=R, Ts=Ts, X=X, f=f, kind=excitation.SINUSOIDAL,
                  filter_A=A, filter_Q=Q, **on)
    res, seconds = _run(n, runs, seed, {"phi": batch.sine_phase}, common, engine, scheduler,
                        client, workers, fmu_dir, progress, backend, summary_only)
    result = {key: res[name] for key, name in SINE_KEYS.items()}
    result.update(_per_run(res))
    result["sine_phi"] = batch.sine_phase(batch.run_seeds(seed, runs))
    summary = summarise(res, REFERENCES)
    summary["parameters"] = dict(params, runs=runs, engine=engine,
                                 filter="Gauss-Markov EKF, A = %g, Q = %g" % (A, Q), **on)
    summary["dc_expected"] = chain.expected_drift(a2, excitation.SINUSOIDAL, X=X,
                                                  a4=on.get("a4", 0.0))
    summary["seconds"] = seconds
    summary["trajectories_kept"] = int(result["sine_dc1"].shape[0])
    result["summary"] = summary
    if out is not None:
        _write(out, result, SINE_KEYS, "sine.png",
               "Drift estimation error over %s: sinusoidal state X = %g g at f = %g Hz "
               "(random phase per run), %s, %s%s, R = %g V², n = %d at Ts = %g s; "
               "Gauss-Markov filter A = %g, Q = %g g²"
               % (_runs_text(runs, summary), X, f, output.value_text("a1", a1),
                  output.value_text("a2", a2),
                  "".join(", " + output.value_text(k, on[k]) for k in ("a3", "a4") if k in on),
                  R, n, Ts, A, Q), plot, on)
    return result


def _per_run(res):
    """The per-run summaries of a ``--summary-only`` run (``settled_<ref>_<estimator>``,
    ``final_dc_ekf1/2``), for montecarlo.npz; empty otherwise."""
    if "settled_realised_ekf1" not in res:
        return {}
    return {k: res[k] for k in res if k.startswith("settled_")
            or k in ("final_dc_ekf1", "final_dc_ekf2")}


def _runs_text(runs, summary):
    kept = summary["trajectories_kept"]
    return ("%d runs" % runs if kept == runs
            else "%d runs (the figure: the first %d of them)" % (runs, kept))


def _write(out, result, keys, figure, title, plot=True, general=None):
    arrays = {k: v for k, v in result.items() if isinstance(v, np.ndarray)}
    with output.staged(out) as stage:
        np.savez(stage / "montecarlo.npz", **arrays)
        output.write_json(stage / "summary.json", result["summary"])
        prefix = next(iter(keys)).split("_")[0]
        if plot:
            plot_population(stage / figure, result, prefix, title, general)


def plot_population(path, result, prefix, title, general=None):
    """The letter's Fig. 1 over a population: per sample, the median (thick) and the 5 % and
    95 % points (thin, same colour and dash) over the runs of each estimator's error against
    the realised drift in percent (top; grey: the 10 % band of "settled"); EKF1 over the
    realised drift in mV (middle, linear: the realised drift wide and grey underneath, EKF1 thin
    on top, so both show); the empirical drift ``z̄ - a0`` in mV on its own linear scale
    (bottom: for a Gaussian state its spread is the linear term ``a1 x̄``, far larger than the
    drift).  Sample axis logarithmic; the dotted line is k = 250, the
    letter's "converged in under 250 samples"; legends beside the axes.  ``general``: the
    general sensor's parameters that are on (``a3, a4``: the realised drift's terms)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    dcs = [result["%s_dc%d" % (prefix, i)] for i in (1, 2, 3)]
    n = dcs[0].shape[1]
    k = np.arange(1, n + 1)
    styles = (("C0", "-", 2.0), ("C1", (0, (3, 3)), 1.4), ("C2", "-", 1.4))
    fig, axes = plt.subplots(3, 1, figsize=(10, 10), sharex=True,
                             gridspec_kw={"height_ratios": [3, 2, 2]})
    realised = result["%s_dc_realised" % prefix]
    empirical = result["%s_dc_empirical" % prefix]
    start = min(n - 1, max(10, n // 100))

    def band(ax, values, color, ls, lw, label, zorder=2, alpha=1.0):
        lo, med, hi = np.nanpercentile(values, [5, 50, 95], axis=0)
        ax.plot(k, med, color=color, ls=ls, lw=lw, label=label, zorder=zorder, alpha=alpha)
        name = label.split(" median")[0]
        ax.plot(k, lo, color=color, ls=ls, lw=0.8, alpha=0.9, zorder=zorder,
                label="_%s 5 %%" % name)
        ax.plot(k, hi, color=color, ls=ls, lw=0.8, alpha=0.9, zorder=zorder,
                label="_%s 95 %%" % name)
        return [lo[start:], hi[start:]]

    top, middle, bottom = axes
    span = []
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, (dc, (color, ls, lw)) in enumerate(zip(dcs, styles), start=1):
            span += band(top, 100.0 * (dc - realised) / np.abs(realised), color, ls, lw,
                         "EKF%d median" % i)
    top.axhspan(-100 * SETTLE_BAND, 100 * SETTLE_BAND, color="0.85", zorder=0,
                label="±%g %% (settled)" % (100 * SETTLE_BAND))
    top.set_ylim(*output._limits(span, include=(0.0,)))
    top.set_ylabel("EKF − realised [% of realised]")
    # EKF1 and the realised drift, linear in mV: the realised drift wide and grey underneath,
    # EKF1 thin on top, so both show where they agree
    span = band(middle, 1e3 * realised, "0.55", "-", 4.0, "realised median (wide, grey)",
                zorder=2, alpha=0.7)
    span += band(middle, 1e3 * dcs[0], "C0", "-", 1.4, "EKF1 median (thin, on top)", zorder=3)
    middle.set_ylim(*output._limits(span, include=(0.0,)))
    middle.set_ylabel("drift [mV]")
    # the empirical drift, linear in mV on its own scale (for a Gaussian state its spread is
    # the linear term a1 x̄, far larger than the drift), with the realised drift for scale
    span = band(bottom, 1e3 * empirical, "C3", "-", 1.6, "empirical z̄ − a0 median")
    bottom.plot(k, np.nanmedian(1e3 * realised, axis=0), color="k", ls=(0, (1, 1.5)), lw=1.2,
                label="realised median")
    bottom.set_ylim(*output._limits(span, include=(0.0,)))
    bottom.set_ylabel("drift [mV]")
    for ax in axes:
        ax.axhline(0.0, color="k", lw=0.6)
        if SETTLE_BY <= n:
            ax.axvline(SETTLE_BY, color="0.3", lw=0.9, ls=":")
            ax.annotate("k = %d" % SETTLE_BY, (SETTLE_BY, 1.0),
                        xycoords=("data", "axes fraction"), xytext=(-3, -12), ha="right",
                        textcoords="offset points", fontsize=8, color="0.3")
        ax.grid(True, which="major", alpha=0.3)
        output.log_sample_axis(ax)
        handles, labels = ax.get_legend_handles_labels()
        handles.append(Line2D([], [], color="0.4", lw=0.8))
        labels.append("thin: 5 % and 95 % of runs")
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9,
                  frameon=False)
    realised_label = output.drift_labels(general)[0]
    middle.set_title("EKF1 beside the realised drift %s, linear" % realised_label, fontsize=10)
    top.set_title("estimation error against the realised drift %s (simulation only)"
                  % realised_label, fontsize=10)
    bottom.set_title("the empirical drift z̄ − a0 (the letter's reference), on its own linear "
                     "scale", fontsize=10)
    axes[-1].set_xlabel("sample k (log scale)")
    axes[-1].set_xlim(1, max(n, 2))
    output.caption(fig, title)
    output.layout(fig)
    output.savefig(fig, path, dpi=120)
    plt.close(fig)


# -- command line ---------------------------------------------------------------------------
def add_cli(groups):
    """``driftfmu montecarlo gaussian`` and ``driftfmu montecarlo sinusoidal``."""
    from driftfmu.simulations import cli
    mc = groups["top"].add_parser("montecarlo", help="many runs of whole trajectories "
                                  "(the letter's Fig. 1 claims over a population)")
    sub = mc.add_subparsers(dest="experiment", metavar="EXPERIMENT", parser_class=type(mc))
    sub.required = True
    g = sub.add_parser("gaussian", help="Gaussian excitation (Sec. III, Fig. 1)")
    cli.add_params(g, ("a0", "a1", "a2", "A", "Q", "R", "runs", "n", "seed", "Ts"), runs=1000,
                   n=1000)
    cli.add_params(g, cli.GENERAL)
    g.add_argument("--P0", type=cli.param_type("P0"), default=None, metavar="P0",
                   help="initial error variance of the filter [g2] (default: Q / (1 - A^2))")
    batch.add_engine_options(g)
    add_summary_only(g)
    cli.add_out(g, "results/montecarlo/gaussian")
    cli.add_fmu_dir(g)
    cli.add_backend(g)
    g.set_defaults(func=cmd_gaussian)

    s = sub.add_parser("sinusoidal", help="x = X sin(2 pi f t + phi), random phase per run")
    cli.add_params(s, ("a0", "a1", "a2", "R", "X", "f", "runs", "n", "seed", "Ts"), runs=1000,
                   n=1000)
    cli.add_params(s, SINE_GENERAL)
    s.add_argument("--A", type=cli.param_type("A"), default=0.0, metavar="A",
                   help="the filter's state transition (default: 0, a white-state model)")
    s.add_argument("--Q", type=cli.param_type("Q"), default=None, metavar="Q",
                   help="the filter's process noise variance [g2] (default: X^2 / 2)")
    batch.add_engine_options(s)
    add_summary_only(s)
    cli.add_out(s, "results/montecarlo/sinusoidal")
    cli.add_fmu_dir(s)
    cli.add_backend(s)
    s.set_defaults(func=cmd_sinusoidal)


def add_summary_only(p):
    p.add_argument("--summary-only", action="store_true",
                   help="keep per-run summaries (settling samples, final drifts) instead of "
                        "every run's trajectories, and the trajectories of the first %d runs "
                        "for the figure: memory and disk grow with --runs, not with --runs x "
                        "--n" % FIGURE_RUNS)


def _with_bar(args, **kw):
    """Both sub-commands: :func:`driftfmu.montecarlo` of kind ``args.experiment``."""
    import driftfmu
    from driftfmu.simulations import budget, cli
    budget.check_montecarlo(args.experiment, args.runs, args.n, args.workers, args.out,
                            summary_only=args.summary_only, engine=args.engine,
                            backend=args.backend)
    desc = "montecarlo (%s engine)" % args.engine
    with cli.progress(args.runs, desc, "run", monitor=False) as update:
        return driftfmu.montecarlo(
                  args.experiment, runs=args.runs, n=args.n, seed=args.seed, Ts=args.Ts,
                  a0=args.a0, a1=args.a1, a2=args.a2, R=args.R, A=args.A, Q=args.Q,
                  engine=args.engine,
                  scheduler=args.scheduler, workers=args.workers, fmu_dir=args.fmu_dir,
                  out=args.out, progress=update, backend=args.backend,
                  summary_only=args.summary_only, **kw)


def _general(args, names):
    return {name: getattr(args, name) for name in names}


def cmd_gaussian(args):
    from driftfmu.simulations import cli
    res = _with_bar(args, P0=args.P0, **_general(args, cli.GENERAL))
    print_summary(res["summary"])
    print("wrote %s/montecarlo.npz, summary.json, fig1.png" % args.out)


def cmd_sinusoidal(args):
    res = _with_bar(args, X=args.X, f=args.f, **_general(args, SINE_GENERAL))
    print_summary(res["summary"])
    print("wrote %s/montecarlo.npz, summary.json, sine.png" % args.out)


def print_summary(s):
    """The summary table: runs settled by sample 250, per estimator and reference (in the
    order of :data:`REFERENCES`, for both kinds of population); the gap."""
    references = [ref for ref in REFERENCES if ref in s["settled_fraction"]]
    print("%d runs of n = %d samples in %.2f s; settled = within %g %% of the reference from "
          "that sample to the end, and at least for the last %d samples"
          % (s["runs"], s["n"], s["seconds"], 100 * s["band"], settle_hold(s["n"])))
    print("%-10s" % "estimator" + "".join(" | settled by %d vs %-9s" % (s["settle_by"], ref)
                                          for ref in references))
    def median(k):  # n + 1: the median run is outside the band at the last sample
        return "%6g" % k if k <= s["n"] else " never"
    for e in ("ekf1", "ekf2", "ekf3"):
        print("%-10s" % e.upper() + "".join(
            " | %5.1f %% (median k %s)   " % (100 * s["settled_fraction"][ref][e],
                                            median(s["median_settled_from"][ref][e]))
            for ref in references))
    g = s["ekf1_ekf2_gap_db"]
    line = ("EKF1-EKF2 gap at the last sample: mean %.4f dB, std %.4f dB, max |gap| %.4f dB "
            "over the runs; of the run means %.4f dB" % (g["mean"], g["std"], g["max_abs"],
                                                          g["of_means"]))
    if "expected" in g:
        line += " (expected 10 log10(1 + R/(a1^2 Q)) = %.4f dB)" % g["expected"]
    print(line)
