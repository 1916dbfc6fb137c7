"""Internal (not a stable API; use driftfmu.build_fmus instead).

What the three slaves share: variables from one table, checks, sampling and hidden state.

A slave lists its variables once in ``VARIABLES`` (name, type, causality, variability, start,
unit, min, max, description); this base registers them with pythonfmu, and the builder writes
units, ranges, dependencies and InitialUnknowns into the model description from the same table.

Timing (the sampled-data step rule).  Sample ``k = 1, 2, ...`` sits at the instant
``t_k = t_start + (k - 1) Ts``.  The FMU keeps its own time ``t`` (the start time plus the sum
of the accepted step sizes, summed with compensation) and a time is *at* sample ``k`` when
``|(t - t_start) / Ts - (k - 1)| <= 1e-6`` (:data:`INSTANT_TOLERANCE`, a millionth of a sample
period).  ``fmi2DoStep(t, h)`` accepts any finite ``h > 0`` and processes the sample instants in
``[t, t + h)`` in order:

* if ``t`` is at sample ``k``, sample ``k`` is *pending* and is committed with the inputs set at
  ``t`` (feedthrough: what the outputs showed at ``t``);
* every other instant in the step is processed with the inputs held from ``t`` (zero-order
  hold); the DriftEstimator takes the held ``z`` as the measurement of the *first* instant of a
  step only and predicts through the others;
* if ``t + h`` is at a sample instant, that sample becomes pending: outputs that depend on
  inputs (``DEPENDENCIES``) are computed from the inputs set at ``t + h`` when they are read or
  when the next step commits them, so a master that sets inputs in the order of the connections
  gets ``z_k`` from ``x_k`` with no hidden one-step lag.  Otherwise the outputs hold those of the
  last sample processed.

Whole-sample steps ``h = m Ts`` therefore advance ``m`` samples, bit for bit as the rule that
allowed only those.  One step processes at most :data:`MAX_SAMPLES_PER_STEP` instants and
``Ts >= 1e-9`` s, so no call runs unbounded.  A step that would end after a defined stop time
(fmi2SetupExperiment) by more than :data:`INSTANT_TOLERANCE` sample periods is refused.  Outputs read in Initialization Mode are computed
from the start values and inputs (sample 1), as the InitialUnknowns declare.

Errors: a bad parameter, a non-finite input, a step ``h`` that is not finite and positive or
spans too many samples, a computation that would make an output or hidden state non-finite
from finite values (overflow), and one that would leave a filter's covariance negative or not
positive semi-definite (:mod:`driftfmu.models.covariance`: the numbers exceed what double
precision can carry) are logged with status error, naming the variable, the value and what is
allowed, and the call changes nothing: a call is validated as a whole before anything is
assigned, and samples are computed into locals and committed only when all of them are valid.
No Python exception leaves an FMI entry point: pythonfmu would turn it into fmi2Fatal and show
its text only with debug logging on.  The FMU's loader shim (fmu_src/loader) sees the error log
line and returns fmi2Error for the call, and forwards error lines to the host's logger even when
debug logging is off.

FMU state: a JSON-ready dict of the fields ``model`` (class name), ``guid`` (of the FMU),
``version`` (driftfmu's), every variable of ``VARIABLES``, ``k``, ``time``
(``[t_start, elapsed, compensation]``), ``stop_time`` (None: none defined), ``flags`` and the
slave's ``HIDDEN`` state.  Setting a state reads exactly these fields, checks each one as the
native twins check theirs (type, finiteness, variances, the mode flags, the state before
initialisation, the parameters, the timing, the stop time), refuses a state of another model,
build or version, and assigns only when all of it is valid; the loader shim has the instance
make the same check when a host deserialises the bytes (:class:`Deserialised`).

This module runs inside the FMU: standard library and pythonfmu only (NumPy where the FMU's
Python has it, for :class:`Blocks`, the same bits without it), and it works under
``python -OO`` (no docstring is read, no ``assert`` is relied on).
"""
import array
import math
import sys
import uuid

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.enums import Fmi2Status
from pythonfmu.default_experiment import DefaultExperiment

from driftfmu.models import drift, excitation, noise, parameters

_TYPES = {"Real": Real, "Integer": Integer}

#: Most sample instants one ``fmi2DoStep`` may process (a step spanning more is an fmi2Error).
MAX_SAMPLES_PER_STEP = 1000000
#: A time is at a sample instant when within this many sample periods of it.
INSTANT_TOLERANCE = 1e-6
#: The value reference through which the loader shim (fmu_src/loader/fmi2_shim.c, SHIM_VR)
#: tells the model what pythonfmu 0.7.0 does not pass on: set to ``[startTime, stopTimeDefined,
#: stopTime]`` it is fmi2SetupExperiment (pythonfmu hands the slave the start time only); set to
#: ``[1.0]`` it makes the next fmi2SetFMUstate, with a state fresh from bytes, the check of
#: fmi2DeSerializeFMUstate (changes nothing).  No variable has it; the shim refuses it from a
#: host.
SHIM_VR = 0x7FFFFFFF
#: Namespace of the deterministic GUIDs: uuid5(this, "<module>.<class> <version>").
GUID_NAMESPACE = uuid.UUID("8d0f3bb2-5a52-4c55-9c1e-6d0e1b7c2a11")
#: The sampled-data step rule, in the model description of every FMU.
STEP_RULE = ("Sampled-data FMU: sample k is at t_start + (k-1) Ts. fmi2DoStep accepts any "
             "finite h > 0 and processes the sample instants in [t, t+h) in order (at most "
             "%d per step) with the inputs held from t (zero-order hold); at a sample instant "
             "the outputs follow the inputs set there, between instants they hold the last "
             "sample. FMU states carry the model, GUID and version and are refused elsewhere."
             % MAX_SAMPLES_PER_STEP)

_STATE_META = ("model", "guid", "version")
#: Names of the variances in the hidden states (the filters' P; C twin: the SLAVE_HIDDEN_REAL
#: checks with nonnegative = 1): a negative one is refused.
VARIANCES = frozenset(("P", "P22", "Pxx", "Pyy", "P11", "P33", "P44", "Pbb"))
_STATE_FIELDS = ("k", "time", "stop_time", "flags")
_FLAGS = ("initialised", "in_init", "at_sample", "terminated")
_ARITHMETIC = (ArithmeticError, ValueError)  # overflow, 0/0, floor(nan) in the models
_INF = math.inf
_ceil = math.ceil
_TERMINATED = ("the instance is terminated (fmi2Terminate); allowed: fmi2Reset, "
               "fmi2FreeInstance, the get functions and fmi2GetFMUstate/fmi2SetFMUstate")


class ModelError(Exception):
    """A problem the host must hear about: logged, then turned into fmi2Error."""


