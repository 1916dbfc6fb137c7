"""The slow errors' Gaussian draws, the ziggurat (models.noise.ziggurat_of and its C twin
noise_ziggurat_of), against independent references: its tables against the normal density's
areas (math.exp, math.erfc), its draws against SciPy's normal distribution (Kolmogorov-Smirnov,
chi-square), each of its branches on its own (the fast region, the wedge's acceptance
probability, the tail beyond R against the normal's conditional tail), and the C twin bit for
bit with the Python floats and arrays on words that take every branch.

Every statistical test draws from fixed streams (so it gives one answer every run) and sets its
bound at a significance of 1e-3 or at four standard deviations of the count it checks, from the
number of draws."""
import ctypes
import math

import numpy as np
import pytest
from scipy import stats

from driftfmu.fmu_src.native.models import generate
from driftfmu.models import noise
from test_native_models import CC, D, U64, compile_models, same

#: Significance of the distribution tests (fixed draws: a bound, not a chance per run).
ALPHA = 1e-3


def f(x):
    return math.exp(-0.5 * x * x)


def branch(w):
    """``"fast"``, ``"wedge"`` or ``"tail"``: where the first try of the word ``w`` lands,
    from the tables (layer ``w & 255``, ``u`` the top 53 bits over [-1, 1))."""
    i = w & 0xFF
    u = (w >> 11) / 2.0 ** 52 - 1.0
    if abs(u) < noise.ZIG_X[i + 1] / noise.ZIG_X[i]:
        return "fast"
    return "tail" if i == 0 else "wedge"


def words(seed, stream, n):
    return noise.bits(seed, stream, np.arange(1, n + 1, dtype=np.uint64))


@pytest.fixture(scope="module")
def c(tmp_path_factory):
    if CC is None:
        pytest.skip("no C compiler (gcc or cc) on PATH: the C port cannot be compiled")
    lib = ctypes.CDLL(str(compile_models(tmp_path_factory.mktemp("ziggurat"))))
    for name, res, args in (("noise_ziggurat_of", D, (U64,)),
                            ("noise_ziggurat", D, (U64, U64, U64)),
                            ("noise_ziggurat_keyed", D, (U64, U64)),
                            ("noise_key", U64, (U64, U64)),
                            ("noise_ziggurat_rest", D, (U64, ctypes.c_uint, D, D))):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib


@pytest.fixture(params=["python", "c"])
def impl(request):
    """The twin under test: ``(ziggurat_of, rest)``, models/noise.py's or the C port's (each
    against the references on its own)."""
    if request.param == "python":
        return noise.ziggurat_of, noise._ziggurat_rest
    lib = request.getfixturevalue("c")
    return lib.noise_ziggurat_of, lib.noise_ziggurat_rest


# -- the tables -------------------------------------------------------------------------------

def test_the_c_table_is_the_generated_one():
    """fmu_src/native/models/ziggurat_table.h is what generate.py writes from models/noise.py
    (run ``python -c "from driftfmu.fmu_src.native.models import generate; ..."`` after a change
    of the tables: this test names the file)."""
    path = generate.HERE / "ziggurat_table.h"
    assert path.read_text() == generate.ziggurat_table(), (
        "%s is not generate.ziggurat_table(): write it again" % path)


def test_every_layer_has_the_area_v_under_the_density():
    """Layer i >= 1: the box of width x_i between the heights f(x_i) and f(x_(i+1)) has the area
    ZIG_V; layer 0: the box R f(R) and the tail beyond R (sqrt(pi/2) erfc(R/sqrt 2)) together;
    the edges fall to x_256 = 0; together the layers cover the half density sqrt(pi / 2)."""
    x, v, r = noise.ZIG_X, noise.ZIG_V, noise.ZIG_R
    assert len(x) == noise.ZIG_N + 1 and x[1] == r and x[-1] == 0.0
    assert all(x[i + 1] < x[i] for i in range(noise.ZIG_N))
    tail = math.sqrt(math.pi / 2.0) * math.erfc(r / math.sqrt(2.0))
    assert r * f(r) + tail == pytest.approx(v, rel=1e-10)
    assert x[0] * f(r) == pytest.approx(v, rel=1e-14)
    for i in range(1, noise.ZIG_N):
        assert x[i] * (f(x[i + 1]) - f(x[i])) == pytest.approx(v, rel=1e-8), i
    # the boxes cover the half density with 0.67 % to spare (what the wedges and restarts
    # reject)
    assert 0.006 < noise.ZIG_N * v / math.sqrt(math.pi / 2.0) - 1.0 < 0.007


