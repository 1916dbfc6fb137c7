"""Internal (not a stable API; use driftfmu.simulate and ``driftfmu inputs`` instead).

When a time that another tool wrote is a sample instant: the one rule for every time driftfmu
reads (the rows of a result file, ``driftfmu inputs``; the ``time`` field of ``simulate``'s
``input``).

The FMUs count a time within a millionth of a sample period of an instant ``t_start + k Ts``
as that instant (:data:`INSTANT_TOLERANCE`, ``slave_base.INSTANT_TOLERANCE`` and its C twin),
on their own clock, the step sizes summed with compensation.  A time another tool wrote is
its own arithmetic's: FMI's communication points are a running sum, ``t_{i+1} = t_i + h_i``
(FMI 2.0 section 4.2.2: ``currentCommunicationPoint`` is the previous one plus the previous
step), a spreadsheet's time column is ``=A2 + 0.001`` filled down, and each addition rounds by
up to ``2^-53 |t_i|``.  After a million additions of 1 ms the sum is off by 1.7e-5 sample
periods, past the FMUs' tolerance, while the FMU (which summed the same steps with
compensation) is at the instant.  Text adds its own rounding: ``%.16g`` (fmusim, fmpy) carries
16 digits, a decimal such as ``0.043`` is the double nearest to it.

So a time ``t`` counts as the instant ``t_k`` when it is within

    tolerance(t) = INSTANT_TOLERANCE + 2^-53 n (|t| + |t_start|) / Ts,   n = |t - t_start| / Ts

sample periods of it (:func:`tolerance`): the FMUs' own tolerance plus the most that a running
sum of ``n`` steps of one period can have rounded on the way.  A sum of finer steps rounds more
often; their times are not sample instants but the points between, which only must not be
taken for the next instant.  The tolerance grows with the square of the samples: 2000 samples
of 1 ms add 4.4e-10 periods, a million 1.1e-4.  Beyond :data:`MAX_TOLERANCE` of a period (about
nine million samples from time 0) times are too coarse to tell the instants apart, and
:func:`period` refuses them (None) rather than guess.
"""
import math

#: A time within this many sample periods of an instant is that instant (the FMUs' own:
#: fmu_src/slave_base.INSTANT_TOLERANCE).
INSTANT_TOLERANCE = 1e-6
#: The unit roundoff of a double: an addition rounds by at most this times its result.
ROUNDOFF = 2.0 ** -53
#: The largest tolerance, in sample periods, that tells the instants apart (far below the
#: quarter period at which ``driftfmu inputs`` changes an input).
MAX_TOLERANCE = 0.01


def tolerance(t, start, Ts):
    """The tolerance of the module's rule, in sample periods, for a time ``t`` of a run that
    starts at ``start`` with the sample period ``Ts`` (floats, or NumPy arrays for ``t``)."""
    n = abs(t - start) / Ts
    return INSTANT_TOLERANCE + ROUNDOFF * n * (abs(t) + abs(start)) / Ts


def period(t, start, Ts):
    """The 0-based index ``k`` of the sample period ``[t_k, t_{k+1})`` that ``t`` is in, a
    time within :func:`tolerance` of an instant counting as that instant; None when ``t`` is
    not a finite number of periods from the start, or its tolerance exceeds
    :data:`MAX_TOLERANCE`."""
    position = (t - start) / Ts
    if not math.isfinite(position):
        return None
    tol = tolerance(t, start, Ts)
    if not tol <= MAX_TOLERANCE:
        return None
    return math.floor(position + tol)


def before_start(t, start, Ts):
    """True when ``t`` lies before the start time ``start`` by more than the tolerance."""
    return (t - start) / Ts < -tolerance(t, start, Ts)


def held_rows(row_times, start, step, n):
    """For the communication points ``start + i step`` (``i < n``), the index of the last row
    of ``row_times`` (non-decreasing) at or before it within :func:`tolerance` (the first row
    before its time): the zero-order hold of ``driftfmu.simulate``'s ``input``."""
    import numpy as np
    grid = start + step * np.arange(n)
    rows = np.searchsorted(row_times, grid + tolerance(grid, start, step) * step,
                           side="right") - 1
    return np.clip(rows, 0, len(row_times) - 1)
