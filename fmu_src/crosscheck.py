"""Internal (not a stable API; use driftfmu.build_fmus instead).

FMI cross-check artifacts for the three FMUs, in the layout of the FMI cross-check rules.

For each FMU ``<Model>`` the folder ``fmus/2.0/cs/linux64/driftfmu/<version>/<Model>/`` holds
(https://github.com/modelica/fmi-cross-check, README "Add FMUs"); the native (C) FMUs get a
folder per FMI version and platform they carry a binary for,
``fmus/2.0/cs/{linux64,win64}/...`` and ``fmus/3.0/cs/{x86_64-linux,x86_64-windows}/...``, each
with the same files (the reference is computed on this machine; the Windows binary gives the
same bits, tests/test_native.py).  Only the platforms whose binaries the tests run on this
machine's kind of processor get a folder (:data:`RUN_PLATFORMS`); the macOS and ARM binaries of
the native FMUs are cross-built and not run here, so no cross-check result is claimed for them:

``<Model>.fmu``
    the FMU as built;
``<Model>_in.csv``
    the input signals (Accelerometer: ``x``, DriftEstimator: ``z``), taken from the wired chain
    of our fmpy master, one row per sample, and the inputs the chain does not wire at their
    start values (the Excitation's ``u_in``, the DriftEstimator's ``u``: 0);
``<Model>_ref.csv``
    the reference result: ``fmpy.simulate_fmu`` with the FMU's default parameters, the input
    file and the options below;
``<Model>_ref.opt``
    ``StartTime``, ``StopTime``, ``StepSize`` and ``RelTol``;
``ReadMe.txt``
    what the FMU computes, how the reference was made and the comparison tolerance.

Timing, which an importer must follow to reproduce the reference (it is what fmpy's
``simulate_fmu`` and the cross-check importers do): at ``t_0`` the inputs of ``t_0`` are set and
the outputs read; then, for each step, the FMU steps from ``t_k`` with the inputs of ``t_k``,
the outputs are read at ``t_{k+1}``, and only then are the inputs of ``t_{k+1}`` set.  The
outputs that depend on an input (Accelerometer ``z``, all DriftEstimator outputs) are therefore
read with the previous input still applied (zero-order hold): row ``k > 0`` of
``Accelerometer_ref.csv`` is ``z = h(x_k) + sqrt(R) v_{k+1}``, the measurement of sample ``k + 1``
of the input held from ``t_k``.  :func:`held_input_reference` computes every reference column
from models/ for this timing, so the references are checked, not just recorded.

The model is discrete and deterministic: an importer that follows the timing reproduces the
reference to rounding, and :data:`TOLERANCE` is stated in every ReadMe.
"""
import csv
import importlib
import shutil
from pathlib import Path

from driftfmu.models import chain, drift, sensor
from driftfmu.models.parameters import PARAMETERS

