"""The C port of models/ (fmu_src/native/models) against models/, bit for bit.

The C units are compiled into a shared library (with the flags the native FMUs use) and called
through ctypes; every result is compared with its Python twin by its IEEE 754 bits, over many
random inputs from fixed seeds.  Any difference fails.
"""
import ctypes
import math
import random
import shutil
import struct
import subprocess

import pytest

from driftfmu.fmu_src.native.models import generate
from driftfmu.models import _ops, adxl203, bias, chain, covariance, drift, dualaxis, ekf, \
    errors, excitation, harmonic, noise, parameters, sensor
from waiting import BOUND

CC = shutil.which("gcc") or shutil.which("cc")
UNITS = ("ops.c", "noise.c", "excitation.c", "sensor.c", "ekf.c", "drift.c", "chain.c",
         "harmonic.c", "adxl203.c", "errors.c", "parameters.c", "dualaxis.c", "covariance.c",
         "bias.c")

D, I64, U64 = ctypes.c_double, ctypes.c_int64, ctypes.c_uint64
PD, PI64 = ctypes.POINTER(D), ctypes.POINTER(I64)


class DriftState(ctypes.Structure):
    _fields_ = [("k", I64)] + [(n, D) for n in drift.DriftState._fields[1:]]


class EstimatorState(ctypes.Structure):
    _fields_ = [("x", D), ("P", D), ("drift", DriftState)]


class HarmonicState(ctypes.Structure):
    _fields_ = [("x", D), ("d", D), ("P", D), ("P12", D), ("P22", D), ("drift", DriftState)]


class Bias(ctypes.Structure):
    _fields_ = [(n, D) for n in bias.Bias._fields]


class Config(ctypes.Structure):
    _fields_ = [("plain", I64), ("a0", D), ("a1", D), ("a2", D), ("a3", D), ("R", D),
                ("sigma", D), ("cross", D), ("has_alpha", I64), ("alpha", D), ("lsb", D),
                ("levels", I64), ("a4", D), ("lo", D)]


REPORT = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p)

FLMAX = errors.FLICKER_MAX


class ErrorConfig(ctypes.Structure):
    _fields_ = [("on", I64)] + [(n, D) for n in ("bias_on", "b_on", "rw", "gm_sigma", "gm_a",
                                                 "gm_c")] + \
        [("fl_n", I64), ("fl_sigma", D), ("fl_a", D * FLMAX), ("fl_c", D * FLMAX)] + \
        [(n, D) for n in ("d_inf", "E_tau", "Ts", "T0", "kT_bias", "kT_scale", "range")]


class ErrorState(ctypes.Structure):
    _fields_ = [("rw", D), ("gm", D), ("E", D), ("fl", D * FLMAX)]


class ErrorTilt(ctypes.Structure):
    _fields_ = [("theta", D), ("sine", D)]


PTILT = ctypes.POINTER(ErrorTilt)


class Axis(ctypes.Structure):
    _fields_ = [(n, D) for n in dualaxis.Axis._fields]


class DualDrift(ctypes.Structure):
    _fields_ = [("k", I64)] + [(n, D) for n in dualaxis.DualDrift._fields[1:]]


class DualState(ctypes.Structure):
    _fields_ = [(n, D) for n in dualaxis.DualState._fields[:-1]] + [("drift", DualDrift)]


class DualHarmonicState(ctypes.Structure):
    _fields_ = [(n, D) for n in dualaxis.DualHarmonicState._fields[:-1]] + \
        [("drift", DualDrift)]


class DualEstimator(ctypes.Structure):
    _fields_ = [("g", DualState), ("h", DualHarmonicState)]


class DualModel(ctypes.Structure):
    _fields_ = [("process", I64)] + [(n, D) for n in ("A", "Q", "Qy", "Qxy", "C", "S", "Qh")]

SIGNATURES = {
    "excitation_gaussian_pair": (None, D, D, D, D, D, D, I64, I64, PD, PD),
    "excitation_correlated_pair": (None, D, D, D, D, D, D, D, D, D, D, PD, PD),
    "sensor_h_bilinear": (D, D, D, D, D, D, D),
    "sensor_measure_bilinear": (D, D, D, D, D, D, D, D, D),
    "dualaxis_measure": (None, D, D, Axis, Axis, D, D, PD, PD),
    "dualaxis_noise": (None, I64, I64, PD, PD),
    "dualaxis_sensor_problems": (ctypes.c_int, I64, D, D, D, D, I64, D, REPORT, ctypes.c_void_p),
    "dualaxis_model": (DualModel, I64, D, D, D, D, D, D, D),
    "dualaxis_estimator_init": (DualEstimator, I64, D, D, D, D),
    "dualaxis_estimator_predict": (DualEstimator, DualEstimator, ctypes.POINTER(DualModel)),
    "dualaxis_estimator_step": (DualEstimator, DualEstimator, D, D, Axis, Axis,
                                ctypes.POINTER(DualModel)),
    "ops_sqrt": (D, D), "ops_floor": (D, D), "ops_frexp": (None, D, PD, PI64),
    "ops_ldexp": (D, D, I64), "ops_log": (D, D), "ops_exp": (D, D), "ops_exp_estrin": (D, D),
    "ops_sin2pi": (D, D),
    "noise_mix": (U64, U64), "noise_key": (U64, U64, U64), "noise_bits": (U64, U64, U64, U64),
    "noise_uniform": (D, U64, U64, U64), "noise_inverse_normal_cdf": (D, D),
    "noise_normal": (D, U64, U64, U64), "noise_normal_keyed": (D, U64, U64),
    "excitation_gauss_markov": (D, D, D, D, D),
    "excitation_gaussian_sample": (D, D, D, D, I64, I64),
    "excitation_sine": (D, I64, D, D, D, D),
    "excitation_stationary_variance": (D, I64, D, D, D),
    "sensor_h": (D, D, D, D, D), "sensor_dh_dx": (D, D, D, D),
    "sensor_measure": (D, D, D, D, D, D, D), "sensor_measurement_noise": (D, I64, I64),
    "sensor_drift": (D, D, D),
    "ekf_predict": (None, D, D, D, D, PD, PD),
    "ekf_update": (None, D, D, D, D, D, D, D, PD, PD),
    "ekf_step": (None, D, D, D, D, D, D, D, D, D, PD, PD),
    "drift_initial_state": (DriftState,), "drift_running_mean": (D, D, D, I64),
    "drift_update": (DriftState, DriftState, D, D, D),
    "drift_estimates": (None, DriftState, D, PD, PD, PD),
    "drift_select": (D, ctypes.POINTER(D * 3), I64),
    "chain_estimator_init": (EstimatorState, D, D),
    "chain_estimator_step": (EstimatorState, EstimatorState, D, D, D, D, D, D, D),
    "chain_compensate": (D, D, D),
    "harmonic_rotation": (None, D, D, PD, PD),
    "harmonic_predict": (None,) + (D,) * 8 + (PD,) * 5,
    "harmonic_update": (None,) + (D,) * 10 + (PD,) * 5,
    "harmonic_step": (None,) + (D,) * 13 + (PD,) * 5,
    "harmonic_estimator_init": (HarmonicState, I64, D, D),
    "harmonic_estimator_step": (HarmonicState, HarmonicState, D, D, D, D, D, I64, D, D, D, D,
                                D),
    "harmonic_estimator_predict": (HarmonicState, HarmonicState, I64, D, D, D, D, D),
    "adxl203_sensitivity": (D, D), "adxl203_noise_sigma": (D, D, D),
    "adxl203_config": (Config, D, D, D, D, D, D, D, D, I64, D, D),
    "adxl203_noise": (D, I64, I64, I64),
    "adxl203_sense": (D, D, D, D, ctypes.POINTER(Config)),
    "adxl203_lowpass": (D, I64, D, D, I64, D),
    "adxl203_quantise": (D, D, ctypes.POINTER(Config)),
    "adxl203_measure": (None, I64, D, D, D, D, ctypes.POINTER(Config), PI64, PD, PD),
    "adxl203_hold": (None, I64, D, D, D, I64, I64, I64, ctypes.POINTER(Config), I64, I64, PI64,
                     PD),
    "adxl203_problems": (ctypes.c_int, D, D, REPORT, ctypes.c_void_p),
    "parameters_repr_float": (ctypes.c_int, D, ctypes.c_char_p, ctypes.c_size_t),
    "ops_sin": (D, D),
    "errors_turn_on": (D, D, I64),
    "errors_random_walk": (D, D, D, D),
    "errors_gauss_markov_coefficients": (None, D, D, D, PD, PD),
    "errors_gauss_markov": (D, D, D, D, D),
    "errors_flicker_taus": (I64, D, D, PD),
    "errors_allan_variance_gm": (D, D, D, D),
    "errors_flicker_sigma": (D, D, PD, I64),
    "errors_flicker": (D, PD, PD, PD, PD, I64, PD),
    "errors_exposure": (D, D, D, D, D, D, PD),
    "errors_tilt": (D, D, D, PTILT),
    "errors_temperature": (None, D, D, D, D, PD, PD),
    "errors_saturate": (D, D, D),
    "errors_config": (ErrorConfig, I64) + (D,) * 14,
    "errors_problems": (ctypes.c_int, D, D, D, REPORT, ctypes.c_void_p),
    "errors_initial_state": (ErrorState, I64, ctypes.POINTER(ErrorConfig)),
    "errors_draws": (None, I64, I64, ctypes.POINTER(ErrorConfig), PD, PD, PD),
    "errors_advance": (None, ctypes.POINTER(ErrorState), D, D, D, PD, ctypes.POINTER(ErrorConfig),
                       ctypes.POINTER(ErrorState), PD),
    "errors_advance_state": (None, ctypes.POINTER(ErrorState), D, D, D, PD,
                             ctypes.POINTER(ErrorConfig)),
    "errors_thermal_bias": (D, D, ctypes.POINTER(ErrorConfig)),
    "errors_sensed": (D, D, D, D, ctypes.POINTER(ErrorConfig), PTILT),
    "errors_hold": (ErrorState, ErrorState, D, I64, I64, I64, ctypes.POINTER(ErrorConfig)),
    "adxl203_config_ranged": (Config, D, D, D, D, D, D, D, D, I64, D, D, D, D),
    "adxl203_measure_errors": (None, I64, D, ctypes.POINTER(ErrorState), D, D, D, D, D, PD, D,
                               D, ctypes.POINTER(Config), ctypes.POINTER(ErrorConfig), PTILT,
                               PI64, PD, PD),
    "covariance_valid2": (ctypes.c_int, D, D, D),
    "covariance_valid": (ctypes.c_int, ctypes.c_int, PD),
    "covariance_refusal": (None, ctypes.c_int, PD, ctypes.POINTER(ctypes.c_char_p),
                           ctypes.c_char_p, ctypes.c_longlong, D, ctypes.c_char_p,
                           ctypes.c_size_t),
    "covariance_state_problem": (ctypes.c_int, ctypes.c_int, PD,
                                 ctypes.POINTER(ctypes.c_char_p), ctypes.c_char_p,
                                 ctypes.c_char_p, ctypes.c_size_t),
    "parameters_allowed": (ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_size_t),
    "errors_class2": (None, D, D, D, D, D, D, PTILT, PD, PD), "errors_class2_offset": (D,) + (D,) * 9,
    "bias_factor": (D, D, D), "bias_init": (Bias, D, D),
    "bias_expected": (D,) + (D,) * 7, "bias_spread": (D, D, D, D),
    "bias_predict": (None, D, D, Bias, D, D, D, D, D, D, PD, PD, ctypes.POINTER(Bias)),
    "bias_update": (None, D, D, Bias) + (D,) * 7 + (PD, PD, ctypes.POINTER(Bias)),
    "bias_estimator_step": (EstimatorState, EstimatorState, ctypes.POINTER(Bias)) + (D,) * 13,
    "bias_estimator_predict": (EstimatorState, EstimatorState, ctypes.POINTER(Bias), D, D, D, D,
                               D, D),
    "bias_compensate": (D, D, D, D),
    "parameters_problem": (ctypes.c_int, ctypes.c_char_p, D, ctypes.c_int, ctypes.c_char_p,
                           ctypes.c_size_t),
}


