"""The overlapping Allan deviation and its IEEE Std 952 reading (models/allan.py), as evidence.

Strongest first: the estimator equals an independent implementation (allantools.oadev) to
rounding; on synthetic signals whose Allan variance is known in closed form (white noise
``N^2 / tau``, the sampled random walk ``K^2 tau / 3 + K^2 Ts^2 / (6 tau)``, a first-order
Gauss-Markov process and a flicker band of them through their autocovariance), each estimate
lies within the two-sided chi-square bounds of its equivalent degrees of freedom, and the
reported N, K and B lie within four of their reported standard errors of the truth.  Every
signal has a fixed seed.  The rules of the reading (which run of slopes, what is not
resolved) each have a test that fails when the rule is changed.
"""
import math

import numpy as np
import pytest

from driftfmu.models import allan

allantools = pytest.importorskip("allantools")
scipy_stats = pytest.importorskip("scipy.stats")
scipy_signal = pytest.importorskip("scipy.signal")

#: Sample period of the synthetic signals [s] (100 Hz) and their length (2^20, 2.9 hours).
TS = 0.01
N_SAMPLES = 2 ** 20
#: White-noise density of the synthetic signals [unit sqrt(s)].
N_TRUE = 1e-3
#: How many of the reported standard errors a figure may be off (two-sided; the reported one
#: is an upper bound of the fitted line's standard error).
Z = 4.0
#: The probability that any one estimate of a table falls outside its bounds (two-sided),
#: spread over the table's tau (Bonferroni).
ALPHA = 1e-3


# -- synthetic signals and their closed forms ----------------------------------------------------

def white(rng, n=N_SAMPLES, N=N_TRUE, Ts=TS):
    """White noise of density N: Allan variance N^2 / tau."""
    return N / math.sqrt(Ts) * rng.standard_normal(n)


def random_walk(rng, K, n=N_SAMPLES, Ts=TS):
    """A random walk of rate K [unit / sqrt(s)] sampled at Ts."""
    return np.cumsum(K * math.sqrt(Ts) * rng.standard_normal(n))


def random_walk_avar(K, m, Ts=TS):
    """The sampled random walk's Allan variance: each difference of cluster sums is the white
    increments weighted by a triangle (0, 1, .., m, .., 1, 0), whose squares sum to
    (2 m^3 + m) / 3, so sigma^2 = K^2 Ts (2 m^2 + 1) / (6 m) = K^2 tau / 3 + K^2 Ts^2 / (6 tau)."""
    tau = m * Ts
    return K * K * tau / 3.0 + K * K * Ts * Ts / (6.0 * tau)


def gauss_markov(rng, n, tc, var, Ts=TS):
    """A stationary first-order Gauss-Markov process, x_k = phi x_(k-1) + w_k with phi =
    exp(-Ts / tc) and variance var."""
    phi = math.exp(-Ts / tc)
    w = rng.standard_normal(n) * math.sqrt(var * (1.0 - phi * phi))
    x0 = rng.standard_normal() * math.sqrt(var)
    y, _ = scipy_signal.lfilter([1.0], [1.0, -phi], w, zi=[phi * x0])
    return y


def gauss_markov_avar(tc, var, m, Ts=TS):
    """Its Allan variance from its autocovariance c(k) = var phi^|k| (exact for the sampled
    process): sigma^2(m) = (Var(S_m) - Cov(S_m, S'_m)) / m^2 over two adjacent clusters,
    Var(S_m) = sum_|k|<m (m - |k|) c(k), Cov = sum_|k|<m (m - |k|) c(m + k)."""
    phi = math.exp(-Ts / tc)
    k = np.arange(-(m - 1), m)
    w = m - np.abs(k)
    return float(np.sum(w * var * phi ** np.abs(k)) - np.sum(w * var * phi ** np.abs(m + k))) \
        / (m * m)


