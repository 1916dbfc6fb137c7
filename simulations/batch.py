"""Internal (not a stable API; use driftfmu.montecarlo or driftfmu.sweep instead).

Batch engine: many Monte-Carlo runs at once, through the same models/ functions as the FMUs.

Runs sit on the leading axis of NumPy arrays.  Sample ``k`` of every run is computed by calling
:mod:`driftfmu.models.excitation`, :mod:`driftfmu.models.sensor`, :mod:`driftfmu.models.chain` (EKF and drift estimators)
and :func:`driftfmu.models.drift.running_mean` on arrays of shape ``(runs,)``, exactly as one FMU calls
them on floats.  Every operation in those functions is correctly rounded IEEE arithmetic, so run
``r`` of a batch gives bit for bit the outputs of the FMU co-simulation of that run.  The noise
is counter-based (:mod:`driftfmu.models.noise`), a pure function of (seed, stream, sample), so it is
generated in blocks of ``(block, runs)`` samples at once and still equals what the FMUs draw.

Seeds: run ``r`` of a batch under ``--seed S`` uses the FMU seed :func:`run_seed` ``(S, r) =
S + r`` for both the Excitation and the Accelerometer.

Parallel: :func:`run_tasks` maps a task function over chunks of runs on local workers
(``concurrent.futures``: threads of this process for chunks in the compiled kernel, whose calls
release the GIL, worker processes otherwise) or on a Dask distributed cluster
(``scheduler=ADDRESS``); the FMU engine (:func:`fmu_task`) is fanned out the same way.
"""
import contextlib
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from driftfmu.models import _ops, chain, drift, excitation, harmonic, noise, parameters, sensor
from driftfmu.simulations import checks
from driftfmu.simulations.errors import UsageError

#: Largest FMU seed (the FMUs' ``seed`` parameter is a 32-bit Integer).
SEED_MAX = parameters.PARAMETERS["seed"].high
#: Trajectories the batch engine can record, each ``(runs, n)``.
TRAJECTORIES = ("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_empirical",
                "dc_realised")
#: Final-sample values every run returns, each ``(runs,)``, under ``"final_<name>"``: the
#: filter state, the three drift estimates, the empirical drift ``z̄ - a0``, the mean square
#: state ``mean(x^2)`` and the realised drift ``mean(a2 x^2 + a3 x^3 + a4 x^4)`` (``a2
#: mean(x^2)`` for the letter's sensor, those bits).
FINALS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "zbar", "x2bar", "dc_realised")
#: With the DriftEstimator's bias state (``bias = 1``): the bias part, as trajectories and
#: under ``"final_<name>"``.
BIAS_OUTPUTS = ("b_hat", "P_bb", "P_xb")
#: Samples of noise generated per block (rows of a ``(block, runs)`` array).
BLOCK = 32
#: Sample-runs per call of the compiled kernel when no one asks for progress (about 0.05 s):
#: long enough that threads running it seldom wait for the GIL, short enough that an
#: interrupted task ends soon.
KERNEL_CALL = 1 << 22
#: Runs per task handed to a worker (large enough for NumPy to be efficient, small enough to
#: stay in cache and to give the progress bar some steps).
CHUNK = 4096
#: Engines of :func:`simulate`: the compiled kernel when available, NumPy, the kernel.
KERNELS = ("auto", "numpy", "c")
#: Seconds to wait for a Dask scheduler before giving up.
CONNECT_TIMEOUT = 3


# -- seeds and checks -----------------------------------------------------------------------
def run_seed(seed, r):
    """FMU seed of run ``r`` (0-based) of a batch under ``seed``: ``seed + r``.

    Used for the Excitation's and the Accelerometer's ``seed`` parameter alike, by the batch
    engine and by the FMU engine.  Works on ints and on integer arrays.
    """
    return seed + r


def run_seeds(seed, runs):
    """The ``uint64`` array of FMU seeds of runs ``0 .. runs-1`` under ``seed``."""
    check_runs(runs)
    seed = int(seed)
    last = run_seed(seed, runs - 1)
    if seed < 0 or last > SEED_MAX:
        raise UsageError("seed = %r with runs = %d needs FMU seeds %d..%d; allowed: "
                         "0 <= seed and seed + runs - 1 <= %d" % (seed, runs, seed, last,
                                                                  SEED_MAX))
    return run_seed(np.uint64(seed), np.arange(runs, dtype=np.uint64))


def check_runs(runs):
    """Raise ValueError unless ``runs`` is an integer >= 1."""
    checks.refuse([checks.count_problem("runs", runs, 1)])


def check_parameters(values):
    """Raise ValueError naming every parameter (scalar or array of per-run values) out of range."""
    problems = []
    for name, value in values.items():
        if name not in parameters.PARAMETERS or value is None:
            continue
        arr = np.asarray(value)
        if arr.size == 0:
            problems.append("%s is empty; allowed: at least one value, %s"
                            % (name, parameters.allowed(name)))
            continue
        for v in np.unique(arr):
            msg = parameters.problem(name, v.item())
            if msg:
                problems.append(msg)
                break
    if problems:
        raise UsageError("; ".join(problems))


def default_P0(A, Q):
    """The filter's initial variance when none is given: the stationary ``Q / (1 - A^2)``."""
    return Q / (1.0 - A * A)


def sine_phase(seed):
    """Random phase in [0, 2 pi) of a sinusoidal run: ``2 pi u`` with ``u`` the first draw of
    stream ``STREAM_PHASE`` under the run's seed (int or ``uint64`` array)."""
    return 2.0 * math.pi * noise.uniform(seed, noise.STREAM_PHASE, 1)


