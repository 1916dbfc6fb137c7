"""Internal (not a stable API; use driftfmu.experiment_drift_classes instead).

The letter's four drift classes, each alone and then all together, estimated and removed by the
DriftEstimator, through the FMUs.

The chain Excitation (Gaussian, the letter's ``A = 0, Q = 0.01``) -> Accelerometer (the class's
terms on) -> DriftEstimator (the class's remedy: EKF1 for class 1; the tilt ``theta`` and the
temperature ``T`` wired to it with the sensor's coefficients for class 2; the bias state for
classes 3 and 4, ``Qb`` from the guidance ``Qb = K^2 Ts``) is co-simulated, ``runs`` runs per
case (run ``r`` with FMU seed ``seed + r``), and every recorded output is checked against the
same models/ functions run on arrays (:func:`reference`), bit for bit.

Per case and run, over the settled window (the samples after the first ``settle`` share of
the run), with ``v_k`` the sensor's measurement draw (a pure function of the seed and ``k``):

* the true drift ``d_k = z_k - a0 - a1 x_k - sqrt(R) v_k``: everything the sensor adds to its
  ideal linear response beyond the white noise (class 1's ``a2 x_k^2``, the tilt's and the
  temperature's offset, the exposure drift, the biases);
* the estimate ``dc_k + b_hat_k + dc_class2_k`` (EKF1, the bias state, the class-2 offset);
* the residual ``r_k = z_comp_k - a0 - a1 x_k - sqrt(R) v_k = d_k - (dc_k + b_hat_k +
  dc_class2_k)``;

and the drift (uncompensated) and residual drift (compensated) are the window means of ``d``
and ``r``.  :func:`sigma` gives the standard deviation of the residual's window mean from the
settings (the filter's steady state and the window's length), and the bound on the residual is
:data:`K_SIGMA` times it (docs/method.md, section 12).
"""
import math
import os
import time
from concurrent.futures import as_completed
from pathlib import Path

import numpy as np

from driftfmu.models import bias as bias_model
from driftfmu.models import chain, drift, errors, excitation, sensor
from driftfmu.models.noise import STREAM_PROCESS, normal
from driftfmu.simulations import batch, output
from driftfmu.simulations.gaussian import ValidationError

#: The letter's Sec. III settings (sensor, excitation, filter, sample time) and the experiment's.
LETTER = dict(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, Ts=1e-3)
#: ``n`` samples per run, ``runs`` runs per case, the settled window (the samples after the
#: first ``settle`` share of each run), the coefficients' error ``wrong`` of the class-2 case
#: that gives the estimator coefficients off by that fraction, and the block length (samples)
#: of the figure's curves.
DEFAULTS = dict(n=40000, runs=3, seed=1, settle=0.5, wrong=0.10, block=1000)
#: The residual drift is bounded by this many standard deviations of its window mean (:func:`sigma`).
K_SIGMA = 4.0

#: The classes' terms, at sizes that stand clear of the letter's noise over a window of seconds
#: (the letter gives no sizes for classes 2 to 4).  Class 2: a tilt and a temperature 30 K
#: above ``T0``; class 3: the exposure drift, whose time constant is ``E_tau / E[x^2] = 5 s``;
#: class 4: a turn-on bias, a random walk, a Gauss-Markov bias and a flicker band.
CLASS2 = dict(theta=0.1, T=298.15 + 30.0, T0=298.15, kT_bias=5e-3, kT_scale=1e-3)
CLASS3 = dict(d_inf=0.1, E_tau=0.05)
CLASS4 = dict(bias_on=0.1, random_walk=2e-3, bias_gm=0.01, tau_gm=5.0, flicker=5e-3,
              tau_min=1.0, tau_max=100.0)
#: The cases: name -> (the class it shows, what differs from the letter's sensor).
CASES = ("class 1", "class 2", "class 2, coefficients off", "class 2, coefficients off, bias "
         "state", "class 3", "class 4", "all classes")
#: The panel of each case in the figure (one per class, and all together).
PANELS = (("class 1", ("class 1",)),
          ("class 2", ("class 2", "class 2, coefficients off",
                       "class 2, coefficients off, bias state")),
          ("class 3", ("class 3",)), ("class 4", ("class 4",)), ("all", ("all classes",)))
#: CSV columns of the table (one row per case; means over the runs) [V] and fractions [1].
CSV_COLUMNS = ("case", "bias", "drift", "estimate", "residual", "bound", "fraction",
               "fraction_bound", "class1_true", "dc", "b_hat", "dc_class2")
