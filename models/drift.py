"""The letter's three EKF drift estimators (eqs. 7-12) and the drift references.

For ``k = 1, 2, ...`` and the a-posteriori estimate ``(x+_k, P+_k)``:

.. math::

    \\text{EKF1:}\\quad s^{(1)}_k = \\tfrac1k \\sum_{i \\le k} (x^{+2}_i + P^+_i), \\qquad dc^{(1)}_k = a_2 s^{(1)}_k

    \\text{EKF2:}\\quad dc^{(2)}_k = \\frac{(k-1)\\, dc^{(2)}_{k-1} + a_2 x^{+2}_k}{k}

    \\text{EKF3:}\\quad s^{(3)}_k = \\frac{(k-1) s^{(3)}_{k-1} + x^{+2}_k}{k}, \\qquad
                       dc^{(3)}_k = \\frac{(k-1)\\, dc^{(3)}_{k-1} + a_2 s^{(3)}_k}{k}

EKF1 uses the posterior second moment ``x+^2 + P+`` (``E[x^2] = E[x+^2] + P``), which makes it
unbiased; EKF2 is low by ``a2 P``.  The letter's equations are garbled in its text; this reading,
and the EKF1-EKF2 gap ``10 log10(1 + R / (a1^2 Q))`` that decides it, are in ``docs/method.md``
(section 3).

References: empirical ``z̄_k - a0``; realised ``a2 (1/k) sum x_i^2`` (simulation only);
expected ``a2 sigma_x^2``.
"""
from collections import namedtuple

#: Running state of the three estimators after ``k`` samples (``k = 0``: nothing seen yet).
DriftState = namedtuple("DriftState", "k s1 dc2 s3 dc3")


def initial_state():
    """Estimator state before the first sample."""
    return DriftState(0, 0.0, 0.0, 0.0, 0.0)


def running_mean(mean_prev, value, k):
    """``((k - 1) mean_prev + value) / k``: the letter's running-mean recursion."""
    return ((k - 1) * mean_prev + value) / k


def update(state, x_post, P_post, a2):
    """Fold the ``k``-th posterior ``(x+, P+)`` into the three estimators."""
    k = state.k + 1
    x2 = x_post * x_post
    s1 = running_mean(state.s1, x2 + P_post, k)
    dc2 = running_mean(state.dc2, a2 * x2, k)
    s3 = running_mean(state.s3, x2, k)
    dc3 = running_mean(state.dc3, a2 * s3, k)
    return DriftState(k, s1, dc2, s3, dc3)


def estimates(state, a2):
    """``(dc1, dc2, dc3)`` of a state."""
    return a2 * state.s1, state.dc2, state.dc3


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


def references(xs, zs, a0, a2, dc_expected):
    """Running drift references over samples ``k = 1..n`` of ``x_k`` and ``z_k``.

    Returns three lists, one value per sample: the empirical drift ``z̄_k - a0``, the realised
    drift ``a2 (1/k) sum x_i^2`` and the expected drift (constant ``dc_expected``).  Elements of
    ``xs`` and ``zs`` are floats (one run) or arrays (a batch of runs).
    """
    empirical, realised, expected = [], [], []
    zbar = 0.0
    x2bar = 0.0
    for k, (x, z) in enumerate(zip(xs, zs), start=1):
        zbar = running_mean(zbar, z, k)
        x2bar = running_mean(x2bar, x * x, k)
        empirical.append(zbar - a0)
        realised.append(a2 * x2bar)
        expected.append(dc_expected)
    return empirical, realised, expected
