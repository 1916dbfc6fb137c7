"""Internal (not a stable API; use driftfmu.experiment_adxl203 or driftfmu.identify instead).

The letter's accelerometer experiment (Sec. IV, Figs. 4-5) on the ADXL203 stand-in.

For each drive frequency, ``sets`` recordings of ``n`` samples are co-simulated with the FMUs:
Excitation (sinusoid, per-set amplitude and phase; small transverse motion ``y``) ->
Accelerometer (the ADXL203 preset of :mod:`driftfmu.models.adxl203`, whose truth holds more than the
filter's model: cubic term, cross-axis coupling, output low-pass, 12-bit ratiometric ADC, noise of
the datasheet's density).  The first ``sets - held_out`` sets (drive ``x`` known, as from a
reference accelerometer) fit one averaged 2nd-order model by harmonic analysis
(:mod:`driftfmu.models.identify`); on the ``held_out`` remaining sets the DriftEstimator FMU (harmonic
process model at the drive frequency, the fitted model, truth unknown to it) runs EKF1.  Per
held-out set: empirical drift ``z̄ - a0`` over whole periods (``a0`` fitted), EKF1 drift at the last
sample, and their difference.  Margin per frequency: ``10 log10(mean drift / rms difference)``
(drift is a second-moment quantity, so dB are 10 log10, as for the EKF1-EKF2 gap).

Choices: ``fs = 10 kHz`` (``Ts = 1e-4``): 50-100 samples per period, 60,000 samples = 6 s =
600-1200 whole periods at every frequency, and well above the 1064 Hz output filter;
``X = 1.5 g`` (2 % set-to-set spread): 88 % of the +-1.7 g range, so the drift
``a2 X^2 / 2 = 11 mV`` is about 2.5 times the output noise (4.5 mg rms) per sample and far above
the error of a 6 s mean, while the part stays in range; transverse motion 5 % of ``X``.

Sets run in parallel (one process per core); each worker co-simulates its sets with the fast
master (:func:`driftfmu.simulations.fastcosim.cosimulate_fast`: direct FMI calls, the stepping loop
in C) for both backends, loading each FMU's library once and instantiating it anew per set.
Every held-out set's FMU outputs are checked against :func:`driftfmu.models.adxl203.simulate`
with the same seeds, computed by its C port in the compiled batch kernel
(:mod:`driftfmu.simulations.kernel`), or by models/ itself without a C compiler.  Where the time
goes is in the summary's ``timing`` and on the command line (docs/performance.md).
"""
import functools
import math
import os
import time
import warnings
from concurrent.futures import as_completed

from driftfmu.models import adxl203, drift, excitation, harmonic, identify, parameters
from driftfmu.models.noise import STREAM_PHASE, normal, uniform
from driftfmu.simulations import batch, output
from driftfmu.simulations.gaussian import TOLERANCE, ValidationError, check_backend, fmu_paths
from driftfmu.simulations.sinusoidal import CONNECTIONS, check_frequency
from driftfmu.simulations.errors import DataError, UsageError

FREQS = (100.0, 125.0, 150.0, 175.0, 200.0)
SETS = 30
HELD_OUT = 5
N = 60000
TS = 1e-4
X = 1.5
AMPLITUDE_SD = 0.02
TRANSVERSE = 0.05
SEED = 1
#: Filter settings: harmonic model at the drive frequency, prior on x from the part's range.
QH = parameters.PARAMETERS["Qh"].default
P0 = adxl203.RANGE_G ** 2
#: The letter's claim: the difference is at least this far below the drift.
CLAIM_DB = 5.0
#: What every held-out set is checked against, by the engine that computes it.
REFERENCES = {"c": "models.adxl203.simulate as its C port (fmu_src/native/models, bit-equal to "
                   "models/) in the compiled batch kernel, same seed, every held-out set",
              "numpy": "models.adxl203.simulate (no C compiler for the kernel), same seed, "
                       "every held-out set"}


def set_seed(seed, f_index, s):
    """Seed of set ``s`` (0-based) at frequency number ``f_index``."""
    return (seed * 7919 + 1000 * (f_index + 1) + s) % (2 ** 31 - 1)


def set_drive(seed, f):
    """Excitation start values of a set: amplitude ``X (1 + 2 % N(0,1))``, uniform phases."""
    amp = X * (1.0 + AMPLITUDE_SD * normal(seed, STREAM_PHASE, 1))
    return dict(kind=excitation.SINUSOIDAL, X=amp, f=f,
                phi=2 * math.pi * uniform(seed, STREAM_PHASE, 2), Xy=TRANSVERSE * amp,
                phiy=2 * math.pi * uniform(seed, STREAM_PHASE, 3), seed=seed)


