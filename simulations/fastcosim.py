"""A fast fixed-step master: the loop of :func:`simulations.cosim.cosimulate` with the FMI
functions called directly through ctypes on preallocated arrays, for FMI 2.0 and FMI 3.0.

fmpy's ``FMU2Slave`` wrappers build argument arrays and check statuses in Python on every call
(microseconds each); here, as in fmpy's ``examples/efficient_loops.py``, fmpy loads, instantiates
and initialises the FMUs, and the stepping loop calls the library's ``fmi2DoStep`` /
``fmi3DoStep``, ``fmi2GetReal`` / ``fmi3GetFloat64`` and the setters with value-reference and
value arrays made once, writing each row straight into a NumPy array.

Per communication point, in the order of ``fmus``: set the FMU's inputs from the values its
connections carry (one call), then read its recorded and connected outputs (one call).  With
connections that run forward in that order (the chain Excitation -> Accelerometer ->
DriftEstimator) this is exactly the Gauss-Seidel loop of ``cosimulate``: each input is set from
its source's output at the same point before the FMU's outputs are read, so the results are
the same bits.  Other wirings are refused.
"""
import ctypes
import shutil
from ctypes import c_double, c_int, c_size_t, c_uint, c_void_p

import numpy as np
from fmpy import extract, read_model_description

from driftfmu.simulations.cosim import CoSimulationError, _STATUS


class FastInstance:
    """One FMU (FMI 2.0 or 3.0) loaded by fmpy, with raw ctypes entry points for the loop."""

    def __init__(self, name, path, logging_on=False):
        self.name = name
        self.md = read_model_description(str(path))
        self.fmi = int(self.md.fmiVersion[0])
        self.unzipdir = extract(str(path))
        self.vrs = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.messages = []
        identifier = self.md.coSimulation.modelIdentifier
        if self.fmi == 2:
            from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, \
                fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free
            self._callbacks = fmi2CallbackFunctions()
            self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log2)
            self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                                 modelIdentifier=identifier, instanceName=name)
            self.fmu.instantiate(callbacks=self._callbacks, loggingOn=logging_on)
            lib = self.fmu.dll
            self.do_step = _raw(lib.fmi2DoStep, [c_void_p, c_double, c_double, c_int])
            self.get_real = _raw(lib.fmi2GetReal, [c_void_p, c_void_p, c_size_t, c_void_p])
            self.set_real = _raw(lib.fmi2SetReal, [c_void_p, c_void_p, c_size_t, c_void_p])
        else:
            from fmpy.fmi3 import FMU3Slave
            self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                                 modelIdentifier=identifier, instanceName=name)
            self.fmu.instantiate(loggingOn=logging_on, logMessage=self._log3)
            lib = self.fmu.dll
            self.do_step = _raw(lib.fmi3DoStep, [c_void_p, c_double, c_double, c_int, c_void_p,
                                                 c_void_p, c_void_p, c_void_p])
            self.get_real = _raw(lib.fmi3GetFloat64, [c_void_p, c_void_p, c_size_t, c_void_p,
                                                      c_size_t])
            self.set_real = _raw(lib.fmi3SetFloat64, [c_void_p, c_void_p, c_size_t, c_void_p,
                                                      c_size_t])
        self.component = self.fmu.component

    def _log2(self, env, instance, status, category, message):
        self.messages.append("%s [%s] %s" % (
            (instance or b"").decode("utf-8", "replace"), _STATUS.get(status, status),
            (message or b"").decode("utf-8", "replace")))

    def _log3(self, env, status, category, message):
        self.messages.append("%s [%s] %s" % (self.name, _STATUS.get(status, status),
                                             (message or b"").decode("utf-8", "replace")))

    def initialise(self, values, start_time):
        """Set up (FMI 2), enter initialisation, set ``values`` by name, exit."""
        fmu = self.fmu
        if self.fmi == 2:
            fmu.setupExperiment(startTime=start_time)
            fmu.enterInitializationMode()
        else:
            fmu.enterInitializationMode(startTime=start_time)
        reals = {n: v for n, v in values.items() if self.types.get(n) in ("Real", "Float64")}
        ints = {n: v for n, v in values.items() if self.types.get(n) in ("Integer", "Int32")}
        unknown = set(values) - set(reals) - set(ints)
        if unknown:
            raise CoSimulationError("%s has no Real or Integer variable %s"
                                    % (self.name, sorted(unknown)))
        if reals:
            vrs = [self.vrs[n] for n in reals]
            vals = [float(v) for v in reals.values()]
            (fmu.setReal if self.fmi == 2 else fmu.setFloat64)(vrs, vals)
        if ints:
            vrs = [self.vrs[n] for n in ints]
            vals = [int(v) for v in ints.values()]
            (fmu.setInteger if self.fmi == 2 else fmu.setInt32)(vrs, vals)
        fmu.exitInitializationMode()

    def free(self):
        try:
            self.fmu.terminate()
        finally:
            self.fmu.freeInstance()
            shutil.rmtree(self.unzipdir, ignore_errors=True)


def _raw(function, argtypes):
    """A fresh ctypes prototype on the address of ``function`` (fmpy's own stays untouched)."""
    address = ctypes.cast(function, c_void_p).value
    return ctypes.CFUNCTYPE(c_int, *argtypes)(address)


