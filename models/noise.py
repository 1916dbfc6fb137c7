"""Internal (not a stable API; use driftfmu.simulate instead).

Counter-based Gaussian noise: a pure function of (seed, stream, sample index).

Sample ``k`` of stream ``s`` under seed ``seed`` is computed from those three integers alone, so
the same noise comes out of one FMU instance stepping sample by sample, out of a batch of
Monte-Carlo runs computed at once, after an FMU state restore, and at any communication step
size.  Nothing here keeps state.

Bits: SplitMix64 (Steele, Lea and Flood, 2014) finaliser over a key derived from (seed, stream)
plus ``k`` times the golden-ratio increment.  Uniform: the top 52 bits, centred, in (0, 1).
Normal: Acklam's rational approximation of the inverse normal CDF (relative error below
1.2e-9), evaluated with the arithmetic-only ``log`` of :mod:`driftfmu.models._ops` so that Python floats
and NumPy arrays give the same bits.

Integers: Python ``int`` for one instance; NumPy ``uint64`` arrays (seed per run, index per
sample, broadcast against each other) for a batch.
"""
import functools

from . import _ops

MASK64 = 0xFFFFFFFFFFFFFFFF
GOLDEN = 0x9E3779B97F4A7C15
_M1 = 0xBF58476D1CE4E5B9
_M2 = 0x94D049BB133111EB

#: Streams: one per noise source, so sources never share a sequence under one seed.
STREAM_PROCESS = 1      # w_k of the Gauss-Markov excitation
STREAM_MEASUREMENT = 2  # v_k of the sensor
STREAM_SENSOR_Y = 3     # second-axis excitation of the accelerometer
STREAM_PHASE = 4        # random phase / amplitude draws of an experiment
STREAM_MEASUREMENT_Y = 5  # v_k of the accelerometer's second axis
STREAM_INPUT = 6        # Gaussian known input u_k of the process model (eq. 1)
# the sensor's slow errors (models/errors.py), one stream each; index 0 is the draw before
# sample 1 (a turn-on value, a stationary initial state)
STREAM_TURN_ON = 7      # turn-on bias, drawn once per seed
STREAM_RANDOM_WALK = 8  # bias random walk
STREAM_BIAS_GM = 9      # Gauss-Markov bias instability
STREAM_FLICKER = 16     # flicker bias: component i draws from stream STREAM_FLICKER + i


def _mix(z):
    """SplitMix64 finaliser of a 64-bit integer (Python int or uint64 array)."""
    z = ((z ^ (z >> 30)) * _M1) & MASK64
    z = ((z ^ (z >> 27)) * _M2) & MASK64
    return z ^ (z >> 31)


def _as_uint64(v):
    if _ops.is_scalar(v):
        return int(v) & MASK64
    return _ops._np().asarray(v).astype(_ops._np().uint64)


def key(seed, stream):
    """64-bit key of a (seed, stream) pair."""
    if _ops.is_scalar(seed):
        return _key_int(int(seed) & MASK64, stream)
    return _mix(_mix(_as_uint64(seed)) ^ ((stream * GOLDEN) & MASK64))


@functools.lru_cache(maxsize=256)
def _key_int(seed, stream):
    # one FMU instance asks for the same key at every sample: computed once
    return _mix(_mix(seed) ^ ((stream * GOLDEN) & MASK64))


def bits(seed, stream, k):
    """64 random bits for sample ``k`` (``k >= 1``; ``k = 0`` is the draw before sample 1) of
    ``stream`` under ``seed``."""
    if (type(k) is int and type(seed) is int) or (_ops.is_scalar(k) and _ops.is_scalar(seed)):
        # one FMU instance, every sample: the short way
        return _mix((_key_int(int(seed) & MASK64, stream) + ((int(k) * GOLDEN) & MASK64))
                    & MASK64)
    k = _as_uint64(k)
    return _mix((key(seed, stream) + ((k * GOLDEN) & MASK64)) & MASK64)


def uniform(seed, stream, k):
    """Uniform draw in the open interval (0, 1), on a grid of 2^-52."""
    return ((bits(seed, stream, k) >> 12) + 0.5) * 2.0 ** -52


# Acklam's coefficients for the inverse of the standard normal CDF.
_A = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
      1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00)
_B = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
      6.680131188771972e+01, -1.328068155288572e+01)
_C = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
      -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00)
_D = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
      3.754408661907416e+00)
P_LOW = 0.02425


