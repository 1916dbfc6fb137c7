"""The sensor's slow errors (models/errors.py, issue 42): the letter's drift classes 2 to 4 and
the measurement range, each against evidence of its own.

Strongest first: closed forms (the exact discretisations, the exposure of a sinusoid, the tilt
and temperature by hand, the range and ADC), then independent implementations (imu-error-model's
coefficients, flicker components and covariances driven with the same parameters; allantools'
overlapping Allan deviation), then seeded statistics with two-sided tolerances derived from the
number of independent values each estimate averages.  The Accelerometer FMU computes its output
with these very functions (tests/test_errors_fmu.py shows the bits equal), so the series here
are the FMU's output.
"""
import array
import itertools
import math
import random

import numpy as np
import pytest

from driftfmu.models import _ops, adxl203, chain, errors, excitation, noise, parameters, sensor

allantools = pytest.importorskip("allantools", reason="allantools (dev extra) computes the "
                                 "independent Allan deviation")
imu = pytest.importorskip("imu_error_model", reason="imu-error-model (dev extra, Python >= "
                          "3.11) is the independent reference of the processes' statistics")
from imu_error_model import AxisConfig, ImuConfig, characterize_imu_error_process  # noqa: E402
from imu_error_model.processes import (flicker_component_parameters,  # noqa: E402
                                       gauss_markov_parameters)

EPS = 2.0 ** -52
#: Two-sided bound, in standard errors, of every statistical comparison (fixed seeds: a run
#: either passes or fails; over ten other seed offsets the worst Allan deviation seen was 2.6).
Z = 5.0


# -- helpers -----------------------------------------------------------------------------------

def sensor_errors(seeds, Ts, a0=0.0, a1=1.0, a2=0.0, R=1e-4, **values):
    return chain.SensorErrors(seeds, a0, a1, a2, R, 0.0, 0.0, Ts, values)


def series(n, runs, Ts, seed0=1, noise_on=False, x=0.0, **values):
    """``z`` of ``runs`` runs (seeds ``seed0 ..``) of ``n`` samples of the first axis with
    ``x`` held (0: the output is the errors alone, a0 = a2 = 0, a1 = 1), the draws in blocks as
    the FMU's: an array ``(runs, n)``."""
    seeds = np.arange(seed0, seed0 + runs, dtype=np.uint64)
    se = sensor_errors(seeds, Ts, **values)
    e = se.ecfg
    out = np.empty((runs, n))
    row = seeds[None, :]
    for k0 in range(1, n + 1, 1024):
        ks = np.arange(k0, min(k0 + 1024, n + 1), dtype=np.uint64)[:, None]
        zero = np.zeros((len(ks), 1))
        n_rw = noise.ziggurat(row, noise.STREAM_RANDOM_WALK, ks) if e.rw else zero
        n_gm = noise.ziggurat(row, noise.STREAM_BIAS_GM, ks) if e.gm_sigma else zero
        n_fl = [noise.ziggurat(row, noise.STREAM_FLICKER + i, ks) for i in range(e.fl_n)]
        v = noise.normal(row, noise.STREAM_MEASUREMENT, ks) if noise_on else zero
        for i in range(len(ks)):
            out[:, k0 + i - 1] = se.measure(x, v[i], k0 + i,
                                            (n_rw[i], n_gm[i], tuple(f[i] for f in n_fl)))
    return out


def overlapping_avar(y, Ts, m):
    """Overlapping Allan variance of rate data ``y`` at ``tau = m Ts`` (IEEE 952), written out."""
    x = np.concatenate(([0.0], np.cumsum(y))) * Ts
    d = x[2 * m:] - 2.0 * x[m:-m] + x[:-2 * m]
    return np.sum(d * d) / (2.0 * (m * Ts) ** 2 * d.size)


def allan(data, Ts, ms):
    """The Allan variance of every ``m`` over the runs (the mean of each run's, allantools'
    ``oadev``), checked against the overlapping estimator written out above."""
    out = []
    for m in ms:
        per_run = []
        for y in data:
            _, dev, _, _ = allantools.oadev(y, rate=1.0 / Ts, data_type="freq",
                                            taus=np.array([m * Ts]))
            per_run.append(dev[0] ** 2)
        out.append(np.mean(per_run))
        assert per_run[0] == pytest.approx(overlapping_avar(data[0], Ts, m), rel=1e-9)
    return np.array(out)


def tolerance(runs, n, m):
    """The two-sided bound of an Allan deviation from ``runs`` runs of ``n`` samples at ``m``:
    Z standard errors of an estimate over ``K = runs (n/m - 1)`` cluster differences,
    ``1 / sqrt(2 K)`` (IEEE Std 952, annex C)."""
    return Z / math.sqrt(2.0 * runs * (n / m - 1.0))


def avar_white(var, m):
    """Exact Allan variance of white samples of variance ``var`` at ``m`` samples."""
    return var / m


def avar_random_walk(q, m):
    """Exact Allan variance of a discrete random walk with increments of variance ``q``:
    ``q (2 m^2 + 1) / (6 m)`` (``K^2 tau / 3`` for large ``m``)."""
    return q * (2.0 * m * m + 1.0) / (6.0 * m)


def avar_gauss_markov(var, a, m):
    """Exact Allan variance of ``b_k = a b_{k-1} + w_k`` (stationary ``var``) at ``m`` samples:
    the variance of an ``m``-average less the covariance of two adjacent ones, from the
    autocovariance ``var a^|d|``."""
    d = np.arange(1, 2 * m, dtype=float)
    lags = np.arange(1, m, dtype=float)
    var_mean = var / m ** 2 * (m + 2.0 * np.sum((m - lags) * a ** lags))
    cov = var / m ** 2 * np.sum(np.where(d <= m, d, 2 * m - d) * a ** d)
    return var_mean - cov


def continuous_avar_gauss_markov(var, tau, T):
    """The textbook continuous-time curve (written independently of models.errors)."""
    r = T / tau
    return var * tau / T * (2.0 - tau / T * (3.0 - 4.0 * math.exp(-r) + math.exp(-2.0 * r)))


def flicker_reference(flicker, tau_min, tau_max, Ts):
    """imu-error-model's flicker components for the same parameters (``M`` one per decade):
    their correlation times, standard deviations and exact ``a = exp(-Ts/tau)``."""
    m = 1 + math.ceil(math.log10(tau_max / tau_min) - 1e-9)
    cfg = AxisConfig(flicker_bias_std=flicker, flicker_min_correlation_time=tau_min,
                     flicker_max_correlation_time=tau_max, flicker_components=m)
    taus, stds = flicker_component_parameters(cfg)
    return taus, stds, np.exp(-Ts / taus)