def compile_models(out_dir, cc=CC, name="libdriftmodels.so", extra=()):
    """Compile the models/ units into the shared library ``out_dir/name``; return its path."""
    generate.write(out_dir)
    lib = out_dir / name
    sources = [str(generate.HERE / u) for u in UNITS]
    subprocess.run([cc, *generate.CFLAGS, "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC",
                    "-I", str(out_dir), "-I", str(generate.HERE), *extra, *sources, "-o",
                    str(lib), "-lm"], check=True, capture_output=True, text=True)
    return lib


@pytest.fixture(scope="module")
def c(tmp_path_factory):
    """The compiled models/ port, with argument and result types set."""
    if CC is None:
        pytest.skip("no C compiler (gcc or cc) on PATH: the C port cannot be compiled")
    lib = ctypes.CDLL(str(compile_models(tmp_path_factory.mktemp("native_models"))))
    for fname, (res, *args) in SIGNATURES.items():
        f = getattr(lib, fname)
        f.restype, f.argtypes = res, args
    return lib


def bits(x):
    return struct.pack("<d", x)


def _pair(c, *args):
    x, y = D(), D()
    c.excitation_gaussian_pair(*args, ctypes.byref(x), ctypes.byref(y))
    return x.value, y.value


def test_correlated_pair_equals_models(c):
    """The pair from draws given by the caller (the Excitation FMU's blocks of draws)."""
    rng = random.Random(RNG_SEED + 31)
    for _ in range(2000):
        args = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-0.999, 0.999),
                rng.uniform(0, 3), rng.choice((0.0, -0.0, rng.uniform(0, 3))), rng.uniform(-1, 1),
                rng.gauss(0, 1), rng.gauss(0, 1), rng.choice((0.0, rng.uniform(-2, 2))),
                rng.uniform(-3, 3))
        x, y = D(), D()
        c.excitation_correlated_pair(*args, ctypes.byref(x), ctypes.byref(y))
        assert_same(excitation.correlated_pair(*args), (x.value, y.value), "correlated_pair")


def test_gaussian_pair_and_bilinear_sensor_equal_models(c):
    rng = random.Random(RNG_SEED + 30)
    for _ in range(2000):
        x, y, A = rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-0.999, 0.999)
        Q, Qy, rho = rng.uniform(0, 3), rng.choice((0.0, -0.0, rng.uniform(0, 3))), \
            rng.uniform(-1, 1)
        seed, k = rng.randrange(2 ** 31), rng.randint(1, 10 ** 9)
        assert_same(excitation.gaussian_pair(x, y, A, Q, Qy, rho, seed, k),
                    _pair(c, x, y, A, Q, Qy, rho, seed, k), "gaussian_pair")
        a0, a1, a2, b = rng.uniform(-3, 3), rng.uniform(-2, 2), rng.uniform(-1, 1), \
            rng.choice((0.0, rng.uniform(-1, 1)))
        R, v = 10.0 ** rng.uniform(-8, 0), rng.gauss(0, 1)
        assert same(sensor.h_bilinear(x, y, a0, a1, a2, b), c.sensor_h_bilinear(x, y, a0, a1, a2, b))
        assert same(sensor.measure_bilinear(x, y, a0, a1, a2, b, R, v),
                    c.sensor_measure_bilinear(x, y, a0, a1, a2, b, R, v))
        ax = dualaxis.Axis(a0, a1, a2, b, R)
        ay = dualaxis.Axis(rng.uniform(-3, 3), rng.uniform(-2, 2), rng.uniform(-1, 1),
                           rng.uniform(-1, 1), 10.0 ** rng.uniform(-8, 0))
        vy = rng.gauss(0, 1)
        zx, zy = D(), D()
        c.dualaxis_measure(x, y, Axis(*ax), Axis(*ay), v, vy, ctypes.byref(zx), ctypes.byref(zy))
        assert_same(dualaxis.measure(x, y, ax, ay, v, vy), (zx.value, zy.value), "measure")
        c.dualaxis_noise(seed, k, ctypes.byref(zx), ctypes.byref(zy))
        assert_same(dualaxis.noise(seed, k), (zx.value, zy.value), "noise")


def _dual_tuple(st, process):
    s = st.g if process == dualaxis.GAUSS_MARKOV else st.h
    names = (dualaxis.DualState if process == dualaxis.GAUSS_MARKOV
             else dualaxis.DualHarmonicState)._fields[:-1]
    return tuple(getattr(s, n) for n in names) + tuple(
        getattr(s.drift, n) for n in dualaxis.DualDrift._fields)


@pytest.mark.parametrize("process", [dualaxis.GAUSS_MARKOV, dualaxis.HARMONIC])
def test_dual_estimator_equals_models_over_both_process_models(c, process):
    """init, step (predict2/4, update2/4 with _row2/_row4, drift_update) and predict over a long
    random sequence, every field of the state bit for bit; with and without cross terms."""
    rng = random.Random(RNG_SEED + 31 + process)
    for case in range(8):
        b = (lambda: 0.0) if case % 4 == 0 else (lambda: rng.uniform(-0.2, 0.2))
        ax = dualaxis.Axis(rng.uniform(-1, 1), rng.uniform(0.5, 2), rng.uniform(-0.1, 0.1), b(),
                           10.0 ** rng.uniform(-6, -2))
        ay = dualaxis.Axis(rng.uniform(-1, 1), rng.uniform(0.5, 2), rng.uniform(-0.1, 0.1), b(),
                           10.0 ** rng.uniform(-6, -2))
        A, Q, Qy = rng.uniform(-0.9, 0.9), rng.uniform(0.001, 0.1), rng.uniform(0.001, 0.1)
        rho = 0.0 if case % 4 == 0 else rng.uniform(-1, 1)
        f, Ts, Qh = rng.uniform(1, 300), rng.choice((1e-3, 1e-4)), 10.0 ** rng.uniform(-10, -4)
        m = dualaxis.model(process, A=A, Q=Q, Qy=Qy, rho=rho, f=f, Ts=Ts, Qh=Qh)
        cm = c.dualaxis_model(process, A, Q, Qy, rho, f, Ts, Qh)
        assert_same([m[n] for n in ("A", "Q", "Qy", "Qxy", "C", "S", "Qh")],
                    [getattr(cm, n) for n in ("A", "Q", "Qy", "Qxy", "C", "S", "Qh")], "model")
        x0, y0, P0, P0y = rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0, 0.5), \
            rng.uniform(0, 0.5)
        py = dualaxis.estimator_init(process, x0, y0, P0, P0y)
        cs = c.dualaxis_estimator_init(process, x0, y0, P0, P0y)
        assert_same(_flat(py), _dual_tuple(cs, process), "init")
        for i in range(300):
            if rng.random() < 0.8:
                zx, zy = rng.uniform(-2, 3), rng.uniform(-2, 3)
                py = dualaxis.estimator_step(py, zx, zy, ax, ay, m)
                cs = c.dualaxis_estimator_step(cs, zx, zy, Axis(*ax), Axis(*ay), ctypes.byref(cm))
            else:
                py = dualaxis.estimator_predict(py, m)
                cs = c.dualaxis_estimator_predict(cs, ctypes.byref(cm))
            assert_same(_flat(py), _dual_tuple(cs, process), (case, i))


def _flat(st):
    return tuple(st[:-1]) + tuple(st.drift)


@pytest.mark.parametrize("values", [dict(dual=0, fc=100.0), dict(dual=1),
                                    dict(dual=1, fc=100.0, bits=12),
                                    dict(dual=1, a3=0.5, cross=-0.1, Vs=5.0, density=1e-5),
                                    dict(dual=2, bits=3, density=float("nan"))])
def test_dual_sensor_problems_same_messages(c, values):
    p = dict(dict.fromkeys(dualaxis.EXTRAS, 0.0), bits=0)
    p.update(values)
    got = []
    cb = REPORT(lambda ctx, msg: got.append(msg.decode()))
    n = c.dualaxis_sensor_problems(p["dual"], p["a3"], p["cross"], p["fc"], p["Vs"], p["bits"],
                                   p["density"], cb, None)
    assert got == dualaxis.sensor_problems(p) and n == len(got)


def same(a, b):
    """Equal IEEE 754 bits (NaN equal to NaN of the same payload, -0.0 unlike 0.0)."""
    return bits(a) == bits(b)


def assert_same(py, cv, what):
    py, cv = tuple(py), tuple(cv)
    assert len(py) == len(cv)
    for i, (a, b) in enumerate(zip(py, cv)):
        assert same(float(a), float(b)), "%s, item %d: Python %r, C %r" % (what, i, a, b)


def outs(n):
    return [D() for _ in range(n)]


def refs(values):
    return [ctypes.byref(v) for v in values]


def vals(values):
    return [v.value for v in values]


RNG_SEED = 20261201


def magnitudes(rng, n, lo=-300, hi=300):
    return [rng.uniform(0.5, 10.0) * 10.0 ** rng.uniform(lo, hi) for _ in range(n)]


def signed(rng, n, scale=10.0):
    return [rng.uniform(-scale, scale) for _ in range(n)]


# -- _ops -------------------------------------------------------------------------------------

def test_log_equals_models_bit_for_bit(c):
    rng = random.Random(RNG_SEED)
    xs = magnitudes(rng, 4000) + [rng.uniform(0.5, 2.0) for _ in range(2000)]
    xs += [5e-324, 2.2250738585072014e-308, 2.225073858507201e-308, 1e-310, 1.0, 2.0, 0.5,
           _ops.SQRT_HALF, math.nextafter(_ops.SQRT_HALF, 0.0), math.nextafter(1.0, 2.0),
           math.nextafter(1.0, 0.0), 1.7976931348623157e308, 0.02425, 1e-300]
    for x in xs:
        assert same(_ops.log(x), c.ops_log(x)), x


