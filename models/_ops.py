"""Internal (not a stable API; use driftfmu.simulate instead).

Elementwise helpers that work unchanged on a Python float and on a NumPy array.

The model functions in this package are written with plain arithmetic (``+ - * /``) and the
helpers below, so one instance inside an FMU runs them on floats with the standard library only,
and the batch engine runs the very same code on arrays of Monte-Carlo runs.  Every operation used
is correctly rounded in IEEE 754 double precision (``sqrt`` included), so both paths give
bit-identical results for the same inputs.  NumPy is imported lazily, only when an array arrives.

``log``, ``exp`` (and ``exp_estrin``), ``sin2pi`` and ``sin`` are computed here by arithmetic only (libm's may differ in the
last bit between platforms, and between ``math`` and ``numpy``); fmu_src/native/models/ops.c is
their C port, operation for operation, and the native FMUs give the same bits.
"""
import math


def is_scalar(x):
    """True for a Python number (NumPy's ``float64`` scalar counts: it subclasses ``float``)."""
    # (``type(x) is float`` first: one FMU instance asks this about floats on every sample)
    return type(x) is float or isinstance(x, (int, float))


def _np():
    import numpy
    return numpy


def sqrt(x):
    """Correctly rounded square root of a float or an array."""
    if type(x) is float or is_scalar(x):
        return math.sqrt(x)
    return _np().sqrt(x)


def floor(x):
    """Floor of a float (as float) or an array; inf and nan are their own floor (as C's
    ``floor`` and NumPy's: math.floor would raise, the C twin ``ops_floor`` does not).  The
    floor of -0.0 is 0.0 on both paths (as ``float(math.floor(-0.0))`` and ``ops_floor``; NumPy's
    is -0.0, which ``+ 0.0`` turns into 0.0 and leaves every other value as it is)."""
    if is_scalar(x):
        if x - x != 0.0:
            return x
        return float(math.floor(x))
    return _np().floor(x) + 0.0


def frexp(x):
    """Mantissa in [0.5, 1) and integer exponent, exactly, of a float or an array."""
    if is_scalar(x):
        return math.frexp(x)
    return _np().frexp(x)


def ldexp(m, e):
    """``m 2^e`` exactly (one rounding if the result is subnormal) of floats or arrays; ``e``
    holds whole numbers (int or float)."""
    if is_scalar(m) and is_scalar(e):
        return math.ldexp(m, int(e))
    np = _np()
    return np.ldexp(m, np.asarray(e).astype(np.int64))


def where(cond, a, b):
    """``a`` where ``cond`` holds, else ``b``: a plain choice for scalars, elementwise for arrays."""
    if is_scalar(cond) or isinstance(cond, bool):
        return a if cond else b
    return _np().where(cond, a, b)


LN2 = 0.6931471805599453
SQRT_HALF = 0.7071067811865476


def log(x):
    """Natural logarithm of a positive float or array, by arithmetic only.

    ``x = m 2^e`` exactly (``frexp``), ``m`` moved into [sqrt(1/2), sqrt(2)), then
    ``ln m = 2 atanh(s)``, ``s = (m - 1)/(m + 1)``, summed to ``s^21`` (truncation below 1e-17).
    Unlike ``math.log`` and ``numpy.log``, which may differ in the last bit, this gives the same
    bits on both paths.  Accuracy: a few ulp.
    """
    m, e = frexp(x)
    low = m < SQRT_HALF
    m = where(low, m * 2.0, m)
    e = where(low, e - 1, e)
    s = (m - 1.0) / (m + 1.0)
    s2 = s * s
    poly = 1.0 / 21.0
    for k in (19, 17, 15, 13, 11, 9, 7, 5, 3, 1):
        poly = poly * s2 + 1.0 / k
    return e * LN2 + 2.0 * s * poly


#: ``ln 2`` split as in fdlibm: ``LN2_HI`` has 33 significant bits, so ``n LN2_HI`` is exact for
#: ``|n| < 2^20``; ``LN2_HI + LN2_LO`` is ``ln 2`` to about 1e-26.
LN2_HI = 0.6931471803691238
LN2_LO = 1.9082149292705877e-10
INV_LN2 = 1.4426950408889634
#: ``exp`` gives ``inf`` above ``EXP_HIGH`` (just below ``ln`` of the largest double, so that
#: ``e^r 2^n`` never overflows inside) and ``0.0`` below ``EXP_LOW`` (where ``e^x`` rounds to 0).
EXP_HIGH = 709.78
EXP_LOW = -745.1332191019412


def exp(x, _floor=math.floor, _ldexp=math.ldexp):
    """``e^x`` of a float or an array, by arithmetic only (same bits on both paths).

    ``x = n ln 2 + r`` with ``n = floor(x / ln 2 + 1/2)``; ``r = (x - n LN2_HI) - n LN2_LO``,
    where ``x - n LN2_HI`` is exact (Cody and Waite), so ``|r| <= ln(2)/2 + 1e-16``.  Then
    ``e^r`` is the Taylor series summed to ``r^14/14!`` in Horner form, coefficients
    ``1.0 / k!`` (truncation below ``0.35^15/15! = 1e-19`` relative, well under 1e-17), and
    ``e^x = e^r 2^n`` exactly (:func:`ldexp`).  Unlike ``math.exp`` and ``numpy.exp``, which may differ in the last bit
    between platforms and paths, this gives the same bits everywhere.  Accuracy: a few ulp for
    ``EXP_LOW <= x <= EXP_HIGH`` (subnormal results lose bits); ``inf`` above, ``0.0`` below,
    ``nan`` for ``nan``.
    """
    if type(x) is float and EXP_LOW <= x <= EXP_HIGH:  # one FMU instance: the same steps,
        m = _floor(x * INV_LN2 + 0.5)                  # the loop below written out (n = m)
        n = float(m)
        r = (x - n * LN2_HI) - n * LN2_LO
        c = _EXP_COEFF
        poly = (((((((((((((c[14] * r + c[13]) * r + c[12]) * r + c[11]) * r + c[10]) * r
                         + c[9]) * r + c[8]) * r + c[7]) * r + c[6]) * r + c[5]) * r + c[4])
                    * r + c[3]) * r + c[2]) * r + c[1]) * r + c[0]
        return _ldexp(poly, m)
    return _exp_reduced(x, _horner)