#: The flicker band: first-order Gauss-Markov components of equal variance, their correlation
#: times spread evenly in log over [0.02 s, 20000 s], three a decade.  Its Allan deviation is
#: flat (within 1.5 %) from about 100 times the shortest correlation time to a hundredth of
#: the longest: a component of correlation time T adds ``2 var T / tau`` where T << tau, so
#: the band must reach well below tau.
BAND = np.geomspace(0.02, 20000.0, 19)
BAND_VAR = 1e-6
#: Components per unit of ln(correlation time) (each stands for the interval between it and
#: its neighbours).
BAND_D = (len(BAND) - 1) / math.log(BAND[-1] / BAND[0])


def flicker(rng, n=N_SAMPLES):
    return sum(gauss_markov(rng, n, tc, BAND_VAR) for tc in BAND)


def flicker_avar(m):
    return sum(gauss_markov_avar(tc, BAND_VAR, m) for tc in BAND)


def within_chi2(estimates, truths, nus, alpha=ALPHA):
    """Indices of the estimates (Allan deviations) outside the two-sided chi-square bounds of
    their EDF: sigma^2 chi2_{a/2}(nu) / nu <= estimate^2 <= sigma^2 chi2_{1-a/2}(nu) / nu,
    a = alpha / count."""
    a = alpha / len(estimates)
    bad = []
    for i, (e, t, nu) in enumerate(zip(estimates, truths, nus)):
        lo = t * t * scipy_stats.chi2.ppf(a / 2, nu) / nu
        hi = t * t * scipy_stats.chi2.ppf(1 - a / 2, nu) / nu
        if not lo <= e * e <= hi:
            bad.append((i, e, t, nu))
    return bad


@pytest.fixture(scope="module")
def signals():
    rng = np.random.default_rng(20260952)
    K = math.sqrt(3.0) * N_TRUE / 1.0  # the white and random-walk lines cross at tau = 1 s
    return {
        "white": white(rng),
        "random_walk": random_walk(rng, K) + white(rng),
        "K": K,
        "flicker": flicker(rng) + white(rng),
    }


# -- the estimator ------------------------------------------------------------------------------