def decimal_flicker_sigma(flicker, taus):
    """``sigma_c`` of every component from 40-digit arithmetic: ``flicker`` over the Allan
    deviation at the band's centre of unit components, ``(2 r - 3 + 4 e^-r - e^-2r) / r^2``."""
    from decimal import Decimal, localcontext
    with localcontext() as ctx:
        ctx.prec = 40
        centre = (Decimal(taus[0]) * Decimal(taus[-1])).sqrt()
        total = Decimal(0)
        for tau in taus:
            r = centre / Decimal(tau)
            total += (2 * r - 3 + 4 * (-r).exp() - (-2 * r).exp()) / (r * r)
        return float(Decimal(flicker) / total.sqrt())


def decimal_allan_deviation(sigma, taus, T):
    """The Allan deviation at ``T`` of the sum of continuous-time Gauss-Markov components of
    standard deviation ``sigma`` and correlation times ``taus``, in 40-digit arithmetic."""
    from decimal import Decimal, localcontext
    with localcontext() as ctx:
        ctx.prec = 40
        total = Decimal(0)
        for tau in taus:
            r = Decimal(T) / Decimal(float(tau))
            total += (2 * r - 3 + 4 * (-r).exp() - (-2 * r).exp()) / (r * r)
        return float((total * Decimal(sigma) ** 2).sqrt())


# -- off means off ------------------------------------------------------------------------------

def test_every_term_off_by_default_and_given_explicitly_keeps_the_letters_bits():
    ecfg = errors.config()
    assert not ecfg.on and ecfg.fl_n == 0
    plain = chain.simulate(400, 3, A=0.4, a3=0.01)
    given = chain.simulate(400, 3, A=0.4, a3=0.01, **chain.SENSOR_ERRORS_OFF)
    for col in plain:
        assert np.asarray(plain[col]).tobytes() == np.asarray(given[col]).tobytes(), col
    for name, off in errors.OFF.items():
        assert parameters.PARAMETERS[name].default == off, name
    for name, start in errors.INPUTS.items():
        assert parameters.PARAMETERS[name].default == start, name


def test_each_term_on_moves_the_output():
    """(so that the test above cannot pass by ignoring the parameters)"""
    base = chain.simulate(50, 3)["z"]
    for values in (dict(bias_on=0.1), dict(random_walk=0.1), dict(bias_gm=0.1),
                   dict(flicker=0.1), dict(d_inf=0.1), dict(theta=0.1),
                   dict(T=300.0, kT_bias=0.01), dict(T=300.0, kT_scale=0.01),
                   dict(range=0.05), dict(bits=8, range=2.0)):
        z = chain.simulate(50, 3, **values)["z"]
        assert z != base, values


def test_turning_one_process_on_changes_no_other_draw():
    """Each process has its own stream: the Gauss-Markov state, the walk and the flicker
    components have the same bits whichever other terms are on."""
    seeds = np.arange(1, 9, dtype=np.uint64)
    alone = {name: sensor_errors(seeds, 0.01, **values) for name, values in (
        ("rw", dict(random_walk=0.1)), ("gm", dict(bias_gm=0.1)), ("fl", dict(flicker=0.1)))}
    both = sensor_errors(seeds, 0.01, random_walk=0.1, bias_gm=0.1, flicker=0.1, bias_on=0.3,
                         d_inf=0.2, R=1e-4)
    for k in range(1, 200):
        for se in list(alone.values()) + [both]:
            se.measure(0.3, 0.0, k)
        assert both.state.rw.tobytes() == alone["rw"].state.rw.tobytes()
        assert both.state.gm.tobytes() == alone["gm"].state.gm.tobytes()
        for a, b in zip(both.state.fl, alone["fl"].state.fl):
            assert a.tobytes() == b.tobytes()


# -- the exact discretisations against imu-error-model and by hand --------------------------------

@pytest.mark.parametrize("sigma, tau, Ts", [(0.1, 1.0, 0.01), (2.0, 0.003, 0.001),
                                            (1e-3, 1e4, 1e-3), (0.5, 0.5, 1.0)])
def test_gauss_markov_coefficients_are_the_exact_discretisation(sigma, tau, Ts):
    a, c = errors.gauss_markov_coefficients(sigma, tau, Ts)
    phi, innovation = gauss_markov_parameters(sigma, tau, Ts)
    assert a == pytest.approx(phi, rel=4 * EPS)
    assert a == pytest.approx(math.exp(-Ts / tau), rel=4 * EPS)
    # 1 - exp(-2 Ts/tau) loses relative precision as Ts/tau shrinks (imu-error-model: expm1)
    assert c * c == pytest.approx(innovation, rel=8 * EPS / (1.0 - math.exp(-2.0 * Ts / tau)))
    # stationary: a^2 sigma^2 + c^2 = sigma^2
    assert a * a * sigma * sigma + c * c == pytest.approx(sigma * sigma, rel=1e-12)


@pytest.mark.parametrize("tau_min, tau_max", [(0.1, 100.0), (1.0, 1000.0), (0.01, 10.0),
                                              (0.5, 2.0), (1e-3, 1e4), (0.2, 0.2000001)])
def test_flicker_components_equal_imu_error_models_for_the_same_parameters(tau_min, tau_max):
    taus, stds, _ = flicker_reference(0.02, tau_min, tau_max, 0.01)
    ours = errors.flicker_taus(tau_min, tau_max)
    assert len(ours) == len(taus) == max(2, 1 + math.ceil(math.log10(tau_max / tau_min) - 1e-9))
    assert ours[0] == tau_min and ours[-1] == tau_max
    assert np.allclose(ours, taus, rtol=1e-13, atol=0.0)
    ecfg = errors.config(Ts=0.01, flicker=0.02, tau_min=tau_min, tau_max=tau_max)
    assert ecfg.fl_n == len(taus)
    # ours sums the series where the curve's terms cancel: against 40-digit arithmetic
    assert ecfg.fl_sigma == pytest.approx(decimal_flicker_sigma(0.02, ours), rel=1e-14)
    # imu-error-model evaluates each component's curve as written: 1 - exp(-r) rounds by eps
    # and its term (1 - e^-r) / r^2 of about 1 / r, so a component of r = T / tau < 1 carries
    # an error of eps / r^2 (2e-9 at r = 3e-4, a band of 7 decades): the two agree within it
    rounding = sum(EPS / min(1.0, math.sqrt(tau_min * tau_max) / t) ** 2 for t in taus)
    assert ecfg.fl_sigma == pytest.approx(stds[0], rel=1e-12 + 10 * rounding)
    for a, c, tau in zip(ecfg.fl_a, ecfg.fl_c, taus):
        assert a == pytest.approx(math.exp(-0.01 / tau), rel=4 * EPS)
        assert a * a * ecfg.fl_sigma ** 2 + c * c == pytest.approx(ecfg.fl_sigma ** 2, rel=1e-9)


