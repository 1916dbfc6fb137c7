"""Internal (not a stable API; use driftfmu.simulate instead).

A fixed-step fmpy master for FMI 2.0 (and FMI 3.0) co-simulation FMUs wired by connections.

The loop is written out in the open, as in FMPy's ``examples/custom_input.py``: the FMUs are
stepped and their outputs copied along the connections in the order the connections are given
(Gauss-Seidel), and the FMUs compute an output that depends on an input from the input set at
the same communication point.  With the chain Excitation -> Accelerometer -> DriftEstimator,
row ``k`` of the result therefore holds ``x_k``, the measurement ``z_k`` of ``x_k`` and the
estimator's ``k``-th update with ``z_k``; there is no one-step lag.

``coupling="jacobi"`` steps the FMUs the way fixed-step SSP masters do (fmpy's ``simulate_ssp``,
libcosim): every FMU steps with the inputs of the previous point, outputs are read right after
the steps, and only then copied along the connections, so each connection delays its signal by
one step.  It is there to compare with such masters, not to get the letter's results.

FMI 3.0 FMUs (the native twins' fmi3 build) run through the same loop: :class:`Fmi3Slave` gives
fmpy's ``FMU3Slave`` the FMI 2.0 method names the loop calls.
"""
import contextlib
import os
import signal
import threading

from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, \
    fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free

from driftfmu.simulations import folders
from driftfmu.simulations.errors import UsageError


#: Folders the FMUs of live instances are extracted to, each with the process that made it
#: (removed by :meth:`Instance.free`, or by :func:`remove_extracted` when a worker process is
#: told to stop and when the process ends).
EXTRACTED = {}

#: The process that registered :func:`remove_extracted` to run when it ends (a forked child
#: starts without its parent's registration).
_REMOVED_AT_END = [None]


def remove_extracted():
    """Remove every folder this process has extracted an FMU to and still holds.  A forked
    worker inherits its parent's folders in :data:`EXTRACTED`: they are the parent's, still in
    use there, and stay."""
    me = os.getpid()
    for d, owner in list(EXTRACTED.items()):
        if owner == me:
            _remove(d)


def new_extract_folder(prefix="driftfmu_fmu_"):
    """A new temporary folder, registered in :data:`EXTRACTED` before anything is written there
    (Ctrl-C and SIGTERM held back until it is), so that a worker told to stop removes it.  It is
    locked for as long as this process lives (:func:`driftfmu.simulations.folders.make`); the
    first call in a process removes the temporary folders left by processes killed outright
    (:data:`driftfmu.simulations.folders.TEMPORARY`).

    The signals' handlers are held back (:func:`interrupts_deferred`), not the signals: a
    signal blocked in this thread goes to another thread of the process (a pool worker runs
    OpenBLAS's), whose C handler marks it, and Python then runs its handler in this thread all
    the same, between ``mkdir`` and the registration (CI: a stopped worker left its folder)."""
    with interrupts_deferred():
        if _REMOVED_AT_END[0] != os.getpid():
            # a multiprocessing finalizer: the interpreter's exit runs it (through atexit),
            # and so does a multiprocessing worker, which ends by os._exit without atexit
            from multiprocessing import util
            util.Finalize(None, remove_extracted, exitpriority=0)
            _REMOVED_AT_END[0] = os.getpid()
        folders.sweep(folders.TEMPORARY)
        unzipdir = folders.make(prefix)
        EXTRACTED[unzipdir] = os.getpid()
    return unzipdir


def _extract(path):
    """Extract the FMU at ``path`` into a new temporary folder (:func:`new_extract_folder`)."""
    unzipdir = new_extract_folder()
    try:
        return extract(path, unzipdir=unzipdir)
    except BaseException:
        _remove(unzipdir)
        raise


def _remove(unzipdir):
    folders.remove(unzipdir)
    EXTRACTED.pop(unzipdir, None)


