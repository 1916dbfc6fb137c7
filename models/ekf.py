"""Internal (not a stable API; use driftfmu.simulate instead).

Scalar extended Kalman filter for the sensor model, in procedural form.

.. math::

    x^-_k = A x^+_{k-1} + B u_k, \\qquad P^-_k = A^2 P^+_{k-1} + Q

    H = h'(x^-_k) = a_1 + 2 a_2 x^-_k + 3 a_3 (x^-_k)^2 + 4 a_4 (x^-_k)^3, \\quad
    S = H^2 P^- + R, \\quad K = P^- H / S

    x^+_k = x^-_k + K (z_k - h(x^-_k)), \\qquad P^+_k = (1 - K H)^2 P^-_k + K^2 R

The covariance update is Joseph's form, which keeps ``P`` positive.  Every function works on
floats (one FMU) and on arrays (a batch of runs) alike.  The known input ``u_k`` (eq. 1) is
exact, so it moves the prediction and leaves ``P`` alone; ``B = 0`` (the letter's case) and
``a3 = a4 = 0`` compute exactly what the letter's filter computes (same bits).
"""
from . import _ops
from .sensor import dh_dx, h


def predict(x, P, A, Q, B=0.0, u=0.0):
    """Time update: ``(A x + B u, A^2 P + Q)``."""
    if (type(B) is float or _ops.is_scalar(B)) and B == 0.0:
        return A * x, A * A * P + Q
    return A * x + B * u, A * A * P + Q


def update(x_pred, P_pred, z, a0, a1, a2, R, a3=0.0, a4=0.0):
    """Measurement update of ``(x^-, P^-)`` with ``z``, linearised at ``x^-``; Joseph form."""
    H = dh_dx(x_pred, a1, a2, a3, a4)
    S = H * H * P_pred + R
    K = P_pred * H / S
    x = x_pred + K * (z - h(x_pred, a0, a1, a2, a3, a4))
    return x, joseph(P_pred, K, H, R)


def joseph(P_pred, K, H, R):
    """Error variance after an update with gain ``K``, ``(1 - K H)^2 P^- + K^2 R`` (Joseph).

    Valid for any gain; the simple form ``(1 - K H) P^-`` holds only at the optimal gain
    ``K = P^- H / (H^2 P^- + R)``, and there it loses accuracy (and positivity) when
    ``R << H^2 P^-``.
    """
    one_minus_KH = 1.0 - K * H
    return one_minus_KH * one_minus_KH * P_pred + K * K * R


def step(x, P, z, a0, a1, a2, A, Q, R, a3=0.0, a4=0.0, B=0.0, u=0.0):
    """Predict from the previous posterior ``(x, P)`` (with the known input ``u_k``), then
    update with ``z``."""
    x_pred, P_pred = predict(x, P, A, Q, B, u)
    return update(x_pred, P_pred, z, a0, a1, a2, R, a3, a4)
