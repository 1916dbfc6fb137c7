"""The differential fuzz: one call script, three implementations, compared call by call.

Every script runs on the Python FMU (pythonfmu behind the loader shim), the native FMI 2.0 FMU
and, through the FMI 3.0 calls that correspond, the native FMI 3.0 FMU of the same model.  For
every call the three must agree on

- the status (fmi2OK == fmi3OK, ..., compared as numbers: the enums are equal);
- the values a getter returns, bit for bit;
- the class of log message: whether the call logged an error (every refused call must say why);
- the state machine: a script mixes calls in and out of order (setup, enter, exit, step, term,
  reset, get/set in every mode), so a twin in another mode answers one of them differently;
- no OK carries a negative variance (issue 31): a variance output read with OK is >= 0, and the
  filter covariances of every state got with OK (the hidden P12, P22, ..., P44 too; read from
  the serialised state) are valid by models/covariance.py.  Some initialisations set extreme
  parameters (near overflow, huge priors and estimates, tiny and huge noise) and the harmonic
  filter (``process = 2``); ``--extreme`` sets them at every one.

A script also sets stop times (steps past them must be refused; stop times that cannot be are
refused), frees its instance with the states it got still held and goes on in a new one (the
held states must be refused: they died with their instance), and calls gets and sets with
counts no array can have (refused before any element is touched).  A serialise, deserialise
and set round trip is one call of the script whose three statuses are compared.

Where the standards differ the comparison says so (``FMI3_DIFFERS``): FMI 3.0 has no
fmi3SetupExperiment (the start and stop times go with fmi3EnterInitializationMode, so ``setup``
is not called on FMI 3.0; a refused setup is followed by a good one before ``enter``) and no
status inquiries (``status``).

``python3 -m tests.fuzz.differential --seconds 1200`` runs random scripts for twenty minutes
(the FMUs are built first); the test suite runs a fixed-seed portion (tests/test_fuzz.py).
With ``--check`` each instance is also compared around every call (:func:`snapshot`): a call
that any of the three refuses must leave that instance as it was.
Each script runs in a child process (``--child``), so that a crash is a reported failure too.
"""
import argparse
import ctypes
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

#: Calls whose comparison with FMI 3.0 is skipped, and why (the standards differ).
FMI3_DIFFERS = {
    "setup": "FMI 3.0 has no fmi3SetupExperiment: the start time is an argument of "
             "fmi3EnterInitializationMode",
    "status": "FMI 3.0 has no status inquiries (fmi2Get*Status)",
}
BACKENDS = ("python", "native-fmi2", "native-fmi3")
#: The models with native twins.
MODELS = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")
OK, WARNING, DISCARD, ERROR, FATAL = range(5)
#: Counts no array can have (the count rule: at most 65,536 value references per call).
IMPOSSIBLE_COUNTS = (2 ** 64 - 1, 2 ** 61, 2 ** 31, 65537)


# -- one FMU, driven through raw calls ---------------------------------------------------------

