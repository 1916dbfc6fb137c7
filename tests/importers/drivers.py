"""Drive the FMUs from independent FMI importers: JavaFMI (JVM), libcosim (C++, via libcosimpy),
and the SSP hosts OMSimulator (OpenModelica's command line) and ecos (C++, via ecospy).

Both are installed from the package registries: JavaFMI from Maven Central by the Maven project
in ``javafmi/`` (``org.siani.javafmi:fmu-wrapper``), libcosim from PyPI (``libcosimpy``, which
bundles libcosimc and the FMI Library).  Neither uses fmpy.

The JVM host runs in a child process with libpython's directory on ``LD_LIBRARY_PATH`` (what
the README tells users) and without ``LD_PRELOAD``: the FMUs' loader shim must find libpython
by itself.
"""
import os
import shutil
import subprocess
import sysconfig
from pathlib import Path


HERE = Path(__file__).resolve().parent
JAVAFMI_DIR = HERE / "javafmi"
#: JavaFMI's unzipper sets file permissions through java.util.prefs by reflection.
JVM_FLAGS = ("--add-opens", "java.prefs/java.util.prefs=ALL-UNNAMED")


class ImporterMissing(RuntimeError):
    """The toolchain of an importer is not installed; the message says what to install."""


# -- JavaFMI ---------------------------------------------------------------------------------
def java_toolchain():
    """Paths of ``java`` and ``mvn``; raises ImporterMissing naming what is absent."""
    missing = [t for t in ("java", "mvn") if shutil.which(t) is None]
    if missing:
        raise ImporterMissing(
            "%s not found: install a JDK >= 11 and Maven (Debian: apt-get install "
            "default-jdk-headless maven) to run the JavaFMI importer" % " and ".join(missing))
    return shutil.which("java"), shutil.which("mvn")


def build_javafmi_host():
    """Compile the JavaFMI host with Maven (dependencies from Maven Central); return its class
    path.  Maven's local repository caches the download; the build is skipped when the classes
    are newer than the sources."""
    _, mvn = java_toolchain()
    target = JAVAFMI_DIR / "target"
    cls = target / "classes" / "driftfmu" / "ChainHost.class"
    sources = [JAVAFMI_DIR / "pom.xml"] + list((JAVAFMI_DIR / "src").rglob("*.java"))
    lib = target / "lib"
    if not (cls.is_file() and lib.is_dir()
            and cls.stat().st_mtime >= max(s.stat().st_mtime for s in sources)):
        proc = subprocess.run([mvn, "-q", "-B", "package"], cwd=JAVAFMI_DIR,
                              capture_output=True, text=True)
        if proc.returncode:
            raise RuntimeError("mvn package of the JavaFMI host failed:\n%s%s"
                               % (proc.stdout[-4000:], proc.stderr[-4000:]))
    return os.pathsep.join([str(target / "classes"), str(lib / "*")])


def host_env():
    """Environment of a non-Python host: libpython's directory on LD_LIBRARY_PATH, no
    LD_PRELOAD."""
    env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
    libdir = sysconfig.get_config_var("LIBDIR")
    env["LD_LIBRARY_PATH"] = os.pathsep.join(
        p for p in (libdir, env.get("LD_LIBRARY_PATH")) if p)
    return env


def run_javafmi(classpath, workdir, fmus, steps, step, start=None, connections=(),
                inputs=None, record=None, order="set-read"):
    """Run FMUs in the JavaFMI host; return ``{"time": [...], "<fmu>.<var>": [...]}`` and the
    host's summary line.

    ``fmus`` maps instance name -> path (stepped in that order); ``start`` instance ->
    {variable: value} (ints are set as Integer); ``connections`` (src, out, dst, in) are copied
    in order at every point; ``inputs`` (instance, variable) -> list of values, one per point;
    ``record`` instance -> variables.  ``order`` is ``"set-read"`` (our master's timing) or
    ``"read-set"`` (the cross-check importers' timing, see fmu_src/crosscheck.py).
    """
    java, _ = java_toolchain()
    workdir = Path(workdir)
    lines = ["fmu %s %s" % (n, Path(p).resolve()) for n, p in fmus.items()]
    for name, values in (start or {}).items():
        for var, value in values.items():
            kind = "integer" if isinstance(value, int) and not isinstance(value, bool) else "real"
            lines.append("start %s %s %s %r" % (name, var, kind, value))
    lines += ["connect %s %s %s %s" % c for c in connections]
    for (name, var), values in (inputs or {}).items():
        lines.append("input %s %s %s" % (name, var, " ".join(repr(float(v)) for v in values)))
    lines += ["record %s %s" % (name, var) for name, names in (record or {}).items()
              for var in names]
    lines += ["steps %d" % steps, "step %r" % step, "order %s" % order]
    spec = workdir / "javafmi_spec.txt"
    spec.write_text("\n".join(lines) + "\n")
    out = workdir / "javafmi_out.csv"
    proc = subprocess.run([java, *JVM_FLAGS, "-cp", classpath, "driftfmu.ChainHost", str(spec),
                           str(out)], capture_output=True, text=True, env=host_env(),
                          timeout=600)
    if proc.returncode:
        raise RuntimeError("JavaFMI host failed (exit %d):\n%s%s"
                           % (proc.returncode, proc.stdout[-4000:], proc.stderr[-4000:]))
    from driftfmu.fmu_src.crosscheck import read_csv
    return read_csv(out), proc.stdout.strip().splitlines()[-1]


