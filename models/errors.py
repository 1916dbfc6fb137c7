"""Internal (not a stable API; use driftfmu.simulate instead).

The sensor's slow errors: the drift classes 2 to 4 of the letter (Sec. II), and the
measurement's range.

The letter sorts the drift of a sensor into four classes; class 1, reversible and state
dependent, is the nonlinearity's ``a2 E[x^2]`` (:mod:`driftfmu.models.sensor`).  The others, as
processes with their own state, one pure function each (state in, state and sample out):

* class 4, irreversible and state independent ("the long-term mean of non-stationary intrinsic
  noise sources, such as 1/f noise"):

  - a turn-on bias ``b_on = bias_on n_0``, one draw per seed (:func:`turn_on`);
  - a bias random walk ``b_k = b_{k-1} + K sqrt(Ts) n_k``, ``b_0 = 0``, Allan deviation
    ``K sqrt(tau/3)`` (:func:`random_walk`, ``K = random_walk``);
  - a bias instability, a first-order Gauss-Markov process, discretised exactly,
    ``b_k = a b_{k-1} + sigma sqrt(1 - exp(-2 Ts/tau)) n_k``, ``a = exp(-Ts/tau)``, started
    stationary ``b_0 = sigma n_0`` (:func:`gauss_markov`, ``sigma = bias_gm``,
    ``tau = tau_gm``);
  - a flicker (1/f) bias: the sum of ``M`` such Gauss-Markov components whose correlation
    times are spread evenly in log over ``[tau_min, tau_max]``, one per decade
    (``M = 1 + ceil(log10(tau_max / tau_min))``, at least 2; :func:`flicker_taus`), each of
    the same standard deviation ``sigma_c``, chosen so that the Allan deviation of the sum at
    the band's centre ``sqrt(tau_min tau_max)`` is ``flicker`` (:func:`flicker_sigma`, from
    the continuous-time Allan variance of each component, :func:`allan_variance_gm`).  A sum
    of first-order processes with equal variances and log-spaced correlation times has a
    ``1/f`` spectrum between ``1/(2 pi tau_max)`` and ``1/(2 pi tau_min)``: its Allan deviation
    is flat, ``flicker`` within 3 % from ``10 tau_min`` to ``tau_max / 10``, and IEEE Std
    952's bias instability is ``B = flicker / sqrt(2 ln 2 / pi) = flicker / 0.664``;

* class 3, irreversible and state dependent (the sensor's own slow dynamics, "an exponential
  decay model"): the exposure ``E_k = E_{k-1} + x_k^2 Ts`` [g^2 s], ``E_0 = 0``, moves the
  offset by ``d_k = d_inf (1 - exp(-E_k / E_tau))``, which never recovers (:func:`exposure`);

* class 2, reversible and state independent: the tilt ``theta`` (the letter's g-offset: the
  sensor measures ``x + sin(theta)`` [g], :func:`tilt`) and the temperature ``T``: the sensed
  acceleration is scaled by ``1 + kT_scale (T - T0)`` and the output moves by
  ``kT_bias (T - T0)`` [V] (:func:`temperature`);

* the measurement range: the sensed acceleration is clipped to ``[-range, range]``
  (:func:`saturate`; the ADC's resolution is :func:`driftfmu.models.adxl203.quantise`).

The sensor composes them (:func:`driftfmu.models.adxl203.measure_errors`):

.. math:: u_k = \\mathrm{clip}\\big((1 + k_{T,s} \\Delta T_k)(x_k + \\sin\\theta_k)\\big), \\qquad
          z_k = \\mathrm{Q}\\big(h(u_k) + v_k + b_{on} + b^{rw}_k + b^{gm}_k + \\textstyle\\sum_i
          b^{fl}_{i,k} + d_k + k_{T,b} \\Delta T_k\\big)

Every process draws from a counter-based noise stream of its own
(:data:`driftfmu.models.noise.STREAM_TURN_ON` ...), so turning one on changes no other draw;
index 0 of a stream is the draw before sample 1.  The draws are standard normal by the ziggurat
(:func:`driftfmu.models.noise.ziggurat`), which costs less than the quantile the letter's
streams use: a sample with every process on draws up to ten of them.  Every term is off by
default, and then the sensor is the one without them, the same bits (nothing here is
evaluated).  All functions run
on floats (one FMU instance) and on arrays of runs (the batch engine) with the same bits; the
coefficients are computed once, with the arithmetic-only ``exp``, ``log`` and ``sin`` of
:mod:`driftfmu.models._ops`, so that the C twin (``fmu_src/native/models/errors.c``) gives them
too.
"""
import math
from collections import namedtuple

