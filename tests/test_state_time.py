"""A state that contradicts its own time is refused by every twin (issue 38).

An FMU state records its time (the start time, the time elapsed since, and the native twins'
current time as well), its sample index ``k`` and whether it is at a sample instant, and its
stop time.  Each consistency check
between these has a case here that breaks it and *no other check*, so that each case fails
when its check goes: the Python FMU (``slave_base._restore``, ``_timing_problems``) and the
native twins, FMI 2.0 and 3.0 (``cosimulation.c``, ``snapshot_problems``).  Each edited state is
refused when its bytes are deserialised, naming what is wrong, and the instance is unchanged;
the unedited state is still taken.
"""
import json

import pytest

from fuzz import differential as diff
from fuzz import native_state as ns

pytestmark = pytest.mark.integration

OK, ERROR = diff.OK, diff.ERROR
Ts = 1e-3


@pytest.fixture(scope="module")
def dirs(python_fmus, native_fmus, tmp_path_factory):
    return diff.unzip_all(python_fmus, native_fmus, tmp_path_factory.mktemp("state_time"))


def call(drv, op, *args):
    drv.logged = []
    return getattr(drv, op)(*args)[0]


def _saved(drv, when):
    """The serialised state ``when``: "uninitialised" (set up, before initialisation),
    "k1" (just initialised: sample 1 pending) or "between" (2.5 sample periods later: sample 4
    next, not at an instant)."""
    assert call(drv, "setup", 0.0) == OK
    if when != "uninitialised":
        assert call(drv, "enter") == OK and call(drv, "exit") == OK, drv.logged
    if when == "between":
        assert call(drv, "step", 0.0, 2.5 * Ts) == OK
    assert call(drv, "gst", 0) == OK, drv.logged
    status, data = drv.ser(0)
    assert status == OK
    return data


#: (case, the state it edits, the words of its refusal).  Each breaks one check alone.
CASES = [
    ("elapsed-negative", "k1", "elapsed"),
    ("stop-before-start", "uninitialised", "stop"),
    ("elapsed-before-initialisation", "uninitialised", "before initialisation"),
    ("not-at-a-sample-before-initialisation", "uninitialised", "before initialisation"),
    ("k-before-initialisation", "uninitialised", "before initialisation"),
    ("k-not-the-time", "between", "do not match the time"),
    ("at-sample-not-the-time", "between", "do not match the time"),
    ("after-the-stop-time", "between", "after the stop time"),
]


def _python_edit(case, state):
    t0, elapsed, c = state["time"]
    flags = state["flags"]
    if case == "elapsed-negative":       # at sample 1 still: only elapsed >= 0 sees it
        return dict(state, time=[t0, -1e-12, 0.0])
    if case == "stop-before-start":      # before initialisation: no time to be after it
        return dict(state, stop_time=t0 - 1.0)
    if case == "elapsed-before-initialisation":
        return dict(state, time=[t0, Ts, 0.0])
    if case == "not-at-a-sample-before-initialisation":
        return dict(state, flags=dict(flags, at_sample=False))
    if case == "k-before-initialisation":
        return dict(state, k=2)
    if case == "k-not-the-time":
        return dict(state, k=state["k"] + 1)
    if case == "at-sample-not-the-time":
        return dict(state, flags=dict(flags, at_sample=not flags["at_sample"]))
    if case == "after-the-stop-time":    # after the start: only the time is after it
        return dict(state, stop_time=t0 + (elapsed + c) / 2)
    raise AssertionError(case)


def _native_edits(case, s):
    """``(path, value)`` of the native snapshot ``s``'s fields that ``case`` sets."""
    if case == "elapsed-negative":
        return [("elapsed", -1e-12), ("time", s.startTime + (-1e-12 + s.elapsed_c))]
    if case == "stop-before-start":
        return [("stopTime", s.startTime - 1.0)]
    if case == "elapsed-before-initialisation":
        return [("elapsed", Ts), ("time", s.startTime + (Ts + s.elapsed_c))]
    if case == "not-at-a-sample-before-initialisation":
        return [("pending", 0)]
    if case == "k-before-initialisation":
        return [("k", 2)]
    if case == "k-not-the-time":
        return [("k", s.k + 1)]
    if case == "at-sample-not-the-time":
        return [("pending", 1 - s.pending)]
    if case == "after-the-stop-time":
        return [("stopTime", s.startTime + (s.elapsed + s.elapsed_c) / 2)]
    raise AssertionError(case)


def _edited(backend, dirs, data, case):
    if backend == "python":
        return json.dumps(_python_edit(case, json.loads(data))).encode()
    S = ns.snapshot_type(dirs["DriftEstimator"][backend])
    for path, value in _native_edits(case, ns.read(S, data)):
        data = ns.crafted(S, data, path, value)
    return data


@pytest.mark.parametrize("backend", diff.BACKENDS)
@pytest.mark.parametrize("case,when,words", CASES, ids=[c[0] for c in CASES])
def test_a_state_that_contradicts_its_time_is_refused(dirs, backend, case, when, words):
    drv = diff.Driver(dirs["DriftEstimator"][backend], 3 if backend.endswith("3") else 2)
    try:
        data = _saved(drv, when)
        blob = _edited(backend, dirs, data, case)
        assert blob != data
        assert call(drv, "gst", 1) == OK
        before = drv.ser(1)[1]
        assert call(drv, "des", blob, 2) == ERROR, (case, drv.logged)
        text = " ".join(m for _, m in drv.logged)
        assert words in text and "refused" in text, text
        assert 2 not in drv.states
        assert call(drv, "gst", 1) == OK and drv.ser(1)[1] == before  # nothing changed
        # the state as it was is taken
        assert call(drv, "des", data, 3) == OK and call(drv, "sst", 3) == OK, drv.logged
    finally:
        drv.free()