#: Recorded FMU outputs by FMU.
RECORD = {"Excitation": ["x"], "Accelerometer": ["z"],
          "DriftEstimator": ["dc", "b_hat", "dc_class2", "z_comp", "x_hat"]}
FMU_NAMES = ("Excitation", "Accelerometer", "DriftEstimator")
#: The chain's connections; the DriftEstimator's ``theta`` and ``T`` take the sensor's values
#: (start values of the inputs both FMUs have: :func:`start_values`).
CONNECTIONS = (("Excitation", "x", "Accelerometer", "x"),
               ("Accelerometer", "z", "DriftEstimator", "z"))


# -- the cases ----------------------------------------------------------------------------------

def _random_walk_qb(ecfg):
    """``Qb`` of a sensor's class-4 processes: the sum of their variances per sample (the random
    walk's ``K^2 Ts``, the Gauss-Markov bias's and each flicker component's
    ``sigma^2 (1 - exp(-2 Ts / tau))``), as one random walk."""
    return ecfg.rw * ecfg.rw + ecfg.gm_c * ecfg.gm_c + sum(c * c for c in ecfg.fl_c)


def qb_exposure(d_inf, E_tau, Ex2, Ts):
    """``Qb`` for the exposure drift (class 3): the random walk ``K = d_inf / sqrt(t_E)`` that
    grows by ``d_inf`` over the drift's time constant ``t_E = E_tau / E[x^2]``, ``Qb = K^2 Ts``
    (:func:`driftfmu.models.bias.qb_random_walk`)."""
    return bias_model.qb_random_walk(d_inf / math.sqrt(E_tau / Ex2), Ts)


def case_values(case, s):
    """``(sensor, estimator)``: the case's Accelerometer terms (its slow errors and inputs, and
    ``a2``) and the DriftEstimator's settings (``a2``, ``bias``, ``Qb``, ``tau_b``, ``b0``,
    ``Pb0``, the class-2 inputs and coefficients)."""
    if case not in CASES:
        raise ValueError("case = %r is not allowed; allowed: %s" % (case, ", ".join(CASES)))
    a2 = s["a2"] if case in ("class 1", "all classes") else 0.0
    sens, est = {"a2": a2}, {"a2": a2}
    qb, pb0 = 0.0, 0.0
    if case.startswith("class 2") or case == "all classes":
        sens.update(CLASS2)
        est.update(CLASS2)
        if "off" in case:
            est.update(kT_bias=CLASS2["kT_bias"] * (1.0 + s["wrong"]),
                       kT_scale=CLASS2["kT_scale"] * (1.0 + s["wrong"]))
        if case.endswith("bias state"):
            # a constant error: Qb = 0, its prior the size of the coefficients' error
            off = errors.class2_offset(CLASS2["theta"], CLASS2["T"], s["a1"], a2,
                                       CLASS2["T0"], CLASS2["kT_bias"], CLASS2["kT_scale"])
            pb0 = (s["wrong"] * off) ** 2
            est.update(bias=1)
    if case in ("class 3", "all classes"):
        sens.update(CLASS3)
        qb += qb_exposure(CLASS3["d_inf"], CLASS3["E_tau"], s["Q"] / (1.0 - s["A"] ** 2),
                          s["Ts"])
        est.update(bias=1)  # (the exposure starts at 0: no prior of its own)
    if case in ("class 4", "all classes"):
        sens.update(CLASS4)
        ecfg = errors.config(seed=1, Ts=s["Ts"], **CLASS4)
        qb += _random_walk_qb(ecfg)
        pb0 += (CLASS4["bias_on"] ** 2 + CLASS4["bias_gm"] ** 2
                + ecfg.fl_n * ecfg.fl_sigma ** 2)
        est.update(bias=1)
    if est.get("bias") == 1:
        if pb0 == 0.0:  # (class 3: the drift starts at 0; a prior that lets it move)
            pb0 = qb
        est.update(Qb=qb, tau_b=0.0, b0=0.0, Pb0=pb0)
    return sens, est


def start_values(case, s, seed):
    """Start values of the three FMUs of a case's run with FMU ``seed``: the sensor's tilt and
    temperature inputs, and the same values at the DriftEstimator's (the wiring)."""
    sens, est = case_values(case, s)
    model = {k: s[k] for k in ("a0", "a1", "R")}
    P0 = s["Q"] / (1.0 - s["A"] ** 2)
    return {"Excitation": dict(kind=excitation.GAUSSIAN, A=s["A"], Q=s["Q"], x0=0.0, Ts=s["Ts"],
                               seed=seed),
            "Accelerometer": dict(model, seed=seed, Ts=s["Ts"], noise=1, **sens),
            "DriftEstimator": dict(model, A=s["A"], Q=s["Q"], x0=0.0, P0=P0, Ts=s["Ts"],
                                   estimator=1, **est)}


