"""Internal (not a stable API; use driftfmu.simulate instead).

Harmonic process model: a 2-state EKF for a sinusoidal state at a known frequency.

The letter's filter models the state as Gauss-Markov, ``x_k = A x_{k-1} + w_k``.  A sinusoid
``x = X sin(2 pi f t + phi)`` is modelled exactly by an undamped oscillator: with the in-phase
component ``c_k = X sin(theta_k)`` and the quadrature ``d_k = X cos(theta_k)``,
``theta_k = 2 pi f t_k + phi``,

.. math::

    \\begin{pmatrix} c_k \\\\ d_k \\end{pmatrix} =
    \\underbrace{\\begin{pmatrix} C & S \\\\ -S & C \\end{pmatrix}}_{F}
    \\begin{pmatrix} c_{k-1} \\\\ d_{k-1} \\end{pmatrix} + w_k,
    \\qquad C = \\cos(2 \\pi f T_s),\\; S = \\sin(2 \\pi f T_s),\\; w_k \\sim N(0, Q_h I)

with the letter's scalar measurement of the first component,
``z_k = a0 + a1 c_k + a2 c_k^2 + v_k``, ``v_k ~ N(0, R)``, so ``H = (a1 + 2 a2 c^-, 0)``.

Predict ``P^- = F P F^T + Q_h I``; update with ``K = P^- H^T / (H P^- H^T + R)`` and Joseph's form
``P^+ = (I - K H) P^- (I - K H)^T + K R K^T``.  The 2x2 algebra is written out with scalars
(``P`` is the triple ``P11, P12, P22``), so every function runs on floats (one FMU) and on arrays
(a batch of runs) with the same bits.  ``C`` and ``S`` come from the arithmetic-only
:func:`driftfmu.models._ops.sin2pi`.

EKF1's drift uses the posterior second moment of the measured component, ``x+^2 + P+_11``
(:func:`driftfmu.models.drift.update` with ``P = P11``); with this model on a pure sinusoid it converges
to ``a2 X^2 / 2``.

Joseph's form keeps ``P`` positive semi-definite only while the numbers stay within double
precision: a huge prior (``P0 = 1e16``) or estimate (``x0 = 3e8``) can make it lose that; a
state whose covariance is not valid (:mod:`driftfmu.models.covariance`) is refused by the FMU,
and :func:`check` stops a batch run there.
"""
from collections import namedtuple

from . import _ops, chain, covariance, drift, ekf
from .sensor import dh_dx, h

GAUSS_MARKOV = 1
HARMONIC = 2
PROCESSES = {GAUSS_MARKOV: "Gauss-Markov", HARMONIC: "harmonic"}

#: Posterior of the harmonic filter: components ``x`` (= c) and ``d``, covariance ``P`` (= P11),
#: ``P12``, ``P22``, and the drift estimators' state.
HarmonicState = namedtuple("HarmonicState", "x d P P12 P22 drift")


def rotation(f, Ts):
    """``(C, S) = (cos 2 pi f Ts, sin 2 pi f Ts)`` by arithmetic only."""
    return _ops.sin2pi(f * Ts + 0.25), _ops.sin2pi(f * Ts)


def predict(x, d, P11, P12, P22, C, S, Qh):
    """Time update ``(F s, F P F^T + Qh I)`` of the state ``s = (x, d)``."""
    xp = C * x + S * d
    dp = C * d - S * x
    CC, SS, CS = C * C, S * S, C * S
    p11 = CC * P11 + 2.0 * CS * P12 + SS * P22 + Qh
    p12 = CS * (P22 - P11) + (CC - SS) * P12
    p22 = SS * P11 - 2.0 * CS * P12 + CC * P22 + Qh
    return xp, dp, p11, p12, p22


def update(x, d, P11, P12, P22, z, a0, a1, a2, R, a3=0.0, a4=0.0):
    """Measurement update with ``z``, linearised at the predicted ``x``; Joseph form."""
    H = dh_dx(x, a1, a2, a3, a4)
    Sv = H * H * P11 + R
    K1 = P11 * H / Sv
    K2 = P12 * H / Sv
    e = z - h(x, a0, a1, a2, a3, a4)
    m11 = 1.0 - K1 * H
    m21 = -K2 * H
    p11 = m11 * m11 * P11 + K1 * K1 * R
    p12 = m11 * (m21 * P11 + P12) + K1 * K2 * R
    p22 = m21 * m21 * P11 + 2.0 * m21 * P12 + P22 + K2 * K2 * R
    return x + K1 * e, d + K2 * e, p11, p12, p22


