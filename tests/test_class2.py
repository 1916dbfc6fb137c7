"""Class 2 (tilt and temperature) is defined once, ``models/errors.py`` ``class2``: the
Accelerometer senses ``u = (1 + kT_scale dT)(x + sin theta)`` and adds ``kT_bias dT``; the
DriftEstimator, given the same coefficients and inputs, evaluates it at ``x = 0``
(``class2_offset``) and removes that offset before filtering.

So the chain Accelerometer -> DriftEstimator (the slave classes; the native twins equal them bit
for bit, tests/test_native_models.py) leaves no class-2 offset in ``z - dc_class2``: to rounding,
not to the bit.  The sensor evaluates ``h`` at the tilted, scaled acceleration in one polynomial
and adds the temperature's offset after the noise, the estimator subtracts the offset as one
number; floating-point addition is not associative, so the two differ by the rounding of those
sums (at most 2 ulp of the output here, never 0 on most samples).  The bound below is 4 ulp of
the output's magnitude, and a coefficient 10 % off, or the offset not removed, is millions of
ulp away from it.
"""
import math

import numpy as np
import pytest

from driftfmu.models import errors

from test_errors_fmu import get, initialised, put
from test_slaves import set_var
from test_bias_fmu import slave as estimator

SENSOR = dict(a0=0.3, a1=1.1, a2=0.05, a3=0.01, R=1e-4, Ts=1e-3)
CLASS2 = dict(T0=293.15, kT_bias=2e-3, kT_scale=-1.5e-3)
TILT, WARM = 0.35, 318.0  # rad, K: an offset of 0.42 V
N = 1500


def chain(theta, T, xs, estimator_class2=CLASS2, seed=11):
    """Each sample of the Accelerometer (``xs`` the true acceleration, the tilt and temperature
    held) into the DriftEstimator (white-state filter of the same sensor): the arrays of ``z``,
    ``dc_class2``, ``z_comp``, ``x_hat``, ``dc_ekf1``."""
    acc = initialised(seed=seed, **SENSOR, **CLASS2)
    est = estimator(dict(SENSOR, A=0.0, Q=0.01, **estimator_class2))
    out = []
    for k, x in enumerate(xs):
        put(acc, "x", float(x))
        for s, setter in ((acc, put), (est, set_var)):
            setter(s, "theta", theta)
            setter(s, "T", T)
        z = get(acc, "z")
        set_var(est, "z", z)
        out.append((z,) + tuple(get(est, n) for n in ("dc_class2", "z_comp", "x_hat", "dc_ekf1")))
        assert acc.do_step(k * 1e-3, 1e-3) and est.do_step(k * 1e-3, 1e-3)
    return {n: np.array(c) for n, c in zip(("z", "dc_class2", "z_comp", "x_hat", "dc_ekf1"),
                                           zip(*out))}


def ulps(values):
    return np.spacing(np.abs(values))


def test_at_rest_the_estimator_with_the_sensors_coefficients_removes_the_offset_to_rounding():
    """x = 0: z - dc_class2 is the output of the same sensor without tilt and temperature (the
    same noise), within 4 ulp at every sample; the filter then gives the same estimates to
    rounding."""
    rest = np.zeros(N)
    on, off = chain(TILT, WARM, rest), chain(0.0, CLASS2["T0"], rest)
    g = (1 + CLASS2["kT_scale"] * (WARM - CLASS2["T0"])) * math.sin(TILT)
    by_hand = CLASS2["kT_bias"] * (WARM - CLASS2["T0"]) + 1.1 * g + 0.05 * g * g + 0.01 * g ** 3
    assert on["dc_class2"] == pytest.approx(np.full(N, by_hand), rel=1e-14)
    assert np.all(off["dc_class2"] == 0.0) and by_hand > 0.4
    residue = (on["z"] - on["dc_class2"]) - off["z"]
    assert np.all(np.abs(residue) <= 4 * ulps(on["z"])), np.abs(residue / ulps(on["z"])).max()
    assert np.any(residue != 0.0)  # (rounding, not bits: see the module's docstring)
    for name in ("z_comp", "x_hat", "dc_ekf1"):
        assert np.abs(on[name] - off[name]).max() <= 1e-14, name


def test_with_the_state_moving_only_the_offset_goes_and_the_sensed_state_stays():
    """x moving (a sinusoid): z - dc_class2 = a0 + h0(u) - h0(g) + sqrt(R) v, u the sensed
    (tilted, scaled) acceleration and g its value at x = 0, computed by hand with math.sin:
    what is left is the sensor's response to its state, no constant."""
    k = np.arange(N)
    xs = 0.8 * np.sin(2 * math.pi * 7.0 * k * 1e-3 + 0.3)
    on, off = chain(TILT, WARM, xs), chain(0.0, CLASS2["T0"], xs)
    scale = 1 + CLASS2["kT_scale"] * (WARM - CLASS2["T0"])
    g = scale * math.sin(TILT)
    u = scale * (xs + math.sin(TILT))

    def h0(v):
        return 1.1 * v + 0.05 * v * v + 0.01 * v ** 3

    noise = off["z"] - (0.3 + h0(xs))  # the same draws without class 2
    want = 0.3 + (h0(u) - h0(g)) + noise
    got = on["z"] - on["dc_class2"]
    assert np.abs(got - want).max() <= 1e-14
    # the constant is gone: the mean of what is left is the sensed state's, not the offset's
    assert abs(np.mean(got - want)) <= 1e-15


@pytest.mark.parametrize("wrong", [dict(kT_bias=1.1 * CLASS2["kT_bias"]),
                                   dict(kT_scale=1.1 * CLASS2["kT_scale"]),
                                   dict(kT_bias=0.0, kT_scale=0.0)])
def test_coefficients_off_by_a_fraction_leave_a_residue_far_beyond_rounding(wrong):
    """The bound above can fail: a coefficient 10 % off (or none) leaves a class-2 residue of
    that fraction of its term, a million ulp and more."""
    rest = np.zeros(200)
    on = chain(TILT, WARM, rest, estimator_class2=dict(CLASS2, **wrong))
    off = chain(0.0, CLASS2["T0"], rest)
    residue = (on["z"] - on["dc_class2"]) - off["z"]
    assert np.all(np.abs(residue) > 1e6 * ulps(on["z"]))
    g = (1 + CLASS2["kT_scale"] * (WARM - CLASS2["T0"])) * math.sin(TILT)
    want = errors.class2_offset(TILT, WARM, 1.1, 0.05, CLASS2["T0"], CLASS2["kT_bias"],
                                CLASS2["kT_scale"], 0.01) - \
        errors.class2_offset(TILT, WARM, 1.1, 0.05, CLASS2["T0"],
                             dict(CLASS2, **wrong)["kT_bias"], dict(CLASS2, **wrong)["kT_scale"],
                             0.01)
    assert residue == pytest.approx(np.full(200, want), abs=1e-14) and abs(want) > 1e-5 * g