# -- the reference: the same models/ functions on arrays ---------------------------------------

def reference(case, s, seeds, n):
    """The chain of a case for the runs ``seeds`` (uint64 array) through models/, as the FMUs
    compute it: ``{column: (runs, n) array}`` for the columns of :data:`RECORD` and ``v`` (the
    measurement draws)."""
    sens, est = case_values(case, s)
    seeds = np.asarray(seeds, dtype=np.uint64)
    runs = seeds.shape[0]
    a0, a1, R, A, Q, Ts = s["a0"], s["a1"], s["R"], s["A"], s["Q"], s["Ts"]
    a2s, a2 = sens["a2"], est["a2"]
    slow_values = {k: v for k, v in sens.items() if k != "a2"}
    slow = chain.SensorErrors(seeds, a0, a1, a2s, R, 0.0, 0.0, Ts, slow_values) \
        if slow_values else None
    c2 = {k: est.get(k, errors.OFF.get(k, errors.INPUTS.get(k))) for k in
          ("theta", "T", "T0", "kT_bias", "kT_scale")}
    on2 = c2["theta"] != 0.0 or c2["kT_bias"] != 0.0 or c2["kT_scale"] != 0.0
    offset = errors.class2_offset(c2["theta"], c2["T"], a1, a2, c2["T0"], c2["kT_bias"],
                                  c2["kT_scale"]) if on2 else 0.0
    P0 = Q / (1.0 - A * A)
    x = np.zeros(runs)
    state = chain.estimator_init(np.zeros(runs), np.full(runs, P0))
    b = None
    if est.get("bias") == 1:
        b = bias_model.init(np.full(runs, est["b0"]), np.full(runs, est["Pb0"]))
        Fb = bias_model.factor(est["tau_b"], Ts)
    cols = {c: np.empty((n, runs)) for c in ("x", "z", "dc", "b_hat", "dc_class2", "z_comp",
                                             "x_hat", "v")}
    row = seeds[None, :]
    ks = np.arange(1, n + 1, dtype=np.uint64)[:, None]
    W = normal(row, STREAM_PROCESS, ks)
    V = sensor.measurement_noise(row, ks)
    plain = slow is None or slow.plain
    if not plain:  # the processes' draws at once, as the batch engine takes them
        D = batch._error_draws(row, ks, slow.ecfg)
    for i in range(n):
        k = i + 1
        x = excitation.gauss_markov(x, A, Q, W[i])
        if plain:
            z = sensor.measure(x, a0, a1, a2s, R, V[i])
        else:
            z = slow.measure(x, V[i], k, (D[0][i], D[1][i], tuple(d[i] for d in D[2])))
        zc = z - offset if on2 else z
        if b is None:
            state = chain.estimator_step(state, zc, a0, a1, a2, A, Q, R)
        else:
            state, b = bias_model.estimator_step(state, b, zc, a0, a1, a2, A, Q, R, Fb,
                                                 est["Qb"])
        dc = drift.select(drift.estimates(state.drift, a2, 0.0, 0.0), 1)
        cols["x"][i], cols["z"][i], cols["v"][i] = x, z, V[i]
        cols["dc"][i], cols["x_hat"][i] = dc, state.x
        cols["dc_class2"][i] = offset
        if b is None:
            cols["b_hat"][i] = 0.0
            cols["z_comp"][i] = chain.compensate(zc, dc)
        else:
            cols["b_hat"][i] = b.b
            cols["z_comp"][i] = bias_model.compensate(zc, dc, b.b)
    return {c: np.ascontiguousarray(v.T) for c, v in cols.items()}


# -- what is measured ---------------------------------------------------------------------------

def window_start(n, settle):
    """The number of samples before the settled window: ``floor(settle n)``; the window is the
    samples ``window_start + 1 .. n``."""
    return int(math.floor(settle * n))


def drift_and_residual(cols, s):
    """Per run (arrays over the runs' axis 0) and sample: the true drift ``d = z - a0 - a1 x -
    sqrt(R) v`` and the residual ``r = z_comp - a0 - a1 x - sqrt(R) v``."""
    ideal = s["a0"] + s["a1"] * cols["x"] + math.sqrt(s["R"]) * cols["v"]
    return cols["z"] - ideal, cols["z_comp"] - ideal


