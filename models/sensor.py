"""Internal (not a stable API; use driftfmu.simulate instead).

The weakly nonlinear sensor of the letter (eqs. 2 and 6), up to the 4th order (eqs. 3-5).

.. math:: z_k = h(x_k) + v_k, \\qquad
          h(x) = a_0 + a_1 x + a_2 x^2 + a_3 x^3 + a_4 x^4, \\qquad v_k \\sim N(0, R)

The letter's specific case is ``a3 = a4 = 0``; then every function here computes exactly what the
quadratic sensor computed before the higher terms existed (same bits: the terms are not even
evaluated).  The even-order terms make a state-dependent DC offset (the drift)
``E[h(x)] - a0 - a1 E[x] = a2 E[x^2] + a3 E[x^3] + a4 E[x^4]``, which for a zero-mean Gaussian
state is ``a2 sigma_x^2 + 3 a4 sigma_x^4`` (eqs. 4-5; the odd ``a3`` term averages to zero).
"""
from . import _ops
from .noise import STREAM_MEASUREMENT, normal


def higher(a3, a4):
    """True unless ``a3`` and ``a4`` are both the number 0 (the letter's quadratic sensor), of
    any numeric type (a NumPy scalar too); an array of coefficients (a batch that sweeps them)
    counts as higher-order."""
    if type(a3) is float and type(a4) is float:  # the per-sample case of one FMU instance
        return a3 != 0.0 or a4 != 0.0
    return not (_zero(a3) and _zero(a4))


def _zero(a):
    """``a`` is one number (not an array of them) and it is 0."""
    return (_ops.is_scalar(a) or getattr(a, "ndim", None) == 0) and a == 0.0


def h(x, a0, a1, a2, a3=0.0, a4=0.0):
    """Noise-free characteristic ``a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4``."""
    y = a0 + a1 * x + a2 * x * x
    if higher(a3, a4):
        x2 = x * x
        y = y + a3 * x2 * x + a4 * x2 * x2
    return y


def dh_dx(x, a1, a2, a3=0.0, a4=0.0):
    """Slope of the characteristic, ``a1 + 2 a2 x + 3 a3 x^2 + 4 a4 x^3`` (the EKF's ``H``)."""
    d = a1 + 2.0 * a2 * x
    if higher(a3, a4):
        x2 = x * x
        d = d + 3.0 * a3 * x2 + 4.0 * a4 * x2 * x
    return d


def measure(x, a0, a1, a2, R, v, a3=0.0, a4=0.0):
    """Measurement ``h(x) + sqrt(R) v`` with ``v`` a standard normal draw."""
    return h(x, a0, a1, a2, a3, a4) + _ops.sqrt(R) * v


def measurement_noise(seed, k):
    """Standard normal draw ``v_k / sqrt(R)`` for sample ``k`` under ``seed``."""
    return normal(seed, STREAM_MEASUREMENT, k)


def h_bilinear(own, other, a0, a1, a2, b):
    """Noise-free output of one axis of the dual-axis sensor, ``a0 + a1 x + a2 x^2 + b x y``
    (``own = x``, ``other = y``); ``b = 0`` is :func:`h`, same bits."""
    return h(own, a0, a1, a2) + b * own * other


def measure_bilinear(own, other, a0, a1, a2, b, R, v):
    """Measurement ``h_bilinear + sqrt(R) v``; ``b = 0`` is :func:`measure`, same bits."""
    return h_bilinear(own, other, a0, a1, a2, b) + _ops.sqrt(R) * v


def drift(a2, variance, a4=0.0, m4=None):
    """Expected drift ``a2 E[x^2] + a4 E[x^4]`` of a zero-mean state with symmetric distribution
    (the odd ``a3`` term averages to zero).

    ``variance`` is ``E[x^2]``; ``m4`` is ``E[x^4]``, by default the Gaussian ``3 sigma_x^4``, so
    that the result is the letter's ``a2 sigma_x^2 + 3 a4 sigma_x^4`` (eqs. 4-5).  ``a4 = 0``
    gives ``a2 sigma_x^2``, same bits as the quadratic sensor's.
    """
    if _zero(a4):
        return a2 * variance
    if m4 is None:
        m4 = 3.0 * variance * variance
    return a2 * variance + a4 * m4