class Driver:
    """One FMU instance of one backend; every call returns ``(status, values)``; the messages
    logged during the call are in ``self.logged`` (status, text)."""

    def __init__(self, unzipped, fmi):
        from fmpy import read_model_description
        self.fmi = fmi
        self.dir = str(unzipped)
        md = read_model_description(self.dir, validate=False)
        self.md = md
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.type = {v.name: v.type for v in md.modelVariables}
        self.logged = []
        self.states = {}
        self.start_time, self.stop_time = 0.0, None
        identifier = md.coSimulation.modelIdentifier
        if fmi == 2:
            from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, \
                fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free
            self._cb = fmi2CallbackFunctions()
            self._cb.logger = fmi2CallbackLoggerTYPE(
                lambda env, inst, status, cat, msg: self.logged.append(
                    (status, (msg or b"").decode("utf-8", "replace"))))
            self._cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            self._cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self.dir,
                                 modelIdentifier=identifier, instanceName="fuzz")
        else:
            from fmpy.fmi3 import FMU3Slave
            self.fmu = FMU3Slave(guid=md.guid, unzipDirectory=self.dir,
                                 modelIdentifier=identifier, instanceName="fuzz")
        self.dll = self.fmu.dll
        self.instantiate()

    def instantiate(self):
        if self.fmi == 2:
            self.fmu.instantiate(callbacks=self._cb, loggingOn=False)
        else:
            self.fmu.instantiate(loggingOn=False, logMessage=lambda env, status, cat, msg:
                                 self.logged.append((status, (msg or b"").decode(
                                     "utf-8", "replace"))))
        self.c = self.fmu.component

    def raw(self, name, argtypes, *args):
        f = getattr(self.dll, name)
        proto = ctypes.CFUNCTYPE(c_int, c_void_p, *argtypes)(ctypes.cast(f, c_void_p).value)
        return proto(self.c, *args)

    # the calls of a script, by FMI 2.0 name
    def setup(self, t0, stop=None):
        """fmi2SetupExperiment (``stop``: the stop time, None: not defined); FMI 3.0 keeps both
        for fmi3EnterInitializationMode."""
        self.start_time, self.stop_time = t0, stop
        if self.fmi == 3:
            return OK, None
        return self.raw("fmi2SetupExperiment", [c_int, c_double, c_double, c_int, c_double],
                        0, 0.0, t0, int(stop is not None), 0.0 if stop is None else stop), None

    def enter(self):
        if self.fmi == 2:
            return self.raw("fmi2EnterInitializationMode", []), None
        stop = getattr(self, "stop_time", None)
        return self.raw("fmi3EnterInitializationMode", [c_int, c_double, c_double, c_int,
                                                         c_double],
                        0, 0.0, self.start_time, int(stop is not None),
                        0.0 if stop is None else stop), None

    def exit(self):
        return self.raw("fmi%dExitInitializationMode" % self.fmi, []), None

    def term(self):
        return self.raw("fmi%dTerminate" % self.fmi, []), None

    def reset(self):
        status = self.raw("fmi%dReset" % self.fmi, [])
        if status <= WARNING:  # as fmi2Reset forgets the experiment
            self.start_time, self.stop_time = 0.0, None
        return status, None

    def _vrs(self, names):
        return (c_uint * len(names))(*[self.vr[n] for n in names])

    def setr(self, names, values):
        vals = (c_double * len(values))(*values)
        if self.fmi == 2:
            return self.raw("fmi2SetReal", [c_void_p, c_size_t, c_void_p],
                            self._vrs(names), len(names), vals), None
        return self.raw("fmi3SetFloat64", [c_void_p, c_size_t, c_void_p, c_size_t],
                        self._vrs(names), len(names), vals, len(values)), None

    def seti(self, names, values):
        vals = (c_int * len(values))(*values)
        if self.fmi == 2:
            return self.raw("fmi2SetInteger", [c_void_p, c_size_t, c_void_p],
                            self._vrs(names), len(names), vals), None
        return self.raw("fmi3SetInt32", [c_void_p, c_size_t, c_void_p, c_size_t],
                        self._vrs(names), len(names), vals, len(values)), None

    def getr(self, names):
        out = (c_double * len(names))()
        if self.fmi == 2:
            s = self.raw("fmi2GetReal", [c_void_p, c_size_t, c_void_p], self._vrs(names),
                         len(names), out)
        else:
            s = self.raw("fmi3GetFloat64", [c_void_p, c_size_t, c_void_p, c_size_t],
                         self._vrs(names), len(names), out, len(names))
        return s, ([float(v).hex() for v in out] if s <= WARNING else None)

    def count(self, which, n):
        """A get or set (``which``: getr, setr, geti, seti) of ``n`` value references with
        one-element arrays, ``n`` a count no array can have (FMI 3.0: nValues = n too)."""
        kind = {"getr": ("Get", "Real", "Float64", c_double),
                "setr": ("Set", "Real", "Float64", c_double),
                "geti": ("Get", "Integer", "Int32", c_int),
                "seti": ("Set", "Integer", "Int32", c_int)}[which]
        vr, values = (c_uint * 1)(0), (kind[3] * 1)()
        if self.fmi == 2:
            return self.raw("fmi2%s%s" % kind[:2], [c_void_p, c_size_t, c_void_p], vr, n,
                            values), None
        return self.raw("fmi3%s%s" % (kind[0], kind[2]), [c_void_p, c_size_t, c_void_p,
                                                         c_size_t], vr, n, values, n), None

    def step(self, t, h):
        if self.fmi == 2:
            return self.raw("fmi2DoStep", [c_double, c_double, c_int], t, h, 1), None
        flags = [c_int(0) for _ in range(3)]
        last = c_double(0.0)
        return self.raw("fmi3DoStep", [c_double, c_double, c_int, c_void_p, c_void_p,
                                       c_void_p, c_void_p], t, h, 1, byref(flags[0]),
                        byref(flags[1]), byref(flags[2]), byref(last)), None

    def status(self, kind):
        if self.fmi == 3:  # FMI3_DIFFERS
            return OK, None
        out = c_double(0.0)
        s = self.raw("fmi2GetRealStatus", [c_int, c_void_p], kind, byref(out))
        return s, ([out.value.hex()] if s <= WARNING else None)

    def gst(self, slot):
        p = c_void_p(self.states.get(slot))
        s = self.raw("fmi%dGet%s" % (self.fmi, "FMUstate" if self.fmi == 2 else "FMUState"),
                     [c_void_p], byref(p))
        if s <= WARNING:
            self.states[slot] = p.value
        return s, None

    def sst(self, slot):
        return self.raw("fmi%dSet%s" % (self.fmi, "FMUstate" if self.fmi == 2 else "FMUState"),
                        [c_void_p], c_void_p(self.states.get(slot))), None

    def fst(self, slot):
        p = c_void_p(self.states.get(slot))
        s = self.raw("fmi%dFree%s" % (self.fmi, "FMUstate" if self.fmi == 2 else "FMUState"),
                     [c_void_p], byref(p))
        if s <= WARNING:
            self.states.pop(slot, None)
        return s, None

    def ser(self, slot):
        """The serialised bytes of state ``slot`` (status, bytes)."""
        size = c_size_t(0)
        name = "FMUstate" if self.fmi == 2 else "FMUState"
        s = self.raw("fmi%dSerialized%sSize" % (self.fmi, name), [c_void_p, c_void_p],
                     c_void_p(self.states.get(slot)), byref(size))
        if s > WARNING:
            return s, None
        buf = ctypes.create_string_buffer(size.value)
        s2 = self.raw("fmi%dSerialize%s" % (self.fmi, name), [c_void_p, c_void_p, c_size_t],
                      c_void_p(self.states.get(slot)), buf, size.value)
        return max(s, s2), (buf.raw if s2 <= WARNING else None)

    def des(self, data, slot):
        """Deserialise into the state the slot holds (NULL when it holds none): the FMU writes
        into that live state or returns a new one."""
        p = c_void_p(self.states.get(slot))
        name = "fmi2DeSerializeFMUstate" if self.fmi == 2 else "fmi3DeserializeFMUState"
        s = self.raw(name, [c_void_p, c_size_t, c_void_p], data, len(data), byref(p))
        if s <= WARNING:
            self.states[slot] = p.value
        return s, None

    def renew(self):
        """Free the instance without freeing its states (FreeInstance frees them: the handles
        the slots keep are stale now) and instantiate a new one in the same library."""
        getattr(self.fmu, "fmi%dFreeInstance" % self.fmi)(self.c)
        self.instantiate()
        self.start_time, self.stop_time = 0.0, None
        return OK, None

    def free(self):
        for slot in list(self.states):
            self.fst(slot)
        self.fmu.freeInstance()