def window_means(cols, s, settle):
    """The window means (over the settled window) per run: ``drift``, ``residual``, the
    estimate's parts ``dc``, ``b_hat``, ``dc_class2`` and their sum ``estimate``, and class 1's
    true part ``a2 mean(x^2)`` (``class1_true``)."""
    n = cols["z"].shape[1]
    w = slice(window_start(n, settle), n)
    d, r = drift_and_residual(cols, s)
    out = {"drift": d[:, w].mean(axis=1), "residual": r[:, w].mean(axis=1)}
    for c in ("dc", "b_hat", "dc_class2"):
        out[c] = cols[c][:, w].mean(axis=1)
    out["estimate"] = out["dc"] + out["b_hat"] + out["dc_class2"]
    out["class1_true"] = cols["a2"] * (cols["x"][:, w] ** 2).mean(axis=1)
    return out


def sigma(case, s):
    """Standard deviation of the residual's window mean [V] from the settings: the window of
    ``W = n - floor(settle n)`` samples after ``k_s = floor(settle n)``.

    * class 1's EKF1 error: ``a2 sqrt((2 sigma_x^4 + 4 sigma_x^2 P) (1/W + 1/k_s))`` (the
      window's realised ``a2 mean(x^2)`` against EKF1's running mean over all samples; ``P``
      the filter's steady variance ``Q R / (Q + R)``);
    * the bias state's error: a random walk (``Qb > 0``) in its steady state, ``p = (Qb +
      sqrt(Qb^2 + 4 Qb r)) / 2``, gain ``g = p / (p + r)``, variance ``P_bb = g r``, an
      AR(1) error of coefficient ``1 - g`` whose window mean has the variance
      ``P_bb (2 - g) / (g W)``; a constant (``Qb = 0``) the variance ``1 / (1/Pb0 + k_s / r)``
      at the window's start; ``r = a1^2 sigma_x^2 + R`` (the white state is the bias filter's
      noise);
    * the class-2 scale factor's and the tilt's zero-mean terms ``a1 kT_scale dT x`` and ``2 a2
      g x``: ``|a1 kT_scale dT + 2 a2 g| sigma_x / sqrt(W)``.
    """
    sens, est = case_values(case, s)
    n = s["n"]
    ks = window_start(n, s["settle"])
    W = n - ks
    vx = s["Q"] / (1.0 - s["A"] ** 2)
    var = 0.0
    a2 = est["a2"]
    if a2 != 0.0:
        P = s["Q"] * s["R"] / (s["Q"] + s["R"])
        var += a2 * a2 * (2.0 * vx * vx + 4.0 * vx * P) * (1.0 / W + 1.0 / max(ks, 1))
    if est.get("bias") == 1:
        r = s["a1"] ** 2 * vx + s["R"]
        Qb = est["Qb"]
        if Qb > 0.0:
            p = (Qb + math.sqrt(Qb * Qb + 4.0 * Qb * r)) / 2.0
            g = p / (p + r)
            var += g * r * (2.0 - g) / (g * W)
        else:
            var += 1.0 / (1.0 / est["Pb0"] + max(ks, 1) / r)
    if "theta" in sens:
        dT = sens["T"] - sens["T0"]
        g2 = (1.0 + sens["kT_scale"] * dT) * math.sin(sens["theta"])
        var += (s["a1"] * sens["kT_scale"] * dT + 2.0 * sens["a2"] * g2) ** 2 * vx / W
    return math.sqrt(var)


def drift_size(case, s):
    """The case's nominal drift size ``D`` [V] over the window: class 1's ``a2 sigma_x^2``, the
    class-2 offset (or, with the coefficients off, the offset's error, what the compensation
    must remove beyond the estimator's own), the exposure drift at the window's start
    ``d_inf (1 - exp(-k_s Ts sigma_x^2 / E_tau))``, class 4's root-mean-square
    ``sqrt(bias_on^2 + bias_gm^2 + flicker^2 + K^2 t)`` at the window's middle ``t``; all
    together: the deterministic ones summed, and class 4's in quadrature."""
    sens, est = case_values(case, s)
    n, Ts = s["n"], s["Ts"]
    ks = window_start(n, s["settle"])
    vx = s["Q"] / (1.0 - s["A"] ** 2)
    det, rand2 = 0.0, 0.0
    if sens["a2"] != 0.0:
        det += sens["a2"] * vx
    if "theta" in sens:
        true2 = errors.class2_offset(sens["theta"], sens["T"], s["a1"], sens["a2"], sens["T0"],
                                     sens["kT_bias"], sens["kT_scale"])
        if "off" in case:
            det += abs(errors.class2_offset(est["theta"], est["T"], s["a1"], est["a2"],
                                            est["T0"], est["kT_bias"], est["kT_scale"])
                       - true2)
        else:
            det += true2
    if "d_inf" in sens:
        det += sens["d_inf"] * (1.0 - math.exp(-ks * Ts * vx / sens["E_tau"]))
    if "bias_on" in sens:
        t = 0.5 * (ks + n) * Ts
        rand2 += (sens["bias_on"] ** 2 + sens["bias_gm"] ** 2 + sens["flicker"] ** 2
                  + sens["random_walk"] ** 2 * t)
    return math.sqrt(det * det + rand2)