@contextlib.contextmanager
def interrupts_deferred(signals=(signal.SIGINT, signal.SIGTERM)):
    """Hold Ctrl-C (SIGINT) and SIGTERM back from FMU calls: yield ``check()``, which acts on
    them between calls.

    A KeyboardInterrupt raised inside an FMU's own Python code would unwind through pythonfmu's
    C++ layer (which frees its objects twice on an exception).  So while the master runs, each
    of ``signals`` whose handler is a Python function only marks itself pending; ``check()``,
    called by the master between steps, hands it to that handler (which raises, e.g.,
    KeyboardInterrupt).  Signals ignored or not handled in Python are left alone, and nothing
    changes outside the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    previous = {s: signal.getsignal(s) for s in signals}
    previous = {s: h for s, h in previous.items() if callable(h)}
    pending = []

    def hold(signum, frame):
        pending.append(signum)

    def restore():
        held = [s for s in previous if signal.getsignal(s) is hold]
        for s in held:
            signal.signal(s, previous[s])
        return held

    def check():
        if pending:
            held = restore()
            if pending[0] in held:
                previous[pending[0]](pending[0], None)

    for s in previous:
        signal.signal(s, hold)
    try:
        yield check
    finally:
        held = restore()
        if pending and pending[0] in held:
            previous[pending[0]](pending[0], None)


def check_fmu_file(path):
    """UsageError unless ``path`` is a zip archive, before fmpy reads it (whose message, "File
    is not a zip file", names neither the file nor what to do)."""
    import zipfile
    if not zipfile.is_zipfile(path):
        raise UsageError("%s is not an FMU (not a zip archive: damaged or cut short); allowed: "
                         "an FMU as driftfmu build writes it (remove this one and it is built "
                         "again)" % path)


def check_variables(insts, connections, record=None, start_values=None, inputs=None):
    """UsageError unless each FMU of ``insts`` (name -> an instance with ``path``, ``md`` and
    ``vrs``) has every variable the master will use: the connections' ends, the recorded
    values, the start values and the inputs.  A wrong FMU under an expected file name (the
    DriftEstimator saved as Excitation.fmu) is named, not a bare "'x'" of a lookup."""
    needed = {name: [] for name in insts}
    for s, o, d, i in connections:
        needed[s].append(o)
        needed[d].append(i)
    for group in (record or {}, start_values or {}, inputs or {}):
        for name, names in group.items():
            if name in needed:  # (values for an FMU not in this run: the masters skip them)
                needed[name].extend(names)
    for name, names in needed.items():
        inst = insts[name]
        missing = sorted(set(v for v in names if v not in inst.vrs))
        if not missing:
            continue
        from driftfmu.fmu_src.builder import NAMES
        model = inst.md.modelName
        ours = name in NAMES
        raise UsageError("%s has no variable %s (its model is %s)%s; allowed: %s" % (
            inst.path, ", ".join(missing), model,
            ": it is not driftfmu's %s" % name if ours and model != name else "",
            "driftfmu's %s.fmu, as driftfmu build writes it (remove this one and it is built "
            "again)" % name if ours else "an FMU with the variables %s uses" % name))


class CoSimulationError(RuntimeError):
    """A co-simulation failed; the message carries what the FMUs logged."""


def failed(exc, insts):
    """The CoSimulationError of a master over ``insts`` (name -> Instance) that met ``exc``:
    its message, with the last error an FMU logged on its first line (what a one-line report
    shows: why the call failed, not only that it did), and, one per line, what else the FMUs
    logged.  The reason is said once: the error on the first line is not repeated on a line of
    its own, and neither the FMU's name nor the failed function is said twice in it."""
    log = [m for inst in insts.values() for m in inst.messages]
    text = str(exc)
    errors = [m for m in log if " [error] " in m or " [fatal] " in m]
    if errors:
        first, _, rest = text.partition("\n")
        text = "%s: %s%s" % (first.rstrip("."), _reason(errors[-1], first), _ + rest)
        log.remove(errors[-1])
    return CoSimulationError("%s%s" % (text, "".join("\n  " + m for m in log)))


def _reason(entry, call):
    """A logged error (``"<instance> [error] <message>"``) as the reason of the failed
    ``call`` (fmpy's ``"fmi2GetReal failed with status 3 (error)"``): ``"<instance>:
    <message>"``, without the instance's name or the function's that the message repeats."""
    inst, _, rest = entry.partition(" [")
    message = rest.partition("] ")[2]
    for prefix in (inst, call.split(" ", 1)[0]):
        if prefix and message.startswith(prefix + ": "):
            message = message[len(prefix) + 2:]
    if call.startswith(inst + ": "):  # the call names the instance already
        return message
    return "%s: %s" % (inst, message)


def free_all(insts):
    """Free every instance of a master at its end, whatever happened (a failing free does not
    hide the others or the master's own error)."""
    for inst in insts.values():
        try:
            inst.free()
        except Exception:
            pass


_STATUS = {0: "ok", 1: "warning", 2: "discard", 3: "error", 4: "fatal", 5: "pending"}


def checked_fmu(path, validate=True):
    """fmpy's model description of the FMU at ``path`` once the file holds what a master relies
    on (:func:`driftfmu.simulations.fmucheck.check_fmu`; a file that is no zip archive at all
    named as :func:`check_fmu_file` names it)."""
    from driftfmu.simulations import fmucheck
    check_fmu_file(path)
    return fmucheck.check_fmu(path, expected=fmucheck.expected_model(path), validate=validate)


def not_instantiated(path, exc, messages):
    """The FileProblem of an FMU at ``path`` whose library did not load or whose instantiation
    failed (``exc``), with the reason the FMU logged (``messages``, the ``Instance`` log's
    lines) or the loader gave: a GUID that does not match the binary's, a library of another
    platform, no libpython for a Python FMU."""
    from driftfmu.simulations.errors import FileProblem
    errors = [m.partition("] ")[2] for m in messages if " [error] " in m or " [fatal] " in m]
    reason = errors[-1] if errors else (exc.strerror if isinstance(exc, OSError) and
                                        exc.strerror else str(exc).strip() or
                                        type(exc).__name__)
    return FileProblem("%s: the FMU could not be instantiated on this host: %s; expected: an "
                       "FMU whose model description and binary come from one build (driftfmu "
                       "doctor %s says more)" % (path, reason.splitlines()[0], path))


class Instance:
    """One FMU instance in the master: the fmpy slave, its value references and its log."""

    def __init__(self, name, path, logging_on=False):
        from driftfmu.simulations import fmucheck
        self.name = name
        self.path = str(path)
        self.md = checked_fmu(self.path)
        self.unzipdir = _extract(self.path)
        self.vrs = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.messages = []
        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        try:
            # before the library is loaded: a cut one would stop this process with SIGBUS
            fmucheck.check_binaries(self.path, self.unzipdir, self.md)
            try:
                if self.md.fmiVersion.startswith("3"):
                    self.fmu = Fmi3Slave(self, name, logging_on)
                    return
                self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                                     modelIdentifier=self.md.coSimulation.modelIdentifier,
                                     instanceName=name)
                self.fmu.instantiate(callbacks=self._callbacks, loggingOn=logging_on)
            except Exception as exc:  # (fmpy's "Failed to instantiate model", an OSError)
                raise not_instantiated(self.path, exc, self.messages) from exc
        except BaseException:
            _remove(self.unzipdir)
            raise

    def _log(self, env, instance, status, category, message):
        self.messages.append("%s [%s] %s" % (
            (instance or b"").decode("utf-8", "replace"), _STATUS.get(status, status),
            (message or b"").decode("utf-8", "replace")))

    def set(self, values):
        """Set start values or inputs given by name (Real and Integer variables)."""
        reals = {n: v for n, v in values.items() if self.types.get(n) in ("Real", "Float64")}
        ints = {n: v for n, v in values.items() if self.types.get(n) in ("Integer", "Int32")}
        unknown = set(values) - set(reals) - set(ints)
        if unknown:
            raise CoSimulationError("%s has no Real or Integer variable %s"
                                    % (self.name, sorted(unknown)))
        if reals:
            self.fmu.setReal([self.vrs[n] for n in reals], [float(v) for v in reals.values()])
        if ints:
            self.fmu.setInteger([self.vrs[n] for n in ints], [int(v) for v in ints.values()])

    def free(self):
        try:
            self.fmu.terminate()
        except FMICallException:
            pass  # terminate is refused before initialisation and a second time: free anyway
        finally:
            self.fmu.freeInstance()
            _remove(self.unzipdir)


