"""Internal (not a stable API; use driftfmu.run_gaussian instead).

The letter's Gaussian simulation (Sec. III, Fig. 1) as an FMU co-simulation.

Excitation (Gaussian) -> Accelerometer -> DriftEstimator, fixed step ``Ts``, one row per sample.
The master checks the FMUs against :func:`driftfmu.models.chain.simulate` on the same seed, sample by
sample, and reports the drift estimates against the three references.
"""
import inspect
import math
from pathlib import Path

from driftfmu.models import chain, drift, errors, excitation, parameters
from driftfmu.simulations import output
from driftfmu.simulations.cosim import cosimulate
from driftfmu.simulations.errors import UsageError

FMU_NAMES = ("Excitation", "Accelerometer", "DriftEstimator")
CONNECTIONS = (("Excitation", "x", "Accelerometer", "x"),
               ("Accelerometer", "z", "DriftEstimator", "z"))
#: The known input u (eq. 1) from the Excitation to the filter's prediction, wired when B != 0.
INPUT_CONNECTION = ("Excitation", "u", "DriftEstimator", "u")
#: The general model's parameters (issue 16) and the sensor's slow errors (issue 42:
#: :data:`driftfmu.models.chain.SENSOR_ERRORS_OFF`, the letter's drift classes 2 to 4, the tilt
#: and temperature held over a run, the range and the ADC's bits), with their off values: the
#: letter's case.
GENERAL_OFF = dict(dict(a3=0.0, a4=0.0, B=0.0, drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0,
                        fu=0.0), **chain.SENSOR_ERRORS_OFF)
#: The Accelerometer's inputs among them (start values of inputs the master does not connect).
SENSOR_INPUTS = ("theta", "T")


def connections(B=0.0):
    """The chain's connections; with the known input's (:data:`INPUT_CONNECTION`) when
    ``B != 0``."""
    return CONNECTIONS + ((INPUT_CONNECTION,) if B != 0.0 else ())
#: Largest difference allowed between an FMU output and models/ run directly.
TOLERANCE = 1e-12
#: "Within 10 % of the realised drift".
SETTLE_BAND = 0.10
#: Share of a run's samples at its end that an estimate must stay inside the band for to count
#: as settled (:func:`settled_from`).
SETTLE_HOLD = 0.10


class ValidationError(RuntimeError):
    """The co-simulation's outputs disagree with models/ run directly."""


#: The FMUs a master can run: the pythonfmu FMUs (``<fmu_dir>/<Name>.fmu``) or their native C
#: twins, FMI 2.0 (``<fmu_dir>/native/fmi2/<Name>.fmu``), bit-identical.
BACKENDS = ("python", "native")


def check_backend(backend):
    """ValueError unless ``backend`` is one of :data:`BACKENDS`."""
    if backend not in BACKENDS:
        raise ValueError("backend = %r is not allowed; allowed: %s"
                         % (backend, " or ".join(repr(b) for b in BACKENDS)))


def master(backend="python"):
    """The co-simulation loop of ``backend``: fmpy's FMU2Slave wrappers
    (:func:`driftfmu.simulations.cosim.cosimulate`) for the Python FMUs, direct FMI calls
    (:func:`driftfmu.simulations.fastcosim.cosimulate_fast`, same results) for the native ones."""
    check_backend(backend)
    if backend == "native":
        from driftfmu.simulations.fastcosim import cosimulate_fast
        return cosimulate_fast
    return cosimulate


def fmu_paths(fmu_dir, backend="python"):
    """Paths of the three FMUs of ``backend`` under ``fmu_dir``; build them first when any is
    missing."""
    check_backend(backend)
    if backend == "native":
        from driftfmu.fmu_src.native_build import native_fmu_paths
        return native_fmu_paths(fmu_dir, 2)
    fmu_dir = Path(fmu_dir)
    paths = {n: fmu_dir / ("%s.fmu" % n) for n in FMU_NAMES}
    if not all(p.is_file() for p in paths.values()):
        from driftfmu.fmu_src.builder import build_fmus, check_fmu_folder
        check_fmu_folder(fmu_dir, [p.name for p in paths.values() if not p.is_file()])
        build_fmus(fmu_dir)
    return paths


def settle_hold(n):
    """Samples an estimate must stay inside the band at the end of a run of ``n`` samples to
    count as settled: :data:`SETTLE_HOLD` of them, at least one."""
    return max(1, math.ceil(SETTLE_HOLD * n))


def settled_from(estimate, reference, band=SETTLE_BAND):
    """First sample (1-based) from which ``|estimate - reference| <= band |reference|`` holds
    to the end, or None when it does not hold for the last :func:`settle_hold` samples.

    "Settled" means "stays inside from here on": a run that enters the band only in its last
    few samples has not shown that it stays (a sinusoid's empirical drift passes through the
    band at every whole number of periods), so it counts as not settled.
    """
    last_out = 0
    for k, (e, r) in enumerate(zip(estimate, reference), start=1):
        if abs(e - r) > band * abs(r):
            last_out = k
    return None if last_out > len(estimate) - settle_hold(len(estimate)) else last_out + 1