from . import _ops, sensor
from .noise import STREAM_BIAS_GM, STREAM_FLICKER, STREAM_RANDOM_WALK, STREAM_TURN_ON, ziggurat

#: Most components of the flicker bias (one per decade of its band, at least two).
FLICKER_MAX = 8
#: Widest band of the flicker bias, in decades of tau_max / tau_min (FLICKER_MAX - 1).
FLICKER_DECADES_MAX = FLICKER_MAX - 1
#: ``ln 10``.
LN10 = 2.302585092994046
#: ``sqrt(2 ln 2 / pi)``: the Allan deviation of a 1/f bias over IEEE Std 952's B.
FLICKER_FLOOR = 0.6642824702679415

#: The parameters of this module and their off values (every term off).
OFF = dict(bias_on=0.0, random_walk=0.0, bias_gm=0.0, tau_gm=1.0, flicker=0.0, tau_min=0.1,
           tau_max=100.0, d_inf=0.0, E_tau=1.0, T0=298.15, kT_bias=0.0, kT_scale=0.0,
           range=0.0)
#: The inputs of this module (the tilt and the temperature) and their start values.
INPUTS = dict(theta=0.0, T=298.15)

#: Constants of the errors, computed once from the (scalar) parameters (:func:`config`).
#: ``on``: any term on; ``bias_on`` and ``b_on``: the turn-on bias's standard deviation and this
#: seed's value [V]; ``rw``: ``K sqrt(Ts)``;
#: ``gm_sigma, gm_a, gm_c``: the Gauss-Markov bias's ``sigma``, ``exp(-Ts/tau)`` and
#: ``sigma sqrt(1 - exp(-2 Ts/tau))``; ``fl_n, fl_sigma, fl_a, fl_c``: the flicker bias's
#: components, their ``sigma_c`` and the tuples of their ``a`` and ``c``; the rest as the
#: parameters.
ErrorConfig = namedtuple("ErrorConfig", "on bias_on b_on rw gm_sigma gm_a gm_c fl_n fl_sigma fl_a fl_c "
                                        "d_inf E_tau Ts T0 kT_bias kT_scale range")
#: The state of the processes after a sample: the random walk, the Gauss-Markov bias, the
#: exposure ``E`` [g^2 s] and the flicker bias's components (a tuple of ``fl_n``).
ErrorState = namedtuple("ErrorState", "rw gm E fl")
#: ``ErrorState(rw, gm, E, fl)`` from a tuple, without the keyword handling (every sample of
#: one FMU instance makes one).
_new_state = tuple.__new__


# -- one pure function per process ------------------------------------------------------------

def turn_on(bias_on, seed):
    """The turn-on bias of ``seed``: ``bias_on n_0``, ``n_0`` the draw before sample 1 of the
    turn-on stream (one value per seed, an int or an array of them)."""
    return bias_on * ziggurat(seed, STREAM_TURN_ON, 0)


def random_walk(b, step, n):
    """One step of the bias random walk, ``b + K sqrt(Ts) n`` (``step = K sqrt(Ts)``): the new
    state, which is the sample."""
    return b + step * n


def gauss_markov_coefficients(sigma, tau, Ts):
    """``(a, c)`` of the exact discretisation of a first-order Gauss-Markov process of
    stationary standard deviation ``sigma`` and correlation time ``tau`` sampled every ``Ts``:
    ``a = exp(-Ts/tau)``, ``c = sigma sqrt(1 - exp(-2 Ts/tau))``."""
    return _ops.exp(-Ts / tau), sigma * _ops.sqrt(1.0 - _ops.exp(-2.0 * Ts / tau))


def gauss_markov(b, a, c, n):
    """One step of a Gauss-Markov bias, ``a b + c n``: the new state, which is the sample."""
    return a * b + c * n