@pytest.mark.parametrize("name", ["exp", "exp_estrin"])
def test_exp_equals_models_bit_for_bit_and_is_close_to_math_exp(c, name):
    exp, c_exp = getattr(_ops, name), getattr(c, "ops_" + name)
    rng = random.Random(RNG_SEED + 1)
    xs = [rng.uniform(-745.2, 709.9) for _ in range(3000)] + signed(rng, 3000, 1.0)
    xs += [0.0, -0.0, 1.0, -1.0, _ops.EXP_HIGH, math.nextafter(_ops.EXP_HIGH, 1e3), _ops.EXP_LOW,
           math.nextafter(_ops.EXP_LOW, -1e3), -708.4, -740.0, 1e-300, -1e-300, 1000.0, -1000.0,
           math.inf, -math.inf, math.nan, -2.0 * math.pi * 1063.829787 * 1e-3]
    worst = 0.0
    for x in xs:
        py = exp(x)
        assert same(py, c_exp(x)), x
        ref = math.exp(x) if x <= _ops.EXP_HIGH else math.inf
        if 2.3e-308 < ref < math.inf:
            worst = max(worst, abs(py - ref) / math.ulp(ref))
    assert worst <= 2.0, "models._ops.%s is %g ulp off math.exp" % (name, worst)


def test_sin2pi_equals_models_bit_for_bit_over_large_cycle_counts(c):
    rng = random.Random(RNG_SEED + 2)
    cs = signed(rng, 2000, 1.0) + magnitudes(rng, 2000, -10, 16)
    cs += [-x for x in magnitudes(rng, 1000, -10, 16)]
    cs += [0.0, -0.0, 0.25, 0.5, 0.75, 1.0, 1e15 + 0.25, 2.0 ** 52 + 1.0, 2.0 ** 60, 1e-300]
    for x in cs:
        assert same(_ops.sin2pi(x), c.ops_sin2pi(x)), x


def test_sin_equals_models_bit_for_bit(c):
    rng = random.Random(RNG_SEED + 40)
    xs = signed(rng, 3000, 10.0) + magnitudes(rng, 1000, -12, 12) + [0.0, -0.0, math.pi,
                                                                      math.pi / 2, -math.pi / 2]
    for x in xs:
        assert same(_ops.sin(x), c.ops_sin(x)), x


def test_sqrt_floor_frexp_ldexp_equal_python(c):
    rng = random.Random(RNG_SEED + 3)
    m, e = D(), I64()
    for x in magnitudes(rng, 1000) + signed(rng, 1000, 1e6) + [0.0, -0.0, 5e-324, 2.5, -2.5]:
        if x >= 0.0:
            assert same(_ops.sqrt(x), c.ops_sqrt(x)), x
        assert same(_ops.floor(x), c.ops_floor(x)), x
        c.ops_frexp(x, ctypes.byref(m), ctypes.byref(e))
        assert (bits(m.value), e.value) == (bits(math.frexp(x)[0]), math.frexp(x)[1]), x
        n = rng.randint(-1100, 900)
        try:
            ref = _ops.ldexp(x, n)
        except OverflowError:
            ref = math.copysign(math.inf, x)
        assert same(ref, c.ops_ldexp(x, n)), (x, n)


# -- noise ------------------------------------------------------------------------------------

HUGE_K = (2 ** 31, 2 ** 32 + 7, 2 ** 53 + 1, 2 ** 63 - 1, 2 ** 63, 2 ** 64 - 1)


def test_noise_bits_uniform_normal_equal_models_for_many_seeds_streams_and_k(c):
    rng = random.Random(RNG_SEED + 4)
    cases = [(rng.randrange(2 ** 31), rng.randint(1, 5), rng.randint(1, 10 ** 6))
             for _ in range(3000)]
    cases += [(s, st, k) for s in (0, 1, 2 ** 31 - 1) for st in (1, 2, 3, 4, 5)
              for k in (1, 2, 3) + HUGE_K]
    for seed, stream, k in cases:
        assert noise.bits(seed, stream, k) == c.noise_bits(seed, stream, k), (seed, stream, k)
        assert noise.key(seed, stream) == c.noise_key(seed, stream)
        assert same(noise.uniform(seed, stream, k), c.noise_uniform(seed, stream, k))
        assert same(noise.normal(seed, stream, k), c.noise_normal(seed, stream, k)), \
            (seed, stream, k)
        assert same(noise.normal(seed, stream, k),
                    c.noise_normal_keyed(noise.key(seed, stream), k)), (seed, stream, k)
    # a k beyond 64 bits wraps as Python's (k * GOLDEN) & MASK64 does
    k = 2 ** 64 + 12345
    assert noise.bits(7, 2, k) == c.noise_bits(7, 2, k & noise.MASK64)
    assert noise._mix(0xDEADBEEF) == c.noise_mix(0xDEADBEEF)


def test_inverse_normal_cdf_equals_models_in_both_tails_and_centre(c):
    rng = random.Random(RNG_SEED + 5)
    ps = [rng.random() for _ in range(3000)] + [10.0 ** rng.uniform(-300, -1) for _ in
                                                range(1000)]
    ps += [1.0 - 10.0 ** rng.uniform(-16, -1) for _ in range(1000)]
    ps += [noise.P_LOW, math.nextafter(noise.P_LOW, 0.0), 1.0 - noise.P_LOW, 0.5, 2.0 ** -53,
           1.0 - 2.0 ** -53]
    for p in ps:
        assert same(noise.inverse_normal_cdf(p), c.noise_inverse_normal_cdf(p)), p


# -- excitation, sensor, ekf, drift, chain ------------------------------------------------------

def test_excitation_equals_models(c):
    rng = random.Random(RNG_SEED + 6)
    for _ in range(2000):
        x, A, Q, w = rng.uniform(-5, 5), rng.uniform(-0.999, 0.999), rng.uniform(0, 3), \
            rng.gauss(0, 1)
        seed, k = rng.randrange(2 ** 31), rng.randint(1, 10 ** 9)
        assert same(excitation.gauss_markov(x, A, Q, w), c.excitation_gauss_markov(x, A, Q, w))
        assert same(excitation.gaussian_sample(x, A, Q, seed, k),
                    c.excitation_gaussian_sample(x, A, Q, seed, k))
        X, f, Ts, phi = rng.uniform(0, 3), rng.uniform(0, 400), 10.0 ** rng.uniform(-6, -1), \
            rng.uniform(-10, 10)
        kk = rng.choice((1, 2, rng.randint(1, 10 ** 6), rng.randint(1, 2 ** 40)))
        assert same(excitation.sine(kk, X, f, Ts, phi), c.excitation_sine(kk, X, f, Ts, phi)), \
            (kk, X, f, Ts, phi)
        for kind in (1, 2):
            assert same(excitation.stationary_variance(kind, A=A, Q=Q, X=X),
                        c.excitation_stationary_variance(kind, A, Q, X))


def test_sensor_equals_models(c):
    rng = random.Random(RNG_SEED + 7)
    for _ in range(2000):
        x, a0, a1, a2 = rng.uniform(-5, 5), rng.uniform(-3, 3), rng.uniform(-2, 2), \
            rng.uniform(-1, 1)
        R, v = 10.0 ** rng.uniform(-8, 0), rng.gauss(0, 1)
        assert same(sensor.h(x, a0, a1, a2), c.sensor_h(x, a0, a1, a2))
        assert same(sensor.dh_dx(x, a1, a2), c.sensor_dh_dx(x, a1, a2))
        assert same(sensor.measure(x, a0, a1, a2, R, v), c.sensor_measure(x, a0, a1, a2, R, v))
        assert same(sensor.drift(a2, R), c.sensor_drift(a2, R))
        seed, k = rng.randrange(2 ** 31), rng.randint(1, 10 ** 7)
        assert same(sensor.measurement_noise(seed, k), c.sensor_measurement_noise(seed, k))


def test_ekf_equals_models_at_A_nonzero_and_large_a2(c):
    rng = random.Random(RNG_SEED + 8)
    for _ in range(2000):
        x, P = rng.uniform(-3, 3), 10.0 ** rng.uniform(-6, 1)
        A, Q, R = rng.uniform(-0.99, 0.99), 10.0 ** rng.uniform(-6, 0), 10.0 ** rng.uniform(-8, 0)
        a0, a1, a2 = rng.uniform(-1, 1), rng.choice((-1, 1)) * rng.uniform(0.1, 3), \
            rng.choice((rng.uniform(-0.05, 0.05), rng.uniform(-50, 50)))
        z = rng.uniform(-5, 5)
        o = outs(2)
        c.ekf_predict(x, P, A, Q, *refs(o))
        assert_same(ekf.predict(x, P, A, Q), vals(o), "predict")
        c.ekf_update(x, P, z, a0, a1, a2, R, *refs(o))
        assert_same(ekf.update(x, P, z, a0, a1, a2, R), vals(o), "update")
        c.ekf_step(x, P, z, a0, a1, a2, A, Q, R, *refs(o))
        assert_same(ekf.step(x, P, z, a0, a1, a2, A, Q, R), vals(o), "step")


def _drift_tuple(s):
    return tuple(getattr(s, n) for n in drift.DriftState._fields)


def assert_drift(py, cv):
    assert py.k == cv.k
    assert_same(py[1:], _drift_tuple(cv)[1:], "DriftState")


def test_drift_estimators_equal_models_over_a_long_sequence(c):
    rng = random.Random(RNG_SEED + 9)
    py, cv = drift.initial_state(), c.drift_initial_state()
    assert_drift(py, cv)
    a2 = 0.37
    dcs_type = D * 3
    for _ in range(5000):
        x, P = rng.gauss(0, 2), rng.uniform(0, 0.1)
        py, cv = drift.update(py, x, P, a2), c.drift_update(cv, x, P, a2)
        assert_drift(py, cv)
        o = outs(3)
        c.drift_estimates(cv, a2, *refs(o))
        dcs = drift.estimates(py, a2)
        assert_same(dcs, vals(o), "estimates")
        for est in (1, 2, 3):
            assert same(drift.select(dcs, est), c.drift_select(dcs_type(*vals(o)), est))
    assert math.isnan(c.drift_select(dcs_type(1.0, 2.0, 3.0), 4))
    for k in (1, 2, 10 ** 9, 2 ** 53 + 3):
        assert same(drift.running_mean(0.3, 0.7, k), c.drift_running_mean(0.3, 0.7, k))


def test_chain_estimator_equals_models(c):
    rng = random.Random(RNG_SEED + 10)
    py, cv = chain.estimator_init(0.2, 0.05), c.chain_estimator_init(0.2, 0.05)
    for _ in range(3000):
        z = rng.gauss(0.01, 1)
        py = chain.estimator_step(py, z, 0.1, 1.2, 0.3, 0.6, 0.02, 1e-3)
        cv = c.chain_estimator_step(cv, z, 0.1, 1.2, 0.3, 0.6, 0.02, 1e-3)
        assert_same(py[:2], (cv.x, cv.P), "EstimatorState")
        assert_drift(py.drift, cv.drift)
    assert same(chain.compensate(1.5, 0.25), c.chain_compensate(1.5, 0.25))


def _bias_tuple(b):
    return (b.b, b.Pxb, b.Pbb)