def exp_estrin(x, _floor=math.floor, _ldexp=math.ldexp):
    """``e^x`` as :func:`exp` (the same reduction and Taylor polynomial, the same accuracy and
    range), the polynomial evaluated by Estrin's scheme (:func:`_estrin`): its longest chain of
    dependent operations is 4 multiply-adds after the powers ``r^2, r^4, r^8`` instead of
    Horner's 14, so a CPU runs it in about a third of the time where nothing else waits on it.
    Its last bits are its own (not :func:`exp`'s); the same on both paths and in C.  The
    exposure drift's exponential (:func:`driftfmu.models.errors.exposure`), the one the sensor
    computes at every sample."""
    if type(x) is float and EXP_LOW <= x <= EXP_HIGH:  # one FMU instance: math's floor, ldexp
        m = _floor(x * INV_LN2 + 0.5)
        n = float(m)
        return _ldexp(_estrin((x - n * LN2_HI) - n * LN2_LO), m)
    return _exp_reduced(x, _estrin)


def _horner(r):
    """``sum r^k / k!`` for ``k = 0 .. 14`` in Horner form (:func:`exp`)."""
    poly = _EXP_COEFF[14]
    for c in _EXP_DOWN:
        poly = poly * r + c
    return poly


def _estrin(r):
    """``sum r^k / k!`` for ``k = 0 .. 14`` by Estrin's scheme (:func:`exp_estrin`): pairs
    ``c_k + c_(k+1) r``, joined by ``r^2``, then ``r^4``, then ``r^8``."""
    c = _EXP_COEFF
    r2 = r * r
    r4 = r2 * r2
    q0 = (c[0] + c[1] * r) + (c[2] + c[3] * r) * r2
    q1 = (c[4] + c[5] * r) + (c[6] + c[7] * r) * r2
    q2 = (c[8] + c[9] * r) + (c[10] + c[11] * r) * r2
    q3 = (c[12] + c[13] * r) + c[14] * r2
    return (q0 + q1 * r4) + (q2 + q3 * r4) * (r4 * r4)


def _exp_reduced(x, poly_of):
    """``e^x`` of :func:`exp` and :func:`exp_estrin` for a float out of range, a NumPy scalar
    or an array: ``poly_of(r) 2^n``, and ``inf``, ``0.0`` or ``nan`` out of the range."""
    big = x > EXP_HIGH
    tiny = x < EXP_LOW
    nan = x != x
    if is_scalar(x):
        if nan or big or tiny:
            return x if nan else (math.inf if big else 0.0)
    else:
        x_in, x = x, where(big | tiny | nan, 0.0, x)
    n = floor(x * INV_LN2 + 0.5)
    r = (x - n * LN2_HI) - n * LN2_LO
    y = ldexp(poly_of(r), n)
    if is_scalar(y):
        return y
    y = where(big, math.inf, y)
    y = where(nan, x_in, y)
    return where(tiny, 0.0, y)


def sin2pi(cycles):
    """``sin(2 pi c)`` of a float or an array, by arithmetic only (same bits on both paths).

    The argument is reduced exactly to ``r = c - floor(c)`` in [0, 1), folded onto [0, 1/4] by the
    symmetries of the sine, and the Taylor series of ``sin`` is summed to degree 23 on
    [0, pi/2] (truncation below 1e-16).
    """
    r = cycles - floor(cycles)
    sign = where(r >= 0.5, -1.0, 1.0)
    r = where(r >= 0.5, r - 0.5, r)
    r = where(r > 0.25, 0.5 - r, r)
    t = 2.0 * math.pi * r
    t2 = t * t
    # Horner form of t - t^3/3! + t^5/5! - ... + t^23/23!
    poly = 0.0
    for c in _SIN_DOWN:
        poly = poly * t2 + c
    return sign * t * poly


#: ``1.0 / k!`` for ``k = 0 .. 14`` (:func:`exp`'s Taylor coefficients) and those of ``k = 13
#: .. 0`` in Horner order; ``(+-1) / n!`` for ``n = 23, 21, .., 1`` (:func:`sin2pi`'s, in Horner
#: order): computed once, the values the functions used to compute at every call.
_EXP_COEFF = tuple(1.0 / math.factorial(k) for k in range(15))
_EXP_DOWN = tuple(_EXP_COEFF[k] for k in range(13, -1, -1))
_SIN_DOWN = tuple((1.0 if (n // 2) % 2 == 0 else -1.0) / math.factorial(n)
                  for n in range(23, 0, -2))


#: ``2 pi`` (exact doubling of ``math.pi``): :func:`sin` divides by it.
TWO_PI = 2.0 * math.pi


def sin(x):
    """``sin(x)`` of a float or an array (``x`` in radians), by arithmetic only: :func:`sin2pi`
    of ``x / (2 pi)`` (the division correctly rounded, so the same bits on both paths and in
    C).  Accuracy: a few ulp of ``x`` (the reduction to cycles rounds once)."""
    return sin2pi(x / TWO_PI)
