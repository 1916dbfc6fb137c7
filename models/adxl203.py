"""Internal (not a stable API; use driftfmu.experiment_adxl203 instead).

A richer accelerometer that can play the ADXL203, and the chain around it.

Every extra effect is off by default, and then the output is the letter's sensor,
``z = a0 + a1 x + a2 x^2 + sqrt(R) v`` (:func:`driftfmu.models.sensor.measure`, same bits).  Switched on:

* cubic and quartic terms ``a3 u^3 + a4 u^4`` (without any other extra: the general sensor
  :func:`driftfmu.models.sensor.measure`) and cross-axis coupling: each axis senses its own acceleration plus
  ``cross`` times the other's, ``u_x = x + cross y``, ``u_y = y + cross x``;
* the second axis (``axes = 2``): ``z_y`` from ``u_y`` with its own noise and filter;
* noise given as a density (``density`` [g/sqrt(Hz)]): white noise sampled at ``fs = 1/Ts`` has the
  one-sided density ``sigma^2 / (fs/2)``, so ``sigma = density sqrt(fs / 2)`` [g], added to the
  sensed acceleration before the output filter; it replaces ``R`` (which is then unused);
* the output low-pass of bandwidth ``fc`` (the datasheet's capacitor rule ``fc = 5 uF / C``,
  32 kOhm internal resistor): the first-order RC filter discretised exactly for a held input,
  ``e_k = alpha e_{k-1} + (1 - alpha) s_k``, ``alpha = exp(-2 pi fc Ts)``, started at ``e_1 = s_1``.
  Behind the filter the white noise above becomes the datasheet's ``density sqrt(1.57 fc)``;
* ratiometric output (supply ``Vs > 0``): zero-g level ``Vs / 2`` (replacing ``a0``) and
  ``a1, a2, a3`` and the noise scaled by ``S(Vs) / S(5 V)``, with the datasheet's sensitivity
  ``S`` = 1000 mV/g at 5 V and 560 mV/g at 3 V, taken linear in ``Vs`` between and beyond;
  ``a1, a2, a3`` are therefore the coefficients at the nominal 5 V supply;
* ADC quantisation to ``bits`` bits over ``[0, Vfs)``, ``Vfs = Vs`` (a ratiometric converter
  referenced to the supply) or 5 V when ``Vs = 0``; codes are clipped to the converter's range,
  which also models the output rails.  For any other sensor (``Vs = 0``) with a measurement
  range (``range > 0`` [g]) the converter spans instead ``[a0 - |a1| range, a0 + |a1| range)``,
  the linear characteristic over the range (``lo`` of :class:`Config` is its lowest level).

The sensor's slow errors (:mod:`driftfmu.models.errors`: the letter's drift classes 2 to 4 and
the range) enter through :func:`measure_errors`: the tilt, the temperature's scale factor and
the range act on the sensed acceleration, the biases and drifts on the voltage before the ADC.

Per sample, with ``s`` the pre-filter signal in volts above zero-g:

.. math:: s_k = a_1 (u_k + n_k) + a_2 u_k^2 + a_3 u_k^3, \\qquad
          z_k = \\mathrm{Q}\\big(z_0 + e_k\\big)

All functions run on floats (one FMU) and arrays (a batch of sets) with the same bits; the
filter coefficient and the other constants are computed once, from scalars (``alpha`` with the
arithmetic-only :func:`driftfmu.models._ops.exp`, so that the C port gives the same bits).
"""
import math
from collections import namedtuple

from . import _ops, errors, excitation, parameters, sensor
from .noise import STREAM_MEASUREMENT, STREAM_MEASUREMENT_Y, normal

#: Nominal supply of the datasheet's headline figures [V].
VS_NOMINAL = 5.0
#: Datasheet sensitivities [V/g] at 5 V and 3 V supply.
SENSITIVITY_5V = 1.000
SENSITIVITY_3V = 0.560
#: Supply range over which the sensitivity law is used [V].
VS_RANGE = (3.0, 6.0)
#: Bandwidth rule of the datasheet: f-3dB = 5 uF / C [Hz F].
BANDWIDTH_RULE = 5e-6
#: Largest bandwidth the datasheet allows [Hz].
MAX_BANDWIDTH = 2500.0
#: Full-scale range of the part [g].
RANGE_G = 1.7

#: The sensor parameters and their off values (the letter's quadratic sensor).
EXTRAS_OFF = dict(a3=0.0, a4=0.0, cross=0.0, fc=0.0, Vs=0.0, bits=0, density=0.0, axes=1)

