"""Evidence for the arithmetic kernels that is independent of their native twins.

models/_ops.py and models/noise.py are mirrored in C and tested equal bit for bit; these tests
check the Python kernels against what they compute, so that a fault in them is caught without the
twin: the logarithm against the math library (a series one term short is 7 ulps off near
sqrt(2), the full series 2), and the uniform draw's grid: the midpoints of a 2^-52 grid,
symmetric about 1/2.  A sub-ulp change of exp's series (the fault ops-exp-series-short) is
visible only in the bits, so the mutation list lets the twins' bit tests catch that one.
"""
import math

import numpy as np

from driftfmu.models import _ops, noise


def test_log_is_within_a_few_ulps_of_the_math_library():
    # near sqrt(2), where the series' last term matters most: 2 ulps; elsewhere 3 (near 1,
    # where log is small)
    for lo, hi, ulps in ((1.3, math.sqrt(2.0), 2.0), (0.5, 2.0, 3.0), (1e-300, 1e-280, 3.0),
                         (1e5, 1e7, 3.0)):
        x = np.geomspace(lo, hi, 20_001)
        ref = np.log(x)
        err = np.abs(_ops.log(x) - ref) / np.spacing(np.abs(ref))
        assert np.max(err) <= ulps, (lo, hi, np.max(err))


def test_uniform_draws_sit_on_the_midpoints_of_a_2_to_the_52_grid():
    # u = (b + 1/2) 2^-52 for the top 52 bits b: symmetric about 1/2 (u(b) + u(2^52 - 1 - b)
    # = 1 exactly), never 0 or 1
    seeds = np.arange(1, 2001, dtype=np.uint64)
    u = noise.uniform(seeds, 3, np.uint64(17))
    b = noise.bits(seeds, 3, np.uint64(17)) >> np.uint64(12)
    assert np.array_equal(u * 2.0 ** 52 - 0.5, b.astype(float))
    assert 0.0 < u.min() and u.max() < 1.0