def test_class2_and_its_offset_equal_models(c):
    """errors.class2 (the sensor's) and class2_offset (the DriftEstimator's), the one definition
    of class 2 in both twins: the same bits, with theta 0, -0.0 and the coefficients off too."""
    rng = random.Random(RNG_SEED + 30)
    u, g = D(), D()
    for _ in range(3000):
        theta = rng.choice((0.0, -0.0, rng.uniform(-50, 50), rng.uniform(-50, 50)))
        T, T0 = rng.uniform(200, 400), rng.uniform(250, 350)
        x = rng.choice((0.0, -0.0, rng.uniform(-3, 3)))
        a1, a2 = rng.uniform(0.2, 2), rng.uniform(-1, 1)
        a3, a4 = rng.choice(((0.0, 0.0), (rng.uniform(-1, 1), rng.uniform(-1, 1))))
        kb, ks = rng.choice((0.0, rng.uniform(-1e-2, 1e-2))), rng.choice((0.0, rng.uniform(-1e-3,
                                                                                           1e-3)))
        c.errors_class2(x, theta, T, T0, kb, ks, None, ctypes.byref(u), ctypes.byref(g))
        py_u, py_c = errors.class2(x, theta, T, T0, kb, ks)
        assert same(py_u, u.value) and same(py_c, g.value)
        assert same(errors.class2_offset(theta, T, a1, a2, T0, kb, ks, a3, a4),
                    c.errors_class2_offset(theta, T, a1, a2, T0, kb, ks, a3, a4))


def test_bias_filter_equals_models(c):
    rng = random.Random(RNG_SEED + 31)
    for _ in range(2000):
        tau, Ts = rng.choice((0.0, 10.0 ** rng.uniform(-5, 2))), 10.0 ** rng.uniform(-5, -2)
        assert same(bias.factor(tau, Ts), c.bias_factor(tau, Ts))
        x, P = rng.uniform(-3, 3), 10.0 ** rng.uniform(-6, 1)
        b = bias.Bias(rng.uniform(-1, 1), rng.uniform(-1e-3, 1e-3), 10.0 ** rng.uniform(-8, -1))
        cb = Bias(*b)
        A, Q, R = rng.uniform(-0.99, 0.99), 10.0 ** rng.uniform(-6, 0), 10.0 ** rng.uniform(-8, 0)
        Fb, Qb = bias.factor(tau, Ts), rng.choice((0.0, 10.0 ** rng.uniform(-12, -2)))
        a0, a1, a2 = rng.uniform(-1, 1), rng.uniform(0.1, 3), rng.uniform(-5, 5)
        a3, a4 = rng.choice(((0.0, 0.0), (rng.uniform(-1, 1), rng.uniform(-1, 1))))
        B, u, z = rng.choice((0.0, rng.uniform(-1, 1))), rng.uniform(-1, 1), rng.uniform(-5, 5)
        assert same(bias.expected(x, P, a0, a1, a2, a3, a4),
                    c.bias_expected(x, P, a0, a1, a2, a3, a4))
        assert same(bias.spread(R, a2, P), c.bias_spread(R, a2, P))
        o, ob = outs(2), Bias()
        c.bias_predict(x, P, cb, A, Q, Fb, Qb, B, u, *refs(o), ctypes.byref(ob))
        want = bias.predict(x, P, b, A, Q, Fb, Qb, B, u)
        assert_same(want[:2] + tuple(want[2]), tuple(vals(o)) + _bias_tuple(ob), "predict")
        c.bias_update(x, P, cb, z, a0, a1, a2, R, a3, a4, *refs(o), ctypes.byref(ob))
        want = bias.update(x, P, b, z, a0, a1, a2, R, a3, a4)
        assert_same(want[:2] + tuple(want[2]), tuple(vals(o)) + _bias_tuple(ob), "update")
        assert same(bias.compensate(z, x, b.b), c.bias_compensate(z, x, b.b))
    init = c.bias_init(0.3, 1e-3)
    assert _bias_tuple(init) == tuple(bias.init(0.3, 1e-3))
    assert bits(c.bias_init(0.0, -0.0).Pxb) == bits(bias.init(0.0, -0.0).Pxb)


def test_bias_estimator_equals_models_over_a_long_sequence(c):
    rng = random.Random(RNG_SEED + 32)
    py, pb = chain.estimator_init(0.2, 0.05), bias.init(0.01, 1e-3)
    cv, cb = c.chain_estimator_init(0.2, 0.05), Bias(*bias.init(0.01, 1e-3))
    Fb = bias.factor(0.05, 1e-3)
    for i in range(3000):
        z, u = rng.gauss(0.01, 1), rng.gauss(0, 1)
        a3, a4 = (0.02, -0.01) if i >= 1500 else (0.0, 0.0)
        if rng.random() < 0.3:
            py, pb = bias.estimator_predict(py, pb, 0.6, 0.02, Fb, 1e-7, 0.4, u)
            cv = c.bias_estimator_predict(cv, ctypes.byref(cb), 0.6, 0.02, Fb, 1e-7, 0.4, u)
        else:
            py, pb = bias.estimator_step(py, pb, z, 0.1, 1.2, 0.3, 0.6, 0.02, 1e-3, Fb, 1e-7,
                                         a3, a4, 0.4, u)
            cv = c.bias_estimator_step(cv, ctypes.byref(cb), z, 0.1, 1.2, 0.3, 0.6, 0.02, 1e-3,
                                       Fb, 1e-7, a3, a4, 0.4, u)
        assert_same(py[:2] + tuple(pb), (cv.x, cv.P) + _bias_tuple(cb), "bias estimator")
        assert_drift(py.drift, cv.drift)


# -- harmonic ---------------------------------------------------------------------------------

def _h_tuple(s):
    return (s.x, s.d, s.P, s.P12, s.P22)


def assert_estimator(py, cv):
    if isinstance(py, chain.EstimatorState):
        assert_same((py.x, py.P), (cv.x, cv.P), "EstimatorState")
    else:
        assert_same(py[:5], _h_tuple(cv), "HarmonicState")
    assert_drift(py.drift, cv.drift)


def test_harmonic_filter_equals_models(c):
    rng = random.Random(RNG_SEED + 11)
    for _ in range(1500):
        f, Ts = rng.uniform(0, 499), 10.0 ** rng.uniform(-5, -3)
        o2 = outs(2)
        c.harmonic_rotation(f, Ts, *refs(o2))
        C, S = harmonic.rotation(f, Ts)
        assert_same((C, S), vals(o2), "rotation")
        st = [rng.uniform(-2, 2), rng.uniform(-2, 2), 10.0 ** rng.uniform(-5, 0),
              rng.uniform(-1e-3, 1e-3), 10.0 ** rng.uniform(-5, 0)]
        Qh, R, z = 10.0 ** rng.uniform(-10, -2), 10.0 ** rng.uniform(-8, 0), rng.uniform(-3, 3)
        a0, a1, a2 = rng.uniform(-1, 1), rng.uniform(0.2, 2), rng.uniform(-20, 20)
        o5 = outs(5)
        c.harmonic_predict(*st, C, S, Qh, *refs(o5))
        assert_same(harmonic.predict(*st, C, S, Qh), vals(o5), "predict")
        c.harmonic_update(*st, z, a0, a1, a2, R, *refs(o5))
        assert_same(harmonic.update(*st, z, a0, a1, a2, R), vals(o5), "update")
        c.harmonic_step(*st, z, a0, a1, a2, C, S, Qh, R, *refs(o5))
        assert_same(harmonic.step(*st, z, a0, a1, a2, C, S, Qh, R), vals(o5), "step")


@pytest.mark.parametrize("process", [harmonic.GAUSS_MARKOV, harmonic.HARMONIC])
def test_harmonic_estimator_equals_models_over_both_process_models(c, process):
    rng = random.Random(RNG_SEED + 12 + process)
    for x0, P0 in ((0.0, 0.01), (-0.3, 1.0), (0.7, 0.0)):
        py = harmonic.estimator_init(process, x0, P0)
        cv = c.harmonic_estimator_init(process, x0, P0)
        assert_estimator(py, cv)
        C, S = harmonic.rotation(150.0, 1e-3)
        model = dict(process=process, A=0.8, Q=0.02, C=C, S=S, Qh=1e-6)
        for _ in range(1500):
            z = 0.01 + rng.gauss(0, 1)
            if rng.random() < 0.3:
                py = harmonic.estimator_predict(py, **model)
                cv = c.harmonic_estimator_predict(cv, process, 0.8, 0.02, C, S, 1e-6)
            else:
                py = harmonic.estimator_step(py, z, 0.1, 1.1, 0.05, 1e-3, **model)
                cv = c.harmonic_estimator_step(cv, z, 0.1, 1.1, 0.05, 1e-3, process, 0.8, 0.02,
                                               C, S, 1e-6)
            assert_estimator(py, cv)
    # the harmonic model's quadrature starts at 0.0 * x0: -0.0 for a negative x0
    if process == harmonic.HARMONIC:
        assert bits(c.harmonic_estimator_init(process, -1.0, 1.0).d) == bits(-0.0)
    assert math.isnan(c.harmonic_estimator_init(3, 0.0, 1.0).x)


# -- adxl203 ----------------------------------------------------------------------------------

CONFIG_ARGS = ("a0", "a1", "a2", "R", "a3", "cross", "fc", "Vs", "bits", "density", "Ts")


def c_config(c, p):
    return c.adxl203_config(*(p[n] for n in CONFIG_ARGS))


def assert_config(py, cv):
    assert bool(py.plain) == bool(cv.plain)
    assert_same((py.a0, py.a1, py.a2, py.a3, py.R, py.sigma, py.cross, py.lsb),
                (cv.a0, cv.a1, cv.a2, cv.a3, cv.R, cv.sigma, cv.cross, cv.lsb), "Config")
    assert (py.alpha is not None) == bool(cv.has_alpha)
    if py.alpha is not None:
        assert same(py.alpha, cv.alpha)
    assert py.levels == cv.levels


def random_sensor(rng, every_extra=True):
    on = (lambda: True) if every_extra else (lambda: rng.random() < 0.5)
    return dict(a0=rng.uniform(-1, 3), a1=rng.uniform(0.2, 2), a2=rng.uniform(-0.1, 0.1),
                R=10.0 ** rng.uniform(-8, -1), a3=rng.uniform(-0.01, 0.01) if on() else 0.0,
                cross=rng.uniform(-0.05, 0.05) if on() else 0.0,
                fc=rng.uniform(1, 2500) if on() else 0.0,
                Vs=rng.uniform(3, 6) if on() else 0.0, bits=rng.randint(1, 24) if on() else 0,
                density=10.0 ** rng.uniform(-6, -3) if on() else 0.0,
                Ts=10.0 ** rng.uniform(-5, -2))


def test_adxl203_config_equals_models_with_every_extra_on_and_the_preset(c):
    rng = random.Random(RNG_SEED + 14)
    sets = [random_sensor(rng, every_extra=i % 2 == 0) for i in range(600)]
    sets.append(adxl203.sensor_parameters(**adxl203.ADXL203))
    sets.append(adxl203.sensor_parameters())
    for p in sets:
        assert_config(adxl203.config(**p), c_config(c, p))
    for Vs in (0.0, 3.0, 3.3, 5.0, 6.0):
        assert same(adxl203.sensitivity(Vs), c.adxl203_sensitivity(Vs))


