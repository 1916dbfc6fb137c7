"""Internal (not a stable API; use driftfmu.simulate instead).

Every model parameter once: paper name, default, allowed range, unit and meaning.

The FMUs take their start values, ``min``/``max`` and descriptions from here, the command line
takes its options and checks from here, and :func:`check` words every range error the same way
for both.  Defaults are the letter's simulation settings (Sec. III).
"""
import math
from collections import namedtuple

Param = namedtuple("Param", "name default low high low_open high_open unit description")


def _p(name, default, low=None, high=None, unit="1", description="", low_open=False,
       high_open=False):
    return Param(name, default, low, high, low_open, high_open, unit, description)


#: Smallest sample period [s]: bounds the samples of a step of given length (and the FMUs'
#: declared ``min`` of Ts).
TS_MIN = 1e-9

PARAMETERS = {p.name: p for p in (
    _p("a0", 0.0, unit="V", description="sensor offset a0 of z = a0 + a1 x + a2 x^2 + v"),
    _p("a1", 1.0, unit="V/g", description="sensor sensitivity a1 (must not be 0)"),
    _p("a2", 0.01, unit="V/g2", description="second-order coefficient a2; its drift is a2 E[x^2]"),
    _p("A", 0.0, -1.0, 1.0, description="state transition x_k = A x_{k-1} + w_k (|A| < 1: a "
       "stationary process; the declared min/max are the doubles next to -1 and 1)", low_open=True,
       high_open=True),
    _p("Q", 0.01, 0.0, unit="g2", description="process noise variance Q of w_k"),
    _p("R", 1e-4, 0.0, unit="V2", description="measurement noise variance R of v_k (R > 0: the "
       "filter divides by H^2 P + R; the declared min is the smallest positive double)",
       low_open=True),
    _p("x0", 0.0, unit="g", description="initial state x_0 (before sample 1)"),
    _p("P0", 0.01, 0.0, unit="g2", description="initial error variance P_0 of the filter"),
    _p("Ts", 1e-3, TS_MIN, unit="s", description="sample period (one sample per Ts; at least "
       "1 ns, so that a communication step of any size processes a bounded number of samples)"),
    _p("X", 1.0, 0.0, unit="g", description="amplitude X of the sinusoidal excitation"),
    _p("f", 150.0, 0.0, unit="Hz", description="frequency f of the sinusoidal excitation"),
    _p("phi", 0.0, unit="rad", description="phase of the sinusoidal excitation"),
    _p("seed", 1, 0, 2 ** 31 - 1, description="seed of the counter-based noise generator"),
    _p("n", 2000, 1, unit="1", description="number of samples"),
    _p("runs", 1, 1, unit="1", description="number of Monte-Carlo runs"),
    # -- sinusoidal excitation's second axis, the ADXL203 stand-in, the harmonic filter -------
    _p("Xy", 0.0, 0.0, unit="g", description="amplitude of the second-axis acceleration "
       "y = Xy sin(2 pi f t + phiy)"),
    _p("phiy", 0.0, unit="rad", description="phase of the second-axis acceleration"),
    _p("a3", 0.0, unit="V/g3", description="third-order coefficient a3 of the sensor "
       "h(x) = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 (0: off); its drift a3 E[x^3] is 0 for a "
       "zero-mean symmetric state"),
    _p("cross", 0.0, -1.0, 1.0, description="cross-axis coupling: each axis senses its own "
       "acceleration plus cross times the other's (0: off)"),
    _p("fc", 0.0, 0.0, unit="Hz", description="output low-pass bandwidth f-3dB = 5 uF / C "
       "(0: off; at most 2500 Hz, the datasheet's maximum)"),
    _p("Vs", 0.0, 0.0, 6.0, unit="V", description="supply voltage of the ratiometric output: "
       "zero-g Vs/2, sensitivity scaled like the datasheet's (0: off, a0 and a1 as given; "
       "otherwise 3 <= Vs <= 6, the datasheet's supply range)"),
    _p("bits", 0, 0, 24, description="ADC resolution over [0, Vs), else over a0 +- |a1| range "
       "when range > 0, else over [0, 5 V) (0: off)"),
    _p("density", 0.0, 0.0, unit="g/sqrt(Hz)", description="noise density; sigma = density "
       "sqrt(fs/2) replaces R (0: off, noise from R)"),
    _p("axes", 1, 1, 2, description="accelerometer axes: 1 x only, 2 x and y"),
    _p("process", 1, 1, 2, description="process model of the filter: 1 Gauss-Markov "
       "(A, Q), 2 harmonic oscillator at f (Qh)"),
    _p("Qh", 1e-8, 0.0, unit="g2", description="process noise variance per component and "
       "sample of the harmonic oscillator model"),
    # -- the dual-axis sensor with a bilinear cross term (models.dualaxis) ------------------------
    _p("dual", 0, 0, 1, description="dual-axis bilinear sensor z_x = a0 + a1 x + a2 x^2 + bx x y "
       "+ v_x, z_y = a0y + a1y y + a2y y^2 + by x y + v_y (1: on, 0: off)"),
    _p("bx", 0.0, unit="V/g2", description="cross term bx of z_x; its drift is bx E[x y]"),
    _p("by", 0.0, unit="V/g2", description="cross term by of z_y; its drift is by E[x y]"),
    _p("a0y", 0.0, unit="V", description="offset a0y of the second axis z_y"),
    _p("a1y", 1.0, unit="V/g", description="sensitivity a1y of the second axis (must not be 0)"),
    _p("a2y", 0.01, unit="V/g2", description="second-order coefficient a2y of the second axis"),
    _p("Ry", 1e-4, 0.0, unit="V2", description="measurement noise variance Ry of v_y",
       low_open=True),
    _p("Qy", 0.0, 0.0, unit="g2", description="process noise variance Qy of the second axis "
       "y_k = A y_{k-1} + w_y,k (0: y = 0)"),
    _p("rho", 0.0, -1.0, 1.0, description="correlation of the two axes' process noises w_x, w_y"),
    _p("y0", 0.0, unit="g", description="initial second-axis state y_0 of the filter"),
    _p("P0y", 0.01, 0.0, unit="g2", description="initial error variance of the second axis"),
    # -- the letter's general sensor: 4th-order term and the known input u (eqs. 1, 3-5) -----------
    _p("a4", 0.0, unit="V/g4", description="fourth-order coefficient a4 of the sensor "
       "h(x) = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 (0: off); its drift is a4 E[x^4]"),
    _p("B", 0.0, unit="1", description="input gain B of x_k = A x_{k-1} + B u_k + w_k (0: no "
       "known input, the letter's case)"),
    _p("drive", 0, 0, 2, description="known input u_k: 0 from the host (the Excitation's "
       "input u_in; 0 unless set), 1 Gaussian white N(0, Qu), 2 sinusoid Xu sin(2 pi fu t)"),
    _p("Qu", 0.0, 0.0, unit="g2", description="variance sigma_u^2 of the Gaussian known input"),
    _p("Xu", 0.0, 0.0, unit="g", description="amplitude of the sinusoidal known input"),
    _p("fu", 0.0, 0.0, unit="Hz", description="frequency of the sinusoidal known input"),
    # -- the DriftEstimator's bias state (its class-2 coefficients are the sensor's below) -----
    _p("bias", 0, 0, 1, description="bias state of the filter: 0 off (the letter's filter), 1 "
       "on: state [x, b], b_k = exp(-Ts/tau_b) b_{k-1} + w_b, z_k = h(x_k) + b_k + v_k"),
    _p("Qb", 0.0, 0.0, unit="V2", description="process noise variance Qb of the bias per sample "
       "(a random walk of K V/sqrt(s) sampled every Ts: Qb = K^2 Ts)"),
    _p("tau_b", 0.0, 0.0, unit="s", description="correlation time of the bias (0: a random walk "
       "b_k = b_{k-1} + w_b; > 0: Gauss-Markov b_k = exp(-Ts/tau_b) b_{k-1} + w_b)"),
    _p("b0", 0.0, unit="V", description="initial bias estimate b_0 of the filter"),
    _p("Pb0", 1e-4, 0.0, unit="V2", description="initial error variance of the bias estimate"),
    # -- the sensor's slow errors: the letter's drift classes 2 to 4, range and resolution ----
    #    (models.errors; every one off by default)
    _p("bias_on", 0.0, 0.0, unit="V", description="turn-on bias: standard deviation of the "
       "offset bias_on n drawn once per seed (class 4; 0: off)"),
    _p("random_walk", 0.0, 0.0, unit="V/sqrt(s)", description="bias random walk K: b_k = "
       "b_{k-1} + K sqrt(Ts) n_k, Allan deviation K sqrt(tau/3) (class 4; 0: off)"),
    _p("bias_gm", 0.0, 0.0, unit="V", description="bias instability as a first-order "
       "Gauss-Markov process: its stationary standard deviation (class 4; 0: off)"),
    _p("tau_gm", 1.0, 0.0, unit="s", low_open=True, description="correlation time of the "
       "Gauss-Markov bias: b_k = exp(-Ts/tau_gm) b_{k-1} + bias_gm sqrt(1 - exp(-2 Ts/tau_gm)) "
       "n_k"),
    _p("flicker", 0.0, 0.0, unit="V", description="1/f (flicker) bias: its Allan deviation, flat "
       "over the band tau_min..tau_max (IEEE 952's bias instability B = flicker / 0.664; "
       "class 4; 0: off)"),
    _p("tau_min", 0.1, 0.0, unit="s", low_open=True, description="shortest correlation time of "
       "the flicker bias's Gauss-Markov components (tau_min < tau_max)"),
    _p("tau_max", 100.0, 0.0, unit="s", low_open=True, description="longest correlation time of "
       "the flicker bias's Gauss-Markov components (one per decade from tau_min, at most 7 "
       "decades)"),
    _p("d_inf", 0.0, unit="V", description="exposure drift that never recovers: d_k = d_inf "
       "(1 - exp(-E_k / E_tau)), E_k = E_{k-1} + x_k^2 Ts (class 3; 0: off)"),
    _p("E_tau", 1.0, 0.0, unit="g2.s", low_open=True, description="exposure at which the "
       "exposure drift has reached 1 - 1/e of d_inf"),
    _p("theta", 0.0, unit="rad", description="tilt: the sensor measures x + sin(theta) [g], the "
       "letter's g-offset (class 2)"),
    _p("T", 298.15, unit="K", description="temperature of the sensor (class 2, with kT_bias "
       "and kT_scale)"),
    _p("T0", 298.15, 0.0, unit="K", description="reference temperature of kT_bias and kT_scale",
       low_open=True),
    _p("kT_bias", 0.0, unit="V/K", description="temperature coefficient of the bias: the output "
       "adds kT_bias (T - T0) (class 2; 0: off)"),
    _p("kT_scale", 0.0, unit="1/K", description="temperature coefficient of the scale factor: "
       "the sensor senses (1 + kT_scale (T - T0)) times the acceleration (class 2; 0: off)"),
    _p("range", 0.0, 0.0, unit="g", description="measurement range: the sensed acceleration is "
       "clipped to [-range, range] (saturation); with bits > 0 and Vs = 0 the ADC spans a0 +- "
       "|a1| range (0: off)"),
)}


