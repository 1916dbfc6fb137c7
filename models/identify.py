"""Internal (not a stable API; use driftfmu.identify instead).

Identification of the filter's 2nd-order model ``a0, a1, a2, R`` from sets with a known drive.

Method: harmonic analysis (linear least squares on the harmonics of the drive), not a least-squares
fit of ``z`` on ``x`` sample by sample.  For each set of samples ``(t_k, x_k, z_k)`` over a whole
number of periods of the drive frequency ``f``:

1. the drive: ``x_k ~ X sin(theta_k)``, ``theta_k = 2 pi f t_k + phi``, by least squares on
   ``(sin, cos)(2 pi f t_k)`` -- amplitude ``X`` and phase ``phi``;
2. the output: ``z_k ~ c_0 + sum_{j=1,2} (alpha_j sin(j theta_k) + beta_j cos(j theta_k))`` by
   least squares (over whole periods the regressors are orthogonal, so this is the DFT at the
   harmonics);
3. for ``z = a0 + a1 x + a2 x^2`` with ``x = X sin(theta)``,
   ``z = a0 + a2 X^2/2 + a1 X sin(theta) - (a2 X^2/2) cos(2 theta)``; a delay between drive
   and output (the part's output filter, the mount) rotates harmonic ``j`` by ``j phi_1``, where
   ``phi_1 = atan2(-beta_1, alpha_1)`` is the measured lag of the fundamental.  So

   .. math::

       a_1 = \\sqrt{\\alpha_1^2 + \\beta_1^2} / X, \\qquad
       a_2 = -\\frac{2}{X^2} (\\beta_2 \\cos 2\\phi_1 + \\alpha_2 \\sin 2\\phi_1), \\qquad
       a_0 = c_0 - a_2 X^2 / 2

   (``a1`` taken positive: the lag is below 90 degrees);
4. ``R`` = variance of the residual of that 2nd-order fit (``N - 5`` degrees of freedom): what the
   2nd-order model leaves unexplained, noise and quantisation plus higher harmonics (a cubic
   term's), is what the filter must treat as measurement noise.

Why: (a) a delay ``phi_1`` between drive and output puts ``a1 X sin(phi_1)`` in quadrature with
the drive; a sample-by-sample fit of ``z`` on ``x`` reads it as noise, inflating ``R`` by
``(a1 X sin phi_1)^2 / 2`` (for the ADXL203 stand-in at 200 Hz behind its 1064 Hz filter that is
over 1000 times the true noise variance) and biasing ``a1`` by ``cos phi_1``; per-harmonic
amplitudes and phases are immune.  (b) With one drive amplitude, ``a0`` and ``a2 X^2/2`` both
sit in the mean of ``z``; the second harmonic separates them.  (c) The errors are known in closed
form: for white noise of variance ``s^2`` over ``N`` samples in whole periods,
``var(c_0) = s^2/N`` and ``var(alpha_j) = var(beta_j) = 2 s^2/N``, hence
``sd(a1) = sqrt(2/N) s / X``, ``sd(a2) = 2 sqrt(2/N) s / X^2``, ``sd(a0) = sqrt(3/N) s``,
``sd(R) = sqrt(2/N) s^2`` (see :func:`standard_errors`), which the tests use as tolerances.

**Orders 3 and 4** (``order``, the letter's general sensor ``h(x) = a0 + ... + a4 x^4``).  With
``x = X sin(theta)``: ``sin^3 = (3 sin - sin 3theta)/4`` and ``sin^4 = (3 - 4 cos 2theta +
cos 4theta)/8``, so a 3rd-order term feeds the 1st and 3rd harmonics and a 4th-order term the
DC, 2nd and 4th.  With ``A_j, B_j`` the sine and cosine coefficients of harmonic ``j`` rotated
back by ``j phi_1``:

.. math::

    a_4 = 8 B_4 / X^4, \\qquad a_3 = -4 A_3 / X^3, \\qquad
    a_2 = -(2 B_2 + a_4 X^4) / X^2, \\qquad a_1 = (A_1 - 3 a_3 X^3 / 4) / X, \\qquad
    a_0 = c_0 - a_2 X^2 / 2 - 3 a_4 X^4 / 8

Five harmonic coefficients for five unknowns: one drive amplitude resolves every order up to 4,
provided the harmonics are distinct frequencies below the Nyquist rate, ``order * f < 1 / (2
Ts)`` (else harmonic ``order`` aliases onto a lower one or the DC, and the fit refuses the order
naming the highest order the data resolve).  The standard errors are those of the linear map
from the least-squares coefficients (covariance ``R (B^T B)^{-1}``) to ``a0..a_order``, exact
for white noise given ``X`` and ``phi_1``; over whole periods they are the closed forms of
:func:`standard_errors`.  ``order = 2`` computes exactly what the 2nd-order fit computed.

Sets are fitted one by one and the fits averaged (the letter's "one averaged 2nd-order model").
Runs on NumPy (it is analysis, not an FMU's step).

What the data must support (checked by :func:`fit_set`): at least :data:`MIN_PERIODS` whole
periods of the drive (else :class:`IdentificationError`; fewer than :data:`FEW_PERIODS` is an
:class:`IdentificationWarning`), and a drive that is a sinusoid at the given ``f``: the share of
the variance of ``x`` that ``X sin(2 pi f t + phi)`` explains, ``(X^2 / 2) / var(x)``, must be at
least :data:`MIN_EXPLAINED` (else an error naming the recording's strongest frequency; below
:data:`GOOD_EXPLAINED` a warning).  A wrong ``f`` makes the phase of the fitted sinusoid drift
against the recording, so this share collapses long before ``a2`` and ``R`` look absurd.
"""
import math
import warnings
from collections import namedtuple


