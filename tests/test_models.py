"""models/: closed forms first, then agreement between the float and array paths, then seeded
statistics with tolerances derived from the sample size."""
import math

import numpy as np
import pytest

from driftfmu.models import _ops, chain, drift, ekf, excitation, noise, parameters, sensor


# -- arithmetic-only special functions --------------------------------------------------------
def test_log_matches_libm_to_a_few_ulp():
    xs = np.random.default_rng(0).uniform(1e-300, 1.0, 5000)
    for x in xs:
        got, want = _ops.log(float(x)), math.log(x)
        assert abs(got - want) <= 4 * math.ulp(want)


def test_sin2pi_matches_libm():
    cs = np.random.default_rng(1).uniform(-3.0, 3.0, 5000)
    for c in cs:
        assert abs(_ops.sin2pi(float(c)) - math.sin(2 * math.pi * c)) < 1e-14


@pytest.mark.parametrize("exp", [_ops.exp, _ops.exp_estrin])
def test_exp_matches_libm_to_a_few_ulp(exp):
    # Horner's and Estrin's evaluation of the same polynomial: each within 2 ulp of libm's
    xs = np.concatenate([np.random.default_rng(3).uniform(-708.0, 709.0, 5000),
                         np.random.default_rng(4).uniform(-1.0, 1.0, 5000),
                         -np.random.default_rng(6).exponential(2.0, 5000)])  # (the exposure's)
    for x in xs:
        got, want = exp(float(x)), math.exp(x)
        assert abs(got - want) <= 2 * math.ulp(want), (x, got, want)
    assert (exp(0.0), exp(800.0), exp(-800.0)) == (1.0, math.inf, 0.0)
    assert math.isnan(exp(math.nan))


def test_exp_estrin_is_estrins_scheme_of_exps_polynomial():
    # the same reduction and coefficients as _ops.exp, the terms grouped as Estrin's scheme
    # does, written here from its definition (pairs c_k + c_(k+1) r, then joined by r^2, r^4,
    # r^8), not from _ops; and it is not Horner's: many results differ from exp's in a bit
    c = [1.0 / math.factorial(k) for k in range(15)]
    xs = np.random.default_rng(7).uniform(-700.0, 700.0, 4000)
    differ = 0
    for x in map(float, xs):
        m = math.floor(x * _ops.INV_LN2 + 0.5)
        r = (x - m * _ops.LN2_HI) - m * _ops.LN2_LO
        pairs = [c[k] + c[k + 1] * r for k in range(0, 14, 2)] + [c[14]]
        r2 = r * r
        quads = [pairs[j] + pairs[j + 1] * r2 for j in range(0, 8, 2)]
        r4 = r2 * r2
        octs = [quads[0] + quads[1] * r4, quads[2] + quads[3] * r4]
        want = math.ldexp(octs[0] + octs[1] * (r4 * r4), m)
        assert _ops.exp_estrin(x) == want, x
        differ += _ops.exp(x) != want
    assert differ > 400, differ


@pytest.mark.parametrize("fn", [_ops.log, _ops.sin2pi, _ops.exp, _ops.exp_estrin])
def test_special_functions_same_bits_on_floats_and_arrays(fn):
    xs = np.random.default_rng(2).uniform(1e-6, 0.999, 2000)
    assert np.array_equal(fn(xs), np.array([fn(float(x)) for x in xs]))


@pytest.mark.parametrize("fn", [_ops.floor, _ops.sin2pi, _ops.sin])
def test_floor_and_sine_same_bits_on_floats_and_arrays_at_the_signed_zeros(fn):
    """The sign of a zero too: floor(-0.0) is 0.0 and sin(-0.0) is -0.0 on both paths (the C
    twins' ``ops_floor`` and ``ops_sin``), and the values around them keep their bits."""
    xs = np.array([-0.0, 0.0, -5e-324, 5e-324, -1e-300, 1e-300, -0.5, 0.5, -1.0, 1.0,
                   -0.9999999999999999, 0.9999999999999999, -7.0, 7.0, np.inf, -np.inf])
    with np.errstate(invalid="ignore"):  # (sin of inf: inf - inf, nan on both paths)
        got = fn(xs)
    want = np.array([fn(float(x)) for x in xs])
    finite = np.isfinite(want)
    assert np.array_equal(np.isfinite(got), finite)
    assert np.array_equal(got[finite].view(np.uint64), want[finite].view(np.uint64)), \
        [(x, a, b) for x, a, b in zip(xs, got, want) if a.tobytes() != b.tobytes()]
    # the C twins' values at -0.0: ops_floor(-0.0) is 0.0, ops_sin(-0.0) is -0.0
    assert math.copysign(1.0, got[0]) == (1.0 if fn is _ops.floor else -1.0)


