"""Internal (not a stable API; use driftfmu.allan instead).

The overlapping Allan deviation of a uniformly sampled signal, its confidence, and the IEEE
Std 952 reading of its white-noise, bias-instability and random-walk figures.

**The estimator.**  For ``n`` samples ``y_1..y_n`` at the sample period ``Ts`` and the cluster
size ``m`` (``tau = m Ts``), with the running sum ``S_0 = 0``, ``S_k = y_1 + .. + y_k``:

.. math::

    \\sigma^2(\\tau) = \\frac{1}{2 m^2 (n - 2m + 1)}
        \\sum_{i=0}^{n-2m} \\left(S_{i+2m} - 2 S_{i+m} + S_i\\right)^2

(NIST SP 1065, eq. 11, with the phase ``x_k = Ts S_k``): the mean of every pair of adjacent
clusters of ``m`` samples, each pair differenced, at every start ``i`` (overlapping).  One
pass over the running sum per ``tau``, O(n).  The mean of ``y`` is taken off before the sum
(the estimate does not depend on it) so that the running sum of a signal with a large offset
keeps its digits.  ``n - 2m + 1`` terms: ``m`` may be at most ``n / 2``, two clusters.

**Confidence.**  The estimate is ``sigma^2 chi^2_nu / nu`` with ``nu`` equivalent degrees of
freedom (EDF), which depend on the noise.  :func:`edf` takes the smaller of NIST SP 1065's
approximations (its Table 5, after Howe, Allan and Barnes) for white noise (``tau^-1/2``) and
for random walk (``tau^+1/2``) at ``N = n + 1`` phase points; flicker noise's lies between
them, so the interval is never narrower than the noise of a sensor's curve warrants.  The
68.3 % interval (one sigma) is ``sigma sqrt(nu / chi^2_{0.841}(nu))`` to
``sigma sqrt(nu / chi^2_{0.159}(nu))``, the chi-square quantiles exact (:func:`chi2_quantile`).

**The reading** (IEEE Std 952-1997, Annex C; :func:`read`), on the octave grid ``m = 1, 2, 4,
..`` whatever ``tau`` the table holds, so that the figures depend on the data alone:

- the *local slope* at ``tau_j`` is the log-log slope between its neighbours,
  ``ln(sigma_{j+1} / sigma_{j-1}) / ln(tau_{j+1} / tau_{j-1})``; a ``tau_j`` is *read* only
  when it has both neighbours and the three estimates each have at least :data:`EDF_MIN`
  EDF (a slope then has a standard error of about 0.07);
- **white noise N** (``sigma = N / sqrt(tau)``): the first run of at least
  :data:`MIN_RUN` consecutive read ``tau`` whose local slope is within :data:`SLOPE_TOL` of
  -1/2; the line of slope -1/2 through them (the EDF-weighted mean of
  ``ln sigma + ln(tau) / 2``), read at ``tau = 1 s``;
- **random walk K** (``sigma = K sqrt(tau / 3)``): the last such run with the slope within
  :data:`SLOPE_TOL` of +1/2; the line of slope +1/2, read at ``tau = 3 s``;
- **bias instability B**: the lowest read ``tau``; when its local slope is within
  :data:`SLOPE_TOL` of 0 (a floor), the flat line through the run of such ``tau`` around it,
  divided by ``sqrt(2 ln 2 / pi) = 0.664`` (flicker noise's Allan deviation is ``0.664 B``).
  Without flicker noise the floor of a white and a random-walk line is where they cross;
  its ``B`` is what a datasheet would print all the same.

A figure whose region the data do not show is *not resolved*: ``None`` with the reason, never
a number.  Each figure's 68.3 % interval: the weighted mean of the per-``tau`` standard errors
of ``ln sigma``, ``1 / sqrt(2 nu)`` (an upper bound of the standard error of the fitted line,
however correlated the estimates are).
"""
import math