def test_the_flicker_band_is_flat_in_allan_deviation_at_the_flicker_level():
    """The closed form of the sum (each component's continuous-time curve, written here): equal
    to ``flicker`` at the band's centre, within 3 % of it from 10 tau_min to tau_max / 10, and
    falling off outside, like white noise below and a bounded bias above."""
    for tau_min, tau_max in ((0.1, 100.0), (1.0, 1e5), (0.01, 1e5)):
        taus = np.geomspace(tau_min, tau_max, 1 + math.ceil(math.log10(tau_max / tau_min)))
        sigma = errors.config(flicker=1.0, tau_min=tau_min, tau_max=tau_max).fl_sigma
        curve = lambda T: decimal_allan_deviation(sigma, taus, T)
        centre = math.sqrt(tau_min * tau_max)
        assert curve(centre) == pytest.approx(1.0, rel=1e-13)
        inside = np.geomspace(10 * tau_min, tau_max / 10, 60)
        assert all(abs(curve(T) - 1.0) <= 0.03 for T in inside)
        assert curve(tau_min / 100) < 0.9 and curve(tau_max * 100) < 0.5
        # IEEE 952's bias instability from the floor
        assert errors.FLICKER_FLOOR == pytest.approx(math.sqrt(2.0 * math.log(2.0) / math.pi),
                                                     rel=1e-15)


def test_exposure_drift_equals_its_closed_form_for_a_sinusoidal_state():
    """``x_k = X sin(2 pi f t_k + phi)``: ``E_k = Ts X^2 (k/2 - sin(k w) cos(2 phi + (k-1) w) /
    (2 sin w))``, ``w = 2 pi f Ts``, and ``d_k = d_inf (1 - exp(-E_k / E_tau))``; the output
    is ``h(x_k) + d_k``, and the offset never recovers once the shaking stops."""
    X, f, phi, Ts, d_inf, E_tau = 1.3, 37.0, 0.4, 1e-3, 0.05, 0.8
    a0, a1, a2 = 0.2, 1.1, 0.03
    se = sensor_errors(1, Ts, a0=a0, a1=a1, a2=a2, d_inf=d_inf, E_tau=E_tau)
    w = 2.0 * math.pi * f * Ts
    last = None
    for k in range(1, 4001):
        x = excitation.sine(k, X, f, Ts, phi)
        z = se.measure(x, 0.0, k)
        E = Ts * X * X * (k / 2.0 - math.sin(k * w) * math.cos(2.0 * phi + (k - 1) * w)
                          / (2.0 * math.sin(w)))
        assert se.state.E == pytest.approx(E, rel=8 * k * EPS), k
        d = d_inf * (1.0 - math.exp(-E / E_tau))
        assert z - sensor.h(x, a0, a1, a2) == pytest.approx(d, rel=1e-10, abs=4 * EPS * 2), k
        last = d
    assert last == pytest.approx(d_inf * (1.0 - math.exp(-Ts * X * X * 2000.0 / E_tau)),
                                 rel=1e-3)
    held = [se.measure(0.0, 0.0, k) - a0 for k in range(4001, 4101)]
    assert held == [held[0]] * 100 and held[0] == pytest.approx(last, rel=1e-12)


def test_the_exposure_is_of_the_true_acceleration_not_of_the_tilted_or_scaled_reading():
    """A sensor at rest tilted by 30 degrees and off its reference temperature reads 0.5 g but
    gains no exposure; shaken, it gains that of x alone (the letter's state)."""
    Ts = 1e-3
    se = sensor_errors(1, Ts, d_inf=0.05, E_tau=0.1, kT_scale=0.01, T0=290.0, theta=math.pi / 6,
                       T=300.0)
    for k in range(1, 101):
        z = se.measure(0.0, 0.0, k)
    assert se.state.E == 0.0 and z == pytest.approx(1.1 * 0.5, rel=1e-14)
    total = 0.0
    for k in range(101, 301):
        x = 0.7 * math.sin(k / 9.0)
        se.measure(x, 0.0, k)
        total += x * x * Ts
    assert se.state.E == pytest.approx(total, rel=1e-12)


def test_tilt_and_temperature_against_hand_computation():
    a0, a1, a2, a3 = 0.3, 0.9, 0.02, 0.004
    T0, kT_bias, kT_scale = 298.15, 0.002, -0.001
    se = chain.SensorErrors(1, a0, a1, a2, 1e-4, a3, 0.0, 1e-3,
                            dict(T0=T0, kT_bias=kT_bias, kT_scale=kT_scale, theta=0.0,
                                 T=T0))
    for x, theta, T in ((0.4, 0.3, 310.0), (-1.2, -0.7, 250.0), (0.0, math.pi / 2, T0),
                        (0.1, 0.0, 400.0), (2.0, 3.0, 298.15)):
        se.theta, se.T = theta, T
        z = se.measure(x, 0.0, 1)
        u = (1.0 + kT_scale * (T - T0)) * (x + math.sin(theta))
        hand = a0 + a1 * u + a2 * u * u + a3 * u ** 3 + kT_bias * (T - T0)
        assert z == pytest.approx(hand, rel=1e-14, abs=1e-15), (x, theta, T)
    # the letter's g-offset: +-90 degrees is +-1 g
    assert errors.tilt(0.0, math.pi / 2) == pytest.approx(1.0, abs=2 * EPS)
    assert errors.tilt(0.5, -math.pi / 2) == pytest.approx(-0.5, abs=2 * EPS)
    assert _ops.sin(-1.0) == pytest.approx(math.sin(-1.0), abs=2 * EPS)


def test_the_tilt_of_one_sample_has_the_arrays_bits_whatever_tilt_came_before():
    """``x + sin(theta)`` of one sample (the FMU's path, which keeps the sine of the tilt it
    held last) has the bits of the array form (the batch engine's) after any tilt, the signed
    zeros included: -0.0 + sin(0.0) is 0.0, -0.0 + sin(-0.0) is -0.0."""
    tilts = (-0.0, 0.0, 1.0, -1.0, 0.3, 5e-324)
    for before in tilts:
        for theta in tilts:
            for x in (-0.0, 0.0, 0.25):
                errors.tilt(0.5, before)
                one = errors.tilt(x, theta)
                arrays = errors.tilt(np.array([x]), np.array([theta]))[0]
                assert np.float64(one).tobytes() == arrays.tobytes(), (before, theta, x)