# -- the engine -----------------------------------------------------------------------------
def simulate(n, seeds, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=None,
             Ts=1e-3, kind=excitation.GAUSSIAN, X=1.0, f=150.0, phi=0.0, filter_A=None,
             filter_Q=None, record=(), block=BLOCK, progress=None, kernel="auto", a3=0.0,
             a4=0.0, B=0.0, drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0, fu=0.0, bias=0, Qb=0.0,
             tau_b=0.0, b0=0.0, Pb0=1e-4, **sensor_errors):
    """Run ``len(seeds)`` Monte-Carlo runs of the chain for samples ``k = 1..n`` at once.

    Run ``r`` is the co-simulation of Excitation -> Accelerometer -> DriftEstimator with both
    FMU seeds ``seeds[r]``: the same functions on arrays, so the same bits.

    Parameters
    ----------
    n : int
        Samples per run.
    seeds : array of uint64, shape (runs,)
        FMU seed of each run (see :func:`run_seeds`).
    a0, a1, a2, A, Q, R, x0, P0, Ts, X, f, phi : float or array (runs,)
        The letter's parameters, one value for all runs or one per run.  ``P0`` defaults to
        ``filter_Q / (1 - filter_A^2)``.
    kind : int
        ``excitation.GAUSSIAN`` (``x_k = A x_{k-1} + w_k``) or ``excitation.SINUSOIDAL``
        (``x_k = X sin(2 pi f (k-1) Ts + phi)``).
    filter_A, filter_Q : float or array, optional
        The filter's process model, by default the excitation's ``A`` and ``Q``.
    a3, a4, B, drive, Qu, Xu, fu : optional
        The general sensor (``h`` up to 4th order, sensor and filter alike) and the known input
        ``u`` (:func:`driftfmu.models.excitation.input_sample`) driving the Gaussian state and
        the filter's prediction through ``B``; the defaults are the letter's case, same bits.
    bias, Qb, tau_b, b0, Pb0 : optional
        The DriftEstimator's bias state (:mod:`driftfmu.models.bias`; ``bias = 1``, the
        others floats or arrays ``(runs,)``): the filter tracks ``[x, b]``, its covariance is
        checked after every sample (a :class:`~driftfmu.models.covariance.CovarianceError`
        names the first sample and run where it is not valid, as the FMU refuses it), and
        the results hold :data:`BIAS_OUTPUTS` too.  ``bias = 0`` (default): the letter's
        filter, same bits.
    record : sequence of str
        Names out of :data:`TRAJECTORIES` (and :data:`BIAS_OUTPUTS` with ``bias = 1``) to
        return as ``(runs, n)`` arrays.
    block : int
        Samples of noise generated at once.
    progress : callable, optional
        Called with the number of samples done after each block.
    kernel : {"auto", "numpy", "c"}
        ``"auto"``: the compiled kernel (:mod:`driftfmu.simulations.kernel`) when a C compiler
        is present, NumPy otherwise; ``"numpy"``: NumPy; ``"c"``: the kernel (RuntimeError
        without a compiler).  All give the same bits.
    **sensor_errors
        The sensor's slow errors and range (:data:`driftfmu.models.chain.SENSOR_ERRORS_OFF`:
        ``bias_on, random_walk, bias_gm, tau_gm, flicker, tau_min, tau_max, d_inf, E_tau, T0,
        kT_bias, kT_scale, range``, the tilt ``theta`` and temperature ``T`` held over the runs,
        the ADC's ``bits``), one value for all runs, as the Accelerometer FMU computes them
        (:class:`driftfmu.models.chain.SensorErrors`; each run's processes draw from its own
        seed's streams); off by default, the same bits.

    Returns
    -------
    dict
        ``"final_<name>"`` for the :data:`FINALS` after sample ``n``, each ``(runs,)``, and
        the recorded trajectories by name, each ``(runs, n)``.
    """
    seeds = np.asarray(seeds, dtype=np.uint64)
    runs = seeds.shape[0]
    recordable = TRAJECTORIES + (BIAS_OUTPUTS if bias == 1 else ())
    unknown = set(record) - set(recordable)
    if unknown:
        raise UsageError("cannot record %s; allowed: %s" % (sorted(unknown),
                                                            ", ".join(recordable)))
    if bias not in (0, 1):
        raise UsageError(parameters.problem("bias", bias) or "bias = %r is not allowed; "
                         "allowed: 0 or 1" % (bias,))
    if bias == 1:
        check_parameters(dict(Qb=Qb, tau_b=tau_b, b0=b0, Pb0=Pb0))
    fA = A if filter_A is None else filter_A
    fQ = Q if filter_Q is None else filter_Q
    if P0 is None:
        P0 = default_P0(fA, fQ)
    slow = _sensor_errors(seeds, a0, a1, a2, R, a3, a4, Ts, sensor_errors)
    lib = _kernel_library(kernel)
    if lib is not None:
        if kind == excitation.GAUSSIAN and drive not in excitation.DRIVES:
            excitation.input_sample(drive, 0, 1)  # models/' own error, as the NumPy path's
        return _simulate_kernel(lib, n, seeds, dict(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, x0=x0,
                                                    P0=P0, Ts=Ts, X=X, f=f, phi=phi, fA=fA,
                                                    fQ=fQ, a3=a3, a4=a4, B=B, drive=drive,
                                                    Qu=Qu, Xu=Xu, fu=fu, bias=bias, Qb=Qb,
                                                    tau_b=tau_b, b0=b0, Pb0=Pb0,
                                                    **sensor_errors),
                                kind, record, progress, slow is not None)
    shape = (runs,)
    wired = dict(chain.SENSOR_ERRORS_OFF, **sensor_errors)
    offset = chain.wired_offset(wired["theta"], wired["T"], a1, a2, a3, a4)
    x = np.broadcast_to(np.asarray(x0, dtype=float), shape).copy()
    est = chain.estimator_init(x.copy(), np.broadcast_to(np.asarray(P0, dtype=float),
                                                         shape).copy())
    b = None
    if bias == 1:
        from driftfmu.models import bias as bias_model
        b = bias_model.init(np.broadcast_to(np.asarray(b0, dtype=float), shape).copy(),
                            np.broadcast_to(np.asarray(Pb0, dtype=float), shape).copy())
        Fb = bias_model.factor(tau_b, Ts)
    zbar = 0.0
    x2bar = 0.0
    hbar = 0.0  # realised drift (1/k) sum a2 x^2 + a3 x^3 + a4 x^4 of the general sensor
    quadratic = not sensor.higher(a3, a4)
    traj = {name: np.empty((n, runs)) for name in record}
    gaussian = kind == excitation.GAUSSIAN
    fB = B if gaussian else 0.0
    inputs = gaussian and drive != excitation.DRIVE_OFF
    row = seeds[None, :]
    for k0 in range(1, n + 1, block):
        ks = np.arange(k0, min(k0 + block, n + 1), dtype=np.uint64)[:, None]
        if gaussian:
            W = noise.normal(row, noise.STREAM_PROCESS, ks)
        V = sensor.measurement_noise(row, ks)
        if slow is not None:
            draws = _error_draws(row, ks, slow.ecfg)
        for i in range(ks.shape[0]):
            k = k0 + i
            u = excitation.input_sample(drive, row[0], k, Qu, Xu, fu, Ts) if inputs else 0.0
            if gaussian:
                x = excitation.gauss_markov(x, A, Q, W[i], fB, u)
            else:
                x = excitation.sine(k, X, f, Ts, phi)
            if slow is None:
                z = sensor.measure(x, a0, a1, a2, R, V[i], a3, a4)
            else:
                z = slow.measure(x, V[i], k, (draws[0][i], draws[1][i],
                                              tuple(d[i] for d in draws[2])))
            ze = z if offset is None else z - offset  # (the tilt wired to the estimator)
            if b is None:
                est = chain.estimator_step(est, ze, a0, a1, a2, fA, fQ, R, a3, a4, fB, u)
            else:
                est, b = bias_model.estimator_step(est, b, ze, a0, a1, a2, fA, fQ, R, Fb, Qb,
                                                   a3, a4, fB, u)
                bias_model.check(est, b, k, seeds)
            zbar = drift.running_mean(zbar, z, k)
            x2 = x * x
            x2bar = drift.running_mean(x2bar, x2, k)
            if not quadratic:
                hbar = drift.running_mean(hbar, a2 * x2 + a3 * x2 * x + a4 * x2 * x2, k)
            if traj:
                _record(traj, k - 1, x, z, est, zbar,
                        _realised(quadratic, a2, a3, a4, x2bar, hbar), a0, (a2, a3, a4), b)
        if progress is not None:
            progress(k0 - 1 + ks.shape[0])
    out = _finals(runs, est, zbar, x2bar, hbar, quadratic, a0, a2, a3, a4, b)
    for name, arr in traj.items():
        out[name] = np.ascontiguousarray(arr.T)
    return out


