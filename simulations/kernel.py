"""Internal (not a stable API; use driftfmu.montecarlo or driftfmu.sweep instead).

The compiled batch kernel: the third engine beside the NumPy batch engine and the FMUs.

``batch_kernel.c`` (next to this file) writes the chains of
:func:`driftfmu.simulations.batch.simulate`, :func:`driftfmu.models.adxl203.simulate` and
:func:`driftfmu.models.dualaxis.simulate` out over the C port of models/
(``fmu_src/native/models``, proven bit-equal to models/ by ``tests/test_native_models.py``),
one run after another.  It is compiled once per machine (the native FMUs' flags, ``-O2
-ffp-contract=off -fno-fast-math``) into a shared library in the private folder of the work
folders (``driftfmu-<uid>/libraries`` in the temporary folder), named by the hash of its
sources and of its own bytes, moved there in one rename, checked before it is loaded
(:func:`driftfmu.simulations.trust.load_library`), and called through ctypes on NumPy arrays.  Without
a C compiler :func:`library` returns None and the callers use the NumPy engine (same results).

``DRIFTFMU_KERNEL=numpy`` in the environment switches the kernel off (for comparisons and for
machines whose compiler misbehaves); ``CC`` names the compiler (default ``cc``).
"""
import ctypes
import functools
import hashlib
import os
import shlex
import subprocess
from pathlib import Path

import numpy as np

from driftfmu.simulations import folders, lifetime

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "batch_kernel.c"
#: The C units of models/ the kernel calls (with their own dependencies).
UNITS = ("ops.c", "noise.c", "excitation.c", "sensor.c", "ekf.c", "drift.c", "chain.c",
         "harmonic.c", "adxl203.c", "errors.c", "parameters.c", "dualaxis.c", "covariance.c",
         "bias.c")
#: Order of the per-run parameter arrays of ``driftfmu_batch_run`` (batch.simulate's names;
#: ``fA``, ``fQ`` are the filter's ``A`` and ``Q``; the general model's, ``drive`` as a
#: float; then the sensor's slow errors, chain.SENSOR_ERRORS_OFF's, ``bits`` as a float).
PARAMS = ("a0", "a1", "a2", "A", "Q", "R", "x0", "P0", "Ts", "X", "f", "phi", "fA", "fQ",
          "a3", "a4", "B", "drive", "Qu", "Xu", "fu", "bias", "Qb", "tau_b", "b0", "Pb0",
          "bias_on", "random_walk", "bias_gm", "tau_gm", "flicker", "tau_min", "tau_max",
          "d_inf", "E_tau", "theta", "T", "T0", "kT_bias", "kT_scale", "range", "bits")
#: Fields of one run's state (``RunState``): float64 but the drift counter ``k`` (int64):
#: x, zbar, x2bar, the filter's x and P, the drift estimators' state (whose 3rd/4th-order
#: sums come last), the general sensor's realised drift, the bias part (b, Pxb, Pbb), the
#: first sample whose covariance (P, Pxb, Pbb) was not valid (0: none) with that covariance,
#: and the slow errors' state (rw, gm, E and the flicker components,
#: models.errors.FLICKER_MAX of them).
STATE_FIELDS = 5 + 9 + 1 + 3 + 4 + 3 + 8
#: models.adxl203.simulate's start values and columns, in the kernel's order.
EXCITATION = ("kind", "A", "Q", "x0", "X", "f", "phi", "Xy", "phiy", "seed")
SENSOR = ("a0", "a1", "a2", "R", "a3", "cross", "fc", "Vs", "bits", "density", "seed", "noise",
          "axes")
ESTIMATOR = ("a0", "a1", "a2", "A", "Q", "R", "x0", "P0", "estimator", "process", "f", "Qh",
             "a3", "a4")
COLUMNS = ("time", "x", "y", "z", "z_y", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3",
           "z_comp")
#: models.dualaxis.simulate's start values and the single-axis estimators', in the kernel's
#: order (its columns are models.dualaxis.COLUMNS).
DUAL_EXCITATION = ("kind", "A", "Q", "Qy", "rho", "x0", "X", "f", "phi", "Xy", "phiy")
DUAL_SENSOR = ("a0", "a1", "a2", "bx", "R", "a0y", "a1y", "a2y", "by", "Ry", "noise")
DUAL_ESTIMATOR = ("a0", "a1", "a2", "bx", "R", "a0y", "a1y", "a2y", "by", "Ry", "A", "Q", "Qy",
                  "rho", "x0", "y0", "P0", "P0y", "f", "Qh", "process", "estimator")
