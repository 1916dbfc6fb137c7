"""The letter's accelerometer experiment (Sec. IV, Figs. 4-5) on the ADXL203 stand-in.

For each drive frequency, ``sets`` recordings of ``n`` samples are co-simulated with the FMUs:
Excitation (sinusoid, per-set amplitude and phase; small transverse motion ``y``) ->
Accelerometer (the ADXL203 preset of :mod:`models.adxl203`, whose truth holds more than the
filter's model: cubic term, cross-axis coupling, output low-pass, 12-bit ratiometric ADC, noise of
the datasheet's density).  The first ``sets - held_out`` sets (drive ``x`` known, as from a
reference accelerometer) fit one averaged 2nd-order model by harmonic analysis
(:mod:`models.identify`); on the ``held_out`` remaining sets the DriftEstimator FMU (harmonic
process model at the drive frequency, the fitted model, truth unknown to it) runs EKF1.  Per
held-out set: empirical drift ``z̄ - a0`` over whole periods (``a0`` fitted), EKF1 drift at the last
sample, and their difference.  Margin per frequency: ``10 log10(mean drift / rms difference)``
(drift is a second-moment quantity, so dB are 10 log10, as for the EKF1-EKF2 gap).

Choices: ``fs = 10 kHz`` (``Ts = 1e-4``): 50-100 samples per period, 60,000 samples = 6 s =
600-1200 whole periods at every frequency, and well above the 1064 Hz output filter;
``X = 1.5 g`` (2 % set-to-set spread): 88 % of the +-1.7 g range, so the drift
``a2 X^2 / 2 = 11 mV`` is about 2.5 times the output noise (4.5 mg rms) per sample and far above
the error of a 6 s mean, while the part stays in range; transverse motion 5 % of ``X``.

Sets run in parallel (one process per core); each worker loads the FMUs once per set through
the master of the backend (:func:`simulations.gaussian.master`: fmpy's wrappers for the Python
FMUs, direct FMI calls for the native ones).
"""
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

from driftfmu.models import adxl203, excitation, harmonic, identify, parameters
from driftfmu.models.noise import STREAM_PHASE, normal, uniform
from driftfmu.simulations import batch, output
from driftfmu.simulations.gaussian import TOLERANCE, ValidationError, check_backend, fmu_paths, \
    master
from driftfmu.simulations.sinusoidal import CONNECTIONS, check_frequency

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


def set_seed(seed, f_index, s):
    """Seed of set ``s`` (0-based) at frequency number ``f_index``."""
    return (seed * 7919 + 1000 * (f_index + 1) + s) % (2 ** 31 - 1)


def set_drive(seed, f):
    """Excitation start values of a set: amplitude ``X (1 + 2 % N(0,1))``, uniform phases."""
    amp = X * (1.0 + AMPLITUDE_SD * normal(seed, STREAM_PHASE, 1))
    return dict(kind=excitation.SINUSOIDAL, X=amp, f=f,
                phi=2 * math.pi * uniform(seed, STREAM_PHASE, 2), Xy=TRANSVERSE * amp,
                phiy=2 * math.pi * uniform(seed, STREAM_PHASE, 3), seed=seed)