def true_drift(drive, sensor):
    """The drift the stand-in really has over whole periods: the DC of ``a2 u^2`` with
    ``u = x + cross y`` (``a3 u^3`` and the noise have none, the low-pass passes DC),

    .. math:: a_2 \\frac{X^2 + (c X_y)^2 + 2 c X X_y \\cos(\\phi - \\phi_y)}{2}

    with ``a2`` scaled to the supply.  ``drive`` and ``sensor`` are the Excitation's and the
    Accelerometer's start values of a set.
    """
    c = sensor["cross"]
    return adxl203.config(**sensor).a2 * (drive["X"] ** 2 + (c * drive["Xy"]) ** 2
                                         + 2 * c * drive["X"] * drive["Xy"]
                                         * math.cos(drive["phi"] - drive["phiy"])) / 2.0


def margin(empirical, ekf1):
    """The letter's margin over held-out sets: how far below the drift EKF1's error lies.

    ``difference = EKF1 - empirical`` per set, ``drift_mean`` the mean empirical drift,
    ``difference_rms = sqrt(mean(difference^2))`` (a root mean square over the sets, not a
    standard error), and ``margin_db = 10 log10(|drift_mean| / difference_rms)`` (the drift is
    a second-moment quantity, so dB are 10 log10 of the ratio, as for the EKF1-EKF2 gap;
    ``inf`` when EKF1 equals the empirical drift in every set).
    """
    diff = [b - a for a, b in zip(empirical, ekf1)]
    drift_mean = sum(empirical) / len(empirical)
    rms = math.sqrt(sum(d * d for d in diff) / len(diff))
    return {"difference": diff, "drift_mean": drift_mean, "difference_rms": rms,
            "margin_db": 10.0 * math.log10(abs(drift_mean) / rms) if rms else math.inf}


#: What the held-out sets record, and what validation compares with the reference.
RECORD = {"Excitation": ["x", "y"], "Accelerometer": ["z", "z_y"],
          "DriftEstimator": ["x_hat", "P", "dc_ekf1"]}


def _run_set(task):
    """Worker: co-simulate one set.  Training: fit the model.  Held out: EKF1 and references.

    The FMUs run in the fast master (:func:`driftfmu.simulations.fastcosim.cosimulate_fast`: the
    stepping loop in C, the FMUs' libraries kept loaded from set to set in this worker) for both
    backends; ``"seconds"`` says where the worker's time went."""
    from driftfmu.simulations.fastcosim import cosimulate_fast
    paths, f, seed, n, Ts, model, validate, backend, order = task
    t0 = time.perf_counter()
    ex = dict(set_drive(seed, f), Ts=Ts)
    sp = dict(adxl203.ADXL203, seed=seed, Ts=Ts, noise=1)
    if model is None:
        fmus = {k: paths[k] for k in ("Excitation", "Accelerometer")}
        raw = cosimulate_fast(fmus, CONNECTIONS[:2], n, Ts, start_values={
            "Excitation": ex, "Accelerometer": sp}, record={"Excitation": ["x"],
                                                          "Accelerometer": ["z"]},
            reuse=True, arrays=True)
        t1 = time.perf_counter()
        fit = identify.fit_set(raw["time"], raw["Excitation.x"], raw["Accelerometer.z"], f,
                               skip=adxl203.settling_samples(sp["fc"], Ts), order=order)
        return {"fit": fit._asdict(), "seconds": {"simulation": t1 - t0,
                                                  "identification": time.perf_counter() - t1}}
    es = estimator_values(model, f, Ts)
    raw = cosimulate_fast(paths, CONNECTIONS, n, Ts, start_values={
        "Excitation": ex, "Accelerometer": sp, "DriftEstimator": es}, record=RECORD,
        reuse=True, arrays=True)
    t1 = time.perf_counter()
    z = raw["Accelerometer.z"]
    dc = raw["DriftEstimator.dc_ekf1"]
    m = identify.whole_periods(n, f, Ts)
    res = {"dc_empirical": sum(z[:m].tolist()) / m - model["a0"],  # Python's sum, as ever
           "dc_ekf1": float(dc[-1]),
           "dc_true": true_drift(ex, sp),
           "trace": [(k, float(dc[k - 1])) for k in _log_samples(n)]}
    t2 = time.perf_counter()
    if validate:
        from driftfmu.simulations import kernel
        lib = kernel.library()
        columns = [v for names in RECORD.values() for v in names]
        ref = kernel.adxl203_simulate(lib, n, ex, sp, es, Ts, columns=columns) if lib \
            else adxl203.simulate(n, ex, sp, es, Ts)  # no C compiler: models/ itself
        res["max_abs_diff"] = _max_abs_diff(raw, ref)
    res["seconds"] = {"simulation": t1 - t0, "identification": t2 - t1,
                      "validation": time.perf_counter() - t2 if validate else 0.0}
    return res


def estimator_values(model, f, Ts):
    """DriftEstimator start values of a held-out set: EKF1 with the fitted ``model`` (with its
    ``a3``, ``a4`` when the fit's order is 3 or 4) and the harmonic process model at the drive
    frequency ``f``."""
    higher = {k: model[k] for k in ("a3", "a4") if k in model}
    return dict(a0=model["a0"], a1=model["a1"], a2=model["a2"], R=model["R"],
                process=harmonic.HARMONIC, f=f, Qh=QH, x0=0.0, P0=P0, Ts=Ts, estimator=1,
                **higher)