class Blocks:
    """``f(k)`` at the samples ``k`` of one FMU instance, for an ``f`` that is a pure function
    of the sample index (a noise draw, a sinusoid: parameters fixed when it is made), computed
    for :attr:`SIZE` consecutive samples at once over a NumPy array of ``k``.  models/ gives
    the array path the bits of the float path (tests/test_models.py; the FMUs are compared
    with models/ and with their native twins), so a sample reads a stored value instead of
    running the draw's Python arithmetic.  Without NumPy, before sample 1, past 2**62, or where
    a block would not be all finite (so that a failure is reported as before), ``f`` runs on
    the one ``k``.  Where the host has not imported NumPy itself (a C host: its import costs
    about 0.15 s), the first :attr:`WARM_UP` samples also run one by one, so that a short run
    never pays for the import and a long one pays once."""

    SIZE = 4096
    WARM_UP = 4096

    def __init__(self, f, warm_up=None):
        self._f = f
        if warm_up is not None:  # (a slave with many streams: their one-by-one samples add up)
            self.WARM_UP = warm_up
        self._k0 = self._end = 0  # the block holds k0 .. end - 1 (nothing yet)
        self._values = None       # (None over a block where f runs sample by sample)
        self._warm = 0            # samples computed one by one before NumPy was imported

    def __call__(self, k):
        i = k - self._k0
        if 0 <= i < self._end - self._k0:
            values = self._values
            return values[i] if values is not None else self._f(k)
        return self._fill(k)

    def run(self, k, n=None):
        """The stored values from sample ``k`` to the end of its block (an ``array('d')``; at
        most ``n`` of them where ``n`` is given), after ``self(k)``; None where ``f`` runs on
        the one ``k`` (no NumPy, the warm-up, a block that is not all finite), the caller then
        calls ``self(k)`` sample by sample."""
        self(k)
        if self._values is None or not self._k0 <= k < self._end:
            return None
        i = k - self._k0
        return self._values[i:] if n is None else self._values[i:i + n]

    def _fill(self, k):
        if self._warm < self.WARM_UP and not _numpy_imported():
            self._warm += 1
            return self._f(k)
        np = _numpy()
        if np is None or type(k) is not int or not 1 <= k <= 2 ** 62:
            return self._f(k)
        # forward from k, or ending at k when the samples run backwards (a state restored)
        k0 = k if k >= self._end else max(1, k - self.SIZE + 1)
        with np.errstate(all="ignore"):
            block = np.asarray(self._f(np.arange(k0, k0 + self.SIZE, dtype=np.int64)),
                               dtype=np.float64)
        self._values = array.array("d", block.tobytes()) if np.isfinite(block).all() else None
        self._k0, self._end = k0, k0 + self.SIZE
        return self(k)


def _numpy_imported():
    """Whether the process has imported NumPy already (a Python host such as fmpy has)."""
    return "numpy" in sys.modules


def _numpy():
    """NumPy, or None where the FMU's Python has none or its arrays do not give models/' float
    bits (checked once, on the first block)."""
    global _NUMPY
    if _NUMPY is False:
        _NUMPY = _exact_numpy()
    return _NUMPY


def _exact_numpy():
    """NumPy if it imports and every function of :data:`_SELF_TEST` gives over an array of
    ``k = 1 .. 256`` the bits it gives sample by sample; else None (the FMU then computes every
    value for its one sample).  The host's Python may have any NumPy: an older one promotes
    integers differently."""
    try:
        import numpy
        ks = range(1, 257)
        for f in _SELF_TEST:
            with numpy.errstate(all="ignore"):
                got = numpy.asarray(f(numpy.arange(1, 257, dtype=numpy.int64)),
                                    dtype=numpy.float64).tobytes()
            if got != array.array("d", [f(k) for k in ks]).tobytes():
                return None
        return numpy
    except Exception:  # (no NumPy, or one that cannot run these)
        return None


#: What :func:`_exact_numpy` checks: draws (over the quantile's central part and both tails:
#: 256 draws hold about a dozen tail values) and a sinusoid.
_SELF_TEST = (lambda k: noise.normal(20261203, noise.STREAM_PROCESS, k),
              lambda k: excitation.sine(k, 1.5, 150.0, 1e-4, 0.7))
_NUMPY = False


def var(name, causality, start=None, unit=None, description=None, type="Real",
        variability=None, low=None, high=None):
    """One row of a slave's ``VARIABLES`` table.

    Parameters named as in :data:`driftfmu.models.parameters.PARAMETERS` take their start value, unit,
    range and description from there unless given here; an open bound there (``R > 0``) is
    declared as the accepted double next to it (FMI 2 bounds are closed).
    """
    p = parameters.PARAMETERS.get(name)
    if p is not None:
        start = p.default if start is None else start
        unit = p.unit if unit is None else unit
        description = p.description if description is None else description
        declared = parameters.declared_range(name)
        low = declared[0] if low is None else low
        high = declared[1] if high is None else high
    if variability is None:  # inputs are sampled: held between communication points (FMI's
        # discrete), so that a host reading an input file holds them instead of interpolating
        variability = {"parameter": "fixed", "input": "discrete"}.get(causality, "continuous")
    if type == "Integer" and unit == "1":
        unit = None
    return {"name": name, "type": type, "causality": causality, "variability": variability,
            "start": start, "unit": unit, "min": low, "max": high,
            "description": "%s [%s]" % (description, unit or "1")}


def _bundle_version():
    """driftfmu's version: written into the FMU's bundled package by the builder, or the
    source tree's ``driftfmu.__version__``."""
    package = sys.modules.get(__name__.rpartition(".")[0])
    version = getattr(package, "__version__", None)
    if version is None:
        version = getattr(sys.modules.get(__name__.split(".")[0]), "__version__", None)
    return version


def vr_text(vr):
    """A value reference as the host sent it: unsigned (pythonfmu passes it as a C int)."""
    return str(vr & 0xFFFFFFFF) if isinstance(vr, int) and vr < 0 else repr(vr)


