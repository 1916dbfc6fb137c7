"""Internal (not a stable API; use driftfmu.simulate instead).

A fast fixed-step master: the loop of :func:`driftfmu.simulations.cosim.cosimulate` with the FMI
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
import subprocess
from ctypes import c_double, c_int, c_size_t, c_uint, c_void_p

import numpy as np
from fmpy.fmi1 import FMICallException

from driftfmu.fmu_src import schemas
from driftfmu.simulations import fmucheck
from driftfmu.simulations.cosim import _STATUS, CoSimulationError, _remove, check_variables, \
    checked_fmu, failed, free_all, new_extract_folder, not_instantiated
from driftfmu.simulations.errors import UsageError


#: fmpy FMU objects whose instance was freed but whose library stays loaded, for the next run
#: of the same FMU in this process (``reuse=True``): (folder, identifier, name) -> object.
_IDLE = {}


class FastInstance:
    """One FMU (FMI 2.0 or 3.0) loaded by fmpy, with raw ctypes entry points for the loop.

    With ``reuse``, the library loaded by an earlier run of the same FMU under the same name in
    this process is instantiated again instead of being loaded anew (fmpy's loading costs tens
    of milliseconds, a run of the native chain of 60,000 steps about as much), and
    :meth:`free` frees the instance but keeps the library for the next run.
    """

    def __init__(self, name, path, logging_on=False, reuse=False):
        self.name = name
        self.path = str(path)
        self.unzipdir, self.md = unpacked(path)
        self.messages = []
        self.fmi = int(self.md.fmiVersion[0])
        self._key = (self.unzipdir, self.md.coSimulation.modelIdentifier, name) if reuse \
            else None
        idle = _IDLE.pop(self._key, None) if reuse else None
        self.vrs = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        try:
            self._load(name, idle, logging_on)
        except Exception as exc:  # (fmpy's "Failed to instantiate model", an OSError)
            raise not_instantiated(self.path, exc, self.messages) from exc
        self.component = self.fmu.component

    def _load(self, name, idle, logging_on):
        identifier = self.md.coSimulation.modelIdentifier
        if self.fmi == 2:
            from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, \
                fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, calloc, free
            self._callbacks = fmi2CallbackFunctions()
            self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log2)
            self._callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            self._callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            self.fmu = idle or FMU2Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                                         modelIdentifier=identifier, instanceName=name)
            self.fmu.instantiate(callbacks=self._callbacks, loggingOn=logging_on)
            lib = self.fmu.dll
            self.do_step = _raw(lib.fmi2DoStep, [c_void_p, c_double, c_double, c_int])
            self.get_real = _raw(lib.fmi2GetReal, [c_void_p, c_void_p, c_size_t, c_void_p])
            self.set_real = _raw(lib.fmi2SetReal, [c_void_p, c_void_p, c_size_t, c_void_p])
        else:
            from fmpy.fmi3 import FMU3Slave
            self.fmu = idle or FMU3Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                                         modelIdentifier=identifier, instanceName=name)
            self.fmu.instantiate(loggingOn=logging_on, logMessage=self._log3)
            lib = self.fmu.dll
            self.do_step = _raw(lib.fmi3DoStep, [c_void_p, c_double, c_double, c_int, c_void_p,
                                                 c_void_p, c_void_p, c_void_p])
            self.get_real = _raw(lib.fmi3GetFloat64, [c_void_p, c_void_p, c_size_t, c_void_p,
                                                      c_size_t])
            self.set_real = _raw(lib.fmi3SetFloat64, [c_void_p, c_void_p, c_size_t, c_void_p,
                                                      c_size_t])

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
        except FMICallException:
            pass  # terminate is refused before initialisation and a second time: free anyway
        finally:
            if self._key is None:
                self.fmu.freeInstance()
            else:  # the instance goes, the library stays loaded for the next run
                (self.fmu.fmi2FreeInstance if self.fmi == 2
                 else self.fmu.fmi3FreeInstance)(self.fmu.component)
                _IDLE[self._key] = self.fmu


_UNPACKED = {}


def unpacked(path):
    """``(folder, model description)`` of the FMU at ``path``, unpacked once per process (the
    model description and this platform's binaries only; removed at exit) and read without
    schema validation (the builder validated it): loading an FMU costs microseconds, not the
    0.2 s of unzipping and validating it again for every run."""
    import os
    import platform
    import zipfile
    stat = os.stat(path)
    # the file's identity and every time it has: the change time (which no one sets) also
    # moves when an FMU is written again with the same size and modification time
    key = (os.path.abspath(path), stat.st_dev, stat.st_ino, stat.st_mtime_ns, stat.st_ctime_ns,
           stat.st_size)
    if key not in _UNPACKED:
        # registered where a worker told to stop finds it (batch._worker_stop), removed when
        # the process ends (cosim.new_extract_folder)
        checked_fmu(path, validate=False)  # what the masters rely on (simulations/fmucheck.py)
        folder = new_extract_folder(prefix="driftfmu_fast_")
        here = {"Linux": ("linux64", "x86_64-linux"), "Windows": ("win64", "x86_64-windows"),
                "Darwin": ("darwin64", "x86_64-darwin", "aarch64-darwin")}.get(
                    platform.system(), ())
        try:
            with zipfile.ZipFile(path) as archive:
                names = [n for n in archive.namelist() if n == "modelDescription.xml"
                         or n.startswith("resources/")
                         or any(n.startswith("binaries/%s/" % p) for p in here)]
                archive.extractall(folder, names)
            md = schemas.read_model_description(folder, validate=False)
            # before a library is loaded: a cut one would stop this process with SIGBUS
            fmucheck.check_binaries(path, folder, md)
        except BaseException:
            _remove(folder)
            raise
        _UNPACKED[key] = (folder, md)
    return _UNPACKED[key]


#: The stepping loop in C, compiled once per machine (see :func:`_c_loop`): the FMI functions are
#: called through the pointers fmpy's loaded libraries export, on the arrays made here.
LOOP_SOURCE = r"""
#include <stddef.h>
typedef int (*step2)(void *, double, double, int);
typedef int (*step3)(void *, double, double, int, void *, void *, void *, void *);
typedef int (*access2)(void *, const unsigned int *, size_t, double *);
typedef int (*access3)(void *, const unsigned int *, size_t, double *, size_t);
typedef struct { int fmi; void *component; void *function; } Stepper;
typedef struct { int fmi; void *component; void *function; const unsigned int *vrs;
                 size_t n; ptrdiff_t offset; } Access;

/* Points k0 .. k1-1: step every FMU (but at point 0), then the setters and getters in order.
 * Returns 0, or 1 + the index of the failing call (steppers first) with *where = k. */
int driftfmu_loop(long k0, long k1, double t0, double h, char *rows, ptrdiff_t row_bytes,
                  int n_steppers, const Stepper *steppers, int n_access,
                  const Access *access, long *where)
{
    unsigned char flags[4];
    double last;
    for (long k = k0; k < k1; k++) {
        char *row = rows + k * row_bytes;
        if (k) {
            double t = t0 + (double)(k - 1) * h;
            for (int i = 0; i < n_steppers; i++) {
                const Stepper *s = &steppers[i];
                int status = s->fmi == 2
                    ? ((step2)s->function)(s->component, t, h, 1)
                    : ((step3)s->function)(s->component, t, h, 1, &flags[0], &flags[1],
                                           &flags[2], &last);
                if (status > 1) {
                    *where = k;
                    return 1 + i;
                }
            }
        }
        for (int i = 0; i < n_access; i++) {
            const Access *a = &access[i];
            double *values = (double *)(row + a->offset);
            int status = a->fmi == 2
                ? ((access2)a->function)(a->component, a->vrs, a->n, values)
                : ((access3)a->function)(a->component, a->vrs, a->n, values, a->n);
            if (status > 1) {
                *where = k;
                return 1 + n_steppers + i;
            }
        }
    }
    return 0;
}
"""


class _Stepper(ctypes.Structure):
    _fields_ = [("fmi", c_int), ("component", c_void_p), ("function", c_void_p)]


class _Access(ctypes.Structure):
    _fields_ = [("fmi", c_int), ("component", c_void_p), ("function", c_void_p),
                ("vrs", c_void_p), ("n", c_size_t), ("offset", ctypes.c_ssize_t)]


_LOOP_LIBRARY = []


#: The flags the C loop is compiled with.
LOOP_FLAGS = ("-O2", "-shared", "-fPIC")


def loop_target():
    """The name of the compiled C loop in the libraries folder, ``loop-<hash>`` (its file:
    ``loop-<hash>-<SHA-256 of its bytes>.so``), the hash of what its bytes depend on:
    :data:`LOOP_SOURCE`, :data:`LOOP_FLAGS` and the compiler
    (:func:`driftfmu.simulations.kernel.compiler_identity`)."""
    import hashlib
    from driftfmu.simulations import kernel
    digest = hashlib.sha256("\0".join(
        (LOOP_SOURCE, " ".join(LOOP_FLAGS),
         kernel.compiler_identity(kernel.compiler_command()))).encode()).hexdigest()[:16]
    return "loop-%s" % digest


def _build_loop(install):
    """Compile :data:`LOOP_SOURCE` in a work folder registered for removal
    (:func:`~driftfmu.simulations.cosim.new_extract_folder`: a worker stopped by SIGTERM removes
    it) and hand the library to ``install``, which moves it into the libraries folder in one
    rename: a worker stopped at any point leaves the whole library or nothing."""
    import os
    from driftfmu.simulations import folders, kernel, lifetime
    compiler = kernel.compiler_command()
    work = new_extract_folder(prefix="driftfmu_loop_")
    try:
        source = os.path.join(work, "loop.c")
        with open(source, "w") as fh:
            fh.write(LOOP_SOURCE)
        partial = os.path.join(work, "loop.so")
        # the work folder's lock held by the compiler too (folders.held_fds); its temporary
        # files in the work folder (lifetime.run's work)
        lifetime.run(compiler + list(LOOP_FLAGS) + ["-o", partial, source], check=True,
                     capture_output=True, work=work, pass_fds=folders.held_fds(work))
        install(partial)
    finally:
        _remove(work)


def loop_library():
    """The compiled C loop (ctypes function), or None when no C compiler works.  Compiled once
    into the private folder's libraries and checked before it is loaded
    (:func:`driftfmu.simulations.trust.load_library`)."""
    if _LOOP_LIBRARY:
        return _LOOP_LIBRARY[0]
    import subprocess
    from driftfmu.simulations import trust
    function = None
    try:
        function = trust.load_library(loop_target(), _build_loop,
                                      "the fast master's loop").driftfmu_loop
        function.restype = c_int
        function.argtypes = [ctypes.c_long, ctypes.c_long, c_double, c_double, c_void_p,
                             ctypes.c_ssize_t, c_int, c_void_p, c_int, c_void_p, c_void_p]
    except (OSError, subprocess.SubprocessError, AttributeError):
        function = None
    _LOOP_LIBRARY.append(function)
    return function


def _c_loop(plan, steppers, start_time, step_size, rows):
    """``loop(k0, k1)`` running :data:`LOOP_SOURCE`, or None without a compiler."""
    function = loop_library()
    if function is None:
        return None
    address = lambda f: ctypes.cast(f, c_void_p).value  # noqa: E731
    stepper_array = (_Stepper * len(steppers))(*[
        _Stepper(inst.fmi, inst.component, address(inst.do_step)) for inst in steppers])
    calls, owners = [], []
    for inst, sets, get_vrs, n_get, offset in plan:
        for set_vrs, n_set, source in sets:
            calls.append(_Access(inst.fmi, inst.component, address(inst.set_real),
                                 ctypes.addressof(set_vrs), n_set, source))
            owners.append((inst, "setting inputs"))
        if n_get:
            calls.append(_Access(inst.fmi, inst.component, address(inst.get_real),
                                 ctypes.addressof(get_vrs), n_get, offset))
            owners.append((inst, "reading outputs"))
    access_array = (_Access * max(1, len(calls)))(*calls)
    where = ctypes.c_long()
    keep = (plan, stepper_array, access_array)  # the arrays live as long as the loop

    def loop(k0, k1):
        failed = function(k0, k1, start_time, step_size, rows.ctypes.data, rows.strides[0],
                          len(steppers), ctypes.addressof(stepper_array), len(calls),
                          ctypes.addressof(access_array), ctypes.byref(where))
        if failed:
            i = failed - 1
            if i < len(steppers):
                _fail(steppers[i], "doStep", where.value, step_size)
            inst, what = owners[i - len(steppers)]
            _fail(inst, what, where.value, step_size)
        return keep
    return loop


def _compile_loop(plan, steppers, start_time, step_size, base, row_bytes):
    """The stepping loop, written out for these FMUs (no inner loops, no lookups): a function
    ``loop(k0, k1)`` that does the communication points ``k0 .. k1 - 1``."""
    env = {"_fail": _fail, "_flags": (ctypes.c_bool * 3)(), "_last": c_double()}
    env["_flag_addresses"] = [ctypes.addressof(env["_flags"]) + i for i in range(3)]
    env["_last_address"] = ctypes.addressof(env["_last"])
    lines = ["def loop(k0, k1):",
             "    t0, h = %r, %r" % (start_time, step_size),
             "    f0, f1, f2 = _flag_addresses",
             "    for k in range(k0, k1):",
             "        row = %d + k * %d" % (base, row_bytes),
             "        if k:",
             "            t = t0 + (k - 1) * h"]
    for j, inst in enumerate(steppers):
        env["S%d" % j], env["C%d" % j], env["I%d" % j] = inst.do_step, inst.component, inst
        extra = "" if inst.fmi == 2 else ", f0, f1, f2, _last_address"
        lines.append("            if S%d(C%d, t, h, 1%s) > 1: _fail(I%d, 'doStep', k, h)"
                     % (j, j, extra, j))
    for j, (inst, sets, get_vrs, n_get, offset) in enumerate(plan):
        env["G%d" % j], env["P%d" % j] = inst.get_real, inst.set_real
        env["C%d" % j], env["I%d" % j] = inst.component, inst
        for i, (set_vrs, n_set, source) in enumerate(sets):
            env["SV%d_%d" % (j, i)] = set_vrs
            extra = "" if inst.fmi == 2 else ", %d" % n_set
            lines.append("        if P%d(C%d, SV%d_%d, %d, row + %d%s) > 1: "
                         "_fail(I%d, 'setting inputs', k, h)"
                         % (j, j, j, i, n_set, source, extra, j))
        if n_get:
            env["GV%d" % j] = get_vrs
            extra = "" if inst.fmi == 2 else ", %d" % n_get
            lines.append("        if G%d(C%d, GV%d, %d, row + %d%s) > 1: "
                         "_fail(I%d, 'reading outputs', k, h)"
                         % (j, j, j, n_get, offset, extra, j))
    exec(compile("\n".join(lines) + "\n", "<fastcosim loop>", "exec"), env)
    return env["loop"]


def _fail(inst, what, k, h):
    raise CoSimulationError("%s: %s at communication point %d (step %r s) failed"
                            % (inst.name, what, k, h))


def _raw(function, argtypes):
    """A fresh ctypes prototype on the address of ``function`` (fmpy's own stays untouched)."""
    address = ctypes.cast(function, c_void_p).value
    return ctypes.CFUNCTYPE(c_int, *argtypes)(address)


def cosimulate_fast(fmus, connections, n_steps, step_size, start_values=None, record=None,
                    start_time=0.0, progress=None, logging_on=False, reuse=False,
                    arrays=False):
    """:func:`driftfmu.simulations.cosim.cosimulate` (Gauss-Seidel) with direct FMI calls.

    Parameters and result as ``cosimulate``; the FMUs may be FMI 2.0 or FMI 3.0 (mixed too).
    ``reuse``: keep the FMUs' libraries loaded for later runs in this process (see
    :class:`FastInstance`); ``arrays``: every column a NumPy array instead of a list (the same
    values).

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
            insts[name] = FastInstance(name, path, logging_on=logging_on, reuse=reuse)
        if record is None:
            record = {name: [v.name for v in inst.md.modelVariables if v.causality == "output"]
                      for name, inst in insts.items()}
        check_variables(insts, connections, record, start_values)
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

        loop = _c_loop(plan, [insts[n] for n in order], start_time, step_size, rows)
        if loop is None:  # no C compiler: the same loop in Python (slower, same bits)
            loop = _compile_loop(plan, [insts[n] for n in order], start_time, step_size, base,
                                 row_bytes)
        every = max(1, n_steps // 100)
        from driftfmu.simulations.cli import start_work
        start_work(progress)  # the FMUs are loaded: the steps' pace counts from here
        for k0 in range(0, n_steps, every):
            k1 = min(n_steps, k0 + every)
            loop(k0, k1)
            if progress is not None:
                progress(k1)
        rows[:, 0] = start_time + np.arange(len(rows)) * step_size  # cosimulate's t, same bits
        rows = rows[:n_steps]
        column = (lambda j: rows[:, j].copy()) if arrays else (lambda j: rows[:, j].tolist())
        out = {"time": column(0)}
        for name, names in record.items():
            for v in names:
                key = "%s.%s" % (name, v)
                out[key] = column(index[key])
        return out
    except UsageError:  # what the caller gave cannot be run (a file that is not an FMU)
        raise
    except Exception as exc:
        raise failed(exc, insts) from exc
    finally:
        free_all(insts)
