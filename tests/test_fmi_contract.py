"""The FMI plumbing's contract (issue 31), each case on the Python FMU (pythonfmu behind the
loader shim), the native FMI 2.0 FMU and the native FMI 3.0 FMU, through raw calls
(tests/fuzz/differential.py's Driver):

- a state belongs to the instance that made it: FreeInstance frees it, and a state whose
  instance is gone, another instance's state or a handle never issued is refused with a reason;
- counts no array can have are refused before any element is read or written;
- a defined stop time is honoured: a step that would end after it is refused;
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


# -- counts checked against what can exist before any array is read or written -------------------

#: Counts no call can have, with one-element arrays: SIZE_MAX, 2^61 (count * 8 wraps), 2^31
#: (crashed the native FMUs) and the first count over the bound.
IMPOSSIBLE = (2 ** 64 - 1, 2 ** 61, 2 ** 31, 65537)
FMI2_CALLS = [("fmi2%s%s" % (op, kind), ctype) for op in ("Get", "Set")
              for kind, ctype in (("Real", "c_double"), ("Integer", "c_int"),
                                  ("Boolean", "c_int"), ("String", "c_char_p"))]
FMI3_CALLS = [("fmi3%s%s" % (op, kind), ctype) for op in ("Get", "Set")
              for kind, ctype in (("Float64", "c_double"), ("Float32", "c_float"),
                                  ("Int8", "c_int8"), ("UInt8", "c_uint8"), ("Int16", "c_int16"),
                                  ("UInt16", "c_uint16"), ("Int32", "c_int32"),
                                  ("UInt32", "c_uint32"), ("Int64", "c_int64"),
                                  ("UInt64", "c_uint64"), ("Boolean", "c_bool"),
                                  ("String", "c_char_p"), ("Binary", "c_void_p"),
                                  ("Clock", "c_bool"))]

COUNTS_CHILD = r"""
import ctypes, json, sys
sys.path.insert(0, sys.argv[1])
from fuzz import differential as diff
from ctypes import *
unzipped, fmi, calls, counts = json.loads(sys.argv[2])
drv = diff.Driver(unzipped, fmi)
drv.setup(0.0), drv.enter(), drv.exit(), drv.step(0.0, 1e-3)
out = []
vr = (c_uint * 1)(0)
for name, ctype in calls:
    kind = getattr(ctypes, ctype)
    for n in counts + ["categories"] * (name == calls[0][0]):
        values, sizes = (kind * 1)(), (c_size_t * 1)(8)
        drv.logged = []
        if n == "categories":  # the category list of SetDebugLogging, 2^31 long
            n, name = 2 ** 31, "SetDebugLogging"
            s = drv.raw("fmi%dSetDebugLogging" % fmi, [c_int, c_size_t, c_void_p], 0, n,
                        (c_char_p * 1)(b"logAll"))
        elif name.endswith("Binary"):
            s = drv.raw(name, [c_void_p, c_size_t, c_void_p, c_void_p, c_size_t], vr, n, sizes,
                        values, n)
        elif name.endswith("Clock") or fmi == 2:
            s = drv.raw(name, [c_void_p, c_size_t, c_void_p], vr, n, values)
        else:
            s = drv.raw(name, [c_void_p, c_size_t, c_void_p, c_size_t], vr, n, values, n)
        out.append([name, n, s, [m for _, m in drv.logged][-1:]])
