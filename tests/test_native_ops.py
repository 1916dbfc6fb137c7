"""The C port's arithmetic against independent references, not against its Python twin: the
arithmetic-only exponential ``ops_exp`` (its scaling by 2^n built from the exponent bits, the
subnormal results by ldexp) against the C library's ``exp`` (Python's math.exp), and the draw
from a stream's key ``noise_normal_keyed`` (the inverse normal CDF's central branch inline, its
tails out of line) against SciPy's ``norm.ppf`` of the same uniform, within Acklam's stated
relative accuracy (1.15e-9); ``ops_floor`` (through int64 below 2^52, the library's floor from
there) against math.floor, and ``ops_log`` (frexp read from the bits of a positive normal
number, called for any other) on both sides of each edge of its two paths."""
import ctypes
import math
import random
import sys

import pytest

from driftfmu.models import _ops
from test_native_models import CC, D, U64, compile_models, same

#: Acklam's rational approximation: relative error below 1.15e-9 over (0, 1) (his page); the
#: margin covers the rounding of the double evaluation (about 1e-15).
ACKLAM = 1.2e-9


@pytest.fixture(scope="module")
def c(tmp_path_factory):
    if CC is None:
        pytest.skip("no C compiler (gcc or cc) on PATH: the C port cannot be compiled")
    lib = ctypes.CDLL(str(compile_models(tmp_path_factory.mktemp("native_ops"))))
    for name, res, args in (("ops_exp", D, (D,)), ("ops_exp_estrin", D, (D,)), ("noise_key", U64, (U64, U64)),
                            ("noise_uniform", D, (U64, U64, U64)),
                            ("noise_normal_keyed", D, (U64, U64)), ("ops_floor", D, (D,)),
                            ("ops_log", D, (D,))):
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    return lib


def ulps(a, b):
    """The distance of two finite doubles in units in the last place of the larger."""
    return abs(a - b) / math.ulp(max(abs(a), abs(b)))


@pytest.mark.parametrize("name, bound", [("ops_exp", 1.0), ("ops_exp_estrin", 2.0)])
def test_exp_is_the_c_librarys_to_an_ulp_over_its_whole_range(c, name, bound):
    """Normal results within 1 ulp of math.exp (Horner's ops_exp; Estrin's ops_exp_estrin,
    whose grouping rounds a little more, within 2: the polynomial's error; the scaling by 2^n
    is exact), at the ends of the scaled range (n = -1022, 1023: x near -708.4, 709.8) too;
    subnormal results (x below -708.4, n < -1022: ldexp's rounding) within 1 ulp of the
    smallest subnormal; 0 below -745.2, inf above 709.8; exp(0) = 1 exactly."""
    exp = getattr(c, name)
    rng = random.Random(4242)
    xs = [rng.uniform(-708.0, 709.0) for _ in range(20000)]
    xs += [rng.uniform(-5.0, 5.0) for _ in range(5000)]
    xs += [-708.39, -708.0, -707.5, 709.0, 709.5, 709.78, 1e-300, -1e-300, 0.5, -0.5]
    for x in xs:
        got, want = exp(x), math.exp(x)
        assert ulps(got, want) <= bound, (x, got, want)
    assert exp(0.0) == 1.0 and exp(1e-20) == 1.0
    tiny = 5e-324
    for x in [rng.uniform(-745.0, -708.4) for _ in range(5000)] + [-708.4, -709.0, -744.4]:
        got, want = exp(x), math.exp(x)
        assert want < sys.float_info.min * 2  # (the subnormal side, or the smallest normals)
        assert abs(got - want) <= max(tiny, math.ulp(want)), (x, got, want)
    assert exp(-746.0) == 0.0 and exp(710.0) == math.inf
    assert math.isnan(exp(math.nan))


def test_keyed_normal_is_the_inverse_normal_cdf_of_its_uniform(c):
    """noise_normal_keyed(noise_key(seed, stream), k) is Phi^-1 of noise_uniform(seed, stream,
    k) to Acklam's accuracy: over 60000 draws, those of both tails (p < 0.02425, p > 0.97575:
    about 2900 each) among them."""
    from scipy.stats import norm
    tails = [0, 0]
    for seed, stream in ((1, 2), (77, 5), (2 ** 40 + 3, 11)):
        key = c.noise_key(seed, stream)
        ps = [c.noise_uniform(seed, stream, k) for k in range(20000)]
        for k, (p, want) in enumerate(zip(ps, norm.ppf(ps).tolist())):
            got = c.noise_normal_keyed(key, k)
            assert abs(got - want) <= ACKLAM * abs(want) + 1e-15, (seed, stream, k, p, got)
            tails[0] += p < 0.02425
            tails[1] += p > 1.0 - 0.02425
    n = 60000 * 0.02425  # the expected count of each tail, +- 6 standard deviations
    assert all(abs(t - n) < 6 * math.sqrt(n) for t in tails), tails


def test_log_equals_models_where_frexp_is_read_from_the_bits_and_where_it_is_called(c):
    # ops_log reads frexp from the bits of a positive normal finite x and calls frexp for any
    # other: both sides of each edge (the smallest normal, the largest finite) and beyond them
    top = 1.7976931348623157e308
    xs = [2.2250738585072014e-308, 2.225073858507201e-308, 5e-324, top, math.inf, 0.0, -0.0,
          math.nan, 0.5, math.nextafter(0.5, 0.0), 1.0, math.nextafter(1.0, 0.0)]
    for x in xs:
        assert same(_ops.log(x), c.ops_log(x)), x
    assert math.isnan(c.ops_log(math.inf)) and math.isnan(c.ops_log(math.nan))
    assert c.ops_log(top) == pytest.approx(math.log(top), rel=1e-15)
    assert c.ops_log(2.2250738585072014e-308) == pytest.approx(-708.3964185322641, rel=1e-15)


def test_floor_equals_models_on_both_sides_of_two_to_the_52(c):
    # below 2^52 ops_floor truncates through int64 (one less where that is above x); from 2^52
    # on it calls floor: each side, both signs, the zeros and the non-finite
    big = 4503599627370496.0  # 2^52
    xs = [big, math.nextafter(big, 0.0), -big, math.nextafter(-big, 0.0),
          math.nextafter(big, math.inf), 2.0 ** 63, -(2.0 ** 63), 1e300, -1e300, math.inf,
          -math.inf, math.nan, 0.0, -0.0, 0.5, -0.5, 1e-300, -1e-300, 5e-324, -5e-324, 3.0,
          -3.0, 2.5, -2.5, math.nextafter(1.0, 0.0), math.nextafter(-1.0, 0.0),
          math.nextafter(-1.0, -2.0), 4503599627370495.5, -4503599627370495.5]
    for x in xs:
        assert same(_ops.floor(x), c.ops_floor(x)), x
        if math.isfinite(x):
            assert c.ops_floor(x) == math.floor(x), x
    assert math.copysign(1.0, c.ops_floor(-0.0)) == 1.0
    assert math.copysign(1.0, c.ops_floor(0.5)) == 1.0
