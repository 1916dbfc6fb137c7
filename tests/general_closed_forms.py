"""The general sensor's closed forms (docs/method.md section 9), written here from the letter's
eqs. 1 and 3-5 with NumPy, independently of models/: what the property tests of
``tests/test_evidence_general_*.py`` compare every reference with.

The state ``x_k = A x_{k-1} + B u_k + w_k`` from ``x_0`` is the sum of a deterministic part
(``A^k x_0``, and for a sinusoidal input the recursion driven by ``B Xu sin(2 pi fu t_k)``) and
a zero-mean Gaussian part (the process noise, and a Gaussian input): at each sample ``x_k`` is
Gaussian with mean ``m_k`` and variance ``v_k``, so every moment is known exactly, at every
sample and in the stationary limit.  The sinusoid's stationary gain is the transfer function
``B / (1 - A e^{-j w})`` evaluated with complex NumPy (models/ writes its squared magnitude out
as ``B^2 / (1 - 2 A cos w + A^2)``).

Also the Hypothesis settings every property test uses: derandomised (the same examples on every
run and machine), no example database, no deadline (a loaded machine's timings say nothing), no
shrinking.
"""
import math

import numpy as np
from hypothesis import HealthCheck, Phase, settings

try:  # see _no_local_constants
    from hypothesis.internal.conjecture import providers as _providers
    from hypothesis.internal.constants_ast import Constants as _Constants
except ImportError:  # another Hypothesis: its draws as they come
    _providers = None


def _no_local_constants():
    """Hypothesis mixes into a few of its draws numbers it finds in the project's modules
    loaded at the time; which are loaded depends on the tests run before in the same process
    (pytest-xdist spreads the modules differently from run to run), so the examples of a
    derandomised test could differ.  Without them every run draws the same examples."""
    if _providers is not None and hasattr(_providers, "_get_local_constants"):
        empty = _Constants()
        _providers._get_local_constants = lambda: empty


_no_local_constants()

#: The settings of every property test (``max_examples`` set per test: enough to find a wrong
#: term, not thousands).  No shrinking: a failure reports the drawn case that failed (each
#: check names its values), and a broken build (the mutation check) fails in seconds instead of
#: the minutes shrinking slow examples takes.
PROPERTY = dict(derandomize=True, database=None, deadline=None, print_blob=False,
                phases=(Phase.explicit, Phase.generate),
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.filter_too_much])


def prop(max_examples):
    """``@settings`` of a property test that draws ``max_examples`` cases."""
    return settings(max_examples=max_examples, **PROPERTY)


OFF, GAUSSIAN, SINUSOIDAL = 0, 1, 2


def sinusoid_gain(A, B, fu, Ts):
    """``|B / (1 - A e^{-j 2 pi fu Ts})|``: the amplitude of the stationary ``x_u`` per unit
    amplitude of the input sinusoid."""
    return float(abs(B / (1.0 - A * np.exp(-2j * np.pi * fu * Ts))))


def stationary_moments(A, Q, B=0.0, drive=OFF, Qu=0.0, Xu=0.0, fu=0.0, Ts=1e-3):
    """``(E[x^2], E[x^4])`` of the stationary state (``|A| < 1``)."""
    sw2 = Q / (1.0 - A * A)
    if B == 0.0 or drive == OFF:
        m2u = m4u = 0.0
    elif drive == GAUSSIAN:
        m2u = B * B * Qu / (1.0 - A * A)
        m4u = 3.0 * m2u * m2u
    else:
        amp = sinusoid_gain(A, B, fu, Ts) * Xu
        m2u, m4u = amp ** 2 / 2.0, 3.0 * amp ** 4 / 8.0
    return sw2 + m2u, 3.0 * sw2 * sw2 + 6.0 * sw2 * m2u + m4u


def expected_drift(a2, a4, A, Q, B=0.0, drive=OFF, Qu=0.0, Xu=0.0, fu=0.0, Ts=1e-3):
    """The stationary drift ``a2 E[x^2] + a4 E[x^4]`` (eqs. 4-5 with ``u``)."""
    m2, m4 = stationary_moments(A, Q, B, drive, Qu, Xu, fu, Ts)
    return a2 * m2 + a4 * m4


def input_samples(drive, n, Xu=0.0, fu=0.0, Ts=1e-3, gaussian=None):
    """``u_k``, ``k = 1..n``: 0, the Gaussian draws given (``gaussian``, already scaled), or
    ``Xu sin(2 pi fu (k - 1) Ts)`` by NumPy's sine."""
    if drive == GAUSSIAN:
        return np.asarray(gaussian, dtype=float)
    if drive == SINUSOIDAL:
        return Xu * np.sin(2.0 * np.pi * fu * Ts * np.arange(n))
    return np.zeros(n)