# -- scripts -----------------------------------------------------------------------------------

def model_info(unzipped):
    from fmpy import read_model_description
    md = read_model_description(str(unzipped), validate=False)
    variables = [v for v in md.modelVariables if v.name != "time"]
    start = {v.name: float(v.start) for v in variables if v.start is not None}
    return {"name": md.modelName,
            "inputs": [v.name for v in variables if v.causality == "input"],
            "outputs": [v.name for v in variables if v.causality == "output"],
            "reals": [v.name for v in variables if v.type in ("Real", "Float64")],
            "params": [v.name for v in variables if v.causality == "parameter"
                       and v.type in ("Real", "Float64")],
            "ints": [v.name for v in variables if v.type in ("Integer", "Int32")],
            "start": start, "Ts": start.get("Ts", 1e-3)}


#: Extreme parameter values (issue 31): near overflow, huge priors and estimates, tiny and huge
#: noise variances; the harmonic filter (process = 2) with them.  A script of
#: :func:`random_script` sets some of them at an initialisation (always with ``extreme``).
EXTREMES = {
    "P0": (1e154, 1e16, 1e300, 1e-300, 5e-324, 0.0), "P0y": (1e154, 1e16, 1e300, 0.0),
    "x0": (3e8, -3e8, 1e150, -1e300, 1e-300), "y0": (3e8, 1e150),
    "R": (5e-324, 1e-300, 1e-20, 1e300), "Ry": (5e-324, 1e-20, 1e300),
    "Q": (0.0, 1e-300, 1e300), "Qy": (0.0, 1e300), "Qh": (0.0, 1e-300, 1e300),
    "A": (0.9999999999999999, -0.9999999999999999), "rho": (1.0, -1.0),
    "a2": (1e150, -1e150, 1e-300), "a1": (1e-300, 1e150), "bx": (1e150,), "by": (-1e150,),
    "X": (1e300,), "Xy": (1e300,), "B": (1e300,), "a3": (1e100,), "a4": (1e75,),
}
#: Inputs of extreme size, with :data:`EXTREMES`.
EXTREME_INPUTS = (0.0, 1e150, -1e150, 1e300, 3e8)


