"""The general sensor's references across its parameter space (issue 32), not at one point.

Hypothesis draws the settings (``Ts`` from 0.1 to 10 ms, ``A`` of both signs, ``a2``, ``a3``,
``a4`` of both signs, alone and together, ``B`` of both signs, every input drive with its own
``Qu``, ``Xu`` and ``fu`` up to 0.45 of the Nyquist rate), and every reference is compared with
the closed form of ``tests/general_closed_forms.py`` (eqs. 4-5 with ``u``, written with NumPy
there, not from models/):

- the stationary moments and the expected drift, through every path that reports it: models/
  (``excitation.state_moments``, ``chain.expected_drift``, the chain's ``dc_expected`` column),
  ``montecarlo gaussian``'s summary, ``sweep``'s table (``a4`` one value for every point, a
  single negative one included, and a sweep over ``a4``), to 1e-12;
- the realised drift of each run, in the chain and in the batch engine (NumPy or the compiled
  kernel), against the running mean of ``a2 x^2 + a3 x^3 + a4 x^4`` of the recorded ``x``, to
  1e-12;
- the realised drift's mean over the runs against its exact expectation at ``n`` samples from
  ``x0 = 0`` (the transient included), two-sided within 4.5 standard errors of the mean over the
  runs;
- a sinusoidal state (``montecarlo sinusoidal``) over whole periods: the realised drift of every
  run is ``a2 X^2/2 + 3 a4 X^4/8`` to rounding, and the summary says so.
"""
import math

import numpy as np
import pytest
from hypothesis import example, given, strategies as st

from driftfmu.models import chain, excitation, noise, sensor
from driftfmu.simulations import batch, montecarlo, sweep

import general_closed_forms as cf
from general_closed_forms import prop

#: Relative agreement of two computations of one closed form (other orders of the same
#: operations, NumPy's complex arithmetic against models/' real one).
CLOSE = 1e-12


def _coefficient(low, high):
    """0, or a value of either sign with magnitude in [low, high]."""
    return st.one_of(st.just(0.0), st.floats(low, high), st.floats(-high, -low))


@st.composite
def general(draw, drives=(cf.OFF, cf.GAUSSIAN, cf.SINUSOIDAL)):
    """Settings of the general sensor: the process, the sensor's higher terms and the input."""
    Ts = 10.0 ** draw(st.floats(-4.0, -2.0))
    drive = draw(st.sampled_from(drives))
    B = draw(st.one_of(st.floats(0.1, 1.5), st.floats(-1.5, -0.1)))
    return dict(Ts=Ts, A=draw(st.floats(-0.9, 0.9)), Q=draw(st.floats(0.01, 0.6)),
                a2=draw(_coefficient(0.005, 0.1)), a3=draw(_coefficient(0.005, 0.1)),
                a4=draw(_coefficient(0.002, 0.05)), B=B, drive=drive,
                Qu=draw(st.floats(0.05, 1.0)) if drive == cf.GAUSSIAN else 0.0,
                Xu=draw(st.floats(0.2, 1.5)) if drive == cf.SINUSOIDAL else 0.0,
                fu=draw(st.floats(0.01, 0.45)) * 0.5 / Ts if drive == cf.SINUSOIDAL else 0.0)


INPUT = ("B", "drive", "Qu", "Xu", "fu")


def _close(got, want, scale):
    assert abs(got - want) <= CLOSE * scale, (got, want)


#: A sinusoidal input through A != 0 at Ts = 0.25 ms: the setting where a reference that
#: takes the default sample period is wrong (|1 - A e^{-jw}| depends on w = 2 pi fu Ts).
SINE_AWAY = dict(Ts=2.5e-4, A=0.7, Q=0.1, a2=0.02, a3=0.0, a4=-0.01, B=0.8, drive=2, Qu=0.0,
                 Xu=1.2, fu=300.0)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # gap at a2 = 0