def compare(cols, ref, names=chain.FMU_COLUMNS, tolerance=None):
    """Largest absolute difference per column; the names of the columns over ``tolerance``
    (default :data:`TOLERANCE`)."""
    tolerance = TOLERANCE if tolerance is None else tolerance
    diffs = {c: max(abs(a - b) for a, b in zip(cols[c], ref[c])) for c in names}
    bad = [c for c, d in diffs.items() if not d <= tolerance]
    return diffs, bad


def start_values(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, seed=1, Ts=1e-3, x0=0.0,
                 P0=None, estimator=1, **general):
    """Start values of the three FMUs for the Gaussian run: {FMU name: {variable: value}}.

    The sensor and the filter share the model ``a0, a1, a2, R``; the filter's process model is
    the excitation's ``(A, Q)``; ``P0`` defaults to ``Q / (1 - A^2)``.  ``general``: the
    general model's ``a3, a4`` (sensor and filter), ``B`` (excitation and filter) and the
    known input ``drive, Qu, Xu, fu`` (excitation), and the sensor's slow errors
    (:data:`driftfmu.models.chain.SENSOR_ERRORS_OFF`: the Accelerometer's parameters, and the
    start values of its inputs ``theta`` and ``T``, which no FMU drives, and the same values at
    the DriftEstimator's inputs of the same name: a tilt set reaches both, and the estimator
    removes its offset, :func:`driftfmu.models.chain.wired_offset`); only those given (and not
    off) are set, so the letter's run sets exactly what it always set.
    """
    unknown = set(general) - set(GENERAL_OFF)
    if unknown:
        named = [n for n, p in inspect.signature(start_values).parameters.items()
                 if p.kind is p.POSITIONAL_OR_KEYWORD]
        raise TypeError("unknown parameter(s) %s; allowed: %s" % (
            ", ".join(sorted(unknown)), ", ".join(named + list(GENERAL_OFF))))
    if P0 is None:
        P0 = Q / (1.0 - A * A)
    model = dict(a0=a0, a1=a1, a2=a2, R=R)
    on = {k: v for k, v in general.items() if v != GENERAL_OFF[k]}
    sensor_terms = {k: on[k] for k in ("a3", "a4") if k in on}
    inputs = {k: on[k] for k in ("B", "drive", "Qu", "Xu", "fu") if k in on}
    slow = {k: on[k] for k in chain.SENSOR_ERRORS_OFF if k in on}
    return {
        "Excitation": dict(kind=excitation.GAUSSIAN, A=A, Q=Q, x0=x0, Ts=Ts, seed=seed,
                           **inputs),
        "Accelerometer": dict(model, seed=seed, Ts=Ts, noise=1, **sensor_terms, **slow),
        "DriftEstimator": dict(model, A=A, Q=Q, x0=x0, P0=P0, Ts=Ts, estimator=estimator,
                               **sensor_terms, **({"B": on["B"]} if "B" in on else {}),
                               **{k: on[k] for k in SENSOR_INPUTS if k in on}),
    }