#: ADXL203 stand-in (datasheet facts and the choices stated here; sources and assumptions in
#: docs/method.md, section 6): 5 V supply (zero-g 2.5 V, 1000 mV/g), noise density
#: 110 ug/sqrt(Hz), C = 4.7 nF on the output (fc = 5 uF / 4.7 nF = 1064 Hz, well above the
#: 200 Hz drive and its 2nd harmonic), 12-bit ratiometric ADC, both axes, cross-axis coupling
#: 1.5 % (an assumption, not verified against the datasheet).  The nonlinearity is chosen, not a
#: datasheet figure: a2 = 0.01 V/g^2 (the letter's value; 0.85 % of full scale for the best
#: straight line over +-1.7 g) and a small cubic a3 = 0.002 V/g^3.
ADXL203 = dict(a0=2.5, a1=SENSITIVITY_5V, a2=0.01, a3=0.002, R=1e-4, cross=0.015,
               fc=round(BANDWIDTH_RULE / 4.7e-9, 6), Vs=5.0, bits=12, density=110e-6, axes=2)
PRESETS = {"adxl203": ADXL203}

Config = namedtuple("Config", "plain a0 a1 a2 a3 R sigma cross alpha lsb levels a4 lo")


def settling_samples(fc, Ts, time_constants=10):
    """Samples in ``time_constants`` time constants ``1 / (2 pi fc)`` of the output filter (its
    start transient has decayed by ``exp(-10) = 4.5e-5`` after ten); 0 without filter."""
    if not fc:
        return 0
    return int(math.ceil(time_constants / (2.0 * math.pi * fc * Ts)))


def bandwidth(C):
    """Output bandwidth [Hz] of the filter capacitor ``C`` [F]: ``5 uF / C``."""
    return BANDWIDTH_RULE / C


def sensitivity(Vs):
    """Datasheet sensitivity [V/g] at supply ``Vs`` [V] (linear through 3 V and 5 V)."""
    return SENSITIVITY_3V + (SENSITIVITY_5V - SENSITIVITY_3V) * (Vs - 3.0) / 2.0


def noise_sigma(density, Ts):
    """Standard deviation [g] of white noise of one-sided density ``density`` sampled every
    ``Ts``: ``density sqrt(fs / 2)``."""
    return density * math.sqrt(0.5 / Ts)


def problems(p):
    """Problems of the extra sensor parameters in mapping ``p`` beyond their plain ranges."""
    out = []
    Vs = p.get("Vs", 0.0)
    if Vs != 0.0 and not VS_RANGE[0] <= Vs <= VS_RANGE[1]:
        out.append("Vs = %r V is not allowed; allowed: Vs = 0 (ratiometric output off) or "
                   "%g <= Vs <= %g" % (Vs, VS_RANGE[0], VS_RANGE[1]))
    fc = p.get("fc", 0.0)
    if fc > MAX_BANDWIDTH:
        out.append("fc = %r Hz is not allowed; allowed: fc = 0 (low-pass off) or "
                   "0 < fc <= %g Hz (datasheet maximum)" % (fc, MAX_BANDWIDTH))
    return out


def config(a0=0.0, a1=1.0, a2=0.01, R=1e-4, a3=0.0, cross=0.0, fc=0.0, Vs=0.0, bits=0,
           density=0.0, Ts=1e-3, a4=0.0, range=0.0, **_ignored):
    """Constants of the sensor, computed once from the parameters (scalars; ``a0 .. a4`` and
    ``R`` may be arrays of per-run values).  ``plain``: no extra on, the letter's general
    sensor ``h(x) + sqrt(R) v`` (any ``a3``, ``a4``).  ``lo``: the ADC's lowest level (0.0 but
    for a converter over the measurement range)."""
    plain = (cross == 0.0 and fc == 0.0 and Vs == 0.0 and bits == 0 and density == 0.0)
    scale = sensitivity(Vs) / sensitivity(VS_NOMINAL) if Vs > 0.0 else 1.0
    z0 = Vs / 2.0 if Vs > 0.0 else a0
    a1e, a2e, a3e = a1 * scale, a2 * scale, a3 * scale
    sigma = a1e * noise_sigma(density, Ts) if density > 0.0 else _ops.sqrt(R)
    alpha = _ops.exp(-2.0 * math.pi * fc * Ts) if fc > 0.0 else None
    levels = 2 ** int(bits) if bits > 0 else 0
    lo = 0.0
    if levels and Vs <= 0.0 and range > 0.0:  # over a0 +- |a1| range
        span = abs(a1e) * range
        lo, lsb = z0 - span, 2.0 * span / levels
    else:
        lsb = (Vs if Vs > 0.0 else VS_NOMINAL) / levels if levels else 0.0
    return Config(plain, z0, a1e, a2e, a3e, R, sigma, cross, alpha, lsb, levels, a4 * scale, lo)