def _sensor_errors(seeds, a0, a1, a2, R, a3, a4, Ts, values):
    """The :class:`driftfmu.models.chain.SensorErrors` of the runs, or None when every slow
    error, the tilt and the ADC are off (the letter's sensor: the engines call
    :func:`driftfmu.models.sensor.measure`, the same bits).  UsageError for a name that is not
    one of them or a per-run array of one (they are one value for all runs)."""
    if not values:
        return None
    unknown = sorted(set(values) - set(chain.SENSOR_ERRORS_OFF))
    if unknown:
        raise UsageError("simulate() got unknown parameter(s) %s; allowed: %s"
                         % (", ".join(unknown), ", ".join(chain.SENSOR_ERRORS_OFF)))
    arrays = sorted(k for k, v in values.items() if not _ops.is_scalar(v))
    if arrays:
        raise UsageError("%s must be one value for all runs, not an array; allowed: a number"
                         % ", ".join(arrays))
    slow = chain.SensorErrors(seeds, a0, a1, a2, R, a3, a4, Ts, values)
    return None if slow.plain else slow


def _error_draws(row, ks, ecfg):
    """The slow errors' draws of the samples ``ks`` (a column) of the runs ``row``:
    ``(n_rw, n_gm, (n_fl_0, ...))``, each ``(len(ks), runs)`` (0.0 for a process that is
    off), as :func:`driftfmu.models.errors.draws` gives them sample by sample."""
    zero = np.zeros((ks.shape[0], 1))
    return (noise.ziggurat(row, noise.STREAM_RANDOM_WALK, ks) if ecfg.rw != 0.0 else zero,
            noise.ziggurat(row, noise.STREAM_BIAS_GM, ks) if ecfg.gm_sigma != 0.0 else zero,
            tuple(noise.ziggurat(row, noise.STREAM_FLICKER + i, ks) for i in range(ecfg.fl_n)))


def _finals(runs, est, zbar, x2bar, hbar, quadratic, a0, a2, a3, a4, b=None):
    """The ``"final_<name>"`` arrays of :data:`FINALS` after the last sample (both engines),
    and of :data:`BIAS_OUTPUTS` with the bias part ``b``."""
    dc1, dc2, dc3 = drift.estimates(est.drift, a2, a3, a4)
    out = {"x_hat": est.x, "P": est.P, "dc_ekf1": dc1, "dc_ekf2": dc2, "dc_ekf3": dc3,
           "zbar": zbar - a0, "x2bar": x2bar,
           "dc_realised": _realised(quadratic, a2, a3, a4, x2bar, hbar)}
    if b is not None:
        out.update(b_hat=b.b, P_bb=b.Pbb, P_xb=b.Pxb)
    return {"final_" + key: np.broadcast_to(np.asarray(v, dtype=float), (runs,)).copy()
            for key, v in out.items()}


def _realised(quadratic, a2, a3, a4, x2bar, hbar):
    """The realised drift so far: ``a2 mean(x^2)`` for the letter's sensor, the running mean
    ``hbar`` of ``a2 x^2 + a3 x^3 + a4 x^4`` otherwise; per run where ``a3``, ``a4`` are
    arrays (a sweep over them), so that a run with ``a3 = a4 = 0`` has the bits of one run of
    the letter's sensor (and of the FMU engine)."""
    if quadratic:
        return a2 * x2bar
    if _ops.is_scalar(a3) and _ops.is_scalar(a4):
        return hbar
    return np.where((np.asarray(a3) == 0.0) & (np.asarray(a4) == 0.0), a2 * x2bar, hbar)