def test_temperature_terms_equal_imu_error_models_linear_thermal_model():
    """A linear sensor (a0 = a2 = 0, a1 = 1) shows imu-error-model's distortion of a rate with
    the same coefficients: ``x (1 + kT_scale dT) + kT_bias dT`` (its temperatures in Celsius,
    the same dT)."""
    from imu_error_model.distortions import apply_distortions
    from imu_error_model.thermal import LinearThermalModel
    cfg = AxisConfig(thermal_bias_coefficient=0.003, thermal_scale_factor_coefficient=2e-4,
                     reference_temperature_celsius=25.0)
    se = sensor_errors(1, 1e-3, a0=0.0, a1=1.0, a2=0.0, T0=298.15, kT_bias=0.003,
                       kT_scale=2e-4)
    for x, T in ((0.5, 310.0), (-2.0, 260.0), (1.0, 298.15)):
        se.T = T
        ref = apply_distortions(np.array([x, 0.0, 0.0]), cfg,
                                LinearThermalModel(cfg).evaluate(T - 273.15))[0]
        assert se.measure(x, 0.0, 1) == pytest.approx(ref, rel=1e-12, abs=1e-15)


def test_range_saturates_the_sensed_acceleration_on_both_sides():
    se = sensor_errors(1, 1e-3, a0=0.1, a1=2.0, a2=0.05, range=1.5)
    for x, u in ((0.5, 0.5), (1.5, 1.5), (1.6, 1.5), (40.0, 1.5), (-1.5, -1.5), (-1.6, -1.5),
                 (-1e300, -1.5)):
        assert se.measure(x, 0.0, 1) == sensor.h(u, 0.1, 2.0, 0.05), x
    se.theta = math.pi / 2  # the tilt's g is sensed too: it saturates with x
    assert se.measure(1.0, 0.0, 1) == sensor.h(1.5, 0.1, 2.0, 0.05)


def test_adc_over_the_measurement_range_rounds_to_its_grid_and_clips():
    """``bits`` with ``range`` (Vs = 0): the converter spans ``a0 +- |a1| range`` in
    ``2^bits`` codes; with Vs or without range it keeps the stand-in's span (its bits)."""
    cfg = adxl203.config(a0=0.5, a1=-2.0, a2=0.0, bits=4, range=1.0)
    assert cfg.lo == -1.5 and cfg.lsb == 0.25 and cfg.levels == 16
    cases = ((0.5, 0.5), (0.61, 0.5), (0.63, 0.75), (-1.5, -1.5), (-9.0, -1.5), (2.24, 2.25),
             (2.5, 2.25), (9.0, 2.25))
    for V, q in cases:
        assert adxl203.quantise(V, cfg) == q, V
    assert math.isnan(adxl203.quantise(math.nan, cfg))
    # the batch engine's path: the same codes over an array (with a nan kept as it is)
    got = adxl203.quantise(np.array([V for V, _ in cases] + [math.nan]), cfg)
    assert got[:-1].tolist() == [q for _, q in cases] and math.isnan(got[-1])
    # a finite voltage whose code overflows (V / lsb = inf) is full scale, not an error
    for V, q in ((1e308, 2.25), (-1e308, -1.5)):
        with np.errstate(over="ignore"):  # (NumPy's warning of the overflowing division)
            assert adxl203.quantise(V, cfg) == q and adxl203.quantise(np.array([V]), cfg)[0] == q
    # a lowest level of exactly 1.0 (a0 - |a1| range = 1.5 - 0.5): codes from it, not from 0
    one = adxl203.config(a0=1.5, a1=0.5, a2=0.0, bits=2, range=1.0)
    assert one.lo == 1.0 and one.lsb == 0.25
    for V, q in ((0.0, 1.0), (1.3, 1.25), (1.9, 1.75), (3.0, 1.75)):
        assert adxl203.quantise(V, one) == q and adxl203.quantise(np.array([V]), one)[0] == q, V
    assert adxl203.config(bits=4).lo == 0.0 and adxl203.config(bits=4).lsb == 5.0 / 16
    assert adxl203.config(bits=4, Vs=5.0, range=1.0).lsb == 5.0 / 16
    assert adxl203.config(range=1.0).levels == 0
    se = sensor_errors(1, 1e-3, a0=0.5, a1=-2.0, bits=4, range=1.0, bias_on=0.0)
    assert se.measure(0.3, 0.0, 1) == 0.0  # 0.5 - 0.6 = -0.1 -> code 6 of 0.25 from -1.5


# -- bad values: one line, what is allowed ------------------------------------------------------

@pytest.mark.parametrize("name", ["bias_on", "random_walk", "bias_gm", "flicker", "range"])
def test_a_negative_standard_deviation_is_refused_and_zero_allowed(name):
    assert parameters.problem(name, 0.0) is None
    assert parameters.problem(name, 1e-300) is None
    msg = parameters.problem(name, -1e-9)
    assert msg == "%s = -1e-09 is out of range; allowed: %s >= 0" % (name, name)


@pytest.mark.parametrize("name", ["tau_gm", "tau_min", "tau_max", "E_tau"])
def test_a_time_or_exposure_scale_must_be_positive(name):
    assert parameters.problem(name, 5e-324) is None
    assert parameters.problem(name, 0.0) == "%s = 0.0 is out of range; allowed: %s > 0" % (
        name, name)


def test_the_flicker_band_must_be_a_band_of_at_most_seven_decades():
    band = lambda lo, hi, flicker=0.01: errors.problems(dict(tau_min=lo, tau_max=hi,
                                                             flicker=flicker))
    assert band(1.0, 1.0000000000000002) == []
    assert band(1.0, 1.0) == [
        "tau_min = 1.0 s and tau_max = 1.0 s are not a band; allowed: tau_min < tau_max (the "
        "correlation times of the flicker bias)"]
    assert band(2.0, 1.0)[0].startswith("tau_min = 2.0 s and tau_max = 1.0 s are not a band")
    assert band(1e-3, 1e4) == []
    assert band(1e-3, 10000.001) == [
        "tau_min = 0.001 s and tau_max = 10000.001 s span more than 7 decades; allowed: "
        "tau_max <= 1e7 tau_min (one flicker component per decade, at most 8)"]
    assert band(-1.0, 0.5) == []  # (its range check's)
    # without a flicker bias the band is not used: nothing to refuse
    assert band(2.0, 1.0, flicker=0.0) == [] and band(5e-324, 1e300, flicker=0.0) == []
    assert errors.problems({}) == []