def extreme_calls(info, rng):
    """Calls setting a few parameters of :data:`EXTREMES` (and process = 2 where the model has
    it, usually), in Initialization Mode."""
    calls = []
    if "process" in info["ints"] and rng.random() < 0.8:
        calls.append(["seti", ["process"], [2]])
    names = [n for n in EXTREMES if n in info["params"]]
    for name in rng.sample(names, min(len(names), rng.randint(1, 3))):
        calls.append(["setr", [name], [rng.choice(EXTREMES[name])]])
    return calls


def random_script(info, rng, n_calls=60, extreme=False):
    """A random call script (a list of calls ``[op, args...]``): mostly a valid run, with calls
    out of order, bad values, refused and retried exits, state round trips and lifecycle calls
    mixed in; extreme parameters and the harmonic filter at some initialisations (at every one
    with ``extreme``, and extreme inputs then)."""
    Ts = info["Ts"]
    calls = []
    t = [0.0]

    def input_value():
        if extreme and rng.random() < 0.3:
            return rng.choice(EXTREME_INPUTS)
        return round(rng.gauss(0, 1.5), 9)

    def bad_value(base):
        return rng.choice([1e300, -1e308, math.nan, math.inf, -math.inf, 1e-320, -base,
                           0.0, -0.0, base * 1e6, 2.2e-308])

    def initialise():
        t0 = rng.choice([0.0, 0.0, 0.0, 1.5, -2.0, 1e9])
        t[0] = t0
        if rng.random() < 0.15:  # a stop time: a few samples on, or at the start
            if rng.random() < 0.3:  # one that cannot be (refused), then a good one
                calls.append(["setup", t0, rng.choice([t0 - 1.0, math.nan, math.inf])])
            stop = t0 + Ts * rng.choice((0, 2, 3.5, 6, 20, 60))
            calls.extend([["setup", t0, stop], ["enter"]])
        else:
            calls.extend([["setup", t0], ["enter"]])
        for name in info["inputs"]:
            if rng.random() < 0.7:
                calls.append(["setr", [name], [input_value()]])
        if extreme or rng.random() < 0.1:
            calls.extend(extreme_calls(info, rng))
        if info["ints"] and rng.random() < 0.3:
            calls.append(["seti", [rng.choice(info["ints"])], [rng.randint(-2, 4)]])
        if rng.random() < 0.3 and info["params"]:
            # a refused exit, then the parameter corrected and the exit retried
            name = rng.choice(info["params"])
            base = info["start"].get(name, 0.0)
            calls.extend([["setr", [name], [bad_value(base)]], ["getr", list(info["outputs"])],
                          ["exit"], ["getr", list(info["outputs"])],
                          ["setr", [name], [base]]])
        elif rng.random() < 0.2 and info["params"]:
            name = rng.choice(info["params"])
            base = info["start"].get(name, 0.0)
            calls.append(["setr", [name], [base * rng.choice((0.5, 2.0, 1.0 + 1e-9))]])
        if info["ints"] and rng.random() < 0.3:
            calls.append(["seti", [info["ints"][0]], [int(info["start"].get(info["ints"][0], 1))]])
        calls.extend([["exit"], ["getr", list(info["outputs"])]])

    initialise()
    for _ in range(n_calls):
        r = rng.random()
        if r < 0.25 and info["inputs"]:
            value = input_value() if rng.random() < 0.9 else bad_value(1.0)
            calls.append(["setr", [rng.choice(info["inputs"])], [value]])
        elif r < 0.28 and info["params"]:
            name = rng.choice(info["params"])
            calls.append(["setr", [name], [info["start"].get(name, 0.0) + 1e-3]])
        elif r < 0.55:
            if rng.random() < 0.95:
                h = Ts * rng.choice((1, 1, 1, 2, 3, 0.5, 0.3, 2.5, 1e7))
            else:
                h = rng.choice((0.0, -Ts, math.nan, math.inf, 1e308))
            tt = t[0] if rng.random() < 0.95 else rng.choice((math.nan, math.inf, 123.0))
            calls.append(["step", tt, h])
            if math.isfinite(h) and h > 0:
                t[0] += h
        elif r < 0.68:
            calls.append(["getr", rng.sample(info["reals"], min(len(info["reals"]),
                                                                rng.randint(1, 4)))])
        elif r < 0.74:
            calls.append(["gst", rng.randrange(3)])
        elif r < 0.79:
            calls.append(["sst", rng.randrange(3)])
        elif r < 0.84:
            calls.append(["serdes", rng.randrange(3), rng.randrange(3, 5)])
        elif r < 0.86:
            calls.append(["garbage", rng.randrange(3, 5)])
        elif r < 0.88:
            calls.append(["fst", rng.randrange(5)])
        elif r < 0.90:
            calls.append(rng.choice([["exit"], ["enter"], ["setup", 0.0], ["term"],
                                     ["status", rng.choice((0, 1, 2, 3, 7))]]))
        elif r < 0.91:  # a count no array can have
            calls.append(["count", rng.choice(("getr", "setr", "geti", "seti")),
                          rng.choice(IMPOSSIBLE_COUNTS)])
        elif r < 0.92:
            # the instance freed with its states kept by the host, a new one made: the kept
            # states (slots 0..4) are refused from now on
            calls.append(["renew"])
            initialise()
        else:
            calls.append(rng.choice([["reset"], ["term"]]))
            if rng.random() < 0.8:
                if calls[-1] == ["term"]:
                    calls.append(["reset"])
                initialise()
        if rng.random() < 0.5:
            calls.append(["getr", list(info["outputs"])])
    return calls


