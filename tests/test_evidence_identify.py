"""Identification (models.identify) against the known truth over many seeds.

- The mean of the fits is the truth and their spread is :func:`identify.standard_errors`
  (sample variance over standard error squared in its chi-square band), without and with a
  delay between drive and output (a pure delay: the lag correction of ``a2`` and ``a0``).
- Behind the ADXL203's output low-pass (models.adxl203, ``fc`` on) the fits converge to the
  closed form of harmonic analysis through the discrete RC filter ``G``:
  ``a1 |G(w)|``, ``a2 |G(2w)| cos(phi_2 - 2 phi_1)`` and ``a0 + a2 X^2/2 (1 - |G(2w)| cos(..))``.
"""
import math

import numpy as np
import pytest
from scipy import stats

from driftfmu.models import adxl203, excitation, identify, noise, sensor

TRUE = dict(a0=0.3, a1=1.2, a2=0.05, R=0.01 ** 2)
SETS, N, X, F, TS = 300, 2000, 1.0, 50.0, 1e-3
Z = 4.5


def _sets(delay, seed0=101):
    """SETS recordings of z = h(X sin(theta - delay)) + v with the drive x = X sin(theta)."""
    seeds = np.arange(seed0, seed0 + SETS, dtype=np.uint64)[:, None]
    phis = 2 * math.pi * noise.uniform(seeds, noise.STREAM_PHASE, 1)
    k = np.arange(1, N + 1, dtype=np.uint64)[None, :]
    x = excitation.sine(k, X, F, TS, phis)
    u = excitation.sine(k, X, F, TS, phis - delay)
    z = sensor.measure(u, TRUE["a0"], TRUE["a1"], TRUE["a2"], TRUE["R"],
                       noise.normal(seeds, noise.STREAM_MEASUREMENT, k))
    t = (np.arange(N) * TS)
    return [identify.fit_set(t, x[i], z[i], F) for i in range(SETS)]


@pytest.fixture(scope="module", params=[0.0, 0.6], ids=["no-lag", "lag-0.6rad"])
def fits(request):
    return request.param, _sets(request.param)


def test_fits_average_to_the_truth(fits):
    delay, fs = fits
    se = identify.standard_errors(math.sqrt(TRUE["R"]), X, N)
    for name, true in TRUE.items():
        v = np.array([getattr(f, name) for f in fs])
        assert abs(v.mean() - true) <= Z * se[name] / math.sqrt(SETS), name
    lag = np.array([f.lag for f in fs])
    assert abs(lag.mean() - delay) <= Z * lag.std(ddof=1) / math.sqrt(SETS)


def test_spread_of_fits_is_the_standard_error_formula(fits):
    # (SETS - 1) s^2 / se^2 ~ chi2(SETS - 1) when se is right; 99.9 % band over the 4 parameters
    _, fs = fits
    se = identify.standard_errors(math.sqrt(TRUE["R"]), X, N)
    q = 0.001 / (2 * len(TRUE))
    lo = stats.chi2.ppf(q, SETS - 1) / (SETS - 1)
    hi = stats.chi2.ppf(1 - q, SETS - 1) / (SETS - 1)
    for name in TRUE:
        v = np.array([getattr(f, name) for f in fs])
        ratio = v.var(ddof=1) / se[name] ** 2
        assert lo <= ratio <= hi, (name, ratio, lo, hi)


def test_average_reports_the_spread_of_the_sets():
    fs = _sets(0.3, seed0=900)[:40]
    avg = identify.average(fs)
    for name in TRUE:
        v = np.array([getattr(f, name) for f in fs])
        assert avg[name] == pytest.approx(v.mean(), rel=1e-12, abs=0)
        assert avg["sd_" + name] == pytest.approx(v.std(ddof=1), rel=1e-12, abs=0)
    assert avg["sets"] == 40


def _rc_gain(fc, f, Ts):
    """Gain of e_k = alpha e_{k-1} + (1 - alpha) s_k at frequency f: (|G|, lag = -arg G)."""
    alpha = math.exp(-2 * math.pi * fc * Ts)
    G = (1 - alpha) / (1 - alpha * np.exp(-2j * math.pi * f * Ts))
    return abs(G), -np.angle(G)


@pytest.mark.parametrize("f", [100.0, 200.0])
def test_fits_behind_the_output_low_pass_follow_its_closed_form(f):
    # the ADXL203 stand-in's filter (fc = 1064 Hz) at fs = 10 kHz, white noise before it
    sets, n, Ts, fc, Xd = 60, 6000, 1e-4, adxl203.ADXL203["fc"], 1.5
    a0, a1, a2 = 2.5, 1.0, 0.01
    cfg = adxl203.config(a0=a0, a1=a1, a2=a2, R=1e-6, fc=fc, Ts=Ts)
    seeds = np.arange(1, sets + 1, dtype=np.uint64)
    phis = 2 * math.pi * noise.uniform(seeds, noise.STREAM_PHASE, 1)
    lp, xs, zs = None, [], []
    for k in range(1, n + 1):
        x = excitation.sine(k, Xd, f, Ts, phis)
        lp, z = adxl203.measure(lp, x, 0.0, adxl203.noise(seeds, k), cfg)
        xs.append(x)
        zs.append(z)
    xs, zs = np.array(xs).T, np.array(zs).T
    t = np.arange(n) * Ts
    skip = adxl203.settling_samples(fc, Ts)
    fs = [identify.fit_set(t, xs[i], zs[i], f, skip=skip) for i in range(sets)]
    g1, lag1 = _rc_gain(fc, f, Ts)
    g2, lag2 = _rc_gain(fc, 2 * f, Ts)
    shrink = g2 * math.cos(lag2 - 2 * lag1)
    want = dict(a1=a1 * g1, a2=a2 * shrink, a0=a0 + a2 * Xd * Xd / 2 * (1 - shrink), lag=lag1)
    for name, w in want.items():
        v = np.array([getattr(fi, name) for fi in fs])
        assert abs(v.mean() - w) <= Z * v.std(ddof=1) / math.sqrt(sets) + 1e-12 * abs(w), name
    assert shrink < 0.99 if f == 200.0 else shrink > 0.98  # what the README says of a2