class SlaveBase(Fmi2Slave):
    """Base of the Excitation, Accelerometer and DriftEstimator slaves."""

    author = "driftfmu contributors"
    license = "MIT"
    #: driftfmu's version (also set by the builder from ``driftfmu.__version__``).
    version = _bundle_version()
    #: One line on what the model is (the model description's description starts with it; not
    #: the docstring, which ``python -OO`` drops).
    DESCRIPTION = ""
    VARIABLES = ()
    DEPENDENCIES = {}
    #: The loader shim may speak to this slave through :data:`SHIM_VR` (the builder records it).
    SHIM_VR = SHIM_VR
    CAN_HANDLE_VARIABLE_STEP = True
    MAX_SAMPLES_PER_STEP = MAX_SAMPLES_PER_STEP
    #: Names of the hidden state: the fields of ``_committed`` and of the FMU state (None
    #: before initialisation).  Slaves provide the hooks ``prepare``, ``initial_hidden``,
    #: ``sample``, ``show`` and optionally ``hold``, ``hidden_valid``, ``covariance_refusal``,
    #: ``parse_hidden`` and ``hidden_problems``; the step rule, the checks and the FMU state are
    #: this class's.
    HIDDEN = ()
    #: Names of the outputs a sample computes, in the order of the tuple ``sample`` returns
    #: (which may be a prefix of it: outputs a configuration does not compute keep their value).
    OUTPUTS = ()

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        _drop_duplicate_path(self.resources)
        cls = type(self)
        self.version = cls.version  # (pythonfmu's __init__ sets None)
        # the same GUID at build time (into the model description) and in every instance
        self.guid = uuid.uuid5(GUID_NAMESPACE, "%s.%s %s" % (cls.__module__, cls.__name__,
                                                             self.version))
        self.description = "%s. %s" % (self.DESCRIPTION, STEP_RULE)
        self.start_time = 0.0
        self._stop_time = _INF  # the defined stop time (inf: none)
        self._stop_at = _INF    # it in sample periods after the start, once Ts is fixed
        self._elapsed = 0.0     # t - t_start, and the compensation of its running sum
        self._elapsed_c = 0.0
        self.k = 1              # the next sample to process (pending when _at_sample)
        self._at_sample = True
        self._dirty = True      # inputs or parameters changed since the outputs were computed
        self._initialised = False
        self._in_init = False
        self._terminated = False
        self._pending = None    # hidden state after the pending sample, when not dirty
        self._feedthrough = bool(self.DEPENDENCIES)  # outputs follow the inputs when read
        #: the committed hidden state, {name: value} over HIDDEN (replaced, never mutated)
        self._committed = {name: None for name in self.HIDDEN}
        self._specs = {}
        for spec in self.VARIABLES:
            setattr(self, spec["name"], spec["start"] if spec["start"] is not None else 0.0)
            self.register_variable(self._make_variable(spec))
            self._specs[len(self._specs)] = spec
        # value reference -> name of the Real variables and of the Real inputs: the fast path
        # of get_real / set_real, called on every sample (value reference = table index)
        self._real_names = {vr: s["name"] for vr, s in self._specs.items() if s["type"] == "Real"}
        self._real_refs = frozenset(self._real_names)
        self._real_inputs = {vr: s["name"] for vr, s in self._specs.items()
                             if s["type"] == "Real" and s["causality"] == "input"}

    # -- registration -----------------------------------------------------------------------
    def _make_variable(self, spec):
        name = spec["name"]
        kind = _TYPES[spec["type"]]
        causality = getattr(Fmi2Causality, spec["causality"])
        variability = getattr(Fmi2Variability, spec["variability"])
        getter = lambda: getattr(self, name)
        setter = None if spec["causality"] == "output" else \
            (lambda value: self._call(self._set_checked, "set", [self._vr_of(name)], [value],
                                      spec["type"]))
        return kind(name, causality=causality, variability=variability,
                    description=spec["description"], getter=getter, setter=setter)

    def _vr_of(self, name):
        return next(vr for vr, s in self._specs.items() if s["name"] == name)

    # -- getters ----------------------------------------------------------------------------
    def get_real(self, vrs):
        if self._dirty and self._at_sample and (self._in_init or (
                self._initialised and self._feedthrough)):
            if not self._real_refs.issuperset(vrs):  # refused as a whole: nothing computed
                return self._get_real_refused(vrs)
            try:  # outputs at this communication point, from its inputs
                if self._initialised:  # (_samples(self._committed, self.k, 1, True), written out)
                    k = self.k
                    try:
                        pending, outputs = self.sample(self._committed, k, True)
                    except _ARITHMETIC as exc:  # (ModelError is neither)
                        self._uncomputable(k, exc)
                    total = sum(outputs)  # not finite if any output is not (or they overflow)
                    if total - total != 0.0:
                        self._check_outputs(outputs, k)
                    check = self.hidden_valid
                    if check is not None and not check(pending):
                        self._check_hidden(pending, k)
                    self.show(outputs)
                    self._pending = pending
                    self._dirty = False
                else:
                    self._refresh_in_init()
            except Exception as exc:
                self._failed("_refresh", exc)
        d, names = self.__dict__, self._real_names
        if len(vrs) == 1:  # the per-sample fast path: one value
            name = names.get(vrs[0])
            if name is not None:
                return [float(d[name])]
        else:
            try:
                return [float(d[names[vr]]) for vr in vrs]
            except KeyError:
                pass
        return self._get_real_refused(vrs)

    def _get_real_refused(self, vrs):
        """fmi2GetReal with a value reference that is not a Real variable: logged, the whole
        call refused; the values of the valid ones, NaN for the others."""
        names = self._real_names
        self._call(self._fail, "fmi2GetReal: %s" % self._bad_refs(vrs, "Real"))
        return [float(getattr(self, names[vr])) if vr in names else math.nan for vr in vrs]

    def get_integer(self, vrs):
        return self._get_typed("fmi2GetInteger", "Integer", vrs, 0, int)

    def get_boolean(self, vrs):
        return self._get_typed("fmi2GetBoolean", "Boolean", vrs, False, bool)

    def get_string(self, vrs):
        return self._get_typed("fmi2GetString", "String", vrs, "", str)

    def _get_typed(self, what, kind, vrs, fallback, convert):
        # pythonfmu's own accessors raise on a bad value reference or type; an exception in a
        # pythonfmu 0.7.0 call releases the instance's Python objects twice (a crash later), so
        # every accessor checks the whole call first and logs what is wrong
        specs = self._specs
        if all(vr in specs and specs[vr]["type"] == kind for vr in vrs):
            return [convert(getattr(self, specs[vr]["name"])) for vr in vrs]
        self._call(self._fail, "%s: %s" % (what, self._bad_refs(vrs, kind)))
        return [convert(getattr(self, specs[vr]["name"]))
                if vr in specs and specs[vr]["type"] == kind else fallback for vr in vrs]

    def _bad_refs(self, vrs, kind):
        """What is wrong with the value references ``vrs`` of a call on ``kind`` variables."""
        problems = []
        for vr in vrs:
            spec = self._specs.get(vr)
            if spec is None:
                problems.append("value reference %s does not exist" % vr_text(vr))
            elif spec["type"] != kind:
                problems.append("value reference %s is %s, %s %s variable, not %s %s"
                                % (vr_text(vr), spec["name"], _article(spec["type"]),
                                   spec["type"], _article(kind), kind))
        return "%s; allowed: the %s value references of modelDescription.xml (%s)" % (
            ", ".join(problems), kind, ", ".join(
                str(vr) for vr, s in self._specs.items() if s["type"] == kind) or "none")

    # -- setters: the whole call is checked before anything is assigned ---------------------
    def _from_shim(self, values):
        """What the loader shim sets to :data:`SHIM_VR`: ``[startTime, stopTimeDefined,
        stopTime]`` (fmi2SetupExperiment) or ``[1.0]`` (the next fmi2SetFMUstate checks)."""
        if len(values) == 1:
            self._check_only = True
            return
        start, defined, stop = values
        self._setup(start, stop if defined else None)

    def set_real(self, vrs, values):
        # the per-sample fast path: finite floats into inputs (v - v is 0 only when v is finite)
        if len(vrs) == 1 and len(values) == 1 and not self._terminated:
            name, v = self._real_inputs.get(vrs[0]), values[0]
            if name is not None and type(v) is float and v - v == 0.0:
                setattr(self, name, v)
                self._dirty = True
                return
        elif not self._terminated and len(vrs) == len(values):
            inputs = self._real_inputs
            names = [inputs.get(vr) for vr in vrs]
            if None not in names:
                for v in values:
                    if type(v) is not float or v - v != 0.0:
                        break
                else:
                    for name, v in zip(names, values):
                        setattr(self, name, v)
                    self._dirty = True
                    return
        if vrs[:1] == [SHIM_VR] and len(vrs) == len(values) and len(vrs) in (1, 3):
            self._call(self._from_shim, values)
            return
        self._call(self._set_checked, "fmi2SetReal", vrs, values, "Real")

    def set_integer(self, vrs, values):
        self._call(self._set_checked, "fmi2SetInteger", vrs, values, "Integer")

    def set_boolean(self, vrs, values):
        self._call(self._set_checked, "fmi2SetBoolean", vrs, values, "Boolean")

    def set_string(self, vrs, values):
        self._call(self._set_checked, "fmi2SetString", vrs, values, "String")

    def _set_checked(self, what, vrs, values, kind):
        problems = []
        if self._terminated:
            problems.append(_TERMINATED)
        bad_refs = [vr for vr in vrs if vr not in self._specs or self._specs[vr]["type"] != kind]
        if bad_refs:
            problems.append(self._bad_refs(bad_refs, kind))
        for vr, value in zip(vrs, values):
            spec = self._specs.get(vr)
            if spec is None or spec["type"] != kind:
                continue
            name = spec["name"]
            if spec["causality"] == "output":
                problems.append("%s is an output; only parameters and inputs can be set" % name)
            elif kind == "Real" and not (_is_number(value) and math.isfinite(value)):
                problems.append("%s = %r is not finite; %s accepts finite values only"
                                % (name, value, spec["causality"]))
            elif kind == "Integer" and not (isinstance(value, int) and not isinstance(value, bool)):
                problems.append("%s = %r is not an integer" % (name, value))
            elif spec["causality"] == "parameter" and self._initialised:
                problems.append("%s is a fixed parameter and cannot be changed after "
                                "initialisation (it stays %r)" % (name, getattr(self, name)))
        if len(values) != len(vrs):
            problems.append("%d values for %d value references" % (len(values), len(vrs)))
        if problems:
            for msg in problems[:-1]:
                self._log_error("%s: %s" % (what, msg))
            self._fail("%s: %s%s" % (what, problems[-1], "; nothing was set" if len(vrs) > 1
                                     else ""))
        for vr, value in zip(vrs, values):
            setattr(self, self._specs[vr]["name"], value)
        self._dirty = True

    # -- errors -----------------------------------------------------------------------------
    def _log_error(self, message):
        # pythonfmu 0.7.0 never releases a reference it takes to each message's text (about
        # 120 bytes a line); interned, a message repeated (a host retrying a bad call) is kept
        # once, not once per call
        self.log(sys.intern("%s: %s" % (self.instance_name, message)), Fmi2Status.error,
                 _ERROR_CATEGORY)

    def _fail(self, message):
        """Log ``message`` with status error and abandon the current FMI call."""
        self._log_error(message)
        raise ModelError(message)

    def _call(self, action, *args):
        """Run the body of an FMI call; return True, or False after logging what went wrong."""
        try:
            action(*args)
        except Exception as exc:
            return self._failed(getattr(action, "__name__", "call"), exc)
        return True

    def _failed(self, where, exc):
        """False, for an FMI call whose body ``where`` raised ``exc``: a ModelError is logged
        already; anything else is a bug, which must reach the host's log, not crash or vanish."""
        if not isinstance(exc, ModelError):
            self._log_error("internal error in %s: %s: %s" % (where, type(exc).__name__, exc))
        return False

    def _not_finite(self, name, value, k):
        """Refuse a sample whose output or hidden state ``name`` would be ``value`` (not
        finite) although every input and parameter is finite."""
        self._fail("%s would be %r at sample %d (t = %r s): the inputs and parameters overflow "
                   "the model; allowed: values whose outputs and state stay finite (nothing "
                   "was changed)" % (name, value, k, self._sample_time(k)))

    def _sample_time(self, k):
        return self.start_time + (k - 1) * self.Ts

    # -- parameters -------------------------------------------------------------------------
    def parameter_values(self):
        """The current values of all parameters, by name."""
        return {s["name"]: getattr(self, s["name"]) for s in self.VARIABLES
                if s["causality"] == "parameter"}

    def check_parameters(self):
        """Problems of the parameter values (one readable line each); extended by subclasses."""
        problems = parameters.check({n: v for n, v in self.parameter_values().items()
                                     if n in parameters.PARAMETERS})
        for s in self.VARIABLES:
            if s["causality"] == "parameter" and s["name"] not in parameters.PARAMETERS:
                v = getattr(self, s["name"])
                low, high = s["min"], s["max"]
                if (low is not None and v < low) or (high is not None and v > high):
                    problems.append("%s = %r is out of range; allowed: %s <= %s <= %s"
                                    % (s["name"], v, low, s["name"], high))
        return problems

    def nyquist_problems(self, name="f"):
        """The Nyquist check of a slave with a sinusoid at the frequency parameter ``name`` (a
        list of at most one problem; none where ``Ts`` itself is refused by its range).  C twin:
        ``slave_check_nyquist_named``."""
        f = getattr(self, name)
        if self.Ts > 0 and f >= 0.5 / self.Ts:
            nyquist = 0.5 / self.Ts
            return ["%s = %r Hz is at or above the Nyquist rate 1/(2 Ts) = %r Hz; allowed: "
                    "%s < %r Hz" % (name, f, nyquist, name, nyquist)]
        return []

    def _check_and_prepare(self, context):
        problems = self.check_parameters()
        for msg in problems[:-1]:
            self._log_error("%s%s" % (context, msg))
        if problems:
            self._fail(context + problems[-1])
        self.prepare()

    # -- FMI calls --------------------------------------------------------------------------
    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._call(self._setup, start_time, stop_time)

    def _setup(self, start_time, stop_time):
        """The experiment: the start time and, when defined, the stop time (finite, at or after
        the start); a step that would end after the stop time is refused (FMI 2.0,
        fmi2SetupExperiment: an FMU asked to compute past a defined stop time returns an
        error)."""
        if not (_is_number(start_time) and math.isfinite(start_time)):
            self._fail("fmi2SetupExperiment: startTime = %r; allowed: a finite time"
                       % (start_time,))
        if stop_time is not None and not (_is_number(stop_time) and math.isfinite(stop_time)
                                          and stop_time >= start_time):
            self._fail("fmi2SetupExperiment: stopTime = %r s with startTime = %r s; allowed: a "
                       "finite stop time >= startTime, or stopTimeDefined = false (nothing was "
                       "changed)" % (stop_time, start_time))
        if not self._initialised:
            self.start_time = float(start_time)
            self._stop_time = _INF if stop_time is None else float(stop_time)

    def _stop_position(self, start_time, stop_time):
        """The stop time in sample periods after the start (inf: none), as cs_do_step computes
        it; for a step's end, compared with the same tolerance as the sample instants."""
        return (stop_time - start_time) / self.Ts

    def enter_initialization_mode(self):
        if self._terminated:
            self._call(self._fail, "fmi2EnterInitializationMode: " + _TERMINATED)
            return
        self._in_init = True
        self._dirty = True

    def exit_initialization_mode(self):
        if self._call(self._initialise):  # refused: still in Initialization Mode, unchanged
            self._initialised, self._in_init = True, False

    def terminate(self):
        self._terminated = True

    def _initialise(self):
        if self._terminated:
            self._fail("fmi2ExitInitializationMode: " + _TERMINATED)
        self._check_and_prepare("")
        hidden = self.initial_hidden()
        outputs = pending = None
        if not self.DEPENDENCIES:  # outputs of sample 1 now: they depend on no input
            pending, outputs = self._samples(hidden, 1, 1, True)
        self._commit(hidden, 1, True, 0.0, 0.0, outputs, pending)
        self._stop_at = self._stop_position(self.start_time, self._stop_time)

    def _refresh_in_init(self):
        """Outputs in Initialization Mode: sample 1 from the start values and inputs (after
        it, fmi2GetReal computes the outputs of the pending sample itself)."""
        self._check_and_prepare("cannot compute the outputs in Initialization Mode: ")
        _, outputs = self._samples(self.initial_hidden(), 1, 1, True)
        self.show(outputs)
        self._pending = None
        self._dirty = False

    def do_step(self, current_time, step_size):
        try:  # (_call written out: this runs once per communication step)
            # The common step, written out: t at sample k, whose hidden state was computed from
            # the inputs set at t (the outputs were read), a finite float h > 0 and one sample
            # instant in [t, t + h), that is ceil((t + h - t_start)/Ts - tol) = k, which for a
            # float is k - 1 < (t + h - t_start)/Ts - tol <= k (false for nan and inf); and no
            # pending sample to compute at t + h.  Then _step would only commit sample k: the
            # same sums and flags here, the same bits.  Everything else (every refusal too)
            # is _step's.
            if (self._at_sample and not self._dirty and type(step_size) is float
                    and 0.0 < step_size < _INF and self._initialised and not self._terminated
                    and self._pending is not None):
                s = self._elapsed
                elapsed = s + step_size  # Neumaier's compensated sum, as in _step
                # (s = t - t_start >= 0 always, so abs(s) is s)
                comp = self._elapsed_c + (((s - elapsed) + step_size) if s >= step_size
                                          else ((step_size - elapsed) + s))
                position = (elapsed + comp) / self.Ts
                k = self.k
                end = position - INSTANT_TOLERANCE
                if k - 1 < end <= k and end <= self._stop_at:
                    at_sample = k <= position + INSTANT_TOLERANCE
                    if self._feedthrough or not at_sample:
                        self._committed = self._pending  # _commit(pending, k + 1, ...)
                        self.k = k + 1
                        self._at_sample = at_sample
                        self._elapsed, self._elapsed_c = elapsed, comp
                        self._pending = None
                        self._dirty = True
                        return True
            self._step(step_size)
        except Exception as exc:
            return self._failed("_step", exc)
        return True

    def _step(self, h):
        if self._terminated:
            self._fail("cannot step: " + _TERMINATED)
        if not self._initialised:
            self._fail("cannot step: initialisation did not complete (see the errors above)")
        if not (type(h) in (float, int) and 0.0 < h < _INF):
            self._fail("communication step h = %r s; allowed: a finite h > 0" % (h,))
        Ts, k, tol = self.Ts, self.k, INSTANT_TOLERANCE
        elapsed = self._elapsed + h  # Neumaier's compensated sum of the step sizes
        s = self._elapsed
        comp = self._elapsed_c + (((s - elapsed) + h) if abs(s) >= h else ((h - elapsed) + s))
        position = (elapsed + comp) / Ts  # t + h in sample periods from the start
        limit = self.MAX_SAMPLES_PER_STEP
        if not position - tol <= limit + k - 1:
            # the room left before the limit, in seconds (C twin: cs_do_step)
            room = (limit + k - 1) * Ts - (self._elapsed + self._elapsed_c)
            if not (math.isfinite(position) and math.isfinite(room)):
                self._fail("communication step h = %r s from t = %r s with Ts = %r s: the time "
                           "in sample periods, (t + h - startTime)/Ts, is not a finite number; "
                           "allowed: steps whose end is a finite number of sample periods "
                           "after the start" % (h, self.start_time + (self._elapsed +
                                                                       self._elapsed_c), Ts))
            self._fail("communication step h = %r s spans more than %d sample instants of "
                       "Ts = %r s; allowed: at most MAX_SAMPLES_PER_STEP = %d sample instants "
                       "per step, h <= about %r s" % (h, limit, Ts, limit, room))
        if not position - tol <= self._stop_at:  # (C twin: cs_do_step, refused_stop)
            self._fail("communication step h = %r s from t = %r s ends at t = %r s, after the "
                       "stop time %r s (fmi2SetupExperiment); allowed: steps that end at or "
                       "before the stop time (within a millionth of a sample period); nothing "
                       "was changed" % (h, self.start_time + (self._elapsed + self._elapsed_c),
                                        self.start_time + (elapsed + comp), self._stop_time))
        last = _ceil(position - tol)          # index (k - 1) of the first instant at or after t+h
        m = max(0, last + 1 - k)              # instants in [t, t + h)
        at_sample = last <= position + tol    # t + h is that instant
        hidden = outputs = pending = None  # hidden None: the committed state stays
        first = True
        if m and self._at_sample:  # sample k: committed with the inputs set at t
            if self._dirty or self._pending is None:
                hidden, outputs = self._samples(self._committed, k, 1, True)
            else:
                hidden = self._pending
            first = False
        if m > 1 or (m and not self._at_sample):  # the other instants: inputs held from t
            start = k + 1 if self._at_sample else k
            hidden, outputs = self._samples(self._committed if hidden is None else hidden,
                                            start, k + m - start, first)
        if at_sample and not self.DEPENDENCIES:
            pending, outputs = self._samples(self._committed if hidden is None else hidden,
                                             k + m, 1, True)
        self._commit(hidden, k + m, at_sample, elapsed, comp, outputs, pending)

    def _commit(self, hidden, k, at_sample, elapsed, comp, outputs, pending):
        """The one place a step or an initialisation changes the instance, after everything
        it needed was computed (so a refused call changes nothing)."""
        if hidden is not None:
            self._committed = hidden
        if outputs is not None:
            self.show(outputs)
        self.k = k
        self._at_sample = at_sample
        self._elapsed, self._elapsed_c = elapsed, comp
        self._pending = pending
        self._dirty = pending is None

    def _samples(self, hidden, k0, n, first):
        """Process samples ``k0 .. k0 + n - 1`` from ``hidden`` with the inputs held; return
        ``(hidden, outputs)`` after the last, or fail if any value is not finite."""
        try:
            if n == 1:
                hidden, outputs = self.sample(hidden, k0, first)
            else:
                hidden, outputs = self.hold(hidden, k0, n, first)
        except _ARITHMETIC as exc:  # (ModelError is neither)
            self._uncomputable(k0 + n - 1, exc)
        total = sum(outputs)  # not finite if any output is not (or if they overflow)
        if total - total != 0.0:
            self._check_outputs(outputs, k0 + n - 1)
        check = self.hidden_valid
        if check is not None and not check(hidden):
            self._check_hidden(hidden, k0 + n - 1)
        return hidden, outputs

    def _uncomputable(self, k, exc):
        self._fail("the outputs at sample %d (t = %r s) cannot be computed: %s: %s; "
                   "allowed: inputs and parameters whose outputs stay finite (nothing was "
                   "changed)" % (k, self._sample_time(k), type(exc).__name__, exc))

    def _check_outputs(self, outputs, k):
        """Refuse sample ``k`` if one of ``outputs`` is not finite (the first, in the order of
        ``OUTPUTS``); called when their sum is not (v - v is 0 for every finite v)."""
        for name, value in zip(self.OUTPUTS, outputs):
            if not math.isfinite(value):
                self._not_finite(name, value, k)

    def _check_hidden(self, hidden, k):
        """Refuse sample ``k`` for the first non-finite number of ``hidden``, else for a
        covariance that is not valid (``covariance_refusal``); called when ``hidden_valid`` says
        there is one."""
        for name, value in hidden.items():
            for part, v in _numbers(name, value):
                if not math.isfinite(v):
                    self._not_finite("hidden state " + part, v, k)
        message = self.covariance_refusal(hidden, k)
        if message is not None:
            self._fail(message)

    # -- hooks for the slaves ---------------------------------------------------------------
    def prepare(self):
        """Derived constants from the (checked) parameters."""

    def blocks(self, name, parameters, f, warm_up=None):
        """The :class:`Blocks` of ``f`` under ``name``, the same object while ``parameters``
        (those ``f`` depends on) keep their bits, so that ``prepare`` after a state restore
        keeps the samples already computed (a master that rolls back every step pays no new
        block).  ``warm_up``: its :attr:`Blocks.WARM_UP` (default the class's)."""
        kept = self.__dict__.setdefault("_kept_blocks", {})
        key = repr(parameters)  # (repr tells -0.0 from 0.0, and gives every float's bits)
        entry = kept.get(name)
        if entry is None or entry[0] != key:
            entry = kept[name] = (key, Blocks(f, warm_up))
        return entry[1]

    def initial_hidden(self):
        """The hidden state before sample 1, ``{name: value}`` over ``HIDDEN``."""
        return {}

    def sample(self, hidden, k, first):
        """Process sample ``k`` with the current inputs from ``hidden`` (the state after
        sample ``k - 1``): ``(hidden after k, outputs)``, ``outputs`` a tuple of values in the
        order of ``OUTPUTS`` (or a prefix of it).  ``first``: the first sample instant of a step
        (or the pending sample)."""
        raise NotImplementedError

    def show(self, outputs):
        """Assign ``outputs`` (as ``sample`` returns them, checked finite) to the output
        variables.  Slaves override this with the same assignment written out (faster)."""
        for name, value in zip(self.OUTPUTS, outputs):
            setattr(self, name, value)

    def hold(self, hidden, k0, n, first):
        """Process ``n >= 1`` samples from ``k0`` with the inputs held (``first`` applies to
        ``k0``); slaves may override this with a shortcut of the same bits."""
        outputs = None
        for i in range(n):
            hidden, outputs = self.sample(hidden, k0 + i, first and i == 0)
        return hidden, outputs

    def parse_hidden(self, name, value):
        """The working value of hidden state ``name`` read back from a state (JSON form);
        raise ValueError or TypeError if it is not one.  Default: None or a finite number."""
        if value is not None and not (_is_number(value) and math.isfinite(value)):
            raise ValueError("not a finite number")
        return value

    def hidden_valid(self, hidden):
        """Whether every number in ``hidden`` is finite and every covariance in it valid
        (:meth:`covariance_refusal` finds none).  Default: the finite test (a slave without a
        covariance).  Slaves may override this with a faster test of the same meaning, or set
        it to None where a non-finite hidden value always makes an output non-finite (which is
        checked first) and there is no covariance to check."""
        for name, value in hidden.items():
            if value is None:
                continue
            if type(value) is float:
                if value - value != 0.0:
                    return False
            elif not all(math.isfinite(v) for _, v in _numbers(name, value)):
                return False
        return True

    def covariance_refusal(self, hidden, k):
        """The message refusing sample ``k`` whose ``hidden`` state (all finite) holds a
        covariance that is not valid (:func:`driftfmu.models.covariance.refusal`), or None
        (hook; a slave without a covariance has none)."""
        return None

    def hidden_problems(self, hidden):
        """Problems of a hidden state read back for the current parameters (hook)."""
        return []

    def _timing_problems(self, k, time, at_sample, stop):
        """Whether sample index ``k`` and the at-a-sample flag agree with the time of a state
        (as :meth:`_step` derives them: ``k - 1`` is the first instant at or after ``t``), and
        the time is not after the stop time ``stop`` (None: none defined)."""
        position = (time[1] + time[2]) / self.Ts
        if not math.isfinite(position):
            return ["time = %r is not a finite number of sample periods Ts = %r s"
                    % (time, self.Ts)]
        first = math.ceil(position - INSTANT_TOLERANCE)
        if k - 1 != first or at_sample != (first <= position + INSTANT_TOLERANCE):
            return ["k = %r and at_sample = %r do not match the time %r s after the start "
                    "(the next sample there is k = %d)" % (k, at_sample, time[1] + time[2],
                                                            first + 1)]
        if stop is not None and not position - INSTANT_TOLERANCE <= self._stop_position(
                time[0], stop):
            return ["the time %r s after the start is after the stop time %r s; allowed: a "
                    "time at or before the stop time" % (time[1] + time[2], stop)]
        return []

    # -- FMU state: variables plus hidden state ---------------------------------------------
    def _identity(self):
        return {"model": type(self).__name__, "guid": str(self.guid), "version": self.version}

    def _get_fmu_state(self):
        state = self._identity()
        for s in self.VARIABLES:
            state[s["name"]] = getattr(self, s["name"])
        state["k"] = self.k
        state["time"] = [self.start_time, self._elapsed, self._elapsed_c]
        state["stop_time"] = None if self._stop_time == _INF else self._stop_time
        state["flags"] = {"initialised": self._initialised, "in_init": self._in_init,
                          "at_sample": self._at_sample, "terminated": self._terminated}
        for name in self.HIDDEN:
            state[name] = _plain(self._committed[name])
        return state

    def _set_fmu_state(self, state):
        check_only = self.__dict__.pop("_check_only", False)  # (SHIM_VR: once)
        if type(state) is Deserialised:
            if check_only or state.why is not None:
                self._call(self._check_deserialised, state,
                           "fmi2DeSerializeFMUstate" if check_only else "fmi2SetFMUstate")
                return
            state = state.state
        self._call(self._restore, state)

    def _check_deserialised(self, d, function):
        """Check a state read from bytes as fmi2SetFMUstate would, and change nothing (the
        loader shim's check in fmi2DeSerializeFMUstate)."""
        if d.why is not None:
            self._fail("%s: not an FMU state of %s: %d bytes that are not a serialised state "
                       "(%s); allowed: the bytes fmi2SerializeFMUstate of this FMU wrote"
                       % (function, type(self).__name__, d.size, d.why))
        self._restore(d.state, function, assign=False)

    def _restore(self, state, function="fmi2SetFMUstate", assign=True):
        """Check ``state`` field by field (as the native twins check theirs: cosimulation.c,
        snapshot_problems) and, with ``assign``, make it the instance's; a state with any
        problem is refused as a whole (every problem logged) and nothing is changed."""
        cls = type(self).__name__
        if not isinstance(state, dict):
            self._fail("%s: not an FMU state of %s: %.80r; allowed: a state that this FMU "
                       "produced" % (function, cls, state))
        mine = self._identity()
        if not isinstance(state.get("model"), str):
            self._fail("%s: not an FMU state of %s: a JSON object without the model, GUID and "
                       "version of a state (%.60r); allowed: a state that this FMU (%s, GUID "
                       "%s) produced" % (function, cls, sorted(map(str, state))[:6], cls,
                                         mine["guid"]))
        if state.get("model") != mine["model"]:
            self._fail("%s: this is an FMU state of model %.40r, not of %s; allowed: a state "
                       "that this FMU (%s, GUID %s) produced"
                       % (function, state.get("model"), cls, cls, mine["guid"]))
        for key in ("guid", "version"):
            if state.get(key) != mine[key]:
                self._fail("%s: the FMU state of %s has %s %.60r, this FMU has %r; allowed: a "
                           "state of this very FMU (same build and version)"
                           % (function, cls, key, state.get(key), mine[key]))
        expected = _STATE_META + tuple(s["name"] for s in self.VARIABLES) + _STATE_FIELDS \
            + tuple(self.HIDDEN)
        unknown = sorted(str(key) for key in state if key not in expected)
        missing = [key for key in expected if key not in state]
        if unknown or missing:
            self._fail("%s: the FMU state of %s has %s; allowed: exactly the fields %s" % (
                           function, cls, " and ".join(
                           part for part in (unknown and "unknown fields %s" % unknown[:8],
                                             missing and "missing fields %s" % missing) if part),
                           ", ".join(expected)))
        values, problems = {}, []
        for s in self.VARIABLES:
            v = state[s["name"]]
            ok = (_is_number(v) and math.isfinite(v)) if s["type"] == "Real" else \
                (isinstance(v, int) and not isinstance(v, bool))
            if ok:
                values[s["name"]] = v
            else:
                problems.append("%s = %.40r is not %s" % (
                    s["name"], v, "a finite number" if s["type"] == "Real" else "an integer"))
        k, time, flags = state["k"], state["time"], state["flags"]
        if not (isinstance(k, int) and not isinstance(k, bool) and k >= 1):
            problems.append("k = %.40r is not a sample index (an integer >= 1)" % (k,))
        if not (isinstance(time, list) and len(time) == 3
                and all(_is_number(v) and math.isfinite(v) for v in time) and time[1] >= 0.0):
            problems.append("time = %.80r is not [t_start, elapsed >= 0, compensation] of "
                            "finite numbers" % (time,))
        stop = state["stop_time"]
        if stop is not None and not (_is_number(stop) and math.isfinite(stop) and (
                not isinstance(time, list) or not time or not _is_number(time[0])
                or stop >= time[0])):
            problems.append("stop_time = %.40r is not null (none defined) or a finite time at "
                            "or after the start time" % (stop,))
        if not (isinstance(flags, dict) and sorted(flags) == sorted(_FLAGS)
                and all(isinstance(v, bool) for v in flags.values())):
            problems.append("flags = %.80r is not {%s} of booleans" % (flags, ", ".join(_FLAGS)))
            flags = None
        elif flags["initialised"] and flags["in_init"]:
            problems.append("flags initialised and in_init are both true; allowed: one mode "
                            "(in_init in Initialization Mode, initialised after it)")
        elif flags["terminated"] and not (flags["initialised"] or flags["in_init"]):
            problems.append("flags terminated without initialised or in_init; allowed: "
                            "terminated after Initialization Mode was entered")
        hidden = {}
        for name in self.HIDDEN:
            try:
                hidden[name] = self.parse_hidden(name, state[name])
            except (ValueError, TypeError, ArithmeticError) as exc:
                problems.append("hidden state %s = %.80r is not valid (%s)"
                                % (name, state[name], exc))
                continue
            for part, v in _numbers(name, hidden[name]):
                if part.rpartition(".")[2] in VARIANCES and not v >= 0.0:
                    problems.append("hidden state %s = %r is a negative variance; allowed: "
                                    "%s >= 0" % (part, v, part))
        if flags is not None and not flags["initialised"]:
            # before initialisation: no hidden state, at sample 1, no time elapsed (C twin:
            # snapshot_problems)
            if any(value is not None for value in hidden.values()):
                problems.append("the hidden state %s is set although initialised is false; "
                                "allowed: null before initialisation" % ", ".join(
                                    name for name, value in hidden.items() if value is not None))
            if k != 1 or flags["at_sample"] is not True:
                problems.append("k = %.40r, at_sample = %r before initialisation; allowed: k = "
                                "1, at_sample = true" % (k, flags["at_sample"]))
            if isinstance(time, list) and len(time) == 3 and (time[1] != 0.0 or time[2] != 0.0):
                problems.append("time = %.80r: time elapsed before initialisation; allowed: "
                                "[t_start, 0.0, 0.0]" % (time,))
        if problems:
            for msg in problems[:-1]:
                self._log_error("%s: %s" % (function, msg))
            self._fail("%s: %s; the state is refused and nothing was changed"
                       % (function, problems[-1]))
        if flags["initialised"]:
            # the parameters of an initialised state must be valid ones: check them on a copy
            saved = self.parameter_values()
            try:
                for name in saved:
                    setattr(self, name, values[name])
                bad = self.check_parameters()
                if not bad:
                    self.prepare()
                    missing = [name for name in self.HIDDEN if hidden[name] is None
                               and self.initial_hidden().get(name) is not None]
                    if missing:
                        bad = ["the hidden state %s of an initialised instance is missing "
                               "(null); allowed: the hidden state of an initialised instance"
                               % ", ".join(missing)]
                    else:
                        bad = self.hidden_problems(hidden) + self._timing_problems(
                            k, time, flags["at_sample"], stop)
            finally:
                for name, value in saved.items():
                    setattr(self, name, value)
                if self._initialised:
                    self.prepare()  # the derived constants of the parameters kept
            if bad:
                self._fail("%s: the FMU state of %s is not valid: %s; the state is refused and "
                           "nothing was changed" % (function, cls, bad[0]))
        if not assign:
            return
        for name, value in values.items():
            setattr(self, name, value)
        self._committed = hidden
        self.k = k
        self.start_time, self._elapsed, self._elapsed_c = (float(v) for v in time)
        self._stop_time = _INF if stop is None else float(stop)
        self._initialised, self._in_init = flags["initialised"], flags["in_init"]
        self._at_sample, self._terminated = flags["at_sample"], flags["terminated"]
        self._pending = None
        self._dirty = True
        if self._initialised:
            self.prepare()
            self._stop_at = self._stop_position(self.start_time, self._stop_time)

    @staticmethod
    def _fmu_state_from_bytes(data):
        """A :class:`Deserialised` of ``data`` (the state, or why the bytes are not one), which
        the loader shim has the instance check before it hands it out (fmi2DeSerializeFMUstate
        refuses bad bytes with the reason; this class method has no instance to log with, and
        without the shim fmi2SetFMUstate refuses them).  An exception here would crash
        pythonfmu."""
        try:
            try:
                return Deserialised(Fmi2Slave._fmu_state_from_bytes(data), len(data), None)
            except Exception as exc:
                return Deserialised(None, len(data), "%s: %s" % (type(exc).__name__, exc))
        except Exception:
            return None

    @staticmethod
    def _fmu_state_to_bytes(state):
        if type(state) is Deserialised:
            state = state.state
        return Fmi2Slave._fmu_state_to_bytes(state)