# -- Allan deviation: the FMU's output against allantools and the closed forms --------------------

RUNS, N = 64, 32768
TAUS = (1, 3, 10, 30, 100, 300, 1000, 3000)


def assert_allan(data, Ts, exact, continuous=None):
    """Every ``m`` of :data:`TAUS`: the Allan deviation over the runs within
    :func:`tolerance` of the exact discrete curve ``exact(m)``; the continuous-time curve
    within 1 % of the exact one where given, from ``m = 100`` (where a sample is short against
    the averaging time; the two differ by about ``Ts / tau`` below)."""
    est = allan(data, Ts, TAUS)
    for m, avar in zip(TAUS, est):
        truth = exact(m)
        assert abs(math.sqrt(avar / truth) - 1.0) <= tolerance(*data.shape, m), \
            (m, math.sqrt(avar), math.sqrt(truth))
        if continuous is not None and m >= 100:
            assert math.sqrt(continuous(m * Ts) / truth) == pytest.approx(1.0, rel=0.01), m


def test_allan_deviation_of_white_noise_is_N_over_sqrt_tau():
    Ts, R = 1e-3, 4e-4
    data = series(N, RUNS, Ts, noise_on=True, R=R, bias_on=0.0)
    N_density = math.sqrt(R * Ts)  # sigma = N / sqrt(Ts)
    assert_allan(data, Ts, lambda m: avar_white(R, m), lambda tau: N_density ** 2 / tau)


def test_allan_deviation_of_the_random_walk_is_K_sqrt_tau_over_3():
    Ts, K = 0.01, 0.02
    data = series(N, RUNS, Ts, random_walk=K)
    assert_allan(data, Ts, lambda m: avar_random_walk(K * K * Ts, m),
                 lambda tau: K * K * tau / 3.0)


def test_allan_deviation_of_the_gauss_markov_bias_follows_its_curve():
    Ts, sigma, tau = 0.01, 0.1, 1.0
    data = series(N, RUNS, Ts, seed0=11, bias_gm=sigma, tau_gm=tau)
    assert_allan(data, Ts, lambda m: avar_gauss_markov(sigma * sigma, math.exp(-Ts / tau), m),
                 lambda T: continuous_avar_gauss_markov(sigma * sigma, tau, T))


def test_allan_deviation_of_the_flicker_bias_is_flat_over_its_band():
    Ts, level, tau_min, tau_max = 0.05, 0.01, 0.1, 100.0
    data = series(N, RUNS, Ts, seed0=21, flicker=level, tau_min=tau_min, tau_max=tau_max)
    taus, stds, a = flicker_reference(level, tau_min, tau_max, Ts)
    exact = lambda m: sum(avar_gauss_markov(s * s, ai, m) for s, ai in zip(stds, a))
    assert_allan(data, Ts, exact, lambda T: sum(continuous_avar_gauss_markov(s * s, t, T)
                                                for s, t in zip(stds, taus)))
    # over the band's inside (10 tau_min .. tau_max / 10: m = 20 .. 200) the estimate is the
    # flat floor: flicker within 3 % and the estimate's bound
    for m in (20, 60, 200):
        avar = allan(data, Ts, (m,))[0]
        assert abs(math.sqrt(avar) / level - 1.0) <= 0.03 + tolerance(RUNS, N, m), m


# -- variance and autocorrelation against imu-error-model ----------------------------------------

ENSEMBLE = 20000


def ensemble(k_last, Ts, seed0=1, **values):
    """The processes' state of ``ENSEMBLE`` seeds at samples 0 .. k_last (a list of
    :class:`ErrorState` of arrays), with the draws of models.errors.draws."""
    seeds = np.arange(seed0, seed0 + ENSEMBLE, dtype=np.uint64)
    se = sensor_errors(seeds, Ts, **values)
    states = [se.state]
    for k in range(1, k_last + 1):
        se.measure(0.0, 0.0, k)
        states.append(se.state)
    return se, states


def persistent(dt, age=0.0, **axis):
    """imu-error-model's characterisation of the accelerometer's persistent error states."""
    est = characterize_imu_error_process(ImuConfig(accelerometer=AxisConfig(**axis)), dt=dt,
                                         process_age_at_interval_start_s=age)
    return est.accelerometer.persistent


def block_diag(matrix, index):
    return np.diag(matrix)[3 * index]


def assert_variance(samples, variance):
    """Sample variance of ``ENSEMBLE`` independent zero-mean Gaussian values against
    ``variance``: relative standard error ``sqrt(2 / n)``."""
    got = np.mean(np.asarray(samples) ** 2)
    assert abs(got / variance - 1.0) <= Z * math.sqrt(2.0 / len(samples)), (got, variance)


def assert_correlation(a, b, rho):
    """Sample correlation of paired values against ``rho``: standard error ``(1 - rho^2) /
    sqrt(n)``."""
    got = np.mean(a * b) / math.sqrt(np.mean(a * a) * np.mean(b * b))
    assert abs(got - rho) <= Z * max(1.0 - rho * rho, 1e-3) / math.sqrt(len(a)), (got, rho)


def test_turn_on_bias_variance_equals_imu_error_models():
    p = persistent(0.01, turn_on_bias_std=0.3)
    seeds = np.arange(1, ENSEMBLE + 1, dtype=np.uint64)
    b_on = errors.config(seed=seeds, bias_on=0.3).b_on
    assert_variance(b_on, block_diag(p.initial_covariance, 0))
    assert abs(np.mean(b_on)) <= Z * 0.3 / math.sqrt(ENSEMBLE)
    # one value per seed: the same at every sample
    se = sensor_errors(seeds[:4], 0.01, bias_on=0.3)
    assert [se.measure(0.0, 0.0, k).tobytes() for k in (1, 2, 500)] == [b_on[:4].tobytes()] * 3


def test_gauss_markov_variance_and_autocorrelation_equal_imu_error_models():
    Ts, sigma, tau = 0.01, 0.1, 0.05
    p = persistent(Ts, bias_std=sigma, bias_correlation_time=tau)
    phi, var = p.bias_transition[0, 0], p.initial_covariance[0, 0]
    assert var == sigma * sigma
    _, states = ensemble(12, Ts, bias_gm=sigma, tau_gm=tau)
    gm = [s.gm for s in states]
    for k in (0, 1, 12):
        assert_variance(gm[k], var)  # stationary from the start
    for lag in (1, 2, 5, 12):
        assert_correlation(gm[0], gm[lag], phi ** lag)