def expected_residual(case, s):
    """The residual drift the case leaves by design [V]: with the class-2 coefficients off and
    no bias state, the offset's error (the true offset less the one removed); 0 otherwise."""
    if case != "class 2, coefficients off":
        return 0.0
    sens, est = case_values(case, s)
    args = ("theta", "T")
    true2 = errors.class2_offset(*(sens[k] for k in args), s["a1"], sens["a2"], sens["T0"],
                                 sens["kT_bias"], sens["kT_scale"])
    return true2 - errors.class2_offset(*(est[k] for k in args), s["a1"], est["a2"], est["T0"],
                                        est["kT_bias"], est["kT_scale"])


def bound(case, s):
    """The bound on a run's residual drift [V]: :data:`K_SIGMA` times :func:`sigma`."""
    return K_SIGMA * sigma(case, s)


# -- the experiment -----------------------------------------------------------------------------

def check_settings(s):
    """UsageError naming every bad setting and what is allowed."""
    from driftfmu.models import parameters
    from driftfmu.simulations import checks
    problems = [checks.number_problem(k, s[k]) for k in LETTER if k in parameters.PARAMETERS]
    problems.append(checks.count_problem("n", s["n"], 2))
    problems.append(checks.count_problem("runs", s["runs"], 1))
    for name in ("settle", "wrong"):
        v = s[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or not 0.0 <= v < 1.0:
            problems.append("%s = %r is not allowed; allowed: a number in [0, 1)" % (name, v))
    block = s["block"]
    if isinstance(block, bool) or not isinstance(block, int) or block < 1:
        problems.append("block = %r is not allowed; allowed: a whole number >= 1" % (block,))
    checks.refuse([p for p in problems if p])
    if isinstance(s["n"], int) and isinstance(s["settle"], float) and \
            s["n"] - window_start(s["n"], s["settle"]) < 2:
        checks.refuse(["n = %d with settle = %r leaves %d samples in the settled window; "
                       "allowed: at least 2" % (s["n"], s["settle"],
                                                s["n"] - window_start(s["n"], s["settle"]))])


def fmu_paths(fmu_dir, backend="python"):
    """Paths of the three FMUs (built first when any is missing)."""
    from driftfmu.simulations.gaussian import fmu_paths as paths_of
    return {k: str(v) for k, v in paths_of(fmu_dir, backend).items()}


def _fmu_task(task):
    """Worker: co-simulate one run of one case; the recorded columns by name."""
    from driftfmu.simulations.gaussian import master
    paths, case, s, seed, backend = task
    raw = master(backend)(paths, CONNECTIONS, s["n"], s["Ts"],
                          start_values=start_values(case, s, seed),
                          record={k: list(v) for k, v in RECORD.items()})
    return {v: raw["%s.%s" % (name, v)] for name, vs in RECORD.items() for v in vs}


def run_drift_classes(out=None, fmu_dir="build/fmus", backend="python", workers=None,
                      progress=None, plot=True, **settings):
    """Co-simulate every case of :data:`CASES` ``runs`` times; with ``out`` write
    ``drift_classes.csv``, ``drift_classes.json`` and (with ``plot``) ``drift_classes.png``
    (all or none).
    Returns the summary (the JSON's content).

    Raises
    ------
    ValueError
        A bad setting (before anything runs).
    ValidationError
        An FMU output differs from models/ run directly (nothing is written).
    """
    from driftfmu.simulations import checks
    unknown = set(settings) - set(DEFAULTS) - set(LETTER)
    if unknown:
        checks.check_keywords("run_drift_classes()", settings,
                              checks.keywords_of(run_drift_classes, dict(DEFAULTS, **LETTER)))
    s = dict(LETTER, **DEFAULTS)
    s.update(settings)
    check_settings(s)
    n, runs = s["n"], s["runs"]
    seeds = batch.run_seeds(s["seed"], runs)
    t0 = time.perf_counter()
    paths = fmu_paths(fmu_dir, backend)
    workers = workers or os.cpu_count() or 1
    cols = {}
    done = 0
    with batch.process_pool(workers, "driftfmu.simulations.drift_classes") as pool:
        futs = {pool.submit(_fmu_task, (paths, case, s, int(sd), backend)): (case, r)
                for case in CASES for r, sd in enumerate(seeds)}
        from driftfmu.simulations.cli import start_work
        start_work(progress, min(workers, len(futs)))
        for fut in as_completed(futs):
            cols[futs[fut]] = fut.result()
            done += 1
            if progress is not None:
                progress(done)
    from driftfmu.simulations.cli import start_phase
    start_phase(progress, "validation (FMU outputs against models/)", len(CASES), "case")
    worst = 0.0
    rows, traces = [], {}
    for i, case in enumerate(CASES):
        ref = reference(case, s, seeds, n)
        fmu = {c: np.array([cols[(case, r)][c] for r in range(runs)]) for c in
               ("x", "z", "dc", "b_hat", "dc_class2", "z_comp", "x_hat")}
        for c, values in fmu.items():
            diff = np.abs(values - ref[c])
            d = float(np.max(diff)) if not np.isnan(diff).any() else math.inf
            worst = max(worst, d)
        fmu["v"] = ref["v"]
        rows.append(summarise_case(case, s, fmu))
        traces[case] = block_traces(fmu, s)
        if progress is not None:
            progress(i + 1)
    if worst != 0.0:
        raise ValidationError("FMU outputs differ from models/ run directly by %.3g; "
                              "allowed: equal bit for bit" % worst)
    wall = time.perf_counter() - t0
    summary = {
        "settings": dict(s, seeds="run r uses FMU seed seed + r", class2=CLASS2, class3=CLASS3,
                         class4=CLASS4, k_sigma=K_SIGMA,
                         window="samples %d..%d" % (window_start(n, s["settle"]) + 1, n)),
        "definitions": {
            "drift": "window mean of d = z - a0 - a1 x - sqrt(R) v (the uncompensated drift)",
            "estimate": "window mean of dc + b_hat + dc_class2",
            "residual": "window mean of z_comp - a0 - a1 x - sqrt(R) v (the compensated "
                        "output's residual drift)",
            "bound": "K_SIGMA sigma: sigma the standard deviation of the residual's window mean "
                     "from the settings (docs/method.md, section 12); a run is within it when "
                     "|residual - expected_residual| <= bound",
            "expected_residual": "the offset's error left by design (class 2 with the "
                                 "coefficients off and no bias state), else 0",
            "fraction": "max over the runs of |residual| / |drift|",
            "fraction_bound": "bound / D, D the case's nominal drift size"},
        "cases": rows,
        "claims": {"residual_within_bound_everywhere": all(r["within_bound"] for r in rows),
                   "bias_state_absorbs_class2_error": absorbs(rows)},
        "validation": {"reference": "the same models/ functions on arrays, same seeds",
                       "max_abs_diff": worst, "bit_identical": worst == 0.0},
        "wall_time_s": wall, "workers": workers, "backend": backend,
    }
    if out is not None:
        with output.staged(out) as stage:
            table = {c: [] for c in CSV_COLUMNS}
            for j, r in enumerate(rows):
                table["case"].append(j + 1)
                for c in CSV_COLUMNS[1:]:
                    table[c].append(r[c])
            output.write_csv(stage / "drift_classes.csv", table, CSV_COLUMNS)
            output.write_json(stage / "drift_classes.json", summary)
            if plot:
                plot_drift_classes(stage / "drift_classes.png", summary, traces)
    return summary


def absorbs(rows):
    """Whether, with the class-2 coefficients off, every run's residual with the bias state is
    smaller than without it."""
    by = {r["case"]: r for r in rows}
    off, on = by["class 2, coefficients off"], by["class 2, coefficients off, bias state"]
    return all(abs(a) < abs(b) for a, b in zip(on["residuals"], off["residuals"]))


def summarise_case(case, s, cols):
    """The table row of one case from its runs' columns (arrays ``(runs, n)``)."""
    sens, est = case_values(case, s)
    cols = dict(cols, a2=sens["a2"])
    m = window_means(cols, s, s["settle"])
    bnd = bound(case, s)
    size = drift_size(case, s)
    expected = expected_residual(case, s)
    frac = np.abs(m["residual"]) / np.abs(m["drift"])
    row = {"case": case, "bias": int(est.get("bias", 0)), "runs": int(len(m["drift"])),
           "drift": float(np.mean(m["drift"])), "estimate": float(np.mean(m["estimate"])),
           "residual": float(np.mean(m["residual"])), "bound": bnd, "drift_size": size,
           "fraction": float(np.max(frac)), "fraction_bound": bnd / size,
           "class1_true": float(np.mean(m["class1_true"])), "dc": float(np.mean(m["dc"])),
           "b_hat": float(np.mean(m["b_hat"])), "dc_class2": float(np.mean(m["dc_class2"])),
           "drifts": [float(v) for v in m["drift"]],
           "residuals": [float(v) for v in m["residual"]],
           "estimator": {k: v for k, v in est.items()}}
    row["expected_residual"] = expected
    row["within_bound"] = bool(np.all(np.abs(m["residual"] - expected) <= bnd))
    return row


def block_traces(cols, s):
    """Block means (blocks of ``block`` samples) of the first run's true drift, estimate and
    residual, for the figure."""
    d, r = drift_and_residual(cols, s)
    est = cols["dc"] + cols["b_hat"] + cols["dc_class2"]
    L = s["block"]
    m = d.shape[1] // L
    if m == 0:
        L, m = d.shape[1], 1

    def blocks(a):
        return a[0, :m * L].reshape(m, L).mean(axis=1).tolist()
    return {"t": [(j + 0.5) * L * s["Ts"] for j in range(m)], "drift": blocks(d),
            "estimate": blocks(est), "residual": blocks(r)}


def plot_drift_classes(path, summary, traces):
    """One panel per class (and all together): block means of the first run's true drift, the
    estimate and the residual [mV] against time, the settled window shaded."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    st = summary["settings"]
    fig, axes = plt.subplots(len(PANELS), 1, figsize=(9, 2.3 * len(PANELS)), sharex=True)
    t_s = window_start(st["n"], st["settle"]) * st["Ts"]
    rows = {r["case"]: r for r in summary["cases"]}
    for ax, (title, cases) in zip(axes, PANELS):
        first = traces[cases[0]]
        ax.plot(first["t"], [1e3 * v for v in first["drift"]], color="k", lw=1.2,
                label="true drift")
        ax.plot(first["t"], [1e3 * v for v in first["estimate"]], color="C0", lw=1.0,
                label="estimate dc + b_hat + dc_class2")
        # the residuals: on the same axis for one case; on an axis of their own (right)
        # where the variants' residuals are small beside the drift
        right = ax.twinx() if len(cases) > 1 else ax
        for j, case in enumerate(cases):
            tr = traces[case]
            label = "residual of z_comp" + ("" if len(cases) == 1 else " (%s, right axis)"
                                            % _short(case))
            right.plot(tr["t"], [1e3 * v for v in tr["residual"]], color="C%d" % (3 + j),
                       ls=("-", "--", ":")[j], lw=1.0, label=label)
        if right is not ax:
            right.set_ylabel("residual [mV]", fontsize=8)
            right.axhline(0.0, color="0.5", lw=0.5)
        ax.axvspan(t_s, st["n"] * st["Ts"], color="0.9", zorder=0)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel("[mV]")
        text = ", ".join("%.3g" % (1e3 * rows[c]["residual"]) for c in cases)
        ax.set_title("%s: residual %s mV of a drift of %.4g mV (means over the window and %d "
                     "runs)" % (title + ("" if len(cases) == 1 else " (%s)" % "; ".join(
                         _short(c) for c in cases)), text, 1e3 * rows[cases[0]]["drift"],
                                rows[cases[0]]["runs"]), fontsize=8)
        handles, labels = ax.get_legend_handles_labels()
        if right is not ax:
            h, lab = right.get_legend_handles_labels()
            handles, labels = handles + h, labels + lab
        ax.legend(handles, labels, fontsize=6, loc="center right", ncol=1)
    axes[-1].set_xlabel("time [s] (block means of %d samples; run 1; the settled window shaded)"
                        % st["block"])
    fig.suptitle("Drift classes estimated and removed by the DriftEstimator\n(a2 = %g, "
                 "Q = %g, R = %g, Ts = %g s, n = %d)"
                 % (st["a2"], st["Q"], st["R"], st["Ts"], st["n"]), fontsize=10)
    output.layout(fig, rect=(0, 0, 1, 0.97))
    output.savefig(fig, path, dpi=110)
    plt.close(fig)


def _short(case):
    """A case's name in a legend: what differs within the class-2 panel."""
    return {"class 2": "coefficients known", "class 2, coefficients off": "coefficients off",
            "class 2, coefficients off, bias state": "off, bias state"}.get(case, case)


# -- command line -------------------------------------------------------------------------------

def add_cli(groups):
    """``driftfmu experiment drift-classes``."""
    from driftfmu.simulations import checks, cli
    g = groups["experiment"].add_parser(
        "drift-classes", help="the letter's four drift classes, each alone and all together: "
        "the true drift, the DriftEstimator's estimate and the compensated output's residual")
    g.add_argument("--runs", type=checks.count_option("runs", 1), default=DEFAULTS["runs"],
                   help="runs per case (default: %d)" % DEFAULTS["runs"])
    g.add_argument("--settle", type=_fraction_option("settle"), default=DEFAULTS["settle"],
                   help="share of each run before the settled window (default: %g)"
                   % DEFAULTS["settle"])
    g.add_argument("--wrong", type=_fraction_option("wrong"), default=DEFAULTS["wrong"],
                   help="fraction by which the class-2 coefficients given to the estimator are "
                   "off in the 'coefficients off' cases (default: %g)" % DEFAULTS["wrong"])
    cli.add_params(g, ("n", "seed"), n=DEFAULTS["n"])
    g.add_argument("--workers", type=checks.count_option("workers", 1), default=None,
                   help="parallel processes (default: the number of cores)")
    cli.add_out(g, "results/drift_classes")
    cli.add_fmu_dir(g)
    cli.add_backend(g)
    g.set_defaults(func=_cmd)


def _fraction_option(name):
    """An argparse type: a number in [0, 1) (else the usage error names it)."""
    import argparse

    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError("%s = %r is not allowed; allowed: a number in "
                                             "[0, 1)" % (name, text)) from None
        if not math.isfinite(v) or not 0.0 <= v < 1.0:
            raise argparse.ArgumentTypeError("%s = %r is not allowed; allowed: a number in "
                                             "[0, 1)" % (name, v))
        return v
    return parse


def _cmd(args):
    """``driftfmu experiment drift-classes``: :func:`driftfmu.experiment_drift_classes`."""
    import driftfmu
    from driftfmu.simulations import budget, cli
    s = dict(LETTER, **DEFAULTS)
    s.update(n=args.n, runs=args.runs, seed=args.seed, settle=args.settle, wrong=args.wrong)
    check_settings(s)
    budget.check_drift_classes(args.runs, args.n, args.workers, args.out, args.backend,
                               announce=True)
    with cli.progress(len(CASES) * args.runs, "runs", "run", monitor=False) as update:
        summary = driftfmu.experiment_drift_classes(
            out=args.out, n=args.n, runs=args.runs, seed=args.seed, settle=args.settle,
            wrong=args.wrong, workers=args.workers, fmu_dir=args.fmu_dir,
            backend=args.backend, progress=update)
    print("wrote %s/drift_classes.csv, drift_classes.json, drift_classes.png" % args.out)
    print(format_table(summary))
    c = summary["claims"]
    print("residual within its bound in every run: %s; the bias state absorbs the class-2 "
          "coefficients' error in every run: %s"
          % ("yes" if c["residual_within_bound_everywhere"] else "NO",
             "yes" if c["bias_state_absorbs_class2_error"] else "NO"))
    print("validation: FMU outputs equal models/ bit for bit: %s"
          % ("yes" if summary["validation"]["bit_identical"] else "NO"))
    print("wall time %.1f s on %d worker(s)" % (summary["wall_time_s"], summary["workers"]))


def format_table(summary):
    """The table as text: per case the drift, estimate, residual and bound [mV] and the
    fractions."""
    lines = ["%-40s %4s | %10s %10s %10s %9s | %8s %8s"
             % ("case", "bias", "drift mV", "estim. mV", "resid. mV", "bound mV", "fraction",
                "bound")]
    for r in summary["cases"]:
        lines.append("%-40s %4d | %10.4f %10.4f %+10.5f %9.5f | %8.4f %8.4f"
                     % (r["case"], r["bias"], 1e3 * r["drift"], 1e3 * r["estimate"],
                        1e3 * r["residual"], 1e3 * r["bound"], r["fraction"],
                        r["fraction_bound"]))
    return "\n".join(lines)