def snapshot(driver, reals):
    """What a refused call must leave as it was: the statuses and values of every Real, and of
    a state got and serialised now (the mode, the hidden state, the time)."""
    driver.logged = []
    got_reals = driver.getr(reals)
    driver.states.pop("snapshot", None)
    got = driver.gst("snapshot")[0]
    data = driver.ser("snapshot") if got <= WARNING else None
    if got <= WARNING:
        driver.fst("snapshot")
    driver.logged = []
    return got_reals, got, data


def run_script(driver, script, reals=None):
    """Run ``script`` on ``driver``; per call ``[status, values, logged an error, last message,
    changed]``.  With ``reals`` (the names of every Real variable), the instance is compared
    around each call (:func:`snapshot`): ``changed`` says that a call refused with an error or
    worse changed it."""
    out = []
    for call in script:
        op, args = call[0], call[1:]
        before = snapshot(driver, reals) if reals else None
        driver.logged = []
        if op == "serdes":
            s1, data = driver.ser(args[0])
            s2 = ERROR if data is None else driver.des(data, args[1])[0]
            s3 = ERROR if s2 > WARNING else driver.sst(args[1])[0]
            status, values = max(s1, s2, s3), [s1, s2, s3]
        elif op == "garbage":
            s1 = driver.des(b'{"k": 1}\x00garbage' * 3, args[0])[0]
            s2 = driver.sst(args[0])[0] if s1 <= WARNING else s1
            status, values = max(s1, s2), [s1, s2]
        else:
            status, values = getattr(driver, op)(*args)
        errors = any(s >= ERROR for s, _ in driver.logged)
        last = [m for _, m in driver.logged][-1:]
        changed = bool(reals) and status >= ERROR and snapshot(driver, reals) != before
        out.append([int(status), values, errors, last, changed,
                    variance_problems(driver, call, status, values)])
    return out