SINGLE = ("a0", "a1", "a2", "R", "Q", "x0", "P0", "A", "process", "f", "Qh")

#: Added to the native FMUs' flags (which keep the bits: no FMA contraction, no fast math):
#: inlining across the models/ units (link-time optimisation, -O3, inlining limits high enough
#: that the chain's step functions, struct results included, are inlined into the kernel's
#: loops; the units' functions are not interposable from outside the library) and no errno
#: for sqrt; from 110 to 58 ns per sample-run of the Gaussian chain on the development
#: machine (52 ns with the per-run noise keys of batch_kernel.c), at a load average of about 20.
#: No straight-line (SLP) vectorisation: GCC 12's SLP pass recognises a*b - c*d, a*b + c*d
#: pairs as complex arithmetic and emits fused multiply-subtract-adds (vfmsubadd) in spite of
#: -ffp-contract=off (found in dualaxis_estimator_predict, and in dualaxis_estimator_step after
#: an unrelated change of ops.c moved the inlining); the loops are vectorised as before, at the
#: same speed.
SPEED_FLAGS = ("-O3", "-fno-math-errno", "-flto", "-fno-semantic-interposition",
               "--param=max-inline-insns-auto=300", "--param=max-inline-insns-single=600",
               "-fno-tree-slp-vectorize")
#: And, where the compiler takes them, the instructions of this machine's processor in
#: vectors of up to 512 bits: the vectorised Gaussian chain (run_gaussian_vector) then advances
#: eight runs per instruction (AVX-512; 0.29 instead of 0.34 s for the default sweep's runs
#: on one core of the development machine) or four (AVX2) instead of two (SSE2).  The library
#: is compiled on the machine that runs it (named by its processor too, :func:`_build`); the
#: vector instructions are the IEEE operations of the scalar ones and -ffp-contract=off still
#: forbids fusing them.
MACHINE_FLAGS = ("-march=native", "-mprefer-vector-width=512")
_LIBRARY = []
_P = ctypes.c_void_p


def enabled():
    """False when ``DRIFTFMU_KERNEL=numpy`` switches the kernel off."""
    return os.environ.get("DRIFTFMU_KERNEL", "").strip().lower() != "numpy"


def _sources():
    from driftfmu.fmu_src.native.models import generate
    return generate, [SOURCE] + [generate.HERE / u for u in UNITS]


def library():
    """The loaded kernel (ctypes library), or None without a working C compiler or when
    :func:`enabled` is False.  Compiled at most once per machine and source version, into the
    private folder's libraries (:func:`driftfmu.simulations.trust.load_library`: loaded only
    when this user's, writable by no one else and the bytes that were built)."""
    if not enabled():
        return None
    if _LIBRARY:
        return _LIBRARY[0]
    from driftfmu.simulations import trust
    lib = None
    try:
        lib = _load(trust.load_library(target(), _build, "the batch kernel"))
    except (OSError, subprocess.SubprocessError):
        lib = None
    _LIBRARY.append(lib)
    return lib


def compiler_command():
    """The C compiler command: ``CC`` split as a shell would, default ``cc``."""
    return shlex.split(os.environ.get("CC", "cc"))


@functools.lru_cache(maxsize=None)
def _version(command):
    try:
        done = lifetime.run(list(command) + ["--version"], capture_output=True, text=True,
                              timeout=60)
    except (OSError, subprocess.SubprocessError):
        return ""
    return done.stdout if done.returncode == 0 else ""


def compiler_identity(command):
    """What names a compiler in the name of a library it compiled: its command and what its
    ``--version`` prints (once per command and process), so that another ``CC``, or the same
    command after an upgrade, compiles anew instead of loading what the other one made."""
    return " ".join(command) + "\n" + _version(tuple(command))


