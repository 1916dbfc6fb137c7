"""Excitation: the true acceleration ``x_k`` that drives the sensor.

Sample ``k = 1, 2, ...`` sits at time ``t_k = t0 + (k - 1) Ts``.

Gaussian (the letter's Sec. III): a Gauss-Markov process

.. math:: x_k = A x_{k-1} + w_k, \\qquad w_k \\sim N(0, Q),

white for ``A = 0``; stationary variance ``Q / (1 - A^2)`` for ``|A| < 1``.

Sinusoidal (Sec. IV): ``x_k = X sin(2 pi f t_k + phi)``, variance ``X^2 / 2`` over whole periods.

Two axes (:mod:`driftfmu.models.dualaxis`): a second Gauss-Markov axis ``y`` whose process noise is
correlated with ``x``'s (:func:`gaussian_pair`), or a second sinusoid at the same frequency.
"""
from . import _ops
from .noise import STREAM_PROCESS, STREAM_SENSOR_Y, normal

GAUSSIAN = 1
SINUSOIDAL = 2
KINDS = {GAUSSIAN: "gaussian", SINUSOIDAL: "sinusoidal"}


def gauss_markov(x_prev, A, Q, w):
    """One step ``x_k = A x_{k-1} + sqrt(Q) w`` with ``w`` a standard normal draw."""
    return A * x_prev + _ops.sqrt(Q) * w


def gaussian_sample(x_prev, A, Q, seed, k):
    """Sample ``k`` of the Gauss-Markov excitation under ``seed`` (process-noise stream)."""
    return gauss_markov(x_prev, A, Q, normal(seed, STREAM_PROCESS, k))


def gaussian_pair(x_prev, y_prev, A, Q, Qy, rho, seed, k):
    """Sample ``k`` of the 2-D Gauss-Markov excitation under ``seed``.

    .. math:: x_k = A x_{k-1} + \\sqrt{Q}\\, w_1, \\qquad
              y_k = A y_{k-1} + \\sqrt{Q_y} \\big(\\rho\\, w_1 + \\sqrt{1 - \\rho^2}\\, w_2\\big)

    with ``w_1`` the process-noise stream (so ``x`` is :func:`gaussian_sample`, same bits) and
    ``w_2`` the second-axis stream; the noises have correlation ``rho`` and the stationary
    covariance is ``E[x y] = rho sqrt(Q Qy) / (1 - A^2)``.  ``Qy = 0`` gives ``y = 0``.
    """
    w1 = normal(seed, STREAM_PROCESS, k)
    x = gauss_markov(x_prev, A, Q, w1)
    if _ops.is_scalar(Qy) and Qy == 0.0:
        return x, 0.0
    w2 = normal(seed, STREAM_SENSOR_Y, k)
    y = A * y_prev + _ops.sqrt(Qy) * (rho * w1 + _ops.sqrt(1.0 - rho * rho) * w2)
    return x, y


def sine(k, X, f, Ts, phi=0.0):
    """Sample ``k`` of ``X sin(2 pi f t_k + phi)`` with ``t_k = (k - 1) Ts``.

    The phase is carried in cycles, ``f (k - 1) Ts + phi / (2 pi)``, and reduced exactly before
    the sine, so long runs keep full accuracy.
    """
    import math
    return X * _ops.sin2pi(f * Ts * (k - 1) + phi / (2.0 * math.pi))


def stationary_variance(kind, A=0.0, Q=0.0, X=0.0):
    """Variance of ``x``: ``Q / (1 - A^2)`` (Gaussian, ``|A| < 1``) or ``X^2 / 2`` (sinusoidal)."""
    if kind == GAUSSIAN:
        return Q / (1.0 - A * A)
    if kind == SINUSOIDAL:
        return X * X / 2.0
    raise ValueError("excitation kind must be %s, got %r" % (sorted(KINDS), kind))
