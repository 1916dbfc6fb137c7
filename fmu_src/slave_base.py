"""What the three slaves share: variables from one table, checks, sampling and hidden state.

A slave lists its variables once in ``VARIABLES`` (name, type, causality, variability, start,
unit, min, max, description); this base registers them with pythonfmu, and the builder writes
units, ranges, dependencies and InitialUnknowns into the model description from the same table.

Timing: sample ``k = 1, 2, ...`` sits at ``t_k = t_start + (k - 1) Ts``.  After initialisation the
FMU is at sample 1; every ``fmi2DoStep`` of ``h = m Ts`` advances ``m`` samples.  Outputs that
depend on inputs (``DEPENDENCIES``) are computed from the inputs set at the current
communication point, when they are read or when the step commits them, so a master that sets
inputs in the order of the connections gets ``z_k`` from ``x_k`` with no hidden one-step lag.

Errors: a bad parameter, a non-finite input or a step that is not a whole number of sample
periods is logged with status error, naming the variable, the value and what is allowed, and the
call changes nothing (a rejected input keeps its previous value).  No Python exception leaves an
FMI entry point: pythonfmu would turn it into fmi2Fatal and show its text only with debug logging
on.  The FMU's loader shim (fmu_src/loader) sees the error log line and returns fmi2Error for
the call, and forwards error lines to the host's logger even when debug logging is off.

This module runs inside the FMU: standard library and pythonfmu only.
"""
import math
import sys

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status
from pythonfmu.default_experiment import DefaultExperiment

from driftfmu.models import parameters

_TYPES = {"Real": Real, "Integer": Integer}


class ModelError(Exception):
    """A problem the host must hear about: logged, then turned into fmi2Error."""


def var(name, causality, start=None, unit=None, description=None, type="Real",
        variability=None, low=None, high=None):
    """One row of a slave's ``VARIABLES`` table.

    Parameters named as in :data:`models.parameters.PARAMETERS` take their start value, unit,
    range and description from there unless given here.
    """
    p = parameters.PARAMETERS.get(name)
    if p is not None:
        start = p.default if start is None else start
        unit = p.unit if unit is None else unit
        description = p.description if description is None else description
        low = p.low if low is None else low
        high = p.high if high is None else high
    if variability is None:
        variability = "fixed" if causality == "parameter" else "continuous"
    if type == "Integer" and unit == "1":
        unit = None
    return {"name": name, "type": type, "causality": causality, "variability": variability,
            "start": start, "unit": unit, "min": low, "max": high,
            "description": "%s [%s]" % (description, unit or "1")}