@prop(40)
@given(p=general())
@example(p=SINE_AWAY)
@example(p=dict(SINE_AWAY, a4=0.0, a3=0.03, drive=1, Qu=0.4, Xu=0.0, fu=0.0))
@example(p=dict(SINE_AWAY, a2=1.0, a3=1.0, a4=1.0, B=1.0))  # (a test for 0 made one for 1)
def test_expected_drift_is_the_closed_form_through_every_path(p):
    m2, m4 = cf.stationary_moments(p["A"], p["Q"], *(p[k] for k in INPUT), p["Ts"])
    scale = abs(p["a2"] * m2) + abs(p["a4"] * m4) + 1e-300
    want = p["a2"] * m2 + p["a4"] * m4
    got2, got4 = excitation.state_moments(p["A"], p["Q"], *(p[k] for k in INPUT), p["Ts"])
    _close(got2, m2, m2)
    _close(got4, m4, m4)
    on = {k: p[k] for k in INPUT}
    _close(chain.expected_drift(p["a2"], excitation.GAUSSIAN, A=p["A"], Q=p["Q"], a4=p["a4"],
                                Ts=p["Ts"], **on), want, scale)
    _close(sensor.drift(p["a2"], got2, p["a4"], got4), want, scale)
    model = dict(a2=p["a2"], a3=p["a3"], a4=p["a4"], A=p["A"], Q=p["Q"], Ts=p["Ts"], **on)
    _close(chain.simulate(2, 3, **model)["dc_expected"][0], want, scale)
    mc = montecarlo.montecarlo_gaussian(runs=1, n=2, workers=1, **model)["summary"]
    _close(mc["dc_expected"], want, scale)
    grid = dict(R=[1e-3], A=p["A"], Q=p["Q"], Ts=p["Ts"], runs=1, n=2, workers=1, a3=p["a3"],
                **on)
    # a4 one value for every point of an a2 grid (a single negative one too) ...
    t = sweep.sweep(a2=[p["a2"]], a4=p["a4"], **grid)["table"]
    _close(t["dc_expected"][0], want, scale)
    if p["a4"] != 0.0:  # ... and a sweep over a4 at one a2
        t = sweep.sweep(a2=[p["a2"]], a4=[0.0, p["a4"]], **grid)["table"]
        _close(t["dc_expected"][0], p["a2"] * m2, abs(p["a2"] * m2) + 1e-300)
        _close(t["dc_expected"][1], want, scale)


def test_the_closed_forms_here_agree_with_a_long_run_of_the_recursion():
    """The test's own closed form, checked once against the recursion it describes: the
    sinusoid's stationary moments at Ts = 0.25 ms through A = 0.7, measured over whole periods
    (the transient decayed to 0.7^2000)."""
    p = SINE_AWAY
    m, v = cf.state_mean_and_variance(6000, p["A"], 0.0, p["B"], p["drive"], 0.0, p["Xu"],
                                      p["fu"], p["Ts"])
    tail = m[2000:]  # 4000 samples = 300 whole periods of fu Ts = 3/40
    m2, m4 = cf.stationary_moments(p["A"], 0.0, p["B"], p["drive"], 0.0, p["Xu"], p["fu"],
                                   p["Ts"])
    assert np.mean(tail ** 2) == pytest.approx(m2, rel=1e-9)
    assert np.mean(tail ** 4) == pytest.approx(m4, rel=1e-9)
    assert not np.any(v)


RUNS, N = 200, 300


def _draws(drive, Qu, runs, n, seed=7):
    """The Gaussian input's draws ``sqrt(Qu) N(0, 1)`` of each run (stream STREAM_INPUT, the
    counter-based generator of tests/test_models.py), ``(runs, n)``."""
    if drive != cf.GAUSSIAN:
        return None
    seeds = batch.run_seeds(seed, runs)[:, None]
    k = np.arange(1, n + 1, dtype=np.uint64)[None, :]
    return math.sqrt(Qu) * noise.normal(seeds, noise.STREAM_INPUT, k)