Fit = namedtuple("Fit", "a0 a1 a2 R X phi lag samples periods explained a3 a4 order se",
                 defaults=(0.0, 0.0, 2, None))

#: Orders of the characteristic a fit can identify.
ORDERS = (2, 3, 4)

#: Fewest whole periods of the drive a fit accepts; below FEW_PERIODS it warns.
MIN_PERIODS = 2
FEW_PERIODS = 10
#: Share of var(x) the sinusoid at ``f`` must explain (error below MIN_EXPLAINED, warning below
#: GOOD_EXPLAINED): a reference accelerometer's noise of 1 % of the drive amplitude costs 2e-4.
MIN_EXPLAINED = 0.9
GOOD_EXPLAINED = 0.999


class IdentificationError(ValueError):
    """The data cannot support the fit (too few periods, a drive not at the given frequency)."""


class IdentificationWarning(UserWarning):
    """The fit ran but is doubtful; the message gives the diagnostic figure."""


def dominant_frequency(x, Ts):
    """The strongest frequency [Hz] in ``x`` (Hann-windowed periodogram peak, refined by a
    parabola through the log magnitudes of the three bins around it)."""
    import numpy as np
    x = np.asarray(x, dtype=float)
    x = x - x.mean()
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    spec[0] = 0.0
    k = int(np.argmax(spec))
    shift = 0.0
    if 0 < k < len(spec) - 1 and np.all(spec[k - 1:k + 2] > 0):
        a, b, c = np.log(spec[k - 1:k + 2])
        den = a - 2 * b + c
        shift = 0.5 * (a - c) / den if den else 0.0
    return (k + shift) / (len(x) * Ts)

#: Columns a recording must have.
CSV_COLUMNS = ("time", "x", "z")


def whole_periods(n, f, Ts, rtol=1e-9):
    """Largest ``m <= n`` such that ``m`` samples span a whole number of periods of ``f``
    (``m f Ts`` an integer to ``rtol``); when no such ``m`` exists (an irrational ratio), the
    samples in ``floor(n f Ts)`` periods, rounded.  At least 1."""
    periods_per_sample = f * Ts
    for m in range(n, 0, -1):
        p = m * periods_per_sample
        if p >= 1.0 and abs(p - round(p)) <= rtol * max(1.0, p):
            return m
        if n - m > 1000 and p < math.floor(n * periods_per_sample):
            break
    whole = math.floor(n * periods_per_sample)
    return max(1, min(n, int(round(whole / periods_per_sample)))) if whole else n


