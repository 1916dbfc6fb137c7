"""The FMI plumbing's contract (issue 31), each case on the Python FMU (pythonfmu behind the
loader shim), the native FMI 2.0 FMU and the native FMI 3.0 FMU, through raw calls
(tests/fuzz/differential.py's Driver):

- a state belongs to the instance that made it: FreeInstance frees it, and a state whose
  instance is gone, another instance's state or a handle never issued is refused with a reason;
"""
import pytest

from fuzz import differential as diff

pytestmark = pytest.mark.integration
OK, WARNING, ERROR = diff.OK, diff.WARNING, diff.ERROR
BACKENDS = diff.BACKENDS


@pytest.fixture(scope="module")
def dirs(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("contract"))


def driver(dirs, name, backend):
    return diff.Driver(dirs[name][backend], 3 if backend.endswith("3") else 2)


def call(drv, op, *args):
    """Run one call with a fresh log; its status."""
    drv.logged = []
    return getattr(drv, op)(*args)[0]


def said(drv):
    return " ".join(m for _, m in drv.logged)


def initialised(drv, steps=1):
    for op in (("setup", 0.0), ("enter",), ("exit",)):
        assert call(drv, *op) == OK, drv.logged
    for i in range(steps):
        assert call(drv, "step", i * 1e-3, 1e-3) == OK, drv.logged
    return steps * 1e-3


# -- a state lives and dies with its instance ----------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_a_state_lives_only_with_its_instance(dirs, backend):
    """FreeInstance frees every state of the instance (FMI 2.0 and 3.0: it frees all memory the
    FMU's functions allocated): a state kept across it is refused by the next instance of the
    same library (the Python FMU's shim even hands the same instance back from its pool), as
    is another live instance's state (to move a state, serialise it) and a handle never issued;
    each refusal says which it is, and none reads the handle.  A get-state into another
    instance's state leaves that state alone."""
    outs = diff.model_info(dirs["DriftEstimator"]["native-fmi2"])["outputs"]
    a = driver(dirs, "DriftEstimator", backend)
    b = driver(dirs, "DriftEstimator", backend)
    try:
        t = initialised(a)
        assert call(a, "gst", 0) == OK
        status, saved = a.ser(0)
        assert status == OK
        assert call(a, "step", t, 1e-3) == OK
        expected = a.getr(outs)
        assert call(a, "renew") == OK  # the instance freed with its state, a new one made
        initialised(a)
        for op in ("sst", "fst"):
            assert call(a, op, 0) == ERROR, (op, a.logged)
            assert "is freed" in said(a) and "FreeInstance" in said(a), said(a)
        assert a.ser(0)[0] == ERROR
        # another live instance's state: refused, and left as it is
        initialised(b)
        assert call(b, "gst", 1) == OK
        a.states[1] = b.states[1]
        for op in ("sst", "fst"):
            assert call(a, op, 1) == ERROR, (op, a.logged)
            assert "belongs to another instance" in said(a) and "serialise" in said(a)
        assert call(a, "gst", 1) == WARNING  # into b's state: a new one, b's left alone
        assert a.states[1] != b.states[1] and call(b, "sst", 1) == OK
        # a handle never issued
        a.states[2] = 0x5A5A5A50
        assert call(a, "sst", 2) == ERROR and "not a live state" in said(a), said(a)
        a.states.pop(2)
        # the serialised bytes do move between instances
        assert call(a, "des", saved, 3) == OK and call(a, "sst", 3) == OK, a.logged
        assert call(a, "step", t, 1e-3) == OK
        assert a.getr(outs) == expected
        a.states.pop(0)
    finally:
        b.free()
        a.free()