#: The least equivalent degrees of freedom of an estimate (and of its two neighbours) for its
#: ``tau`` to count in the reading: one-sigma relative error about 7 %, a local slope's
#: standard error about 0.07.
EDF_MIN = 100.0
#: How far a local slope may be from -1/2, 0 or +1/2 for its ``tau`` to belong to that line.
SLOPE_TOL = 0.15
#: Consecutive ``tau`` (an octave apart) a white-noise or random-walk line needs.
MIN_RUN = 2
#: ``tau`` [s] at which the white-noise line is read (IEEE Std 952: N = sigma(1 s)).
N_TAU = 1.0
#: ``tau`` [s] at which the random-walk line is read (IEEE Std 952: K = sigma(3 s)).
K_TAU = 3.0
#: Flicker noise's Allan deviation over its bias instability B: ``sqrt(2 ln 2 / pi)``.
FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: The normal quantile of the one-sigma interval (68.27 %): the bounds are the 15.87 % and
#: 84.13 % points.
Z_SIGMA = 1.0


def octave_m(n):
    """Cluster sizes ``1, 2, 4, ..`` up to ``n / 2`` (two clusters)."""
    m, out = 1, []
    while 2 * m <= n:
        out.append(m)
        m *= 2
    return out


def decade_m(n, per_decade):
    """About ``per_decade`` cluster sizes per decade, ``10^(j / per_decade)`` rounded (the
    repeats of short ``tau`` once), up to ``n / 2``."""
    out, j = [], 0
    while True:
        m = int(round(10.0 ** (j / per_decade)))
        if 2 * m > n:
            return out
        if not out or m != out[-1]:
            out.append(m)
        j += 1


