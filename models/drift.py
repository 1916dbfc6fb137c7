"""Internal (not a stable API; use driftfmu.simulate instead).

The letter's three EKF drift estimators (eqs. 7-12), for the sensor up to 4th order, and the
drift references.

The drift of ``h(x) = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4`` is
``E[h(x)] - a0 - a1 E[x] = a2 E[x^2] + a3 E[x^3] + a4 E[x^4]``.  For ``k = 1, 2, ...`` and the
a-posteriori estimate ``(x+_k, P+_k)``:

.. math::

    \\text{EKF1:}\\quad dc^{(1)}_k = a_2 s^{(1)}_k + a_3 t^{(1)}_k + a_4 q^{(1)}_k, \\qquad
        s^{(1)}_k = \\tfrac1k \\sum_{i \\le k} (x^{+2}_i + P^+_i), \\quad
        t^{(1)}_k = \\tfrac1k \\sum_{i \\le k} (x^{+3}_i + 3 x^+_i P^+_i), \\quad
        q^{(1)}_k = \\tfrac1k \\sum_{i \\le k} (x^{+4}_i + 6 x^{+2}_i P^+_i + 3 P^{+2}_i)

    \\text{EKF2:}\\quad dc^{(2)}_k = \\frac{(k-1)\\, dc^{(2)}_{k-1}
        + a_2 x^{+2}_k + a_3 x^{+3}_k + a_4 x^{+4}_k}{k}

    \\text{EKF3:}\\quad s^{(3)}_k, t^{(3)}_k, q^{(3)}_k = \\text{running means of }
        x^{+2}, x^{+3}, x^{+4}, \\qquad
        dc^{(3)}_k = \\frac{(k-1)\\, dc^{(3)}_{k-1} + a_2 s^{(3)}_k + a_3 t^{(3)}_k
        + a_4 q^{(3)}_k}{k}

EKF1 uses the moments of the Gaussian posterior ``N(x+, P+)`` (:func:`posterior_moments`:
``E[x^2] = x+^2 + P``, ``E[x^3] = x+^3 + 3 x+ P``, ``E[x^4] = x+^4 + 6 x+^2 P + 3 P^2``), which
makes it unbiased; EKF2 plugs ``x+`` into the polynomial (low by ``a2 P`` at 2nd order); EKF3
smooths EKF2's moments once more.  With ``a3 = a4 = 0`` these are the letter's estimators, same
bits (the higher moments are not even computed; their sums stay 0).  The letter's equations are
garbled in its text; this reading, and the EKF1-EKF2 gap ``10 log10(1 + R / (a1^2 Q))`` that
decides it, are in ``docs/method.md`` (section 3; the higher orders in section 9).

References: empirical ``z̄_k - a0``; realised ``a2 (1/k) sum x_i^2`` (simulation only);
expected ``a2 sigma_x^2`` (``+ 3 a4 sigma_x^4`` at 4th order).
"""
from collections import namedtuple

from .sensor import higher

#: Running state of the three estimators after ``k`` samples (``k = 0``: nothing seen yet):
#: EKF1's posterior moments ``s1, t1, q1`` (2nd, 3rd, 4th), EKF2's drift ``dc2``, EKF3's
#: smoothed moments ``s3, t3, q3`` and drift ``dc3``.  The 3rd/4th-order sums come last and
#: default to 0, so the letter's quadratic state ``(k, s1, dc2, s3, dc3)`` is a DriftState too.
DriftState = namedtuple("DriftState", "k s1 dc2 s3 dc3 t1 q1 t3 q3",
                        defaults=(0.0, 0.0, 0.0, 0.0))
#: Fields of the letter's quadratic estimators (the JSON form of a state without higher sums).
QUADRATIC_FIELDS = 5


def initial_state():
    """Estimator state before the first sample."""
    return DriftState(0, 0.0, 0.0, 0.0, 0.0)


def running_mean(mean_prev, value, k):
    """``((k - 1) mean_prev + value) / k``: the letter's running-mean recursion."""
    return ((k - 1) * mean_prev + value) / k


def posterior_moments(x, P):
    """Raw moments ``(E[x^2], E[x^3], E[x^4])`` of the Gaussian ``N(x, P)``:
    ``(x^2 + P, x^3 + 3 x P, x^4 + 6 x^2 P + 3 P^2)``."""
    x2 = x * x
    return x2 + P, x2 * x + 3.0 * x * P, x2 * x2 + 6.0 * x2 * P + 3.0 * P * P