def target():
    """The name of the compiled kernel in the libraries folder, ``kernel-<hash>`` (its file:
    ``kernel-<hash>-<SHA-256 of its bytes>.so``), the hash of everything its bytes depend on:
    the sources and headers, the parameter table, the flags, the compiler
    (:func:`compiler_identity`) and the processor the machine flags are for."""
    generate, sources = _sources()
    digest = hashlib.sha256()
    for path in sorted(sources + sorted(generate.HERE.glob("*.h"))):
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    digest.update(generate.parameters_table().encode())
    digest.update(" ".join(generate.CFLAGS + SPEED_FLAGS + MACHINE_FLAGS).encode())
    digest.update(compiler_identity(compiler_command()).encode())
    digest.update(_processor().encode())
    return "kernel-%s" % digest.hexdigest()[:16]


def _build(install):
    """Compile the kernel in a work folder and hand the library to ``install`` (which moves
    it into the libraries folder)."""
    generate, sources = _sources()
    table = generate.parameters_table()
    compiler = compiler_command()
    with folders.temporary("driftfmu_kernel_") as work:
        (Path(work) / "parameters_table.h").write_text(table)
        partial = Path(work) / "kernel.so"
        # a compiler without the machine flags, or without link-time optimisation, gets fewer
        for extra in (SPEED_FLAGS + MACHINE_FLAGS, SPEED_FLAGS, ()):
            command = compiler + list(generate.CFLAGS) + list(extra) + [
                "-shared", "-fPIC", "-I", work, "-I", str(generate.HERE)] + [
                str(s) for s in sources] + ["-o", str(partial), "-lm"]
            try:
                # the work folder's lock held by the compiler too (folders.held_fds); the
                # compiler's own temporary files (link-time optimisation writes several) go
                # into the work folder, so an interrupted compile leaves none in TMPDIR
                lifetime.run(command, check=True, capture_output=True, work=work,
                             pass_fds=folders.held_fds(work))
                break
            except subprocess.CalledProcessError:
                if not extra:
                    raise
        install(str(partial))


def _processor():
    """What names this machine's processor for :data:`MACHINE_FLAGS` (its model and
    instruction-set flags where /proc/cpuinfo tells them)."""
    import platform
    text = platform.machine() + " " + platform.processor()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.split(":")[0].strip() in ("model name", "flags", "Features"):
                    text += "\n" + line.strip()
                if line.strip() == "":
                    break  # the first processor's block is enough
    except OSError:
        pass
    return text


def _load(lib):
    """``lib`` (the loaded kernel) with its functions' prototypes."""
    i64, d = ctypes.c_int64, ctypes.c_double
    lib.driftfmu_batch_init.restype = None
    lib.driftfmu_batch_init.argtypes = [i64, _P, _P, _P]
    lib.driftfmu_batch_run.restype = None
    lib.driftfmu_batch_run.argtypes = [i64, i64, i64, i64, _P, i64, i64, i64, i64, _P, _P, _P]
    lib.driftfmu_adxl203.restype = ctypes.c_int
    lib.driftfmu_adxl203.argtypes = [i64, d, _P, _P, _P, _P, _P]
    lib.driftfmu_dual.restype = ctypes.c_int
    lib.driftfmu_dual.argtypes = [i64, i64, _P, d, _P, _P, _P, _P, _P, _P, _P]
    return lib


def _pointers(arrays):
    """A C array of the arrays' data pointers (None: NULL)."""
    return (_P * len(arrays))(*[None if a is None else a.ctypes.data for a in arrays])