class Deserialised:
    """What fmi2DeSerializeFMUstate made of a host's bytes: ``state`` (None when the bytes are
    not one, ``why`` saying why) of ``size`` bytes.  The loader shim has the instance check it
    before handing it out (:data:`SHIM_VR`); fmi2SetFMUstate checks it again and restores it."""

    __slots__ = ("state", "size", "why")

    def __init__(self, state, size, why):
        self.state, self.size, self.why = state, size, why


#: One category string for every error line (pythonfmu 0.7.0 keeps a reference to each
#: message's category: a fresh string per line would be kept too).
_ERROR_CATEGORY = "logStatusError"


def _article(word):
    return "an" if word[0] in "AEIOU" else "a"


def _is_number(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def check_estimator_plain(value, sizes, drift_size, state_text, drift_text):
    """Check the JSON form of an estimator's hidden state (for a slave's ``parse_hidden``): a
    list of one of ``sizes`` entries, the last the drift estimators' ``[k, ...]`` of
    ``drift_size`` entries with ``k`` a count, every other entry a finite number.  Raises
    ValueError saying what was expected (``state_text``, ``drift_text``) or which entry is not
    finite."""
    if not isinstance(value, list) or len(value) not in sizes:
        raise ValueError("not %s" % state_text)
    *head, d = value
    drift_sizes = drift_size if isinstance(drift_size, tuple) else (drift_size,)
    if not (isinstance(d, list) and len(d) in drift_sizes and isinstance(d[0], int)
            and not isinstance(d[0], bool) and d[0] >= 0):
        raise ValueError("not %s" % drift_text)
    for v in head + d[1:]:
        if not (_is_number(v) and math.isfinite(v)):
            raise ValueError("%r is not a finite number" % (v,))


def _numbers(name, value):
    """``(path, number)`` of every number in a hidden state value (namedtuples nested)."""
    if value is None:
        return
    if isinstance(value, tuple):
        fields = getattr(value, "_fields", None) or range(len(value))
        for field, v in zip(fields, value):
            yield from _numbers("%s.%s" % (name, field), v)
    elif _is_number(value):
        yield name, value


def _drop_duplicate_path(path):
    """pythonfmu 0.7.0 puts the resources folder at the front of sys.path on every
    instantiation; keep one entry, so that sys.path (and import time) do not grow."""
    if path:
        while sys.path.count(path) > 1:
            sys.path.remove(path)


#: Default experiment of every FMU: 0 to 2 s in steps of 1 ms (the default Ts), 2001 samples.
#: Chosen for the hosts' defaults: fmusim's --output-interval defaults to the step size (whole
#: samples), and the FMU Compliance Checker's 500 output points over 2 s are steps of 4 ms =
#: 4 Ts (the stop time 1.999 s of 2000 samples made that 3.998 ms).  Any other step works too.
DEFAULT_EXPERIMENT = DefaultExperiment(start_time=0.0, stop_time=2.0, step_size=1e-3)


def _plain(value):
    """JSON-ready copy of hidden state (namedtuples become nested lists; a drift-estimator state
    without 3rd/4th-order sums keeps the letter's five entries, :func:`drift.plain`)."""
    if isinstance(value, drift.DriftState):
        return drift.plain(value)
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value