def _max_abs_diff(raw, ref):
    """Largest ``|FMU - reference|`` over the recorded columns (NaN when any is NaN)."""
    import numpy as np
    diffs = [np.abs(np.asarray(raw["%s.%s" % (fmu, v)]) - np.asarray(ref[v]))
             for fmu, names in RECORD.items() for v in names]
    if any(np.isnan(d).any() for d in diffs):
        return math.nan
    return max(float(np.max(d)) for d in diffs)


def _preload_matplotlib():
    """Import matplotlib (Agg) and pyplot now, in this process, which otherwise only waits for
    its workers: the figures at the end then start at once."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401


def _log_samples(n, points=400):
    """About ``points`` sample numbers from 1 to ``n``, spaced evenly on a log scale."""
    ks = sorted({int(round(n ** (i / (points - 1)))) for i in range(points)})
    return [k for k in ks if 1 <= k <= n]


def default_held_out(sets):
    """Held-out sets for ``sets`` sets when none are given: the letter's share, 5 of 30
    (``sets / 6`` rounded), at least 1."""
    return max(1, int(round(sets / 6.0)))


#: Orders of the model the filter runs with (``--order``): the letter's 2nd-order model, or with
#: the identified cubic (and quartic) term of :func:`driftfmu.models.identify.fit_set`.
ORDERS = identify.ORDERS


def check_settings(freqs, sets, held_out, n, Ts, order=2):
    """ValueError (value and what is allowed) for bad experiment settings."""
    from driftfmu.simulations import checks
    checks.refuse([checks.choice_problem("order", order, ORDERS), checks.freqs_problem(freqs)])
    twice = sorted({f for f in freqs if list(freqs).count(f) > 1})
    if twice:
        raise UsageError("freqs = %s names %s more than once; allowed: distinct frequencies"
                         % (",".join("%g" % f for f in freqs), ", ".join("%g Hz" % f
                                                                        for f in twice)))
    for f in freqs:
        check_frequency(f, Ts)
        try:
            identify.check_order(order, f, Ts)
        except identify.IdentificationError as exc:
            raise UsageError(str(exc)) from None
    if held_out < 1 or sets - held_out < 2:
        raise UsageError("sets = %r with held_out = %r is not allowed; allowed: held_out >= 1 "
                         "and at least 2 sets to fit (sets >= held_out + 2): %s"
                         % (sets, held_out, "sets >= %d" % (max(1, held_out) + 2)
                            if sets < 3 or held_out < 1 else "held_out <= %d, or sets >= %d"
                            % (sets - 2, held_out + 2)))
    skip = adxl203.settling_samples(adxl203.ADXL203["fc"], Ts)
    need = skip + math.ceil(identify.MIN_PERIODS / (min(freqs) * Ts))  # MIN_PERIODS = 2
    if n < need:
        raise UsageError("n = %r samples are too few: the fit leaves out the first %d (the output "
                         "filter's start) and needs two periods of the lowest frequency, %g Hz, "
                         "after them; allowed: n >= %d" % (n, skip, min(freqs), need))


def run_adxl203(out=None, freqs=FREQS, sets=SETS, held_out=HELD_OUT, n=N, Ts=TS, seed=SEED,
                fmu_dir="build/fmus", workers=None, progress=None, validate=True, plot=True,
                backend="python", order=2):
    """Run the experiment; with ``out`` write adxl203.csv/.json/.npz, fig4.png and fig5.png
    (all or none).  Returns the summary dict (``per_frequency`` holds the margins).

    ``order``: the order of the model fitted (:func:`driftfmu.models.identify.fit_set`) and
    run by the filter: 2 (the letter's, default), 3 (with the identified cubic term ``a3``,
    which the stand-in has) or 4; the summary's ``settings["order"]`` says which.

    Raises ValueError for bad settings (before anything runs), ValidationError when a held-out
    set's FMU outputs differ from models/ by more than ``TOLERANCE``.  ``backend`` picks the
    FMUs: ``"python"`` or ``"native"`` (the C twins, same bits, much faster).
    """
    check_backend(backend)
    freqs = tuple(float(f) for f in freqs)
    check_settings(freqs, sets, held_out, n, Ts, order)
    t0 = time.perf_counter()
    paths = {k: str(v) for k, v in fmu_paths(fmu_dir, backend).items()}
    train = sets - held_out
    workers = workers or os.cpu_count() or 1
    done = [0]

    def tick():
        done[0] += 1
        if progress is not None:
            progress(done[0])

    fits = {f: [None] * train for f in freqs}
    tests = {f: [None] * held_out for f in freqs}
    models = {}
    seconds = dict(simulation=0.0, identification=0.0, validation=0.0)

    def spent(res):
        for key, value in res.pop("seconds").items():
            seconds[key] += value
        return res

    reference = None
    if validate:
        from driftfmu.simulations import kernel
        # compiled (or found) once, before the workers fork
        reference = REFERENCES["c" if kernel.library() is not None else "numpy"]
    with batch.process_pool(workers, "driftfmu.simulations.adxl203") as pool:
        futs = {pool.submit(_run_set, (paths, f, set_seed(seed, i, s), n, Ts, None, False,
                                       backend, order)): (f, s)
                for i, f in enumerate(freqs) for s in range(train)}
        from driftfmu.simulations.cli import start_work
        start_work(progress, min(workers, len(futs)))  # the sets' pace counts from here
        if out is not None and plot:
            _preload_matplotlib()  # while the workers (forked by now) run the sets
        for fut in as_completed(futs):
            f, s = futs[fut]
            fits[f][s] = identify.Fit(**spent(fut.result())["fit"])
            tick()
        for f in freqs:
            models[f] = identify.average(fits[f])
        t_fit = time.perf_counter()
        futs = {pool.submit(_run_set, (paths, f, set_seed(seed, i, train + s), n, Ts, models[f],
                                       validate, backend, order)): (f, s)
                for i, f in enumerate(freqs) for s in range(held_out)}
        for fut in as_completed(futs):
            f, s = futs[fut]
            tests[f][s] = spent(fut.result())
            tick()
    t_held = time.perf_counter()
    wall = t_held - t0

    diffs = [r.get("max_abs_diff", 0.0) for f in freqs for r in tests[f]]
    worst = math.nan if any(math.isnan(d) for d in diffs) else max(diffs, default=0.0)
    if validate and not worst <= TOLERANCE:
        raise ValidationError("FMU outputs differ from models/ run directly by %.3g (tolerance "
                              "%g)" % (worst, TOLERANCE))
    per = []
    for f in freqs:
        emp = [r["dc_empirical"] for r in tests[f]]
        ekf = [r["dc_ekf1"] for r in tests[f]]
        m = margin(emp, ekf)
        per.append({"frequency": f, "model": models[f], "dc_empirical": emp, "dc_ekf1": ekf,
                    "difference": m["difference"], "dc_true": [r["dc_true"] for r in tests[f]],
                    "drift_mean": m["drift_mean"], "difference_rms": m["difference_rms"],
                    "margin_db": m["margin_db"]})
    avg = {k: sum(p["model"][k] for p in per) / len(per)
           for k in ("a0", "a1", "a2", "R") + ("a3", "a4")[:order - 2]}
    summary = {
        "settings": {"freqs": list(freqs), "sets": sets, "held_out": held_out, "n": n, "Ts": Ts,
                     "fs": 1.0 / Ts, "X": X, "amplitude_sd": AMPLITUDE_SD,
                     "transverse": TRANSVERSE, "seed": seed, "sensor": adxl203.ADXL203,
                     "filter": {"process": "harmonic at the drive frequency", "Qh": QH,
                                "P0": P0, "x0": 0.0},
                     "order": order},
        "identification": "harmonic analysis (models.identify), averaged over the fitting sets, "
                          "one model per frequency" + ("" if order == 2 else
                                                       ", of order %d: the filter runs with its "
                                                       "a3%s" % (order, ", a4" * (order == 4))),
        "model": avg,
        "margin_definition": "10 log10(mean empirical drift / rms(EKF1 - empirical)) over the "
                             "held-out sets",
        "claim_db": CLAIM_DB,
        "per_frequency": [{k: v for k, v in p.items()} for p in per],
        "min_margin_db": min(p["margin_db"] for p in per),
        "claim_holds": all(p["margin_db"] >= CLAIM_DB for p in per),
        "validation": {"reference": reference, "tolerance": TOLERANCE,
                       "max_abs_diff": worst if validate else None},
        "wall_time_s": wall, "workers": workers, "backend": backend,
        "timing": {"wall_s": wall, "training_sets_wall_s": t_fit - t0,
                   "held_out_sets_wall_s": t_held - t_fit,
                   "workers_s": seconds, "writing_s": None},
    }
    if out is not None:
        import numpy as np
        t_out = time.perf_counter()
        with output.staged(out) as stage:
            if plot:  # first, so that the JSON can say how long they took; side by side
                output.draw_beside(
                    functools.partial(plot_fig4, stage / "fig4.png", per,
                                      [[r["trace"] for r in tests[f]] for f in freqs], train,
                                      n, Ts),
                    functools.partial(plot_fig5, stage / "fig5.png", per))
            rows = {"frequency": [], "set": [], "dc_empirical": [], "dc_ekf1": [],
                    "difference": []}
            for p in per:
                for s in range(held_out):
                    rows["frequency"].append(p["frequency"])
                    rows["set"].append(train + s + 1)
                    rows["dc_empirical"].append(p["dc_empirical"][s])
                    rows["dc_ekf1"].append(p["dc_ekf1"][s])
                    rows["difference"].append(p["difference"][s])
            output.write_csv(stage / "adxl203.csv", rows, tuple(rows))
            np.savez(stage / "adxl203.npz", adxl_freqs=np.array(freqs),
                     adxl_emp=np.array([p["dc_empirical"] for p in per]),
                     adxl_ekf1=np.array([p["dc_ekf1"] for p in per]))
            summary["timing"]["writing_s"] = time.perf_counter() - t_out
            output.write_json(stage / "adxl203.json", summary)
    return summary


def plot_fig4(path, per, traces, train, n, Ts):
    """Fig. 4: EKF1 against the empirical drift for every held-out set at every frequency
    (left: discrete sets as markers, spread around their frequency, with the rms difference
    per frequency), and EKF1's running estimate of every held-out set over that set's empirical
    drift in percent (right; 100 %: a match).  ``traces`` holds, per frequency, the held-out
    sets' traces."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from driftfmu.simulations.output import caption
    freqs = np.array([p["frequency"] for p in per])
    step = float(np.min(np.diff(freqs))) if len(freqs) > 1 else max(freqs[0] * 0.2, 1.0)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    for c, p in enumerate(per):
        h = len(p["dc_empirical"])
        dx = 0.5 * step * (np.arange(h) - (h - 1) / 2.0) / max(h, 1)
        x = p["frequency"] + dx
        ax.plot(x, 1e3 * np.array(p["dc_empirical"]), "s", mfc="none", mec="k", ms=7,
                label="empirical z̄ − a0" if c == 0 else None)
        ax.plot(x, 1e3 * np.array(p["dc_ekf1"]), "o", color="C0", ms=4.5,
                label="EKF1 (last sample)" if c == 0 else None)
        ax.annotate("%.1f dB" % p["margin_db"], (p["frequency"], 0.0),
                    xycoords=("data", "axes fraction"), xytext=(0, 4),
                    textcoords="offset points", ha="center", fontsize=8, color="0.3")
    ax.set_xticks(freqs)
    ax.set_xlim(freqs[0] - 0.6 * step, freqs[-1] + 0.6 * step)
    lo, hi = ax.get_ylim()
    ax.set_ylim(lo - 0.12 * (hi - lo), hi)  # room for the margin labels
    ax.set_xlabel("drive frequency [Hz] (held-out sets %d-%d side by side)"
                  % (train + 1, train + len(per[0]["dc_empirical"])))
    ax.set_ylabel("drift [mV]")
    ax.set_title("each held-out set: EKF1 and the empirical drift (bottom: margin)",
                 fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.16), ncol=2, fontsize=9,
              frameon=False)
    # every held-out set of every frequency, each as its running EKF1 estimate over its own
    # empirical drift: 100 % is a match, one reference line for all (no dotted line to pair
    # with its curve)
    for c, (p, tr) in enumerate(zip(per, traces)):
        color = plt.cm.viridis(0.9 * c / max(1, len(per) - 1))
        for s, (trace, emp) in enumerate(zip(tr, p["dc_empirical"])):
            k, dc = np.array(trace).T
            ax2.plot(k, 100.0 * dc / emp, lw=0.9, color=color, alpha=0.8,
                     label=("%g Hz (sets %d-%d)" % (p["frequency"], train + 1, train + len(tr))
                            if s == 0 else "_%g Hz set %d" % (p["frequency"], train + 1 + s)))
    ax2.axhline(100.0, color="k", lw=1.0, ls="--", label="the set's empirical drift (100 %)")
    ax2.set_ylim(0, 200)
    from driftfmu.simulations.output import log_sample_axis
    log_sample_axis(ax2)
    ax2.set_xlim(1, max(n, 2))
    ax2.set_xlabel("sample k (log scale; fs = %g kHz)" % (1e-3 / Ts))
    ax2.set_ylabel("EKF1 / the set's empirical drift [%]")
    ax2.set_title("every held-out set: EKF1 over its empirical drift", fontsize=10)
    ax2.grid(True, which="major", alpha=0.3)
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
    caption(fig, "Fig. 4 of the letter on the ADXL203 stand-in: EKF1 drift estimate against "
                 "the empirical drift on the held-out sets, %d samples per set at fs = %g kHz"
                 % (n, 1e-3 / Ts), width=120)
    output.layout(fig)
    output.savefig(fig, path, dpi=120)
    plt.close(fig)