def test_floor_of_a_float_is_a_float():
    """As its docstring says: a Python float (the FMUs' path stays in plain floats), not a
    NumPy scalar; -0.0's floor 0.0, inf and nan their own."""
    for x, want in ((2.5, 2.0), (-2.5, -3.0), (-0.0, 0.0), (1e300, 1e300), (-5e-324, -1.0),
                    (math.inf, math.inf)):
        got = _ops.floor(x)
        assert type(got) is float and got == want and math.copysign(1.0, got) == \
            math.copysign(1.0, want), (x, got)
    assert type(_ops.floor(math.nan)) is float and math.isnan(_ops.floor(math.nan))


@pytest.mark.parametrize("exp", [_ops.exp, _ops.exp_estrin])
def test_exp_same_bits_on_floats_and_arrays_over_its_whole_range(exp):
    xs = np.concatenate([np.random.default_rng(5).uniform(-760.0, 720.0, 3000),
                         [0.0, -0.0, _ops.EXP_HIGH, _ops.EXP_LOW, 1e4, -1e4, np.inf, -np.inf,
                          np.nextafter(_ops.EXP_HIGH, np.inf), np.nextafter(_ops.EXP_LOW, -np.inf)]])
    got = exp(xs)
    assert np.array_equal(got.view(np.uint64),
                          np.array([exp(float(x)) for x in xs]).view(np.uint64))
    assert np.isnan(exp(np.array([np.nan, 1.0])))[0]


# -- noise ------------------------------------------------------------------------------------
def test_noise_is_a_pure_function_of_seed_stream_and_index():
    a = [noise.normal(5, noise.STREAM_PROCESS, k) for k in range(1, 100)]
    b = [noise.normal(5, noise.STREAM_PROCESS, k) for k in range(1, 100)]
    assert a == b
    assert a != [noise.normal(6, noise.STREAM_PROCESS, k) for k in range(1, 100)]
    assert a != [noise.normal(5, noise.STREAM_MEASUREMENT, k) for k in range(1, 100)]


def test_noise_same_bits_for_scalars_and_batches():
    k = np.arange(1, 3001, dtype=np.uint64)
    seeds = np.array([0, 1, 2 ** 31 - 1], dtype=np.uint64)
    batch = noise.normal(seeds[:, None], noise.STREAM_MEASUREMENT, k[None, :])
    for i, s in enumerate((0, 1, 2 ** 31 - 1)):
        single = [noise.normal(s, noise.STREAM_MEASUREMENT, int(j)) for j in k]
        assert np.array_equal(batch[i], single)


@pytest.mark.parametrize("p", [1e-9, 0.01, 0.3, 0.5, 0.99, 1.0 - 1e-9])
def test_inverse_normal_cdf_of_a_numpy_scalar_is_the_floats(p):
    # a value read out of an array (numpy.float64) takes the float path: the same bits, a
    # scalar back (the array path would index it)
    got = noise.inverse_normal_cdf(np.float64(p))
    assert np.ndim(got) == 0 and float(got) == noise.inverse_normal_cdf(p)


@pytest.mark.parametrize("which", ["both tails and centre", "lower tail only", "upper tail only",
                                   "centre only", "tails only"])
def test_inverse_normal_cdf_same_bits_on_arrays_at_and_around_the_tail_bounds(which):
    # the array path takes both tails in one pass (the upper at 1 - p, negated): each value as
    # the float path gives it, the bounds P_LOW and 1 - P_LOW and their neighbours included
    lo, hi = noise.P_LOW, 1.0 - noise.P_LOW
    near = lambda b: [np.nextafter(b, 0.0), b, np.nextafter(b, 1.0)]
    parts = {"lower": [1e-16, 1e-9, 0.001, 0.02] + near(lo)[:1],
             "upper": [0.98, 0.999, 1.0 - 1e-9, 1.0 - 2.0 ** -52] + near(hi)[2:],
             "centre": [0.5, 0.3, 0.7] + near(lo)[1:] + near(hi)[:2]}
    keys = {"both tails and centre": ("lower", "centre", "upper"), "lower tail only":
            ("lower",), "upper tail only": ("upper",), "centre only": ("centre",),
            "tails only": ("upper", "lower")}[which]
    p = np.array([q for key in keys for q in parts[key]])
    got = noise.inverse_normal_cdf(p.copy())
    want = np.array([noise.inverse_normal_cdf(float(q)) for q in p])
    assert got.tobytes() == want.tobytes(), (p, got, want)
    assert (np.sign(got[p < 0.5]) <= 0).all() and (np.sign(got[p > 0.5]) >= 0).all()


