"""The Accelerometer's slow errors (issue 42) in the built FMUs: the Python FMU, the native FMI
2.0 and the native FMI 3.0 FMU give the same bits with every term on (inputs moving, steps of
any size, a state round trip through serialised bytes); a non-finite tilt or temperature is
refused by each, with one line and nothing changed; and each refuses a serialised state whose
error part cannot be its sensor's (the native one field by field, the flicker components too)."""
import json
import math
import random

import pytest

from fuzz import differential as diff
from fuzz import native_state as ns

pytestmark = pytest.mark.integration
OK, WARNING, ERROR = diff.OK, diff.WARNING, diff.ERROR

#: Every term on (four flicker components: 3 decades).
ALL_ON = dict(bias_on=0.05, random_walk=0.02, bias_gm=0.03, tau_gm=0.02, flicker=0.01,
              tau_min=0.003, tau_max=3.0, d_inf=0.04, E_tau=0.5, T0=290.0, kT_bias=0.002,
              kT_scale=-0.003, range=1.8, a3=0.01, fc=300.0)


@pytest.fixture(scope="module")
def dirs(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("errors"))


def driver(dirs, backend):
    return diff.Driver(dirs["Accelerometer"][backend], 3 if backend.endswith("3") else 2)


def call(drv, op, *args):
    drv.logged = []
    return getattr(drv, op)(*args)[0]


def text(drv):
    return " ".join(m for _, m in drv.logged)


def started(drv, values=ALL_ON, seed=21):
    for op in (("setup", 0.0), ("enter",)):
        assert call(drv, *op) == OK, text(drv)
    assert call(drv, "setr", list(values), list(values.values())) == OK, text(drv)
    assert call(drv, "seti", ["seed"], [seed]) == OK
    assert call(drv, "exit") == OK, text(drv)


def test_the_three_fmus_give_the_same_bits_with_every_term_on(dirs):
    rng = random.Random(8)
    plan = []
    for _ in range(150):
        plan.append(([rng.uniform(-2, 2), rng.uniform(-1, 1), rng.uniform(260, 330)],
                     1e-3 * rng.choice((1, 1, 2, 3, 0.5, 0.25, 1.5, 4))))
    runs = {}
    for backend in diff.BACKENDS:
        drv = driver(dirs, backend)
        try:
            started(drv)
            t, out = 0.0, []
            for i, (inputs, h) in enumerate(plan):
                assert call(drv, "setr", ["x", "theta", "T"], inputs) == OK, text(drv)
                status, z = drv.getr(["z"])
                assert status == OK, text(drv)
                out.append(z[0])
                if i == 60:
                    assert call(drv, "gst", 0) == OK
                    saved, at = drv.ser(0)[1], (t, len(out))
                assert call(drv, "step", t, h) == OK, text(drv)
                t += h
            # the state at step 60 through its bytes, and the same steps again
            assert call(drv, "des", saved, 1) == OK and call(drv, "sst", 1) == OK, text(drv)
            t, n = at
            for inputs, h in plan[60:90]:
                assert call(drv, "setr", ["x", "theta", "T"], inputs) == OK
                out.append(drv.getr(["z"])[1][0])
                call(drv, "step", t, h)
                t += h
            assert out[-30:] == out[n - 1:n + 29]
            runs[backend] = out
        finally:
            drv.free()
    assert runs["native-fmi2"] == runs["python"]
    assert runs["native-fmi3"] == runs["python"]
    assert len(set(runs["python"])) > 100  # (they move)


ALONE = [dict(bias_on=0.05), dict(random_walk=0.02), dict(bias_gm=0.03, tau_gm=0.02),
         dict(flicker=0.01, tau_min=0.003, tau_max=3.0), dict(d_inf=0.04, E_tau=0.05),
         dict(kT_bias=0.002, kT_scale=-0.003, T0=290.0), dict(range=0.9),
         dict(tilt_alone=None)]  # (no slow error: the tilt input alone)


@pytest.mark.parametrize("fc", [0.0, 300.0])
@pytest.mark.parametrize("alone", ALONE, ids=lambda d: next(iter(d)))
def test_each_term_alone_in_steps_of_several_samples_gives_the_same_bits(dirs, alone, fc):
    """Each slow error alone, with and without the output filter, in steps of 1 to 9 samples
    with the inputs held (the native hold advances the error state and the filter over the
    samples a step spans, as Accelerometer.hold): the three FMUs' z, bit for bit."""
    rng = random.Random(len(alone) + int(fc))
    plan = [([rng.uniform(-1.5, 1.5), rng.uniform(-0.5, 0.5), rng.uniform(270, 320)],
             1e-3 * rng.randint(1, 9)) for _ in range(60)]
    runs = {}
    for backend in diff.BACKENDS:
        drv = driver(dirs, backend)
        try:
            started(drv, dict({k: v for k, v in alone.items() if k != "tilt_alone"}, fc=fc,
                              a2=0.05))
            t, out = 0.0, []
            for inputs, h in plan:
                assert call(drv, "setr", ["x", "theta", "T"], inputs) == OK, text(drv)
                status, z = drv.getr(["z"])
                assert status == OK, text(drv)
                out.append(z[0])
                assert call(drv, "step", t, h) == OK, text(drv)
                t += h
            runs[backend] = out
        finally:
            drv.free()
    assert runs["native-fmi2"] == runs["python"] and runs["native-fmi3"] == runs["python"]
    assert len(set(runs["python"])) > 50