def flicker_taus(tau_min, tau_max):
    """The correlation times of the flicker bias's components: ``M = 1 +
    ceil(log10(tau_max / tau_min))`` (at least 2) spread evenly in log from ``tau_min`` to
    ``tau_max`` (both exactly), ``tau_i = tau_min exp(i ln(tau_max / tau_min) / (M - 1))``."""
    span = _ops.log(tau_max / tau_min)
    decades = span / LN10
    m = 1 + int(-_ops.floor(-(decades - 1e-9)))
    m = max(2, min(m, FLICKER_MAX))
    step = span / (m - 1)
    return tuple(tau_min if i == 0 else tau_max if i == m - 1 else
                 tau_min * _ops.exp(i * step) for i in range(m))


#: ``(-1)^n (4 - 2^n) / n!`` for ``n = 3 .. 22``: the series of ``2 r - 3 + 4 e^-r - e^-2r``
#: (its terms of order 0, 1 and 2 cancel), which :func:`allan_variance_gm` sums below
#: ``r = 1/2`` (truncation below ``1/23! = 4e-23`` relative).
GM_SERIES = tuple((-1) ** n * (4 - 2 ** n) / math.factorial(n) for n in range(3, 23))


def allan_variance_gm(variance, tau, T):
    """The Allan variance at averaging time ``T`` of a continuous-time first-order Gauss-Markov
    process of stationary ``variance`` and correlation time ``tau``: the variance of a
    ``T``-average less the covariance of two adjacent ones,

    .. math:: \\sigma^2_A(T) = \\mathrm{variance}\\, \\frac{2 r - 3 + 4 e^{-r} - e^{-2 r}}{r^2},
              \\qquad r = T / \\tau

    (``2 variance (tau T - tau^2 (1 - e^-r)) / T^2 - variance tau^2 (1 - e^-r)^2 / T^2``).
    Below ``r = 1/2`` the numerator, whose terms cancel to ``2 r^3 / 3``, is summed as its
    series (:data:`GM_SERIES`), so that it keeps its precision over a wide band."""
    r = T / tau
    if r < 0.5:
        poly = GM_SERIES[-1]
        for c in GM_SERIES[-2::-1]:
            poly = poly * r + c
        f = poly * r * r * r
    else:
        e = _ops.exp(-r)
        f = ((2.0 * r - 3.0) + 4.0 * e) - e * e
    return variance * f / (r * r)


def flicker_sigma(flicker, taus):
    """``sigma_c`` of every component: the Allan deviation of the sum of unit components at
    the centre ``sqrt(tau_min tau_max)`` of the band, scaled to ``flicker``."""
    centre = _ops.sqrt(taus[0] * taus[-1])
    total = 0.0
    for tau in taus:
        total = total + allan_variance_gm(1.0, tau, centre)
    return flicker / _ops.sqrt(total)


def flicker(components, a, c, n):
    """One step of the flicker bias: every component ``a_i b_i + c_i n_i``; ``(components,
    sample)``, the sample their sum in order."""
    out = []
    total = 0.0
    for b, ai, ci, ni in zip(components, a, c, n):
        b = ai * b + ci * ni  # (gauss_markov, written out)
        out.append(b)
        total = total + b
    return tuple(out), total


def exposure(E, x, Ts, d_inf, E_tau):
    """One step of the exposure drift: ``E = E + x^2 Ts`` and ``d = d_inf (1 - exp(-E /
    E_tau))``; ``(E, d)``."""
    E = E + x * x * Ts
    return E, d_inf * (1.0 - _ops.exp_estrin(-E / E_tau))


def tilt(x, theta):
    """The acceleration a tilted sensor senses [g]: ``x + sin(theta)``."""
    if type(theta) is float:  # one FMU instance: the tilt is held, its sine computed once
        last = _TILT[0]
        if theta != last[0] or theta == 0.0:  # (-0.0 equals 0.0 but has its own sine)
            last = _TILT[0] = (theta, _ops.sin(theta))
        return x + last[1]
    return x + _ops.sin(theta)


#: ``(theta, sin(theta))`` of the last tilt (:func:`tilt`; shared by the instances of a process:
#: a tuple replaced whole, never changed).  The native twins hold one per instance (C's
#: ``ErrorTilt`` of ``errors_tilt``, in the FMU state, checked when a state is restored).
_TILT = [(0.0, 0.0)]