#: What :func:`estimate` can record, each ``(runs, n)``, and returns after the last sample
#: under ``"final_<name>"``.
ESTIMATES = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "b_hat", "P_bb", "P_xb")


def estimate(zs, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=None, Ts=1e-3,
             a3=0.0, a4=0.0, bias=0, Qb=0.0, tau_b=0.0, b0=0.0, Pb0=1e-4, record=()):
    """The DriftEstimator (Gauss-Markov process model, the bias state with ``bias = 1``) over
    recorded outputs: ``zs`` of shape ``(runs, n)``, one measurement per sample; the same
    models/ functions as the FMU on arrays of runs, so run ``r`` gives the FMU's bits for the
    measurements ``zs[r]`` (each step one sample).

    The parameters are the DriftEstimator's, each a float or a ``(runs,)`` array; ``P0``
    defaults to ``Q / (1 - A^2)``.  The bias filter's covariance is checked after every sample
    (:func:`driftfmu.models.bias.check`: a :class:`~driftfmu.models.covariance.CovarianceError`
    names the first run and sample where it is not valid), as the FMU refuses such a sample.

    Returns ``"final_<name>"`` for :data:`ESTIMATES` after the last sample, each ``(runs,)``
    (``b_hat``, ``P_bb``, ``P_xb`` with ``bias = 1`` only), and the ``record``-ed ones, each
    ``(runs, n)``.
    """
    from driftfmu.models import bias as bias_model
    zs = np.asarray(zs, dtype=float)
    if zs.ndim != 2:
        raise UsageError("zs has shape %r; allowed: (runs, n)" % (zs.shape,))
    names = set(ESTIMATES) if bias == 1 else set(ESTIMATES[:5])
    unknown = set(record) - names
    if unknown:
        raise UsageError("cannot record %s; allowed: %s" % (sorted(unknown), ", ".join(
            n for n in ESTIMATES if n in names)))
    check_parameters(dict(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, x0=x0, P0=P0, Ts=Ts, a3=a3,
                          a4=a4, bias=bias, Qb=Qb, tau_b=tau_b, b0=b0, Pb0=Pb0))
    runs, n = zs.shape
    if P0 is None:
        P0 = default_P0(A, Q)
    shape = (runs,)
    est = chain.estimator_init(np.broadcast_to(np.asarray(x0, dtype=float), shape).copy(),
                               np.broadcast_to(np.asarray(P0, dtype=float), shape).copy())
    b = None
    if bias == 1:
        b = bias_model.init(np.broadcast_to(np.asarray(b0, dtype=float), shape).copy(),
                            np.broadcast_to(np.asarray(Pb0, dtype=float), shape).copy())
        Fb = bias_model.factor(tau_b, Ts)
    traj = {name: np.empty((runs, n)) for name in record}
    for k in range(1, n + 1):
        z = zs[:, k - 1]
        if b is None:
            est = chain.estimator_step(est, z, a0, a1, a2, A, Q, R, a3, a4)
        else:
            est, b = bias_model.estimator_step(est, b, z, a0, a1, a2, A, Q, R, Fb, Qb, a3, a4)
            bias_model.check(est, b, k)
        if traj:
            values = _estimates(est, b, a2, a3, a4)
            for name, arr in traj.items():
                arr[:, k - 1] = values[name]
    out = {"final_" + key: np.broadcast_to(np.asarray(v, dtype=float), shape).copy()
           for key, v in _estimates(est, b, a2, a3, a4).items()}
    out.update(traj)
    return out


def _estimates(est, b, a2, a3, a4):
    """The values of :data:`ESTIMATES` of a state (without the bias part when ``b`` is None)."""
    dc1, dc2, dc3 = drift.estimates(est.drift, a2, a3, a4)
    out = {"x_hat": est.x, "P": est.P, "dc_ekf1": dc1, "dc_ekf2": dc2, "dc_ekf3": dc3}
    if b is not None:
        out.update(b_hat=b.b, P_bb=b.Pbb, P_xb=b.Pxb)
    return out


def _kernel_library(kernel):
    """The compiled kernel for ``kernel`` (``"auto"``, ``"numpy"`` or ``"c"``), or None."""
    from driftfmu.simulations import kernel as compiled
    if kernel not in KERNELS:
        raise UsageError("kernel = %r is not allowed; allowed: %s" % (kernel, ", ".join(KERNELS)))
    if kernel == "numpy":
        return None
    lib = compiled.library()
    if lib is None and kernel == "c":
        raise RuntimeError("the compiled batch kernel is not available (no working C compiler "
                           "'%s', or DRIFTFMU_KERNEL=numpy); allowed here: kernel='auto' or "
                           "'numpy'" % os.environ.get("CC", "cc"))
    return lib