def _basis(theta, harmonics):
    """The columns ``1, sin(j theta), cos(j theta)`` for ``j = 1 .. harmonics``, as a list."""
    import numpy as np
    cols = [np.ones_like(theta)]
    for j in range(1, harmonics + 1):
        cols += [np.sin(j * theta), np.cos(j * theta)]
    return cols


def _least_squares(columns, y):
    """``(c, G)``: the least-squares coefficients ``c`` of ``y`` on ``columns`` (arrays of one
    length) and ``G``, the inverse of their Gram matrix ``B^T B`` (``B`` the matrix of the
    columns), as lists.

    Householder QR in elementwise NumPy operations and sums (NumPy's pairwise summation), the
    small triangular systems in Python floats: no BLAS or LAPACK call, so the same bits on every
    processor.  (OpenBLAS picks its kernels by processor: with LAPACK's ``lstsq`` the ADXL203
    experiment's margins differed in their last bits between an AVX2 and an AVX-512 machine.)
    """
    import numpy as np
    n = len(columns)
    a = [np.array(col, dtype=float) for col in columns]  # reduced in place
    b = np.array(y, dtype=float)
    r = [[0.0] * n for _ in range(n)]
    for j in range(n):
        v = a[j][j:].copy()
        norm = math.sqrt(float(np.sum(v * v)))
        if not norm > 0.0:
            raise IdentificationError("the fit's basis is degenerate (column %d of %d is a "
                                      "combination of the others); allowed: a recording of "
                                      "whole periods of a sinusoidal drive" % (j + 1, n))
        alpha = -norm if v[0] >= 0.0 else norm
        v[0] -= alpha
        vv = float(np.sum(v * v))
        r[j][j] = alpha
        for k in range(j + 1, n):
            col = a[k][j:]
            col -= v * (2.0 * float(np.sum(v * col)) / vv)
            r[j][k] = float(col[0])
        rest = b[j:]
        rest -= v * (2.0 * float(np.sum(v * rest)) / vv)
    qb = [float(b[j]) for j in range(n)]
    coef = [0.0] * n
    for i in reversed(range(n)):  # R c = Q^T y
        acc = qb[i]
        for k in range(i + 1, n):
            acc -= r[i][k] * coef[k]
        coef[i] = acc / r[i][i]
    inv = [[0.0] * n for _ in range(n)]  # R^-1, upper triangular
    for i in range(n):
        inv[i][i] = 1.0 / r[i][i]
        for k in range(i + 1, n):
            acc = 0.0
            for l in range(i, k):
                acc -= inv[i][l] * r[l][k]
            inv[i][k] = acc / r[k][k]
    gram_inv = [[0.0] * n for _ in range(n)]  # (B^T B)^-1 = R^-1 R^-T
    for i in range(n):
        for k in range(n):
            acc = 0.0
            for l in range(max(i, k), n):
                acc += inv[i][l] * inv[k][l]
            gram_inv[i][k] = acc
    return coef, gram_inv


def _dot(u, v):
    """``sum(u[i] * v[i])`` added left to right (Python floats, or arrays element by element):
    the fixed order of a BLAS-free product."""
    acc = 0.0
    for a, b in zip(u, v):
        acc = acc + a * b
    return acc


def resolvable_order(f, Ts):
    """Highest order (at most 4) whose harmonics ``j f``, ``j <= order``, lie below the Nyquist
    rate ``1 / (2 Ts)``; 0 when not even the fundamental does."""
    top = 0
    for j in range(1, max(ORDERS) + 1):
        if j * f * Ts < 0.5 - 1e-12:
            top = j
    return top