def test_the_tables_ratio_and_heights_are_the_edges():
    for i in range(noise.ZIG_N):
        assert noise.ZIG_RATIO[i] == noise.ZIG_X[i + 1] / noise.ZIG_X[i]
    for xi, fi in zip(noise.ZIG_X, noise.ZIG_F):
        assert abs(fi - f(xi)) <= 4 * math.ulp(f(xi))


# -- the draws --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def many():
    """2^21 draws of each of two streams under two seeds (8 388 608), by the array path."""
    n = 1 << 21
    return np.concatenate([noise.ziggurat(s, st, np.arange(1, n + 1, dtype=np.uint64))
                           for s in (3, 2026) for st in (noise.STREAM_RANDOM_WALK,
                                                         noise.STREAM_FLICKER + 2)])


def test_the_draws_are_standard_normal_by_kolmogorov_smirnov(many):
    d = stats.kstest(many, "norm").statistic
    bound = math.sqrt(-math.log(ALPHA / 2.0) / 2.0) / math.sqrt(many.size)
    assert d < bound, (d, bound)
    # the other side: the test tells a normal of standard deviation 1.002 from it
    assert stats.kstest(many * 1.002, "norm").statistic > bound


def test_the_draws_fill_every_layer_as_the_normal_does(many):
    """Chi-square over the bins between the layers' edges, each split at its middle (1022 bins
    from -x_1 to x_1 and the two tails), against the normal's probabilities.  A wedge that
    always accepted would move 0.7 % of the mass into the wedges: that is shown to fail too."""
    def chi2_p(draws):
        inner = np.array(noise.ZIG_X[1:])
        half = np.concatenate([inner, (inner[:-1] + inner[1:]) / 2.0])
        edges = np.unique(np.concatenate([-half, half]))
        edges = np.concatenate([[-np.inf], edges, [np.inf]])
        obs, _ = np.histogram(draws, edges)
        exp = np.diff(stats.norm.cdf(edges)) * draws.size
        return stats.chisquare(obs, exp * obs.sum() / exp.sum()).pvalue
    assert chi2_p(many) > ALPHA
    # a ziggurat whose wedges accept everything: the same words, every first try kept
    w = words(3, noise.STREAM_RANDOM_WALK, 1 << 22)
    i = (w & np.uint64(0xFF)).astype(np.intp)
    u = (w >> np.uint64(11)).astype(np.float64) * 2.0 ** -52 - 1.0
    wrong = u * np.asarray(noise.ZIG_X)[i]
    wrong[i == 0] = noise.ziggurat_of(w[i == 0])  # (the tail as it is)
    assert chi2_p(wrong) < ALPHA


def test_the_c_twins_draws_are_standard_normal(c):
    """The C port's draws of one stream on their own (2^20, through ctypes), by the same
    bounds as the Python draws': Kolmogorov-Smirnov, the mean, the variance, the tail beyond R."""
    key = c.noise_key(2026, noise.STREAM_FLICKER + 3)
    n = 1 << 20
    draws = np.array([c.noise_ziggurat_keyed(key, k) for k in range(1, n + 1)])
    bound = math.sqrt(-math.log(ALPHA / 2.0) / 2.0) / math.sqrt(n)
    assert stats.kstest(draws, "norm").statistic < bound
    check_moments(draws)


def check_moments(draws):
    n = draws.size
    assert abs(draws.mean()) < 4.0 / math.sqrt(n)
    assert abs(draws.var() - 1.0) < 4.0 * math.sqrt(2.0 / n)
    p = 2.0 * stats.norm.sf(noise.ZIG_R)
    beyond = np.count_nonzero(np.abs(draws) > noise.ZIG_R)
    assert abs(beyond - n * p) < 4.0 * math.sqrt(n * p * (1.0 - p)) + 1, (beyond, n * p)
    assert abs(np.count_nonzero(draws > 0.0) - n / 2.0) < 4.0 * math.sqrt(n / 4.0)


def test_the_mean_variance_and_tail_fraction(many):
    check_moments(many)


# -- each branch on its own -------------------------------------------------------------------

def test_the_tail_is_the_normals_beyond_r_with_the_sign_of_u(impl):
    """_ziggurat_rest from layer 0 (the first try beyond R): 20 000 draws from the words of a
    stream, for u < 0 and u > 0, against P(|X| > t | |X| > R) = erfc(t/sqrt 2)/erfc(R/sqrt 2)
    (Kolmogorov-Smirnov); every draw beyond R, its sign u's."""
    r = noise.ZIG_R
    w = [int(v) for v in words(11, noise.STREAM_BIAS_GM, 20000)]
    _, rest = impl
    pos = np.array([rest(v, 0, 0.999, 0.999 * noise.ZIG_X[0]) for v in w])
    neg = np.array([rest(v, 0, -0.999, -0.999 * noise.ZIG_X[0]) for v in w])
    assert (pos > r).all() and (neg < -r).all()
    np.testing.assert_array_equal(pos, -neg)  # the same words: the same magnitudes

    def cdf(t):
        return 1.0 - stats.norm.sf(t) / stats.norm.sf(r)
    d = stats.kstest(pos, cdf).statistic
    bound = math.sqrt(-math.log(ALPHA / 2.0) / 2.0) / math.sqrt(pos.size)
    assert d < bound, (d, bound)
    assert stats.kstest(pos + 0.01, cdf).statistic > bound  # the other side