def noise(seed, k, axis=1):
    """Standard normal draw of the measurement noise of ``axis`` (1: x, 2: y) at sample ``k``."""
    return normal(seed, STREAM_MEASUREMENT if axis == 1 else STREAM_MEASUREMENT_Y, k)


def sense(own, other, v, cfg):
    """Pre-filter signal [V above zero-g] of an axis: ``a1 (u + n) + a2 u^2 + a3 u^3 + a4 u^4``
    (the ``a4`` term only when ``a4 != 0``: same bits as the cubic sensor)."""
    u = own + cfg.cross * other
    u2 = u * u
    if cfg.a4 == 0.0:
        return cfg.a1 * u + cfg.a2 * u2 + cfg.a3 * u2 * u + cfg.sigma * v
    return cfg.a1 * u + cfg.a2 * u2 + cfg.a3 * u2 * u + cfg.a4 * u2 * u2 + cfg.sigma * v


def lowpass(prev, s, alpha):
    """One step of the output filter; ``prev = None`` starts it at ``s``; ``alpha = None``: off."""
    if alpha is None or prev is None:
        return s
    return alpha * prev + (1.0 - alpha) * s


def quantise(V, cfg, _floor=math.floor):
    """ADC: nearest code of ``V - lo`` on the grid ``lsb``, clipped to ``[0, levels - 1]``, as
    the voltage ``lo + code lsb`` (``lo = 0.0``: ``code lsb``, the same bits); a non-finite
    ``V`` (an overflow upstream) stays as it is, so that the FMU names it instead of showing
    full scale."""
    if not cfg.levels:
        return V
    if type(V) is float:  # one FMU instance: the same steps, written out for a float
        if V - V != 0.0:
            return V
        lsb, levels, _, lo = cfg[9:]  # (Config's last fields)
        code = (V / lsb if lo == 0.0 else (V - lo) / lsb) + 0.5
        code = code if code - code != 0.0 else float(_floor(code))  # (_ops.floor)
        code = 0.0 if code < 0.0 else code
        top = levels - 1.0
        code = top if code > top else code
        return code * lsb if lo == 0.0 else lo + code * lsb
    if cfg.lo == 0.0:
        code = _ops.floor(V / cfg.lsb + 0.5)
    else:
        code = _ops.floor((V - cfg.lo) / cfg.lsb + 0.5)
    code = _ops.where(code < 0.0, 0.0, code)
    top = cfg.levels - 1.0
    code = _ops.where(code > top, top, code)
    if cfg.lo == 0.0:
        return _ops.where(V - V == 0.0, code * cfg.lsb, V)
    return _ops.where(V - V == 0.0, cfg.lo + code * cfg.lsb, V)


def measure(prev, own, other, v, cfg):
    """One sample of an axis: ``(filter state, output z)``.

    ``prev`` is the filter state after the previous sample (None before the first).  With every
    extra off this is :func:`driftfmu.models.sensor.measure` (state None).
    """
    if cfg.plain:
        return None, sensor.measure(own, cfg.a0, cfg.a1, cfg.a2, cfg.R, v, cfg.a3, cfg.a4)
    e = lowpass(prev, sense(own, other, v, cfg), cfg.alpha)
    return e, quantise(cfg.a0 + e, cfg)


def measure_errors(prev, state, own, other, v, draws, theta, T, cfg, ecfg):
    """One sample of the first axis with the slow errors of :mod:`driftfmu.models.errors`:
    ``(filter state, error state, output z)``.

    ``state`` is the :class:`~driftfmu.models.errors.ErrorState` after the previous sample,
    ``draws`` the sample's ``(n_rw, n_gm, n_fl)`` (:func:`driftfmu.models.errors.draws`),
    ``theta`` and ``T`` the tilt [rad] and temperature [K] inputs.  The processes advance with
    the true acceleration ``own`` (the exposure's); the sensor senses
    :func:`driftfmu.models.errors.sensed` of it; the processes' bias and the temperature's are
    added to the voltage before the ADC:

    .. math:: z = \\mathrm{Q}\\big(h(u) + \\sqrt{R}\\, v + b + k_{T,b} (T - T_0)\\big)

    (with the extras of :func:`measure`: ``a0 + e`` in place of ``h(u) + sqrt(R) v``).
    """
    state, b = errors.advance(state, own, draws[0], draws[1], draws[2], ecfg)
    u = errors.sensed(own, theta, T, ecfg)
    if cfg.plain:
        e, V = None, sensor.measure(u, cfg.a0, cfg.a1, cfg.a2, cfg.R, v, cfg.a3, cfg.a4)
    else:
        e = lowpass(prev, sense(u, other, v, cfg), cfg.alpha)
        V = cfg.a0 + e
    V = V + b
    if ecfg.kT_bias != 0.0:
        V = V + errors.thermal_bias(T, ecfg)
    return e, state, quantise(V, cfg)


