"""Internal (not a stable API; use driftfmu.simulate instead).

Excitation: the true acceleration ``x_k`` that drives the sensor.

Sample ``k = 1, 2, ...`` sits at time ``t_k = t0 + (k - 1) Ts``.

Gaussian (the letter's Sec. III): a Gauss-Markov process with the known input of eq. 1

.. math:: x_k = A x_{k-1} + B u_k + w_k, \\qquad w_k \\sim N(0, Q),

white for ``A = 0``; stationary variance ``Q / (1 - A^2)`` for ``|A| < 1`` and ``B = 0`` (the
letter's case, same bits as without the input).  The input ``u_k`` (:func:`input_sample`) is off,
Gaussian white ``N(0, Qu)`` or a sinusoid ``Xu sin(2 pi fu t_k)``; :func:`state_moments` gives the
stationary ``E[x^2]`` and ``E[x^4]`` with it.

Sinusoidal (Sec. IV): ``x_k = X sin(2 pi f t_k + phi)``, variance ``X^2 / 2`` over whole periods.

Two axes (:mod:`driftfmu.models.dualaxis`): a second Gauss-Markov axis ``y`` whose process noise is
correlated with ``x``'s (:func:`gaussian_pair`), or a second sinusoid at the same frequency.
"""
from . import _ops
from .noise import STREAM_INPUT, STREAM_PROCESS, STREAM_SENSOR_Y, normal

GAUSSIAN = 1
SINUSOIDAL = 2
KINDS = {GAUSSIAN: "gaussian", SINUSOIDAL: "sinusoidal"}

#: Known input ``u`` (parameter ``drive``): none (0; or the value a host sets), Gaussian white
#: ``N(0, Qu)``, or the sinusoid ``Xu sin(2 pi fu t)``.
DRIVE_OFF = 0
DRIVES = {DRIVE_OFF: "off", GAUSSIAN: "gaussian", SINUSOIDAL: "sinusoidal"}


def gauss_markov(x_prev, A, Q, w, B=0.0, u=0.0):
    """One step ``x_k = A x_{k-1} + B u_k + sqrt(Q) w`` with ``w`` a standard normal draw;
    ``B = 0`` is ``A x_{k-1} + sqrt(Q) w``, same bits."""
    if (type(B) is float or _ops.is_scalar(B)) and B == 0.0:
        return A * x_prev + _ops.sqrt(Q) * w
    return A * x_prev + B * u + _ops.sqrt(Q) * w


def gaussian_sample(x_prev, A, Q, seed, k, B=0.0, u=0.0):
    """Sample ``k`` of the Gauss-Markov excitation under ``seed`` (process-noise stream)."""
    return gauss_markov(x_prev, A, Q, normal(seed, STREAM_PROCESS, k), B, u)


def input_sample(drive, seed, k, Qu=0.0, Xu=0.0, fu=0.0, Ts=1e-3):
    """Sample ``k`` of the known input ``u``: 0 (``drive = 0``), ``sqrt(Qu)`` times the
    input stream's standard normal draw (1), or ``Xu sin(2 pi fu t_k)`` (2)."""
    if drive == GAUSSIAN:
        return _ops.sqrt(Qu) * normal(seed, STREAM_INPUT, k)
    if drive == SINUSOIDAL:
        return sine(k, Xu, fu, Ts)
    if drive == DRIVE_OFF:
        return 0.0
    raise ValueError("drive = %r is not allowed; allowed: %s"
                     % (drive, ", ".join("%d %s" % kv for kv in DRIVES.items())))


def state_moments(A=0.0, Q=0.0, B=0.0, drive=DRIVE_OFF, Qu=0.0, Xu=0.0, fu=0.0, Ts=1e-3):
    """Stationary ``(E[x^2], E[x^4])`` of ``x_k = A x_{k-1} + B u_k + w_k`` (``|A| < 1``).

    ``x`` is the sum of two independent zero-mean parts, the noise-driven ``x_w`` (Gaussian,
    ``sigma_w^2 = Q / (1 - A^2)``) and the input-driven ``x_u = sum_j A^j B u_{k-j}``:

    * Gaussian ``u``: ``x_u`` Gaussian, ``m2u = B^2 Qu / (1 - A^2)``, ``m4u = 3 m2u^2``;
    * sinusoidal ``u``: ``x_u`` a sinusoid of amplitude ``|B| Xu / |1 - A e^{-j w}|``,
      ``w = 2 pi fu Ts``, so ``m2u = amp^2 / 2``, ``m4u = 3 amp^4 / 8``.

    Then ``E[x^2] = sigma_w^2 + m2u`` and ``E[x^4] = 3 sigma_w^4 + 6 sigma_w^2 m2u + m4u``; odd
    moments vanish.  ``B = 0`` or ``drive = 0`` gives ``(sigma_w^2, 3 sigma_w^4)``.
    """
    import math
    sw2 = Q / (1.0 - A * A)
    if B == 0.0 or drive == DRIVE_OFF:
        m2u, m4u = 0.0, 0.0
    elif drive == GAUSSIAN:
        m2u = B * B * Qu / (1.0 - A * A)
        m4u = 3.0 * m2u * m2u
    elif drive == SINUSOIDAL:
        w = 2.0 * math.pi * fu * Ts
        amp2 = B * B * Xu * Xu / (1.0 - 2.0 * A * math.cos(w) + A * A)
        m2u, m4u = amp2 / 2.0, 3.0 * amp2 * amp2 / 8.0
    else:
        raise ValueError("drive = %r is not allowed; allowed: %s"
                         % (drive, ", ".join("%d %s" % kv for kv in DRIVES.items())))
    return sw2 + m2u, 3.0 * sw2 * sw2 + 6.0 * sw2 * m2u + m4u


def gaussian_pair(x_prev, y_prev, A, Q, Qy, rho, seed, k, B=0.0, u=0.0):
    """Sample ``k`` of the 2-D Gauss-Markov excitation under ``seed``.

    .. math:: x_k = A x_{k-1} + \\sqrt{Q}\\, w_1, \\qquad
              y_k = A y_{k-1} + \\sqrt{Q_y} \\big(\\rho\\, w_1 + \\sqrt{1 - \\rho^2}\\, w_2\\big)

    with ``w_1`` the process-noise stream (so ``x`` is :func:`gaussian_sample`, same bits) and
    ``w_2`` the second-axis stream; the noises have correlation ``rho`` and the stationary
    covariance is ``E[x y] = rho sqrt(Q Qy) / (1 - A^2)``.  ``Qy = 0`` gives ``y = 0``.  The
    known input ``B u_k`` drives ``x`` only (:func:`gauss_markov`).
    """
    w1 = normal(seed, STREAM_PROCESS, k)
    if (type(Qy) is float or _ops.is_scalar(Qy)) and Qy == 0.0:
        return correlated_pair(x_prev, y_prev, A, Q, Qy, rho, w1, 0.0, B, u)
    return correlated_pair(x_prev, y_prev, A, Q, Qy, rho, w1,
                           normal(seed, STREAM_SENSOR_Y, k), B, u)


def correlated_pair(x_prev, y_prev, A, Q, Qy, rho, w1, w2, B=0.0, u=0.0):
    """:func:`gaussian_pair` from its two standard normal draws ``w1`` (process-noise stream)
    and ``w2`` (second-axis stream; not used while ``Qy = 0``), for a caller that draws them
    itself (the Excitation FMU draws them in blocks of samples, the same bits)."""
    x = gauss_markov(x_prev, A, Q, w1, B, u)
    if (type(Qy) is float or _ops.is_scalar(Qy)) and Qy == 0.0:
        return x, 0.0
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