print(json.dumps(out))
"""


@pytest.mark.parametrize("backend", BACKENDS)
def test_counts_no_array_can_have_are_refused_before_any_element_is_touched(dirs, backend):
    """The count rule: a get or set names at most 65,536 value references (FMI 3.0: and nValues
    equals nValueReferences, every variable being a scalar); a larger count is refused before
    any element of the arrays is read or written.  Every get and set of every type, FMI 2.0 and
    3.0, with SIZE_MAX, 2^61, 2^31 and 65,537 and one-element arrays, in a child process (the
    native FMUs crashed with SIGSEGV; the shim read past the array): fmi2Error / fmi3Error with
    a line naming the count.  The native FMUs ignore the category list of SetDebugLogging (they
    read none: OK); the shim, which keeps it, refuses 2^31 categories."""
    import json
    import subprocess
    import sys
    from pathlib import Path
    fmi = 3 if backend.endswith("3") else 2
    calls = FMI3_CALLS if fmi == 3 else FMI2_CALLS
    rows = []
    for name in ("DriftEstimator", "Excitation"):
        done = subprocess.run(
            [sys.executable, "-c", COUNTS_CHILD, str(Path(__file__).parent),
             json.dumps([str(dirs[name][backend]), fmi, calls, list(IMPOSSIBLE)])],
            capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, (name, done.returncode, done.stderr[-3000:])
        rows += json.loads(done.stdout.splitlines()[-1])
    assert len(rows) == 2 * (len(calls) * len(IMPOSSIBLE) + 1)
    for call_name, n, status, logged in rows:
        if call_name == "SetDebugLogging" and backend != "python":
            assert status == OK, logged  # the native FMUs read no category
            continue
        assert status == ERROR, (call_name, n, status, logged)
        assert logged and str(n) in logged[0] and "allowed" in logged[0], (call_name, logged)


# -- the stop time ---------------------------------------------------------------------------------

def _enter_with(drv, start, stop):
    """Set up with ``stop`` and enter Initialization Mode: the status of the call that checks
    the stop time (fmi2SetupExperiment; FMI 3.0: fmi3EnterInitializationMode)."""
    status = call(drv, "setup", start, stop)
    if drv.fmi == 3:
        status = call(drv, "enter")
    elif status == OK:
        assert call(drv, "enter") == OK
    return status


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_defined_stop_time_is_honoured(dirs, backend):
    """fmi2SetupExperiment(c, 0, 0, 0.0, fmi2True, 0.0025) (FMI 3.0:
    fmi3EnterInitializationMode(c, false, 0, 0.0, true, 0.0025)), then steps of 1 ms: the steps
    to 1 and 2 ms and the half step to 2.5 ms are taken, a step that would end at 4 or 3.5 ms
    is refused naming the stop time and changes nothing (FMI 2.0 and 3.0: an FMU asked to
    compute past a defined stop time returns an error; all were OK).  A step that ends at the
    stop time up to rounding (25 steps of 0.1 ms) is taken.  A stop time before the start time,
    NaN or inf is refused when it is given (it was accepted), and nothing is changed."""
    outs = diff.model_info(dirs["DriftEstimator"]["native-fmi2"])["outputs"]
    drv = driver(dirs, "DriftEstimator", backend)
    try:
        assert _enter_with(drv, 0.0, 0.0025) == OK and call(drv, "exit") == OK
        assert call(drv, "step", 0.0, 1e-3) == OK and call(drv, "step", 1e-3, 1e-3) == OK
        values = drv.getr(outs)
        assert call(drv, "gst", 0) == OK
        before = (drv.ser(0)[1], values)
        for h in (2e-3, 1.5e-3, 0.5e-3 + 1e-8):  # (the tolerance: 1e-9 s)
            assert call(drv, "step", 2e-3, h) == ERROR, (h, drv.logged)
            assert "after the stop time 0.0025 s" in said(drv), said(drv)
            assert "allowed" in said(drv) and "nothing was changed" in said(drv)
            assert call(drv, "gst", 0) == OK and (drv.ser(0)[1], drv.getr(outs)) == before
        assert call(drv, "step", 2e-3, 0.5e-3) == OK  # to the stop time
        assert call(drv, "step", 2.5e-3, 1e-3) == ERROR
        # the stop time up to rounding: 25 steps of 0.1 ms sum to 2.5 ms
        assert call(drv, "reset") == OK
        assert _enter_with(drv, 0.0, 0.0025) == OK and call(drv, "exit") == OK
        t = 0.0
        for _ in range(25):
            assert call(drv, "step", t, 1e-4) == OK, drv.logged
            t += 1e-4
        assert call(drv, "step", t, 1e-4) == ERROR
        # stop times that cannot be: refused when given, nothing changed
        for start, stop in ((1.0, 0.5), (0.0, float("nan")), (0.0, float("inf")),
                            (0.0, -1e-300)):
            assert call(drv, "reset") == OK
            assert _enter_with(drv, start, stop) == ERROR, (start, stop)
            assert "stopTime" in said(drv) and "allowed" in said(drv), said(drv)
            assert call(drv, "exit") == ERROR  # still instantiated
        # a stop time equal to the start time: no step at all; none defined: steps go on
        assert _enter_with(drv, 1.0, 1.0) == OK and call(drv, "exit") == OK
        assert call(drv, "step", 1.0, 1e-3) == ERROR
        assert call(drv, "reset") == OK
        assert _enter_with(drv, 0.0, None) == OK and call(drv, "exit") == OK
        assert call(drv, "step", 0.0, 10.0) == OK
    finally:
        drv.free()


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_state_carries_its_stop_time(dirs, backend):
    """The stop time is part of the experiment a state continues: restored into an instance
    set up without one, it applies again."""
    drv = driver(dirs, "DriftEstimator", backend)
    try:
        assert _enter_with(drv, 0.0, 0.0025) == OK and call(drv, "exit") == OK
        assert call(drv, "step", 0.0, 2e-3) == OK and call(drv, "gst", 0) == OK
        assert call(drv, "reset") == OK
        assert _enter_with(drv, 0.0, None) == OK and call(drv, "exit") == OK
        assert call(drv, "step", 0.0, 4e-3) == OK  # no stop time now
        assert call(drv, "sst", 0) == OK
        assert call(drv, "step", 2e-3, 2e-3) == ERROR and "stop time" in said(drv)
        assert call(drv, "step", 2e-3, 0.5e-3) == OK
    finally:
        drv.free()


# -- one state check: every field, in every twin, when the bytes are deserialised ------------------

#: The filters' variances, by model and process model: the index in the Python state's JSON
#: list and the field of the native hidden state.
VARIANCE_FIELDS = {
    ("DriftEstimator", 1): [(1, "h.state.P")],
    ("DriftEstimator", 2): [(2, "h.state.P"), (4, "h.state.P22")],
    ("DualDriftEstimator", 1): [(2, "h.state.g.Pxx"), (4, "h.state.g.Pyy")],
    ("DualDriftEstimator", 2): [(4, "h.state.h.P11"), (6, "h.state.h.P22"),
                                (7, "h.state.h.P33"), (9, "h.state.h.P44")],
}


def _saved_state(dirs, name, backend, process):
    """A driver of ``name`` initialised with ``process``, stepped twice, its serialised state
    (slot 0 keeps it) and the instance's outputs and state after one more step."""
    drv = driver(dirs, name, backend)
    assert call(drv, "setup", 0.0) == OK and call(drv, "enter") == OK
    assert call(drv, "seti", ["process"], [process]) == OK
    assert call(drv, "exit") == OK, drv.logged
    for i in range(2):
        assert call(drv, "step", i * 1e-3, 1e-3) == OK
    assert call(drv, "gst", 0) == OK
    data = drv.ser(0)[1]
    assert call(drv, "step", 2e-3, 1e-3) == OK
    return drv, data