def cosimulate_fast(fmus, connections, n_steps, step_size, start_values=None, record=None,
                    start_time=0.0, progress=None, logging_on=False):
    """:func:`simulations.cosim.cosimulate` (Gauss-Seidel) with direct FMI calls.

    Parameters and result as ``cosimulate``; the FMUs may be FMI 2.0 or FMI 3.0 (mixed too).

    Raises
    ------
    CoSimulationError
        When an FMU call fails (the message holds the FMUs' log), or when a connection runs
        backwards in the order of ``fmus``.
    """
    start_values = start_values or {}
    order = list(fmus)
    position = {name: i for i, name in enumerate(order)}
    for s, o, d, i in connections:
        if position[s] >= position[d]:
            raise CoSimulationError("connection %s.%s -> %s.%s runs against the order of the "
                                    "FMUs %s; the fast master needs forward connections"
                                    % (s, o, d, i, order))
    insts = {}
    try:
        for name, path in fmus.items():
            insts[name] = FastInstance(name, path, logging_on=logging_on)
        if record is None:
            record = {name: [v.name for v in inst.md.modelVariables if v.causality == "output"]
                      for name, inst in insts.items()}
        # one row per point: time, then per FMU the recorded and connected outputs it is read for
        reads = {name: list(record.get(name, ())) for name in order}
        for s, o, d, i in connections:
            if o not in reads[s]:
                reads[s].append(o)
        columns = ["time"] + ["%s.%s" % (name, v) for name in order for v in reads[name]]
        index = {key: j for j, key in enumerate(columns)}
        rows = np.zeros((max(n_steps, 1), len(columns)))
        row_bytes = rows.strides[0]
        base = rows.ctypes.data
        plan = []   # per FMU: (inst, [(set vrs, count, source offset)], get vrs, count, offset)
        for name in order:
            inst = insts[name]
            links = [(index["%s.%s" % (s, o)], inst.vrs[i]) for s, o, d, i in connections
                     if d == name]
            runs = []   # links whose sources sit side by side in the row: one call each
            for column, vr in links:
                if runs and runs[-1][0] + len(runs[-1][1]) == column:
                    runs[-1][1].append(vr)
                else:
                    runs.append((column, [vr]))
            sets = [((c_uint * len(vrs))(*vrs), len(vrs), column * 8) for column, vrs in runs]
            get_list = [inst.vrs[v] for v in reads[name]]
            get_vrs = (c_uint * len(get_list))(*get_list)
            offset = index["%s.%s" % (name, reads[name][0])] * 8 if reads[name] else 0
            plan.append((inst, sets, get_vrs, len(get_list), offset))
        for name in order:
            insts[name].initialise(start_values.get(name, {}), start_time)

        steppers = [(inst.do_step, inst.component, inst.fmi, inst.name) for inst in
                    (insts[n] for n in order)]
        fmi3_flags = (ctypes.c_bool * 3)()
        last_time = c_double()
        flag_addresses = [ctypes.addressof(fmi3_flags) + k for k in range(3)]
        every = max(1, n_steps // 100)
        t = start_time
        for k in range(n_steps):
            row = base + k * row_bytes
            if k:
                for do_step, component, fmi, name in steppers:
                    if fmi == 2:
                        status = do_step(component, t, step_size, 1)
                    else:
                        status = do_step(component, t, step_size, 1, flag_addresses[0],
                                         flag_addresses[1], flag_addresses[2],
                                         ctypes.addressof(last_time))
                    if status > 1:
                        raise CoSimulationError("%s: doStep at t = %r returned %s"
                                                % (name, t, _STATUS.get(status, status)))
                t = start_time + k * step_size
            rows[k, 0] = t
            for inst, sets, get_vrs, n_get, offset in plan:
                for set_vrs, n_set, source in sets:
                    if inst.fmi == 2:
                        status = inst.set_real(inst.component, set_vrs, n_set, row + source)
                    else:
                        status = inst.set_real(inst.component, set_vrs, n_set, row + source,
                                               n_set)
                    if status > 1:
                        raise CoSimulationError("%s: setting inputs at t = %r returned %s"
                                                % (inst.name, t, _STATUS.get(status, status)))
                if n_get:
                    if inst.fmi == 2:
                        status = inst.get_real(inst.component, get_vrs, n_get, row + offset)
                    else:
                        status = inst.get_real(inst.component, get_vrs, n_get, row + offset,
                                               n_get)
                    if status > 1:
                        raise CoSimulationError("%s: reading outputs at t = %r returned %s"
                                                % (inst.name, t, _STATUS.get(status, status)))
            if progress is not None and (k + 1) % every == 0:
                progress(k + 1)
        rows = rows[:n_steps]
        out = {"time": rows[:, 0].tolist()}
        for name, names in record.items():
            for v in names:
                key = "%s.%s" % (name, v)
                out[key] = rows[:, index[key]].tolist()
        return out
    except Exception as exc:
        log = [m for inst in insts.values() for m in inst.messages]
        raise CoSimulationError("%s%s" % (exc, "".join("\n  " + m for m in log))) from exc
    finally:
        for inst in insts.values():
            try:
                inst.free()
            except Exception:
                pass