@pytest.mark.parametrize("i", [1, 2, 40, 128, 254, 255])
def test_a_wedge_keeps_x_with_the_probability_of_the_curve_over_it(i, impl):
    """_ziggurat_rest from layer i >= 1 at an x inside the wedge (between x_(i+1) and x_i):
    it returns that very x with probability (f(x) - f(x_i)) / (f(x_(i+1)) - f(x_i)) (its height
    uniform over the layer), else a new draw; 20 000 words, the count within 4 standard
    deviations; at x_i's side and at x_(i+1)'s side of the wedge too."""
    lo, hi = noise.ZIG_X[i + 1], noise.ZIG_X[i]
    w = [int(v) for v in words(5 + i, noise.STREAM_FLICKER, 20000)]
    for t in (0.5, 0.05, 0.95):
        x = lo + t * (hi - lo)
        u = x / hi
        p = (f(x) - f(hi)) / (f(lo) - f(hi))
        kept = sum(impl[1](v, i, u, x) == x for v in w)
        assert abs(kept - len(w) * p) < 4.0 * math.sqrt(len(w) * p * (1 - p)) + 1, (t, kept, p)


def test_the_fast_region_returns_u_times_the_layers_width(impl):
    w = [int(v) for v in words(7, noise.STREAM_TURN_ON, 5000)]
    fast = [v for v in w if branch(v) == "fast"]
    assert len(fast) > 4800
    for v in fast:
        i, u = v & 0xFF, (v >> 11) / 2.0 ** 52 - 1.0
        assert impl[0](v) == u * noise.ZIG_X[i]


def test_every_branch_is_taken_and_a_rejected_draw_starts_again(impl):
    """Of 2^20 words, the share of first tries outside the fast region is 1 - mean(ratio)
    (within 4 standard deviations), tails among them; a wedge's rejection starts again from the
    words after it (a draw different from the first try's x)."""
    w = [int(v) for v in words(1, noise.STREAM_RANDOM_WALK, 1 << 20)]
    kinds = [branch(v) for v in w]
    n, slow = len(w), kinds.count("wedge") + kinds.count("tail")
    p = 1.0 - sum(noise.ZIG_RATIO) / noise.ZIG_N
    assert abs(slow - n * p) < 4.0 * math.sqrt(n * p * (1 - p)), (slow, n * p)
    assert kinds.count("tail") > 0
    restarted = 0
    for v, kind in zip(w, kinds):
        if kind == "wedge":
            i, u = v & 0xFF, (v >> 11) / 2.0 ** 52 - 1.0
            if impl[0](v) != u * noise.ZIG_X[i]:
                restarted += 1
    assert restarted > 0


# -- the paths and the C twin -----------------------------------------------------------------

def branchy_words():
    """Words of every branch: the first 1000 of a stream and the first 300 of each slow branch
    among 2^18."""
    w = [int(v) for v in words(2026, noise.STREAM_FLICKER + 5, 1 << 18)]
    out = w[:1000]
    for kind in ("wedge", "tail"):
        out += [v for v in w if branch(v) == kind][:300]
    return out


def test_floats_and_arrays_give_the_same_bits_in_any_shape():
    """An array's draws are its floats' draws: with more slow draws than noise._ZIG_ROUND (a
    round of them at once, then the rest one by one) and with fewer (all one by one), in a
    batch's runs x samples grid too."""
    w = branchy_words()
    floats = [noise.ziggurat_of(v) for v in w]
    for part in (slice(0, 40), slice(0, 1000), slice(None)):
        slow = sum(branch(v) != "fast" for v in w[part])
        arr = noise.ziggurat_of(np.array(w[part], dtype=np.uint64))
        assert all(same(a, b) for a, b in zip(floats[part], arr)), (part, slow)
    assert sum(branch(v) != "fast" for v in w[:40]) <= noise._ZIG_ROUND
    assert sum(branch(v) != "fast" for v in w) > noise._ZIG_ROUND
    # a batch's shape: runs x samples, broadcast from a column of seeds and a row of indices
    seeds = np.array([[1], [7], [2026]], dtype=np.uint64)
    ks = np.arange(1, 4001, dtype=np.uint64)
    grid = noise.ziggurat(seeds, noise.STREAM_BIAS_GM, ks)
    assert grid.shape == (3, 4000)
    for r, s in enumerate((1, 7, 2026)):
        for k in range(1, 4001, 1):
            assert same(grid[r, k - 1], noise.ziggurat(s, noise.STREAM_BIAS_GM, k))