def _central(p):
    q = p - 0.5
    r = q * q
    num = (((((_A[0] * r + _A[1]) * r + _A[2]) * r + _A[3]) * r + _A[4]) * r + _A[5]) * q
    den = ((((_B[0] * r + _B[1]) * r + _B[2]) * r + _B[3]) * r + _B[4]) * r + 1.0
    return num / den


def _lower_tail(p):
    q = _ops.sqrt(-2.0 * _ops.log(p))
    num = ((((_C[0] * q + _C[1]) * q + _C[2]) * q + _C[3]) * q + _C[4]) * q + _C[5]
    den = (((_D[0] * q + _D[1]) * q + _D[2]) * q + _D[3]) * q + 1.0
    return num / den


def inverse_normal_cdf(p):
    """Standard normal quantile of ``p`` in (0, 1) (Acklam; relative error < 1.2e-9)."""
    if type(p) is float or _ops.is_scalar(p):
        if p < P_LOW:
            return _lower_tail(p)
        if p > 1.0 - P_LOW:
            return -_lower_tail(1.0 - p)
        return _central(p)
    out = _central(p)
    # both tails at once (one pass of the tail's arithmetic over few values): the lower tail at
    # p, the upper at 1 - p, negated
    tail = (p < P_LOW) | (p > 1.0 - P_LOW)
    pt = p[tail]
    lower = pt < P_LOW
    t = _lower_tail(_ops.where(lower, pt, 1.0 - pt))
    out[tail] = _ops.where(lower, t, -t)
    return out


def normal(seed, stream, k):
    """Standard normal draw for sample ``k`` of ``stream`` under ``seed``."""
    return inverse_normal_cdf(uniform(seed, stream, k))


# -- the slow errors' draws: the ziggurat -------------------------------------------------------
#
# The sensor's slow errors (models/errors.py) draw up to ten numbers a sample, where the letter's
# sensor draws one; their streams use the ziggurat method of Marsaglia and Tsang (2000), which
# takes most draws with a table look-up, one multiplication and one comparison (Acklam's
# quantile above takes two polynomials and a division).  The letter's streams keep the quantile.
#
# The normal density's right half (up to the factor 1/sqrt(2 pi)), f(x) = exp(-x^2/2), is
# covered by ZIG_N layers of equal area ZIG_V: layer i (i >= 1) the box of width x_i between the
# heights f(x_i) and f(x_(i+1)); layer 0 the box of width x_1 = ZIG_R under f(ZIG_R) with the tail
# beyond ZIG_R, as one box of width x_0 = ZIG_V / f(ZIG_R).  A draw: a 64-bit word w of the
# stream; i = the low 8 bits; u = the top 53 bits over [-1, 1); x = u x_i.  Where |u| <
# x_(i+1) / x_i (98.5 % of the draws), x is under the curve: done.  Otherwise, for i >= 1, a
# height y uniform between f(x_i) and f(x_(i+1)) accepts x where y < f(x) (the wedge); for i = 0,
# a draw from the tail beyond ZIG_R (Marsaglia's: a = -log(U1) / R, b = -log(U2) until 2 b > a^2,
# then R + a, with u's sign).  A rejected draw starts again.  The words after w: w' = mix(w +
# GOLDEN), one each for a height, a tail's U1 and U2, a new start.
#
# The tables come from ZIG_R and ZIG_V by x_(i+1) = sqrt(-2 log(ZIG_V / x_i + f(x_i))) with the
# arithmetic-only exp and log of _ops, so the same bits on every machine; the C twin has them as
# literals (fmu_src/native/models/ziggurat_table.h, written by generate.py, compared by a test).

#: Layers of the ziggurat.
ZIG_N = 256
#: The right edge of the base layer (Marsaglia and Tsang's r for 256 layers).
ZIG_R = 3.6541528853610088
#: The area of each layer under f(x) = exp(-x^2/2) (Marsaglia and Tsang's v for 256 layers).
ZIG_V = 4.92867323399e-3


def _density(x):
    """``exp(-x^2/2)`` by the arithmetic-only exp (float or array)."""
    return _ops.exp(-0.5 * x * x)


def _ziggurat_tables():
    x = [0.0] * (ZIG_N + 1)
    x[0] = ZIG_V / _density(ZIG_R)
    x[1] = ZIG_R
    for i in range(2, ZIG_N):
        x[i] = _ops.sqrt(-2.0 * _ops.log(ZIG_V / x[i - 1] + _density(x[i - 1])))
    ratio = tuple(x[i + 1] / x[i] for i in range(ZIG_N))
    return tuple(x), ratio, tuple(_density(v) for v in x)