def update(state, x_post, P_post, a2, a3=0.0, a4=0.0):
    """Fold the ``k``-th posterior ``(x+, P+)`` into the three estimators."""
    k = state.k + 1
    x2 = x_post * x_post
    s1 = running_mean(state.s1, x2 + P_post, k)
    if not higher(a3, a4):
        dc2 = running_mean(state.dc2, a2 * x2, k)
        s3 = running_mean(state.s3, x2, k)
        dc3 = running_mean(state.dc3, a2 * s3, k)
        return DriftState(k, s1, dc2, s3, dc3, state.t1, state.q1, state.t3, state.q3)
    _, m3, m4 = posterior_moments(x_post, P_post)
    x3, x4 = x2 * x_post, x2 * x2
    t1 = running_mean(state.t1, m3, k)
    q1 = running_mean(state.q1, m4, k)
    dc2 = running_mean(state.dc2, a2 * x2 + a3 * x3 + a4 * x4, k)
    s3 = running_mean(state.s3, x2, k)
    t3 = running_mean(state.t3, x3, k)
    q3 = running_mean(state.q3, x4, k)
    dc3 = running_mean(state.dc3, a2 * s3 + a3 * t3 + a4 * q3, k)
    return DriftState(k, s1, dc2, s3, dc3, t1, q1, t3, q3)


def estimates(state, a2, a3=0.0, a4=0.0):
    """``(dc1, dc2, dc3)`` of a state."""
    if not higher(a3, a4):
        return a2 * state.s1, state.dc2, state.dc3
    return a2 * state.s1 + a3 * state.t1 + a4 * state.q1, state.dc2, state.dc3


def plain(state):
    """JSON form of a state: the letter's five numbers ``[k, s1, dc2, s3, dc3]`` while the
    3rd/4th-order sums are all 0 (as every state of a quadratic sensor), all nine otherwise."""
    if state.t1 == 0.0 and state.q1 == 0.0 and state.t3 == 0.0 and state.q3 == 0.0:
        return list(state[:QUADRATIC_FIELDS])
    return list(state)


def select(dcs, estimator):
    """The drift estimate of ``estimator`` (1, 2 or 3) out of ``(dc1, dc2, dc3)``."""
    if estimator not in (1, 2, 3):
        raise ValueError("estimator must be 1, 2 or 3, got %r" % (estimator,))
    return dcs[estimator - 1]


def gap_db(dc1, dc2):
    """Gap between EKF1 and EKF2 in dB, ``10 log10(dc1 / dc2)``."""
    import math
    return 10.0 * math.log10(dc1 / dc2)


def expected_gap_db(a1, Q, R):
    """Stationary EKF1-EKF2 gap for a white state (``A = 0``): ``10 log10(1 + R / (a1^2 Q))``."""
    import math
    return 10.0 * math.log10(1.0 + R / (a1 * a1 * Q))


def references(xs, zs, a0, a2, dc_expected, a3=0.0, a4=0.0):
    """Running drift references over samples ``k = 1..n`` of ``x_k`` and ``z_k``.

    Returns three lists, one value per sample: the empirical drift ``z̄_k - a0``, the realised
    drift ``(1/k) sum (a2 x_i^2 + a3 x_i^3 + a4 x_i^4)`` and the expected drift (constant
    ``dc_expected``).  Elements of ``xs`` and ``zs`` are floats (one run) or arrays (a batch of
    runs).  ``a3 = a4 = 0``: the realised drift is ``a2 (1/k) sum x_i^2``, same bits.
    """
    empirical, realised, expected = [], [], []
    quadratic = not higher(a3, a4)
    zbar = 0.0
    x2bar = 0.0
    hbar = 0.0
    for k, (x, z) in enumerate(zip(xs, zs), start=1):
        zbar = running_mean(zbar, z, k)
        empirical.append(zbar - a0)
        if quadratic:
            x2bar = running_mean(x2bar, x * x, k)
            realised.append(a2 * x2bar)
        else:
            x2 = x * x
            hbar = running_mean(hbar, a2 * x2 + a3 * x2 * x + a4 * x2 * x2, k)
            realised.append(hbar)
        expected.append(dc_expected)
    return empirical, realised, expected
