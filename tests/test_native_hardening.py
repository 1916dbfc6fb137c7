"""The native FMUs as hard as the Python ones (issue 20), each case on the Python FMU, the native
FMI 2.0 FMU and the native FMI 3.0 FMU, through raw calls (tests/fuzz/differential.py's Driver):

- a refused fmi2ExitInitializationMode changes nothing and can be retried;
- every field of a native serialised state is checked (NaN, inf, out of range, inconsistent),
  the state is refused as a whole naming the field, and the instance is left unchanged; the
  Python FMU's JSON state likewise;
- the tampered states the issue found (x = NaN, A = 5, R = 0, k = -5, Ts = 0) are refused;
- sizes, counts and lengths from the host are not trusted (SIZE_MAX, in a child process: a
  crash is a failure);
- a state deserialised into a state the host holds is written into it (no new allocation);
- messages say what was given and what is allowed, true to what the code does.
"""
import ctypes
import json
import math
import subprocess
import sys
from ctypes import c_double, c_int, c_int32, c_int64
from pathlib import Path

import pytest

from fuzz import differential as diff
from fuzz import native_state as ns
from driftfmu.fmu_src.builder import NAMES
from waiting import BOUND

pytestmark = pytest.mark.integration
OK, WARNING, DISCARD, ERROR = diff.OK, diff.WARNING, diff.DISCARD, diff.ERROR
BACKENDS = diff.BACKENDS
NATIVE = [("native-fmi2", 2), ("native-fmi3", 3)]


@pytest.fixture(scope="module")
def dirs(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("hardening"))


def driver(dirs, name, backend):
    return diff.Driver(dirs[name][backend], 3 if backend.endswith("3") else 2)


def info(dirs, name):
    return diff.model_info(dirs[name]["native-fmi2"])


def messages(drv):
    return [m for _, m in drv.logged]


def call(drv, op, *args):
    """Run one call with a fresh log; its status."""
    drv.logged = []
    return getattr(drv, op)(*args)[0]


def initialised(drv, Ts=1e-3, steps=(2.5,)):
    """Set up, initialise and step ``drv`` (steps in sample periods)."""
    for op in (("setup", 0.0), ("enter",), ("exit",)):
        assert call(drv, *op) == OK, messages(drv)
    t = 0.0
    for n in steps:
        assert call(drv, "step", t, n * Ts) == OK, messages(drv)
        t += n * Ts
    return t


# -- a refused call changes nothing -----------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", NAMES)
def test_a_refused_exit_changes_nothing_and_can_be_retried(dirs, name, backend):
    outs = info(dirs, name)["outputs"]
    drv = driver(dirs, name, backend)
    try:
        assert call(drv, "setup", 0.0) == OK and call(drv, "enter") == OK
        assert call(drv, "setr", ["Ts"], [0.0]) == OK
        assert call(drv, "exit") == ERROR
        assert any("Ts = 0.0 is out of range" in m for m in messages(drv)), messages(drv)
        # still in Initialization Mode: no step, no outputs from Ts = 0, no second entry
        assert call(drv, "step", 0.0, 1e-3) == ERROR
        assert "initiali" in messages(drv)[-1].lower(), messages(drv)
        assert call(drv, "getr", outs) == ERROR
        assert "Ts = 0.0" in messages(drv)[-1]
        assert call(drv, "enter") == ERROR
        # corrected, the exit goes through, and the run is that of a clean instance
        assert call(drv, "setr", ["Ts"], [1e-3]) == OK
        assert call(drv, "exit") == OK, messages(drv)
        assert call(drv, "step", 0.0, 2e-3) == OK, messages(drv)
        after_retry = drv.getr(outs)
        clean = driver(dirs, name, backend)
        try:
            initialised(clean, steps=(2,))
            assert clean.getr(outs) == after_retry
        finally:
            clean.free()
    finally:
        drv.free()