def test_adxl203_sense_filter_adc_measure_hold_equal_models(c):
    rng = random.Random(RNG_SEED + 15)
    for i in range(300):
        p = random_sensor(rng, every_extra=i % 3 != 0)
        cfg = adxl203.config(**p)
        ccfg = c_config(c, p)
        pc = ctypes.byref(ccfg)
        seed = rng.randrange(2 ** 31)
        lp, lp_set, lp_c = None, 0, 0.0
        for k in range(1, 40):
            own, other, v = rng.uniform(-2, 2), rng.uniform(-2, 2), rng.gauss(0, 1)
            assert same(adxl203.sense(own, other, v, cfg), c.adxl203_sense(own, other, v, pc))
            V = rng.uniform(-1, 7)
            assert same(adxl203.quantise(V, cfg), c.adxl203_quantise(V, pc)), (V, p)
            e_set, e, z = I64(), D(), D()
            c.adxl203_measure(lp_set, lp_c, own, other, v, pc, ctypes.byref(e_set),
                              ctypes.byref(e), ctypes.byref(z))
            lp, zp = adxl203.measure(lp, own, other, v, cfg)
            assert same(zp, z.value), (k, p)
            assert (lp is not None) == bool(e_set.value)
            if lp is not None:
                assert same(lp, e.value)
            lp_set, lp_c = e_set.value, e.value
            m, axis, noise_on = rng.randint(1, 6), rng.choice((1, 2)), rng.choice((0, 1))
            lp = adxl203.hold(lp, own, other, seed, k, m, cfg, axis=axis, noise_on=noise_on)
            c.adxl203_hold(lp_set, lp_c, own, other, seed, k, m, pc, axis, noise_on,
                           ctypes.byref(e_set), ctypes.byref(e))
            assert (lp is not None) == bool(e_set.value)
            if lp is not None:
                assert same(lp, e.value)
            lp_set, lp_c = e_set.value, e.value
            for axis in (1, 2):
                assert same(adxl203.noise(seed, k, axis), c.adxl203_noise(seed, k, axis))
        for prev in (None, 0.3):
            s, alpha = rng.uniform(-1, 1), rng.choice((None, 0.9))
            assert same(adxl203.lowpass(prev, s, alpha),
                        c.adxl203_lowpass(prev is not None, prev or 0.0, s, alpha is not None,
                                          alpha or 0.0))


def collect(call, *args):
    """Messages a C check reports, in order, and the count it returns."""
    got = []
    cb = REPORT(lambda ctx, msg: got.append(msg.decode()))
    n = call(*args, cb, None)
    return n, got


@pytest.mark.parametrize("Vs, fc", [(0.0, 0.0), (5.0, 1064.0), (2.0, 0.0), (7.5, 3000.0),
                                    (6.000000000000001, 2500.0), (0.1, 2500.000001),
                                    (-1.0, -3.0)])
def test_adxl203_problems_same_messages(c, Vs, fc):
    n, got = collect(c.adxl203_problems, Vs, fc)
    assert got == adxl203.problems(dict(Vs=Vs, fc=fc))
    assert n == len(got)


# -- errors: the sensor's slow errors -----------------------------------------------------------

ERROR_ARGS = ("seed", "Ts", "bias_on", "random_walk", "bias_gm", "tau_gm", "flicker", "tau_min",
              "tau_max", "d_inf", "E_tau", "T0", "kT_bias", "kT_scale", "range")


def random_errors(rng, every=False):
    """Parameters of the slow errors, each on with probability 1/2 (all with ``every``)."""
    on = (lambda: True) if every else (lambda: rng.random() < 0.5)
    lo = 10.0 ** rng.uniform(-4, 1)
    return dict(bias_on=rng.uniform(0, 0.3) if on() else 0.0,
                random_walk=10.0 ** rng.uniform(-4, 0) if on() else 0.0,
                bias_gm=rng.uniform(0, 0.2) if on() else 0.0, tau_gm=10.0 ** rng.uniform(-4, 3),
                flicker=10.0 ** rng.uniform(-4, -1) if on() else 0.0, tau_min=lo,
                tau_max=lo * 10.0 ** rng.uniform(0.01, 6.9),
                d_inf=rng.uniform(-0.2, 0.2) if on() else 0.0, E_tau=10.0 ** rng.uniform(-3, 2),
                T0=rng.uniform(250, 320), kT_bias=rng.uniform(-0.01, 0.01) if on() else 0.0,
                kT_scale=rng.uniform(-0.01, 0.01) if on() else 0.0,
                range=rng.uniform(0.5, 3) if on() else 0.0)


def c_errors(c, p):
    return c.errors_config(*(p[n] for n in ERROR_ARGS))


def error_state(py, cs, fl_n):
    """The Python ErrorState against the C one: every field and every component bit for bit,
    the components beyond fl_n 0.0."""
    assert_same((py.rw, py.gm, py.E) + tuple(py.fl) + (0.0,) * (FLMAX - fl_n),
                (cs.rw, cs.gm, cs.E) + tuple(cs.fl), "ErrorState")


def test_error_processes_equal_models_function_for_function(c):
    rng = random.Random(RNG_SEED + 41)
    o2 = outs(2)
    for _ in range(2000):
        b, n, a, cc = rng.gauss(0, 1), rng.gauss(0, 1), rng.uniform(0, 1), rng.uniform(0, 1)
        seed = rng.randrange(2 ** 31)
        assert same(errors.turn_on(b, seed), c.errors_turn_on(b, seed))
        assert same(errors.random_walk(b, a, n), c.errors_random_walk(b, a, n))
        assert same(errors.gauss_markov(b, a, cc, n), c.errors_gauss_markov(b, a, cc, n))
        sigma, tau, Ts = rng.uniform(0, 2), 10.0 ** rng.uniform(-6, 6), 10.0 ** rng.uniform(-6, 0)
        c.errors_gauss_markov_coefficients(sigma, tau, Ts, *refs(o2))
        assert_same(errors.gauss_markov_coefficients(sigma, tau, Ts), vals(o2), "coefficients")
        T = 10.0 ** rng.uniform(-8, 8)
        assert same(errors.allan_variance_gm(sigma, tau, T),
                    c.errors_allan_variance_gm(sigma, tau, T)), (sigma, tau, T)
        lo = 10.0 ** rng.uniform(-5, 3)
        hi = lo * 10.0 ** rng.choice((rng.uniform(1e-9, 7), 1.0, 2.0, 7.0))
        taus = (D * FLMAX)()
        m = c.errors_flicker_taus(lo, hi, taus)
        py_taus = errors.flicker_taus(lo, hi)
        assert m == len(py_taus)
        assert_same(py_taus, taus[:m], "flicker_taus")
        assert same(errors.flicker_sigma(sigma, py_taus), c.errors_flicker_sigma(sigma, taus, m))
        comps = [rng.gauss(0, 1) for _ in range(m)]
        aa = [rng.uniform(0, 1) for _ in range(m)]
        cs_ = [rng.uniform(0, 1) for _ in range(m)]
        ns = [rng.gauss(0, 1) for _ in range(m)]
        out = (D * FLMAX)()
        total = c.errors_flicker((D * FLMAX)(*comps), (D * FLMAX)(*aa), (D * FLMAX)(*cs_),
                                 (D * FLMAX)(*ns), m, out)
        py_out, py_total = errors.flicker(comps, aa, cs_, ns)
        assert_same(py_out + (py_total,), tuple(out[:m]) + (total,), "flicker")
        E, x, d_inf, E_tau = rng.uniform(0, 5), rng.uniform(-3, 3), rng.uniform(-1, 1), \
            10.0 ** rng.uniform(-3, 3)
        E_out = D()
        d = c.errors_exposure(E, x, Ts, d_inf, E_tau, ctypes.byref(E_out))
        assert_same(errors.exposure(E, x, Ts, d_inf, E_tau), (E_out.value, d), "exposure")
        theta, T, T0 = rng.uniform(-7, 7), rng.uniform(200, 400), rng.uniform(250, 320)
        assert same(errors.tilt(x, theta), c.errors_tilt(x, theta, None))
        kb, ks = rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01)
        c.errors_temperature(T, T0, kb, ks, *refs(o2))
        assert_same(errors.temperature(T, T0, kb, ks), vals(o2), "temperature")
        limit = rng.uniform(0.1, 3)
        for u in (x, limit, -limit, 10 * x, math.nan, math.inf, -math.inf):
            assert same(errors.saturate(u, limit), c.errors_saturate(u, limit)), (u, limit)


def test_error_config_state_draws_and_composition_equal_models(c):
    """config, initial_state, draws, advance, sensed, thermal_bias, hold and the composed
    sample (adxl203.measure_errors, through the plain and the extras' path, with the ADC over
    the range) over random parameters and inputs, every field bit for bit."""
    rng = random.Random(RNG_SEED + 42)
    for case in range(300):
        p = dict(random_errors(rng, every=case % 3 == 0), seed=rng.randrange(2 ** 31),
                 Ts=10.0 ** rng.uniform(-5, -1))
        ecfg = errors.config(**p)
        cfg_c = c_errors(c, p)
        assert (ecfg.on, ecfg.fl_n) == (bool(cfg_c.on), cfg_c.fl_n)
        reals = ("bias_on", "b_on", "rw", "gm_sigma", "gm_a", "gm_c", "fl_sigma", "d_inf",
                 "E_tau", "Ts", "T0", "kT_bias", "kT_scale", "range")
        assert_same([getattr(ecfg, n) for n in reals], [getattr(cfg_c, n) for n in reals],
                    "ErrorConfig")
        assert_same(ecfg.fl_a + ecfg.fl_c, cfg_c.fl_a[:ecfg.fl_n] + cfg_c.fl_c[:ecfg.fl_n],
                    "flicker coefficients")
        assert not any(cfg_c.fl_a[ecfg.fl_n:]) and not any(cfg_c.fl_c[ecfg.fl_n:])
        pe = ctypes.byref(cfg_c)
        state, cstate = errors.initial_state(p["seed"], ecfg), \
            c.errors_initial_state(p["seed"], pe)
        error_state(state, cstate, ecfg.fl_n)
        sp = dict(random_sensor(rng, every_extra=rng.random() < 0.4), Ts=p["Ts"],
                  range=p["range"])
        sp["fc"] = min(sp["fc"], 0.4 / sp["Ts"])
        if rng.random() < 0.3:  # the ADC over the range
            sp.update(Vs=0.0, bits=rng.randint(1, 16))
        cfg = adxl203.config(**sp)
        ccfg = c.adxl203_config_ranged(*(sp[n] for n in CONFIG_ARGS), 0.0, sp["range"])
        assert_config(cfg, ccfg)
        assert same(cfg.lo, ccfg.lo)
        lp, lp_set, lp_c = None, 0, 0.0
        cs_state = ErrorState(cstate.rw, cstate.gm, cstate.E, cstate.fl)
        held = ErrorTilt(0.0, 0.0)  # the sine of the held tilt, carried from sample to sample
        for k in range(1, 30):
            x, y, v = rng.uniform(-2, 2), rng.uniform(-2, 2), rng.gauss(0, 1)
            theta, T = rng.choice((0.0, rng.uniform(-2, 2))), rng.uniform(230, 350)
            n_rw, n_gm, n_fl = D(), D(), (D * FLMAX)()
            c.errors_draws(p["seed"], k, pe, ctypes.byref(n_rw), ctypes.byref(n_gm), n_fl)
            draws = errors.draws(p["seed"], k, ecfg)
            assert_same((draws[0], draws[1]) + draws[2],
                        (n_rw.value, n_gm.value) + tuple(n_fl[:ecfg.fl_n]), "draws")
            assert same(errors.sensed(x, theta, T, ecfg),
                        c.errors_sensed(x, theta, T, pe, ctypes.byref(ErrorTilt())))
            assert same(errors.thermal_bias(T, ecfg), c.errors_thermal_bias(T, pe))
            b = D()
            st2, b_py = errors.advance(state, x, *draws, ecfg)
            cst2 = ErrorState()
            c.errors_advance(ctypes.byref(cs_state), x, n_rw, n_gm, n_fl, pe,
                             ctypes.byref(cst2), ctypes.byref(b))
            error_state(st2, cst2, ecfg.fl_n)
            assert same(b_py, b.value)
            cst3 = ErrorState(cs_state.rw, cs_state.gm, cs_state.E, cs_state.fl)
            c.errors_advance_state(ctypes.byref(cst3), x, n_rw, n_gm, n_fl, pe)
            error_state(errors.advance_state(state, x, *draws, ecfg), cst3, ecfg.fl_n)
            error_state(st2, cst3, ecfg.fl_n)
            e_set, e, z = I64(), D(), D()
            c.adxl203_measure_errors(lp_set, lp_c, ctypes.byref(cs_state), x, y, v, n_rw, n_gm,
                                     n_fl, theta, T, ctypes.byref(ccfg), pe, ctypes.byref(held),
                                     ctypes.byref(e_set), ctypes.byref(e), ctypes.byref(z))
            lp, state, zp = adxl203.measure_errors(lp, state, x, y, v, draws, theta, T, cfg,
                                                   ecfg)
            assert same(zp, z.value), (k, p, sp)
            assert (lp is not None) == bool(e_set.value)
            if lp is not None:
                assert same(lp, e.value)
            lp_set, lp_c = e_set.value, e.value
            error_state(state, cs_state, ecfg.fl_n)
        m = rng.randint(1, 9)
        after = errors.hold(state, 0.7, p["seed"], 29, m, ecfg)
        error_state(after, c.errors_hold(cs_state, 0.7, p["seed"], 29, m, pe), ecfg.fl_n)