@prop(14)
@given(p=general())
@example(p=SINE_AWAY)
@example(p=dict(SINE_AWAY, A=-0.6, a2=0.0, a3=0.05, a4=0.0))
@example(p=dict(SINE_AWAY, a2=1.0, a3=1.0, a4=1.0, B=1.0, drive=1, Qu=0.3, Xu=0.0, fu=0.0))
def test_realised_drift_of_every_run_and_its_mean_over_the_runs(p):
    """The batch engine (the compiled kernel here, NumPy in the mutation check): each run's
    realised drift is the running mean of ``h(x) - a0 - a1 x`` of its recorded ``x``; over the
    runs it averages to the exact expectation at ``n`` samples."""
    seeds = batch.run_seeds(7, RUNS)
    on = {k: p[k] for k in INPUT}
    coeffs = dict(a2=p["a2"], a3=p["a3"], a4=p["a4"])
    res = batch.simulate(N, seeds, A=p["A"], Q=p["Q"], R=1e-3, Ts=p["Ts"],
                         record=("x", "dc_realised"), **coeffs, **on)
    want = cf.realised(res["x"], **coeffs)
    scale = np.abs(cf.realised(np.abs(res["x"]), *(abs(c) for c in coeffs.values())))
    assert np.all(np.abs(res["dc_realised"] - want) <= CLOSE * scale + 1e-300)
    assert np.all(np.abs(res["final_dc_realised"] - want[:, -1]) <= CLOSE * scale[:, -1] + 1e-300)
    expectation = cf.realised_expectation(N, *coeffs.values(), p["A"], p["Q"], **on, Ts=p["Ts"])
    off, tolerance = cf.band(res["final_dc_realised"], expectation)
    assert off <= tolerance, (off, tolerance, expectation)
    # the input the state was driven by is the one the test computes (drive, Xu, fu, Ts)
    if p["drive"] != cf.OFF and p["B"] != 0.0:
        m, _ = cf.state_mean_and_variance(N, p["A"], p["Q"], **on, Ts=p["Ts"])
        u = cf.input_samples(p["drive"], N, p["Xu"], p["fu"], p["Ts"],
                             _draws(p["drive"], p["Qu"], RUNS, N))
        x = np.asarray(res["x"])
        w = x.copy()  # the process noise alone: x_k - A x_{k-1} - B u_k
        w[:, 1:] -= p["A"] * x[:, :-1]
        w -= p["B"] * u
        want_w = math.sqrt(p["Q"]) * noise.normal(seeds[:, None], noise.STREAM_PROCESS,
                                                  np.arange(1, N + 1, dtype=np.uint64)[None, :])
        assert np.allclose(w, want_w, rtol=0, atol=1e-9 * (1 + np.abs(x).max()))


@prop(12)
@given(p=general(), n=st.integers(2, 40))
def test_chain_references_are_the_running_means_of_the_recorded_samples(p, n):
    """models/ chain (the Gaussian master's reference): the empirical drift ``z̄ - a0`` and
    the realised drift, sample by sample, against NumPy on the chain's own ``x`` and ``z``."""
    on = {k: p[k] for k in INPUT}
    coeffs = dict(a2=p["a2"], a3=p["a3"], a4=p["a4"])
    seeds = batch.run_seeds(11, 4)
    cols = chain.simulate(n, seeds, a0=0.3, A=p["A"], Q=p["Q"], R=1e-3, Ts=p["Ts"], **coeffs,
                          **on)
    want = cf.realised(cols["x"], **coeffs)
    scale = cf.realised(np.abs(cols["x"]), *(abs(c) for c in coeffs.values())) + 1e-300
    assert np.all(np.abs(cols["dc_realised"] - want) <= CLOSE * scale)
    zbar = np.cumsum(cols["z"], axis=1) / np.arange(1, n + 1)
    assert np.allclose(cols["dc_empirical"], zbar - 0.3, rtol=1e-13, atol=1e-13)
    # the sensor's z is h(x) + sqrt(R) v with the full polynomial
    v = noise.normal(seeds[:, None], noise.STREAM_MEASUREMENT,
                     np.arange(1, n + 1, dtype=np.uint64)[None, :])
    x = cols["x"]
    h = 0.3 + x + p["a2"] * x ** 2 + p["a3"] * x ** 3 + p["a4"] * x ** 4
    assert np.allclose(cols["z"], h + math.sqrt(1e-3) * v, rtol=1e-13, atol=1e-13)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # gap at a2 = 0