class SlaveBase(Fmi2Slave):
    """Base of the Excitation, Accelerometer and DriftEstimator slaves."""

    author = "driftfmu contributors"
    license = "MIT"
    #: Set by the builder from ``driftfmu.__version__`` (the one place the version is written).
    version = None
    VARIABLES = ()
    DEPENDENCIES = {}
    CAN_HANDLE_VARIABLE_STEP = True
    #: Relative tolerance when checking that a step is a whole number of sample periods.
    STEP_TOLERANCE = 1e-9

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        _drop_duplicate_path(self.resources)
        self.description = self.__class__.__doc__.strip().splitlines()[0]
        self.k = 1
        self._dirty = True
        self._initialised = False
        for spec in self.VARIABLES:
            setattr(self, spec["name"], spec["start"] if spec["start"] is not None else 0.0)
            self.register_variable(self._make_variable(spec))
        # value reference -> name of the Real variables and of the Real inputs: the fast path
        # of get_real / set_real, called on every sample (value reference = table index)
        self._real_names = {vr: s["name"] for vr, s in enumerate(self.VARIABLES)
                            if s["type"] == "Real"}
        self._real_inputs = {vr: s["name"] for vr, s in enumerate(self.VARIABLES)
                             if s["type"] == "Real" and s["causality"] == "input"}
        self._last_step = None

    # -- registration -----------------------------------------------------------------------
    def _make_variable(self, spec):
        name = spec["name"]
        kind = _TYPES[spec["type"]]
        causality = getattr(Fmi2Causality, spec["causality"])
        variability = getattr(Fmi2Variability, spec["variability"])
        getter = lambda: getattr(self, name)
        setter = None if spec["causality"] == "output" else \
            (lambda value: self._call(self._write, spec, value))
        return kind(name, causality=causality, variability=variability,
                    description=spec["description"], getter=getter, setter=setter)

    def get_real(self, vrs):
        if self._dirty and self._initialised and self.DEPENDENCIES:
            self._call(self._refresh)  # outputs at this communication point, from its inputs
        names = self._real_names
        try:
            return [float(getattr(self, names[vr])) for vr in vrs]
        except KeyError:
            self._call(self._fail, "value references %s are not Real variables"
                       % sorted(set(vrs) - set(names)))
            return [float(getattr(self, names[vr])) if vr in names else math.nan
                    for vr in vrs]

    # pythonfmu's own accessors raise on a bad value reference or type; an exception in a
    # pythonfmu 0.7.0 call releases the instance's Python objects twice (a crash later), so
    # every other accessor is guarded: the problem is logged and the call returns fmi2Error.
    def get_integer(self, vrs):
        return self._guarded("fmi2GetInteger", super().get_integer, [0] * len(vrs), vrs)

    def get_boolean(self, vrs):
        return self._guarded("fmi2GetBoolean", super().get_boolean, [False] * len(vrs), vrs)

    def get_string(self, vrs):
        return self._guarded("fmi2GetString", super().get_string, [""] * len(vrs), vrs)

    def set_integer(self, vrs, values):
        self._guarded("fmi2SetInteger", super().set_integer, None, vrs, values)

    def set_boolean(self, vrs, values):
        self._guarded("fmi2SetBoolean", super().set_boolean, None, vrs, values)

    def set_string(self, vrs, values):
        self._guarded("fmi2SetString", super().set_string, None, vrs, values)

    def _guarded(self, what, call, fallback, vrs, *args):
        try:
            return call(vrs, *args)
        except KeyError as exc:
            problem = "value reference %s does not exist" % (exc.args[0],)
        except Exception as exc:
            problem = str(exc)
        self.log("%s: %s%r: %s" % (self.instance_name, what, tuple(vrs), problem),
                 Fmi2Status.error)
        return fallback

    def set_real(self, vrs, values):
        inputs = self._real_inputs
        for vr, value in zip(vrs, values):
            name = inputs.get(vr)
            if name is not None and math.isfinite(value):  # the per-sample fast path
                setattr(self, name, value)
                self._dirty = True
            elif vr in self._real_names:
                self._call(self._write, self.VARIABLES[vr], value)
            else:
                self._call(self._fail, "value reference %r is not a Real variable" % (vr,))

    def _write(self, spec, value):
        name = spec["name"]
        if spec["causality"] == "output":
            self._fail("%s is an output; only parameters and inputs can be set" % name)
        if spec["type"] == "Real" and not math.isfinite(value):
            self._fail("%s = %r is not finite; %s accepts finite values only"
                       % (name, value, spec["causality"]))
        if spec["causality"] == "parameter" and self._initialised:
            self._fail("%s is a fixed parameter and cannot be changed after initialisation"
                       % name)
        setattr(self, name, value)
        self._dirty = True

    # -- errors -----------------------------------------------------------------------------
    def _fail(self, message):
        """Log ``message`` with status error and abandon the current FMI call."""
        self.log("%s: %s" % (self.instance_name, message), Fmi2Status.error)
        raise ModelError(message)

    def _call(self, action, *args):
        """Run the body of an FMI call; return True, or False after logging what went wrong."""
        try:
            action(*args)
            return True
        except ModelError:
            return False
        except Exception as exc:  # a bug must reach the host's log, not crash or vanish
            self.log("%s: internal error in %s: %s: %s"
                     % (self.instance_name, getattr(action, "__name__", "call"),
                        type(exc).__name__, exc), Fmi2Status.error)
            return False

    def parameter_values(self):
        """The current values of all parameters, by name."""
        return {s["name"]: getattr(self, s["name"]) for s in self.VARIABLES
                if s["causality"] == "parameter"}

    def check_parameters(self):
        """Problems of the parameter values (one readable line each); extended by subclasses."""
        problems = parameters.check(self.parameter_values())
        for s in self.VARIABLES:
            if s["causality"] == "parameter" and s["name"] not in parameters.PARAMETERS:
                v = getattr(self, s["name"])
                low, high = s["min"], s["max"]
                if (low is not None and v < low) or (high is not None and v > high):
                    problems.append("%s = %r is out of range; allowed: %s <= %s <= %s"
                                    % (s["name"], v, low, s["name"], high))
        return problems

    # -- FMI calls --------------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self.start_time = start_time

    def exit_initialization_mode(self):
        self._initialised = self._call(self._initialise)

    def _initialise(self):
        problems = self.check_parameters()
        for msg in problems[:-1]:
            self.log("%s: %s" % (self.instance_name, msg), Fmi2Status.error)
        if problems:
            self._fail(problems[-1])
        self.k = 1
        self.start()
        self._dirty = True

    def do_step(self, current_time, step_size):
        return self._call(self._step, step_size)

    def _step(self, step_size):
        if not self._initialised:
            self._fail("cannot step: initialisation did not complete (see the errors above)")
        m = self._samples_in(step_size)
        if self._dirty and self.DEPENDENCIES:
            self._refresh()
        self.advance(m)
        self.k += m
        self._dirty = True

    def _samples_in(self, h):
        if self._last_step is not None and self._last_step[0] == h:
            return self._last_step[1]
        Ts = self.Ts
        m = round(h / Ts)
        if m < 1 or abs(h - m * Ts) > self.STEP_TOLERANCE * max(h, Ts):
            self._fail("communication step %r s is not a whole number of sample periods "
                       "Ts = %r s; allowed: h = m Ts with m = 1, 2, ..." % (h, Ts))
        self._last_step = (h, m)
        return m

    def _refresh(self):
        self.compute()
        self._dirty = False

    # -- hooks for the slaves ---------------------------------------------------------------
    def start(self):
        """Set the hidden state for sample 1 (after the parameters are checked)."""

    def compute(self):
        """Compute the outputs at sample ``self.k`` from the inputs and the committed state."""

    def advance(self, m):
        """Commit sample ``self.k`` and move the hidden state on by ``m`` samples."""

    HIDDEN = ()

    # -- FMU state: variables plus hidden state ---------------------------------------------
    def _get_fmu_state(self):
        state = {s["name"]: getattr(self, s["name"]) for s in self.VARIABLES}
        for name in ("k", "_dirty", "_initialised") + tuple(self.HIDDEN):
            state[name] = _plain(getattr(self, name))
        return state

    def _set_fmu_state(self, state):
        self._call(self._restore, state)

    def _restore(self, state):
        if not isinstance(state, dict) or "k" not in state:
            self._fail("not an FMU state of %s: %.80r" % (type(self).__name__, state))
        for name, value in state.items():
            setattr(self, name, value)
        self._last_step = None
        self.restore_hidden()

    @staticmethod
    def _fmu_state_from_bytes(data):
        """The state in ``data``, or None (which fmi2SetFMUstate then refuses with an error)
        when ``data`` is not a serialised state: an exception here would crash pythonfmu."""
        try:
            return Fmi2Slave._fmu_state_from_bytes(data)
        except Exception:
            return None

    def restore_hidden(self):
        """Turn hidden state read back from JSON into its working types (hook)."""


def _drop_duplicate_path(path):
    """pythonfmu 0.7.0 puts the resources folder at the front of sys.path on every
    instantiation; keep one entry, so that sys.path (and import time) do not grow."""
    if path:
        while sys.path.count(path) > 1:
            sys.path.remove(path)


def default_experiment(n_samples, Ts):
    """DefaultExperiment of ``n_samples`` samples at period ``Ts``, samples at 0..(n-1) Ts."""
    return DefaultExperiment(start_time=0.0, stop_time=(n_samples - 1) * Ts, step_size=Ts)


def _plain(value):
    """JSON-ready copy of hidden state (namedtuples become nested lists)."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value