class Fmi3Slave:
    """fmpy's ``FMU3Slave`` behind the FMI 2.0 method names of ``FMU2Slave`` that the master
    and the tests call (setupExperiment, getReal/setReal, getInteger/setInteger, doStep,
    get/set/free/serialise/deserialise FMU state, instantiate, fmi2FreeInstance); log messages
    go to the owning :class:`Instance` in its format."""

    def __init__(self, owner, name, logging_on=False):
        from fmpy.fmi3 import FMU3Slave
        self._owner = owner
        self._name = name
        self._start = 0.0
        self._fmu = FMU3Slave(guid=owner.md.guid, unzipDirectory=owner.unzipdir,
                              modelIdentifier=owner.md.coSimulation.modelIdentifier,
                              instanceName=name)
        self.instantiate(loggingOn=logging_on)

    def _log(self, env, status, category, message):
        self._owner.messages.append("%s [%s] %s" % (
            self._name, _STATUS.get(status, status), (message or b"").decode("utf-8",
                                                                              "replace")))

    @property
    def component(self):
        return self._fmu.component

    def instantiate(self, callbacks=None, loggingOn=False):
        self._fmu.instantiate(loggingOn=loggingOn, logMessage=self._log)

    def fmi2FreeInstance(self, component):
        """Free the instance, keep the library loaded (fmpy's freeInstance also unloads it)."""
        self._fmu.fmi3FreeInstance(component)

    def freeInstance(self):
        self._fmu.freeInstance()

    def setupExperiment(self, tolerance=None, startTime=0.0, stopTime=None):
        self._start = startTime

    def enterInitializationMode(self):
        self._fmu.enterInitializationMode(startTime=self._start)

    def exitInitializationMode(self):
        self._fmu.exitInitializationMode()

    def doStep(self, currentCommunicationPoint, communicationStepSize,
               noSetFMUStatePriorToCurrentPoint=True):
        return self._fmu.doStep(currentCommunicationPoint, communicationStepSize,
                                noSetFMUStatePriorToCurrentPoint)

    def getReal(self, vr):
        return self._fmu.getFloat64(vr)

    def setReal(self, vr, value):
        self._fmu.setFloat64(vr, value)

    def getInteger(self, vr):
        return self._fmu.getInt32(vr)

    def setInteger(self, vr, value):
        self._fmu.setInt32(vr, value)

    def getBoolean(self, vr):
        return self._fmu.getBoolean(vr)

    def getFMUstate(self):
        return self._fmu.getFMUState()

    def setFMUstate(self, state):
        self._fmu.setFMUState(state)

    def freeFMUstate(self, state):
        self._fmu.freeFMUState(state)

    def serializeFMUstate(self, state):
        return self._fmu.serializeFMUState(state)

    def deSerializeFMUstate(self, data):
        return self._fmu.deserializeFMUState(data)

    def reset(self):
        self._fmu.reset()

    def terminate(self):
        self._fmu.terminate()