def measure_errors_run(prev, state, row, own, other, v, theta, T, cfg, ecfg, _exp=_ops.exp_estrin,
                       _sin=_ops.sin, _TILT=errors._TILT, _new_state=tuple.__new__,
                       _ErrorState=errors.ErrorState):
    """:func:`measure_errors` of one FMU instance (``own``, ``other``, ``v``, ``theta`` and ``T``
    floats) with the sample's input-independent processes given: ``row`` is the sample's
    ``(rw, gm, fl, p)`` of :func:`driftfmu.models.errors.run` from ``state``, and ``p`` plus
    the exposure drift is :func:`~driftfmu.models.errors.advance`'s sum ``b``.

    The rest is written out for floats: the exposure (:func:`~driftfmu.models.errors.exposure`),
    what the sensor senses (:func:`~driftfmu.models.errors.sensed`: ``class2`` with
    ``temperature`` and ``tilt``, whose held sine it shares, and ``saturate``), the output
    filter (:func:`lowpass`) and the temperature's bias
    (:func:`~driftfmu.models.errors.thermal_bias`): the same operations on the same conditions
    as :func:`measure_errors`, without the calls between them, which cost a Python FMU's sample
    more than their arithmetic.  The same bits (tests/test_errors.py compares the two, term by
    term and with every term on)."""
    rw, gm, fl, b = row
    E = state[2]
    d_inf, E_tau, Ts, T0, kT_bias, kT_scale, limit = ecfg[-7:]  # (ErrorConfig's last fields)
    if d_inf != 0.0:
        E = E + own * own * Ts  # (errors.exposure)
        b = b + d_inf * (1.0 - _exp(-E / E_tau))
    dT = T - T0  # (errors.sensed: errors.class2 with errors.temperature, errors.saturate)
    u = own
    if theta != 0.0:  # (errors.tilt: its sine held while theta is)
        held = _TILT[0]
        if theta != held[0]:
            held = _TILT[0] = (theta, _sin(theta))
        u = u + held[1]
    if kT_scale != 0.0:
        u = (1.0 + kT_scale * dT) * u
    if limit != 0.0:
        u = limit if u > limit else u
        u = -limit if u < -limit else u
    if cfg.plain:
        e, V = None, sensor.measure(u, cfg.a0, cfg.a1, cfg.a2, cfg.R, v, cfg.a3, cfg.a4)
    else:
        e = sense(u, other, v, cfg)
        alpha = cfg.alpha
        if alpha is not None and prev is not None:  # (lowpass)
            e = alpha * prev + (1.0 - alpha) * e
        V = cfg.a0 + e
    V = V + b  # (the processes' bias)
    if kT_bias != 0.0:
        V = V + kT_bias * dT  # (errors.thermal_bias)
    return e, _new_state(_ErrorState, (rw, gm, E, fl)), quantise(V, cfg)


def hold(prev, own, other, seed, k0, m, cfg, axis=1, noise_on=True):
    """Filter state after the samples ``k0 + 1 .. k0 + m - 1`` that lie between communication
    points, with the input held at ``(own, other)`` and fresh noise (a no-op without filter)."""
    if cfg.alpha is None:
        return prev
    for j in range(1, m):
        v = noise(seed, k0 + j, axis) if noise_on else 0.0
        prev = lowpass(prev, sense(own, other, v, cfg), cfg.alpha)
    return prev


def sensor_parameters(**values):
    """All accelerometer parameters: ``values`` over the defaults (extras off)."""
    p = dict(parameters.defaults("a0", "a1", "a2", "R", "seed", "Ts"), noise=1)
    p.update(EXTRAS_OFF)
    p.update(values)
    return p


def check(p):
    """Every problem of a mapping of accelerometer parameters (range and combination)."""
    return parameters.check(p) + problems(p)


# -- the chain around it: the reference the co-simulations are checked against ---------------