def temperature(T, T0, kT_bias, kT_scale):
    """``(scale, bias)`` at temperature ``T``: ``1 + kT_scale (T - T0)`` and ``kT_bias (T -
    T0)`` [V]."""
    dT = T - T0
    return 1.0 + kT_scale * dT, kT_bias * dT


def class2(x, theta, T, T0, kT_bias, kT_scale):
    """The letter's class 2 (reversible, state independent) at true acceleration ``x`` [g]:
    ``(u, c)``, the acceleration the sensing element senses [g] and the offset the temperature
    adds to the output [V],

    .. math:: u = (1 + k_{T,scale} \\Delta T)(x + \\sin\\theta), \\qquad
              c = k_{T,bias} \\Delta T, \\qquad \\Delta T = T - T_0

    (:func:`tilt` only when ``theta`` is not 0, the scale factor only when ``kT_scale`` is not
    0: the same bits as ``x`` when they are).  The one definition of class 2: the sensor senses
    ``u`` (:func:`sensed`) and adds ``c``; the DriftEstimator removes what they make at ``x =
    0`` (:func:`class2_offset`)."""
    scale, c = temperature(T, T0, kT_bias, kT_scale)
    u = x
    if (theta != 0.0) if type(theta) is float else _nonzero(theta):
        u = tilt(u, theta)
    if (kT_scale != 0.0) if type(kT_scale) is float else _nonzero(kT_scale):
        u = scale * u
    return u, c


def class2_offset(theta, T, a1, a2, T0, kT_bias, kT_scale, a3=0.0, a4=0.0):
    """The class-2 offset [V]: what the tilt and the temperature add to the output of the
    sensor ``h`` at ``x = 0`` (:func:`class2` at ``x = 0``, through ``h`` without ``a0``),

    .. math:: dc_{class2} = k_{T,bias} \\Delta T + a_1 g + a_2 g^2 + a_3 g^3 + a_4 g^4,
              \\qquad g = (1 + k_{T,scale} \\Delta T) \\sin\\theta

    0 with ``theta = 0`` and ``kT_bias = kT_scale = 0``.  The DriftEstimator subtracts it from
    ``z`` before filtering (docs/method.md, section 11); given the sensor's coefficients it
    removes the offset the sensor's :func:`class2` makes."""
    g, c = class2(0.0, theta, T, T0, kT_bias, kT_scale)
    return c + sensor.h(g, 0.0, a1, a2, a3, a4)


def saturate(u, limit):
    """``u`` clipped to ``[-limit, limit]`` (the measurement range)."""
    if type(u) is float:  # (the same choices, written out for one FMU instance)
        u = limit if u > limit else u
        return -limit if u < -limit else u
    u = _ops.where(u > limit, limit, u)
    return _ops.where(u < -limit, -limit, u)


# -- the constants, the initial state, the draws ------------------------------------------------

def _nonzero(v):
    """``v != 0`` for a number; for an array of per-run values, whether any is."""
    if _ops.is_scalar(v):
        return v != 0.0
    return bool((_ops._np().asarray(v) != 0.0).any())


def config(seed=1, Ts=1e-3, bias_on=0.0, random_walk=0.0, bias_gm=0.0, tau_gm=1.0, flicker=0.0,
           tau_min=0.1, tau_max=100.0, d_inf=0.0, E_tau=1.0, T0=298.15, kT_bias=0.0,
           kT_scale=0.0, range=0.0, **_ignored):
    """The :class:`ErrorConfig` of the (scalar, checked) parameters; ``seed`` an int or an
    array of the runs' seeds (then ``b_on`` is an array)."""
    on = (bias_on != 0.0 or random_walk != 0.0 or bias_gm != 0.0 or flicker != 0.0
          or d_inf != 0.0 or kT_bias != 0.0 or kT_scale != 0.0 or range != 0.0)
    b_on = turn_on(bias_on, seed) if bias_on != 0.0 else 0.0
    rw = random_walk * _ops.sqrt(Ts) if random_walk != 0.0 else 0.0
    gm_a, gm_c = gauss_markov_coefficients(bias_gm, tau_gm, Ts) if bias_gm != 0.0 else (0.0, 0.0)
    fl_sigma, fl_a, fl_c = 0.0, (), ()
    if flicker != 0.0:
        taus = flicker_taus(tau_min, tau_max)
        fl_sigma = flicker_sigma(flicker, taus)
        pairs = [gauss_markov_coefficients(fl_sigma, tau, Ts) for tau in taus]
        fl_a, fl_c = tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)
    return ErrorConfig(on, bias_on, b_on, rw, bias_gm, gm_a, gm_c, len(fl_a), fl_sigma, fl_a, fl_c,
                       d_inf, E_tau, Ts, T0, kT_bias, kT_scale, range)