@pytest.mark.parametrize("offset", [0.0, 2.5, -1e3])
def test_oadev_equals_allantools(offset):
    """allantools.oadev on frequency data (an independent implementation through the phase
    x_k = Ts S_k) gives the same deviations and term counts, with an offset (the estimate
    does not depend on it) and at every kind of tau: all small m, octaves, per decade."""
    rng = np.random.default_rng(7)
    y = offset + white(rng, n=20001) + random_walk(rng, 1e-4, n=20001)
    n = y.size
    ms = sorted(set(allan.all_m(300) + allan.octave_m(n) + allan.decade_m(n, 7) + [n // 2 - 1]))
    ours, terms = allan.oadev(y, ms)
    taus, theirs, _, ns = allantools.oadev(y, rate=1.0 / TS, data_type="freq",
                                           taus=np.array(ms) * TS)
    assert len(theirs) == len(ms)
    np.testing.assert_allclose(taus, np.array(ms) * TS, rtol=1e-12)
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=0)
    assert list(terms) == [int(k) for k in ns] == [n - 2 * m + 1 for m in ms]


def test_oadev_takes_two_clusters_and_no_fewer():
    """m = n / 2 is two clusters (one difference); m = n / 2 + 1 and m = 0 are refused."""
    y = np.array([1.0, 3.0, 2.0, 6.0])
    adev, terms = allan.oadev(y, [1, 2])
    assert list(terms) == [3, 1]
    # by hand: m = 2, one difference of the cluster means (2 + 6)/2 - (1 + 3)/2 = 2
    assert adev[1] == pytest.approx(math.sqrt(2.0 ** 2 / 2.0), rel=1e-15)
    assert adev[0] == pytest.approx(math.sqrt((2.0 ** 2 + 1.0 + 4.0 ** 2) / (2 * 3)), rel=1e-15)
    for m in (3, 0):
        with pytest.raises(ValueError, match=r"allowed: 1 <= m <= n / 2"):
            allan.oadev(y, [m])


def test_grids():
    assert allan.octave_m(2) == [1] and allan.octave_m(1) == []
    assert allan.octave_m(64) == [1, 2, 4, 8, 16, 32] and allan.octave_m(63)[-1] == 16
    assert allan.all_m(9) == [1, 2, 3, 4] and allan.all_m(10)[-1] == 5
    assert allan.decade_m(10 ** 4, 3) == [1, 2, 5, 10, 22, 46, 100, 215, 464, 1000, 2154, 4642]
    assert allan.decade_m(10 ** 4, 10)[:8] == [1, 2, 3, 4, 5, 6, 8, 10]


def test_white_noise_estimates_lie_within_their_chi2_bounds(signals):
    y = signals["white"]
    ms = allan.octave_m(y.size)
    adev, _ = allan.oadev(y, ms)
    truth = [N_TRUE / math.sqrt(m * TS) for m in ms]
    nus = [allan.edf_white(y.size + 1, m) for m in ms]
    assert within_chi2(adev, truth, nus) == []
    # and the bounds are not vacuous: a sensor 2 % noisier fails them
    assert within_chi2(adev, [1.02 * t for t in truth], nus) != []
    assert within_chi2(adev, [0.98 * t for t in truth], nus) != []


def test_random_walk_estimates_lie_within_their_chi2_bounds():
    rng = np.random.default_rng(31)
    K = 2e-3
    y = random_walk(rng, K, n=2 ** 18)
    ms = allan.octave_m(y.size)
    adev, _ = allan.oadev(y, ms)
    truth = [math.sqrt(random_walk_avar(K, m)) for m in ms]
    nus = [allan.edf_random_walk(y.size + 1, m) for m in ms]
    assert within_chi2(adev, truth, nus) == []
    assert within_chi2(adev, [1.05 * t for t in truth], nus) != []
    assert within_chi2(adev, [0.95 * t for t in truth], nus) != []


def test_gauss_markov_estimates_lie_within_their_chi2_bounds():
    """A bias instability modelled as first-order Gauss-Markov (tc = 2 s): its hump, rising
    as sqrt(tau) and falling as 1/sqrt(tau), in closed form."""
    rng = np.random.default_rng(32)
    y = gauss_markov(rng, 2 ** 18, 2.0, 4e-6)
    ms = allan.octave_m(y.size)
    adev, _ = allan.oadev(y, ms)
    truth = [math.sqrt(gauss_markov_avar(2.0, 4e-6, m)) for m in ms]
    assert within_chi2(adev, truth, [allan.edf(y.size, m) for m in ms]) == []
    # the closed form against the continuous process's (IEEE 952 / Xing and
    # Gebre-Egziabher): q tc^2 / tau (1 - tc / (2 tau) (3 - 4 e^-tau/tc + e^-2tau/tc)),
    # q = 2 var / tc, away from the sample period
    for m in (1000, 4000, 20000):
        tau, tc, q = m * TS, 2.0, 2 * 4e-6 / 2.0
        cont = q * tc * tc / tau * (1 - tc / (2 * tau) * (3 - 4 * math.exp(-tau / tc)
                                                           + math.exp(-2 * tau / tc)))
        assert gauss_markov_avar(tc, 4e-6, m) == pytest.approx(cont, rel=2e-3)


def test_flicker_band_estimates_lie_within_their_chi2_bounds_and_its_floor_is_0664_B(signals):
    """The band's Allan deviation is flat between its correlation times at 0.664 B, B^2 = pi
    h with h = var D (D components per unit of ln tc: one-sided PSD h / f)."""
    y = signals["flicker"]
    ms = allan.octave_m(y.size)
    adev, _ = allan.oadev(y, ms)
    truth = [math.sqrt(flicker_avar(m) + N_TRUE ** 2 / (m * TS)) for m in ms]
    assert within_chi2(adev, truth, [allan.edf(y.size, m) for m in ms]) == []
    B = math.sqrt(math.pi * BAND_VAR * BAND_D)
    for m in (128, 512, 2048, 8192, 16384):  # tau 1.3 s to 164 s, inside the band
        assert math.sqrt(flicker_avar(m)) == pytest.approx(allan.FLOOR * B, rel=0.015)


# -- confidence ---------------------------------------------------------------------------------

@pytest.mark.parametrize("m", [1, 2, 7, 64, 1000, 524288])
def test_edf_is_nist_sp1065s_white_and_random_walk_formulas(m):
    """allantools.edf_simple implements NIST SP 1065's Table 5 independently; ours is the
    smaller of its white (alpha = 0) and random-walk (alpha = -2) values."""
    n = N_SAMPLES
    white_ = allantools.edf_simple(n + 1, m, 0)
    walk = allantools.edf_simple(n + 1, m, -2)
    assert allan.edf_white(n + 1, m) == pytest.approx(white_, rel=1e-12)
    assert allan.edf_random_walk(n + 1, m) == pytest.approx(walk, rel=1e-12)
    assert allan.edf(n, m) == pytest.approx(max(1.0, min(white_, walk)), rel=1e-12)


def test_edf_of_one_difference_is_about_one():
    """Two samples, three phase points: the random-walk form divides by N - 3 = 0 and is not
    used; two clusters of two give one difference too.  Never below 1."""
    assert allan.edf(2, 1) == pytest.approx(allan.edf_white(3, 1), rel=1e-15)
    assert 1.0 <= allan.edf(2, 1) < 1.05
    assert allan.edf(4, 2) >= 1.0
    assert allan.edf(10 ** 6, 5 * 10 ** 5) >= 1.0


def test_edf_white_matches_the_estimators_spread():
    """Seeded Monte-Carlo: 600 white series of 4096 samples at m = 64; the EDF 2 E^2 / Var of
    the Allan variance estimates within its sampling error (about 6 % at 600 runs) of NIST's
    white-noise formula, and the reported EDF (the smaller one) not above it."""
    rng = np.random.default_rng(11)
    est = np.array([allan.oadev(rng.standard_normal(4096), [64])[0][0] ** 2
                    for _ in range(600)])
    nu = 2 * est.mean() ** 2 / est.var(ddof=1)
    assert nu == pytest.approx(allan.edf_white(4097, 64), rel=0.25)
    assert allan.edf(4096, 64) <= nu * 1.25


@pytest.mark.parametrize("nu", [0.3, 1.0, 1.37, 2.0, 9.5, 100.0, 3.3e4, 1e7])
@pytest.mark.parametrize("p", [1e-9, 0.0013, 0.158655, 0.5, 0.841345, 0.9987, 1 - 1e-9])
def test_chi2_quantile_equals_scipys(nu, p):
    """To 1e-8; at 10^7 degrees of freedom to 1e-6 (ln Gamma(a) of 8e7 keeps 8 digits of
    the exponent's difference)."""
    assert allan.chi2_quantile(p, nu) == pytest.approx(scipy_stats.chi2.ppf(p, nu),
                                                       rel=1e-8 if nu < 1e5 else 1e-6)


def test_gamma_p_equals_scipys_on_both_branches():
    from scipy.special import gammainc
    for a in (0.15, 0.5, 1.0, 3.7, 50.0, 5e5):
        for x in (1e-8, 0.1 * a, 0.9 * a, a + 0.5, a + 2.0, 3.0 * a + 5.0):
            assert allan.gamma_p(a, x) == pytest.approx(gammainc(a, x), abs=1e-300,
                                                        rel=1e-11 if a < 1e3 else 1e-8)
    assert allan.gamma_p(2.0, 0.0) == 0.0


def test_gamma_p_refuses_where_its_continued_fraction_has_not_converged():
    # near x = a the fraction needs more terms the larger a is (9027 at a = 1e9); the last
    # that it may take is the 9999th: here it converges at the 9999th and at the 10000th term
    from scipy.special import gammainc
    a = 1295996276.0
    assert allan.gamma_p(a, a + 1.0) == pytest.approx(gammainc(a, a + 1.0), abs=1e-6)
    a = 1295974451.0
    with pytest.raises(ValueError, match=r"at a = 1295974451\.0, x = 1295974452\.0: the "
                                         r"continued fraction has not converged in 9999 terms"):
        allan.gamma_p(a, a + 1.0)
    # far from the median the fraction is short whatever a (the 68 % interval's quantiles)
    assert allan.gamma_p(1e11, 1e11 + 1e6) == pytest.approx(gammainc(1e11, 1e11 + 1e6),
                                                            abs=1e-4)
    assert math.isnan(allan.gamma_p(3.0, math.nan))


def test_interval_is_the_one_sigma_chi2_interval():
    p = scipy_stats.norm.cdf(1.0)  # 84.13 %
    for nu in (1.0, 4.0, 250.0):
        low, high = allan.interval(2.0, nu)
        assert low == pytest.approx(2.0 * math.sqrt(nu / scipy_stats.chi2.ppf(p, nu)), rel=1e-8)
        assert high == pytest.approx(2.0 * math.sqrt(nu / scipy_stats.chi2.ppf(1 - p, nu)),
                                     rel=1e-8)
        assert low < 2.0 < high


# -- the reading: N, K, B against the truth -------------------------------------------------------

def _close(fig, truth, extra=0.0):
    """The reported value within Z reported standard errors of ``truth`` (ln scale), plus
    ``extra`` (a known bias of the reading); two-sided."""
    assert fig["value"] is not None, fig["reason"]
    off = abs(math.log(fig["value"] / truth))
    assert off <= Z * fig["se_log"] + extra, (fig, truth, off / fig["se_log"])


def _reading_bias(reading, name, truth_avar, slope):
    """How far the reading's line lies from the truth on the exact curve: the same fixed-slope
    fit over the same tau, on the closed-form Allan deviation (the IEEE reading's own bias
    near a transition; 0 on a pure power law)."""
    grid = reading["grid"]
    fig = reading[name]
    pts = [j for j, t in enumerate(grid["tau"]) if fig["tau_from"] <= t <= fig["tau_to"]]
    w = [grid["edf"][j] for j in pts]
    level = sum(wj * (0.5 * math.log(truth_avar(grid["tau"][j])) - slope * math.log(
        grid["tau"][j])) for wj, j in zip(w, pts)) / sum(w)
    return level


def test_white_noise_reads_N_at_one_second_and_nothing_else(signals):
    r = allan.read(signals["white"], TS)
    _close(r["N"], N_TRUE)
    assert r["N"]["read_at"] == 1.0 and r["N"]["se_log"] < 0.003
    assert r["N"]["tau_from"] == 2 * TS  # the first tau with a neighbour on each side
    assert r["K"]["value"] is None and "+0.5" in r["K"]["reason"]
    assert r["B"]["value"] is None and r["B"]["reason"].startswith("no floor: the lowest read")


def test_white_and_random_walk_read_N_and_K_where_the_standard_says(signals):
    """White noise N and a random walk K crossing at tau = 1 s: N read at tau = 1 s on the
    -1/2 line, K at tau = 3 s on the +1/2 line, each within four standard errors of the truth
    plus the reading's own bias near the crossing (computed on the closed form, under 2 %)."""
    K = signals["K"]
    r = allan.read(signals["random_walk"], TS)

    def avar(tau):
        return N_TRUE ** 2 / tau + random_walk_avar(K, round(tau / TS))
    for name, truth, slope, at in (("N", N_TRUE, -0.5, 1.0), ("K", K, 0.5, 3.0)):
        level = _reading_bias(r, name, avar, slope)
        ideal = math.exp(level + slope * math.log(at)) * (math.sqrt(3.0 / at) if name == "K"
                                                          else math.sqrt(at))
        bias = abs(math.log(ideal / truth))
        assert bias < 0.02, (name, bias)
        _close(r[name], truth, extra=bias)
    assert r["N"]["tau_to"] < 1.0 < r["K"]["tau_from"]
    # the floor of the two lines, where they cross: sigma^2 = 2 N^2 / tau_c at tau_c = 1 s
    assert r["B"]["value"] is not None
    assert r["B"]["floor"] == pytest.approx(math.sqrt(2.0) * N_TRUE, rel=0.08)
    assert r["B"]["value"] == pytest.approx(r["B"]["floor"] / 0.664, rel=2e-3)


def test_flicker_band_reads_B_as_its_floor_over_0664(signals):
    r = allan.read(signals["flicker"], TS)
    fig = r["B"]

    def avar(tau):
        return flicker_avar(round(tau / TS)) + N_TRUE ** 2 / tau
    floor = math.exp(_reading_bias(r, "B", avar, 0.0))  # the exact curve's flat line there
    _close(fig, floor / allan.FLOOR)
    assert fig["floor"] == pytest.approx(fig["value"] * 0.6643, rel=1e-3)
    assert fig["tau_from"] < 5.0 and fig["tau_to"] > 30.0 and fig["points"] >= 4
    # against the band's own B: the white noise lifts the floor's short end (by 10 % at 2.6 s;
    # the exact curve above counts it)
    assert fig["value"] == pytest.approx(math.sqrt(math.pi * BAND_VAR * BAND_D), rel=0.08)
    # N: the band's short correlation times add to the white line (the reading's own bias,
    # on the exact curve)
    bias = abs(_reading_bias(r, "N", avar, -0.5) - math.log(N_TRUE))
    assert bias < 0.05
    _close(r["N"], N_TRUE, extra=bias)
    assert r["K"]["value"] is None


# -- the rules of the reading --------------------------------------------------------------------

def test_N_comes_from_the_first_white_run_not_a_later_one():
    """White noise at short tau, then a strong Gauss-Markov bias (tc = 0.25 s) whose tail past
    its hump falls as 1/sqrt(tau) again, with another density, sqrt(2 var tc) = 7.1e-3: N is
    the first run's."""
    rng = np.random.default_rng(41)
    n, Ts = 2 ** 21, 1e-3
    y = white(rng, n=n, Ts=Ts) + gauss_markov(rng, n, 0.25, 1e-4, Ts=Ts)
    r = allan.read(y, Ts)

    def avar(tau):
        return N_TRUE ** 2 / tau + gauss_markov_avar(0.25, 1e-4, round(tau / Ts), Ts=Ts)
    bias = abs(_reading_bias(r, "N", avar, -0.5) - math.log(N_TRUE))
    _close(r["N"], N_TRUE, extra=bias)
    assert r["N"]["tau_to"] < 0.05
    near = [j for j, (s, ok) in enumerate(zip(r["grid"]["slope"], r["grid"]["read"]))
            if ok and abs(s + 0.5) <= allan.SLOPE_TOL]
    later = [j for j in near if r["grid"]["tau"][j] > 2.0]
    assert len(later) >= 2  # the later -1/2 run is there, and not taken


def test_K_comes_from_the_last_random_walk_run():
    """A Gauss-Markov bias rising as sqrt(tau) at short tau (tc = 0.5 s), its hump, then a
    random walk K = 1e-3: K is the last run's."""
    rng = np.random.default_rng(42)
    n, Ts, K = 2 ** 20, 0.02, 1e-3
    y = (gauss_markov(rng, n, 0.5, 9e-6, Ts=Ts) + random_walk(rng, K, n=n, Ts=Ts)
         + white(rng, n=n, N=1e-5, Ts=Ts))
    r = allan.read(y, Ts)

    def avar(tau):
        m = round(tau / Ts)
        return (1e-10 / tau + gauss_markov_avar(0.5, 9e-6, m, Ts=Ts)
                + random_walk_avar(K, m, Ts=Ts))
    # the line of slope +1/2 through the exact curve, at tau = 3 s: e^level sqrt(3)
    bias = abs(_reading_bias(r, "K", avar, 0.5) + 0.5 * math.log(3.0) - math.log(K))
    assert bias < 0.05
    _close(r["K"], K, extra=bias)
    assert r["K"]["tau_from"] > 10.0
    rising = [j for j, (s, ok) in enumerate(zip(r["grid"]["slope"], r["grid"]["read"]))
              if ok and abs(s - 0.5) <= allan.SLOPE_TOL]
    assert r["grid"]["tau"][rising[0]] < 0.2  # the earlier +1/2 run is there, and not taken


def test_too_few_samples_resolve_nothing_and_say_why():
    """A tau is read when it and both neighbours have 100 EDF or more: 409 samples at least
    (m = 4's random-walk EDF, about n / 4, decides); with fewer every figure is not resolved,
    and the reason says how many are needed."""
    least = allan.least_samples()
    assert least == 409
    rng = np.random.default_rng(5)
    for n in (2, 3, 100, least - 1):
        r = allan.read(white(rng, n=n), TS)
        assert not any(r["grid"]["read"])
        for name in "NBK":
            assert r[name]["value"] is None, (n, r[name])
            assert r[name]["reason"] == (
                "no tau with both neighbours and each of the three with at least 100 EDF (%d "
                "samples: at least %d needed)" % (n, least))
    assert allan.read(white(rng, n=least), TS)["grid"]["read"][1]
    assert allan.read(white(rng, n=4000), TS)["N"]["value"] is not None


def test_a_single_white_octave_is_not_a_run():
    """A white line needs two consecutive read tau; with exactly one read tau near -1/2 the
    figure is not resolved."""
    taus = [TS * 2 ** j for j in range(6)]
    flags = [False, True, False, True, True, False]
    assert allan._runs(flags) == [(1, 1), (3, 4)]
    assert allan._runs([True]) == [(0, 0)] and allan._runs([]) == []


def test_a_figure_is_read_from_edf_rich_tau_only(monkeypatch):
    """With the least EDF raised above what the data have, nothing is read."""
    rng = np.random.default_rng(6)
    y = white(rng, n=2 ** 14)
    assert allan.read(y, TS)["N"]["value"] is not None
    monkeypatch.setattr(allan, "EDF_MIN", 1e6)
    assert allan.read(y, TS)["N"]["value"] is None


def test_local_slopes_are_central_log_log_differences():
    taus = [1.0, 2.0, 4.0, 8.0]
    adevs = [1.0, 1.0 / math.sqrt(2.0), 0.5, 0.5]
    s = allan.local_slopes(taus, adevs)
    assert s[0] is None and s[-1] is None
    assert s[1] == pytest.approx(-0.5, abs=1e-15)
    assert s[2] == pytest.approx(math.log(0.5 / (1 / math.sqrt(2.0))) / math.log(4.0),
                                 abs=1e-15)


def test_a_constant_signal_resolves_nothing_and_does_not_fail():
    """A constant (a sensor at rest with its noise off) has Allan deviation 0 everywhere: no
    slope, no figure, no division by zero."""
    r = allan.read(np.full(5000, 0.25), TS)
    assert set(r["grid"]["adev"]) == {0.0} and not any(r["grid"]["read"])
    assert all(r[k]["value"] is None for k in "NBK")
    assert allan.local_slopes([1.0, 2.0, 4.0], [1.0, 0.0, 0.0]) == [None, None, None]


@pytest.mark.parametrize("nu", [1.5, 10.0, 250.0])
@pytest.mark.parametrize("p", [0.025, 0.5, 0.975])
def test_chi2_quantile_stops_when_newton_has_converged(monkeypatch, nu, p):
    """The quantile's iteration stops once a step no longer moves it (Newton's quadratic
    convergence: a handful of evaluations), not after its 200-iteration bound, and gives SciPy's
    value."""
    scipy_stats = pytest.importorskip("scipy.stats")
    calls = []
    gamma_p = allan.gamma_p

    def counted(a, x):
        calls.append(x)
        return gamma_p(a, x)
    monkeypatch.setattr(allan, "gamma_p", counted)
    q = allan.chi2_quantile(p, nu)
    assert q == pytest.approx(scipy_stats.chi2.ppf(p, nu), rel=1e-9)
    assert len(calls) <= 40, len(calls)