def all_m(n):
    """Every cluster size ``1 .. n / 2``."""
    return list(range(1, n // 2 + 1))


def oadev(y, ms):
    """The overlapping Allan deviation of ``y`` (a 1-D array) at cluster sizes ``ms`` (each
    ``1 <= m <= len(y) / 2``): ``(adev, terms)``, two arrays; ``terms[i] = n - 2 m + 1``, the
    number of differences averaged.  In units of ``y``; ``tau = m Ts``."""
    import numpy as np
    y = np.asarray(y, dtype=float)
    n = y.size
    S = np.empty(n + 1)
    S[0] = 0.0
    np.cumsum(y - y.mean(), out=S[1:])
    adev = np.empty(len(ms))
    terms = np.empty(len(ms), dtype=np.int64)
    for i, m in enumerate(ms):
        m = int(m)
        if not 1 <= 2 * m <= n:
            raise ValueError("m = %d with %d samples; allowed: 1 <= m <= n / 2" % (m, n))
        v = S[2 * m:] - 2.0 * S[m:n + 1 - m] + S[:n + 1 - 2 * m]
        terms[i] = v.size
        adev[i] = math.sqrt(float(np.sum(v * v)) / (2.0 * v.size)) / m
    return adev, terms


def edf_white(N, m):
    """EDF of the overlapping Allan variance for white noise (``alpha = 0``), ``N`` phase
    points (NIST SP 1065, Table 5)."""
    return (3.0 * (N - 1) / (2.0 * m) - 2.0 * (N - 2) / N) * (4.0 * m * m / (4.0 * m * m + 5.0))


def edf_random_walk(N, m):
    """EDF of the overlapping Allan variance for random walk (``alpha = -2``), ``N`` phase
    points (NIST SP 1065, Table 5); ``N > 3``."""
    return (N - 2.0) / (m * (N - 3.0) ** 2) * ((N - 1.0) ** 2 - 3.0 * m * (N - 1.0)
                                               + 4.0 * m * m)


def edf(n, m):
    """The EDF of the estimate at cluster size ``m`` of ``n`` samples: the smaller of the
    white-noise and the random-walk ones (``N = n + 1`` phase points), at least 1 (one
    difference, two clusters, is one chi-square degree of freedom)."""
    N = n + 1.0
    nu = edf_white(N, m)
    if N > 3:
        nu = min(nu, edf_random_walk(N, m))
    return max(1.0, nu)


def gamma_p(a, x):
    """The regularized lower incomplete gamma function ``P(a, x)`` (``a > 0``, ``x >= 0``): its
    series for ``x < a + 1``, else one minus its continued fraction (modified Lentz), each to
    about 1e-15.  ValueError where the continued fraction has not converged in 9999 terms
    (from ``a`` about 1.3e9, near ``x = a``) instead of an unconverged value."""
    if x <= 0.0:
        return 0.0
    front = math.exp(a * math.log(x) - x - math.lgamma(a))
    if x < a + 1.0:
        term = total = 1.0 / a
        k = a
        while abs(term) > 1e-17 * abs(total):
            k += 1.0
            term *= x / k
            total += term
        return front * total
    tiny = 1e-300
    b = x + 1.0 - a
    c, d = 1.0 / tiny, 1.0 / b
    h = d
    for i in range(1, 10000):
        an = -i * (i - a)
        b += 2.0
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1.0 / d
        step = d * c
        h *= step
        if abs(step - 1.0) < 1e-16:
            break
    else:
        if h == h:  # (NaN arguments give NaN, as every step does)
            raise ValueError("P(a, x) at a = %r, x = %r: the continued fraction has not "
                             "converged in 9999 terms (near x = a it needs more the larger a "
                             "is); allowed: a up to about 1e9" % (a, x))
    return 1.0 - front * h


def chi2_quantile(p, nu):
    """The ``p`` quantile (``0 < p < 1``) of the chi-square distribution with ``nu > 0``
    degrees of freedom: the ``q`` with ``P(nu / 2, q / 2) = p``.  Newton's method on
    ``ln q`` from Wilson and Hilferty's approximation ``nu (1 - 2/(9 nu) + z_p sqrt(2/(9
    nu)))^3``, kept inside a bracket that bisection narrows when a step would leave it."""
    from statistics import NormalDist
    a = nu / 2.0
    c = 2.0 / (9.0 * nu)
    guess = nu * max(1.0 - c + NormalDist().inv_cdf(p) * math.sqrt(c), 1e-3) ** 3
    lo, hi = -745.0, max(math.log(guess), 0.0) + 1.0
    while gamma_p(a, math.exp(hi) / 2.0) < p:
        lo, hi = hi, hi + 2.0
    u = min(max(math.log(guess), lo), hi)
    for _ in range(200):
        q = math.exp(u)
        f = gamma_p(a, q / 2.0) - p
        if f < 0.0:
            lo = u
        else:
            hi = u
        # dP/du = q pdf(q) = (q/2)^a e^(-q/2) / Gamma(a)
        slope = math.exp(a * math.log(q / 2.0) - q / 2.0 - math.lgamma(a))
        step = f / slope if slope > 0.0 else math.inf
        new = u - step
        if not lo < new < hi:
            new = 0.5 * (lo + hi)
        if abs(new - u) < 1e-12 or hi - lo < 1e-12:
            return math.exp(new)
        u = new
    return math.exp(u)


def interval(adev, nu, z=Z_SIGMA):
    """``(low, high)``: the two-sided interval of an Allan deviation ``adev`` estimated with
    ``nu`` EDF, ``z`` sigmas wide (the normal probability between -z and z)."""
    from statistics import NormalDist
    p = NormalDist().cdf(z)
    return (adev * math.sqrt(nu / chi2_quantile(p, nu)),
            adev * math.sqrt(nu / chi2_quantile(1.0 - p, nu)))


def local_slopes(taus, adevs):
    """The log-log slope at each ``tau`` between its neighbours (None at either end, and
    where a neighbour is 0: a constant signal)."""
    out = [None] * len(taus)
    for j in range(1, len(taus) - 1):
        if adevs[j + 1] > 0 and adevs[j - 1] > 0:
            out[j] = (math.log(adevs[j + 1] / adevs[j - 1])
                      / math.log(taus[j + 1] / taus[j - 1]))
    return out


def _runs(flags):
    """The runs of consecutive True in ``flags``: a list of (first, last) indices."""
    runs, start = [], None
    for j, f in enumerate(list(flags) + [False]):
        if f and start is None:
            start = j
        elif not f and start is not None:
            runs.append((start, j - 1))
            start = None
    return runs


def _line(taus, adevs, nus, first, last, slope):
    """The line of fixed ``slope`` through points ``first..last`` (the EDF-weighted mean of
    ``ln sigma - slope ln tau``): ``(ln sigma at tau = 1 s, standard-error bound)``."""
    w = nus[first:last + 1]
    total = sum(w)
    level = sum(wj * (math.log(a) - slope * math.log(t)) for wj, a, t in
                zip(w, adevs[first:last + 1], taus[first:last + 1])) / total
    se = sum(wj / math.sqrt(2.0 * wj) for wj in w) / total
    return level, se


def _figure(value, se, region, points, read_at=None, floor=None):
    out = {"value": value, "low": value * math.exp(-se), "high": value * math.exp(se),
           "se_log": se, "tau_from": region[0], "tau_to": region[1], "points": points,
           "reason": None}
    if read_at is not None:
        out["read_at"] = read_at
    if floor is not None:
        out["floor"] = floor
    return out


def _unresolved(reason):
    return {"value": None, "reason": reason}


def least_samples():
    """The fewest samples with a ``tau`` to read: ``m = 2`` with its neighbours ``m = 1, 4``
    each at :data:`EDF_MIN` or more."""
    n = 8
    while min(edf(n, m) for m in (1, 2, 4)) < EDF_MIN:
        n += 1
    return n


def read(y, Ts):
    """The IEEE Std 952 reading of ``y`` sampled at ``Ts`` (the module's rules): a dict with
    ``"N"`` [unit sqrt(s)], ``"B"`` [unit] and ``"K"`` [unit / sqrt(s)], each either
    ``{"value", "low", "high", "se_log", "tau_from", "tau_to", "points", "read_at"
    (N, K) or "floor" (B), "reason": None}`` or ``{"value": None, "reason": why}``; and
    ``"grid"``: the octave grid's ``tau``, ``adev``, ``edf``, ``slope`` and ``read`` (the
    points that count)."""
    n = len(y)
    ms = octave_m(n)
    adevs, _ = oadev(y, ms)
    adevs = [float(a) for a in adevs]
    taus = [m * Ts for m in ms]
    nus = [edf(n, m) for m in ms]
    slopes = local_slopes(taus, adevs)
    ok = [0 < j < len(ms) - 1 and min(nus[j - 1:j + 2]) >= EDF_MIN
          and min(adevs[j - 1:j + 2]) > 0 for j in range(len(ms))]
    grid = {"tau": taus, "adev": adevs, "edf": nus, "slope": slopes, "read": ok}
    result = {"grid": grid}
    if not any(ok):
        why = ("no tau with both neighbours and each of the three with at least %g EDF "
               "(%d samples: at least %d needed)" % (EDF_MIN, n, least_samples()))
        for name in ("N", "B", "K"):
            result[name] = _unresolved(why)
        return result

    def near(target):
        return [ok[j] and abs(slopes[j] - target) <= SLOPE_TOL for j in range(len(ms))]

    for name, target, pick, read_at in (("N", -0.5, 0, N_TAU), ("K", 0.5, -1, K_TAU)):
        runs = [r for r in _runs(near(target)) if r[1] - r[0] + 1 >= MIN_RUN]
        if not runs:
            result[name] = _unresolved(
                "no %d consecutive tau with a local slope within %g of %+g (and at least %g "
                "EDF)" % (MIN_RUN, SLOPE_TOL, target, EDF_MIN))
            continue
        first, last = runs[pick]
        level, se = _line(taus, adevs, nus, first, last, target)
        # the line's value at tau = read_at: N / sqrt(1 s) = N, K sqrt(3 s / 3) = K
        value = math.exp(level + target * math.log(read_at))
        result[name] = _figure(value, se, (taus[first], taus[last]), last - first + 1,
                               read_at=read_at)

    lowest = min((j for j in range(len(ms)) if ok[j]), key=lambda j: adevs[j])
    flat = near(0.0)
    if not flat[lowest]:
        result["B"] = _unresolved(
            "no floor: the lowest read tau (%g s) has a local slope of %+.2f, not within %g "
            "of 0" % (taus[lowest], slopes[lowest], SLOPE_TOL))
    else:
        first, last = next(r for r in _runs(flat) if r[0] <= lowest <= r[1])
        level, se = _line(taus, adevs, nus, first, last, 0.0)
        result["B"] = _figure(math.exp(level) / FLOOR, se, (taus[first], taus[last]),
                              last - first + 1, floor=math.exp(level))
    return result
