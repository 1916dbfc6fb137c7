"""The native plumbing's undo (fmu_src/native/cosimulation.c): a step or a refresh of the
feedthrough outputs that a model hook fails saves only what model.h lets a hook change (the
outputs and the hidden state) and puts it back; the whole instance, as its serialised FMU state
shows byte for byte, is as before the refused call.  FMI 2.0 and FMI 3.0.
"""
import pytest

from fuzz import differential as diff

pytestmark = pytest.mark.integration

OK, ERROR = diff.OK, diff.ERROR
NATIVE = ("native-fmi2", "native-fmi3")


@pytest.fixture(scope="module")
def dirs(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("plumbing"))


def ready(dirs, name, backend, reals, ints=None):
    """An instance of ``name`` initialised with the parameters ``reals`` / ``ints``."""
    drv = diff.Driver(dirs[name][backend], 3 if backend.endswith("3") else 2)
    assert drv.setup(0.0)[0] == OK and drv.enter()[0] == OK
    if ints:
        assert drv.seti(list(ints), list(ints.values()))[0] == OK
    assert drv.setr(list(reals), list(reals.values()))[0] == OK
    assert drv.exit()[0] == OK, drv.logged
    return drv


def state_bytes(drv):
    """The instance's serialised FMU state (every field: variables, hidden state, time, flags)."""
    assert drv.gst("s")[0] == OK
    status, data = drv.ser("s")
    assert status == OK and data
    assert drv.fst("s")[0] == OK
    return data


@pytest.mark.parametrize("backend", NATIVE)
def test_a_step_that_overflows_inside_the_model_changes_no_byte(dirs, backend):
    # the harmonic model's covariance grows by Qh per predict: sample 30 of the step overflows
    drv = ready(dirs, "DriftEstimator", backend, {"Qh": 1e307, "P0": 0.0}, {"process": 2})
    try:
        outputs = ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp"]
        assert drv.getr(outputs)[0] == OK      # the pending sample computed (a refresh)
        before, values = state_bytes(drv), drv.getr(outputs)
        drv.logged = []
        assert drv.step(0.0, 30e-3)[0] == ERROR
        assert any("would not be finite in the step" in m and "nothing was changed" in m
                   for _, m in drv.logged), drv.logged
        assert state_bytes(drv) == before
        assert drv.getr(outputs) == values
        assert drv.step(0.0, 1e-3)[0] == OK    # a step the model can take still goes on
    finally:
        drv.free()


@pytest.mark.parametrize("backend", NATIVE)
@pytest.mark.parametrize("name, reals, inputs", [
    ("DriftEstimator", {}, {"z": 1e200}),
    ("Accelerometer", {"a2": 1e308}, {"x": 2.0}),
])
def test_a_refresh_that_overflows_changes_no_byte(dirs, backend, name, reals, inputs):
    drv = ready(dirs, name, backend, reals)
    try:
        assert drv.step(0.0, 1e-3)[0] == OK
        assert drv.setr(list(inputs), list(inputs.values()))[0] == OK
        before = state_bytes(drv)
        output = "dc" if name == "DriftEstimator" else "z"
        drv.logged = []
        assert drv.getr([output])[0] == ERROR
        assert any("would not be finite at sample 2" in m and "nothing was changed" in m
                   for _, m in drv.logged), drv.logged
        assert state_bytes(drv) == before
        assert drv.step(1e-3, 1e-3)[0] == ERROR   # the same inputs: refused again, no change
        assert state_bytes(drv) == before
    finally:
        drv.free()


@pytest.mark.parametrize("backend", NATIVE)
def test_a_step_refused_after_its_own_refresh_leaves_the_outputs_due(dirs, backend):
    """An input set, then a step: the step first computes the pending sample from the new input
    (a refresh, which marks the outputs current) and then overflows.  The refusal puts the
    outputs back, so they must be marked due again, or a get returns the outputs of the old
    input without a word: the whole instance is as before the step, flags included."""
    drv = ready(dirs, "DriftEstimator", backend, {"Qh": 1e307, "P0": 0.0}, {"process": 2})
    twin = ready(dirs, "DriftEstimator", backend, {"Qh": 1e307, "P0": 0.0}, {"process": 2})
    try:
        outputs = ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp"]
        for d in (drv, twin):
            assert d.getr(outputs)[0] == OK   # the pending sample with z = 0
            assert d.setr(["z"], [0.5])[0] == OK
        before = state_bytes(drv)
        assert drv.step(0.0, 30e-3)[0] == ERROR
        assert state_bytes(drv) == before
        assert drv.getr(outputs) == twin.getr(outputs)   # computed from z = 0.5, as the twin's
    finally:
        drv.free()
        twin.free()
