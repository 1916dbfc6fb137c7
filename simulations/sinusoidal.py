"""Internal (not a stable API; use driftfmu.run_sinusoidal instead).

Sinusoidal excitation (the letter's Sec. IV drive) as an FMU co-simulation.

Excitation (``x = X sin(2 pi f t + phi)``, and ``y`` for the second axis) -> Accelerometer ->
DriftEstimator, fixed step ``Ts``, one row per sample.  The filter's process model is the letter's
Gauss-Markov one (``process = 1``, ``A``, ``Q``) or a harmonic oscillator at ``f``
(``process = 2``, ``Qh``).  With ``preset="adxl203"`` the accelerometer is the ADXL203 stand-in of
:mod:`driftfmu.models.adxl203`, and the filter gets that part's nominal quadratic model.

The master checks the FMUs against :func:`driftfmu.models.adxl203.simulate` on the same seed, sample by
sample, and reports the drift estimates against the references: the expected drift
``a2 E[u^2]`` (``a2 X^2 / 2`` for one axis), the realised drift and the empirical drift
``z̄ - a0`` over the largest whole number of periods, which is the natural reference here.
"""
import math
import sys

from driftfmu.models import adxl203, chain, drift, excitation, harmonic, identify, parameters
from driftfmu.simulations import output
from driftfmu.simulations.errors import UsageError
from driftfmu.simulations.gaussian import TOLERANCE, ValidationError, compare, fmu_paths, master, \
    settled_from

CONNECTIONS = (("Excitation", "x", "Accelerometer", "x"),
               ("Excitation", "y", "Accelerometer", "y"),
               ("Accelerometer", "z", "DriftEstimator", "z"))
#: The known input u (eq. 1) from the Excitation to the filter's prediction, wired when B != 0.
INPUT_CONNECTION = ("Excitation", "u", "DriftEstimator", "u")
#: The known input's parameters and their off values (the letter's drive).
INPUT_OFF = dict(B=0.0, drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0, fu=0.0)


def connections(B=0.0):
    """The sinusoidal chain's connections; with the known input's (:data:`INPUT_CONNECTION`)
    when the filter's ``B != 0``."""
    return CONNECTIONS + ((INPUT_CONNECTION,) if B != 0.0 else ())