def problems(p):
    """Problems of the errors' parameters in mapping ``p`` beyond their plain ranges (one
    readable line each): with a flicker bias (``flicker != 0``), its band ``tau_min <
    tau_max``, at most :data:`FLICKER_DECADES_MAX` decades wide (without one, the band is not
    used)."""
    lo, hi = p.get("tau_min", OFF["tau_min"]), p.get("tau_max", OFF["tau_max"])
    if p.get("flicker", 0.0) == 0.0:
        return []
    if not (lo > 0.0 and hi > 0.0) or lo - lo != 0.0 or hi - hi != 0.0:
        return []  # (their own range check says what is wrong)
    if not lo < hi:
        return ["tau_min = %r s and tau_max = %r s are not a band; allowed: tau_min < tau_max "
                "(the correlation times of the flicker bias)" % (lo, hi)]
    if hi / lo > 10.0 ** FLICKER_DECADES_MAX:
        return ["tau_min = %r s and tau_max = %r s span more than %d decades; allowed: "
                "tau_max <= 1e%d tau_min (one flicker component per decade, at most %d)"
                % (lo, hi, FLICKER_DECADES_MAX, FLICKER_DECADES_MAX, FLICKER_MAX)]
    return []


def initial_state(seed, ecfg):
    """The state before sample 1: the walk and the exposure at 0, the Gauss-Markov bias and the
    flicker components drawn from their stationary distributions (index 0 of their streams)."""
    gm = ecfg.gm_sigma * ziggurat(seed, STREAM_BIAS_GM, 0) if ecfg.gm_sigma != 0.0 else 0.0
    fl = tuple(ecfg.fl_sigma * ziggurat(seed, STREAM_FLICKER + i, 0) for i in range(ecfg.fl_n))
    return ErrorState(0.0, gm, 0.0, fl)


def draws(seed, k, ecfg):
    """The standard normal draws of sample ``k``: ``(n_rw, n_gm, (n_fl_0, ...))``, 0.0 for a
    process that is off."""
    n_rw = ziggurat(seed, STREAM_RANDOM_WALK, k) if ecfg.rw != 0.0 else 0.0
    n_gm = ziggurat(seed, STREAM_BIAS_GM, k) if ecfg.gm_sigma != 0.0 else 0.0
    return n_rw, n_gm, tuple(ziggurat(seed, STREAM_FLICKER + i, k) for i in range(ecfg.fl_n))


def stream_of(name, i=0):
    """The noise stream of process ``name`` (``"rw"``, ``"gm"``, ``"fl"`` with component
    ``i``)."""
    return {"rw": STREAM_RANDOM_WALK, "gm": STREAM_BIAS_GM, "fl": STREAM_FLICKER + i}[name]


# -- the composition ----------------------------------------------------------------------------

def advance(state, x, n_rw, n_gm, n_fl, ecfg):
    """The processes one sample on, with the true acceleration ``x`` (the exposure's) and the
    sample's draws: ``(state, b)``, the new :class:`ErrorState` (a process that is off keeps
    its state) and the sum of the processes' samples [V] in this order: the turn-on bias, the
    random walk, the Gauss-Markov bias, the flicker bias, the exposure drift (each only when
    on; 0.0 when all are off)."""
    rw, gm, E, fl = state
    b = 0.0
    if ecfg.bias_on != 0.0:
        b = b + ecfg.b_on
    if ecfg.rw != 0.0:
        rw = random_walk(rw, ecfg.rw, n_rw)
        b = b + rw
    if ecfg.gm_sigma != 0.0:
        gm = gauss_markov(gm, ecfg.gm_a, ecfg.gm_c, n_gm)
        b = b + gm
    if ecfg.fl_n:
        fl, total = flicker(fl, ecfg.fl_a, ecfg.fl_c, n_fl)
        b = b + total
    if ecfg.d_inf != 0.0:
        E, d = exposure(E, x, ecfg.Ts, ecfg.d_inf, ecfg.E_tau)
        b = b + d
    return _new_state(ErrorState, (rw, gm, E, fl)), b


