"""Internal (not a stable API; use driftfmu.simulate instead).

The DriftEstimator's bias state: an EKF over ``[x, b]`` that tracks a slow bias ``b`` (the
letter's classes 3 and 4: drift that is not a function of the state's statistics) beside the
state ``x``, whose second moment makes the state-dependent drift (class 1).

.. math::

    x_k = A x_{k-1} + B u_k + w_k, \\qquad b_k = F_b\\, b_{k-1} + w_{b,k}, \\qquad
    w_{b,k} \\sim N(0, Q_b), \\qquad z_k = h(x_k) + b_k + v_k

with ``F_b = exp(-Ts / tau_b)`` (a first-order Gauss-Markov bias) or ``F_b = 1`` for
``tau_b = 0`` (a random walk; a constant bias with ``Qb = 0``).

Predict (the ``x`` part is :func:`driftfmu.models.ekf.predict`)::

    x- = A x + B u,   P- = A^2 P + Q,   b- = F_b b,   Pxb- = A F_b Pxb,   Pbb- = F_b^2 Pbb + Qb

Update with the Jacobian row ``(H, 1)``, ``H = h'(x-)``, the innovation and the measurement
variance of the Gaussian prior ``x ~ N(x-, P-)``::

    e  = z - E[h(x)] - b-,   E[h(x)] = a0 + a1 x- + a2 (x-^2 + P-) + a3 (x-^3 + 3 x- P-)
                                      + a4 (x-^4 + 6 x-^2 P- + 3 P-^2)
    R' = R + 2 a2^2 P-^2                  (the variance of a2 (x - x-)^2)

and Joseph's form ``P+ = (I - K H) P- (I - K H)^T + K R' K^T`` (the 2-state scalar update
:func:`driftfmu.models.dualaxis._row2` with ``G = 1``).  Why ``E[h(x)]`` and not the letter's
``h(x-)``: a first-order EKF expects ``h(x-)``, so the mean ``a2 P-`` of the quadratic term (for
a white state, ``A = 0``, the whole drift ``a2 Q``) is left in the innovation, and the bias state
would absorb the state-dependent drift that EKF1-3 report as well: counted twice.  With the
expectation the filter attributes ``a2 (x-^2 + P-)`` to the state and only what its model does
not explain to ``b`` (docs/method.md, section 11).  For a quadratic ``h`` the update is then
the exact Gaussian moment update (the covariances of ``x, b`` with ``z`` and the variance of
``z`` under the prior); the cubic and quartic terms enter through ``E[h]`` and ``H`` (their
extra variance is not added).  With ``a2 = a3 = a4 = 0`` it is the linear Kalman filter of
``[x, b]``.

Every function works on floats (one FMU) and on arrays (a batch of runs) with the same bits;
fmu_src/native/models/bias.c is the C port.
"""
from collections import namedtuple

from . import _ops, chain, covariance, drift, ekf
from .dualaxis import _row2
from .sensor import dh_dx, higher

#: The bias part of the filter: estimate ``b`` [V], its cross-covariance with ``x`` ``Pxb``
#: [g V] and its variance ``Pbb`` [V^2].
Bias = namedtuple("Bias", "b Pxb Pbb")
#: Names of the filter's covariance ``[[P, Pxb], [Pxb, Pbb]]`` as the FMU's outputs are called,
#: in the shape :func:`covariance_of` gives them.
COVARIANCE_NAMES = (("P",), ("P_xb", "P_bb"))


def factor(tau_b, Ts):
    """``F_b``: ``exp(-Ts / tau_b)`` (arithmetic only) for ``tau_b > 0``, 1 for ``tau_b = 0`` (a
    random walk)."""
    if _ops.is_scalar(tau_b):
        return 1.0 if tau_b == 0.0 else _ops.exp(-Ts / tau_b)
    np = _ops._np()
    zero = np.asarray(tau_b) == 0.0
    return np.where(zero, 1.0, _ops.exp(-Ts / np.where(zero, 1.0, tau_b)))


def init(b0, Pb0):
    """The bias part before sample 1: ``b0``, ``Pb0`` and no cross-covariance (independent
    priors)."""
    return Bias(b0, 0.0 * Pb0, Pb0)


def expected(x, P, a0, a1, a2, a3=0.0, a4=0.0):
    """``E[h(x)]`` for ``x ~ N(x, P)``: ``a0 + a1 x + a2 (x^2 + P)`` (``+ a3 (x^3 + 3 x P) +
    a4 (x^4 + 6 x^2 P + 3 P^2)`` with the higher terms)."""
    if not higher(a3, a4):
        return a0 + a1 * x + a2 * (x * x + P)
    m2, m3, m4 = drift.posterior_moments(x, P)
    return a0 + a1 * x + a2 * m2 + a3 * m3 + a4 * m4