class Batch:
    """The state of ``len(seeds)`` runs of batch.simulate's chain in the kernel.

    ``params`` maps the names of :data:`PARAMS` to floats or ``(runs,)`` arrays.  :meth:`run`
    advances every run over samples ``k0 .. k1 - 1``; :meth:`state` gives the run states.
    ``general``: the general sensor or the known input in the batch; ``quadratic``: ``a3 =
    a4 = 0`` in every run; ``slow``: the sensor's slow errors, tilt or ADC are on
    (:func:`driftfmu.simulations.batch.simulate`'s flags).  The parameters of
    :data:`PARAMS` missing from ``params`` take their off values.
    """

    def __init__(self, lib, seeds, params, kind, n, record, general=False, quadratic=True,
                 slow=False):
        from driftfmu.models import chain
        from driftfmu.simulations.batch import BIAS_OUTPUTS, TRAJECTORIES
        self.lib = lib
        self.seeds = np.ascontiguousarray(seeds, dtype=np.uint64)
        runs = self.seeds.shape[0]
        params = dict(chain.SENSOR_ERRORS_OFF, **params)
        self.params = [np.ascontiguousarray(np.broadcast_to(np.asarray(params[name],
                                                                       dtype=float), (runs,)))
                       for name in PARAMS]
        self.param_ptrs = _pointers(self.params)
        self.kind, self.n, self.runs = int(kind), int(n), runs
        self.general, self.quadratic = int(bool(general)), int(bool(quadratic))
        self.slow = int(bool(slow))
        self.traj = {name: np.empty((runs, n)) for name in record}
        self.traj_ptrs = _pointers([self.traj.get(name) for name in
                                    TRAJECTORIES + BIAS_OUTPUTS]) if self.traj else None
        self.buffer = np.zeros((runs, STATE_FIELDS))
        lib.driftfmu_batch_init(runs, self.seeds.ctypes.data, self.param_ptrs,
                                self.buffer.ctypes.data)

    def run(self, k0, k1):
        """Samples ``k0 .. k1 - 1`` (1-based) of every run."""
        self.lib.driftfmu_batch_run(k0, k1, self.n, self.runs, self.seeds.ctypes.data,
                                    self.kind, self.general, self.quadratic, self.slow,
                                    self.param_ptrs, self.buffer.ctypes.data, self.traj_ptrs)

    def state(self):
        """``(x, zbar, x2bar, est, hbar)``: arrays ``(runs,)``, a chain.EstimatorState of
        arrays, and the realised ``mean(a2 x^2 + a3 x^3 + a4 x^4)`` (0 unless the batch has
        ``a3`` or ``a4``)."""
        from driftfmu.models import chain, drift
        b = self.buffer
        k = b[:, 5].copy().view(np.int64)
        est = chain.EstimatorState(b[:, 3].copy(), b[:, 4].copy(),
                                   drift.DriftState(k, *(b[:, i].copy() for i in range(6, 14))))
        return b[:, 0].copy(), b[:, 1].copy(), b[:, 2].copy(), est, b[:, 14].copy()

    def bias(self):
        """The bias part of every run, a models.bias.Bias of arrays ``(runs,)``."""
        from driftfmu.models import bias
        return bias.Bias(*(self.buffer[:, i].copy() for i in (15, 16, 17)))

    def check_bias(self, est, seeds):
        """Raise the CovarianceError models.bias.check raises in the NumPy engine: the first
        sample at which a run's covariance (P, Pxb, Pbb) was not valid, and the first run
        there (with its seed)."""
        from driftfmu.models import bias, covariance
        bad_k = self.buffer[:, 18]
        if not (bad_k > 0).any():
            return
        k = bad_k[bad_k > 0].min()
        run = int(np.flatnonzero(bad_k == k)[0])
        P, Pxb, Pbb = (float(v) for v in self.buffer[run, 19:22])
        raise covariance.error(bias.COVARIANCE_NAMES, ((P,), (Pxb, Pbb)), int(k),
                               "the bias filter", run, int(seeds[run]))


def adxl203_simulate(lib, n, excitation_values, sensor_values, estimator_values, Ts,
                     columns=COLUMNS):
    """:func:`driftfmu.models.adxl203.simulate` for one run (scalar seeds) in the kernel, the same
    defaults filled in; returns the ``columns`` asked for as ``(n,)`` arrays."""
    from driftfmu.models import adxl203, covariance, excitation, harmonic, parameters
    ex = dict(kind=excitation.GAUSSIAN, A=0.0, Q=0.01, x0=0.0, X=1.0, f=150.0, phi=0.0,
              Xy=0.0, phiy=0.0, seed=1)
    ex.update(excitation_values)
    sp = adxl203.sensor_parameters(**sensor_values)
    es = dict(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=0.01, estimator=1,
              process=harmonic.GAUSS_MARKOV, f=150.0, Qh=parameters.PARAMETERS["Qh"].default,
              a3=0.0, a4=0.0)
    es.update(estimator_values)
    vectors = [np.array([float(d[k]) for k in names])
               for d, names in ((ex, EXCITATION), (sp, SENSOR), (es, ESTIMATOR))]
    out = {c: np.empty(n) for c in columns}
    ptrs = _pointers([out.get(c) for c in COLUMNS])
    bad = np.zeros(4)
    status = lib.driftfmu_adxl203(n, float(Ts), *[v.ctypes.data for v in vectors], ptrs,
                                  bad.ctypes.data)
    if status == 2:  # models.harmonic.check's error, from the values the kernel met
        k, P, P12, P22 = bad.tolist()
        raise covariance.error(harmonic.COVARIANCE_NAMES, ((P,), (P12, P22)), int(k),
                               "the harmonic filter")
    if status:
        raise ValueError("estimator = %r, process = %r; allowed: estimator 1, 2 or 3 and "
                         "process %d or %d" % (es["estimator"], es["process"],
                                               harmonic.GAUSS_MARKOV, harmonic.HARMONIC))
    return out