def check_order(order, f, Ts):
    """Raise :class:`IdentificationError` unless ``order`` is one of :data:`ORDERS` and its
    harmonics are resolvable at ``f`` and ``Ts``."""
    if order not in ORDERS:
        raise IdentificationError("order = %r; allowed: %s" % (order, ", ".join(map(str, ORDERS))))
    top = resolvable_order(f, Ts)
    if order > 2 and order > top:  # (order 2 is checked as it always was: not here)
        raise IdentificationError(
            "order %d needs harmonic %d of f = %g Hz, %g Hz, below the Nyquist rate 1/(2 Ts) = "
            "%g Hz, or it aliases and cannot be told apart; allowed: order <= %d at this f and "
            "Ts (or f < %g Hz for order %d)"
            % (order, order, f, order * f, 0.5 / Ts, top, 0.5 / (order * Ts), order))


def fit_set(t, x, z, f, skip=0, order=2):
    """Harmonic analysis of one set: a :class:`Fit` of ``z = a0 + a1 x + ... + a_order x^order
    + v`` (``order`` 2, 3 or 4).

    ``t, x, z`` are sequences of equal length (``x`` the known drive, ``z`` the output), ``f``
    the drive frequency [Hz].  The first ``skip`` samples are left out (a start transient, e.g.
    of a simulated output filter; 0 for a recording of a part already running); of the rest,
    only the samples in a whole number of periods are used.
    """
    import numpy as np
    t, x, z = (np.asarray(a, dtype=float)[skip:] for a in (t, x, z))
    if len(t) < 2:
        raise IdentificationError("%d sample(s) after the first %d; allowed: at least %d whole "
                                  "periods of the drive" % (len(t), skip, MIN_PERIODS))
    Ts = (t[-1] - t[0]) / (len(t) - 1)
    periods = math.floor(len(t) * f * Ts + 1e-9)
    if periods < MIN_PERIODS:
        raise IdentificationError(
            "%d samples at Ts = %.6g s span %.3g periods of f = %g Hz; allowed: at least %d "
            "whole periods (%d samples)" % (len(t), Ts, len(t) * f * Ts, f, MIN_PERIODS,
                                            math.ceil(MIN_PERIODS / (f * Ts))))
    check_order(order, f, Ts)
    m = whole_periods(len(t), f, Ts)
    t, x, z = t[:m], x[:m], z[:m]
    w = 2.0 * math.pi * f * (t - t[0])
    (s, c), _ = _least_squares([np.sin(w), np.cos(w)], x)
    X = math.hypot(s, c)
    if not X > 0.0:
        raise IdentificationError("the drive x has no component at f = %r Hz; allowed: a "
                                  "sinusoidal drive at the given frequency" % (f,))
    var_x = float(np.var(x))
    explained = min(1.0, X * X / 2.0 / var_x) if var_x > 0 else 1.0
    text = ("a sinusoid at f = %g Hz explains %.1f %% of the variance of the drive x (the "
            "recording's strongest frequency is %.4g Hz)"
            % (f, 100 * explained, dominant_frequency(x, Ts))) if explained < GOOD_EXPLAINED \
        else None
    if explained < MIN_EXPLAINED:
        raise IdentificationError("%s; allowed: at least %g %%: give the drive frequency of "
                                  "the recording" % (text, 100 * MIN_EXPLAINED))
    if m * f * Ts < FEW_PERIODS - 1e-9:
        warnings.warn("only %d whole periods of f = %g Hz: the closed-form standard errors "
                      "hold for many periods; the fit is rough"
                      % (round(m * f * Ts), f), IdentificationWarning, stacklevel=3)
    phi = math.atan2(c, s)
    B = _basis(w + phi, order)
    coef, gram_inv = _least_squares(B, z)
    c0, al1, be1, al2, be2 = coef[:5]
    lag = math.atan2(-be1, al1)
    resid = z - _dot(B, coef)  # z - B c, column by column
    R = float(np.sum(resid * resid)) / max(1, m - len(B))
    a3 = a4 = 0.0
    if order == 2:  # the 2nd-order fit, written as it always was (same bits)
        a1 = math.hypot(al1, be1) / X
        a2 = -2.0 / (X * X) * (be2 * math.cos(2 * lag) + al2 * math.sin(2 * lag))
        a0 = c0 - a2 * X * X / 2.0
    M = [[float(v) for v in row] for row in _coefficient_map(order, X, lag)]
    a = [_dot(row, coef) for row in M]
    if order > 2:
        a0, a1, a2, a3 = (float(v) for v in a[:4])
        if order == 4:
            a4 = float(a[4])
    # standard errors: the diagonal of R M (B^T B)^-1 M^T
    var = [R * _dot(row, [_dot(g, row) for g in gram_inv]) for row in M]
    se = {"a%d" % i: float(math.sqrt(max(var[i], 0.0))) for i in range(order + 1)}
    if text is not None:
        # the part of x the sinusoid misses reaches z through a1 and is counted as noise
        leak = a1 * a1 * (1.0 - explained) * var_x / R if R > 0 else math.inf
        warnings.warn("%s: the fit is doubtful (a wrong f, a distorted or noisy drive); if that "
                      "part of x is motion, it makes up to %.0f %% of the fitted R"
                      % (text, 100 * min(1.0, leak)), IdentificationWarning, stacklevel=3)
    return Fit(float(a0), float(a1), float(a2), R, X, phi, lag, m,
               int(round(m * f * Ts)), explained, a3, a4, order, se)