def _run_set(task):
    """Worker: co-simulate one set.  Training: fit the model.  Held out: EKF1 and references."""
    paths, f, seed, n, Ts, model, validate, backend = task
    cosimulate = master(backend)
    ex = dict(set_drive(seed, f), Ts=Ts)
    sp = dict(adxl203.ADXL203, seed=seed, Ts=Ts, noise=1)
    if model is None:
        fmus = {k: paths[k] for k in ("Excitation", "Accelerometer")}
        raw = cosimulate(fmus, CONNECTIONS[:2], n, Ts, start_values={"Excitation": ex,
                         "Accelerometer": sp}, record={"Excitation": ["x"],
                                                       "Accelerometer": ["z"]})
        fit = identify.fit_set(raw["time"], raw["Excitation.x"], raw["Accelerometer.z"], f,
                               skip=adxl203.settling_samples(sp["fc"], Ts))
        return {"fit": fit._asdict()}
    es = dict(a0=model["a0"], a1=model["a1"], a2=model["a2"], R=model["R"],
              process=harmonic.HARMONIC, f=f, Qh=QH, x0=0.0, P0=P0, Ts=Ts, estimator=1)
    record = {"Excitation": ["x", "y"], "Accelerometer": ["z", "z_y"],
              "DriftEstimator": ["x_hat", "P", "dc_ekf1"]}
    raw = cosimulate(paths, CONNECTIONS, n, Ts, start_values={"Excitation": ex,
                     "Accelerometer": sp, "DriftEstimator": es}, record=record)
    z = raw["Accelerometer.z"]
    m = identify.whole_periods(n, f, Ts)
    res = {"dc_empirical": sum(z[:m]) / m - model["a0"],
           "dc_ekf1": raw["DriftEstimator.dc_ekf1"][-1],
           "dc_true": adxl203.config(**sp).a2 * (ex["X"] ** 2 + (sp["cross"] * ex["Xy"]) ** 2
                                              + 2 * sp["cross"] * ex["X"] * ex["Xy"]
                                              * math.cos(ex["phi"] - ex["phiy"])) / 2.0,
           "trace": [(k, raw["DriftEstimator.dc_ekf1"][k - 1]) for k in _log_samples(n)]}
    if validate:
        ref = adxl203.simulate(n, ex, sp, es, Ts)
        res["max_abs_diff"] = max(max(abs(a - b) for a, b in zip(raw["%s.%s" % (fmu, v)], ref[v]))
                                  for fmu, names in record.items() for v in names)
    return res


def _log_samples(n, points=400):
    """About ``points`` sample numbers from 1 to ``n``, spaced evenly on a log scale."""
    ks = sorted({int(round(n ** (i / (points - 1)))) for i in range(points)})
    return [k for k in ks if 1 <= k <= n]


def check_settings(freqs, sets, held_out, n, Ts):
    """ValueError (value and what is allowed) for bad experiment settings."""
    if not freqs:
        raise ValueError("freqs is empty; allowed: one or more frequencies")
    for f in freqs:
        check_frequency(f, Ts)
    if held_out < 1 or sets - held_out < 2:
        raise ValueError("sets = %r with %r held out is not allowed; allowed: held_out >= 1 and "
                         "at least 2 sets to fit (sets >= held_out + 2)" % (sets, held_out))
    for f in freqs:
        if n * f * Ts < 2:
            raise ValueError("n = %r samples span %.3g periods at f = %r Hz; allowed: n >= %d "
                             "(two periods at the lowest frequency)"
                             % (n, n * f * Ts, f, math.ceil(2 / (min(freqs) * Ts))))