def plot_fig5(path, per):
    """Fig. 5: the drift and the rms difference EKF1 - empirical over the held-out sets,
    against frequency, in dB of volts (``10 log10(value / 1 V)``, as the letter's margin); the
    margin between them labelled at each frequency."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from driftfmu.simulations.output import caption
    f = np.array([p["frequency"] for p in per])
    drift = np.array([abs(p["drift_mean"]) for p in per])
    diff = np.array([p["difference_rms"] for p in per])
    fig, ax = plt.subplots(figsize=(8, 4.8))
    ax.plot(f, 10 * np.log10(drift), "ks-", label="drift: mean empirical z̄ − a0")
    ax.plot(f, 10 * np.log10(diff), "o--", color="C3",
            label="rms(EKF1 − empirical) over the held-out sets")
    for fi, a, b in zip(f, drift, diff):
        ax.annotate("", xy=(fi, 10 * math.log10(b)), xytext=(fi, 10 * math.log10(a)),
                    arrowprops=dict(arrowstyle="<->", color="0.6", lw=0.8))
        ax.annotate("%.1f dB" % (10 * math.log10(a / b)), (fi, 10 * math.log10(math.sqrt(a * b))),
                    xytext=(4, 0), textcoords="offset points", ha="left", va="center",
                    fontsize=8)
    ax.set_xlabel("drive frequency [Hz]")
    # the letter writes its margin as 10 log10 of a voltage ratio; kept so that the margins
    # compare with its numbers (20 log10, the usual one for voltages, doubles every value):
    # the label says which, the caption why
    ax.set_ylabel("10·log10(v / 1 V) [dB re 1 V]")
    ax.set_xticks(f)
    step = float(np.min(np.diff(f))) if len(f) > 1 else max(f[0] * 0.2, 1.0)
    ax.set_xlim(f[0] - 0.4 * step, f[-1] + 0.6 * step)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(0.0, -0.14), ncol=1,
              frameon=False)
    caption(fig, "Fig. 5 of the letter on the ADXL203 stand-in: drift and estimation "
                 "difference against frequency, in dB re 1 V: 10 log10(v / 1 V) of a voltage, "
                 "as the letter (20 log10 would double every value); labelled, the margin (the "
                 "letter claims at least %g dB)" % CLAIM_DB, width=80)
    output.layout(fig)
    output.savefig(fig, path, dpi=120)
    plt.close(fig)


# -- identification from recordings (CSV), the same pipeline on real data -----------------------

def _check_distinct(files, data, held_out):
    """UsageError when two of ``files`` are one recording (the same file, or the same data
    under another name; ``data``: their columns as read): fitted twice it weighs double in the
    average; fitted and held out, the check is no check (a margin of 45 dB where a recording
    not fitted gives 13 dB)."""
    import hashlib
    import numpy as np
    seen = {}
    train = len(files) - held_out
    for i, (p, columns) in enumerate(zip(files, data)):
        key = hashlib.sha256(b"".join(np.ascontiguousarray(c).tobytes() for c in columns))
        key = key.hexdigest()
        if key in seen:
            j = seen[key]
            role = lambda k: "held out" if k >= train else "fitted"  # noqa: E731
            same = ("is given twice" if os.path.realpath(files[j]) == os.path.realpath(p)
                    else "holds the same recording as %s" % files[j])
            raise UsageError("%s %s (%s, then %s); allowed: distinct recordings, each fitted "
                             "or held out once" % (p, same, role(j), role(i)))
        seen[key] = i


def run_identify(files, f, held_out=0, out=None, Qh=QH, P0=P0, order=2):
    """Fit the averaged 2nd-order model on recordings ``files`` (CSV ``time, x, z``) and run EKF1
    (harmonic model at ``f``) on the last ``held_out`` of them (``z`` only).

    Every file is read and checked before anything is fitted; with ``out``, ``identify.json``
    (and ``identify.csv`` of the held-out sets) are written, all or none.
    """
    from driftfmu.simulations import checks
    checks.refuse([checks.choice_problem("order", order, identify.ORDERS)])
    files = [str(p) for p in files]
    if len(files) - held_out < 1 or held_out < 0:
        raise UsageError("%d file(s) with %d held out; allowed: 0 <= held_out < number of files"
                         % (len(files), held_out))
    data = [identify.read_csv(p) for p in files]
    _check_distinct(files, data, held_out)
    Ts = None
    for p, (t, _, _) in zip(files, data):
        try:
            ts = identify.sample_period(t)
        except ValueError as exc:
            raise DataError("%s: %s" % (p, exc)) from None
        check_frequency(f, ts)
        try:  # a setting the recordings' sampling cannot resolve, not a file's fault
            identify.check_order(order, f, ts)
        except identify.IdentificationError as exc:
            raise UsageError(str(exc)) from None
        Ts = ts if Ts is None else Ts
    train = len(files) - held_out
    fits, doubts = [], []
    for p, (t, x, z) in zip(files[:train], data[:train]):
        fits.append(_fit_file(p, t, x, z, f, doubts, order))
    for p, (t, x, _) in zip(files[train:], data[train:]):
        # a held-out recording is checked too: its drive must be at f for EKF1's model
        _fit_file(p, t, x, x, f, doubts, order)
    if train == 1:
        doubts.append("the model comes from one recording: no spread (sd) to report; fit two "
                      "or more to see how much the coefficients scatter")
        warnings.warn(doubts[-1], identify.IdentificationWarning, stacklevel=2)
    model = identify.average(fits)
    summary = {"frequency": f, "files": files[:train], "model": model,
               "fits": [fi._asdict() for fi in fits], "method": "harmonic analysis",
               "warnings": doubts, "order": order}
    higher = dict(a3=model.get("a3", 0.0), a4=model.get("a4", 0.0))
    rows = {"file": [], "dc_empirical": [], "dc_ekf1": [], "difference": []}
    for p, (t, _, z) in zip(files[train:], data[train:]):
        ts = identify.sample_period(t)
        m = identify.whole_periods(len(z), f, ts)
        emp = float(sum(z[:m]) / m - model["a0"])
        st = harmonic.run([float(v) for v in z], model["a0"], model["a1"], model["a2"],
                          model["R"], P0=P0, f=f, Ts=ts, Qh=Qh, **higher)
        ekf = drift.estimates(st.drift, model["a2"], higher["a3"], higher["a4"])[0]
        rows["file"].append(p)
        rows["dc_empirical"].append(emp)
        rows["dc_ekf1"].append(ekf)
        rows["difference"].append(ekf - emp)
    if held_out:
        summary["held_out"] = rows
        summary["margin_db"] = margin(rows["dc_empirical"], rows["dc_ekf1"])["margin_db"]
    if out is not None:
        with output.staged(out) as stage:
            output.write_json(stage / "identify.json", summary)
            if held_out:
                with open(stage / "identify.csv", "w") as fh:
                    fh.write("file,dc_empirical,dc_ekf1,difference\n")
                    for i in range(held_out):
                        fh.write("%s,%.17g,%.17g,%.17g\n" % tuple(rows[k][i] for k in rows))
    return summary


def _fit_file(path, t, x, z, f, doubts, order=2):
    """fit_set on one recording; its errors and warnings name the file (warnings are also
    appended to ``doubts``)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", identify.IdentificationWarning)
        try:
            fit = identify.fit_set(t, x, z, f, order=order)
        except identify.IdentificationError as exc:
            raise identify.IdentificationError("%s: %s" % (path, exc)) from None
    for w in caught:
        doubts.append("%s: %s" % (path, w.message))
        warnings.warn(doubts[-1], w.category, stacklevel=3)
    return fit