def dual_simulate(lib, n, seeds, excitation_values, sensor_values, estimator_values, Ts,
                  record=()):
    """:func:`driftfmu.models.dualaxis.simulate` for ``len(seeds)`` runs in the kernel (run ``r``
    with both FMU seeds ``seeds[r]``), the same results as its batch form: ``final_<column>``,
    ``mean_xx``, ``mean_xy``, ``mean_yy``, each ``(runs,)``, and the ``record``-ed columns, each
    ``(runs, n)``.  None when a start value other than the seeds is an array (per run): the
    caller then uses the NumPy form."""
    from driftfmu.models import dualaxis
    ex = dualaxis.excitation_values(**excitation_values)
    sp = dualaxis.sensor_values(**sensor_values)
    es = dualaxis.estimator_values(**estimator_values)
    singles = [dualaxis.single_values(es, axis) for axis in (1, 2)]
    values = [(ex, DUAL_EXCITATION), (sp, DUAL_SENSOR), (es, DUAL_ESTIMATOR)] + \
        [(s1, SINGLE) for s1 in singles]
    if any(np.ndim(d[k]) for d, names in values for k in names):
        return None
    vectors = [np.array([float(d[k]) for k in names]) for d, names in values[:3]]
    vectors.append(np.array([float(s1[k]) for s1 in singles for k in SINGLE]))
    seeds = np.ascontiguousarray(seeds, dtype=np.uint64)
    runs = seeds.shape[0]
    cols = {c: np.empty((runs, n)) for c in record}
    finals = [np.empty(runs) for _ in range(len(dualaxis.COLUMNS) + 3)]
    bad = np.zeros(13)
    status = lib.driftfmu_dual(n, runs, seeds.ctypes.data, float(Ts),
                               *[v.ctypes.data for v in vectors],
                               _pointers([cols.get(c) for c in dualaxis.COLUMNS]),
                               _pointers(finals), bad.ctypes.data)
    if status == 2:  # models.dualaxis.simulate's error, from the values the kernel met
        raise _dual_error(bad, es["process"], seeds)
    if status:
        raise ValueError("estimator = %r, process = %r; allowed: estimator 1, 2 or 3 and "
                         "process %d or %d" % (es["estimator"], es["process"],
                                               dualaxis.GAUSS_MARKOV, dualaxis.HARMONIC))
    out = {"final_" + c: v for c, v in zip(dualaxis.COLUMNS, finals)}
    out.update(zip(("mean_xx", "mean_xy", "mean_yy"), finals[len(dualaxis.COLUMNS):]))
    out.update(cols)
    return out


def _dual_error(bad, process, seeds):
    """The CovarianceError of models.dualaxis.simulate (``check`` of the dual filter or
    ``harmonic.check`` of a single-axis one) from driftfmu_dual's ``bad``: (sample, filter, run,
    the covariance's lower triangle packed by rows)."""
    from driftfmu.models import covariance, dualaxis, harmonic
    k, which, run = int(bad[0]), int(bad[1]), int(bad[2])
    if which == 0:
        names, what = dualaxis.COVARIANCE_NAMES[int(process)], "the dual-axis filter"
    else:
        names, what = harmonic.COVARIANCE_NAMES, "the harmonic filter"
    packed = iter(bad[3:].tolist())
    lower = [[next(packed) for _ in row] for row in names]
    return covariance.error(names, lower, k, what, run, int(seeds[run]))