def _unchanged(drv, outs):
    drv.getr(outs)
    assert call(drv, "gst", 9) == OK
    return drv.ser(9)[1], drv.getr(outs)


def _refused_at_deserialise(drv, blob, outs, *named):
    """``blob`` is refused by fmi2DeSerializeFMUstate / fmi3DeserializeFMUState itself, with a
    message naming ``named``, and the instance is unchanged."""
    before = _unchanged(drv, outs)
    assert call(drv, "des", blob, 5) == ERROR, (named, drv.logged)
    text = said(drv)
    assert all(word in text for word in named) and ("refused" in text or "allowed" in text), \
        (named, text)
    assert 5 not in drv.states and _unchanged(drv, outs) == before


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name, process", sorted(VARIANCE_FIELDS))
def test_a_negative_variance_in_a_state_is_refused_in_every_twin(dirs, backend, name, process):
    """The filter's P (P22 of the harmonic model; the dual filter's Pxx, Pyy, P11, P22, P33,
    P44) set to -1 or -1e300 in a serialised state: refused when the bytes are deserialised,
    naming the field, in every twin (the Python FMU restored such a state with OK and stepped on
    with changed outputs; the native twins refused it)."""
    import json
    from fuzz import native_state as ns
    outs = diff.model_info(dirs[name]["native-fmi2"])["outputs"]
    drv, data = _saved_state(dirs, name, backend, process)
    try:
        for index, field in VARIANCE_FIELDS[name, process]:
            for value in (-1.0, -1e300):
                if backend == "python":
                    state = json.loads(data)
                    state["_state"][index] = value
                    blob, named = json.dumps(state).encode(), "_state." + field.split(".")[-1]
                else:
                    blob = ns.crafted(ns.snapshot_type(dirs[name][backend]), data, field, value)
                    named = field[2:]
                _refused_at_deserialise(drv, blob, outs, named, "negative variance")
        assert call(drv, "des", data, 5) == OK and call(drv, "sst", 5) == OK  # as it was: taken
    finally:
        drv.free()