def _coefficient_map(order, X, lag):
    """The matrix ``M`` with ``(a0, .., a_order) = M c`` for the least-squares coefficients
    ``c = (c0, alpha_1, beta_1, .., alpha_order, beta_order)`` (see the module docstring)."""
    import numpy as np
    n = 1 + 2 * order
    # rotated coefficients: A_j = alpha_j cos(j lag) - beta_j sin(j lag),
    #                       B_j = alpha_j sin(j lag) + beta_j cos(j lag)
    Arow, Brow = {}, {}
    for j in range(1, order + 1):
        ra, rb = np.zeros(n), np.zeros(n)
        cj, sj = math.cos(j * lag), math.sin(j * lag)
        ra[2 * j - 1], ra[2 * j] = cj, -sj
        rb[2 * j - 1], rb[2 * j] = sj, cj
        Arow[j], Brow[j] = ra, rb
    c0 = np.zeros(n)
    c0[0] = 1.0
    a4 = 8.0 * Brow[4] / X ** 4 if order >= 4 else np.zeros(n)
    a3 = -4.0 * Arow[3] / X ** 3 if order >= 3 else np.zeros(n)
    a2 = -(2.0 * Brow[2] + a4 * X ** 4) / X ** 2
    a1 = (Arow[1] - 0.75 * a3 * X ** 3) / X
    a0 = c0 - a2 * X ** 2 / 2.0 - 0.375 * a4 * X ** 4
    return np.array([a0, a1, a2, a3, a4][:order + 1])


def average(fits):
    """The averaged model ``{a0, a1, a2, R}`` of a list of :class:`Fit` (plain means), with the
    spread (sample standard deviation) of each and the number of sets.  With one set there is
    no spread: the ``sd_*`` are None."""
    import numpy as np
    if not fits:
        raise IdentificationError("no sets to average; allowed: one or more fits")
    out = {"sets": len(fits)}
    order = max(getattr(fi, "order", 2) for fi in fits)
    names = ("a0", "a1", "a2", "R") + (("a3",) if order >= 3 else ()) + \
        (("a4",) if order >= 4 else ())
    if order > 2:
        out["order"] = order
    for name in names:
        v = np.array([getattr(fi, name) for fi in fits])
        out[name] = float(v.mean())
        out["sd_" + name] = float(v.std(ddof=1)) if len(v) > 1 else None
    return out


