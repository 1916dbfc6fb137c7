"""Internal (not a stable API; use driftfmu.simulate instead).

The whole measurement chain, excitation -> sensor -> EKF -> drift estimators.

:func:`estimator_step` is what the DriftEstimator FMU runs on each sample; :func:`simulate` runs
the chain sample by sample through the same functions as the three FMUs, on floats (one run, the
reference that the co-simulation is checked against) or on arrays of seeds (a batch of runs).
"""
from collections import namedtuple

from . import drift, ekf, errors, excitation, sensor
from .noise import STREAM_MEASUREMENT, STREAM_PROCESS, normal

#: Filter state after ``drift.k`` samples: posterior mean and variance, estimator sums.
EstimatorState = namedtuple("EstimatorState", "x P drift")

#: Columns of a results table, in order.
COLUMNS = ("time", "x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_empirical",
           "dc_realised", "dc_expected", "z_comp")
#: The columns that come out of the FMUs (the others are references the master computes).
FMU_COLUMNS = ("time", "x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")


def estimator_init(x0, P0):
    """Filter state before the first sample."""
    return EstimatorState(x0, P0, drift.initial_state())


def estimator_step(state, z, a0, a1, a2, A, Q, R, a3=0.0, a4=0.0, B=0.0, u=0.0):
    """One EKF predict (with the known input ``u``)/update with ``z`` and the three drift
    estimators folded forward."""
    x, P = ekf.step(state.x, state.P, z, a0, a1, a2, A, Q, R, a3, a4, B, u)
    return EstimatorState(x, P, drift.update(state.drift, x, P, a2, a3, a4))


def compensate(z, dc):
    """Drift-compensated sensor output ``z - dc``."""
    return z - dc


def expected_drift(a2, kind=excitation.GAUSSIAN, A=0.0, Q=0.01, X=1.0, a4=0.0, B=0.0,
                   drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0, fu=0.0, Ts=1e-3):
    """The stationary drift ``a2 E[x^2] + a4 E[x^4]`` of the chain's state (eqs. 4-5; the odd
    ``a3`` term averages to zero).

    Gauss-Markov ``x`` with the known input ``B u`` (``B != 0``, ``drive != 0``): the moments of
    :func:`driftfmu.models.excitation.state_moments`; without it ``sigma_x^2 = Q / (1 - A^2)``
    and ``E[x^4] = 3 sigma_x^4``, so ``a2 sigma_x^2 + 3 a4 sigma_x^4``; a sinusoid
    ``X sin(.)``: ``E[x^2] = X^2 / 2``, ``E[x^4] = 3 X^4 / 8``.  ``a4 = 0`` gives
    ``a2 sigma_x^2``, the letter's bits.  ``a2``, ``a4`` may be arrays.
    """
    if kind == excitation.GAUSSIAN and not (B == 0.0 or drive == excitation.DRIVE_OFF):
        var_x, m4 = excitation.state_moments(A, Q, B, drive, Qu, Xu, fu, Ts)
    else:
        var_x = excitation.stationary_variance(kind, A=A, Q=Q, X=X)
        m4 = 3.0 * var_x * var_x if kind == excitation.GAUSSIAN else 0.375 * X ** 4
    return sensor.drift(a2, var_x, a4, m4)


#: The sensor's slow errors (:mod:`driftfmu.models.errors`: its parameters, the tilt and
#: temperature inputs held constant over a run) and the ADC's ``bits``, with their off values:
#: what :func:`simulate` and the batch engine take beyond the general model.
SENSOR_ERRORS_OFF = dict(errors.OFF, **errors.INPUTS, bits=0)


def check_sensor_errors(values, function="simulate()"):
    """Raise TypeError for a name that is not one of :data:`SENSOR_ERRORS_OFF`."""
    unknown = sorted(set(values) - set(SENSOR_ERRORS_OFF))
    if unknown:
        raise TypeError("%s got unknown parameter(s) %s; allowed: %s"
                        % (function, ", ".join(unknown), ", ".join(SENSOR_ERRORS_OFF)))


def wired_offset(theta, T, a1, a2, a3=0.0, a4=0.0):
    """The class-2 offset the DriftEstimator removes from ``z`` when the sensor's tilt
    ``theta`` and temperature ``T`` are wired to its inputs of the same name and its own
    class-2 coefficients are off (``T0``, ``kT_bias = kT_scale = 0``, its defaults): the
    tilt's :func:`driftfmu.models.errors.class2_offset`, ``a1 sin(theta) + a2 sin(theta)^2
    (+ a3, a4 terms)``.  None with ``theta = 0``: the estimator then filters ``z`` itself (the
    same bits as unwired).  ``theta``, ``T`` are one value for all runs."""
    if not errors._nonzero(theta):
        return None
    return errors.class2_offset(theta, T, a1, a2, errors.OFF["T0"], 0.0, 0.0, a3, a4)


