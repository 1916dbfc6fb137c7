"""The weakly nonlinear sensor of the letter (eqs. 2 and 6).

.. math:: z_k = h(x_k) + v_k = a_0 + a_1 x_k + a_2 x_k^2 + v_k, \\qquad v_k \\sim N(0, R)

The even-order term makes a state-dependent DC offset (the drift) ``E[a2 x^2] = a2 sigma_x^2``.
"""
from . import _ops
from .noise import STREAM_MEASUREMENT, normal


def h(x, a0, a1, a2):
    """Noise-free characteristic ``a0 + a1 x + a2 x^2``."""
    return a0 + a1 * x + a2 * x * x


def dh_dx(x, a1, a2):
    """Slope of the characteristic, ``a1 + 2 a2 x`` (the EKF's ``H``)."""
    return a1 + 2.0 * a2 * x


def measure(x, a0, a1, a2, R, v):
    """Measurement ``h(x) + sqrt(R) v`` with ``v`` a standard normal draw."""
    return h(x, a0, a1, a2) + _ops.sqrt(R) * v


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


def drift(a2, variance):
    """Expected drift of the quadratic sensor, ``a2 sigma_x^2`` (eq. 4)."""
    return a2 * variance