#: Parameters that must not be 0 (a sensitivity: the filter divides by it), beyond their range.
NONZERO = ("a1", "a1y")


def allowed(name):
    """Human-readable allowed range of parameter ``name``, e.g. ``'R > 0'``, ``'an integer
    drive >= 0 and drive <= 2'`` (a parameter whose default is an int takes whole numbers
    only: an Integer variable of the FMUs)."""
    p = PARAMETERS[name]
    parts = []
    if p.low is not None:
        parts.append("%s %s %s" % (name, ">" if p.low_open else ">=", _fmt(p.low)))
    if p.high is not None:
        parts.append("%s %s %s" % (name, "<" if p.high_open else "<=", _fmt(p.high)))
    if name in NONZERO:
        parts.append("%s != 0" % name)
    if isinstance(p.default, int):
        return "an integer " + " and ".join(parts) if parts else "any integer"
    return " and ".join(parts) if parts else ANY_FINITE


#: What :func:`allowed` says of a parameter without bounds.
ANY_FINITE = "any finite value"


def next_float(x, toward):
    """The double next to ``x`` in the direction of ``toward`` (``math.nextafter``, also on
    Python 3.8, where the FMUs may run)."""
    if x == toward:
        return x
    if x == 0.0:
        return math.copysign(5e-324, toward - x)
    import struct
    bits = struct.unpack("<q", struct.pack("<d", x))[0]
    bits += 1 if (toward > x) == (x > 0.0) else -1
    return struct.unpack("<d", struct.pack("<q", bits))[0]