def run_gaussian(out=None, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, n=2000, seed=1,
                 Ts=1e-3, x0=0.0, P0=None, estimator=1, fmu_dir="build/fmus", progress=None,
                 plot=True, backend="python", **general):
    """Co-simulate the three FMUs under Gaussian excitation; optionally write the results.

    Parameters are the letter's names (defaults: its Sec. III settings, 2000 samples).  ``P0``
    defaults to the stationary variance ``Q / (1 - A^2)``.  ``backend`` picks the FMUs
    (:data:`BACKENDS`).  ``general``: the general model's ``a3, a4, B, drive, Qu, Xu, fu``
    (:func:`start_values`); with ``B != 0`` the Excitation's ``u`` is wired to the
    DriftEstimator's.  With ``out`` set, ``results.csv``,
    ``summary.json`` and ``drift.png`` are written there, all of them or none.

    Returns
    -------
    dict
        ``columns`` (the results table as lists) and ``summary``.

    Raises
    ------
    ValueError
        A parameter is out of range (the message says which and what is allowed).
    ValidationError
        An FMU output differs from models/ by more than ``TOLERANCE`` (nothing is written).
    """
    from driftfmu.simulations import checks
    checks.check_keywords("run_gaussian()", general, checks.keywords_of(run_gaussian,
                                                                        GENERAL_OFF))
    params = dict(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, n=n, seed=seed, Ts=Ts, x0=x0)
    if P0 is None:
        P0 = Q / (1.0 - A * A)
    params["P0"] = P0
    general = dict(GENERAL_OFF, **general)
    params.update({k: v for k, v in general.items() if v != GENERAL_OFF[k]})
    problems = parameters.check(params) + errors.problems(params)
    if problems:
        raise UsageError("; ".join(problems))
    if estimator not in (1, 2, 3):
        raise UsageError("estimator = %r is not allowed; allowed: 1, 2 or 3" % (estimator,))
    start = start_values(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, seed=seed, Ts=Ts, x0=x0, P0=P0,
                         estimator=estimator, **general)
    record = {"Excitation": ["x"], "Accelerometer": ["z"],
              "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}
    raw = master(backend)(fmu_paths(fmu_dir, backend), connections(general["B"]), n, Ts,
                          start_values=start, record=record, progress=progress)
    cols = {"time": raw["time"]}
    for name, names in record.items():
        for v in names:
            cols[v] = raw["%s.%s" % (name, v)]
    ref = chain.simulate(n, seed, a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, x0=x0, P0=P0, Ts=Ts,
                         estimator=estimator, **general)
    if general == GENERAL_OFF:
        dc_expected = a2 * excitation.stationary_variance(excitation.GAUSSIAN, A=A, Q=Q)
    else:
        dc_expected = ref["dc_expected"][0]
    cols["dc_empirical"], cols["dc_realised"], cols["dc_expected"] = drift.references(
        cols["x"], cols["z"], a0, a2, dc_expected, general["a3"], general["a4"])
    diffs, bad = compare(cols, ref)
    # the gap's closed form 10 log10(1 + R/(a1^2 Q)) is the letter's quadratic sensor's, at
    # A = 0 without the input (as montecarlo gaussian reports it)
    summary = summarise(cols, params, a1=a1, Q=Q, R=R, A=A if general == GENERAL_OFF else None)
    summary["estimator"] = estimator
    summary["validation"] = {"reference": "models.chain.simulate, same seed",
                             "tolerance": TOLERANCE, "max_abs_diff": diffs,
                             "passed": not bad}
    if bad:
        raise ValidationError(
            "FMU outputs differ from models/ run directly: %s (tolerance %g)"
            % (", ".join("%s by %.3g" % (c, diffs[c]) for c in bad), TOLERANCE))
    if out is not None:
        with output.staged(out) as stage:
            output.write_csv(stage / "results.csv", cols, chain.COLUMNS)
            output.write_json(stage / "summary.json", summary)
            if plot:
                on = {k: v for k, v in general.items() if v != GENERAL_OFF[k]}
                output.plot_drift(stage / "drift.png", cols, plot_title(
                    "Drift estimates of one co-simulation", on, a1=a1, a2=a2, Q=Q, R=R, A=A,
                    n=n, seed=seed), general=on)
    return {"columns": cols, "summary": summary}


def plot_title(what, general, a1, a2, Q, R, A, n, seed=None, runs=None):
    """The caption of a Gaussian run's figure: the letter's Fig. 1 for the letter's sensor;
    for the general sensor, its parameters instead of the letter's name."""
    sensor = "%s, %s" % (output.value_text("a1", a1), output.value_text("a2", a2))
    more = output.general_text(general)
    head = ("%s, the general sensor (%s, method §9)" % (what, more) if more
            else "%s (the letter's Fig. 1%s)" % (what, " as a population" if runs else ""))
    return "%s: Gaussian state, %s, %s, %s, A = %g, n = %d%s" % (
        head, sensor, output.value_text("Q", Q), output.value_text("R", R), A, n,
        "" if seed is None else ", seed %d" % seed)


def summarise(cols, params, a1, Q, R, A):
    """Final drifts, the EKF1-EKF2 gap and when each estimator settles (vs. realised drift);
    the gap's closed form for ``A = 0`` (None: no closed form, the general sensor)."""
    final = {c: cols[c][-1] for c in ("dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_empirical",
                                      "dc_realised", "dc_expected")}
    gap = drift.gap_db(final["dc_ekf1"], final["dc_ekf2"])
    summary = {"parameters": params, "final": final, "ekf1_ekf2_gap_db": gap}
    if A == 0.0:
        expected = drift.expected_gap_db(a1, Q, R)
        summary["ekf1_ekf2_gap_db_expected"] = expected
        summary["ekf1_ekf2_gap_rel_error"] = gap / expected - 1.0 if expected else math.nan
    summary["settled_from_sample"] = {
        "reference": "realised drift %s, band %g %%" % (
            output.drift_labels(params)[0], 100 * SETTLE_BAND),
        "ekf1": settled_from(cols["dc_ekf1"], cols["dc_realised"]),
        "ekf2": settled_from(cols["dc_ekf2"], cols["dc_realised"]),
        "ekf3": settled_from(cols["dc_ekf3"], cols["dc_realised"]),
    }
    return summary