#: Outputs that are variances: a value read with OK is >= 0 (issue 31).
VARIANCE_OUTPUTS = ("P", "P_xx", "P_yy")


def variance_problems(driver, call, status, values):
    """What a call answered OK carries that no covariance may hold: a variance output below 0
    (``getr``), or a filter covariance of the state just got (``gst``) that the rule of
    models/covariance.py refuses (the hidden P12, P22, P44, ... included)."""
    if status > WARNING:
        return []
    if call[0] == "getr" and values:
        return ["%s = %r is a negative variance" % (name, float.fromhex(v))
                for name, v in zip(call[1], values)
                if name in VARIANCE_OUTPUTS and not float.fromhex(v) >= 0.0]
    if call[0] == "gst" and driver.md.modelName in ("DriftEstimator", "DualDriftEstimator"):
        return hidden_covariance_problems(driver, call[1])
    return []


def hidden_covariance_problems(driver, slot):
    """The filter covariances of the state in ``slot`` (serialised: the Python FMU's JSON, the
    native FMUs' snapshot, its committed and its pending filter state) that are not valid."""
    from driftfmu.models import covariance, dualaxis, harmonic
    try:
        from . import native_state as ns
    except ImportError:  # (run as a script: the child process)
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import native_state as ns
    status, data = driver.ser(slot)
    if data is None:
        return []
    model = driver.md.modelName
    found = []
    try:
        plain = json.loads(data)
    except ValueError:
        plain = None
    if plain is not None:  # the Python FMU: the committed filter state
        value = plain.get("_state")
        if value is None:
            return []
        if model == "DriftEstimator":
            st = harmonic.from_plain(value)
            lowers = [("_state", harmonic.covariance_of(st) or ((st.P,),))]
        else:
            lowers = [("_state", dualaxis.covariance_of(dualaxis.from_plain(value))[1])]
    else:
        snap = ns.read(ns.snapshot_type(driver.dir), data)
        process = snap.v.process
        lowers = []
        for which in ("state", "pending"):
            st = getattr(snap.h, which)
            if model == "DriftEstimator":
                lower = (((st.P,), (st.P12, st.P22)) if process == harmonic.HARMONIC
                         else ((st.P,),))
            elif process == dualaxis.HARMONIC:
                h = st.h
                lower = ((h.P11,), (h.P12, h.P22), (h.P13, h.P23, h.P33),
                         (h.P14, h.P24, h.P34, h.P44))
            else:
                lower = ((st.g.Pxx,), (st.g.Pxy, st.g.Pyy))
            lowers.append((which, lower))
    for which, lower in lowers:
        if all(math.isfinite(v) for row in lower for v in row) and not covariance.valid(lower):
            found.append("the hidden %s's covariance %s is not valid" % (which, lower))
    return found


def compare(script, results, plant=None):
    """Disagreements between the backends' results (a list of readable lines)."""
    found = []
    names = list(results)
    for i, call in enumerate(script):
        rows = {name: results[name][i] for name in names}
        found += ["call %d %s: a refused call changed the %s instance (%s)" % (
            i, json.dumps(call), name, rows[name][3]) for name in names if rows[name][4]]
        found += ["call %d %s: the %s FMU answered OK with %s" % (i, json.dumps(call), name, p)
                  for name in names for p in rows[name][5]]
        for name in names[1:]:
            if name == "native-fmi3" and call[0] in FMI3_DIFFERS:
                continue
            a, b = rows[names[0]], rows[name]
            what = []
            if a[0] != b[0]:
                what.append("status %d vs %d" % (a[0], b[0]))
            elif a[1] != b[1]:
                what.append("values %s vs %s" % (a[1], b[1]))
            elif a[2] != b[2]:
                what.append("logged an error: %s vs %s" % (a[2], b[2]))
            if what:
                found.append("call %d %s: %s vs %s: %s (%s: %s | %s: %s)" % (
                    i, json.dumps(call), names[0], name, "; ".join(what), names[0], a[3],
                    name, b[3]))
        if found:
            break  # the first disagreement; what follows may only repeat it
    return found