RECORD = {"Excitation": ["x", "y"], "Accelerometer": ["z", "z_y"],
          "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}
FMU_COLUMNS = ("time", "x", "y", "z", "z_y", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3",
               "z_comp")


def check_frequency(f, Ts, name="f"):
    """ValueError unless ``0 < f < 1 / (2 Ts)`` (``name``: the parameter's name)."""
    nyquist = 0.5 / Ts
    if not 0.0 < f < nyquist:
        raise UsageError("%s = %r Hz is not allowed at Ts = %r s; allowed: 0 < %s < 1/(2 Ts) = "
                         "%r Hz (the Nyquist rate)" % (name, f, Ts, name, nyquist))


def expected_drift(a2, cross, X, Xy, phi, phiy, a4=0.0):
    """``a2 E[u^2] + a4 E[u^4]`` of the sensed ``u = x + cross y`` for ``x = X sin(theta +
    phi)``, ``y = Xy sin(theta + phiy)``: ``u`` is one sinusoid, of squared amplitude ``U^2 = X^2
    + cross^2 Xy^2 + 2 cross X Xy cos(phi - phiy)``, so ``E[u^2] = U^2 / 2`` and ``E[u^4] =
    3 U^4 / 8`` (``a2 X^2 / 2`` for one axis and the quadratic sensor; the odd ``a3`` term has
    no drift)."""
    U2 = X * X + cross ** 2 * Xy * Xy + 2.0 * cross * X * Xy * math.cos(phi - phiy)
    if a4 == 0.0:
        return a2 * U2 / 2.0
    return a2 * U2 / 2.0 + 0.375 * a4 * U2 * U2


def empirical_whole_periods(z, f, Ts, a0):
    """``(m, z̄ - a0)`` over the first ``m`` samples, the largest whole number of periods of
    ``f``; ``(0, None)`` when the samples do not span one whole period (no empirical reference
    to speak of)."""
    if len(z) * f * Ts < 1.0:
        return 0, None
    m = identify.whole_periods(len(z), f, Ts)
    return m, sum(z[:m]) / m - a0


def nominal_model(sensor_values, Ts):
    """The quadratic model ``a0, a1, a2, R`` a filter should use for a sensor: its effective
    zero-g level and coefficients, and the output noise variance (behind the low-pass, plus the
    ADC's ``lsb^2 / 12``)."""
    cfg = adxl203.config(Ts=Ts, **{k: v for k, v in sensor_values.items() if k != "Ts"})
    if cfg.plain:
        return dict(a0=cfg.a0, a1=cfg.a1, a2=cfg.a2, R=cfg.R)
    var = cfg.sigma ** 2
    if cfg.alpha is not None:
        var *= (1.0 - cfg.alpha) / (1.0 + cfg.alpha)
    var += cfg.lsb ** 2 / 12.0
    return dict(a0=cfg.a0, a1=cfg.a1, a2=cfg.a2, R=var)


def run_sinusoidal(out=None, X=1.0, f=150.0, phi=0.0, Ts=1e-3, n=2000, seed=1, a0=0.0, a1=1.0,
                   a2=0.01, R=1e-4, process=harmonic.HARMONIC, Qh=None, A=0.0, Q=None, P0=None,
                   x0=0.0, estimator=1, preset=None, sensor=None, Xy=0.0, phiy=0.0,
                   fmu_dir="build/fmus", progress=None, plot=True, backend="python",
                   **inputs):
    """Co-simulate the three FMUs under sinusoidal excitation; optionally write the results.

    Parameters
    ----------
    X, f, phi : float
        Amplitude [g], frequency [Hz] and phase [rad] of ``x``; ``Xy``, ``phiy`` of ``y``.
    a0, a1, a2, R : float
        The quadratic sensor, also the filter's model (ignored with ``preset``: the filter then
        takes the preset part's nominal model, see :func:`nominal_model`).
    process : int
        Filter process model: 1 Gauss-Markov (``A``, ``Q``; ``Q`` defaults to ``X^2 / 2``),
        2 harmonic at ``f`` (``Qh``, default from models.parameters).
    P0 : float, optional
        Initial error variance, default ``X^2 / 2``.
    preset : str, optional
        ``"adxl203"``: the accelerometer is the ADXL203 stand-in.
    sensor : dict, optional
        Further accelerometer parameters (``a3``, ``cross``, ``fc``, ``Vs``, ``bits``,
        ``density``, ``axes``) over the preset.
    backend : str
        ``"python"`` (the pythonfmu FMUs) or ``"native"`` (their C twins, FMI 2.0).
    inputs : optional
        The known input ``u`` of eq. 1 (:data:`INPUT_OFF`): the Excitation's ``drive, Qu, Xu,
        fu`` make ``u_k``, which does not move the sinusoid, and ``B != 0`` is the Gauss-Markov
        filter's input gain, ``x-_k = A x+_{k-1} + B u_k``, with ``Excitation.u`` wired to
        ``DriftEstimator.u`` (:func:`connections`).  E.g. a shaker's commanded motion
        ``u = X sin(2 pi f t)`` (``drive = 2, Xu = X, fu = f``) with ``A = 0, B = 1``: the
        filter predicts the commanded ``x`` and ``Q`` is the motion's deviation from it.

    Returns
    -------
    dict
        ``columns`` (the results table as lists) and ``summary``.

    Raises
    ------
    ValueError
        A parameter is out of range or ``f`` is at or above the Nyquist rate; nothing is written.
    ValidationError
        An FMU output differs from models/ by more than ``TOLERANCE``; nothing is written.
    """
    from driftfmu.simulations import checks
    checks.check_keywords("run_sinusoidal()", inputs, checks.keywords_of(run_sinusoidal,
                                                                         INPUT_OFF))
    inputs = {k: v for k, v in inputs.items() if v != INPUT_OFF[k]}
    B = inputs.get("B", 0.0)
    if B != 0.0 and process != harmonic.GAUSS_MARKOV:
        raise UsageError("B = %r is not allowed with process = %r (harmonic); allowed: B != 0 "
                         "with process = %d (Gauss-Markov), whose prediction takes B u"
                         % (B, process, harmonic.GAUSS_MARKOV))
    Qh = parameters.PARAMETERS["Qh"].default if Qh is None else Qh
    Q = X * X / 2.0 if Q is None else Q
    P0 = X * X / 2.0 if P0 is None else P0
    sp = dict(a0=a0, a1=a1, a2=a2, R=R)
    if preset is not None:
        if preset not in adxl203.PRESETS:
            raise UsageError("preset = %r is not known; allowed: %s"
                             % (preset, ", ".join(sorted(adxl203.PRESETS))))
        sp.update(adxl203.PRESETS[preset])
    sp.update(sensor or {})
    sp.update(seed=seed, Ts=Ts, noise=1)
    params = dict(X=X, f=f, phi=phi, Xy=Xy, phiy=phiy, Ts=Ts, n=n, seed=seed, Qh=Qh, A=A, Q=Q,
                  P0=P0, x0=x0, process=process, **inputs)
    problems = parameters.check(params) + adxl203.check(sp)
    if problems:
        raise UsageError("; ".join(problems))
    if estimator not in (1, 2, 3):
        raise UsageError("estimator = %r is not allowed; allowed: 1, 2 or 3" % (estimator,))
    check_frequency(f, Ts)
    if inputs.get("drive") == excitation.SINUSOIDAL:
        check_frequency(inputs.get("fu", 0.0), Ts, "fu")
    model = nominal_model(sp, Ts) if preset is not None else dict(a0=a0, a1=a1, a2=a2, R=R)
    start = {
        "Excitation": dict(kind=excitation.SINUSOIDAL, X=X, f=f, phi=phi, Xy=Xy, phiy=phiy,
                           Ts=Ts, seed=seed,
                           **{k: v for k, v in inputs.items() if k != "B"}),
        "Accelerometer": sp,
        "DriftEstimator": dict(model, process=process, f=f, Qh=Qh, A=A, Q=Q, x0=x0, P0=P0,
                               Ts=Ts, estimator=estimator, **({"B": B} if B != 0.0 else {})),
    }
    raw = master(backend)(fmu_paths(fmu_dir, backend), connections(B), n, Ts,
                          start_values=start,
                          record=RECORD, progress=progress)
    cols = {"time": raw["time"]}
    for name, names in RECORD.items():
        for v in names:
            cols[v] = raw["%s.%s" % (name, v)]
    ref = adxl203.simulate(n, start["Excitation"], sp, start["DriftEstimator"], Ts)
    diffs, bad = compare(cols, ref, names=FMU_COLUMNS)

    cfg = adxl203.config(**sp)
    u = [xi + cfg.cross * yi for xi, yi in zip(cols["x"], cols["y"])]
    # the sensor's own a3, a4 (scaled with the supply like a2): the references of the general
    # sensor, mean(a2 u^2 + a3 u^3 + a4 u^4) and a2 E[u^2] + a4 E[u^4]
    dc_expected = expected_drift(cfg.a2, cfg.cross, X, Xy, phi, phiy, cfg.a4)
    cols["dc_empirical"], cols["dc_realised"], cols["dc_expected"] = drift.references(
        u, cols["z"], cfg.a0, cfg.a2, dc_expected, cfg.a3, cfg.a4)
    periods = n * f * Ts
    m, dc_whole = empirical_whole_periods(cols["z"], f, Ts, cfg.a0)

    final = {c: cols[c][-1] for c in ("dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_empirical",
                                      "dc_realised", "dc_expected")}
    final["dc_empirical_whole_periods"] = dc_whole
    summary = {
        "parameters": params, "sensor": sp, "filter_model": model,
        "process": harmonic.PROCESSES[process], "estimator": estimator, "final": final,
        "whole_periods": {"samples": m, "periods": round(m * f * Ts, 6)},
        "empirical_note": None if m else "the %d samples span %.3g periods of f = %g Hz: no "
                          "whole period, so no empirical reference (n >= %d needed)"
                          % (n, periods, f, math.ceil(1.0 / (f * Ts))),
        "ekf1_rel_error": {"vs_expected": final["dc_ekf1"] / dc_expected - 1.0
                           if dc_expected else None,
                           "vs_empirical_whole_periods": final["dc_ekf1"] / dc_whole - 1.0
                           if dc_whole else None},
        "settled_from_sample": {
            "reference": "realised drift %s, band 10 %%" % (
                "a2 mean(u^2)" if cfg.a3 == 0.0 and cfg.a4 == 0.0
                else "mean(a2 u^2 + a3 u^3 + a4 u^4)"),
            "ekf1": settled_from(cols["dc_ekf1"], cols["dc_realised"]),
            "ekf2": settled_from(cols["dc_ekf2"], cols["dc_realised"]),
            "ekf3": settled_from(cols["dc_ekf3"], cols["dc_realised"])},
        "validation": {"reference": "models.adxl203.simulate, same seed",
                       "tolerance": TOLERANCE, "max_abs_diff": diffs, "passed": not bad},
    }
    if bad:
        raise ValidationError(
            "FMU outputs differ from models/ run directly: %s (tolerance %g)"
            % (", ".join("%s by %.3g" % (c, diffs[c]) for c in bad), TOLERANCE))
    if out is not None:
        names = chain.COLUMNS + (("y", "z_y") if sp.get("axes", 1) == 2 else ())
        with output.staged(out) as stage:
            output.write_csv(stage / "results.csv", cols, names)
            output.write_json(stage / "summary.json", summary)
            if plot:
                output.plot_drift(stage / "drift.png", cols,
                                  "Drift estimates of one co-simulation: sinusoidal state "
                                  "X = %g g at f = %g Hz, %s, %s%s, %s filter%s%s, n = %d at "
                                  "Ts = %g s, seed %d" % (
                                      X, f, output.value_text("a1", cfg.a1),
                                      output.value_text("a2", cfg.a2),
                                      ", %s" % output.value_text("a3", cfg.a3) if cfg.a3
                                      else "", harmonic.PROCESSES[process],
                                      ", %s stand-in" % preset if preset else "",
                                      ", %s" % output.general_text(inputs) if inputs else "",
                                      n, Ts, seed),
                                  labels=None if not cfg.cross else (
                                      "a2·mean(u²), u = x + %g·y sensed" % cfg.cross,
                                      "a2·E[u²]"))
    return {"columns": cols, "summary": summary}


#: The known input's options of ``driftfmu run sinusoidal``: the filter's gain ``B`` and the
#: Excitation's drive of ``u`` (it does not move the sinusoid; a filter that knows the commanded
#: motion predicts with it).
INPUT_OPTIONS = ("B", "drive", "Qu", "Xu", "fu")


def add_cli(groups):
    """``driftfmu run sinusoidal``."""
    from driftfmu.simulations import checks, cli
    g = groups["run"].add_parser("sinusoidal", help="sinusoidal excitation (the letter's Sec. IV "
                                 "drive), Gauss-Markov or harmonic filter, optional ADXL203")
    cli.add_params(g, ("X", "f", "phi", "a0", "a1", "a2", "R", "n", "seed", "Ts", "process",
                       "Qh", "A"), process=harmonic.HARMONIC)
    g.add_argument("--Q", type=cli.param_type("Q"), default=None, metavar="Q",
                   help="process noise of the Gauss-Markov filter [g2] (default: X^2 / 2)")
    g.add_argument("--P0", type=cli.param_type("P0"), default=None, metavar="P0",
                   help="initial error variance of the filter [g2] (default: X^2 / 2)")
    g.add_argument("--estimator", type=checks.choice_option("estimator", (1, 2, 3)),
                   choices=(1, 2, 3), default=1,
                   help="estimator whose drift is subtracted in z_comp (default: 1, EKF1)")
    g.add_argument("--preset", type=checks.choice_option("preset", tuple(sorted(
                   adxl203.PRESETS))), choices=sorted(adxl203.PRESETS), default=None,
                   help="accelerometer preset (the filter then uses its nominal model; "
                        "a0, a1, a2, R are ignored)")
    cli.add_params(g, ("Xy", "phiy"))
    cli.add_params(g, INPUT_OPTIONS)
    cli.add_out(g, "results/sinusoidal")
    cli.add_fmu_dir(g)
    cli.add_backend(g)
    g.set_defaults(func=_cmd)


def _cmd(args):
    """``driftfmu run sinusoidal``: :func:`driftfmu.run_sinusoidal`."""
    import driftfmu
    from driftfmu.simulations import budget, cli
    budget.check_run("sinusoidal", args.n, args.out, args.backend)
    with cli.progress(args.n, "co-simulation", "sample") as update:
        res = driftfmu.run_sinusoidal(out=args.out, X=args.X, f=args.f, phi=args.phi, Ts=args.Ts,
                             n=args.n, seed=args.seed, a0=args.a0, a1=args.a1, a2=args.a2,
                             R=args.R, process=args.process, Qh=args.Qh, A=args.A, Q=args.Q,
                             P0=args.P0, estimator=args.estimator, preset=args.preset,
                             Xy=args.Xy, phiy=args.phiy, fmu_dir=args.fmu_dir,
                             progress=update, backend=args.backend,
                             **{name: getattr(args, name) for name in INPUT_OPTIONS})
    s = res["summary"]
    f = s["final"]
    print("wrote %s/results.csv, summary.json, drift.png" % args.out)
    wp = s["whole_periods"]
    emp = ("empirical over %d whole periods %.5g" % (wp["periods"],
                                                     f["dc_empirical_whole_periods"])
           if wp["samples"] else "empirical: none (not one whole period)")
    # the references in the order of run gaussian's line: realised, empirical, expected
    print("final drift [V]: EKF1 %.5g, EKF2 %.5g, EKF3 %.5g | realised %.5g, %s, expected %.5g"
          % (f["dc_ekf1"], f["dc_ekf2"], f["dc_ekf3"], f["dc_realised"], emp, f["dc_expected"]))
    e = s["ekf1_rel_error"]

    def pct(v):
        return "n/a" if v is None else "%+.3f %%" % (100 * v)
    print("EKF1 (%s filter) vs expected %s, vs empirical %s"
          % (s["process"], pct(e["vs_expected"]), pct(e["vs_empirical_whole_periods"])))
    if s["empirical_note"]:
        sys.stderr.write("driftfmu: warning: %s\n" % s["empirical_note"])
    print("validation: FMU outputs equal models/ (max |diff| %.3g, tolerance %g)"
          % (max(s["validation"]["max_abs_diff"].values()), s["validation"]["tolerance"]))