def run_adxl203(out=None, freqs=FREQS, sets=SETS, held_out=HELD_OUT, n=N, Ts=TS, seed=SEED,
                fmu_dir="build/fmus", workers=None, progress=None, validate=True, plot=True,
                backend="python"):
    """Run the experiment; with ``out`` write adxl203.csv/.json/.npz, fig4.png and fig5.png
    (all or none).  Returns the summary dict (``per_frequency`` holds the margins).

    Raises ValueError for bad settings (before anything runs), ValidationError when a held-out
    set's FMU outputs differ from models/ by more than ``TOLERANCE``.  ``backend`` picks the
    FMUs: ``"python"`` or ``"native"`` (the C twins, same bits, much faster).
    """
    check_backend(backend)
    freqs = tuple(float(f) for f in freqs)
    check_settings(freqs, sets, held_out, n, Ts)
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
    context = batch.mp_context("driftfmu.simulations.adxl203")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        futs = {pool.submit(_run_set, (paths, f, set_seed(seed, i, s), n, Ts, None, False,
                                             backend)): (f, s)
                for i, f in enumerate(freqs) for s in range(train)}
        for fut in as_completed(futs):
            f, s = futs[fut]
            fits[f][s] = identify.Fit(**fut.result()["fit"])
            tick()
        for f in freqs:
            models[f] = identify.average(fits[f])
        futs = {pool.submit(_run_set, (paths, f, set_seed(seed, i, train + s), n, Ts, models[f],
                                       validate, backend)): (f, s)
                for i, f in enumerate(freqs) for s in range(held_out)}
        for fut in as_completed(futs):
            f, s = futs[fut]
            tests[f][s] = fut.result()
            tick()
    wall = time.perf_counter() - t0

    worst = max((r.get("max_abs_diff", 0.0) for f in freqs for r in tests[f]), default=0.0)
    if validate and not worst <= TOLERANCE:
        raise ValidationError("FMU outputs differ from models/ run directly by %.3g (tolerance "
                              "%g)" % (worst, TOLERANCE))
    per = []
    for f in freqs:
        emp = [r["dc_empirical"] for r in tests[f]]
        ekf = [r["dc_ekf1"] for r in tests[f]]
        diff = [b - a for a, b in zip(emp, ekf)]
        drift_mean = sum(emp) / len(emp)
        rms = math.sqrt(sum(d * d for d in diff) / len(diff))
        per.append({"frequency": f, "model": models[f], "dc_empirical": emp, "dc_ekf1": ekf,
                    "difference": diff, "dc_true": [r["dc_true"] for r in tests[f]],
                    "drift_mean": drift_mean, "difference_rms": rms,
                    "margin_db": 10.0 * math.log10(abs(drift_mean) / rms) if rms else math.inf})
    avg = {k: sum(p["model"][k] for p in per) / len(per) for k in ("a0", "a1", "a2", "R")}
    summary = {
        "settings": {"freqs": list(freqs), "sets": sets, "held_out": held_out, "n": n, "Ts": Ts,
                     "fs": 1.0 / Ts, "X": X, "amplitude_sd": AMPLITUDE_SD,
                     "transverse": TRANSVERSE, "seed": seed, "sensor": adxl203.ADXL203,
                     "filter": {"process": "harmonic at the drive frequency", "Qh": QH,
                                "P0": P0, "x0": 0.0}},
        "identification": "harmonic analysis (models.identify), averaged over the fitting sets, "
                          "one model per frequency",
        "model": avg,
        "margin_definition": "10 log10(mean empirical drift / rms(EKF1 - empirical)) over the "
                             "held-out sets",
        "claim_db": CLAIM_DB,
        "per_frequency": [{k: v for k, v in p.items()} for p in per],
        "min_margin_db": min(p["margin_db"] for p in per),
        "claim_holds": all(p["margin_db"] >= CLAIM_DB for p in per),
        "validation": {"reference": "models.adxl203.simulate, same seed (held-out sets)",
                       "tolerance": TOLERANCE, "max_abs_diff": worst if validate else None},
        "wall_time_s": wall, "workers": workers, "backend": backend,
    }
    if out is not None:
        import numpy as np
        with output.staged(out) as stage:
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
            output.write_json(stage / "adxl203.json", summary)
            np.savez(stage / "adxl203.npz", adxl_freqs=np.array(freqs),
                     adxl_emp=np.array([p["dc_empirical"] for p in per]),
                     adxl_ekf1=np.array([p["dc_ekf1"] for p in per]))
            if plot:
                plot_fig4(stage / "fig4.png", per[0], [r["trace"] for r in tests[freqs[0]]],
                          train, n, Ts)
                plot_fig5(stage / "fig5.png", per)
    return summary


def plot_fig4(path, p, traces, train, n, Ts):
    """Fig. 4: EKF1 against the empirical drift for each held-out set at one frequency, with the
    EKF1 running estimates (inset axis: convergence over the set)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    sets = np.arange(train + 1, train + 1 + len(p["dc_empirical"]))
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    ax.plot(sets, 1e3 * np.array(p["dc_empirical"]), "ks-", label="empirical  z̄ - a0")
    ax.plot(sets, 1e3 * np.array(p["dc_ekf1"]), "o--", color="C0", label="EKF1")
    ax.set_xlabel("held-out set")
    ax.set_ylabel("drift [mV]")
    ax.set_xticks(sets)
    ax.set_title("Estimated vs empirical drift, %g Hz (margin %.1f dB)"
                 % (p["frequency"], p["margin_db"]))
    ax.grid(True, alpha=0.3)
    ax.legend()
    for i, tr in enumerate(traces):
        k, dc = np.array(tr).T
        ax2.semilogx(k, 1e3 * dc, lw=1, color="C%d" % i, label="set %d" % sets[i])
        ax2.axhline(1e3 * p["dc_empirical"][i], color="C%d" % i, lw=0.8, ls=":")
    ax2.set_ylim(0, 2 * 1e3 * max(p["dc_empirical"]))
    ax2.set_xlabel("sample k (fs = %g kHz)" % (1e-3 / Ts))
    ax2.set_ylabel("EKF1 drift [mV]")
    ax2.set_title("EKF1 running estimate (dotted: empirical)")
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fig5(path, per):
    """Fig. 5: drift and |EKF1 - empirical| (rms over the held-out sets) against frequency, dB."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    f = np.array([p["frequency"] for p in per])
    drift = np.array([abs(p["drift_mean"]) for p in per])
    diff = np.array([p["difference_rms"] for p in per])
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(f, 10 * np.log10(drift), "ks-", label="drift (empirical)")
    ax.plot(f, 10 * np.log10(diff), "o--", color="C3", label="difference EKF1 - empirical (rms)")
    for fi, a, b in zip(f, drift, diff):
        ax.annotate("%.1f dB" % (10 * math.log10(a / b)), (fi, 10 * math.log10(math.sqrt(a * b))),
                    ha="center", fontsize=8)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("10 log10(|value| / 1 V) [dB]")
    ax.set_title("ADXL203 stand-in: drift vs estimation difference")
    ax.set_xticks(f)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# -- identification from recordings (CSV), the same pipeline on real data -----------------------