def test_random_walk_variance_and_autocorrelation_equal_imu_error_models():
    Ts, K = 0.01, 0.05
    _, states = ensemble(40, Ts, random_walk=K)
    rw = [s.rw for s in states]
    assert not np.any(rw[0])  # it starts at 0, as imu-error-model's
    assert persistent(Ts, bias_std=K).initial_covariance[0, 0] == 0.0
    for k in (1, 10, 40):
        p = persistent(Ts, age=(k - 1) * Ts, bias_std=K)  # the state after k intervals
        assert_variance(rw[k], p.end_covariance[0, 0])
    for j, k in ((1, 4), (10, 40), (20, 21)):
        assert_correlation(rw[j], rw[k], math.sqrt(j / k))


def test_the_processes_draw_independent_noise():
    """The walk's, the Gauss-Markov bias's and the flicker components' innovations of one
    sample are uncorrelated over the seeds (their own streams; a shared stream would make them
    equal): every pair within five standard errors, 1 / sqrt(n), of 0."""
    Ts = 0.01
    se, states = ensemble(1, Ts, random_walk=0.1, bias_gm=0.1, tau_gm=0.05, flicker=0.01,
                          tau_min=0.02, tau_max=20.0)
    e, s0, s1 = se.ecfg, states[0], states[1]
    innovations = [(s1.rw - s0.rw) / e.rw, (s1.gm - e.gm_a * s0.gm) / e.gm_c] + \
        [(b1 - a * b0) / c for b0, b1, a, c in zip(s0.fl, s1.fl, e.fl_a, e.fl_c)]
    for i in range(len(innovations)):
        assert_variance(innovations[i], 1.0)
        for j in range(i):
            assert_correlation(innovations[i], innovations[j], 0.0)


def test_flicker_components_variance_and_autocorrelation_equal_imu_error_models():
    Ts, level, tau_min, tau_max = 0.02, 0.01, 0.03, 3.0
    m = 1 + math.ceil(math.log10(tau_max / tau_min) - 1e-9)
    p = persistent(Ts, flicker_bias_std=level, flicker_min_correlation_time=tau_min,
                   flicker_max_correlation_time=tau_max, flicker_components=m)
    se, states = ensemble(8, Ts, flicker=level, tau_min=tau_min, tau_max=tau_max)
    assert se.ecfg.fl_n == m == len(p.state_block_labels)
    total = 0.0
    for i in range(m):
        var, phi = block_diag(p.initial_covariance, i), block_diag(p.transition, i)
        comp = [s.fl[i] for s in states]
        assert_variance(comp[0], var)
        assert_variance(comp[8], var)
        assert_correlation(comp[0], comp[1], phi)
        assert_correlation(comp[0], comp[8], phi ** 8)
        total += var
    assert_variance(sum(states[8].fl), total)  # the components are independent


# -- the survey's survivors (models/errors.py) ----------------------------------------------------

HELD = dict(seed=3, random_walk=0.02, bias_gm=0.03, tau_gm=0.02, flicker=0.01, tau_min=0.003,
            tau_max=3.0, d_inf=0.04, E_tau=0.5)


def test_hold_advances_each_sample_between_communication_points_with_its_own_draws():
    """errors.hold(state, x, seed, k0, m): the samples k0 + 1 .. k0 + m - 1, each with the
    draws of its own index: m = 1 holds nothing, m = 2 is one advance with sample k0 + 1's
    draws, m = 3 two with k0 + 1's then k0 + 2's."""
    ecfg = errors.config(**HELD)
    state = errors.initial_state(3, ecfg)
    assert errors.hold(state, 0.7, 3, 10, 1, ecfg) == state
    one = errors.advance(state, 0.7, *errors.draws(3, 11, ecfg), ecfg)[0]
    assert one != state
    assert errors.hold(state, 0.7, 3, 10, 2, ecfg) == one
    two = errors.advance(one, 0.7, *errors.draws(3, 12, ecfg), ecfg)[0]
    assert errors.hold(state, 0.7, 3, 10, 3, ecfg) == two
    assert two != errors.advance(one, 0.7, *errors.draws(3, 11, ecfg), ecfg)[0]


#: (d_inf negative: a drift that pulls down is allowed, and the exposure grows all the same)
STATE_TERMS = dict(bias_on=0.05, random_walk=0.002, bias_gm=0.003, flicker=0.001, d_inf=-0.04)
STATE_SUBSETS = [on for r in range(1, 6) for on in itertools.combinations(STATE_TERMS, r)]


@pytest.mark.parametrize("on", STATE_SUBSETS, ids="+".join)
def test_advance_state_is_the_state_of_advance_bit_for_bit(on):
    """errors.advance_state (a sample between communication points, no sum, no exponential) is
    advance's new state, bit for bit, for every subset of the processes: over 200 samples with
    inputs x of both signs, 0.0 and -0.0, and from states of -0.0 and of both signs; a process
    that is off keeps its state object."""
    rng = random.Random(len(on) * 31 + sum(map(len, on)))
    values = dict(tau_gm=0.05, tau_min=0.01, tau_max=10.0, E_tau=0.5,
                  **{n: STATE_TERMS[n] for n in on})
    ecfg = errors.config(seed=11, Ts=1e-3, **values)
    fl = tuple(rng.choice((-0.0, 0.0, rng.uniform(-1e-3, 1e-3))) for _ in range(ecfg.fl_n))
    starts = [errors.initial_state(11, ecfg),
              errors.ErrorState(-0.0, -0.0, 0.0, fl), errors.ErrorState(-2e-3, 3e-3, 1.5, fl)]
    for start in starts:
        a = b = start
        for k in range(1, 201):
            x = rng.choice((0.0, -0.0, rng.uniform(-3.0, 3.0), 1e-200))
            d = errors.draws(11, k, ecfg)
            a = errors.advance(a, x, *d, ecfg)[0]
            b_next = errors.advance_state(b, x, *d, ecfg)
            off = {"rw": ecfg.rw == 0.0, "gm": ecfg.gm_sigma == 0.0, "E": ecfg.d_inf == 0.0,
                   "fl": ecfg.fl_n == 0}
            for name in off:
                if off[name]:
                    assert getattr(b_next, name) is getattr(b, name), name
            b = b_next
            assert hexes(*b) == hexes(*a), (k, x)
    assert type(b) is errors.ErrorState