# -- command line -------------------------------------------------------------------------------

def _freq_list(text):
    """argparse type of ``--freqs F1,F2,...``: the frequencies, each a number > 0 [Hz]."""
    import argparse
    from driftfmu.simulations import checks

    def number(item):
        try:
            return float(item)
        except ValueError:
            return item.strip()
    freqs = [number(v) for v in text.split(",") if v.strip()]
    problem = checks.freqs_problem(freqs)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return freqs


def add_cli(groups):
    """``driftfmu experiment adxl203`` and ``driftfmu identify``."""
    from driftfmu.simulations import checks, cli
    top = groups["top"]
    exp = top.add_parser("experiment", help="the letter's experiments on the FMUs")
    sub = exp.add_subparsers(dest="experiment", metavar="EXPERIMENT",
                             parser_class=type(exp))
    sub.required = True
    groups["experiment"] = sub  # driftfmu experiment dual-axis goes here too
    g = sub.add_parser("adxl203", help="accelerometer experiment (Sec. IV, Figs. 4-5): fit on "
                       "25 sets, EKF1 on 5 held out, per frequency")
    g.add_argument("--freqs", type=_freq_list, default=list(FREQS), metavar="F1,F2,...",
                   help="drive frequencies [Hz] (default: %s)" % ",".join("%g" % f for f in FREQS))
    g.add_argument("--sets", type=checks.count_option("sets", 1), default=SETS,
                   help="sets per frequency; allowed: sets >= held-out + 2 (default: %d)"
                        % SETS)
    g.add_argument("--held-out", type=checks.count_option("held_out", 1), default=None,
                   metavar="K",
                   help="of the sets, the last K are held out for EKF1, the others fit the "
                        "model; allowed: 1 <= K <= sets - 2 (default: sets / 6 rounded, at "
                        "least 1: %d of %d)" % (HELD_OUT, SETS))
    g.add_argument("--n", type=checks.count_option("n", 1), default=N,
                   help="samples per set; allowed: at least two periods of the lowest "
                        "frequency (default: %d)" % N)
    cli.add_params(g, ("Ts", "seed"), Ts=TS, seed=SEED)
    g.add_argument("--workers", type=checks.count_option("workers", 1), default=None,
                   help="parallel processes (default: the number of cores)")
    g.add_argument("--order", type=checks.choice_option("order", ORDERS), choices=ORDERS,
                   default=2,
                   help="order of the model fitted on the training sets and run by the filter: "
                        "2, the letter's a0 + a1 x + a2 x^2; 3, with the identified cubic "
                        "term a3 (the stand-in has one); 4, also a4 (default: 2)")
    cli.add_out(g, "results/adxl203")
    cli.add_fmu_dir(g)
    cli.add_backend(g)
    g.set_defaults(func=_cmd_experiment)

    i = top.add_parser("identify", help="fit a0, a1, a2, R from recordings (CSV: time, x, z) "
                       "by harmonic analysis; EKF1 on held-out recordings")
    i.add_argument("files", nargs="+", metavar="CSV", help="recordings with columns time, x, z")
    i.add_argument("--f", type=cli.frequency_type, required=True,
                   help="drive frequency [Hz] of the recordings; allowed: %s of the "
                        "recordings' sample period; checked against the recorded drive x"
                        % checks.FREQUENCY_ALLOWED)
    i.add_argument("--held-out", type=checks.count_option("held_out", 0), default=0,
                   metavar="K",
                   help="the last K files are held out: the model is fitted on the others "
                        "and EKF1 runs on these (z only), with the margin against their "
                        "empirical drift; allowed: 0 <= K < number of files (default: 0)")
    i.add_argument("--order", type=checks.choice_option("order", identify.ORDERS),
                   choices=identify.ORDERS, default=2,
                   help="order of the characteristic a0 + a1 x + ... + a_order x^order to fit "
                        "from the harmonics 0..order (with standard errors); an order whose "
                        "harmonics reach the Nyquist rate is refused (default: 2)")
    cli.add_out(i, "results/identify")
    i.set_defaults(func=_cmd_identify)