@pytest.mark.parametrize("backend", BACKENDS)
def test_terminate_only_after_initialisation_and_once(dirs, backend):
    drv = driver(dirs, "DriftEstimator", backend)
    try:
        assert call(drv, "term") == ERROR
        assert "not allowed" in messages(drv)[-1]
        initialised(drv)
        assert call(drv, "term") == OK
        assert call(drv, "term") == ERROR
        assert "not allowed" in messages(drv)[-1]
        assert call(drv, "reset") == OK and call(drv, "setup", 0.0) == OK
        assert call(drv, "enter") == OK and call(drv, "term") == OK  # from initialisation
    finally:
        drv.free()


# -- a restored state is a checked state --------------------------------------------------------

def _api_refuses(dirs, name, backend, path, value):
    """Whether exiting initialisation with variable ``path`` (v.<name>) = ``value`` set through
    the API is refused (the reference for the same value in a state)."""
    drv = driver(dirs, name, backend)
    try:
        call(drv, "setup", 0.0)
        call(drv, "enter")
        variable = path.split(".", 1)[1]
        op = "seti" if drv.type[variable] in ("Integer", "Int32") else "setr"
        status = call(drv, op, [variable], [value])
        return status >= ERROR or call(drv, "exit") >= ERROR
    finally:
        drv.free()


def derived_of(name, path):
    return path.startswith("h.") and path.split(".")[1] in ns.DERIVED[name]


def _tamperings(S, data, name):
    """``(path, value, kind)`` of the crafted edits of a state that must be refused: non-finite
    numbers everywhere, flags and counts out of range, variances < 0, derived constants that
    do not follow from the parameters, times and sample indices that do not agree."""
    s = ns.read(S, data)
    out = []
    for path, kind in ns.leaves(S):
        if path.startswith("header") or path == "checksum":
            continue
        last = path.split(".")[-1]
        hidden = path.startswith("h.")
        derived = hidden and path.split(".")[1] in ns.DERIVED[name]
        value = ns.get(s, path)
        if path == "stopTime":  # inf: none defined; else at or after the start and the time
            out += [(path, v, "stop") for v in (math.nan, -math.inf, s.startTime - 1.0)]
            out.append((path, s.startTime + (s.elapsed + s.elapsed_c) / 2, "consistent"))
        elif kind is c_double:
            out += [(path, v, "not finite") for v in (math.nan, math.inf, -math.inf)]
            if hidden and last in ns.VARIANCES and not derived:
                out.append((path, -1.0, "variance"))
            if derived:
                out.append((path, value * 2.0 + 1.0, "derived"))
        elif derived:
            out.append((path, value + 1, "derived"))
        elif hidden and (last.endswith("_set") or last == "has_pending"):
            out += [(path, 2, "flag"), (path, -1, "flag")]
        elif hidden and last == "k":
            out.append((path, -1, "count"))
        elif path in ("pending", "dirty", "initialised"):
            out += [(path, 2, "flag"), (path, -1, "flag")]
        elif path == "state":
            out += [(path, 0, "mode"), (path, 64, "mode"), (path, 3, "mode")]
        elif path == "k":
            out += [(path, 0, "index"), (path, -5, "index"), (path, value + 1, "index")]
    out += [("time", s.time + 1.0, "consistent"), ("elapsed", -1.0, "elapsed"),
            ("elapsed", s.elapsed + 0.5, "consistent"), ("startTime", s.startTime + 1.0,
                                                         "consistent"),
            ("initialised", 0, "consistent")]
    return out