@pytest.mark.parametrize("on", STATE_SUBSETS, ids="+".join)
def test_hold_run_is_advance_state_sample_by_sample_bit_for_bit(on):
    """errors.hold_run over m samples (m = 0, 1, 2, 97) is advance_state over them one by one,
    bit for bit, for every subset of the processes, with draws as list, array('d') and NumPy,
    inputs x of both signs and -0.0, from states of -0.0 and of both signs; m = 0 gives the
    state itself."""
    rng = random.Random(len(on) * 17 + sum(map(len, on)))
    values = dict(tau_gm=0.05, tau_min=0.01, tau_max=10.0, E_tau=0.5,
                  **{n: STATE_TERMS[n] for n in on})
    ecfg = errors.config(seed=13, Ts=1e-3, **values)
    fl = tuple(rng.choice((-0.0, rng.uniform(-1e-3, 1e-3))) for _ in range(ecfg.fl_n))
    for start in (errors.initial_state(13, ecfg), errors.ErrorState(-0.0, -0.0, 0.0, fl),
                  errors.ErrorState(-2e-3, 3e-3, 1.5, fl)):
        for m, x, kind in ((0, 0.5, list), (1, -0.0, list), (2, -1.25, array_d), (97, 0.3,
                                                                                  np.array)):
            k0 = rng.randint(1, 5000)
            draws, each = run_draws(13, range(k0, k0 + m), ecfg, kind)
            got = errors.hold_run(start, x, m, draws, ecfg)
            want = start
            for d in each:
                want = errors.advance_state(want, x, *d, ecfg)
            assert hexes(*got) == hexes(*want), (m, x)
            assert type(got) is errors.ErrorState
            if m == 0:
                assert got is start


def array_d(values):
    return array.array("d", values)


@pytest.mark.parametrize("alone", [dict(random_walk=1.0), dict(bias_gm=1.0, tau_gm=2.0),
                                   dict(flicker=1.0, tau_min=2.0, tau_max=50.0),
                                   dict(d_inf=1.0), dict(d_inf=-1.0)], ids=str)
def test_hold_advances_each_process_alone_even_at_the_value_1(alone):
    """errors.hold with one process alone (Ts = 1 s, so that rw, gm_sigma and d_inf are 1.0 or
    -1.0 exactly) advances it over the held samples as advance_state does; with every process
    off (the turn-on bias alone has no state) it gives the state itself."""
    ecfg = errors.config(seed=5, Ts=1.0, E_tau=50.0, **alone)
    state = errors.initial_state(5, ecfg)
    want = state
    for k in (8, 9, 10):
        want = errors.advance_state(want, 0.6, *errors.draws(5, k, ecfg), ecfg)
    got = errors.hold(state, 0.6, 5, 7, 4, ecfg)
    assert hexes(*got) == hexes(*want) and got != state
    off = errors.config(seed=5, Ts=1.0, bias_on=1.0)
    still = errors.initial_state(5, off)
    assert errors.hold(still, 0.6, 5, 7, 4, off) is still


@pytest.mark.parametrize("bias_gm", [1.0, 0.5, 2.0])
def test_draws_give_the_gauss_markov_draw_whenever_its_sigma_is_not_zero(bias_gm):
    """n_gm is stream STREAM_BIAS_GM's draw of sample k for any bias_gm != 0 (1.0 included),
    0.0 with bias_gm = 0."""
    ecfg = errors.config(seed=9, bias_gm=bias_gm, tau_gm=0.02)
    assert ecfg.gm_sigma == bias_gm
    for k in (1, 2, 17):
        n_gm = errors.draws(9, k, ecfg)[1]
        assert n_gm == noise.ziggurat(9, errors.STREAM_BIAS_GM, k) and n_gm != 0.0
    assert errors.draws(9, 1, errors.config(seed=9, bias_gm=0.0))[1] == 0.0


def test_a_random_walk_that_is_off_keeps_its_state_bit_for_bit():
    """advance: with random_walk = 0 the walk's state is kept as it is, whatever the draw
    passed: -0.0 (a state the FMU accepts, as 0) stays -0.0, and the sample b is the other
    processes' alone."""
    ecfg = errors.config(seed=2, bias_on=0.05)
    for n_rw in (0.0, math.inf):
        state, b = errors.advance(errors.ErrorState(-0.0, 0.0, 0.0, ()), 0.3, n_rw, 0.0, (),
                                  ecfg)
        assert math.copysign(1.0, state.rw) == -1.0 and state.rw == 0.0
        assert b == ecfg.b_on


def test_the_chains_sensor_with_slow_errors_keeps_its_quartic_term():
    """models.chain's sensor with a slow error on (not the plain path) measures the general
    polynomial: at x = 1.5 with the same draws, a4 = 0.05 adds a4 x^4 to z, and a3 a3 x^3."""
    x, values = 1.5, {"bias_on": 0.01}
    base = chain.SensorErrors(1, 0.0, 1.0, 0.0, 1e-4, 0.0, 0.0, 1e-3, values)
    quartic = chain.SensorErrors(1, 0.0, 1.0, 0.0, 1e-4, 0.0, 0.05, 1e-3, values)
    cubic = chain.SensorErrors(1, 0.0, 1.0, 0.0, 1e-4, 0.02, 0.0, 1e-3, values)
    assert not base.plain
    z0, z4, z3 = (s.measure(x, 0.0, 1) for s in (base, quartic, cubic))
    assert z4 - z0 == pytest.approx(0.05 * x ** 4, rel=1e-12)
    assert z3 - z0 == pytest.approx(0.02 * x ** 3, rel=1e-12)


# -- one FMU instance's runs: errors.run and adxl203.measure_errors_run have the bits of advance
# -- and measure_errors (the Python Accelerometer computes with them) ----------------------------

def hexes(*values):
    """The bits of floats (and of tuples of them), -0.0 apart from 0.0."""
    out = []
    for v in values:
        out += hexes(*v) if isinstance(v, tuple) else [float(v).hex()]
    return out


#: The input-independent processes, each with signs that make the sums' order matter.
RUN_TERMS = dict(bias_on=1.0, random_walk=0.002, bias_gm=0.003, flicker=0.001)
RUN_SUBSETS = [on for r in range(1, 5) for on in itertools.combinations(RUN_TERMS, r)
               if set(on) - {"bias_on"}]


def run_draws(seed, ks, ecfg, kind=list):
    """errors.run's draws for samples ``ks`` (``kind``: list, array('d') or NumPy array), and
    errors.draws of each sample."""
    each = [errors.draws(seed, k, ecfg) for k in ks]
    n_rw = kind([d[0] for d in each]) if ecfg.rw != 0.0 else None
    n_gm = kind([d[1] for d in each]) if ecfg.gm_sigma != 0.0 else None
    n_fl = tuple(kind([d[2][i] for d in each]) for i in range(ecfg.fl_n))
    return (n_rw, n_gm, n_fl), each