def test_the_held_tilts_sine_is_the_sine_of_the_tilt_held(c):
    """errors_tilt with the sine of the held tilt (the native Accelerometer's cache, the C form
    of models.errors._TILT): every value of a sequence that holds, changes, returns to a tilt,
    passes 0.0 and -0.0, the bits of the sine computed afresh and of models/; the cache holds
    the last tilt and its sine."""
    rng = random.Random(RNG_SEED + 43)
    held = ErrorTilt(0.0, 0.0)
    thetas = [0.3, 0.3, 0.3, -1.2, -1.2, 0.3, 0.0, -0.0, -0.0, 0.0, 5e-324, -5e-324, 2.5]
    thetas += [rng.choice((rng.uniform(-7, 7), thetas[-1])) for _ in range(400)]
    for theta in thetas:
        x = rng.uniform(-2, 2)
        got = c.errors_tilt(x, theta, ctypes.byref(held))
        assert same(got, c.errors_tilt(x, theta, None)) and same(got, errors.tilt(x, theta))
        assert same(held.theta, theta) and same(held.sine, c.ops_sin(theta))
    stale = ErrorTilt(0.3, 0.5)  # a sine that is not the held theta's would be used as it is:
    assert c.errors_tilt(0.0, 0.3, ctypes.byref(stale)) == 0.5  # hence the state check


@pytest.mark.parametrize("flicker, tau_min, tau_max", [
    (0.01, 1.0, 1.0), (0.01, 2.0, 1.0), (0.01, 1e-3, 1e4), (0.01, 1e-3, 10000.001),
    (0.0, 2.0, 1.0), (0.01, -1.0, 2.0), (0.01, 0.1, float("nan")), (1e-9, 0.3, 3e6)])
def test_errors_problems_same_messages(c, flicker, tau_min, tau_max):
    n, got = collect(c.errors_problems, flicker, tau_min, tau_max)
    assert got == errors.problems(dict(flicker=flicker, tau_min=tau_min, tau_max=tau_max))
    assert n == len(got)


# -- covariance -------------------------------------------------------------------------------

def _random_lower(rng, n):
    """The lower triangle of a random symmetric n x n matrix near the PSD boundary (rows by
    rows), now and then with a zero or negative variance, a tiny or huge scale, NaN or inf."""
    cols = [[rng.gauss(0, 1) for _ in range(rng.randint(1, n))] for _ in range(n)]
    scale = 10.0 ** rng.uniform(-300, 300)
    lower = [[sum(a * b for a, b in zip(cols[i], cols[j])) * scale
              * (1.0 + rng.choice([0.0, 1e-16, 1e-7, 1e-5, 0.3]) * rng.gauss(0, 1))
              for j in range(i + 1)] for i in range(n)]
    r = rng.random()
    if r < 0.1:
        i = rng.randrange(n)
        lower[i][i] = rng.choice([0.0, -0.0, -lower[i][i], -5e-324])
    elif r < 0.13:
        i = rng.randrange(n)
        lower[i][rng.randrange(i + 1)] = rng.choice([math.nan, math.inf, -math.inf])
    return lower