@pytest.mark.parametrize("backend,version", NATIVE)
@pytest.mark.parametrize("name", NAMES)
def test_every_field_of_a_native_state_is_checked(dirs, name, backend, version, report):
    S = ns.snapshot_type(dirs[name][backend])
    outs = info(dirs, name)["outputs"]
    drv = driver(dirs, name, backend)
    try:
        t = initialised(drv)
        assert call(drv, "gst", 0) == OK
        status, data = drv.ser(0)
        assert status == OK and len(data) == ctypes.sizeof(S)
        assert ns.read(S, data).checksum == ns.checksum(data)
        assert call(drv, "step", t, 1e-3) == OK  # the instance moves on from the saved state
        call(drv, "gst", 1)
        before = (drv.ser(1)[1], drv.getr(outs))
        cases = _tamperings(S, data, name)
        # the parameters and inputs: what the API refuses, a state must refuse too (outputs
        # cannot be set through the API: theirs is the finite check above)
        for path, kind in ns.leaves(S):
            if path[2:] in outs:
                continue
            if path.startswith("v.") and kind is c_double:
                for value in (-1.0, 0.0, 1e308, -1e308, 1e-320):
                    if _api_refuses(dirs, name, backend, path, value):
                        cases.append((path, value, "API"))
            elif path.startswith("v."):
                for value in (-1, 0, 7, 2 ** 31 - 1):
                    if _api_refuses(dirs, name, backend, path, value):
                        cases.append((path, value, "API"))
        missed = []
        for path, value, why in cases:
            blob = ns.crafted(S, data, path, value)
            if call(drv, "des", blob, 2) != ERROR:
                missed.append((path, value, why))
                call(drv, "fst", 2)
                continue
            text = " ".join(messages(drv))
            field = path.split(".", 1)[1] if path.startswith(("v.", "h.")) else path
            if derived_of(name, path):  # a derived constant is named as a whole
                field = path.split(".")[1]
            named = field in text or why in ("derived", "consistent", "API", "index") \
                or (not path.startswith("h.") and field.split(".")[-1] in text)
            assert named, (path, value, text)
            assert "refused" in text, text
        assert missed == [], missed
        # corruption: any byte changed without the checksum put right
        for at in range(0, len(data), max(1, len(data) // 40)):
            blob = bytearray(data)
            blob[at] ^= 0x5A
            assert call(drv, "des", bytes(blob), 2) == ERROR, at
            text = " ".join(messages(drv))
            assert "corrupted" in text or "not an FMU state" in text or "damaged" in text, text
        call(drv, "gst", 1)
        assert (drv.ser(1)[1], drv.getr(outs)) == before  # nothing changed
        # and the state as it was is accepted, and restores the instance
        assert call(drv, "des", data, 2) == OK and call(drv, "sst", 2) == OK
        assert call(drv, "step", t, 1e-3) == OK
        assert drv.getr(outs) == before[1]
        report("HARDENING %s FMI %d.0: %d crafted fields and %d corrupted bytes of a serialised "
               "state refused, the instance unchanged" % (name, version, len(cases),
                                                          len(range(0, len(data),
                                                                    max(1, len(data) // 40)))))
    finally:
        drv.free()


#: The tampered states issue 20 found restored without a word (the class is the field-by-field
#: tests around this one): (model, field, value, what the refusal names).  The native field is
#: v.<name> (a variable) or the snapshot's own sample index k.
ISSUE_SAMPLES = [("Accelerometer", "x", math.nan, "x"),
                 ("DriftEstimator", "x_hat", math.nan, "x_hat"),
                 ("DriftEstimator", "A", 5.0, "A"),
                 ("DriftEstimator", "R", 0.0, "R"),
                 ("DriftEstimator", "k", -5, "k"),
                 ("DriftEstimator", "Ts", 0.0, "Ts")]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name, field, value, named", ISSUE_SAMPLES,
                         ids=["%s-%s" % (s[0], s[1]) for s in ISSUE_SAMPLES])
def test_the_issues_tampered_states_are_refused(dirs, name, field, value, named, backend):
    """x = NaN, A = 5, R = 0, k = -5, Ts = 0 written into a serialised state (the native one
    with its checksum put right, the Python one's JSON): refused at deserialisation or at
    the restore that follows, naming the field, and the instance is unchanged."""
    outs = info(dirs, name)["outputs"]
    drv = driver(dirs, name, backend)
    try:
        t = initialised(drv)
        assert call(drv, "gst", 0) == OK
        data = drv.ser(0)[1]
        if backend == "python":
            state = json.loads(data)
            assert field in state, sorted(state)
            blob = json.dumps(dict(state, **{field: value})).encode()
        else:
            S = ns.snapshot_type(dirs[name][backend])
            blob = ns.crafted(S, data, field if field == "k" else "v." + field, value)
        assert call(drv, "step", t, 1e-3) == OK
        call(drv, "gst", 1)
        before = (drv.ser(1)[1], drv.getr(outs))
        status = call(drv, "des", blob, 2)
        if status <= WARNING:  # the Python FMU takes the bytes and refuses them when set
            status = call(drv, "sst", 2)
        assert status == ERROR, messages(drv)
        text = " ".join(messages(drv))
        assert named in text and ("refused" in text or "nothing was changed" in text), text
        call(drv, "gst", 1)
        assert (drv.ser(1)[1], drv.getr(outs)) == before
    finally:
        drv.free()


def _json_edits(state):
    for key, value in state.items():
        if key in ("model", "guid", "version"):
            yield key, "other"
        elif isinstance(value, float):
            yield key, "NaN"
            yield key, "Infinity"
            yield key, '"x"'
        elif isinstance(value, (int, list, dict)):
            yield key, "null"
            yield key, "[[1]]"


@pytest.mark.parametrize("name", NAMES)
def test_every_field_of_a_python_state_is_checked(dirs, name):
    outs = info(dirs, name)["outputs"]
    drv = driver(dirs, name, "python")
    try:
        t = initialised(drv)
        call(drv, "gst", 0)
        data = drv.ser(0)[1]
        state = json.loads(data)
        call(drv, "step", t, 1e-3)
        call(drv, "gst", 1)
        before = (drv.ser(1)[1], drv.getr(outs))
        n = 0
        for key, text in _json_edits(state):
            edited = dict(state)
            edited[key] = "__EDIT__"
            blob = json.dumps(edited).replace('"__EDIT__"', text).encode()
            status = call(drv, "des", blob, 2)
            status = max(status, call(drv, "sst", 2)) if status <= WARNING else status
            assert status == ERROR, (key, text)
            assert key in " ".join(messages(drv)) or "not an FMU state" in \
                " ".join(messages(drv)), (key, messages(drv))
            n += 1
        call(drv, "gst", 1)
        assert (drv.ser(1)[1], drv.getr(outs)) == before
        assert n > 10
    finally:
        drv.free()


# -- sizes from the host ------------------------------------------------------------------------

SIZES_CHILD = r'''
import ctypes, json, sys
sys.path.insert(0, sys.argv[1])
from fuzz import differential as diff
from ctypes import byref, c_size_t, c_void_p
out = []
for unzipped, fmi in json.loads(sys.argv[2]):
    drv = diff.Driver(unzipped, fmi)
    name = "fmi2DeSerializeFMUstate" if fmi == 2 else "fmi3DeserializeFMUState"
    for size in (2 ** 64 - 1, 2 ** 64 - 2, 2 ** 63, 2 ** 32 + 2):
        p = c_void_p(None)
        drv.logged = []
        s = drv.raw(name, [c_void_p, c_size_t, c_void_p], b"{}", size, byref(p))
        out.append([unzipped, size, s, [m for _, m in drv.logged][-1:]])
    drv.free()
print(json.dumps(out))
'''


def _run_child(script, dirs):
    """Run ``script`` in a child Python (a crash is a failure, not the end of the session) on
    every model and backend; ``(targets, rows)``: the folders it got and the rows it printed."""
    targets = [(str(dirs[name][b]), 3 if b.endswith("3") else 2) for name in NAMES
               for b in BACKENDS]
    done = subprocess.run([sys.executable, "-c", script, str(Path(__file__).parent),
                           json.dumps(targets)], capture_output=True, text=True, timeout=BOUND)
    assert done.returncode == 0, done.stderr[-3000:]
    return targets, json.loads(done.stdout.splitlines()[-1])


def test_sizes_from_the_host_are_not_trusted(dirs):
    """fmi2DeSerializeFMUstate(c, "{}", SIZE_MAX, &s) and other sizes no state can have (size + 1
    wraps, or more than the address space holds): an error that says what was given and
    allowed, no crash (in a child process).  A plausible size larger than the buffer cannot be
    told from a real one by any FMU: the standard makes the host answer for it."""
    targets, rows = _run_child(SIZES_CHILD, dirs)
    assert len(rows) == 4 * len(targets)
    for where, size, status, logged in rows:
        assert status == ERROR, (where, size)
        assert logged and str(size) in logged[0] and "allowed" in logged[0], (where, logged)


COUNTS_CHILD = r"""
import ctypes, json, sys
sys.path.insert(0, sys.argv[1])
from fuzz import differential as diff
from ctypes import byref, c_char_p, c_double, c_int, c_int32, c_size_t, c_uint, c_void_p
HUGE = (2 ** 64 - 1, 2 ** 63, 2 ** 61 + 1)
out = []
for unzipped, fmi in json.loads(sys.argv[2]):
    drv = diff.Driver(unzipped, fmi)
    def row(what, status):
        out.append([unzipped, what, status, [m for _, m in drv.logged][-1:]])
        drv.logged = []
    drv.setup(0.0), drv.enter(), drv.exit()
    drv.logged = []
    # a category list of a length no array has: refused (the shim, which keeps the list: its
    # calloc checks the count * size for overflow), or not read (the native FMUs ignore it)
    one = (c_char_p * 1)(b"logAll")
    for n in HUGE:
        row("categories %d" % n, drv.raw("fmi%dSetDebugLogging" % fmi,
                                         [c_int, c_size_t, c_void_p], 0, n, one))
    if fmi == 3:
        # value counts that do not match the value references: refused before any value is
        # read or written (the array holds 2 values; the counts say 0, 2 or more)
        vr = (c_uint * 1)(drv.vr["Ts"])
        before = drv.getr(["Ts"])
        for n in (0, 2) + HUGE:
            for call, kind in (("fmi3GetFloat64", c_double), ("fmi3SetFloat64", c_double),
                               ("fmi3GetInt32", c_int32), ("fmi3SetInt32", c_int32)):
                values = (kind * 2)(1, 1)
                row("%s nValues %d" % (call, n), drv.raw(call, [c_void_p, c_size_t, c_void_p,
                                                                c_size_t], vr, 1, values, n))
        out.append([unzipped, "unchanged", int(drv.getr(["Ts"]) == before), []])
        # intermediate variables: a count with no array, refused without reading it
        logged = []
        Log = ctypes.CFUNCTYPE(None, c_void_p, c_int, c_char_p, c_char_p)
        inst = ctypes.CFUNCTYPE(c_void_p, c_char_p, c_char_p, c_char_p, c_int, c_int, c_int,
                                c_int, c_void_p, c_size_t, c_void_p, Log, c_void_p)(
            ctypes.cast(drv.dll.fmi3InstantiateCoSimulation, c_void_p).value)
        log = Log(lambda env, status, cat, msg: logged.append(msg.decode()))
        for n in HUGE:
            c = inst(b"counts", drv.md.guid.encode(), None, 0, 0, 0, 0, None, c_size_t(n),
                     None, log, None)
            out.append([unzipped, "intermediate %d" % n, 3 if c is None else 0, logged[-1:]])
        # strings of any length (an instance name and a resource path of 100,000 characters,
        # as the case fuzz gives the FMI 2.0 FMUs), and no logger: the instance works
        free = ctypes.CFUNCTYPE(None, c_void_p)(
            ctypes.cast(drv.dll.fmi3FreeInstance, c_void_p).value)
        enter = ctypes.CFUNCTYPE(c_int, c_void_p, c_int, c_double, c_double, c_int, c_double)(
            ctypes.cast(drv.dll.fmi3EnterInitializationMode, c_void_p).value)
        for what, name, path, logger in (
                ("strings", b"n" * 100000, b"/" + b"a/" * 50000, log),
                ("nologger", b"quiet", None, Log())):
            c = inst(name, drv.md.guid.encode(), path, 0, 0, 0, 0, None, 0, None, logger,
                     None)
            status = 3 if c is None else enter(c, 0, 0.0, 0.0, 0, 0.0)
            if c is not None:
                free(c)
            out.append([unzipped, what, status, logged[-1:]])
    drv.free()
print(json.dumps(out))
"""


def test_counts_and_lengths_from_the_host_are_not_trusted(dirs, report):
    """Array counts no array can have (SIZE_MAX, 2**63, 2**61 + 1: count * size overflows or
    exceeds the address space), in a child process (a crash is a failure): a category list
    (fmi2SetDebugLogging / fmi3SetDebugLogging), FMI 3.0 value counts that do not match the
    value references (0, 2 and the huge ones; nothing read or written), FMI 3.0 intermediate
    variables.  The Python FMU refuses the category count (its shim keeps the list); the native
    FMUs ignore categories and read none.  A plausible count larger than the array cannot be
    told from a real one by any FMU: the standard makes the host answer for it.  And FMI 3.0
    strings of any length (instance name, resource path) and no logger: the instance works."""
    targets, rows = _run_child(COUNTS_CHILD, dirs)
    seen = {}
    for where, what, status, logged in rows:
        python = Path(where).name == "python"  # dirs: <folder>/<model>/<backend>
        kind = what.split()[0]
        seen[kind] = seen.get(kind, 0) + 1
        if what == "unchanged":
            assert status == 1, where
        elif kind == "categories":
            assert status == (ERROR if python else OK), (where, what, logged)
            if python:
                assert what.split()[1] in logged[0] and "nothing was changed" in logged[0]
        elif kind in ("strings", "nologger"):
            assert status == OK, (where, what, logged)
        else:  # FMI 3.0 value counts and intermediate variables
            assert status == ERROR and logged, (where, what)
            if kind.startswith("fmi3"):
                assert "%s values" % what.split()[-1] in logged[0] and "allowed" in logged[0], \
                    logged
    assert seen["categories"] == 3 * len(targets)
    assert seen["unchanged"] == seen["strings"] == seen["nologger"] == len(NAMES)
    report("HARDENING counts: %s" % ", ".join("%d %s" % (n, k) for k, n in sorted(seen.items())))


# -- messages true to what the code does ----------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_communication_point_message_is_true(dirs, backend):
    drv = driver(dirs, "DriftEstimator", backend)
    try:
        t = initialised(drv)
        assert call(drv, "step", math.nan, 1e-3) == ERROR
        text = messages(drv)[-1]
        assert "keeps its own time" in text and "%r" % t in text.replace("%.17g" % t, "%r" % t) \
            or "keeps its own time" in text, text
        assert call(drv, "step", 123.0, 1e-3) == OK  # as the message says: any finite time
        assert call(drv, "status", 2) == OK
        if backend != "native-fmi3":
            assert float.fromhex(drv.status(2)[1][0]) == pytest.approx(t + 1e-3, abs=0)
    finally:
        drv.free()


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", NAMES)
def test_huge_sample_period_is_named_not_an_internal_error(dirs, name, backend):
    drv = driver(dirs, name, backend)
    try:
        call(drv, "setup", 0.0)
        call(drv, "enter")
        call(drv, "setr", ["Ts"], [1e308])
        status = call(drv, "exit")
        seen = list(messages(drv))
        if status == OK:
            for h in (1e308, 1e308, 1.0):
                call(drv, "step", 0.0, h)
                seen += messages(drv)
                call(drv, "getr", info(dirs, name)["outputs"])
                seen += messages(drv)
        assert not any("internal error" in m for m in seen), seen
        assert not any("h <= about inf" in m or "h <= about nan" in m for m in seen), seen
        assert all("Ts" in m or "overflow" in m for m in seen), seen
    finally:
        drv.free()


@pytest.mark.parametrize("backend", ["python", "native-fmi2"])
def test_status_inquiries_log_at_the_level_they_return(dirs, backend):
    drv = driver(dirs, "Excitation", backend)
    try:
        assert call(drv, "status", 2) == ERROR  # before initialisation
        initialised(drv)
        for kind in (0, 1, 3):
            assert call(drv, "status", kind) == DISCARD
            assert [s for s, _ in drv.logged] == [DISCARD], drv.logged
        assert call(drv, "status", 7) == ERROR
        assert "status kind 7 does not exist" in messages(drv)[-1]
    finally:
        drv.free()


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_state_pointer_from_another_copy_of_the_same_fmu(dirs, backend, tmp_path):
    """Unzipped twice, the same FMU is two libraries: a state pointer of one is refused by the
    other with a message that says so (not "not a state of this FMU" with the same GUID); its
    serialised bytes are taken."""
    import shutil
    copy = tmp_path / "copy"
    shutil.copytree(dirs["DriftEstimator"][backend], copy)
    fmi = 3 if backend.endswith("3") else 2
    a = diff.Driver(dirs["DriftEstimator"][backend], fmi)
    b = diff.Driver(copy, fmi)
    try:
        t = initialised(a)
        initialised(b)
        call(a, "gst", 0)
        b.states[0] = a.states[0]
        assert call(b, "sst", 0) == ERROR
        text = messages(b)[-1]
        assert "loaded copy" in text and "serialise" in text, text
        b.states.pop(0)
        assert call(b, "des", a.ser(0)[1], 1) == OK and call(b, "sst", 1) == OK
        call(a, "step", t, 1e-3)
        call(b, "step", t, 1e-3)
        outs = info(dirs, "DriftEstimator")["outputs"]
        assert a.getr(outs) == b.getr(outs)
    finally:
        b.free()
        a.free()


# -- deserialising into a state the host holds ----------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_deserialise_into_a_live_state_reuses_it(dirs, backend):
    """fmi2DeSerializeFMUstate / fmi3DeserializeFMUState with ``*FMUstate`` a live state of the
    FMU write into that state, as fmi2GetFMUstate does (a host that deserialises into one
    pointer again and again allocates nothing: tests/test_memory.py measures it; the native
    FMUs allocated a new state each time); a refused one leaves it as it was; a pointer that is
    not a live state is said in a warning, left alone, and a new state is returned."""
    outs = info(dirs, "DriftEstimator")["outputs"]
    drv = driver(dirs, "DriftEstimator", backend)
    name = "fmi2DeSerializeFMUstate" if drv.fmi == 2 else "fmi3DeserializeFMUState"

    def des_into(data, pointer):
        p = ctypes.c_void_p(pointer)
        drv.logged = []
        status = drv.raw(name, [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p], data,
                         len(data), ctypes.byref(p))
        return status, p.value

    try:
        t = initialised(drv)
        assert call(drv, "gst", 0) == OK
        saved = drv.ser(0)[1]
        assert call(drv, "step", t, 1e-3) == OK
        expected = drv.getr(outs)
        assert call(drv, "step", t + 1e-3, 1e-3) == OK
        assert call(drv, "gst", 1) == OK
        held = drv.states[1]
        status, p = des_into(saved, held)
        assert (status, p) == (OK, held), messages(drv)
        assert drv.ser(1)[1] == saved
        corrupted = bytearray(drv.ser(1)[1])
        corrupted[len(corrupted) // 2] ^= 0x5A
        status, p = des_into(bytes(corrupted), held)
        assert status == ERROR and p == held, messages(drv)  # refused as it is read
        assert drv.ser(1)[1] == saved
        junk = ctypes.create_string_buffer(b"\x5a" * 64, 64)
        status, p = des_into(saved, ctypes.addressof(junk))
        assert status == WARNING and p not in (None, ctypes.addressof(junk)), messages(drv)
        assert "not a live FMU state" in messages(drv)[0], messages(drv)
        assert junk.raw == b"\x5a" * 64
        drv.states[2] = p  # freed with the driver
        for slot in (1, 2):  # both restore the saved state
            assert call(drv, "sst", slot) == OK
            assert call(drv, "step", t, 1e-3) == OK
            assert drv.getr(outs) == expected
    finally:
        drv.free()