@prop(12)
@given(samples=st.integers(5, 40), periods=st.integers(3, 12), Ts=st.sampled_from(
    [1e-4, 2.5e-4, 1e-3, 4e-3]), X=st.floats(0.3, 2.0), a2=_coefficient(0.005, 0.1),
    a3=_coefficient(0.005, 0.1), a4=_coefficient(0.002, 0.05))
def test_sinusoidal_population_over_whole_periods_is_the_closed_form(samples, periods, Ts, X,
                                                                      a2, a3, a4):
    """``montecarlo sinusoidal`` with ``a3``, ``a4``: ``n`` a whole number of periods of
    ``samples >= 5`` samples (so that the sampled means of ``sin^2``, ``sin^3`` and ``sin^4``
    are 1/2, 0 and 3/8 exactly): the summary's expected drift and every run's realised drift
    are ``a2 X^2/2 + 3 a4 X^4/8``; the realised drift follows the recorded ``x`` at every
    sample."""
    f = 1.0 / (samples * Ts)
    n = samples * periods
    res = montecarlo.montecarlo_sinusoidal(runs=3, n=n, seed=2, workers=1, X=X, f=f, Ts=Ts,
                                           a2=a2, a3=a3, a4=a4)
    want = cf.sinusoid_drift(a2, a4, X)
    scale = abs(a2) * X * X + abs(a3) * X ** 3 + abs(a4) * X ** 4 + 1e-300
    _close(res["summary"]["dc_expected"], want, scale)
    k = np.arange(n)
    x = X * np.sin(2 * np.pi * f * Ts * k[None, :] + res["sine_phi"][:, None])
    assert np.allclose(res["sine_x"], x, rtol=0, atol=1e-12 * X)
    assert np.allclose(res["sine_dc_realised"], cf.realised(res["sine_x"], a2, a3, a4),
                       rtol=1e-12, atol=1e-14 * scale)
    assert np.allclose(res["sine_dc_realised"][:, -1], want, rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("zero", [np.float64(0.0), 0, np.int64(0), np.float32(0.0)],
                         ids=["float64", "int", "int64", "float32"])
def test_zero_coefficients_of_any_numeric_type_are_the_letters_sensor_bit_for_bit(zero):
    """docs/method.md section 9: the letter's case is computed exactly as before, the higher
    terms not even evaluated: also when ``a3 = a4 = 0`` come as NumPy scalars or integers (a
    script's numbers), in the chain (the masters' reference) and the batch engine (its NumPy
    path: the mutation check runs it), the realised drift included."""
    seeds = batch.run_seeds(3, 5)
    model = dict(a0=0.2, a2=0.3, A=0.7, Q=0.05, R=1e-3)
    plain = chain.simulate(40, seeds, **model)
    zeros = chain.simulate(40, seeds, a3=zero, a4=zero, **model)
    for c in chain.COLUMNS:
        assert plain[c].tobytes() == zeros[c].tobytes(), c
    for kernel in ("numpy", "auto"):
        want = batch.simulate(40, seeds, record=batch.TRAJECTORIES, kernel=kernel, **model)
        got = batch.simulate(40, seeds, record=batch.TRAJECTORIES, kernel=kernel, a3=zero,
                             a4=zero, **model)
        for key in want:
            assert want[key].tobytes() == got[key].tobytes(), (kernel, key)
    assert not sensor.higher(zero, zero) and sensor.higher(zero, 1e-3)