@pytest.mark.parametrize("backend", diff.BACKENDS)
def test_a_tilt_that_moves_and_returns_gives_its_own_sine_at_every_sample(dirs, backend):
    """Each FMU keeps the sine of the held tilt (the native ones per instance, in their state):
    with the tilt moving, returning to earlier values, passing 0.0 and -0.0, and held over
    steps of several samples, every z is a0 + a1 (x + sin theta) by hand (math.sin; no noise,
    a linear sensor, no other term), to a few ulp."""
    thetas = [0.3, 0.3, -1.1, 0.3, 0.0, -0.0, 2.0, 2.0, -1.1, 0.7, 0.3, 1e-300, 0.3]
    drv = driver(dirs, backend)
    try:
        for op in (("setup", 0.0), ("enter",)):
            assert call(drv, *op) == OK, text(drv)
        values = dict(a0=0.5, a1=1.3, a2=0.0, R=1e-12, kT_bias=1e-3, T0=300.0)
        assert call(drv, "setr", list(values), list(values.values())) == OK, text(drv)
        assert call(drv, "seti", ["noise"], [0]) == OK, text(drv)
        assert call(drv, "exit") == OK, text(drv)
        t = 0.0
        for i, theta in enumerate(thetas):
            x = 0.1 * i - 0.4
            assert call(drv, "setr", ["x", "theta", "T"], [x, theta, 300.0]) == OK, text(drv)
            z = float.fromhex(drv.getr(["z"])[1][0])
            want = 0.5 + 1.3 * (x + math.sin(theta))
            assert abs(z - want) <= 4 * 2.3e-16 * (abs(want) + 1.3), (i, theta, z, want)
            h = 1e-3 * (3 if i % 4 == 1 else 1)  # (held over three samples now and then)
            assert call(drv, "step", t, h) == OK, text(drv)
            t += h
    finally:
        drv.free()


@pytest.mark.parametrize("backend", diff.BACKENDS)
def test_the_two_axes_draw_independent_measurement_noise_of_variance_R(dirs, backend):
    """Each axis's measurement noise comes from its own stream (the native FMUs draw it from
    the streams' keys, derived once): over n = 4000 samples at rest the outputs' correlation is
    within 4.5/sqrt(n) of 0 and each variance within 6 standard errors (sqrt(2/n)) of R (axes =
    2: both axes the same sensor)."""
    n, R = 4000, 1e-4
    drv = driver(dirs, backend)
    try:
        values = dict(a0=0.5, a1=1.0, a2=0.0, R=R, Ts=1e-3)
        for op in (("setup", 0.0), ("enter",), ("setr", list(values), list(values.values())),
                   ("seti", ["seed", "axes"], [5, 2]), ("exit",)):
            assert call(drv, *op) == OK, (op, text(drv))
        zs = []
        for i in range(n):
            assert call(drv, "step", i * 1e-3, 1e-3) == OK, text(drv)
            status, z = drv.getr(["z", "z_y"])
            assert status == OK, text(drv)
            zs.append((float.fromhex(z[0]), float.fromhex(z[1])))
    finally:
        drv.free()
    mx, my = sum(a for a, _ in zs) / n, sum(b for _, b in zs) / n
    zs = [(a - mx, b - my) for a, b in zs]
    vx, vy = sum(a * a for a, _ in zs) / n, sum(b * b for _, b in zs) / n
    r = sum(a * b for a, b in zs) / n / math.sqrt(vx * vy)
    assert abs(r) < 4.5 / math.sqrt(n), r
    assert abs(vx / R - 1) < 6 * math.sqrt(2 / n), vx
    assert abs(vy / R - 1) < 6 * math.sqrt(2 / n), vy


@pytest.mark.parametrize("backend", diff.BACKENDS)
@pytest.mark.parametrize("name", ["theta", "T"])
def test_a_non_finite_tilt_or_temperature_is_refused_with_one_line(dirs, backend, name):
    drv = driver(dirs, backend)
    try:
        started(drv)
        assert call(drv, "setr", ["x", "theta", "T"], [0.3, 0.2, 300.0]) == OK
        call(drv, "step", 0.0, 1e-3)
        before = drv.getr(["z"])[1]
        call(drv, "gst", 0)
        state = drv.ser(0)[1]
        for value in (math.nan, math.inf, -math.inf):
            assert call(drv, "setr", [name], [value]) == ERROR
            lines = [m for _, m in drv.logged]
            assert len(lines) == 1 and ("%s = %r is not finite" % (name, value)) in lines[0] \
                and "finite values" in lines[0], lines
        assert drv.getr(["z"])[1] == before
        call(drv, "gst", 0)
        assert drv.ser(0)[1] == state or backend == "python"  # (JSON: the same state anew)
        assert call(drv, "step", 1e-3, 1e-3) == OK
    finally:
        drv.free()