def test_the_c_twin_gives_the_python_bits_on_every_branch(c):
    for v in branchy_words():
        assert same(c.noise_ziggurat_of(v), noise.ziggurat_of(v)), hex(v)


def test_the_c_draw_of_a_stream_and_of_its_key(c):
    for seed in (0, 1, 2026, 2 ** 64 - 1):
        for stream in (noise.STREAM_TURN_ON, noise.STREAM_RANDOM_WALK, noise.STREAM_FLICKER + 7):
            key = c.noise_key(seed, stream)
            for k in list(range(0, 300)) + [2 ** 40 + 3, 2 ** 63 + 5]:
                want = noise.ziggurat(seed, stream, k)
                assert same(c.noise_ziggurat(seed, stream, k), want)
                assert same(c.noise_ziggurat_keyed(key, k), want)


# -- the algorithm as written down, against the code ------------------------------------------

def reference_draw(w):
    """The draw of the word ``w`` by the steps models/noise.py's comment gives, written anew
    here with math.exp and math.log (the code's are arithmetic-only: a tail's draw may differ in
    its last bits; a last-bit difference of f would change a path only where a height falls
    within an ulp of the curve, which none of the words below does)."""
    mask, golden = 2 ** 64 - 1, noise.GOLDEN

    def next_word(v):
        return noise._mix((v + golden) & mask)

    def uniform(v):
        return ((v >> 12) + 0.5) / 2.0 ** 52
    while True:
        i, u = w & 0xFF, (w >> 11) / 2.0 ** 52 - 1.0
        x = u * noise.ZIG_X[i]
        if abs(u) < noise.ZIG_X[i + 1] / noise.ZIG_X[i]:
            return x
        if i == 0:
            while True:
                w = next_word(w)
                a = -math.log(uniform(w)) / noise.ZIG_R
                w = next_word(w)
                b = -math.log(uniform(w))
                if 2.0 * b > a * a:
                    return math.copysign(noise.ZIG_R + a, u)
        w = next_word(w)
        y = f(noise.ZIG_X[i]) + uniform(w) * (f(noise.ZIG_X[i + 1]) - f(noise.ZIG_X[i]))
        if y < f(x):
            return x
        w = next_word(w)


def restarts_into_the_base(n):
    """Words of a stream whose first try is a wedge's, rejected, and whose new start falls in
    the base layer's fast region (|x| < R): about one word in 90,000."""
    w0 = words(2027, noise.STREAM_RANDOM_WALK, n)
    X, RATIO, F = (np.asarray(t) for t in (noise.ZIG_X, noise.ZIG_RATIO, noise.ZIG_F))
    i0 = (w0 & np.uint64(0xFF)).astype(np.intp)
    u0 = (w0 >> np.uint64(11)).astype(np.float64) / 2.0 ** 52 - 1.0
    x0 = u0 * X[i0]
    w1 = noise._mix(w0 + np.uint64(noise.GOLDEN))
    y = F[i0] + ((w1 >> np.uint64(12)).astype(np.float64) + 0.5) / 2.0 ** 52 * (
        F[np.minimum(i0 + 1, noise.ZIG_N)] - F[i0])
    w2 = noise._mix(w1 + np.uint64(noise.GOLDEN))
    i2 = (w2 & np.uint64(0xFF)).astype(np.intp)
    u2 = (w2 >> np.uint64(11)).astype(np.float64) / 2.0 ** 52 - 1.0
    pick = ((np.abs(u0) >= RATIO[i0]) & (i0 != 0) & (y >= np.exp(-0.5 * x0 * x0))
            & (i2 == 0) & (np.abs(u2) < RATIO[0]))
    return [int(v) for v in w0[pick]]


def test_every_branch_is_the_algorithm_as_written_down(impl):
    """The draws of words of every branch (the fast region, wedges kept and rejected, tails,
    new starts that land in the base layer's fast region) equal the algorithm written anew
    with math.exp and math.log, in each twin: to the bit outside the tail, within 4 ulp in it
    (a draw by another path differs by far more)."""
    base = restarts_into_the_base(1 << 22)
    assert len(base) >= 10
    for v in branchy_words() + base:
        got, want = impl[0](v), reference_draw(v)
        if abs(want) > noise.ZIG_R:
            assert abs(got - want) <= 4 * math.ulp(want), hex(v)
        else:
            assert same(got, want), hex(v)
    for v in base:  # (their draw is the new start's x, under R)
        assert abs(impl[0](v)) < noise.ZIG_R