def test_normal_moments_within_sampling_error():
    n = 400_000
    v = noise.normal(np.uint64(3) + np.zeros(1, dtype=np.uint64), 1,
                     np.arange(1, n + 1, dtype=np.uint64))
    # 5-sigma bands of the sample mean, variance and kurtosis of N(0, 1) for n draws
    assert abs(v.mean()) < 5 / math.sqrt(n)
    assert abs(v.var() - 1.0) < 5 * math.sqrt(2.0 / n)
    assert abs((v ** 4).mean() - 3.0) < 5 * math.sqrt(96.0 / n)


def test_normal_distribution_passes_ks_at_fixed_seed():
    from scipy import stats
    n = 100_000
    v = noise.normal(np.zeros(1, dtype=np.uint64), 2, np.arange(1, n + 1, dtype=np.uint64))
    d = stats.kstest(v, "norm").statistic
    assert d < 1.63 / math.sqrt(n)  # 1 % critical value of the KS statistic


def test_inverse_normal_cdf_accuracy():
    from scipy import stats
    p = np.concatenate([np.logspace(-15, -1, 200), np.linspace(0.01, 0.99, 200)])
    got = np.array([noise.inverse_normal_cdf(float(q)) for q in p])
    assert np.allclose(got, stats.norm.ppf(p), rtol=1.2e-9, atol=0)


# -- sensor, EKF, drift estimators: closed forms ----------------------------------------------
def test_sensor_characteristic_and_slope():
    assert sensor.h(0.5, 0.1, 2.0, 0.3) == pytest.approx(0.1 + 1.0 + 0.075)
    assert sensor.dh_dx(0.5, 2.0, 0.3) == pytest.approx(2.3)
    assert sensor.measure(0.5, 0.1, 2.0, 0.3, 0.04, 1.5) == pytest.approx(1.175 + 0.3)


def test_joseph_form_equals_standard_form_for_the_optimal_gain():
    for x_pred, P_pred, a2 in [(0.3, 0.02, 0.01), (-1.0, 0.5, 0.2), (0.0, 1e-3, 0.0)]:
        x, P = ekf.update(x_pred, P_pred, 0.1, 0.0, 1.0, a2, 1e-4)
        H = 1.0 + 2 * a2 * x_pred
        K = P_pred * H / (H * H * P_pred + 1e-4)
        assert P == pytest.approx((1 - K * H) * P_pred, rel=1e-12)


def test_linear_sensor_white_state_posterior_variance_closed_form():
    # a2 = 0, A = 0: P- = Q every step, so P+ = Q R / (a1^2 Q + R) exactly
    a1, Q, R = 2.0, 0.01, 1e-3
    x, P = 0.0, 5.0
    for z in (0.1, -0.3, 0.2):
        x, P = ekf.step(x, P, z, 0.0, a1, 0.0, 0.0, Q, R)
        assert P == pytest.approx(Q * R / (a1 * a1 * Q + R), rel=1e-14)


def test_drift_estimators_follow_the_letters_recursions():
    xs, Ps, a2 = [0.1, -0.2, 0.4], [0.01, 0.02, 0.03], 0.5
    st = drift.initial_state()
    for x, P in zip(xs, Ps):
        st = drift.update(st, x, P, a2)
    dc1, dc2, dc3 = drift.estimates(st, a2)
    x2 = [x * x for x in xs]
    assert dc1 == pytest.approx(a2 * sum(x + p for x, p in zip(x2, Ps)) / 3)
    assert dc2 == pytest.approx(a2 * sum(x2) / 3)
    s3 = [x2[0], (x2[0] + x2[1]) / 2, sum(x2) / 3]
    assert dc3 == pytest.approx(a2 * sum(s3) / 3)
    assert dc1 - dc2 == pytest.approx(a2 * sum(Ps) / 3)  # EKF2 is low by a2 mean(P)


def test_expected_gap_at_the_letters_settings():
    assert drift.expected_gap_db(1.0, 0.01, 1e-4) == pytest.approx(0.0432, abs=1e-4)


def test_stationary_variance():
    assert excitation.stationary_variance(excitation.GAUSSIAN, A=0.5, Q=0.03) == pytest.approx(0.04)
    assert excitation.stationary_variance(excitation.SINUSOIDAL, X=2.0) == 2.0
    with pytest.raises(ValueError, match="kind"):
        excitation.stationary_variance(7)