def simulate(n, excitation_values, sensor_values, estimator_values, Ts):
    """Run Excitation -> Accelerometer -> DriftEstimator for samples ``k = 1..n`` through the
    same models/ functions as the FMUs, from the FMUs' start values (dicts by variable name).

    The seeds (and the sinusoid's ``X``, ``phi``, ``Xy``, ``phiy``) may be arrays of shape
    ``(runs,)``: every column is then an array ``(runs, n)``; otherwise lists of floats.
    The filter's model may hold ``a3``, ``a4`` (the DriftEstimator's; 0 by default, the
    letter's quadratic model, same bits).  Returns the columns ``time, x, y, z, z_y, x_hat, P,
    dc_ekf1, dc_ekf2, dc_ekf3, z_comp``.

    The known input ``u_k`` (the Excitation's ``drive, Qu, Xu, fu``) drives a Gaussian ``x`` by
    the Excitation's ``B``, and reaches the filter's prediction by the DriftEstimator's ``B``
    (the master's connection ``Excitation.u -> DriftEstimator.u``); a sinusoidal ``x`` does not
    move with it.  Both ``B = 0`` (the defaults) give the letter's chain, same bits.  A sample
    after which the harmonic filter's covariance is not valid (which the DriftEstimator
    refuses) raises :class:`driftfmu.models.covariance.CovarianceError`
    (:func:`driftfmu.models.harmonic.check`).
    """
    from . import drift, harmonic
    ex = dict(kind=excitation.GAUSSIAN, A=0.0, Q=0.01, x0=0.0, X=1.0, f=150.0, phi=0.0,
              Xy=0.0, phiy=0.0, seed=1, B=0.0, drive=excitation.DRIVE_OFF, Qu=0.0, Xu=0.0,
              fu=0.0)
    ex.update(excitation_values)
    sp = sensor_parameters(**sensor_values)
    es = dict(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=0.01, estimator=1,
              process=harmonic.GAUSS_MARKOV, f=150.0, Qh=parameters.PARAMETERS["Qh"].default,
              a3=0.0, a4=0.0, B=0.0)
    es.update(estimator_values)
    cfg = config(Ts=Ts, **{k: v for k, v in sp.items() if k != "Ts"})
    C, S = harmonic.rotation(es["f"], Ts)
    model = dict(process=es["process"], A=es["A"], Q=es["Q"], C=C, S=S, Qh=es["Qh"],
                 B=es["B"])
    inputs = ex["drive"] != excitation.DRIVE_OFF
    u = 0.0
    state = harmonic.estimator_init(es["process"], es["x0"], es["P0"])
    seeds = sp["seed"] if not _ops.is_scalar(sp["seed"]) else ex["seed"]
    names = ("time", "x", "y", "z", "z_y", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3",
             "z_comp")
    cols = {c: [] for c in names}
    x = ex["x0"]
    lp = lpy = None
    zy = 0.0
    for k in range(1, n + 1):
        if inputs:
            u = excitation.input_sample(ex["drive"], ex["seed"], k, ex["Qu"], ex["Xu"], ex["fu"],
                                        Ts)
        if ex["kind"] == excitation.GAUSSIAN:
            x = excitation.gaussian_sample(x, ex["A"], ex["Q"], ex["seed"], k, ex["B"], u)
            y = 0.0
        else:
            x = excitation.sine(k, ex["X"], ex["f"], Ts, ex["phi"])
            y = excitation.sine(k, ex["Xy"], ex["f"], Ts, ex["phiy"])
        v = noise(sp["seed"], k) if sp["noise"] else 0.0
        lp, z = measure(lp, x, y, v, cfg)
        if sp["axes"] == 2:
            vy = noise(sp["seed"], k, 2) if sp["noise"] else 0.0
            lpy, zy = measure(lpy, y, x, vy, cfg)
        state = harmonic.estimator_step(state, z, es["a0"], es["a1"], es["a2"], es["R"], u=u,
                                        a3=es["a3"], a4=es["a4"], **model)
        harmonic.check(state, k, seeds)
        dcs = drift.estimates(state.drift, es["a2"], es["a3"], es["a4"])
        dc = drift.select(dcs, es["estimator"])
        row = ((k - 1) * Ts, x, y, z, zy, state.x, state.P, dcs[0], dcs[1], dcs[2], z - dc)
        for c, value in zip(names, row):
            cols[c].append(value)
    if not _ops.is_scalar(ex["seed"]) or not _ops.is_scalar(sp["seed"]):
        import numpy as np
        shape = np.broadcast(np.asarray(ex["seed"]), np.asarray(sp["seed"])).shape
        for c in names:
            cols[c] = np.stack([np.broadcast_to(np.asarray(v, dtype=float), shape)
                                for v in cols[c]], axis=-1)
    return cols