def state_mean_and_variance(n, A, Q, B=0.0, drive=OFF, Qu=0.0, Xu=0.0, fu=0.0, Ts=1e-3,
                            x0=0.0):
    """``(m_k, v_k)``, ``k = 1..n``: the mean and variance of ``x_k`` from ``x_0 = x0``."""
    k = np.arange(1, n + 1)
    decay = 1.0 - A ** (2 * k)
    v = Q * (k if A * A == 1.0 else decay / (1.0 - A * A))
    if B != 0.0 and drive == GAUSSIAN:
        v = v + B * B * Qu * decay / (1.0 - A * A)
    u = input_samples(drive, n, Xu, fu, Ts) if drive == SINUSOIDAL and B != 0.0 else np.zeros(n)
    m = np.empty(n)
    prev = x0
    for i in range(n):
        prev = A * prev + B * u[i]
        m[i] = prev
    return m, v


def raw_moments(m, v):
    """``E[x^2], E[x^3], E[x^4]`` of ``N(m, v)``."""
    return m * m + v, m ** 3 + 3.0 * m * v, m ** 4 + 6.0 * m * m * v + 3.0 * v * v


def realised_expectation(n, a2, a3, a4, A, Q, B=0.0, drive=OFF, Qu=0.0, Xu=0.0, fu=0.0,
                         Ts=1e-3, x0=0.0):
    """``E[(1/n) sum_k a2 x_k^2 + a3 x_k^3 + a4 x_k^4]`` exactly at ``n`` samples from ``x0``
    (the transient included): what the realised drift at sample ``n`` averages to over runs."""
    m, v = state_mean_and_variance(n, A, Q, B, drive, Qu, Xu, fu, Ts, x0)
    e2, e3, e4 = raw_moments(m, v)
    return float(np.mean(a2 * e2 + a3 * e3 + a4 * e4))


def realised(xs, a2, a3=0.0, a4=0.0):
    """The realised drift at every sample of ``xs`` (``(n,)`` or ``(runs, n)``): the running mean
    of ``a2 x^2 + a3 x^3 + a4 x^4``."""
    xs = np.asarray(xs, dtype=float)
    h = a2 * xs ** 2 + a3 * xs ** 3 + a4 * xs ** 4
    return np.cumsum(h, axis=-1) / np.arange(1, xs.shape[-1] + 1)


def sinusoid_drift(a2, a4, amplitude):
    """``a2 X^2/2 + 3 a4 X^4/8``: the drift of a sinusoid of amplitude ``X`` over whole
    periods (the mean of ``sin^2`` is 1/2, of ``sin^4`` 3/8)."""
    return a2 * amplitude ** 2 / 2.0 + 3.0 * a4 * amplitude ** 4 / 8.0


def band(values, expected, k=4.5):
    """``(|mean - expected|, k standard errors of the mean)`` of the runs' ``values``."""
    values = np.asarray(values, dtype=float)
    se = values.std(ddof=1) / math.sqrt(values.size)
    return abs(values.mean() - expected), k * se


def harmonic_filter(zs, a, R, f, Ts, P0, Qh, x0=0.0):
    """The 2-state harmonic EKF (docs/method.md section 2: rotation by ``2 pi f Ts`` per sample,
    ``Qh I`` per component, Joseph's update) with ``h`` of coefficients ``a = (a0, .., a4)``,
    one measurement per sample, written with 2x2 NumPy matrices; returns the final drift
    estimates ``(dc1, dc2, dc3)`` of the three estimators over ``x+`` and ``P+_11``."""
    C, S = math.cos(2 * math.pi * f * Ts), math.sin(2 * math.pi * f * Ts)
    F = np.array([[C, S], [-S, C]])
    s, P = np.array([x0, 0.0]), np.eye(2) * P0
    a = list(a) + [0.0] * (5 - len(a))
    m = np.zeros(3)      # running means of the posterior moments (EKF1)
    d2 = 0.0             # EKF2
    p = np.zeros(3)      # running means of x+^2, x+^3, x+^4 (EKF3)
    d3 = 0.0
    for k, z in enumerate(zs, start=1):
        s, P = F @ s, F @ P @ F.T + Qh * np.eye(2)
        c = s[0]
        H = np.array([[a[1] + 2 * a[2] * c + 3 * a[3] * c ** 2 + 4 * a[4] * c ** 3, 0.0]])
        K = P @ H.T / (H @ P @ H.T + R)
        s = s + (K * (z - sum(a[i] * c ** i for i in range(5)))).ravel()
        IKH = np.eye(2) - K @ H
        P = IKH @ P @ IKH.T + R * K @ K.T
        x, v = s[0], P[0, 0]
        m += (np.array([x * x + v, x ** 3 + 3 * x * v, x ** 4 + 6 * x * x * v + 3 * v * v]) - m) / k
        d2 += (a[2] * x * x + a[3] * x ** 3 + a[4] * x ** 4 - d2) / k
        p += (np.array([x * x, x ** 3, x ** 4]) - p) / k
        d3 += (a[2] * p[0] + a[3] * p[1] + a[4] * p[2] - d3) / k
    return a[2] * m[0] + a[3] * m[1] + a[4] * m[2], d2, d3