# -- libcosim (libcosimpy) --------------------------------------------------------------------
def libcosim():
    """The libcosimpy modules; raises ImporterMissing when libcosimpy is not installed."""
    try:
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimManipulator import CosimManipulator
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave
    except ImportError as exc:
        raise ImporterMissing("libcosimpy is not installed (pip install libcosimpy): %s" % exc)
    return CosimExecution, CosimManipulator, CosimObserver, CosimLocalSlave


def run_libcosim(fmu, name, steps, step, inputs=None, record=(), lookahead=False):
    """Run one FMU in libcosim's fixed-step algorithm; return ``{"time", <var>: [...]}``.

    libcosim sets an FMU's inputs before ``fmi2DoStep`` and reads its outputs right after it,
    before the inputs of the new point are set: row 0 is read after initialisation with the
    inputs of ``t_0`` (initial values), row ``k > 0`` after the step from ``t_{k-1}``.  With
    ``lookahead=False`` the step from ``t_{k-1}`` gets the inputs of ``t_{k-1}`` (the
    cross-check timing); with ``lookahead=True`` it gets those of ``t_k``, so an FMU without
    memory is read exactly at the inputs of ``t_k`` (our master's timing).
    """
    from fmpy import read_model_description

    CosimExecution, CosimManipulator, CosimObserver, CosimLocalSlave = libcosim()
    md = read_model_description(str(fmu))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    ns = int(round(step * 1e9))
    ex = CosimExecution.from_step_size(ns)
    idx = ex.add_local_slave(CosimLocalSlave(fmu_path=str(Path(fmu).resolve()),
                                             instance_name=name))
    inputs = inputs or {}
    for var, values in inputs.items():
        ex.real_initial_value(idx, vrs[var], float(values[0]))
    observer = CosimObserver.create_time_series(buffer_size=steps + 10)
    ex.add_observer(observer)
    for var in record:
        observer.start_time_series(idx, vrs[var], _real_type())
    manipulator = CosimManipulator.create_override()
    ex.add_manipulator(manipulator)
    for k in range(1, steps):
        if inputs:
            j = k if lookahead else k - 1
            manipulator.slave_real_values(idx, [vrs[v] for v in inputs],
                                          [float(values[j]) for values in inputs.values()])
        if not ex.step(1):
            raise RuntimeError("libcosim step %d of %s failed: %s" % (k, name, ex.status()))
    cols = {}
    for var in record:
        # libcosimpy trims its result at the number of zero step numbers, which drops one
        # sample when step 0 (the initial values) is included: read step 0 on its own
        t0, _, v0 = observer.time_series_real_samples(idx, vrs[var], from_step=0,
                                                      sample_count=2)
        times, _, values = observer.time_series_real_samples(idx, vrs[var], from_step=1,
                                                             sample_count=steps - 1)
        times, values = t0[:1] + list(times), v0[:1] + list(values)
        if len(values) != steps:
            raise RuntimeError("libcosim recorded %d of %d samples of %s.%s"
                               % (len(values), steps, name, var))
        cols[var] = [float(v) for v in values]
        cols["time"] = [t * 1e-9 for t in times]
    return cols



def run_libcosim_ssp(ssp, workdir, steps, step, record):
    """Load an SSP archive with libcosim's own SSP parser (connections and parameter bindings
    from the SSD) and run it; return ``{"<Component>.<var>": [...]}`` for the rows after the
    steps from ``t_0 .. t_{steps-1}`` (rows as fmpy's ``simulate_ssp`` labels them)."""
    import zipfile
    from fmpy import read_model_description

    CosimExecution, _, CosimObserver, _ = libcosim()
    unpacked = Path(workdir) / "ssp"
    with zipfile.ZipFile(ssp) as z:
        z.extractall(unpacked)
    ex = CosimExecution.from_ssp_file(str(unpacked), step_size=int(round(step * 1e9)))
    index = {i.name.decode(): i.index for i in ex.slave_infos()}
    observer = CosimObserver.create_time_series(buffer_size=steps + 10)
    ex.add_observer(observer)
    vrs = {}
    for name, names in record.items():
        md = read_model_description(str(unpacked / "resources" / ("%s.fmu" % name)))
        refs = {v.name: v.valueReference for v in md.modelVariables}
        for var in names:
            vrs[name, var] = refs[var]
            observer.start_time_series(index[name], refs[var], _real_type())
    if not ex.step(steps):
        raise RuntimeError("libcosim failed to step %s: %s" % (ssp, ex.status()))
    cols = {}
    for (name, var), vr in vrs.items():
        _, _, values = observer.time_series_real_samples(index[name], vr, from_step=1,
                                                         sample_count=steps)
        if len(values) != steps:
            raise RuntimeError("libcosim recorded %d of %d samples of %s.%s"
                               % (len(values), steps, name, var))
        cols["%s.%s" % (name, var)] = [float(v) for v in values]
    return cols