def declared_range(name):
    """``(min, max)`` of parameter ``name`` as closed bounds (None where unbounded), for FMI 2
    model descriptions, whose bounds are closed: an open bound ``R > 0`` becomes the accepted
    double next to it (``R >= 5e-324``, ``A <= 0.9999999999999999``)."""
    p = PARAMETERS[name]
    low, high = p.low, p.high
    if low is not None and p.low_open:
        low = next_float(float(low), math.inf)
    if high is not None and p.high_open:
        high = next_float(float(high), -math.inf)
    return low, high


def _fmt(v):
    return str(v) if isinstance(v, int) else "%g" % v


def problem(name, value):
    """Why ``value`` is not allowed for parameter ``name``, or None when it is."""
    p = PARAMETERS[name]
    try:  # (text and True/False are not numbers, though float() reads them)
        if isinstance(value, (str, bytes, bool)):
            raise TypeError
        v = float(value)
    except (TypeError, ValueError):
        return "%s = %r is not a number; allowed: %s" % (name, value, allowed(name))
    if not math.isfinite(v):
        rule = allowed(name)
        return "%s = %r is not finite; allowed: %s" % (
            name, value, rule if rule == ANY_FINITE else "a finite value with " + rule)
    if isinstance(p.default, int) and v != int(v):  # a wrong type, whatever its range
        return "%s = %r is not an integer; allowed: %s" % (name, value, allowed(name))
    bad = False
    if p.low is not None:
        bad = v <= p.low if p.low_open else v < p.low
    if not bad and p.high is not None:
        bad = v >= p.high if p.high_open else v > p.high
    if not bad and name in NONZERO:
        bad = v == 0.0
    if bad:
        return "%s = %r is out of range; allowed: %s" % (name, value, allowed(name))
    return None


def check(values):
    """Problems of a mapping of parameter values (names not listed here are ignored)."""
    out = []
    for name, value in values.items():
        if name in PARAMETERS:
            msg = problem(name, value)
            if msg:
                out.append(msg)
    return out


def defaults(*names):
    """Default values of the named parameters."""
    return {n: PARAMETERS[n].default for n in names}