COUPLINGS = ("gauss-seidel", "jacobi")


def cosimulate(fmus, connections, n_steps, step_size, start_values=None, record=None,
               start_time=0.0, progress=None, logging_on=False, coupling="gauss-seidel",
               inputs=None):
    """Run FMUs wired by ``connections`` for ``n_steps`` communication points.

    Parameters
    ----------
    fmus : dict
        Instance name -> path of the ``.fmu``; stepped in this order.
    connections : sequence of (src, output, dst, input)
        Copied in this order at every communication point (before recording).
    n_steps : int
        Number of communication points recorded, at ``start_time + i * step_size``.
    step_size : float
        Communication step.
    start_values : dict, optional
        Instance name -> {variable: value}, set in initialisation mode.
    record : dict, optional
        Instance name -> list of variables to record (default: every output).
    progress : callable, optional
        Called with the number of steps done, every 1 % or so.
    coupling : {"gauss-seidel", "jacobi"}
        Gauss-Seidel (default): outputs copied along the connections in order, then recorded;
        no lag.  Jacobi: outputs recorded right after the steps, then copied; inputs start at
        their start values; one step of delay per connection.
    inputs : dict, optional
        Instance name -> {input variable: sequence of ``n_steps`` floats}: value ``i`` is set at
        communication point ``i``, before the connections are copied (external signals).

    Returns
    -------
    dict
        ``"time"`` and ``"<instance>.<variable>"`` -> list of floats, one per point.

    Raises
    ------
    CoSimulationError
        When an FMU call fails; the message holds the FMUs' log.
    """
    if coupling not in COUPLINGS:
        raise UsageError("coupling = %r is not allowed; allowed: %s" % (coupling, COUPLINGS))
    with interrupts_deferred() as check:
        return _cosimulate(fmus, connections, n_steps, step_size, start_values, record,
                           start_time, progress, logging_on, coupling == "jacobi", check,
                           inputs or {})