def step(x, d, P11, P12, P22, z, a0, a1, a2, C, S, Qh, R, a3=0.0, a4=0.0):
    """Predict from the previous posterior, then update with ``z``."""
    return update(*predict(x, d, P11, P12, P22, C, S, Qh), z, a0, a1, a2, R, a3, a4)


# -- the estimator (EKF + drift estimators) for either process model -----------------------------

def estimator_init(process, x0, P0):
    """Filter state before the first sample: ``x0`` (quadrature 0), variances ``P0``."""
    if process == GAUSS_MARKOV:
        return chain.estimator_init(x0, P0)
    if process == HARMONIC:
        return HarmonicState(x0, 0.0 * x0, P0, 0.0 * P0, P0, drift.initial_state())
    raise ValueError("process = %r is not allowed; allowed: %s"
                     % (process, ", ".join("%d %s" % kv for kv in PROCESSES.items())))


def estimator_step(state, z, a0, a1, a2, R, process=GAUSS_MARKOV, A=0.0, Q=0.0, C=1.0, S=0.0,
                   Qh=0.0, a3=0.0, a4=0.0, B=0.0, u=0.0):
    """One EKF predict/update with ``z`` (Gauss-Markov ``A, Q`` with the known input ``B u``, or
    harmonic ``C, S, Qh``) and the three drift estimators folded forward with ``x+`` and
    ``P+_11``."""
    if process == GAUSS_MARKOV:
        return chain.estimator_step(state, z, a0, a1, a2, A, Q, R, a3, a4, B, u)
    x, d, p11, p12, p22 = step(state.x, state.d, state.P, state.P12, state.P22, z, a0, a1, a2,
                               C, S, Qh, R, a3, a4)
    return HarmonicState(x, d, p11, p12, p22, drift.update(state.drift, x, p11, a2, a3, a4))


def estimator_predict(state, process=GAUSS_MARKOV, A=0.0, Q=0.0, C=1.0, S=0.0, Qh=0.0, B=0.0,
                      u=0.0):
    """Time update only (a sample without a measurement); the drift state is kept."""
    if process == GAUSS_MARKOV:
        x, P = ekf.predict(state.x, state.P, A, Q, B, u)
        return chain.EstimatorState(x, P, state.drift)
    x, d, p11, p12, p22 = predict(state.x, state.d, state.P, state.P12, state.P22, C, S, Qh)
    return HarmonicState(x, d, p11, p12, p22, state.drift)


def from_plain(values):
    """Estimator state from its JSON form (nested lists), either process model."""
    *head, d = values
    state_type = chain.EstimatorState if len(values) == 3 else HarmonicState
    return state_type(*head, drift.DriftState(*d))


#: Names of the harmonic filter's covariance entries (the fields of :class:`HarmonicState`),
#: in the shape :func:`covariance_of` gives them.
COVARIANCE_NAMES = (("P",), ("P12", "P22"))


def covariance_of(state):
    """The rows of the lower triangle of the harmonic filter's covariance, ``((P,), (P12,
    P22))``; None for the Gauss-Markov state, whose scalar ``P`` stays ``>= 0`` by construction
    (:mod:`driftfmu.models.covariance`)."""
    if type(state) is HarmonicState:
        return (state.P,), (state.P12, state.P22)
    return None


def valid(state):
    """Whether the state's covariance is valid (:func:`driftfmu.models.covariance.valid2`;
    always for the Gauss-Markov state); a boolean array for a batch of runs."""
    if type(state) is not HarmonicState:
        return True
    return covariance.valid2(state.P, state.P12, state.P22)


def check(state, k, seeds=None):
    """Raise :class:`driftfmu.models.covariance.CovarianceError` unless the covariance of the
    state after sample ``k`` is valid (a batch: every run; the message names the first run that
    is not, and its ``seeds`` entry)."""
    lower = covariance_of(state)
    if lower is not None:
        covariance.check(COVARIANCE_NAMES, lower, k, "the harmonic filter", seeds)


def run(zs, a0, a1, a2, R, x0=0.0, P0=1.0, process=HARMONIC, f=150.0, Ts=1e-3, A=0.0, Q=0.0,
        Qh=1e-8, a3=0.0, a4=0.0):
    """Run the estimator over recorded outputs ``zs`` (one measurement per sample, floats or
    arrays of runs); return the final state.  The same steps as the DriftEstimator FMU, which
    refuses a sample whose covariance is not valid: here :func:`check` raises there."""
    C, S = rotation(f, Ts)
    model = dict(process=process, A=A, Q=Q, C=C, S=S, Qh=Qh)
    state = estimator_init(process, x0, P0)
    for k, z in enumerate(zs, start=1):
        state = estimator_step(state, z, a0, a1, a2, R, a3=a3, a4=a4, **model)
        check(state, k)
    return state