def advance_state(state, x, n_rw, n_gm, n_fl, ecfg):
    """:func:`advance`'s new state alone, for a sample whose output no one sees (one between
    communication points, :func:`hold`): the same operations on the state, in the same order,
    without the sum and the exposure drift's exponential (the same bits as ``advance(...)[0]``;
    tests/test_errors.py compares them)."""
    rw, gm, E, fl = state
    if ecfg.rw != 0.0:
        rw = random_walk(rw, ecfg.rw, n_rw)
    if ecfg.gm_sigma != 0.0:
        gm = gauss_markov(gm, ecfg.gm_a, ecfg.gm_c, n_gm)
    if ecfg.fl_n:
        fl = flicker(fl, ecfg.fl_a, ecfg.fl_c, n_fl)[0]
    if ecfg.d_inf != 0.0:
        E = E + x * x * ecfg.Ts  # (exposure's E)
    return _new_state(ErrorState, (rw, gm, E, fl))


def thermal_bias(T, ecfg):
    """The temperature's bias ``kT_bias (T - T0)`` [V] (0.0 while ``kT_bias = 0``)."""
    if ecfg.kT_bias == 0.0:
        return 0.0
    return temperature(T, ecfg.T0, ecfg.kT_bias, ecfg.kT_scale)[1]


def sensed(x, theta, T, ecfg):
    """The acceleration the sensing element sees [g]: :func:`class2`'s (the tilt's ``x +
    sin(theta)`` when ``theta`` is not 0, scaled by the temperature's ``1 + kT_scale (T - T0)``
    when ``kT_scale`` is not 0), clipped to the range (when on)."""
    u = class2(x, theta, T, ecfg.T0, ecfg.kT_bias, ecfg.kT_scale)[0]
    if ecfg.range != 0.0:
        u = saturate(u, ecfg.range)
    return u


def hold(state, x, seed, k0, m, ecfg):
    """The state after the samples ``k0 + 1 .. k0 + m - 1`` that lie between communication
    points, with the input held at ``x`` (a no-op while every process is off)."""
    if not (ecfg.rw != 0.0 or ecfg.gm_sigma != 0.0 or ecfg.d_inf != 0.0 or ecfg.fl_n):
        return state
    for j in range(1, m):
        state = advance_state(state, x, *draws(seed, k0 + j, ecfg), ecfg)
    return state


def run(state, draws, ecfg):
    """The processes of :func:`advance` that do not depend on the input (the random walk, the
    Gauss-Markov and flicker biases) over consecutive samples, for one FMU instance: from
    ``state`` (the state before the first sample, floats) and ``draws = (n_rw, n_gm, n_fl)``,
    the samples' draws (sequences of floats of one length; ``n_fl`` one per flicker component;
    None for a process that is off), a list of ``(rw, gm, fl, p)`` per sample: the walk, the
    Gauss-Markov bias and the tuple of flicker components after it, and ``p`` the sum that
    :func:`advance` forms before it adds the exposure drift (the turn-on bias, the walk, the
    Gauss-Markov bias, the flicker bias, in that order, each only when on).  A process that is
    off keeps its state, as in :func:`advance`.

    The same operations in the same order as :func:`advance` sample by sample (the same bits;
    tests/test_errors.py compares them): the products ``c n`` and the sums across the
    processes are element by element over NumPy arrays (one correctly rounded operation per
    element, as on floats), and each recurrence ``a b + (c n)`` runs over the run in one Python
    loop, so that a Python FMU pays the calls and tuples of :func:`advance` once per run
    instead of once per sample.  Needs NumPy (the FMU uses it where its blocks of draws are
    NumPy's)."""
    np = _ops._np()
    rw, gm, _, fl = state
    n_rw, n_gm, n_fl = draws
    n = len(next(d for d in (n_rw, n_gm) + tuple(n_fl) if d is not None))
    p = np.full(n, 0.0 + ecfg.b_on if ecfg.bias_on != 0.0 else 0.0)
    rws = [rw] * n
    if ecfg.rw != 0.0:  # (random_walk: b + step n, which is 1.0 b + step n bit for bit)
        rws = _recurrence(rw, 1.0, ecfg.rw, n_rw)
        p = p + np.array(rws)
    gms = [gm] * n
    if ecfg.gm_sigma != 0.0:
        gms = _recurrence(gm, ecfg.gm_a, ecfg.gm_c, n_gm)  # (gauss_markov)
        p = p + np.array(gms)
    fls = [fl] * n
    if ecfg.fl_n:
        components = [_recurrence(b, a, c, x)  # (flicker: gauss_markov of each component)
                      for b, a, c, x in zip(fl, ecfg.fl_a, ecfg.fl_c, n_fl)]
        total = np.zeros(n)
        for out in components:  # (flicker: their sum in order)
            total = total + np.array(out)
        p = p + total
        fls = list(zip(*components))
    return list(zip(rws, gms, fls, p.tolist()))