def _cosimulate(fmus, connections, n_steps, step_size, start_values, record, start_time,
                progress, logging_on, jacobi, check, inputs=None):
    start_values = start_values or {}
    insts = {}
    try:
        for name, path in fmus.items():
            insts[name] = Instance(name, path, logging_on=logging_on)
            check()
        if record is None:
            record = {name: [v.name for v in inst.md.modelVariables if v.causality == "output"]
                      for name, inst in insts.items()}
        check_variables(insts, connections, record, start_values,
                        {name: list(signals) for name, signals in (inputs or {}).items()})
        links = [(insts[s].fmu, insts[s].vrs[o], insts[d].fmu, insts[d].vrs[i])
                 for s, o, d, i in connections]
        feeds = [(insts[name].fmu, insts[name].vrs[v], values)
                 for name, signals in (inputs or {}).items() for v, values in signals.items()]
        reads = [(insts[name].fmu, [insts[name].vrs[v] for v in names])
                 for name, names in record.items()]
        keys = ["%s.%s" % (name, v) for name, names in record.items() for v in names]
        out = {"time": []}
        out.update({key: [] for key in keys})
        columns = [out[key] for key in keys]
        for name, inst in insts.items():
            inst.fmu.setupExperiment(startTime=start_time)
            inst.fmu.enterInitializationMode()
            inst.set(start_values.get(name, {}))
            inst.fmu.exitInitializationMode()
        every = max(1, n_steps // 100)
        t = start_time
        from driftfmu.simulations.cli import start_work
        start_work(progress)  # the FMUs are loaded: the steps' pace counts from here
        for i in range(n_steps):
            check()
            if i:
                for inst in insts.values():
                    inst.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=step_size)
                t = start_time + i * step_size
            for fmu, vr, values in feeds:
                fmu.setReal([vr], [float(values[i])])
            if not jacobi:
                for src, ovr, dst, ivr in links:
                    dst.setReal([ivr], src.getReal([ovr]))
            else:
                copied = [(dst, ivr, src.getReal([ovr])) for src, ovr, dst, ivr in links]
            out["time"].append(t)
            j = 0
            for fmu, vrs in reads:
                for value in fmu.getReal(vrs):
                    columns[j].append(value)
                    j += 1
            if jacobi and i:  # the first step runs on the start values of the inputs
                for dst, ivr, value in copied:
                    dst.setReal([ivr], value)
            if progress is not None and (i + 1) % every == 0:
                progress(i + 1)
        return out
    except UsageError:  # what the caller gave cannot be run (a file that is not an FMU)
        raise
    except Exception as exc:
        raise failed(exc, insts) from exc
    finally:
        free_all(insts)