#: Tool ID and version in the cross-check tree.
TOOL_ID = "driftfmu"
#: Absolute tolerance stated in the ReadMe files and used to re-verify the references.
TOLERANCE = 1e-12
#: Relative tolerance written to the options files (passed to fmi2SetupExperiment; the FMUs
#: are discrete-time and do not use it).
REL_TOL = 1e-6
#: Samples in each reference run.
N_SAMPLES = 200
FMU_NAMES = ("Excitation", "Accelerometer", "DriftEstimator")
#: Input and output columns of each FMU in the cross-check files.
INPUTS = {"Excitation": (), "Accelerometer": ("x",), "DriftEstimator": ("z",)}
OUTPUTS = {"Excitation": ("x",), "Accelerometer": ("z",),
           "DriftEstimator": ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp")}
#: The FMU's default estimator (DriftEstimator.estimator), whose drift feeds dc and z_comp.
DEFAULT_ESTIMATOR = 1


#: The binary folders a cross-check result is written for: x86-64 Linux (run here) and Windows
#: (run under wine, the same bits).
RUN_PLATFORMS = ("linux64", "win64", "x86_64-linux", "x86_64-windows")


def model_dir(root, name, version, fmi_version=2, platform="linux64"):
    """``root/fmus/<fmi_version>.0/cs/<platform>/driftfmu/<version>/<name>``."""
    return (Path(root) / "fmus" / ("%d.0" % fmi_version) / "cs" / platform / TOOL_ID / version
            / name)


def fmu_platforms(fmu):
    """The binary folders of an FMU (``linux64``, ``win64``, ``x86_64-linux``, ...)."""
    import zipfile
    with zipfile.ZipFile(fmu) as archive:
        return sorted({n.split("/")[1] for n in archive.namelist()
                       if n.startswith("binaries/") and n.count("/") >= 2 and n.split("/")[1]})


def defaults():
    """The FMUs' default parameter values (models.parameters), by name."""
    return {name: p.default for name, p in PARAMETERS.items()}


def chain_columns(n=N_SAMPLES):
    """``x`` and ``z`` of the wired chain at the FMUs' defaults, from models/ (``time`` too).

    The gaussian master reproduces these to 1e-12 (tests/test_gaussian.py), so they are the
    inputs our fmpy master feeds the Accelerometer and the DriftEstimator.
    """
    p = defaults()
    return chain.simulate(n, p["seed"], a0=p["a0"], a1=p["a1"], a2=p["a2"], A=p["A"],
                          Q=p["Q"], R=p["R"], x0=p["x0"], P0=p["P0"], Ts=p["Ts"],
                          estimator=DEFAULT_ESTIMATOR)


def held_input_reference(name, inputs, n=None):
    """The outputs of FMU ``name`` under the cross-check timing, computed from models/.

    Parameters
    ----------
    name : str
        ``"Excitation"``, ``"Accelerometer"`` or ``"DriftEstimator"`` (default parameters).
    inputs : dict
        Input name -> list of values at ``t_0, t_1, ...`` (as in ``<name>_in.csv``).
    n : int, optional
        Number of rows (default: the length of the input).

    Returns
    -------
    dict
        ``time`` and the output columns.  Row 0 is read after the inputs of ``t_0`` are set;
        row ``k > 0`` after the step from ``t_{k-1}`` with the inputs of ``t_{k-1}`` held.
    """
    p = defaults()
    if n is None:
        n = len(next(iter(inputs.values()))) if inputs else N_SAMPLES
    cols = {"time": [i * p["Ts"] for i in range(n)]}
    if name == "Excitation":
        cols["x"] = chain_columns(n)["x"]
        return cols
    if name == "Accelerometer":
        x = inputs["x"]
        # the measurement of sample k + 1 of the input applied at row k - 1 (row 0: sample 1)
        cols["z"] = [sensor.measure(x[max(k - 1, 0)], p["a0"], p["a1"], p["a2"], p["R"],
                                    sensor.measurement_noise(p["seed"], k + 1))
                     for k in range(n)]
        return cols
    if name == "DriftEstimator":
        z = inputs["z"]
        out = {c: [] for c in OUTPUTS[name]}
        committed = chain.estimator_init(p["x0"], p["P0"])
        for k in range(n):
            u = z[max(k - 1, 0)]          # the input applied at the previous point (row 0: z_0)
            if k > 0:                      # the step from t_{k-1} commits sample k with it
                committed = chain.estimator_step(committed, u, p["a0"], p["a1"], p["a2"],
                                                 p["A"], p["Q"], p["R"])
            shown = chain.estimator_step(committed, u, p["a0"], p["a1"], p["a2"], p["A"],
                                         p["Q"], p["R"])
            dcs = drift.estimates(shown.drift, p["a2"])
            dc = drift.select(dcs, DEFAULT_ESTIMATOR)
            for c, v in zip(OUTPUTS[name], (shown.x, shown.P) + tuple(dcs)
                            + (dc, chain.compensate(u, dc))):
                out[c].append(v)
        cols.update(out)
        return cols
    raise ValueError("no cross-check reference for FMU %r; allowed: %s"
                     % (name, ", ".join(FMU_NAMES)))



def write_csv(path, cols, names):
    """CSV in the cross-check format: header row, ``time`` first, values with ``repr``."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(names)
        for row in zip(*(cols[c] for c in names)):
            w.writerow([repr(float(v)) for v in row])


def read_csv(path):
    """A cross-check CSV as ``{column: list of floats}``, columns in file order."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    names = [n.strip('"') for n in rows[0]]
    return {n: [float(r[i]) for r in rows[1:]] for i, n in enumerate(names)}


def max_abs_diff(result, reference, names):
    """Largest absolute difference per column (``inf`` when the lengths differ)."""
    diffs = {}
    for c in names:
        a, b = result[c], reference[c]
        diffs[c] = max(abs(x - y) for x, y in zip(a, b)) if len(a) == len(b) else float("inf")
    return diffs


def other_inputs(fmu, name):
    """Inputs of ``fmu`` outside :data:`INPUTS` (not wired in the chain): name -> start value."""
    from driftfmu.fmu_src.schemas import read_model_description
    md = read_model_description(str(fmu))
    return {v.name: float(v.start or 0.0) for v in md.modelVariables
            if v.causality == "input" and v.name not in INPUTS[name]}


def simulate_reference(fmu, name, inputs, n, Ts):
    """Run ``fmu`` with ``fmpy.simulate_fmu`` under the cross-check options; return columns."""
    import numpy as np
    from fmpy import simulate_fmu

    signals = None
    if inputs:
        dtype = [("time", np.float64)] + [(c, np.float64) for c in inputs]
        signals = np.array([tuple([i * Ts] + [inputs[c][i] for c in inputs])
                            for i in range(n)], dtype=dtype)
    res = simulate_fmu(str(fmu), start_time=0.0, stop_time=(n - 1) * Ts, output_interval=Ts,
                       relative_tolerance=REL_TOL, input=signals, output=list(OUTPUTS[name]))
    return {c: [float(v) for v in res[c]] for c in res.dtype.names}


README = """\
{name}.fmu: {doc}

Exported by driftfmu {version} {kind}

Files
  {name}.fmu
                   the FMU, FMI {fmi}.0 co-simulation, default parameters (the letter's Sec. III)
  {name}_in.csv
                   {inputs}
  {name}_ref.csv
                   reference result: fmpy {fmpy} simulate_fmu with the input file and the
                   options file, default parameters, outputs {outputs}
  {name}_ref.opt
                   StartTime, StopTime, StepSize (= the sample period Ts), RelTol (unused:
                   the model is discrete-time)

Timing
  At t_0 the inputs of t_0 are set and the outputs read.  Each step goes from t_k to t_k + Ts
  with the inputs of t_k; the outputs are read at t_(k+1) before the inputs of t_(k+1) are set.
  {timing}

Comparison
  The model is discrete and deterministic: every output of an importer that follows the timing
  above must equal the reference to an absolute tolerance of {tol:g} (no tube or resampling
  needed).  The reference itself equals the models/ computation of the project to {tol:g}.
"""

TIMING = {
    "Excitation": "Its one input, u_in (the host's known input, used when drive = 0), is 0 "
                  "here:\n  row k is the Gauss-Markov sample x_(k+1).",
    "Accelerometer": "z depends on x directly, so row k > 0 is the measurement of sample k+1 "
                     "of the\n  input held from t_(k-1): z = a0 + a1 x + a2 x^2 + sqrt(R) "
                     "v_(k+1) with x from row k-1 of the input.",
    "DriftEstimator": "Every output depends on z directly.  The step from t_k commits the "
                      "EKF update of\n  sample k+1 with z(t_k); the outputs read at t_(k+1) "
                      "are the next update computed\n  with z(t_k) still applied (zero-order "
                      "hold), replaced when z(t_(k+1)) is set.",
}


#: How each backend's FMU is made, for the ReadMe.
KIND = {
    "python": "(pythonfmu 0.7.0 slave, C loader shim as\nbinaries/linux64/{name}.so; libpython 3 "
              "must be loadable, e.g. on the library path).",
    "native": "(native C twin of the pythonfmu FMU, FMI {fmi}.0, the same bits;\n"
              "needs nothing but the C runtime; also a source FMU: sources/).",
}


def write_cross_check(fmus, out_dir="build/cross-check", n=N_SAMPLES, version=None,
                      fmi_version=2, backend="python"):
    """Write the cross-check folders of the three FMUs under ``out_dir``.

    Parameters
    ----------
    fmus : dict
        FMU name -> path of the built ``.fmu``.
    out_dir : path
        Root of the tree (``fmus/2.0/cs/linux64/driftfmu/<version>/<Model>/``).
    n : int
        Samples in each reference run.
    version : str, optional
        Tool version in the tree (default: the FMUs' version).
    fmi_version : int
        FMI version of the FMUs (2 or 3): the tree's ``2.0`` or ``3.0`` folder.
    backend : str
        ``"python"`` (one folder, linux64) or ``"native"`` (one folder per binary platform of
        the FMU).

    Returns
    -------
    list of Path
        The model folders written.

    Raises
    ------
    RuntimeError
        A reference from fmpy differs from the models/ computation by more than
        :data:`TOLERANCE` (nothing is left half-written for that model).
    """
    import fmpy
    from driftfmu import __version__

    version = version or __version__
    Ts = defaults()["Ts"]
    master = chain_columns(n)
    written = []
    for name in FMU_NAMES:
        platforms = ["linux64"] if backend == "python" else [
            p for p in fmu_platforms(fmus[name]) if p in RUN_PLATFORMS]
        folders = [model_dir(out_dir, name, version, fmi_version, p) for p in platforms]
        d = folders[0]
        for folder in folders:
            if folder.exists():
                shutil.rmtree(folder)
        d.mkdir(parents=True)
        inputs = {c: master[c] for c in INPUTS[name]}
        for c, start in other_inputs(fmus[name], name).items():
            inputs[c] = [start] * n
        ref = simulate_reference(fmus[name], name, inputs, n, Ts)
        expected = held_input_reference(name, inputs, n)
        diffs = max_abs_diff(ref, expected, ("time",) + OUTPUTS[name])
        bad = {c: v for c, v in diffs.items() if not v <= TOLERANCE}
        if bad:
            shutil.rmtree(d)
            raise RuntimeError("cross-check reference of %s differs from models/: %s"
                               % (name, ", ".join("%s by %.3g" % kv for kv in bad.items())))
        shutil.copyfile(fmus[name], d / ("%s.fmu" % name))
        if inputs:
            write_csv(d / ("%s_in.csv" % name), dict(inputs, time=master["time"]),
                      ("time",) + tuple(inputs))
        write_csv(d / ("%s_ref.csv" % name), ref, ("time",) + OUTPUTS[name])
        (d / ("%s_ref.opt" % name)).write_text(
            "StartTime,%r\nStopTime,%r\nStepSize,%r\nRelTol,%r\n"
            % (0.0, (n - 1) * Ts, Ts, REL_TOL))
        doc = getattr(importlib.import_module("driftfmu.fmu_src.%s" % name), name).__doc__.strip()
        (d / "ReadMe.txt").write_text(README.format(
            name=name, doc=doc.splitlines()[0], version=version, fmpy=fmpy.__version__,
            inputs=("input %s per sample, from the wired chain Excitation -> Accelerometer ->\n"
                    "                   DriftEstimator%s" % (", ".join(INPUTS[name]), "; "
                    + ", ".join(sorted(set(inputs) - set(INPUTS[name]))) + " (not wired) at "
                    "its start value" if set(inputs) - set(INPUTS[name]) else "")) if inputs
            else "(none: the FMU has no inputs)",
            outputs=", ".join(OUTPUTS[name]), timing=TIMING[name], tol=TOLERANCE,
            kind=KIND[backend].format(name=name, fmi=fmi_version), fmi=fmi_version))
        written.append(d)
        for folder in folders[1:]:
            shutil.copytree(d, folder)
            written.append(folder)
    return written