@pytest.mark.parametrize("on", RUN_SUBSETS, ids="+".join)
def test_a_run_of_the_input_independent_processes_has_the_bits_of_advance(on):
    """errors.run over 300 samples from a stationary state: each row is the walk, the
    Gauss-Markov bias and the flicker components that errors.advance gives sample by sample,
    and p its sum b (no exposure drift here), bit for bit; a process that is off keeps its state
    object."""
    values = dict(tau_gm=0.05, tau_min=0.01, tau_max=10.0, **{n: RUN_TERMS[n] for n in on})
    ecfg = errors.config(seed=7, Ts=1e-3, **values)
    start = errors.initial_state(7, ecfg)
    for kind in (list, lambda v: array.array("d", v), np.array):
        draws, each = run_draws(7, range(1, 301), ecfg, kind)
        rows = errors.run(start, draws, ecfg)
        assert len(rows) == 300
        state = start
        for k, (row, d) in enumerate(zip(rows, each), 1):
            state, b = errors.advance(state, 0.0, *d, ecfg)
            assert hexes(*row) == hexes(state.rw, state.gm, state.fl, b), k
        if ecfg.rw == 0.0:
            assert all(row[0] is start.rw for row in rows)


@pytest.mark.parametrize("flicker", [1.0, 0.0])
def test_a_run_keeps_signed_zeros_and_the_order_of_its_sums_as_advance(flicker):
    """Draws and states of -0.0 and 0.0, and values whose sums round differently in another
    order, with and without the flicker bias: errors.run's rows are advance's, bit for bit (a
    sum of zeros keeps its sign as advance's does; p adds the turn-on bias, the walk, the
    Gauss-Markov bias and the flicker bias in that order, the components in theirs)."""
    ecfg = errors.config(seed=3, Ts=1e-3, bias_on=1.0, random_walk=1.0, bias_gm=1.0, tau_gm=0.5,
                         flicker=flicker, tau_min=0.1, tau_max=10.0)
    ecfg = ecfg._replace(b_on=-0.0)
    start = errors.ErrorState(-0.0, -0.0, 0.0, tuple(-0.0 for _ in range(ecfg.fl_n)))
    big, tiny = 1e16, 1.0
    cols = [[-0.0, 0.0, -0.0, big, tiny, -big, tiny, 3.0, -0.0],
            [-0.0, -0.0, 0.0, tiny, big, tiny, -big, -3.0, 0.0]]
    cols += [[-0.0, tiny, -tiny, -big, big, 0.5, -0.5, 1e-300, -0.0][::1 - 2 * (i % 2)]
             for i in range(ecfg.fl_n)]
    rows = errors.run(start, (cols[0], cols[1], tuple(cols[2:])), ecfg)
    state = start
    for j, row in enumerate(rows):
        state, b = errors.advance(state, 0.0, cols[0][j], cols[1][j],
                                  tuple(c[j] for c in cols[2:]), ecfg)
        assert hexes(*row) == hexes(state.rw, state.gm, state.fl, b), j


def test_the_float_paths_read_the_fields_they_name():
    """measure_errors_run and quantise read their constants by position (one unpacking on the
    float path): the positions are the fields' (a field added before them would shift them)."""
    assert errors.ErrorConfig._fields[-7:] == ("d_inf", "E_tau", "Ts", "T0", "kT_bias",
                                               "kT_scale", "range")
    assert adxl203.Config._fields[9:] == ("lsb", "levels", "a4", "lo")


#: Sensors for measure_errors_run: the plain path, the output filter, the ADC over the range,
#: each with the class-2 terms and the exposure on or off.
RUN_SENSORS = [dict(), dict(a4=0.02), dict(fc=150.0), dict(bits=10, range=1.2),
               dict(fc=80.0, bits=12, range=0.9)]
RUN_ERRORS = [dict(random_walk=0.01),
              dict(bias_gm=0.02, tau_gm=0.05, d_inf=0.05, E_tau=0.02),
              dict(flicker=0.01, tau_min=0.01, tau_max=1.0, kT_bias=0.003, T0=300.0),
              dict(random_walk=0.01, bias_on=0.1, kT_scale=-0.002, range=0.8, d_inf=0.03,
                   E_tau=0.1),
              dict(bias_gm=0.01, flicker=0.005, kT_bias=-0.001, kT_scale=0.004, range=1.5),
              dict(random_walk=0.01, d_inf=-0.04, E_tau=0.05, kT_bias=1.0, kT_scale=1.0,
                   range=2.0)]


@pytest.mark.parametrize("sensor_values", RUN_SENSORS, ids=lambda v: "+".join(v) or "plain")
@pytest.mark.parametrize("error_values", RUN_ERRORS, ids=lambda v: "+".join(v))
def test_measure_errors_run_has_the_bits_of_measure_errors(sensor_values, error_values):
    """adxl203.measure_errors_run with errors.run's row of each sample gives the filter state,
    the error state and z of adxl203.measure_errors with that sample's draws, bit for bit, for
    inputs that move (x beyond the range on both sides; a tilt of 0, -0.0, one equal to the sine
    of the one before, others held and changed; temperatures on both sides of T0)."""
    values = dict(sensor_values, **error_values)
    p = adxl203.sensor_parameters(a0=0.3, a1=1.1, a2=0.02, a3=0.01, R=1e-4, seed=5, Ts=1e-3,
                                  **values)
    cfg, ecfg = adxl203.config(**p), errors.config(**p)
    rng = np.random.default_rng(11)
    n = 400
    draws, each = run_draws(5, range(1, n + 1), ecfg)
    rows = errors.run(errors.initial_state(5, ecfg), draws, ecfg)
    thetas = [0.0, -0.0, 0.3, _ops.sin(0.3), -0.2, 1.0]  # (a tilt equal to the last one's sine)
    a = b = (None, errors.initial_state(5, ecfg))
    for k in range(1, n + 1):
        x = float(rng.uniform(-2.5, 2.5))
        theta = thetas[k % 6] if k % 7 else float(rng.uniform(-1, 1))
        T = float(rng.uniform(280.0, 320.0))
        v = adxl203.noise(5, k)
        got = adxl203.measure_errors_run(a[0], a[1], rows[k - 1], x, 0.1, v, theta, T, cfg, ecfg)
        want = adxl203.measure_errors(b[0], b[1], x, 0.1, v, each[k - 1], theta, T, cfg, ecfg)
        assert hexes(got[0] if got[0] is not None else 0.0, *got[1], got[2]) == \
            hexes(want[0] if want[0] is not None else 0.0, *want[1], want[2]), k
        assert (got[0] is None) == (want[0] is None)
        a, b = got[:2], want[:2]