# -- the child process: one model, many scripts ------------------------------------------------

def child(dirs, seeds, n_calls, plant, check=False, extreme=False):
    """Run each seed's script on the three backends (``check``: with :func:`snapshot` around
    every call; ``extreme``: :func:`random_script`'s); print one JSON line per script."""
    info = model_info(dirs["native-fmi2"])
    drivers = {"python": Driver(dirs["python"], 2), "native-fmi2": Driver(dirs["native-fmi2"], 2),
               "native-fmi3": Driver(dirs["native-fmi3"], 3)}
    for seed in seeds:
        script = random_script(info, random.Random(seed), n_calls, extreme)
        results = {}
        for name, driver in drivers.items():
            driver.reset()
            for slot in list(driver.states):
                driver.fst(slot)
            driver.states.clear()  # (stale handles of a renewed instance are refused)
            results[name] = run_script(driver, script, info["reals"] if check else None)
            if plant == name:  # a planted difference: the twin answers one read differently
                for call, row in zip(script, results[name]):
                    if call[0] == "getr" and row[1] is not None:
                        row[1] = [float.fromhex(row[1][0]).__add__(1.0).hex()] + row[1][1:]
                        break
        print(json.dumps({"seed": seed, "problems": compare(script, results),
                          "calls": len(script)}), flush=True)
    for driver in drivers.values():
        driver.free()


#: valgrind options for :func:`run` (memory errors only: CPython's uninitialised-value reports
#: are not the FMUs').
VALGRIND = ["valgrind", "-q", "--undef-value-errors=no", "--error-exitcode=99",
            "--suppressions=%s" % (Path(__file__).resolve().parent / "valgrind.supp")]


def child_environment(valgrind=False):
    """The child's environment: it imports the driftfmu that this process imported (the
    checkout's, when this module runs as ``python -m tests.fuzz.differential`` in a checkout
    that is not installed, where the child's own path, tests/fuzz, would not find it)."""
    import driftfmu
    root = str(Path(driftfmu.__file__).resolve().parent.parent)
    rest = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p and p != root]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([root] + rest))
    if valgrind:
        env["PYTHONMALLOC"] = "malloc"
    return env


def run(dirs, seeds, n_calls=60, plant=None, time_limit=600, valgrind=False, check=False,
        extreme=False):
    """Run the scripts of ``seeds`` in a child process (under valgrind if asked; ``check``:
    every refused call must leave its instance unchanged; ``extreme``: extreme parameters at
    every initialisation): a list of problem lines (a crash, a hang or a valgrind error of the
    child is one)."""
    command = (VALGRIND if valgrind else []) + [
        sys.executable, str(Path(__file__).resolve()), "--child",
               json.dumps({k: str(v) for k, v in dirs.items()}), "--seeds",
               ",".join(map(str, seeds)), "--calls", str(n_calls)]
    if plant:
        command += ["--plant", plant]
    if check:
        command.append("--check")
    if extreme:
        command.append("--extreme")
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=time_limit,
                              env=child_environment(valgrind))
    except subprocess.TimeoutExpired:
        return ["hang: the scripts did not end within %g s" % time_limit]
    problems, seen = [], set()
    for line in done.stdout.splitlines():
        if line.startswith("{"):
            row = json.loads(line)
            seen.add(row["seed"])
            problems += ["seed %d: %s" % (row["seed"], p) for p in row["problems"]]
    if done.returncode != 0:
        problems.append("the child exited with %d after seeds %s: %s" % (
            done.returncode, sorted(seen), done.stderr[-2000:]))
    return problems


def prepare(work):
    """Build the Python and native FMUs into ``work`` and unzip them: {model: {backend: dir}}."""
    import fmpy
    from driftfmu.fmu_src.builder import NAMES, build_fmus
    from driftfmu.fmu_src.native_build import build_native_fmus
    work = Path(work)
    python = dict(zip(NAMES, build_fmus(work / "fmus", names=NAMES, log=lambda line: None)))
    native = build_native_fmus(work / "native", log=lambda line: None)
    return unzip_all(python, native, work / "unzipped")