def _cmd_experiment(args):
    """``driftfmu experiment adxl203``: :func:`driftfmu.experiment_adxl203`."""
    import driftfmu
    from driftfmu.simulations import budget, cli
    total = len(args.freqs) * args.sets
    held_out = default_held_out(args.sets) if args.held_out is None else args.held_out
    check_settings(args.freqs, args.sets, held_out, args.n, args.Ts, args.order)
    # refused when it cannot fit; announced when it takes long
    budget.check_adxl203(args.freqs, args.sets, args.n, args.workers, args.out, args.backend,
                         announce=True)
    with cli.progress(total, "sets", "set") as update:
        s = driftfmu.experiment_adxl203(
                        out=args.out, freqs=args.freqs, sets=args.sets, held_out=held_out,
                        n=args.n, Ts=args.Ts, seed=args.seed, fmu_dir=args.fmu_dir,
                        workers=args.workers, progress=update, backend=args.backend,
                        order=args.order)
    print("wrote %s/adxl203.csv, adxl203.json, adxl203.npz, fig4.png, fig5.png" % args.out)
    for p in s["per_frequency"]:
        m = p["model"]
        more = "".join(", a%d %.5f V/g^%d" % (i, m["a%d" % i], i) for i in (3, 4)
                       if "a%d" % i in m)
        print("%6g Hz: model a0 %.5f V, a1 %.5f V/g, a2 %.5f V/g^2%s, R %.3g V^2 | drift %.3f mV, "
              "rms difference "
              "%.4f mV, margin %.1f dB" % (p["frequency"], m["a0"], m["a1"], m["a2"], more,
                                           m["R"], 1e3 * p["drift_mean"],
                                           1e3 * p["difference_rms"], p["margin_db"]))
    print("claim (difference at least %g dB below the drift at every frequency): %s"
          % (CLAIM_DB, "holds" if s["claim_holds"] else "FAILS"))
    print("wall time %.1f s on %d worker(s) (%d sets x %d samples x %d frequencies, %s FMUs)"
          % (s["wall_time_s"], s["workers"], args.sets, args.n, len(args.freqs), s["backend"]))
    print(timing_line(s["timing"]))