def spread(R, a2, P):
    """The measurement variance the update uses, ``R + 2 a2^2 P^2``: the noise and the variance
    of the quadratic term ``a2 (x - x-)^2`` under the prior ``N(x-, P)``."""
    return R + 2.0 * a2 * a2 * P * P


def predict(x, P, bias, A, Q, Fb, Qb, B=0.0, u=0.0):
    """Time update: ``(x-, P-, Bias(F_b b, A F_b Pxb, F_b^2 Pbb + Qb))``."""
    x_pred, P_pred = ekf.predict(x, P, A, Q, B, u)
    return x_pred, P_pred, Bias(Fb * bias.b, A * Fb * bias.Pxb, Fb * Fb * bias.Pbb + Qb)


def update(x_pred, P_pred, bias, z, a0, a1, a2, R, a3=0.0, a4=0.0):
    """Measurement update with ``z`` (row ``(h'(x-), 1)``, innovation ``z - E[h(x)] - b-``,
    variance :func:`spread`); Joseph form.  Returns ``(x+, P+, Bias)``."""
    H = dh_dx(x_pred, a1, a2, a3, a4)
    e = z - expected(x_pred, P_pred, a0, a1, a2, a3, a4) - bias.b
    x, b, P, Pxb, Pbb = _row2(x_pred, bias.b, P_pred, bias.Pxb, bias.Pbb, H, 1.0, e,
                              spread(R, a2, P_pred))
    return x, P, Bias(b, Pxb, Pbb)


def estimator_step(state, bias, z, a0, a1, a2, A, Q, R, Fb, Qb, a3=0.0, a4=0.0, B=0.0, u=0.0):
    """One predict/update of ``[x, b]`` with ``z`` and the three drift estimators folded forward
    with ``x+`` and ``P+`` (as :func:`driftfmu.models.chain.estimator_step`).  ``state`` is a
    :class:`driftfmu.models.chain.EstimatorState`; returns ``(state, bias)``."""
    x, P, bias = update(*predict(state.x, state.P, bias, A, Q, Fb, Qb, B, u), z, a0, a1, a2, R,
                        a3, a4)
    return chain.EstimatorState(x, P, drift.update(state.drift, x, P, a2, a3, a4)), bias


def estimator_predict(state, bias, A, Q, Fb, Qb, B=0.0, u=0.0):
    """Time update only (a sample without a measurement); the drift state is kept."""
    x, P, bias = predict(state.x, state.P, bias, A, Q, Fb, Qb, B, u)
    return chain.EstimatorState(x, P, state.drift), bias


def compensate(z, dc, b):
    """The compensated output ``z - dc - b``."""
    return chain.compensate(z, dc) - b


def covariance_of(state, bias):
    """The rows of the lower triangle of the covariance of ``[x, b]``, ``((P,), (Pxb, Pbb))``."""
    return (state.P,), (bias.Pxb, bias.Pbb)


def check(state, bias, k, seeds=None):
    """Raise :class:`driftfmu.models.covariance.CovarianceError` unless the covariance after
    sample ``k`` is valid (a batch: the first run that is not, and its ``seeds`` entry)."""
    covariance.check(COVARIANCE_NAMES, covariance_of(state, bias), k, "the bias filter", seeds)


# -- guidance ----------------------------------------------------------------------------------

def qb_random_walk(K, Ts):
    """``Qb = K^2 Ts``: the variance per sample of a bias random walk ``K`` [V/sqrt(s)]
    sampled every ``Ts`` [s] (its variance grows by ``K^2 t`` in ``t`` seconds)."""
    return K * K * Ts


def qb_gauss_markov(sigma, tau_b, Ts):
    """``Qb = sigma^2 (1 - exp(-2 Ts / tau_b))``: the variance per sample that keeps a
    Gauss-Markov bias of correlation time ``tau_b`` at the stationary standard deviation
    ``sigma`` [V]."""
    F = factor(tau_b, Ts)
    return sigma * sigma * (1.0 - F * F)


def steady_variance(Qb, r):
    """The bias's steady-state posterior variance of a random walk (``F_b = 1``) seen through a
    noise of variance ``r`` (for a white state, ``A = 0``: ``r = a1^2 Q + R``): the prior
    ``p = (Qb + sqrt(Qb^2 + 4 Qb r)) / 2`` solves ``p = p r / (p + r) + Qb``, and the
    posterior is ``p r / (p + r)``, about ``sqrt(Qb r)`` for ``Qb << r``."""
    p = (Qb + _ops.sqrt(Qb * Qb + 4.0 * Qb * r)) / 2.0
    return p * r / (p + r)