# -- the chain --------------------------------------------------------------------------------
def test_chain_batch_equals_single_runs_bit_for_bit():
    seeds = np.array([1, 2, 9], dtype=np.uint64)
    for kind in (excitation.GAUSSIAN, excitation.SINUSOIDAL):
        batch = chain.simulate(120, seeds, kind=kind, A=0.3, f=40.0)
        for i, s in enumerate((1, 2, 9)):
            one = chain.simulate(120, s, kind=kind, A=0.3, f=40.0)
            for c in chain.COLUMNS:
                assert np.array_equal(batch[c][i], np.asarray(one[c], dtype=float)), c


def test_letters_claims_hold_for_the_default_seed():
    r = chain.simulate(2000, 1)
    gap = drift.gap_db(r["dc_ekf1"][-1], r["dc_ekf2"][-1])
    assert gap == pytest.approx(drift.expected_gap_db(1.0, 0.01, 1e-4), rel=0.10)
    band = [abs(e - ref) <= 0.1 * ref for e, ref in zip(r["dc_ekf1"], r["dc_realised"])]
    assert all(band[249:])


def test_ekf1_is_unbiased_over_seeds():
    # mean of EKF1 / realised drift over runs: its spread shrinks as 1/sqrt(runs)
    seeds = np.arange(100, 300, dtype=np.uint64)
    r = chain.simulate(500, seeds)
    ratio = r["dc_ekf1"][:, -1] / r["dc_realised"][:, -1]
    assert abs(ratio.mean() - 1.0) < 5 * ratio.std() / math.sqrt(len(seeds))


# -- parameters -------------------------------------------------------------------------------
@pytest.mark.parametrize("name,value,text", [
    ("R", 0.0, "R = 0.0 is out of range; allowed: R > 0"),
    ("Q", -1.0, "Q = -1.0 is out of range; allowed: Q >= 0"),
    ("A", 1.0, "allowed: A > -1 and A < 1"),
    ("a1", 0.0, "allowed: a1 != 0"),
    ("a2", float("nan"), "a2 = nan is not finite; allowed: any finite value"),
    ("n", 2.5, "n = 2.5 is not an integer; allowed: an integer n >= 1"),
    # (issue 31: "allowed: drive >= 0 and drive <= 2" was said of 1.5, which is within it)
    ("drive", 1.5, "drive = 1.5 is not an integer; allowed: an integer drive >= 0 and drive <= 2"),
    # a wrong type is called one, in range or not (not "out of range")
    ("seed", 1.5, "seed = 1.5 is not an integer; allowed: an integer seed >= 0 and seed <= "
                  "2147483647"),
    ("seed", -1.5, "seed = -1.5 is not an integer; allowed: an integer seed >= 0 and seed <= "
                   "2147483647"),
    ("seed", "x", "seed = 'x' is not a number"),
])
def test_parameter_problems_name_value_and_range(name, value, text):
    assert text in parameters.problem(name, value)


def test_good_parameters_have_no_problem():
    assert parameters.check(parameters.defaults(*parameters.PARAMETERS)) == []


@pytest.mark.parametrize("exp", [_ops.exp, _ops.exp_estrin])
def test_exp_of_an_array_out_of_its_range_warns_of_nothing(exp):
    # the values out of the range (inf, nan, beyond EXP_HIGH and EXP_LOW) are set aside before
    # the reduction, whose inf - inf would be NumPy's "invalid value" warning
    import warnings
    x = np.array([np.inf, -np.inf, np.nan, 1e4, -1e4, _ops.EXP_HIGH + 1.0, 0.5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        y = exp(x)
    assert y[:2].tolist() == [math.inf, 0.0] and math.isnan(y[2])
    assert y[3:6].tolist() == [math.inf, 0.0, math.inf] and y[6] == exp(0.5)


@pytest.mark.parametrize("exp", [_ops.exp, _ops.exp_estrin])
def test_exp_of_an_int_or_a_numpy_scalar_is_the_floats(exp):
    """_ops.exp and exp_estrin take their general path for an int and a NumPy float64 (not type
    float): the same value as the float's, out of the range too."""
    for x in (1, -3, 0, 0.3, -2.7, 800, -800):
        assert exp(x) == exp(float(x)) == exp(np.float64(x)), x
    assert exp(np.float64(0.5)) == exp(0.5) == pytest.approx(math.exp(0.5), rel=1e-15)