def standard_errors(sigma, X, n, order=2):
    """Standard errors of one set's fit for white noise ``sigma`` over ``n`` samples in whole
    periods (``var(c0) = s^2/n``, ``var(A_j) = var(B_j) = 2 s^2/n``, through the formulas of
    the module docstring: e.g. at order 4 ``a0 = c0 + B2 + B4`` and ``a1 = (A1 + 3 A3) / X``)."""
    if order == 2:
        return {"a0": math.sqrt(3.0 / n) * sigma, "a1": math.sqrt(2.0 / n) * sigma / X,
                "a2": 2.0 * math.sqrt(2.0 / n) * sigma / (X * X),
                "R": math.sqrt(2.0 / n) * sigma * sigma}
    out = {"a0": math.sqrt((3.0 if order == 3 else 5.0) / n) * sigma,
           "a1": math.sqrt(20.0 / n) * sigma / X,
           "a2": (2.0 * math.sqrt(2.0 / n) if order == 3 else math.sqrt(136.0 / n)) * sigma / X ** 2,
           "a3": 4.0 * math.sqrt(2.0 / n) * sigma / X ** 3,
           "R": standard_errors(sigma, X, n)["R"]}
    if order == 4:
        out["a4"] = 8.0 * math.sqrt(2.0 / n) * sigma / X ** 4
    return out


def read_csv(path, columns=CSV_COLUMNS, min_rows=3):
    """A recording with a header row (extra columns ignored) as one float array per name of
    ``columns`` (default ``time, x, z``; the first is the time).

    Raises ValueError naming the file and the problem: missing columns, a value that is not a
    finite number (row and column), fewer than ``min_rows`` rows, or time not strictly
    increasing.
    """
    import csv

    import numpy as np
    path = str(path)
    columns = tuple(columns)
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise ValueError("%s: cannot be read (%s)" % (path, exc.strerror or exc)) from None
    except (UnicodeDecodeError, csv.Error) as exc:  # a binary file, NUL bytes
        raise ValueError("%s: not a text CSV file (%s); allowed: a UTF-8 text file with a "
                         "header row with columns %s, then numbers"
                         % (path, str(exc).splitlines()[0], ", ".join(columns))) from None
    if not rows:
        raise ValueError("%s: empty file; allowed: a header row with columns %s, then numbers"
                         % (path, ", ".join(columns)))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in columns if c not in header]
    if missing:
        # the first row as read, each cell quoted: a JSON file's "{" or a row that another
        # separator joins ("time;x;z") shows as what it is
        raise ValueError("%s: missing column(s) %s: its first row, the header, holds %s; "
                         "allowed: a header row with columns %s, separated by commas"
                         % (path, ", ".join(missing), ", ".join(repr(h) for h in header)
                            if any(header) else "nothing", ", ".join(columns)))
    idx = [header.index(c) for c in columns]
    data = []
    for r, row in enumerate(rows[1:], start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        values = []
        for name, i in zip(columns, idx):
            cell = row[i].strip() if i < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise ValueError("%s: line %d, column %s: %r is not a finite number; allowed: "
                                 "finite numbers only" % (path, r, name, cell))
            values.append(v)
        data.append(values)
    if len(data) < min_rows:
        raise ValueError("%s: %d data row(s); allowed: at least %d" % (path, len(data),
                                                                       min_rows))
    arr = np.array(data)
    if not np.all(np.diff(arr[:, 0]) > 0):
        raise ValueError("%s: %s is not strictly increasing; allowed: uniformly sampled, "
                         "increasing time" % (path, columns[0]))
    return tuple(arr[:, i] for i in range(len(columns)))


def sample_period(t, rtol=1e-6):
    """The sample period of uniformly sampled times ``t``; ValueError when not uniform."""
    import numpy as np
    d = np.diff(np.asarray(t, dtype=float))
    Ts = float(d.mean())
    if np.max(np.abs(d - Ts)) > rtol * Ts + 1e-12:
        raise ValueError("time is not uniformly sampled (steps from %g to %g s); allowed: "
                         "uniform sampling" % (d.min(), d.max()))
    return Ts