def run_identify(files, f, held_out=0, out=None, Qh=QH, P0=P0):
    """Fit the averaged 2nd-order model on recordings ``files`` (CSV ``time, x, z``) and run EKF1
    (harmonic model at ``f``) on the last ``held_out`` of them (``z`` only).

    Every file is read and checked before anything is fitted; with ``out``, ``identify.json``
    (and ``identify.csv`` of the held-out sets) are written, all or none.
    """
    files = [str(p) for p in files]
    if len(files) - held_out < 1 or held_out < 0:
        raise ValueError("%d file(s) with %d held out; allowed: 0 <= held_out < number of files"
                         % (len(files), held_out))
    data = [identify.read_csv(p) for p in files]
    Ts = None
    for p, (t, _, _) in zip(files, data):
        try:
            ts = identify.sample_period(t)
        except ValueError as exc:
            raise ValueError("%s: %s" % (p, exc)) from None
        check_frequency(f, ts)
        Ts = ts if Ts is None else Ts
    train = len(files) - held_out
    fits = [identify.fit_set(t, x, z, f) for t, x, z in data[:train]]
    model = identify.average(fits)
    summary = {"frequency": f, "files": files[:train], "model": model,
               "fits": [fi._asdict() for fi in fits], "method": "harmonic analysis"}
    rows = {"file": [], "dc_empirical": [], "dc_ekf1": [], "difference": []}
    for p, (t, _, z) in zip(files[train:], data[train:]):
        ts = identify.sample_period(t)
        m = identify.whole_periods(len(z), f, ts)
        emp = float(sum(z[:m]) / m - model["a0"])
        st = harmonic.run([float(v) for v in z], model["a0"], model["a1"], model["a2"],
                          model["R"], P0=P0, f=f, Ts=ts, Qh=Qh)
        ekf = model["a2"] * st.drift.s1
        rows["file"].append(p)
        rows["dc_empirical"].append(emp)
        rows["dc_ekf1"].append(ekf)
        rows["difference"].append(ekf - emp)
    if held_out:
        drift_mean = sum(rows["dc_empirical"]) / held_out
        rms = math.sqrt(sum(d * d for d in rows["difference"]) / held_out)
        summary["held_out"] = rows
        summary["margin_db"] = 10 * math.log10(abs(drift_mean) / rms) if rms else math.inf
    if out is not None:
        with output.staged(out) as stage:
            output.write_json(stage / "identify.json", summary)
            if held_out:
                with open(stage / "identify.csv", "w") as fh:
                    fh.write("file,dc_empirical,dc_ekf1,difference\n")
                    for i in range(held_out):
                        fh.write("%s,%.17g,%.17g,%.17g\n" % tuple(rows[k][i] for k in rows))
    return summary


# -- command line -------------------------------------------------------------------------------

def _freq_list(text):
    import argparse
    try:
        freqs = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError("freqs = %r is not a comma-separated list of numbers"
                                         % text)
    if not freqs or not all(math.isfinite(v) and v > 0 for v in freqs):
        raise argparse.ArgumentTypeError("freqs = %r; allowed: positive frequencies in Hz, "
                                         "e.g. 100,125,150" % text)
    return freqs