def test_covariance_rule_and_messages_equal_models(c):
    """covariance_valid2, covariance_valid, the refusal of a step and the problem of a restored
    state: the answers and the texts of models/covariance.py."""
    rng = random.Random(RNG_SEED + 31)
    buf = ctypes.create_string_buffer(2048)
    answers = []
    for n in (1, 2, 3, 4) * 1500:
        lower = _random_lower(rng, n)
        flat = [v for row in lower for v in row]
        arr = (D * len(flat))(*flat)
        want = covariance.valid(lower)
        assert bool(c.covariance_valid(n, arr)) is want, lower
        if n == 2:
            assert bool(c.covariance_valid2(*flat)) is want, lower
        answers.append(want)
        names = [("N%d%d" % (i, j)) for i in range(n) for j in range(i + 1)]
        nested = [[names[i * (i + 1) // 2 + j] for j in range(i + 1)] for i in range(n)]
        cnames = (ctypes.c_char_p * len(names))(*[x.encode() for x in names])
        listing = rng.choice([None, "the covariance (all) of hidden state _state"])
        clisting = None if listing is None else listing.encode()
        k, t = rng.randint(1, 10 ** 6), rng.uniform(-10, 10)
        if not want:
            c.covariance_refusal(n, arr, cnames, clisting, k, t, buf, 2048)
            assert buf.value.decode() == covariance.refusal(nested, lower, k, t, listing)
        got = c.covariance_state_problem(n, arr, cnames, clisting, buf, 2048)
        want_lines = covariance.state_problems(nested, lower, listing)
        assert got == len(want_lines)
        if want_lines:
            assert buf.value.decode() == want_lines[0]
    assert 1000 < sum(answers) < len(answers) - 1000


# -- parameters -------------------------------------------------------------------------------

def test_repr_float_is_pythons_repr(c):
    rng = random.Random(RNG_SEED + 16)
    xs = [struct.unpack("<d", struct.pack("<Q", rng.getrandbits(64)))[0] for _ in range(3000)]
    xs += magnitudes(rng, 2000, -20, 20) + [round(rng.uniform(-1e4, 1e4), rng.randint(0, 6))
                                            for _ in range(1000)]
    xs += [0.0, -0.0, 1.0, -1.0, 0.1, 1e16, 1e15, 9999999999999998.0, 1e-4, 1e-5, 0.00012,
           5e-324, 1.7976931348623157e308, math.inf, -math.inf, math.nan, 1e-9, 2.5e-05, 123.0]
    buf = ctypes.create_string_buffer(64)
    for x in xs:
        c.parameters_repr_float(x, buf, 64)
        assert buf.value.decode() == repr(x), x


def test_allowed_and_problem_messages_equal_models(c):
    buf = ctypes.create_string_buffer(parameters_max := 512)
    rng = random.Random(RNG_SEED + 17)
    for name, p in parameters.PARAMETERS.items():
        assert c.parameters_allowed(name.encode(), buf, parameters_max) >= 0
        assert buf.value.decode() == parameters.allowed(name)
        integer = isinstance(p.default, int)
        edges = [v for b in (p.low, p.high) if b is not None
                 for v in (b, math.nextafter(b, -math.inf), math.nextafter(b, math.inf))]
        values = edges + [0.0, 1.0, -1.0, 0.5, 2 ** 31, -(2 ** 31), 1e300, -1e300] + \
            [rng.uniform(-3, 3) for _ in range(20)]
        for v in values:
            if integer and (v != int(v) or not -2 ** 31 <= v < 2 ** 31):
                continue  # an Integer variable holds 32-bit ints
            v = int(v) if integer else float(v)
            want = parameters.problem(name, v)
            got = c.parameters_problem(name.encode(), float(v), integer, buf, parameters_max)
            assert got == (want is not None), (name, v)
            if want is not None:
                assert buf.value.decode() == want
        for v in (math.inf, -math.inf, math.nan):
            if not integer:
                assert c.parameters_problem(name.encode(), v, 0, buf, parameters_max) == 1
                assert buf.value.decode() == parameters.problem(name, v)
        if integer:  # a fraction is a wrong type, in range or not: "not an integer"
            for v in (0.5, -1.5, 2.25, 1e10 + 0.5):
                assert c.parameters_problem(name.encode(), v, 0, buf, parameters_max) == 1
                assert buf.value.decode() == parameters.problem(name, v)
                assert " is not an integer; allowed: " in buf.value.decode()
    assert c.parameters_allowed(b"nonsense", buf, 512) == -1


# == the per-model step logic (fmu_src/native/models/<Model>_step.c) ============================
#
# Each model's step logic is compiled with a harness (tests/native_harness) into its own shared
# library and driven here as the plumbing drives it: the sample planning of the step rule below
# is slave_base's (the Python FMUs'), so the C hooks are checked against the Python slaves and
# against models.adxl203.simulate, bit for bit.

from pathlib import Path  # noqa: E402

from driftfmu.fmu_src import slave_base  # noqa: E402
from driftfmu.fmu_src.Accelerometer import ERROR_SWITCHES, Accelerometer  # noqa: E402
from driftfmu.fmu_src.DriftEstimator import DriftEstimator  # noqa: E402
from driftfmu.fmu_src.DualDriftEstimator import DualDriftEstimator  # noqa: E402
from driftfmu.fmu_src.Excitation import Excitation  # noqa: E402

HARNESS = Path(__file__).resolve().parent / "native_harness"
NATIVE = generate.HERE.parent
SLAVES = {"Excitation": Excitation, "Accelerometer": Accelerometer,
          "DriftEstimator": DriftEstimator, "DualDriftEstimator": DualDriftEstimator}
#: The step rule of slave_base (any h > 0).
VARIABLE_STEPS = hasattr(slave_base, "MAX_SAMPLES_PER_STEP")


def config_h(slave):
    """config.h of a model as the native build writes it (the parts the step logic uses)."""
    try:  # the native build's own generator, once the native branch is in the tree
        from driftfmu.fmu_src import native_build
        if (NATIVE / "model.h").exists():
            return native_build.config_h(slave, "{test}", 2)
    except (ImportError, AttributeError, TypeError):  # not there (or another signature)
        pass
    lines = ["#include <stddef.h>", '#define MODEL_NAME "%s"' % slave.__name__,
             "#define N_VARIABLES %d" % len(slave.VARIABLES),
             "#define MODEL_HAS_FEEDTHROUGH %d" % bool(slave.DEPENDENCIES),
             '#include "%s_step.h"' % slave.__name__, "typedef struct {"]
    lines += ["    %s %s;" % ("double" if s["type"] == "Real" else "int", s["name"])
              for s in slave.VARIABLES]
    lines += ["} ModelVariables;", "static const VariableInfo MODEL_VARIABLES[N_VARIABLES] = {"]
    lines += ['    {"%s", TYPE_%s, CAUSALITY_%s, offsetof(ModelVariables, %s)},'
              % (s["name"], s["type"].upper(), s["causality"].upper(), s["name"])
              for s in slave.VARIABLES]
    lines += ["};", "#define MODEL_START_VALUES { %s }" % ", ".join(
        repr(float(s["start"] or 0)) if s["type"] == "Real" else str(int(s["start"] or 0))
        for s in slave.VARIABLES)]
    return "\n".join(lines) + "\n"


def step_sources(name):
    return [generate.HERE / u for u in generate.UNITS[name]] + [HARNESS / "harness.c"]


def write_generated(folder, name):
    folder.mkdir(parents=True, exist_ok=True)
    generate.write(folder)
    (folder / "config.h").write_text(config_h(SLAVES[name]))
    return folder


def include_dirs(gen):
    """The generated headers, the plumbing's model.h and the C port's headers."""
    return ["-I", str(gen), "-I", str(NATIVE), "-I", str(generate.HERE)]


def run_parallel(commands, timeout=BOUND, env=None):
    """Run the commands at once (two cores: the compilations overlap); their stdout, in order.
    A failing command fails the test with its stderr."""
    procs = [subprocess.Popen(c, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env) for c in commands]
    outs = []
    for c, p in zip(commands, procs):
        out, err = p.communicate(timeout=timeout)
        assert p.returncode == 0, "%s failed (%d): %s" % (" ".join(c[:1]), p.returncode, err)
        outs.append(out)
    return outs


H_SIGNATURES = {
    "h_new": (ctypes.c_void_p,), "h_free": (None, ctypes.c_void_p), "h_size": (ctypes.c_size_t,),
    "h_copy": (None, ctypes.c_void_p, ctypes.c_void_p),
    "h_index": (ctypes.c_int, ctypes.c_char_p), "h_set": (None, ctypes.c_void_p, ctypes.c_int, D),
    "h_get": (D, ctypes.c_void_p, ctypes.c_int), "h_set_k": (None, ctypes.c_void_p,
                                                             ctypes.c_longlong),
    "h_check": (ctypes.c_int, ctypes.c_void_p), "h_start": (None, ctypes.c_void_p),
    "h_compute": (ctypes.c_char_p, ctypes.c_void_p),
    "h_advance": (ctypes.c_char_p, ctypes.c_void_p, ctypes.c_longlong, ctypes.c_longlong,
                  ctypes.c_int, ctypes.c_int, ctypes.c_longlong),
    "h_log": (ctypes.c_char_p,), "h_log_clear": (None,),
}


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """name -> the compiled step logic of that model (one shared library each)."""
    if CC is None:
        pytest.skip("no C compiler (gcc or cc) on PATH: the C port cannot be compiled")
    root = tmp_path_factory.mktemp("native_steps")
    libs, outs = {}, {name: root / ("lib%s.so" % name) for name in SLAVES}
    run_parallel([[CC, *generate.CFLAGS, "-Wall", "-Wextra", "-Werror", "-shared", "-fPIC",
                   *include_dirs(write_generated(root / name, name)),
                   *map(str, step_sources(name)), "-o", str(out), "-lm"]
                  for name, out in outs.items()])
    for name, out in outs.items():
        lib = ctypes.CDLL(str(out))
        for fname, (res, *args) in H_SIGNATURES.items():
            f = getattr(lib, fname)
            f.restype, f.argtypes = res, args
        libs[name] = lib
    return libs


TOL = 1e-6  # slave_base.INSTANT_TOLERANCE


def neumaier(s, c, h):
    """slave_base's running sum of the step sizes: ``(s + h, compensation)`` (Neumaier)."""
    t = s + h
    return t, c + (((s - t) + h) if abs(s) >= h else ((h - t) + s))


class CSlave:
    """One native model driven through its hooks, with the plumbing's part (sample planning,
    feedthrough refresh, dirty and pending flags) done as slave_base does it."""

    def __init__(self, lib, name, values=()):
        self.lib, self.name, self.slave = lib, name, SLAVES[name]
        self.p = lib.h_new()
        self.index = {s["name"]: i for i, s in enumerate(self.slave.VARIABLES)}
        self.feedthrough = bool(self.slave.DEPENDENCIES)
        for n, v in dict(values).items():
            self.set(n, v)
        self.k, self.at_sample, self.dirty, self.initialised = 1, True, True, False
        self.elapsed = self.comp = 0.0

    def __del__(self):
        self.lib.h_free(self.p)

    def set(self, name, value):
        self.lib.h_set(self.p, self.index[name], value)
        self.dirty = True

    def raw(self, name):
        return self.lib.h_get(self.p, self.index[name])

    def get(self, name):
        if self.feedthrough and self.dirty and self.at_sample and self.initialised:
            bad = self.lib.h_compute(self.p)
            assert bad is None, bad
            self.dirty = False
        return self.raw(name)

    def check(self):
        self.lib.h_log_clear()
        n = self.lib.h_check(self.p)
        msgs = [m for m in self.lib.h_log().decode().split("\n") if m]
        assert n == len(msgs)
        return msgs

    def initialise(self):
        assert self.check() == []
        self.lib.h_start(self.p)
        self.lib.h_set_k(self.p, 1)
        self.initialised, self.dirty = True, True

    def step(self, h):
        """slave_base._step's planning; the hooks do the rest."""
        Ts, k = self.raw("Ts"), self.k
        elapsed, comp = neumaier(self.elapsed, self.comp, h) if VARIABLE_STEPS else \
            (self.elapsed + h, 0.0)
        position = (elapsed + comp) / Ts
        last = math.ceil(position - TOL)
        m = max(0, last + 1 - k)
        at = last <= position + TOL
        self.elapsed, self.comp = elapsed, comp
        if m and self.at_sample:
            self.get(self.slave.VARIABLES[0]["name"])  # refresh of the pending sample
        bad = self.lib.h_advance(self.p, k, m, bool(m and self.at_sample), at, k + m)
        assert bad is None, bad
        self.k, self.at_sample, self.dirty = k + m, at, True
        self.lib.h_set_k(self.p, k + m)

    def save(self):
        buf = ctypes.create_string_buffer(self.lib.h_size())
        self.lib.h_copy(buf, self.p)
        return buf, (self.k, self.at_sample, self.dirty, self.elapsed, self.comp)

    def restore(self, saved):
        buf, (self.k, self.at_sample, self.dirty, self.elapsed, self.comp) = saved
        self.lib.h_copy(self.p, buf)


def py_slave(name, values=()):
    """The Python slave (no FMU built), with start values set."""
    s = SLAVES[name](instance_name=name)
    for n, v in dict(values).items():
        setattr(s, n, v)
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    assert s._initialised, [m.msg for m in s.log_queue]
    return s


def py_vr(slave, name):
    return next(i for i, s in enumerate(slave.VARIABLES) if s["name"] == name)


def py_get(slave, name):
    return slave.get_real([py_vr(slave, name)])[0]


def py_set(slave, name, value):
    slave.set_real([py_vr(slave, name)], [value])


def outputs_of(name):
    return [s["name"] for s in SLAVES[name].VARIABLES if s["causality"] == "output"]


def inputs_of(name):
    return [s["name"] for s in SLAVES[name].VARIABLES if s["causality"] == "input"]


def random_values(name, rng):
    if name == "Excitation":
        return dict(kind=rng.choice((1, 2)), A=rng.uniform(-0.95, 0.95), Q=rng.uniform(0, 0.1),
                    x0=rng.uniform(-1, 1), X=rng.uniform(0, 2), f=rng.uniform(1, 120),
                    phi=rng.uniform(-3, 3), Xy=rng.uniform(0, 1), phiy=rng.uniform(-3, 3),
                    Ts=rng.choice((1e-3, 2.5e-3, 1e-4)), seed=rng.randrange(2 ** 31),
                    Qy=rng.choice((0.0, rng.uniform(0, 0.1))), rho=rng.uniform(-1, 1))
    if name == "Accelerometer":
        p = random_sensor(rng, every_extra=rng.random() < 0.5)
        p.update(noise=rng.choice((0, 1)), seed=rng.randrange(2 ** 31),
                 axes=rng.choice((1, 2)), Ts=rng.choice((1e-3, 1e-4)))
        p["fc"] = min(p["fc"], 0.4 / p["Ts"])
        if rng.random() < 0.5:  # the slow errors (models.errors)
            p.update(random_errors(rng))
        if rng.random() < 0.4:  # the dual-axis bilinear sensor (models.dualaxis)
            p.update({n: 0 if n == "bits" else 0.0 for n in dualaxis.EXTRAS})
            p.update({n: 0.0 for n in ERROR_SWITCHES})
            p.update(random_dual_sensor(rng), dual=1)
        return p
    if name == "DualDriftEstimator":
        p = random_dual_sensor(rng)
        p.update(A=rng.uniform(-0.9, 0.9), Q=rng.uniform(0.001, 0.1), Qy=rng.uniform(0.001, 0.1),
                 rho=rng.uniform(-1, 1), x0=rng.uniform(-0.5, 0.5), y0=rng.uniform(-0.5, 0.5),
                 P0=rng.uniform(0, 0.1), P0y=rng.uniform(0, 0.1), Ts=rng.choice((1e-3, 1e-4)),
                 estimator=rng.randint(1, 3), process=rng.choice((1, 2)),
                 f=rng.uniform(1, 300), Qh=10.0 ** rng.uniform(-10, -4))
        return p
    p = dict(a0=rng.uniform(-1, 1), a1=rng.uniform(0.5, 2), a2=rng.uniform(-0.1, 0.1),
             A=rng.uniform(-0.9, 0.9), Q=rng.uniform(0.001, 0.1), R=10.0 ** rng.uniform(-6, -2),
             x0=rng.uniform(-0.5, 0.5), P0=rng.uniform(0, 0.1), Ts=rng.choice((1e-3, 1e-4)),
             estimator=rng.randint(1, 3), process=rng.choice((1, 2)), f=rng.uniform(1, 300),
             Qh=10.0 ** rng.uniform(-10, -4))
    if rng.random() < 0.5:  # the bias state (Gauss-Markov process model only)
        p.update(bias=1, process=1, Qb=rng.choice((0.0, 10.0 ** rng.uniform(-12, -4))),
                 tau_b=rng.choice((0.0, 10.0 ** rng.uniform(-4, 1))), b0=rng.uniform(-0.1, 0.1),
                 Pb0=rng.uniform(0, 0.01), a3=rng.choice((0.0, 0.01)), B=rng.uniform(-1, 1))
    if rng.random() < 0.5:  # the class-2 coefficients (the inputs theta, T are random)
        p.update(kT_bias=rng.uniform(-1e-3, 1e-3), kT_scale=rng.choice((0.0, 1e-4)),
                 T0=rng.uniform(1, 3))
    return p


def random_dual_sensor(rng):
    """Both axes of the dual-axis sensor, with cross terms (sometimes 0)."""
    b = (lambda: rng.choice((0.0, rng.uniform(-0.1, 0.1))))
    return dict(a0=rng.uniform(-1, 1), a1=rng.uniform(0.5, 2), a2=rng.uniform(-0.1, 0.1),
                bx=b(), R=10.0 ** rng.uniform(-6, -2), a0y=rng.uniform(-1, 1),
                a1y=rng.uniform(0.5, 2), a2y=rng.uniform(-0.1, 0.1), by=b(),
                Ry=10.0 ** rng.uniform(-6, -2))


def random_steps(rng, Ts, count):
    """Communication steps: mostly whole numbers of samples, fractional ones with the step rule."""
    steps = []
    for _ in range(count):
        r = rng.random()
        if r < 0.5 or not VARIABLE_STEPS:
            steps.append(Ts * rng.choice((1, 1, 1, 2, 3, 7)))
        elif r < 0.8:
            steps.append(Ts * rng.uniform(0.05, 3.5))
        else:
            steps.append(Ts * rng.choice((0.5, 0.25, 1.5)))
    return steps


@pytest.mark.parametrize("name", list(SLAVES))
def test_step_logic_equals_the_python_slave_over_random_parameters_and_steps(models, name):
    """Random parameters, inputs and steps (multi-sample, and fractional under the step rule),
    with an FMU state saved and restored in the middle: every output equal bit for bit."""
    rng = random.Random(RNG_SEED + 100 + len(name))
    for case in range(12):
        values = random_values(name, rng)
        py, cs = py_slave(name, values), CSlave(models[name], name, values)
        cs.initialise()
        steps = random_steps(rng, values["Ts"], 60)
        saved = None
        for i, h in enumerate(steps):
            for n in inputs_of(name):
                v = rng.uniform(-1.5, 3.0)
                py_set(py, n, v)
                cs.set(n, v)
            for n in outputs_of(name):
                assert same(py_get(py, n), cs.get(n)), (case, i, n, values)
            if i == 20:
                saved = (cs.save(), py._get_fmu_state())
            if i == 40:  # back to step 20 and the same steps again: the same bits
                cs.restore(saved[0])
                py._set_fmu_state(saved[1])
                for h2 in steps[20:40]:
                    py.do_step(0.0, h2)
                    cs.step(h2)
            assert py.do_step(0.0, h) is not False
            cs.step(h)
        for n in outputs_of(name):
            assert same(py_get(py, n), cs.get(n)), (case, "end", n, values)


def py_problems(name, values):
    s = SLAVES[name](instance_name=name)
    for n, v in values.items():
        setattr(s, n, v)
    return s.check_parameters()


BAD = {"Ts": (0.0, -1e-3, 1e-12, 1e-9, 5.0), "R": (0.0, -1.0, 5e-324), "A": (1.0, -1.0, 0.5),
       "Q": (-0.1,), "P0": (-1.0,), "a1": (0.0,), "seed": (-1, 2 ** 31 - 1), "kind": (0, 3),
       "f": (-1.0, 600.0, 499.99), "X": (-1.0,), "noise": (2, -1), "bits": (25, -1, 12),
       "axes": (0, 3), "Vs": (2.0, 6.5, 5.0), "fc": (3000.0, -1.0), "cross": (1.5,),
       "density": (-1e-6,), "estimator": (0, 4), "process": (0, 3, 2), "Qh": (-1e-9,),
       "Qy": (-0.1,), "rho": (1.5, -1.0, float("nan")), "Ry": (0.0, -1.0), "a1y": (0.0,),
       "dual": (1, 2, -1), "P0y": (-1.0,), "bias": (2, -1, 1), "Qb": (-1e-9,),
       "tau_b": (-0.1,), "Pb0": (-1.0,), "T0": (0.0, -1.0),
       "bias_on": (-0.1, 0.2), "random_walk": (-1.0, 0.5), "bias_gm": (-0.1, 0.3),
       "flicker": (-0.01, 0.02), "tau_gm": (0.0, -2.0), "tau_min": (0.0, 1e-14, 200.0),
       "tau_max": (0.05, 1e20), "E_tau": (0.0, -1.0), "range": (-1.0, 1.0),
       "kT_scale": (0.01,),
       **({"a2": (1e308,), "a3": (1.7e308,)} if VARIABLE_STEPS else {})}
#: effective values of the slow errors that overflow: random_walk sqrt(Ts), bias_on n_0
BAD["random_walk"] += (1e308,)
BAD["bias_on"] += (1.7e308,)
BAD["Ts"] += (100.0,)


@pytest.mark.parametrize("name", list(SLAVES))
def test_parameter_checks_give_the_python_slaves_messages(models, name):
    rng = random.Random(RNG_SEED + 200 + len(name))
    names = [s["name"] for s in SLAVES[name].VARIABLES if s["causality"] == "parameter"]
    bad = [n for n in names if n in BAD]
    for case in range(150):
        values = random_values(name, rng)
        for n in rng.sample(bad, rng.randint(0, 3)):
            values[n] = rng.choice(BAD[n])
        if name == "Accelerometer" and VARIABLE_STEPS and rng.random() < 0.2:
            # effective values that overflow (checked by the hardened slaves)
            values.update(a1=1.7e308, Vs=6.0, a3=0.0)
        values = {n: v for n, v in values.items() if n in names}
        cs = CSlave(models[name], name, values)
        assert cs.check() == py_problems(name, values), values


# -- whole runs: the three models chained sample by sample against models.adxl203.simulate ----

COLUMNS = ("x", "y", "z", "z_y", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")


def chain_run(models, n, ex, sp, es, Ts):
    e = CSlave(models["Excitation"], "Excitation", dict(ex, Ts=Ts))
    a = CSlave(models["Accelerometer"], "Accelerometer", dict(sp, Ts=Ts))
    d = CSlave(models["DriftEstimator"], "DriftEstimator", dict(es, Ts=Ts))
    for s in (e, a, d):
        s.initialise()
    cols = {c: [] for c in COLUMNS}
    for _ in range(n):
        x, y = e.get("x"), e.get("y")
        a.set("x", x)
        a.set("y", y)
        z = a.get("z")
        d.set("z", z)
        row = dict(x=x, y=y, z=z, z_y=a.get("z_y"))
        row.update({c: d.get(c) for c in ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3",
                                          "z_comp")})
        for c in COLUMNS:
            cols[c].append(row[c])
        for s in (e, a, d):
            s.step(Ts)
    return cols


def assert_run(models, n, ex, sp, es, Ts):
    ref = adxl203.simulate(n, ex, sp, es, Ts)
    got = chain_run(models, n, ex, sp, es, Ts)
    for c in COLUMNS:
        for k, (a, b) in enumerate(zip(ref[c], got[c]), start=1):
            assert same(a, b), "%s at sample %d: Python %r, C %r" % (c, k, a, b)


def test_gaussian_paper_run_equals_models_bit_for_bit(models):
    assert_run(models, 4000, dict(seed=7), dict(seed=7), dict(estimator=1), 1e-3)


def test_sinusoidal_run_with_the_harmonic_filter_equals_models_bit_for_bit(models):
    ex = dict(kind=excitation.SINUSOIDAL, X=1.0, f=150.0, phi=0.4, seed=3)
    es = dict(process=harmonic.HARMONIC, f=150.0, P0=0.5, estimator=3)
    assert_run(models, 4000, ex, dict(seed=3), es, 1e-3)


def test_adxl203_preset_run_equals_models_bit_for_bit(models):
    ex = dict(kind=excitation.SINUSOIDAL, X=1.02, f=200.0, phi=1.3, Xy=0.51, phiy=-0.7, seed=11)
    sp = dict(adxl203.ADXL203, seed=11, noise=1)
    es = dict(a0=2.5, a1=1.0, a2=0.01, R=1.2e-5, process=harmonic.HARMONIC, f=200.0, Qh=1e-8,
              P0=1.0, estimator=1)
    assert_run(models, 6000, ex, sp, es, 1e-4)


# -- the same bits on Windows: mingw-w64 build under wine ---------------------------------------

MINGW = shutil.which("x86_64-w64-mingw32-gcc")
WINE = next((w for w in ("/usr/lib/wine/wine64", shutil.which("wine64") or "",
                         shutil.which("wine") or "") if w and Path(w).exists()), None)


@pytest.mark.qualification
def test_windows_build_under_wine_prints_the_linux_bits(tmp_path):
    """tests/native_harness/bits_main.c (the models/ math over a grid, a 3000-step run of each
    model's step logic with whole-sample and fractional steps, the check messages of a bad
    parameter set) compiled with gcc and with x86_64-w64-mingw32-gcc: the Windows programs run
    under wine print the same hex bits and messages, line for line."""
    if CC is None:
        pytest.skip("no C compiler (gcc or cc) on PATH")
    if MINGW is None:
        pytest.skip("x86_64-w64-mingw32-gcc not installed (Debian: gcc-mingw-w64-x86-64)")
    if WINE is None:
        pytest.skip("wine64 not installed (Debian: wine64); /usr/lib/wine/wine64 is absent")
    builds = []
    for name in SLAVES:
        gen = write_generated(tmp_path / name, name)
        sources = [*map(str, step_sources(name)), str(HARNESS / "bits_main.c")]
        flags = [*generate.CFLAGS, "-Wall", "-Wextra", "-Werror", *include_dirs(gen)]
        builds.append([CC, *flags, *sources, "-o", str(tmp_path / (name + ".elf")), "-lm"])
        builds.append([MINGW, *flags, "-D__USE_MINGW_ANSI_STDIO=1", *sources, "-o",
                       str(tmp_path / (name + ".exe")), "-lm"])
    run_parallel(builds)
    linux = run_parallel([[str(tmp_path / (name + ".elf"))] for name in SLAVES])
    # wine's own temporary folder (wine-XXXXXX) in the test's folder
    env = dict(__import__("os").environ, WINEDEBUG="-all", TMPDIR=str(tmp_path))
    windows = []
    for name in SLAVES:
        # to files, one after the other: a wineserver started by the first program inherits
        # its pipes, so reading a pipe to its end would wait for the wineserver to exit
        out, err = tmp_path / (name + ".out"), tmp_path / (name + ".err")
        with open(out, "w") as fo, open(err, "w") as fe:
            rc = subprocess.run([WINE, str(tmp_path / (name + ".exe"))], stdout=fo, stderr=fe,
                                stdin=subprocess.DEVNULL, env=env, timeout=600).returncode
        assert rc == 0, "%s.exe under wine failed (%d): %s" % (name, rc, err.read_text()[-2000:])
        windows.append(out.read_text().replace("\r\n", "\n"))
    for name, lin, win in zip(SLAVES, linux, windows):
        lines = lin.splitlines()
        assert len(lines) > 3000 and lines[-1].startswith(("Ts = ", "kind = ", "noise = ",
                                                           "estimator = ", "f = ", "fc = ",
                                                           "tau_min = ")), \
            lines[-3:]
        for i, (a, b) in enumerate(zip(lines, win.splitlines())):
            assert a == b, "%s, line %d: Linux %r, Windows %r" % (name, i + 1, a, b)
        assert len(win.splitlines()) == len(lines), name