def timing_line(t):
    """Where the time went, in one line: wall time of the phases, the workers' seconds."""
    w = t["workers_s"]
    return ("time: training sets %.2f s, held-out sets %.2f s, figures and files %.2f s "
            "(wall); in the workers: co-simulation %.2f s, identification and drift %.2f s, "
            "validation %.2f s"
            % (t["training_sets_wall_s"], t["held_out_sets_wall_s"],
               t["writing_s"] or 0.0, w["simulation"],
               w["identification"], w["validation"]))


def _cmd_identify(args):
    """``driftfmu identify``: :func:`driftfmu.identify`."""
    import driftfmu
    from driftfmu.simulations import budget
    budget.check_identify(args.files, args.out, announce=False)
    s = driftfmu.identify(args.files, args.f, held_out=args.held_out, out=args.out,
                          order=args.order)
    m = s["model"]
    print("wrote %s/identify.json%s" % (args.out, ", identify.csv" if args.held_out else ""))
    print("model from %d set(s): a0 %.6g, a1 %.6g, a2 %.6g, R %.4g"
          % (m["sets"], m["a0"], m["a1"], m["a2"], m["R"]))
    if args.order > 2:
        fit = s["fits"][0]
        print("order %d: %s; standard errors of the first set: %s"
              % (args.order, ", ".join("a%d %.6g" % (i, m["a%d" % i])
                                       for i in range(3, args.order + 1)),
                 ", ".join("%s %.3g" % kv for kv in sorted(fit["se"].items()))))
    if m["sd_a2"] is not None:
        print("spread over the sets (sd): a0 %.3g, a1 %.3g, a2 %.3g, R %.3g"
              % (m["sd_a0"], m["sd_a1"], m["sd_a2"], m["sd_R"]))
    if s["warnings"]:
        print("%d warning(s), see above and identify.json: the fit is doubtful"
              % len(s["warnings"]))
    if args.held_out:
        print("EKF1 on %d held-out set(s): margin %.1f dB" % (args.held_out, s["margin_db"]))