def _positive_int(name):
    import argparse

    def parse(text):
        try:
            v = int(text)
        except ValueError:
            v = 0
        if v < 1:
            raise argparse.ArgumentTypeError("%s = %r; allowed: a positive integer" % (name, text))
        return v
    return parse


def add_cli(groups):
    """``driftfmu experiment adxl203`` and ``driftfmu identify``."""
    from driftfmu.simulations import cli
    top = groups["top"]
    exp = top.add_parser("experiment", help="the letter's experiments on the FMUs")
    sub = exp.add_subparsers(dest="experiment", metavar="EXPERIMENT",
                             parser_class=type(exp))
    sub.required = True
    g = sub.add_parser("adxl203", help="accelerometer experiment (Sec. IV, Figs. 4-5): fit on "
                       "25 sets, EKF1 on 5 held out, per frequency")
    g.add_argument("--freqs", type=_freq_list, default=list(FREQS), metavar="F1,F2,...",
                   help="drive frequencies [Hz] (default: %s)" % ",".join("%g" % f for f in FREQS))
    g.add_argument("--sets", type=_positive_int("sets"), default=SETS,
                   help="sets per frequency (default: %d)" % SETS)
    g.add_argument("--held-out", type=_positive_int("held-out"), default=HELD_OUT,
                   help="sets held out for EKF1 (default: %d)" % HELD_OUT)
    g.add_argument("--n", type=_positive_int("n"), default=N,
                   help="samples per set (default: %d)" % N)
    cli.add_params(g, ("Ts", "seed"), Ts=TS, seed=SEED)
    g.add_argument("--workers", type=_positive_int("workers"), default=None,
                   help="parallel processes (default: the number of cores)")
    cli.add_out(g, "results/adxl203")
    cli.add_fmu_dir(g)
    cli.add_backend(g)
    g.set_defaults(func=_cmd_experiment)

    i = top.add_parser("identify", help="fit a0, a1, a2, R from recordings (CSV: time, x, z) "
                       "by harmonic analysis; EKF1 on held-out recordings")
    i.add_argument("files", nargs="+", metavar="CSV", help="recordings with columns time, x, z")
    i.add_argument("--f", type=cli.param_type("f"), required=True,
                   help="drive frequency [Hz]")
    i.add_argument("--held-out", type=int, default=0,
                   help="the last K files are held out for EKF1 (default: 0)")
    cli.add_out(i, "results/identify")
    i.set_defaults(func=_cmd_identify)


def _cmd_experiment(args):
    from driftfmu.simulations import cli
    total = len(args.freqs) * args.sets
    with cli.progress(total, "sets") as update:
        s = run_adxl203(out=args.out, freqs=args.freqs, sets=args.sets, held_out=args.held_out,
                        n=args.n, Ts=args.Ts, seed=args.seed, fmu_dir=args.fmu_dir,
                        workers=args.workers, progress=update, backend=args.backend)
    print("wrote %s/adxl203.csv, adxl203.json, adxl203.npz, fig4.png, fig5.png" % args.out)
    for p in s["per_frequency"]:
        m = p["model"]
        print("%6g Hz: model a0 %.5f a1 %.5f a2 %.5f R %.3g | drift %.3f mV, rms difference "
              "%.4f mV, margin %.1f dB" % (p["frequency"], m["a0"], m["a1"], m["a2"], m["R"],
                                           1e3 * p["drift_mean"], 1e3 * p["difference_rms"],
                                           p["margin_db"]))
    print("claim (difference at least %g dB below the drift at every frequency): %s"
          % (CLAIM_DB, "holds" if s["claim_holds"] else "FAILS"))
    print("wall time %.1f s on %d worker(s) (%d sets x %d samples x %d frequencies, %s FMUs)"
          % (s["wall_time_s"], s["workers"], args.sets, args.n, len(args.freqs), s["backend"]))


def _cmd_identify(args):
    s = run_identify(args.files, args.f, held_out=args.held_out, out=args.out)
    m = s["model"]
    print("wrote %s/identify.json%s" % (args.out, ", identify.csv" if args.held_out else ""))
    print("model from %d set(s): a0 %.6g, a1 %.6g, a2 %.6g, R %.4g"
          % (m["sets"], m["a0"], m["a1"], m["a2"], m["R"]))
    if args.held_out:
        print("EKF1 on %d held-out set(s): margin %.1f dB" % (args.held_out, s["margin_db"]))