def hold_run(state, x, m, draws, ecfg):
    """:func:`hold` over a run, for one FMU instance: the state after ``m >= 0`` consecutive
    samples with the input held at ``x``, from their draws (``draws`` as for :func:`run`,
    sequences of ``m`` floats).  The same operations as :func:`advance_state` sample by sample,
    so the same bits (tests/test_errors.py compares them), process by process instead of sample
    by sample: each recurrence runs over the run in one loop of floats, without a call or a
    state per sample, and the exposure adds ``x^2 Ts``, formed once (the same product at every
    sample)."""
    if m == 0:
        return state
    rw, gm, E, fl = state
    n_rw, n_gm, n_fl = draws
    if ecfg.rw != 0.0:
        step = ecfg.rw
        for n in n_rw:
            rw = rw + step * n  # (random_walk)
    if ecfg.gm_sigma != 0.0:
        a, c = ecfg.gm_a, ecfg.gm_c
        for n in n_gm:
            gm = a * gm + c * n  # (gauss_markov)
    if ecfg.fl_n:
        out = []
        for b, a, c, ns in zip(fl, ecfg.fl_a, ecfg.fl_c, n_fl):
            for n in ns:
                b = a * b + c * n  # (flicker's component: gauss_markov)
            out.append(b)
        fl = tuple(out)
    if ecfg.d_inf != 0.0:
        step = x * x * ecfg.Ts  # (exposure's E)
        for _ in range(m):
            E = E + step
    return _new_state(ErrorState, (rw, gm, E, fl))


def _recurrence(b, a, c, n):
    """The states ``b_k = a b_{k-1} + c n_k`` of a Gauss-Markov process over the draws ``n``
    from ``b`` (:func:`gauss_markov` over a run: the products ``c n_k`` over an array)."""
    out = []
    for x in (c * _ops._np().asarray(n)).tolist():
        b = a * b + x
        out.append(b)
    return out


def state_problems(state, ecfg):
    """Why ``state`` (an :class:`ErrorState` read back from an FMU state) cannot be the state of
    a sensor with ``ecfg``: a number that is not finite, a negative exposure, a process that is
    off with a state that is not 0, a number of flicker components other than ``fl_n``."""
    out = []
    for name in ("rw", "gm", "E"):
        v = getattr(state, name)
        if v - v != 0.0:
            out.append("%s = %r is not finite" % (name, v))
    if state.E < 0.0:
        out.append("E = %r is a negative exposure; allowed: E >= 0 (a sum of x^2 Ts)"
                   % (state.E,))
    for name, on, what in (("rw", ecfg.rw != 0.0, "random_walk"),
                           ("gm", ecfg.gm_sigma != 0.0, "bias_gm"),
                           ("E", ecfg.d_inf != 0.0, "d_inf")):
        if not on and getattr(state, name) != 0.0:
            out.append("%s = %r although %s = 0 (off); allowed: %s = 0.0"
                       % (name, getattr(state, name), what, name))
    if len(state.fl) != ecfg.fl_n:
        out.append("%d flicker components; allowed: %d (tau_min, tau_max and flicker give them)"
                   % (len(state.fl), ecfg.fl_n))
    for i, v in enumerate(state.fl):
        if v - v != 0.0:
            out.append("fl[%d] = %r is not finite" % (i, v))
    return out