#: The layers' edges x_0 .. x_256 (x_256 = 0), the fast acceptance bound x_(i+1) / x_i of each
#: layer, and f at each edge.
ZIG_X, ZIG_RATIO, ZIG_F = _ziggurat_tables()


def _next_word(w):
    """The word after ``w`` in a draw that needs more than one (a Python int or a uint64
    array)."""
    return _mix((w + GOLDEN) & MASK64)


def _open_uniform(w):
    """The uniform in (0, 1) of a word (as :func:`uniform`; int or uint64 array)."""
    return ((w >> 12) + 0.5) * 2.0 ** -52


def _layer(w):
    """The layer of a try: the word's low 8 bits (int or uint64 array)."""
    return w & 0xFF


def _centred(w):
    """The ``u`` of a try: the word's top 53 bits over [-1, 1) (exact: int or uint64 array)."""
    return (w >> 11) * 2.0 ** -52 - 1.0


def _ziggurat_rest(w, i, u, x):
    """The draw whose first try (word ``w``: layer ``i``, ``u``, ``x``) was not in its layer's
    fast region."""
    while True:
        if i == 0:
            while True:  # the tail beyond ZIG_R
                w = _next_word(w)
                a = -_ops.log(_open_uniform(w)) / ZIG_R
                w = _next_word(w)
                b = -_ops.log(_open_uniform(w))
                if b + b > a * a:
                    return ZIG_R + a if u >= 0.0 else -(ZIG_R + a)
        w = _next_word(w)
        y = ZIG_F[i] + _open_uniform(w) * (ZIG_F[i + 1] - ZIG_F[i])
        if y < _density(x):
            return x
        w = _next_word(w)
        i, u = _layer(w), _centred(w)
        x = u * ZIG_X[i]
        if abs(u) < ZIG_RATIO[i]:
            return x


def ziggurat_of(w):
    """The standard normal draw of the word ``w`` (a 64-bit Python int or a uint64 array)."""
    if _ops.is_scalar(w):
        w = int(w)
        i, u = _layer(w), _centred(w)
        x = u * ZIG_X[i]
        if abs(u) < ZIG_RATIO[i]:
            return x
        return _ziggurat_rest(w, i, u, x)
    np = _ops._np()
    X, RATIO, F = _ziggurat_arrays()
    i, u = _layer(w), _centred(w)
    out = u * X[i]
    flat = out.ravel()  # (a view: out is a new C-ordered array)
    # the draws not in their layer's fast region (1.5 %): one round of them at once, as
    # _ziggurat_rest takes them (the same words, the same operations: a wedge's height, then a
    # new start), then what is left one by one in _ziggurat_rest (a wedge rejected again, a
    # tail; an array's exp costs as much as some twenty floats' do)
    i, u = i.ravel(), u.ravel()
    at = np.flatnonzero(~(np.abs(u) < RATIO[i]))
    w, i, u, x = w.ravel()[at], i[at], u[at], flat[at]
    if at.size > _ZIG_ROUND:
        wedge = i != 0
        rest = [(at[~wedge], w[~wedge], i[~wedge], u[~wedge], x[~wedge])]
        at, w, i, x = at[wedge], _next_word(w[wedge]), i[wedge], x[wedge]
        y = F[i] + _open_uniform(w) * (F[i + 1] - F[i])
        kept = y < _density(x)
        flat[at[kept]] = x[kept]
        at, w = at[~kept], _next_word(w[~kept])
        i, u = _layer(w), _centred(w)
        x = u * X[i]
        fast = np.abs(u) < RATIO[i]
        flat[at[fast]] = x[fast]
        rest.append((at[~fast], w[~fast], i[~fast], u[~fast], x[~fast]))
    else:
        rest = [(at, w, i, u, x)]
    for at, w, i, u, x in rest:
        for j in range(at.size):
            flat[at[j]] = _ziggurat_rest(int(w[j]), int(i[j]), float(u[j]), float(x[j]))
    return out


#: Draws outside the fast region that an array takes one by one rather than in a round at once.
_ZIG_ROUND = 24


@functools.lru_cache(maxsize=1)
def _ziggurat_arrays():
    np = _ops._np()
    return np.array(ZIG_X), np.array(ZIG_RATIO), np.array(ZIG_F)


def ziggurat(seed, stream, k):
    """Standard normal draw for sample ``k`` of ``stream`` under ``seed`` by the ziggurat (the
    slow errors' streams; :func:`normal` is the quantile's)."""
    return ziggurat_of(bits(seed, stream, k))
