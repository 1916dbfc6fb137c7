"""Scalar extended Kalman filter for the sensor model, in procedural form.

.. math::

    x^-_k = A x^+_{k-1}, \\qquad P^-_k = A^2 P^+_{k-1} + Q

    H = a_1 + 2 a_2 x^-_k, \\quad S = H^2 P^- + R, \\quad K = P^- H / S

    x^+_k = x^-_k + K (z_k - h(x^-_k)), \\qquad P^+_k = (1 - K H)^2 P^-_k + K^2 R

The covariance update is Joseph's form, which keeps ``P`` positive.  Every function works on
floats (one FMU) and on arrays (a batch of runs) alike.
"""
from .sensor import dh_dx, h


def predict(x, P, A, Q):
    """Time update: ``(A x, A^2 P + Q)``."""
    return A * x, A * A * P + Q


def update(x_pred, P_pred, z, a0, a1, a2, R):
    """Measurement update of ``(x^-, P^-)`` with ``z``, linearised at ``x^-``; Joseph form."""
    H = dh_dx(x_pred, a1, a2)
    S = H * H * P_pred + R
    K = P_pred * H / S
    x = x_pred + K * (z - h(x_pred, a0, a1, a2))
    return x, joseph(P_pred, K, H, R)


def joseph(P_pred, K, H, R):
    """Error variance after an update with gain ``K``, ``(1 - K H)^2 P^- + K^2 R`` (Joseph).

    Valid for any gain; the simple form ``(1 - K H) P^-`` holds only at the optimal gain
    ``K = P^- H / (H^2 P^- + R)``, and there it loses accuracy (and positivity) when
    ``R << H^2 P^-``.
    """
    one_minus_KH = 1.0 - K * H
    return one_minus_KH * one_minus_KH * P_pred + K * K * R


def step(x, P, z, a0, a1, a2, A, Q, R):
    """Predict from the previous posterior ``(x, P)``, then update with ``z``."""
    x_pred, P_pred = predict(x, P, A, Q)
    return update(x_pred, P_pred, z, a0, a1, a2, R)