@pytest.mark.parametrize("backend", ["native-fmi2", "native-fmi3"])
def test_a_native_state_whose_error_part_cannot_be_this_sensors_is_refused(dirs, backend):
    S = ns.snapshot_type(dirs["Accelerometer"][backend])
    drv = driver(dirs, backend)
    try:
        started(drv, dict(ALL_ON, random_walk=0.0))  # (the walk off: its state must stay 0)
        call(drv, "setr", ["x", "theta"], [0.4, 0.3])
        for k in range(5):
            call(drv, "step", k * 1e-3, 1e-3)
        call(drv, "gst", 0)
        data = drv.ser(0)[1]
        s = ns.read(S, data)
        assert s.h.ecfg.fl_n == 4 and s.h.err.E > 0.0 and s.h.err.fl[3] != 0.0
        assert (s.h.tilt.theta, s.h.tilt.sine) == (0.3, pytest.approx(math.sin(0.3), rel=1e-15))
        z = drv.getr(["z"])
        call(drv, "gst", 1)
        before = (z, drv.ser(1)[1])
        cases = [("h.err.E", -1e-9, "negative exposure"), ("h.err.rw", 0.5, "err.rw = 0.5"),
                 ("h.err_pending.rw", 0.5, "err_pending.rw"),
                 ("h.err.gm", math.nan, "err.gm"), ("h.err_pending.E", math.inf, "err_pending.E"),
                 ("h.ecfg.fl_n", 5, "ecfg"), ("h.ecfg.gm_a", 0.5, "ecfg"),
                 # the held tilt's sine (a cache of ops_sin): another number, or another tilt
                 ("h.tilt.sine", 0.5, "tilt.sine = 0.5 is not the sine of tilt.theta = 0.3"),
                 ("h.tilt.theta", 0.31, "is not the sine of tilt.theta = 0.31"),
                 ("h.tilt.theta", math.inf, "tilt.theta")]
        for path, value, words in cases:
            blob = ns.crafted(S, data, path, value)
            assert call(drv, "des", blob, 2) == ERROR, path
            assert words in text(drv) and "refused" in text(drv), (path, text(drv))
        for i, value, words in ((4, 0.1, "err.fl[4] = 0.1 is a flicker component the "
                                          "parameters do not have (4 of them)"),
                                (7, -0.2, "err.fl[7]"), (2, math.nan, "err.fl[2]")):
            crafted = ns.read(S, data)
            crafted.h.err.fl[i] = value
            raw = bytearray(bytes(crafted))
            crafted.checksum = ns.checksum(raw)
            assert call(drv, "des", bytes(crafted), 2) == ERROR, i
            assert words in text(drv), text(drv)
        z = drv.getr(["z"])
        call(drv, "gst", 1)
        assert (z, drv.ser(1)[1]) == before  # nothing changed
        assert call(drv, "des", data, 2) == OK and call(drv, "sst", 2) == OK
    finally:
        drv.free()


def test_a_native_state_with_every_term_off_must_have_no_error_state(dirs):
    S = ns.snapshot_type(dirs["Accelerometer"]["native-fmi2"])
    drv = driver(dirs, "native-fmi2")
    try:
        started(drv, {})
        call(drv, "step", 0.0, 1e-3)
        call(drv, "gst", 0)
        data = drv.ser(0)[1]
        crafted = ns.read(S, data)
        crafted.h.err.fl[7] = 1e-3
        raw = bytearray(bytes(crafted))
        crafted.checksum = ns.checksum(raw)
        assert call(drv, "des", bytes(crafted), 1) == ERROR
        assert "err.fl[7] = 0.001 although every slow error is off" in text(drv), text(drv)
    finally:
        drv.free()


def test_the_python_fmus_serialised_error_state_is_checked(dirs):
    drv = driver(dirs, "python")
    try:
        started(drv)
        call(drv, "setr", ["x"], [0.4])
        call(drv, "step", 0.0, 2e-3)
        call(drv, "gst", 0)
        state = json.loads(drv.ser(0)[1])
        z = drv.getr(["z"])
        call(drv, "gst", 1)
        before = (z, drv.ser(1)[1])
        for err, words in (([0.0, 0.0, -1.0, state["_err"][3]], "negative exposure"),
                           (state["_err"][:3] + [state["_err"][3][:2]], "2 flicker components"),
                           (None, "_err of an initialised instance is missing")):
            blob = json.dumps(dict(state, _err=err)).encode()
            status = call(drv, "des", blob, 2)
            if status <= WARNING:
                status = call(drv, "sst", 2)
            assert status == ERROR and words in text(drv), text(drv)
        z = drv.getr(["z"])
        call(drv, "gst", 1)
        assert (z, drv.ser(1)[1]) == before
    finally:
        drv.free()