def _real_type():
    from libcosimpy.CosimEnums import CosimVariableType
    return CosimVariableType.REAL


# -- OMSimulator (OpenModelica's co-simulation engine, its command line) ----------------------
#: The environment variable that names the OMSimulator executable (else it is looked up on PATH).
OMSIMULATOR_ENV = "DRIFTFMU_OMSIMULATOR"


def omsimulator():
    """The OMSimulator executable: ``$DRIFTFMU_OMSIMULATOR``, else ``OMSimulator`` on PATH;
    raises ImporterMissing saying where to get it."""
    path = os.environ.get(OMSIMULATOR_ENV) or shutil.which("OMSimulator")
    if not path or not os.access(path, os.X_OK):
        raise ImporterMissing(
            "OMSimulator not found (%s): put OMSimulator's bin/ on PATH or set %s to the "
            "OMSimulator executable; get it with OpenModelica's installers or build it from "
            "its repository (docs/development.md)" % (
                "%s=%s is not an executable" % (OMSIMULATOR_ENV, path) if path else
                "not on PATH and %s not set" % OMSIMULATOR_ENV, OMSIMULATOR_ENV))
    return path


def run_omsimulator_ssp(ssp, workdir, stop_time, result_file):
    """``OMSimulator --stopTime=<stop_time> <ssp>`` in ``workdir`` (the result file the archive
    names, ``result_file``, and OMSimulator's temporary folders go there); return ``(proc,
    columns)``: the finished process and the result's ``{"time", "<Component>.<var>": numpy
    array}`` with one row per communication point (OMSimulator records every point twice,
    before and after it copies the outputs along the connections: the second, our master's
    timing, is kept), None when there is no result file."""
    import numpy as np
    exe = omsimulator()
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    result = workdir / result_file
    proc = subprocess.run([exe, "--stopTime=%r" % stop_time, str(Path(ssp).resolve())],
                          cwd=workdir, capture_output=True, text=True, timeout=600)
    if proc.returncode or not result.is_file():
        return proc, None
    raw = read_oms_mat(result)
    time = raw["time"]
    last = {}
    for i, t in enumerate(time):
        last[t] = i                  # the last row of each time point
    rows = np.array(sorted(last.values()))
    cols = {"time": time[rows]}
    for name, values in raw.items():
        parts = name.split(".")      # <model>.<system>.<Component>.<var>
        if len(parts) == 4:
            cols["%s.%s" % (parts[2], parts[3])] = values[rows]
    return proc, cols


def read_oms_mat(path):
    """The signals of an OpenModelica result file (MAT v4, ``Aclass`` ``binTrans``): name ->
    numpy array over the rows of ``data_2`` (parameters, from ``data_1``, repeated)."""
    import numpy as np
    import scipy.io
    m = scipy.io.loadmat(str(path))
    chars = [str(row) for row in m["name"]]          # transposed: one name per column
    width = max(len(row) for row in chars)
    chars = [row.ljust(width) for row in chars]
    names = ["".join(row[j] for row in chars).strip().strip("\x00") for j in range(width)]
    info = m["dataInfo"]
    rows = m["data_2"].shape[1]
    out = {}
    for j, name in enumerate(names):
        table, column = int(info[0, j]), int(info[1, j])
        data = m["data_1"] if table == 1 else m["data_2"]
        values = np.sign(column) * data[abs(column) - 1, :] if column else data[0, :]
        out[name] = values if table != 1 else np.full(rows, values[0])
    return out


# -- ecos (ecospy) ----------------------------------------------------------------------------
def ecos():
    """ecospy's EcosSimulation; raises ImporterMissing when it cannot be imported."""
    try:
        from ecospy import EcosSimulation
    except ImportError as exc:  # (OSError: its library needs libtbb.so.12)
        raise ImporterMissing("ecospy is not installed (pip install ecospy): %s" % exc)
    except OSError as exc:
        raise ImporterMissing("ecospy's library does not load (Debian: apt-get install "
                              "libtbb12): %s" % exc)
    return EcosSimulation


def run_ecos_ssp(ssp, steps, step, parameter_set, record):
    """Load an SSP archive with ecos' own SSP parser, initialise it with the named
    ``parameter_set`` (ecos applies one), step it ``steps`` times and read ``record``
    (component -> variables) after each step; return ``{"<Component>.<var>": [...]}`` and
    whether ``init`` succeeded."""
    EcosSimulation = ecos()
    sim = EcosSimulation(ssp_path=str(ssp), step_size=step)
    cols = {"%s.%s" % (c, v): [] for c, names in record.items() for v in names}
    try:
        if not sim.init(0.0, parameter_set):
            return cols, False
        for _ in range(steps):
            sim.step()
            for c, names in record.items():
                for v in names:
                    cols["%s.%s" % (c, v)].append(sim.get_real("%s::%s" % (c, v)))
        sim.terminate()
    finally:
        sim.free()
    return cols, True