def _simulate_kernel(lib, n, seeds, params, kind, record, progress, slow=False):
    """:func:`simulate` in the compiled kernel: the same loop over samples, in blocks of about
    1/32 of ``n`` for ``progress``, else of :data:`KERNEL_CALL` sample-runs; the same finals
    computed by the same models/ code."""
    from driftfmu.simulations import kernel as compiled
    runs = seeds.shape[0]
    a2, a3, a4, a0 = params["a2"], params["a3"], params["a4"], params["a0"]
    quadratic = not sensor.higher(a3, a4)
    on = params["bias"] == 1
    general = not quadratic or not (_ops.is_scalar(params["B"]) and params["B"] == 0.0) or on
    state = compiled.Batch(lib, seeds, params, kind, n, record, general, quadratic, slow)
    step = max(BLOCK, -(-n // 32) if progress is not None else KERNEL_CALL // max(1, runs))
    for k0 in range(1, n + 1, step):
        k1 = min(k0 + step, n + 1)
        state.run(k0, k1)
        if progress is not None:
            progress(k1 - 1)
    x, zbar, x2bar, est, hbar = state.state()
    if on:
        state.check_bias(est, seeds)
    out = _finals(runs, est, zbar, x2bar, hbar, quadratic, a0, a2, a3, a4,
                  state.bias() if on else None)
    out.update(state.traj)
    return out


def _record(traj, j, x, z, est, zbar, realised, a0, coefficients, b=None):
    """Store sample ``j`` (0-based) of the recorded trajectories (``coefficients`` are
    ``(a2, a3, a4)``, ``realised`` the realised drift so far, ``b`` the bias part)."""
    values = {"x": lambda: x, "z": lambda: z, "x_hat": lambda: est.x, "P": lambda: est.P,
              "dc_ekf1": lambda: drift.estimates(est.drift, *coefficients)[0],
              "dc_ekf2": lambda: est.drift.dc2, "dc_ekf3": lambda: est.drift.dc3,
              "dc_empirical": lambda: zbar - a0, "dc_realised": lambda: realised,
              "b_hat": lambda: b.b, "P_bb": lambda: b.Pbb, "P_xb": lambda: b.Pxb}
    for name, arr in traj.items():
        arr[j] = values[name]()


def dual_simulate(n, seeds, excitation_values, sensor_values, estimator_values, Ts, record=(),
                  kernel="auto"):
    """The dual-axis chain of :mod:`driftfmu.models.dualaxis` for ``len(seeds)`` runs at once (the batch
    engine of ``driftfmu experiment dual-axis``): run ``r`` is the co-simulation of Excitation ->
    Accelerometer (``dual = 1``) -> DualDriftEstimator and the two single-axis DriftEstimators
    with both FMU seeds ``seeds[r]``, bit for bit.

    Returns :func:`driftfmu.models.dualaxis.simulate`'s ``final_<column>`` and ``mean_xx``, ``mean_xy``,
    ``mean_yy``, each ``(runs,)``, and the ``record``-ed columns, each ``(runs, n)``.  ``kernel``
    as in :func:`simulate` (the compiled kernel takes start values shared by all runs but the
    seeds; per-run arrays of others run in NumPy).
    """
    from driftfmu.models import dualaxis
    seeds = np.asarray(seeds, dtype=np.uint64)
    lib = _kernel_library(kernel)
    if lib is not None:
        from driftfmu.simulations import kernel as compiled
        out = compiled.dual_simulate(lib, n, seeds, excitation_values, sensor_values,
                                     estimator_values, Ts, record=record)
        if out is not None:
            return out
    return dualaxis.simulate(n, dict(excitation_values, seed=seeds),
                             dict(sensor_values, seed=seeds), estimator_values, Ts,
                             record=record)


# -- the FMU engine -------------------------------------------------------------------------
def fmu_simulate(n, seed, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=None,
                 Ts=1e-3, kind=excitation.GAUSSIAN, X=1.0, f=150.0, phi=0.0, filter_A=None,
                 filter_Q=None, fmu_dir="build/fmus", record=(), backend="python", **general):
    """One run co-simulated with the three FMUs (FMU seed ``seed``); same outputs as one row of
    :func:`simulate`: the :data:`FINALS` as floats and the recorded trajectories as arrays.

    Gaussian runs go through :func:`driftfmu.simulations.gaussian.run_gaussian`, sinusoidal ones through
    :func:`driftfmu.simulations.sinusoidal.run_sinusoidal` with the Gauss-Markov filter; both also check
    the FMUs against models/.  ``backend`` picks the FMUs (``"python"`` or ``"native"``).
    ``general``: the general model's ``a3, a4, B, drive, Qu, Xu, fu`` as in :func:`simulate`
    (Gaussian runs; with ``B != 0`` the master wires ``Excitation.u -> DriftEstimator.u``).
    """
    from driftfmu.simulations import gaussian
    checks.check_keywords("fmu_simulate()", general,
                          checks.keywords_of(fmu_simulate, gaussian.GENERAL_OFF))
    on = sorted(k for k, v in general.items() if v != gaussian.GENERAL_OFF[k])
    if on and kind != excitation.GAUSSIAN:
        raise UsageError("the FMU engine runs %s with the Gaussian excitation only (its "
                         "sinusoidal state has the letter's sensor); allowed with kind = %r: "
                         "%s, or engine 'batch'" % (", ".join(on), kind, ", ".join(
                             "%s = %r" % (k, gaussian.GENERAL_OFF[k]) for k in on)))
    fA = A if filter_A is None else filter_A
    fQ = Q if filter_Q is None else filter_Q
    if P0 is None:
        P0 = default_P0(fA, fQ)
    general = dict(gaussian.GENERAL_OFF, **general)
    on = {k: v for k, v in general.items() if v != gaussian.GENERAL_OFF[k]}
    if kind == excitation.GAUSSIAN and (fA, fQ) == (A, Q):
        cols = gaussian.run_gaussian(a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, n=n, seed=seed,
                                     Ts=Ts, x0=x0, P0=P0, fmu_dir=fmu_dir, plot=False,
                                     backend=backend, **on)["columns"]
    elif kind == excitation.SINUSOIDAL:
        from driftfmu.simulations.sinusoidal import run_sinusoidal
        cols = run_sinusoidal(X=X, f=f, phi=phi, Ts=Ts, n=n, seed=seed, a0=a0, a1=a1, a2=a2,
                              R=R, process=harmonic.GAUSS_MARKOV, A=fA, Q=fQ, P0=P0, x0=x0,
                              fmu_dir=fmu_dir, plot=False, backend=backend)["columns"]
    else:
        raise UsageError("the FMU engine runs kind = %r with filter (A, Q) = (%r, %r); allowed: "
                         "the Gaussian excitation with the filter's A and Q equal to the "
                         "excitation's, or the sinusoidal one" % (kind, fA, fQ))
    zbar, x2bar, hbar = 0.0, 0.0, 0.0
    a3, a4 = general["a3"], general["a4"]
    quadratic = not sensor.higher(a3, a4)
    for k, (x, z) in enumerate(zip(cols["x"], cols["z"]), start=1):
        zbar = drift.running_mean(zbar, z, k)
        x2 = x * x
        x2bar = drift.running_mean(x2bar, x2, k)
        if not quadratic:  # as simulate() folds it
            hbar = drift.running_mean(hbar, a2 * x2 + a3 * x2 * x + a4 * x2 * x2, k)
    out = {"final_" + name: cols[name][-1]
           for name in ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3")}
    out["final_zbar"] = zbar - a0
    out["final_x2bar"] = x2bar
    out["final_dc_realised"] = a2 * x2bar if quadratic else hbar
    for name in record:
        out[name] = np.asarray(cols[name], dtype=float)
    return out


# -- tasks: chunks of runs for workers ------------------------------------------------------
def make_tasks(n, seeds, per_run, common, record=(), chunk=CHUNK, engine="batch",
               fmu_dir=None, backend="python"):
    """Split runs into tasks of at most ``chunk`` runs.

    ``seeds`` (runs,) and the arrays in ``per_run`` (each (runs,)) are sliced; ``common`` holds
    keyword arguments shared by all runs.  The FMU engine uses chunks of a few runs.
    """
    runs = len(seeds)
    tasks = []
    for lo in range(0, runs, chunk):
        hi = min(lo + chunk, runs)
        kw = dict(common)
        kw.update({name: np.asarray(v)[lo:hi] for name, v in per_run.items()})
        tasks.append({"engine": engine, "n": n, "seeds": np.asarray(seeds[lo:hi]),
                      "kwargs": kw, "record": tuple(record), "fmu_dir": fmu_dir,
                      "backend": backend})
    return tasks


def run_task(task):
    """Run one task on a worker; return ``(outputs, seconds)``.

    The batch engine runs the chunk at once; the FMU engine co-simulates its runs one by one;
    ``"dual"`` runs the dual-axis chain's chunk at once (:func:`dual_simulate`).
    """
    t0 = time.perf_counter()
    if task["engine"] == "batch":
        out = simulate(task["n"], task["seeds"], record=task["record"], **task["kwargs"])
    elif task["engine"] == "fmu":
        out = fmu_task(task)
    elif task["engine"] == "dual":  # the dual-axis chain (driftfmu experiment dual-axis)
        out = dual_simulate(task["n"], task["seeds"], record=task["record"], **task["kwargs"])
    else:
        raise UsageError("engine = %r is not allowed; allowed: 'batch', 'fmu' or 'dual'"
                         % (task["engine"],))
    if task.get("reduce"):  # "module:function": what the worker sends back instead of out
        import importlib
        module, name = task["reduce"].split(":")
        out = getattr(importlib.import_module(module), name)(out, task)
    return out, time.perf_counter() - t0


def fmu_task(task):
    """The FMU engine over one task's runs: :func:`fmu_simulate` per run, stacked like
    :func:`simulate`'s outputs."""
    kw = task["kwargs"]
    rows = []
    for r, seed in enumerate(task["seeds"]):
        one = {key: (v[r].item() if isinstance(v, np.ndarray) else v) for key, v in kw.items()}
        rows.append(fmu_simulate(task["n"], int(seed), fmu_dir=task["fmu_dir"],
                                 record=task["record"], backend=task.get("backend", "python"),
                                 **one))
    return {key: np.stack([np.asarray(row[key], dtype=float) for row in rows])
            for key in rows[0]}


def workers_default():
    """Local worker processes by default: one per core."""
    return max(1, os.cpu_count() or 1)


def connect(scheduler, timeout=CONNECT_TIMEOUT):
    """A ``dask.distributed.Client`` of the cluster at ``scheduler``; a clear error within
    ``timeout`` seconds when nothing answers there."""
    Client = dask_client_class()
    def fail(why, exc):
        raise ConnectionError("no Dask scheduler answered at %r (%s); allowed: the address of "
                              "a running dask scheduler, e.g. tcp://host:8786"
                              % (scheduler, why)) from exc

    if not isinstance(scheduler, str) or not scheduler.strip():
        fail("not an address", None)
    try:
        _probe(scheduler, timeout)
    except (OSError, ValueError) as exc:
        fail(_first_line(exc), exc)
    try:
        return Client(scheduler, timeout="%ss" % timeout)
    except (OSError, TimeoutError) as exc:
        fail(_first_line(exc), exc)
    except Exception as exc:  # something answered, but not a Dask scheduler
        fail("something answered but not as a Dask scheduler: %s" % _first_line(exc), exc)


#: How to get what ``--scheduler`` needs.
DASK_EXTRA = checks.DASK_EXTRA


def dask_client_class():
    """``dask.distributed.Client``; a usage error naming the extra to install when Dask is
    missing (it is not part of the default install)."""
    try:
        from dask.distributed import Client
    except ImportError as exc:
        raise UsageError("--scheduler needs Dask, which is not installed (%s); install the "
                         "extra: %s" % (_first_line(exc), DASK_EXTRA)) from None
    return Client


def _first_line(exc):
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _probe(address, timeout):
    """For a tcp:// or tls:// address, open and close a TCP connection: a refused or unknown
    address fails at once instead of after the whole connection timeout."""
    import socket
    from distributed.comm.addressing import parse_address, parse_host_port
    scheme, loc = parse_address(address)
    if scheme not in ("tcp", "tls"):
        return
    host, port = parse_host_port(loc)
    with socket.create_connection((host, port), timeout=timeout):
        pass


def run_tasks(tasks, scheduler=None, client=None, workers=None, progress=None, meanwhile=None):
    """Run ``tasks`` with :func:`run_task`; return their outputs in task order.

    Parameters
    ----------
    scheduler : str, optional
        Address of a Dask scheduler; the tasks then run on that cluster.
    client : dask.distributed.Client, optional
        An existing client (used instead of ``scheduler``).
    workers : int, optional
        Local workers (default: one per core): threads of this process when every task runs
        in the compiled kernel (:func:`in_kernel`), worker processes otherwise; 1 runs in
        this process.
    progress : callable, optional
        Called with the number of runs done whenever a task finishes.
    meanwhile : callable, optional
        Called once in this process while local workers run the tasks (after they started),
        e.g. to import what comes after; before the tasks when they run in this process.
    """
    from driftfmu.simulations.cli import start_work
    results = [None] * len(tasks)
    done = 0
    if any(task["engine"] in ("batch", "dual") for task in tasks):
        from driftfmu.simulations import kernel
        kernel.library()  # compiled (or found) once here, loaded before local workers fork

    def finished(i, res):
        nonlocal done
        results[i] = res[0]
        done += len(tasks[i]["seeds"])
        if progress is not None:
            progress(done)

    if scheduler is not None or client is not None:
        own = client is None
        client = connect(scheduler) if own else client
        try:
            from dask.distributed import as_completed
            futures = client.map(run_task, tasks, pure=False)
            start_work(progress, _runs_at_once(tasks, _cluster_threads(client)))
            index = {f.key: i for i, f in enumerate(futures)}
            try:
                for fut in as_completed(futures):
                    finished(index[fut.key], fut.result())
            except BaseException:  # Ctrl-C or a failed task: the cluster drops the rest
                with contextlib.suppress(Exception):
                    client.cancel(futures)
                raise
        finally:
            if own:
                client.close()
        return results
    workers = workers_default() if workers is None else workers
    if workers < 1:
        raise UsageError("workers = %r is not allowed; allowed: workers >= 1" % (workers,))
    if workers == 1 or len(tasks) == 1:
        if meanwhile is not None:
            meanwhile()
        start_work(progress, _runs_at_once(tasks, 1))
        for i, task in enumerate(tasks):
            finished(i, run_task(task))
        return results
    workers = min(workers, len(tasks))
    pool = thread_pool if all(map(in_kernel, tasks)) else process_pool
    start_work(progress, _runs_at_once(tasks, workers))
    with pool(workers) as pool:
        for i, res in bounded_map(pool, run_task, tasks, ahead=2 * workers,
                                  meanwhile=meanwhile):
            finished(i, res)
    return results


def _runs_at_once(tasks, workers):
    """Runs the first ``workers`` tasks hold: what ``workers`` run at once."""
    return sum(len(task["seeds"]) for task in tasks[:max(1, workers)])


def _cluster_threads(client):
    """Tasks a Dask cluster runs at once (its workers' threads; 1 when it cannot tell)."""
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # an older or another client: one at a time
        return 1


def in_kernel(task):
    """Whether :func:`run_task` runs ``task`` in the compiled kernel, whose calls release the
    GIL: such tasks run in threads of this process (no workers to start, nothing to pickle)."""
    return task["engine"] == "batch" and \
        _kernel_library(task["kwargs"].get("kernel", "auto")) is not None


@contextlib.contextmanager
def thread_pool(workers):
    """A ``ThreadPoolExecutor`` of ``workers`` threads that, when the block fails or is
    interrupted (Ctrl-C), cancels what is queued and returns at once (a running task ends with
    its current block of samples, a fraction of a second)."""
    from concurrent.futures import ThreadPoolExecutor
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="driftfmu-kernel")
    try:
        yield pool
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def bounded_map(pool, fn, items, ahead, meanwhile=None):
    """Yield ``(i, fn(items[i]))`` as the tasks finish on ``pool``, with at most ``ahead`` of
    them submitted and not yet done: the pool's queues then hold a few tasks, not all of them
    (less memory; an interrupt has little to cancel).  ``meanwhile()``, when given, is called
    once, after the first tasks are submitted (while the workers run them)."""
    from concurrent.futures import FIRST_COMPLETED, wait
    pending = {}
    it = iter(enumerate(items))
    while True:
        for i, item in it:
            pending[pool.submit(fn, item)] = i
            if len(pending) >= ahead:
                break
        if meanwhile is not None:
            meanwhile()
            meanwhile = None
        if not pending:
            return
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        for fut in done:
            yield pending.pop(fut), fut.result()


def _worker_init(owner=None):
    """Start of a worker process of the pool that process ``owner`` made: it ends when that
    process is gone, however it ended (:func:`driftfmu.simulations.lifetime.end_with_parent`);
    Ctrl-C is the parent's to handle (it stops the workers); SIGTERM from the parent removes
    the FMUs this worker has extracted, then exits at once."""
    import signal
    import warnings
    from driftfmu.simulations import lifetime
    lifetime.end_with_parent(owner)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_stop)
    if hasattr(signal, "pthread_sigmask"):  # forked with both blocked (see process_pool)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    warnings.showwarning = _worker_warning  # one line each, as the command's own
    # one BLAS thread: the pool runs one worker per core already, and OpenBLAS's own thread per
    # core in every worker would oversubscribe them (its threads spin while they wait: the
    # ADXL203 experiment took 1.6 times as long)
    from driftfmu.models import _blas
    _blas.set_threads(1)


def _worker_warning(message, category, filename, lineno, file=None, line=None):
    import sys
    text = str(message).strip().splitlines()
    sys.stderr.write("driftfmu: warning: %s\n" % (text[0] if text else category.__name__))


def _worker_stop(signum, frame):
    from driftfmu.simulations import cosim
    cosim.remove_extracted()
    os._exit(128 + signum)


@contextlib.contextmanager
def process_pool(workers, preload="driftfmu.simulations.batch"):
    """A ``ProcessPoolExecutor`` of ``workers`` processes (:func:`mp_context`) that, when the
    block fails or is interrupted (Ctrl-C), cancels what is queued and stops its workers at once
    instead of waiting for their tasks to finish.  Its workers end when this process is gone,
    however it ended (SIGKILL: :mod:`driftfmu.simulations.lifetime`)."""
    pool = _Pool(max_workers=workers, mp_context=mp_context(preload), initializer=_worker_init,
                 initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        stop_pool(pool)
        raise
    pool.shutdown(wait=True)


@contextlib.contextmanager
def _signals_blocked():
    """SIGINT and SIGTERM held back (this thread): a worker forked meanwhile starts with them
    blocked and so cannot be stopped before :func:`_worker_init` has set its handlers."""
    import signal
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


class _Pool(ProcessPoolExecutor):
    """A ProcessPoolExecutor whose workers, forked in ``submit``, start with SIGINT and SIGTERM
    blocked (until :func:`_worker_init` has set their handlers and unblocks them)."""

    def submit(self, *args, **kwargs):
        with _signals_blocked():
            return super().submit(*args, **kwargs)


def stop_pool(pool, timeout=2.0):
    """Cancel the queued tasks of ``pool``, SIGTERM its worker processes (each removes its
    temporary files and exits) and wait for them; SIGKILL any still alive after ``timeout``,
    and then remove the work folders they left (:func:`folders.sweep`).

    Then nothing of the pool may keep this process waiting: the queue feeder thread may be
    blocked writing a task to the pipe that the stopped workers read (this process holds the
    pipe's read end too, so the write never fails); the executor's manager thread may be
    reading half a result that a stopped worker was sending (this process holds the pipe's
    write end, so no end of file comes); the manager thread joins the feeder, and the
    interpreter's exit joins the manager thread.  So the result pipe's write end is closed here
    (the read sees the end of the file; the manager never closes it), and the manager, which
    finds the pool broken once its workers are gone, closes the task pipe's read end itself
    (CPython's terminate_broken: the feeder's write fails).  That end is closed here only when
    the manager has not ended within ``timeout``: closing it from two threads at once closes
    the descriptor twice (an EBADF traceback in the manager thread, or another file that was
    given the number meanwhile), as CI once saw under load.
    """
    procs = list((getattr(pool, "_processes", None) or {}).values())
    call_queue = getattr(pool, "_call_queue", None)
    result_queue = getattr(pool, "_result_queue", None)
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    deadline = time.monotonic() + timeout
    killed = False
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(1.0)
            killed = True
    if killed:  # their work folders (FMUs extracted) are left; their locks died with them
        from driftfmu.simulations import folders
        folders.sweep(folders.TEMPORARY, again=True)
    if call_queue is not None:
        with contextlib.suppress(Exception):
            call_queue.cancel_join_thread()
    if result_queue is not None:  # a worker stopped half-way through sending its result
        with contextlib.suppress(Exception):  # leaves the manager reading: this ends the read
            result_queue._writer.close()
    if manager is not None:
        manager.join(timeout)
    if call_queue is not None and (manager is None or manager.is_alive()):
        # the manager shut down without finding the pool broken and waits for a feeder
        # blocked on the full task pipe (or never started): its read end closed here
        with contextlib.suppress(Exception):
            call_queue._reader.close()
        if manager is not None:
            manager.join(timeout)


def mp_context(preload="driftfmu.simulations.batch"):
    """Worker processes by ``fork`` (fast: NumPy and the models are already imported) while this
    process runs a single thread; by ``forkserver`` (or the platform's default) when other
    threads run, e.g. a progress bar's monitor, since forking a threaded process can deadlock.
    ``preload`` is the module the fork server imports once for all its workers."""
    import multiprocessing
    import threading
    methods = multiprocessing.get_all_start_methods()
    if threading.active_count() == 1 and "fork" in methods:
        return multiprocessing.get_context("fork")
    if "forkserver" in methods:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload([preload])
        _multiprocessing_folder()
        return ctx
    return multiprocessing.get_context()


def _multiprocessing_folder():
    """multiprocessing's own temporary folder, where the fork server listens (``pymp-*`` in
    the temporary folder, which a process killed outright leaves for good), made a work folder
    of driftfmu's (:func:`driftfmu.simulations.folders.make`): removed when this process ends,
    and by the next run's sweep when it was killed.  Once per process."""
    import multiprocessing
    from driftfmu.simulations import folders
    config = getattr(multiprocessing.process.current_process(), "_config", None)
    if not isinstance(config, dict) or config.get("tempdir") or folders.fcntl is None:
        return
    folder = folders.make("driftfmu_mp_")
    multiprocessing.util.Finalize(None, folders.remove, args=(folder,), exitpriority=-100)
    config["tempdir"] = folder


def gather(results):
    """Concatenate task outputs along the run axis."""
    return {key: np.concatenate([r[key] for r in results]) for key in results[0]}


# -- command line ---------------------------------------------------------------------------
def add_engine_options(p):
    """``--engine``, ``--scheduler`` and ``--workers`` (shared with ``driftfmu montecarlo``)."""
    from driftfmu.simulations import checks
    p.add_argument("--engine", type=checks.choice_option("engine", ENGINES), choices=ENGINES,
                   default="batch",
                   help="batch: many runs at once through models/ (default); fmu: every run "
                        "co-simulated with the three FMUs")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS", type=scheduler_address,
                   help="run on the Dask distributed cluster at ADDRESS (e.g. "
                        "tcp://host:8786; needs the extra driftfmu[dask]); default: local "
                        "workers")
    p.add_argument("--workers", type=checks.count_option("workers", 1), default=None,
                   metavar="N",
                   help="local workers (default: one per core): threads for runs in the "
                        "compiled kernel, worker processes otherwise")


#: The engines of ``montecarlo`` and ``sweep``.
ENGINES = ("batch", "fmu")


def scheduler_address(text):
    """argparse type of ``--scheduler``: an address a Dask client can connect to, checked by
    its form only (:func:`driftfmu.simulations.checks.scheduler_problem`)."""
    import argparse
    from driftfmu.simulations import checks
    problem = checks.scheduler_problem(text)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return text.strip()