class SensorErrors:
    """The slow errors of the chain's sensor for one run or a batch of runs (seeds an int or an
    array): :meth:`measure` is the Accelerometer's first axis, sample by sample, with its
    :class:`driftfmu.models.errors.ErrorState`; ``plain`` when every term is off and the tilt
    is 0 (then the chain calls :func:`driftfmu.models.sensor.measure` itself, the same bits)."""

    def __init__(self, seed, a0, a1, a2, R, a3, a4, Ts, values):
        from . import adxl203
        v = dict(SENSOR_ERRORS_OFF, **values)
        self.ecfg = errors.config(seed=seed, Ts=Ts, **v)
        self.cfg = adxl203.config(a0=a0, a1=a1, a2=a2, R=R, a3=a3, a4=a4, bits=v["bits"],
                                  range=v["range"], Ts=Ts)
        self.theta, self.T, self.seed = v["theta"], v["T"], seed
        self.plain = not self.ecfg.on and not errors._nonzero(self.theta) and not v["bits"]
        self.state = errors.initial_state(seed, self.ecfg)

    def measure(self, x, v, k, draws=None):
        """Output ``z_k`` of the true acceleration ``x`` and measurement draw ``v`` (``draws``:
        the processes' draws of sample ``k``, by default :func:`driftfmu.models.errors.draws`)."""
        from . import adxl203
        if draws is None:
            draws = errors.draws(self.seed, k, self.ecfg)
        _, self.state, z = adxl203.measure_errors(None, self.state, x, 0.0, v, draws,
                                                  self.theta, self.T, self.cfg, self.ecfg)
        return z


def simulate(n, seed, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=None,
             Ts=1e-3, estimator=1, kind=excitation.GAUSSIAN, X=1.0, f=150.0, phi=0.0,
             filter_A=None, filter_Q=None, measure_noise=True, a3=0.0, a4=0.0, B=0.0,
             drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0, fu=0.0, **sensor_errors):
    """Run the chain for samples ``k = 1..n``; return a dict of the results columns.

    ``seed`` is an int (one run; each column a list of floats) or a ``uint64`` array of shape
    ``(runs,)`` (each column an array ``(runs, n)``).  The sensor and the filter share the model
    ``a0, a1, a2, R``; the excitation is Gauss-Markov ``(A, Q)`` or ``X sin(2 pi f t + phi)``.
    The filter's process model is ``(filter_A, filter_Q)``, by default the excitation's.
    ``P0`` defaults to the stationary variance ``Q / (1 - A^2)``.  The general model: ``a3, a4``
    (sensor and filter), and the known input ``u`` (``drive``, ``Qu``, ``Xu``, ``fu``) entering
    the Gauss-Markov excitation and the filter's prediction through ``B``; the expected drift is
    then ``a2 E[x^2] + a4 E[x^4]`` of :func:`driftfmu.models.excitation.state_moments`.  Their
    defaults give the letter's chain, same bits.  ``sensor_errors``: the sensor's slow errors
    and range (:data:`SENSOR_ERRORS_OFF`: :mod:`driftfmu.models.errors`' parameters, the tilt
    ``theta`` and temperature ``T`` held over the run, the ADC's ``bits``), as the Accelerometer
    FMU computes them; off by default (the same bits).  The filter keeps the letter's model:
    the errors are what it does not know, but for the tilt and temperature, wired to the
    DriftEstimator's inputs as the masters wire them: it removes the tilt's offset
    (:func:`wired_offset`) before filtering, and ``z_comp`` is ``z - wired_offset - dc``.
    """
    check_sensor_errors(sensor_errors)
    fA = A if filter_A is None else filter_A
    fQ = Q if filter_Q is None else filter_Q
    if P0 is None:
        P0 = fQ / (1.0 - fA * fA)
    dc_expected = expected_drift(a2, kind, A, Q, X, a4, B, drive, Qu, Xu, fu, Ts)
    fB = B if kind == excitation.GAUSSIAN else 0.0  # a sinusoidal x has no input term
    scalar = isinstance(seed, int)
    cols = {c: [] for c in COLUMNS}
    x = x0
    est = estimator_init(x0, P0)
    slow = SensorErrors(seed, a0, a1, a2, R, a3, a4, Ts, sensor_errors) if sensor_errors \
        else None
    if slow is not None and slow.plain:
        slow = None
    wired = dict(SENSOR_ERRORS_OFF, **sensor_errors)
    offset = wired_offset(wired["theta"], wired["T"], a1, a2, a3, a4)
    for k in range(1, n + 1):
        u = excitation.input_sample(drive, seed, k, Qu, Xu, fu, Ts)
        if kind == excitation.GAUSSIAN:
            x = excitation.gauss_markov(x, A, Q, normal(seed, STREAM_PROCESS, k), B, u)
        else:
            x = excitation.sine(k, X, f, Ts, phi)
        v = normal(seed, STREAM_MEASUREMENT, k) if measure_noise else 0.0
        if slow is None:
            z = sensor.measure(x, a0, a1, a2, R, v, a3, a4)
        else:
            z = slow.measure(x, v, k)
        ze = z if offset is None else z - offset  # (the tilt wired to the estimator)
        est = estimator_step(est, ze, a0, a1, a2, fA, fQ, R, a3, a4, fB, u)
        dcs = drift.estimates(est.drift, a2, a3, a4)
        row = ((k - 1) * Ts, x, z, est.x, est.P, dcs[0], dcs[1], dcs[2],
               compensate(ze, drift.select(dcs, estimator)))
        for c, value in zip(FMU_COLUMNS, row):
            cols[c].append(value)
    cols["dc_empirical"], cols["dc_realised"], cols["dc_expected"] = drift.references(
        cols["x"], cols["z"], a0, a2, dc_expected, a3, a4)
    if not scalar:
        import numpy as np
        for c in COLUMNS:
            cols[c] = np.stack([np.broadcast_to(np.asarray(v, dtype=float), seed.shape)
                                for v in cols[c]], axis=-1)
    return cols
