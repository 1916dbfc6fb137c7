"""Internal (not a stable API; use driftfmu.simulate instead).

When a filter's covariance is valid: every variance ``>= 0``, the matrix positive
semi-definite within rounding.

A Kalman filter's covariance is positive semi-definite (PSD) in exact arithmetic: Joseph's form
``(I - K H) P (I - K H)^T + K R K^T`` and the prediction ``F P F^T + Q`` keep it so.  In double
precision they keep it so only while the numbers stay within what 53 bits can carry: with a
prior ``P0 = 1e154`` and an estimate of ``3e8`` (or a prior ``P0 = 1e16`` alone) the terms of an
update are many orders of magnitude above the result, their rounding errors exceed it, and the
harmonic filter's 2x2 covariance leaves the PSD cone (a "variance" of -3.7e137 or -0.5).  Such
a result means nothing, so the FMUs refuse the sample, as they refuse one that overflows, and
the batch engines stop with :class:`CovarianceError`.

The rule, one for every covariance a filter carries (the harmonic filter's ``P11, P12, P22``,
the dual-axis filters' 2x2 and 4x4), for a symmetric ``n x n`` matrix ``P``:

1. every variance ``P_ii >= 0`` (exactly; NaN fails);
2. a row of zero variance has zero covariances: ``P_ij = 0`` where ``P_ii P_jj = 0``;
3. the correlation matrix with its diagonal raised by :data:`SLACK`, ``c_ii = 1 + SLACK`` and
   ``c_ij = P_ij / s_j / s_i`` (``j < i``, ``s_i = sqrt(P_ii)``; 0 where ``s_i s_j = 0``), has
   positive pivots ``d_j > 0`` in its ``L D L^T`` factorisation (``d_j = c_jj - sum_k
   u_jk (u_jk / d_k)``, ``u_ij = c_ij - sum_k u_ik (u_jk / d_k)``, ``k < j``, in that order).

That is ``P + SLACK diag(P)`` positive definite on the rows of nonzero variance: for a 2x2,
``|P12| < (1 + SLACK) sqrt(P11) sqrt(P22)`` up to the rounding of the test.  ``SLACK = 2^-20``
is far above the rounding errors of a filter that works and far below what a filter that has
lost its precision shows (``tests/test_covariance.py``): the experiments' settings keep the
least eigenvalue of every correlation matrix above 0.4; a singular covariance (the dual filter
with ``rho = 1``, whose two process noises are one) keeps it within 1e-11 of 0 over 100,000
samples; a filter past double precision shows -0.5 and below.

The scalar filter's ``P`` (models/ekf.py) needs no test: Joseph's ``(1 - K H)^2 P + K^2 R`` and
``A^2 P + Q`` are sums of products of numbers ``>= 0``, so from ``P0 >= 0`` it stays ``>= 0``
(or turns non-finite, which the overflow checks catch).

Every function works on floats (one FMU) and on arrays (a batch of runs) with the same result:
``+ - * /``, ``sqrt`` and comparisons only, in one order; fmu_src/native/models/covariance.c is
the C port.
"""
import math

from . import _ops

#: The slack of rule 3: the correlation matrix's diagonal is ``1 + SLACK``.
SLACK = 2.0 ** -20
BOUND = 1.0 + SLACK
#: What a refusal says is the cause.
CAUSE = "the inputs and parameters exceed what double precision can carry"
#: What a refusal says is allowed.
ALLOWED = "values whose covariances stay positive semi-definite"


class CovarianceError(ValueError):
    """A batch run whose covariance left the PSD cone (the message names the run, the sample,
    the covariance and its values)."""


def _np():
    import numpy
    return numpy


def valid2(P11, P12, P22):
    """Whether ``[[P11, P12], [P12, P22]]`` is a valid covariance (the module's rule); a boolean
    array for arrays.  The same answer as :func:`valid` of ``((P11,), (P12, P22))``."""
    if type(P11) is float and type(P12) is float and type(P22) is float:
        if not (P11 >= 0.0 and P22 >= 0.0):
            return False
        s1 = math.sqrt(P11)
        s2 = math.sqrt(P22)
        if s2 * s1 == 0.0:
            return P12 == 0.0
        c = P12 / s1 / s2
        return BOUND - c * (c / BOUND) > 0.0
    return valid(((P11,), (P12, P22)))