def unzip_all(python, native, folder):
    import fmpy
    dirs = {}
    for name in native[2]:
        dirs[name] = {}
        for backend, fmu in (("python", python[name]), ("native-fmi2", native[2][name]),
                             ("native-fmi3", native[3][name])):
            target = Path(folder) / name / backend
            if not target.exists():
                fmpy.extract(str(fmu), unzipdir=str(target))
            dirs[name][backend] = target
    return dirs


#: The defect of issue 20 planted back into a copy of a native twin's sources: the transition to
#: step mode taken before the parameter check in fmi2ExitInitializationMode.
PLANTED_DEFECT = ("""    if (model_check(comp) > 0)
        return STATUS_ERROR;
    comp->state = STATE_STEP;""", """    comp->state = STATE_STEP;
    comp->initialised = 0;
    if (model_check(comp) > 0)
        return STATUS_ERROR;""")


#: The defects of issue 31 planted back the same way, by class: a state kept across the free of
#: its instance (not freed with it, so a later instance takes it), a stop time not honoured, a
#: count no array can have taken at its word.
PLANTED_31 = {
    "states": ("    free_states_of(comp);   /* every state", "    /* free_states_of(comp); every"),
    "stop": ("    if (!LIKELY(position - tol <= (comp->stopTime - comp->startTime) / Ts))",
             "    if (0)"),
    "counts": ("    if (LIKELY(n <= MAX_VALUES_PER_CALL))\n        return 1;",
               "    return 1;"),
}


def plant_defect(unzipped, folder, defect=None):
    """A copy of the native FMU unzipped in ``unzipped``, in ``folder``, whose binary is rebuilt
    from its own sources with ``defect`` (``(old, new)`` text of cosimulation.c; default
    :data:`PLANTED_DEFECT`): the twin that the differential fuzz must tell from the others."""
    defect = defect or PLANTED_DEFECT
    import shutil
    from driftfmu.fmu_src import native_build
    from fmpy import read_model_description
    folder = Path(folder)
    shutil.copytree(str(unzipped), str(folder))
    source = folder / "sources" / "cosimulation.c"
    text = source.read_text()
    assert defect[0] in text, "the planted code changed: update %r" % (defect[0],)
    source.write_text(text.replace(*defect))
    md = read_model_description(str(folder), validate=False)
    identifier = md.coSimulation.modelIdentifier
    subprocess.run(native_build.PLAIN_COMPILE.format(identifier=identifier), shell=True,
                   cwd=str(folder), check=True, capture_output=True)
    sub = "linux64" if md.fmiVersion.startswith("2") else "x86_64-linux"
    shutil.copyfile(str(folder / (identifier + ".so")),
                    str(folder / "binaries" / sub / (identifier + ".so")))
    return folder


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m tests.fuzz.differential",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--calls", type=int, default=60)
    parser.add_argument("--batch", type=int, default=20, help="scripts per child process")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--seeds", default="", help=argparse.SUPPRESS)
    parser.add_argument("--plant", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--check", action="store_true",
                        help="also compare each instance around every call: a refused call "
                             "must change nothing (about three times slower)")
    parser.add_argument("--extreme", action="store_true",
                        help="extreme parameters (near overflow, huge priors and estimates, "
                             "tiny and huge noise) and the harmonic filter at every "
                             "initialisation")
    args = parser.parse_args(argv)
    if args.child:
        child(json.loads(args.child), [int(s) for s in args.seeds.split(",") if s],
              args.calls, args.plant, args.check, args.extreme)
        return 0
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(2 ** 31)
    rng = random.Random(seed)
    with tempfile.TemporaryDirectory(prefix="driftfmu-difffuzz-") as work:
        dirs = prepare(work)
        end = time.monotonic() + args.seconds
        scripts = failures = 0
        while time.monotonic() < end:
            model = rng.choice(sorted(dirs))
            seeds = [rng.randrange(2 ** 31) for _ in range(args.batch)]
            problems = run(dirs[model], seeds, args.calls, check=args.check,
                           extreme=args.extreme or rng.random() < 0.5)
            scripts += len(seeds)
            failures += len(problems)
            for p in problems:
                print("FAIL %s %s" % (model, p), flush=True)
        print("differential fuzz: %d scripts on %d models x 3 backends, %d disagreements "
              "(seed %d)" % (scripts, len(dirs), failures, seed))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