#: Bytes that are no state: refused at deserialisation, with the reason.
GARBAGE = [b"hello", b"", b"{}", b"[1, 2]", b"\x00" * 64, b'{"model": "DriftEstimator"']


@pytest.mark.parametrize("backend", BACKENDS)
def test_bytes_that_are_no_state_are_refused_at_deserialisation(dirs, backend):
    """fmi2DeSerializeFMUstate / fmi3DeserializeFMUState of "hello", empty bytes, JSON that is
    no state, zeros, a cut state: an error at once, saying what the bytes are not and what is
    allowed (the Python FMUs returned OK and the later set said "not an FMU state of
    Excitation: None"); a cut or edited real state too."""
    outs = diff.model_info(dirs["DriftEstimator"]["native-fmi2"])["outputs"]
    drv, data = _saved_state(dirs, "DriftEstimator", backend, 1)
    try:
        for blob in GARBAGE + [data[:len(data) // 2], data + b"x"]:
            _refused_at_deserialise(drv, blob, outs, "not an FMU state of DriftEstimator",
                                    "allowed")
    finally:
        drv.free()


#: Edits of the Python state's own fields that the native twins refuse in theirs (the mode
#: flags, the state before initialisation, the stop time): (edit, the words of the refusal).
def _python_edits(state):
    t = state["time"]
    yield dict(state, flags=dict(state["flags"], in_init=True)), "initialised and in_init"
    yield dict(state, stop_time=t[0] - 1.0), "stop_time"
    yield dict(state, stop_time="x"), "stop_time"
    yield dict(state, stop_time=t[0] + (t[1] + t[2]) / 2), "after the stop time"
    before = dict(state, flags=dict(state["flags"], initialised=False))
    yield before, "initialised is false"
    yield dict(before, _state=None), "before initialisation"
    yield dict(before, _state=None, time=[t[0], 0.0, 0.0], k=2), "k = 2"
    yield dict(state, flags=dict(state["flags"], initialised=False, terminated=True),
               _state=None, k=1, time=[t[0], 0.0, 0.0]), "terminated"


def test_the_python_state_checks_what_the_native_state_checks(dirs):
    """The fields the native snapshot checks beyond finiteness and ranges: the mode flags
    consistent, nothing set and no time elapsed before initialisation, the stop time at or
    after the start and not before the time: the Python state's equivalents are refused at
    deserialisation, naming what is wrong (they were restored with OK)."""
    import json
    outs = diff.model_info(dirs["DriftEstimator"]["native-fmi2"])["outputs"]
    drv, data = _saved_state(dirs, "DriftEstimator", "python", 1)
    try:
        for edited, words in _python_edits(json.loads(data)):
            _refused_at_deserialise(drv, json.dumps(edited).encode(), outs, words)
    finally:
        drv.free()