def valid(lower):
    """Whether the symmetric matrix whose rows ``lower[i] = (P_i0, ..., P_ii)`` are given (its
    lower triangle; floats or arrays) is a valid covariance by the module's rule; a boolean
    array for arrays."""
    if len(lower) == 4:  # the dual-axis harmonic filter's, checked at every sample of an FMU
        (p11,), (p21, p22), (p31, p32, p33), (p41, p42, p43, p44) = lower
        if type(p11) is float and type(p21) is float and type(p22) is float and \
                type(p31) is float and type(p32) is float and type(p33) is float and \
                type(p41) is float and type(p42) is float and type(p43) is float and \
                type(p44) is float:
            return _valid4_floats(p11, p21, p22, p31, p32, p33, p41, p42, p43, p44)
    if all(_ops.is_scalar(v) for row in lower for v in row):
        return _valid_floats(lower)
    np = _np()
    with np.errstate(all="ignore"):
        return _valid_arrays(np, [[np.asarray(v, dtype=float) for v in row] for row in lower])


def _valid_floats(lower):
    n = len(lower)
    for i in range(n):
        if not lower[i][i] >= 0.0:
            return False
    s = [math.sqrt(lower[i][i]) for i in range(n)]
    c = {}
    for i in range(n):
        for j in range(i):
            if s[i] * s[j] == 0.0:
                if lower[i][j] != 0.0:
                    return False
                c[i, j] = 0.0
            else:
                c[i, j] = lower[i][j] / s[j] / s[i]
    for dj in _pivots(c, n):
        if not dj > 0.0:
            return False  # (before the next pivot divides by it)
    return True


def _valid4_floats(p11, p21, p22, p31, p32, p33, p41, p42, p43, p44):
    """:func:`_valid_floats` of a 4x4 matrix of floats, written out: the same operations in the
    same order (the same answer, bit for bit the same pivots), without the lists, the dict and
    the generator, which cost the dual-axis FMU's long steps 80 % of their time."""
    if not (p11 >= 0.0 and p22 >= 0.0 and p33 >= 0.0 and p44 >= 0.0):
        return False
    sqrt = math.sqrt
    s1, s2, s3, s4 = sqrt(p11), sqrt(p22), sqrt(p33), sqrt(p44)
    if s2 * s1 == 0.0:
        if p21 != 0.0:
            return False
        c21 = 0.0
    else:
        c21 = p21 / s1 / s2
    if s3 * s1 == 0.0:
        if p31 != 0.0:
            return False
        c31 = 0.0
    else:
        c31 = p31 / s1 / s3
    if s3 * s2 == 0.0:
        if p32 != 0.0:
            return False
        c32 = 0.0
    else:
        c32 = p32 / s2 / s3
    if s4 * s1 == 0.0:
        if p41 != 0.0:
            return False
        c41 = 0.0
    else:
        c41 = p41 / s1 / s4
    if s4 * s2 == 0.0:
        if p42 != 0.0:
            return False
        c42 = 0.0
    else:
        c42 = p42 / s2 / s4
    if s4 * s3 == 0.0:
        if p43 != 0.0:
            return False
        c43 = 0.0
    else:
        c43 = p43 / s3 / s4
    d0 = BOUND                     # the pivots of _pivots, in its order
    d1 = d0 - c21 * (c21 / d0)
    if not d1 > 0.0:
        return False
    u32 = c32 - c31 * (c21 / d0)
    u42 = c42 - c41 * (c21 / d0)
    d2 = d0 - c31 * (c31 / d0) - u32 * (u32 / d1)
    if not d2 > 0.0:
        return False
    u43 = c43 - c41 * (c31 / d0) - u42 * (u32 / d1)
    d3 = d0 - c41 * (c41 / d0) - u42 * (u42 / d1) - u43 * (u43 / d2)
    return d3 > 0.0


def _pivots(c, n):
    """The pivots ``d_j`` of the ``L D L^T`` factorisation of the correlation matrix (below the
    diagonal ``c[i, j]``, on it ``BOUND``), one after the other (floats or arrays): ``u_ij =
    l_ij d_j``; the rows after ``d_j`` are computed only when the next pivot is asked for."""
    d, u = [], {}
    for j in range(n):
        dj = BOUND
        for k in range(j):
            dj = dj - u[j, k] * (u[j, k] / d[k])
        yield dj
        d.append(dj)
        for i in range(j + 1, n):
            v = c[i, j]
            for k in range(j):
                v = v - u[i, k] * (u[j, k] / d[k])
            u[i, j] = v


def _valid_arrays(np, lower):
    """:func:`_valid_floats` elementwise (the same operations in the same order)."""
    n = len(lower)
    ok = np.asarray(True)
    for i in range(n):
        ok = ok & (lower[i][i] >= 0.0)
    s = [np.sqrt(np.where(lower[i][i] >= 0.0, lower[i][i], 0.0)) for i in range(n)]
    c = {}
    for i in range(n):
        for j in range(i):
            zero = s[i] * s[j] == 0.0
            ok = ok & ~(zero & (lower[i][j] != 0.0))
            c[i, j] = np.where(zero, 0.0, lower[i][j] / np.where(zero, 1.0, s[j])
                               / np.where(zero, 1.0, s[i]))
    for dj in _pivots(c, n):
        ok = ok & (dj > 0.0)
    return ok


def problem(names, lower, listing=None):
    """What is wrong with the covariance ``lower`` (floats, rows as :func:`valid` takes them)
    whose entries are called ``names`` (the same shape) and the matrix ``listing`` (by default
    ``"the covariance (<names>)"``): ``(subject, values, what)``, e.g.
    ``("P22", "-1.0", "a negative variance")`` or ``("the covariance (P, P12, P22)", "(1.0,
    2.0, 1.0)", "not positive semi-definite")`` (or an entry ``"not finite"``); None when it is
    valid."""
    if valid(lower):
        return None
    for name_row, row in zip(names, lower):
        for name, v in zip(name_row, row):
            if not math.isfinite(v):
                return name, repr(float(v)), "not finite"
    for i, row in enumerate(lower):
        if not row[i] >= 0.0:
            return names[i][i], repr(float(row[i])), "a negative variance"
    if listing is None:
        listing = "the covariance (%s)" % ", ".join(name for row in names for name in row)
    return (listing,
            "(%s)" % ", ".join(repr(float(v)) for row in lower for v in row),
            "not positive semi-definite")


def refusal(names, lower, k, t, listing=None):
    """The FMUs' message refusing sample ``k`` at time ``t`` for the covariance ``lower``
    (which :func:`problem` finds wrong)."""
    subject, values, what = problem(names, lower, listing)
    return "%s would be %s at sample %d (t = %r s), %s: %s; allowed: %s (nothing was changed)" % (
        subject, values, k, t, what, CAUSE, ALLOWED)


def state_problems(names, lower, listing=None):
    """The problem of a covariance read back from an FMU state (a list of at most one line):
    the refusal's words, without a sample."""
    found = problem(names, lower, listing)
    if found is None:
        return []
    subject, values, what = found
    return ["%s = %s is %s; allowed: a covariance whose variances are >= 0 and that is "
            "positive semi-definite (docs/method.md)" % (subject, values, what)]


def check(names, lower, k, what, seeds=None):
    """Raise :class:`CovarianceError` (:func:`error`) unless the covariance ``lower`` (floats:
    one run; arrays: runs on the leading axis) after sample ``k`` is valid; the message names
    ``what`` (the filter), the first run that fails and its ``seeds`` entry."""
    ok = valid(lower)
    if ok is True:
        return
    if ok is False:
        raise error(names, lower, k, what)
    np = _np()
    if bool(np.all(ok)):
        return
    shape = np.broadcast(*[np.asarray(v) for row in lower for v in row], ok).shape
    run = int(np.argmin(np.broadcast_to(ok, shape)))
    values = [[float(np.broadcast_to(np.asarray(v, dtype=float), shape)[run]) for v in row]
              for row in lower]
    seed = None
    if seeds is not None and np.ndim(seeds):
        seed = int(np.asarray(seeds).reshape(-1)[run])
    raise error(names, values, k, what, run, seed)


def error(names, lower, k, what, run=None, seed=None):
    """The :class:`CovarianceError` of the (invalid) covariance ``lower`` (floats) of ``what``
    after sample ``k`` (of batch run ``run``, FMU seed ``seed``)."""
    subject, text, kind = problem(names, lower)
    where = "" if run is None else " in run %d%s" % (run, "" if seed is None
                                                      else " (seed %d)" % seed)
    return CovarianceError("%s of %s would be %s at sample %d%s, %s: %s; allowed: %s" % (
        subject, what, text, k, where, kind, CAUSE, ALLOWED))
