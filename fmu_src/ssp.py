"""Internal (not a stable API; use driftfmu.build_fmus instead).

The wired chain Excitation -> Accelerometer -> DriftEstimator as an SSP 1.0 archive.

``DriftChain.ssp`` holds ``SystemStructure.ssd`` and the three FMUs under ``resources/``.  The
SSD declares each FMU's outputs, its connected inputs and its bound parameters as connectors
(unconnected inputs get no connector: they keep their start values, or the values bound to
them, as the Accelerometer's tilt ``theta`` and temperature ``T`` with its slow errors, bound
with the same values at the DriftEstimator's inputs of the same name), the two
connections of the master (``Excitation.x -> Accelerometer.x``, ``Accelerometer.z ->
DriftEstimator.z``) and, when the DriftEstimator's ``B != 0``, the known input's
``Excitation.u -> DriftEstimator.u`` (eq. 1, :func:`connections`), each component's parameter
values as an SSP parameter set of its own, ``resources/<Component>.ssv`` (SSV 1.0), which the
component's ``ssd:ParameterBindings`` references: the letter's Gaussian run with the user's
values over it (:func:`parameter_values`; every set has the system's name, so ecos, which
applies one named set per run, applies all of them with ``init(0, "DriftChain")``), and the
default experiment (``ssd:DefaultExperiment``: ``startTime = 0``, ``stopTime = (n - 1) Ts``).
SSP has no standard element for the communication step: use ``Ts`` (the ``description`` of the
system says so).  OpenModelica's vendor annotation (:func:`_oms_annotation`) gives it to
OMSimulator (``oms:FixedStepMaster stepSize``), whose importer needs it to make the system at
all.

OMSimulator's fixed-step master (``oms-ma``) steps every FMU, then copies the outputs along the
connections in their order (Gauss-Seidel at the communication point, as our master) and records
each point before and after that copy: its second row of each point is our master's row, bit for
bit (tests/test_ssp.py).  Its command line takes the stop time from ``--stopTime`` (default
1 s), not from the default experiment.

Stepping in an SSP master.  fmpy's ``fmpy.ssp.simulation.simulate_ssp`` (like libcosim's and
Ecos' fixed-step algorithms) is a Jacobi master: every FMU is stepped with the inputs copied at
the previous point, its outputs are read right after its step, and only then are outputs copied
along the connections.  Each connection therefore delays its signal by one communication step
(zero-order hold), which our own master avoids by copying outputs along the connections in
order at each point (simulations/cosim.py).  For this chain the delay is not a plain shift of
our master's rows: the sensor's noise follows the FMU's own sample counter while its input
arrives one step late.  Row ``i`` of ``simulate_ssp`` (time label ``t_i``; the values are those
after the step from ``t_i``) holds exactly, with ``x_k`` and ``v_k`` the excitation and
measurement-noise samples of our master:

* ``Excitation.x = x_{i+2}`` (our master's row ``i + 1``);
* ``Accelerometer.z = a0 + a1 u + a2 u^2 + sqrt(R) v_{i+2}`` with ``u = x_{i+1}`` (``u = 0``,
  the connectors' initial value, in row 0);
* the DriftEstimator has been updated with the measurements ``0, z~_0, z~_1, ...`` (``z~_i`` the
  Accelerometer's row ``i``), one row late, and shows the next update with the last one held.

:func:`jacobi_reference` computes these rows from models/; tests/test_ssp.py checks
``simulate_ssp`` against it to 1e-12 and the ``x`` column against our master's rows shifted by
one.  libcosim's own SSP loader (libcosimpy ``CosimExecution.from_ssp_file`` on the unpacked
archive) applies the parameter bindings and gives the same rows except that it copies the
outputs read after initialisation along the connections before the first step
(``jacobi_reference(..., initial="outputs")``).  To get our master's results from the same FMUs, run ``driftfmu run gaussian`` (or any
master that propagates outputs along the connections in order before reading them).
"""
import contextlib
import os
import shutil
import tempfile
import threading
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

from driftfmu.models import chain, drift, excitation, sensor
from driftfmu.simulations.gaussian import GENERAL_OFF, INPUT_CONNECTION
from driftfmu.simulations.gaussian import start_values as chain_start_values

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    # OpenModelica's vendor annotation (OMSimulator's importer reads the prefixed names)
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
#: The ``type`` of OpenModelica's vendor annotation (``ssc:Annotation``).
OMS_ANNOTATION = "org.openmodelica"
#: OMSimulator's relative tolerance in the annotation (its default; our FMUs are discrete-time
#: and do not use it).
OMS_TOLERANCE = 1e-4
#: The result file OMSimulator writes (its own default name; MAT keeps every double whole).
OMS_RESULT_FILE = "DriftChain_res.mat"
#: Rows OMSimulator buffers before it writes them (its own default).
OMS_BUFFER_SIZE = 10
SYSTEM = "DriftChain"
FMU_NAMES = ("Excitation", "Accelerometer", "DriftEstimator")
CONNECTIONS = (("Excitation", "x", "Accelerometer", "x"),
               ("Accelerometer", "z", "DriftEstimator", "z"))
DRIFT_OUTPUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp")



def connections(start_values):
    """The archive's connections: :data:`CONNECTIONS`, and the known input's
    (``Excitation.u -> DriftEstimator.u``) when ``start_values`` give the DriftEstimator a
    ``B != 0``."""
    B = start_values.get("DriftEstimator", {}).get("B", 0.0)
    return CONNECTIONS + ((INPUT_CONNECTION,) if B != 0.0 else ())


for _prefix, _uri in NS.items():
    ET.register_namespace(_prefix, _uri)


def _q(prefix, tag):
    return "{%s}%s" % (NS[prefix], tag)


def system_structure(fmus, start_values, n, Ts):
    """The ``SystemStructure.ssd`` element tree of the chain."""
    from driftfmu.fmu_src.schemas import read_model_description

    root = ET.Element(_q("ssd", "SystemStructureDescription"),
                      {"version": "1.0", "name": SYSTEM})
    system = ET.SubElement(root, _q("ssd", "System"), {
        "name": SYSTEM,
        "description": "Excitation -> Accelerometer -> DriftEstimator (Chorti et al. 2006), "
                       "fixed communication step Ts = %r s" % Ts})
    elements = ET.SubElement(system, _q("ssd", "Elements"))
    wiring = connections(start_values)
    wired = {(d, i) for _, _, d, i in wiring}
    for name in FMU_NAMES:
        md = read_model_description(str(fmus[name]))
        starts = start_values.get(name, {})
        comp = ET.SubElement(elements, _q("ssd", "Component"), {
            "name": name, "type": "application/x-fmu-sharedlibrary",
            "source": "resources/%s.fmu" % name})
        connectors = ET.SubElement(comp, _q("ssd", "Connectors"))
        for v in md.modelVariables:
            # an input no connection feeds gets no connector, bound or not (the tilt and the
            # temperature): fmpy (0.3.32) would wire it to the source of the previous input
            # (get_connections keeps a stale start path)
            if v.causality == "output" or (name, v.name) in wired or (
                    v.name in starts and v.causality != "input"):
                c = ET.SubElement(connectors, _q("ssd", "Connector"),
                                  {"name": v.name, "kind": v.causality})
                ET.SubElement(c, _q("ssc", v.type))
        if starts:  # the component's parameter set, in resources/<name>.ssv
            ET.SubElement(ET.SubElement(comp, _q("ssd", "ParameterBindings")),
                          _q("ssd", "ParameterBinding"), {"source": ssv_path(name)})
    conns = ET.SubElement(system, _q("ssd", "Connections"))
    for s, o, d, i in wiring:
        ET.SubElement(conns, _q("ssd", "Connection"), {
            "startElement": s, "startConnector": o, "endElement": d, "endConnector": i})
    _oms_annotation(system, {"FixedStepMaster": {
        "description": "oms-ma", "stepSize": repr(Ts), "relativeTolerance": repr(OMS_TOLERANCE)}})
    experiment = ET.SubElement(root, _q("ssd", "DefaultExperiment"),
                               {"startTime": "0.0", "stopTime": repr((n - 1) * Ts)})
    # (all three, as OMSimulator exports them: a bufferSize it reads as 0 corrupts its heap)
    _oms_annotation(experiment, {}, {"resultFile": OMS_RESULT_FILE, "loggingInterval": "0.0",
                                     "bufferSize": str(OMS_BUFFER_SIZE)})
    return ET.ElementTree(root)


def ssv_path(name):
    """The archive path of component ``name``'s parameter set."""
    return "resources/%s.ssv" % name


def parameter_set_document(values, types):
    """The SSV 1.0 document of one component's parameter set: ``values`` {parameter: value},
    ``types`` {parameter: "Real" or "Integer"} (an Integer as its digits, a Real as Python's
    ``repr``, which reads back to the same double).  Every set has the system's name: a host
    that applies one named parameter set (ecos: the sets of one name over all components)
    applies them all."""
    pset = ET.Element(_q("ssv", "ParameterSet"), {"version": "1.0", "name": SYSTEM})
    params = ET.SubElement(pset, _q("ssv", "Parameters"))
    for var, value in values.items():
        p = ET.SubElement(params, _q("ssv", "Parameter"), {"name": var})
        text = str(int(value)) if types[var] == "Integer" else repr(float(value))
        ET.SubElement(p, _q("ssv", types[var]), {"value": text})
    return ET.tostring(pset, encoding="utf-8", xml_declaration=True)


def _oms_annotation(parent, children, attributes=None):
    """OpenModelica's vendor annotation under ``parent`` (SSP 1.0 allows vendor annotations):
    ``ssd:Annotations/ssc:Annotation[@type=org.openmodelica]/oms:Annotations/
    oms:SimulationInformation`` with ``attributes`` and the elements ``children`` (name ->
    attributes).  OMSimulator's importer needs it on the system, where ``oms:FixedStepMaster``
    makes the system a weakly coupled one stepped at ``stepSize`` by its fixed-step master
    ``oms-ma`` (without it the import aborts: ``[NewSystem] internal error``); on the default
    experiment it names the result file (without it OMSimulator warns of "deprecated content").
    Other hosts ignore it."""
    annotation = ET.SubElement(ET.SubElement(parent, _q("ssd", "Annotations")),
                               _q("ssc", "Annotation"), {"type": OMS_ANNOTATION})
    info = ET.SubElement(ET.SubElement(annotation, _q("oms", "Annotations")),
                         _q("oms", "SimulationInformation"), attributes or {})
    for name, attrs in children.items():
        ET.SubElement(info, _q("oms", name), attrs)
    return annotation


def build_ssp(fmus, out="build/DriftChain.ssp", start_values=None, n=2000, Ts=1e-3):
    """Write the SSP archive of the chain; return its path.

    Parameters
    ----------
    fmus : dict
        FMU name -> path of the built ``.fmu`` (Excitation, Accelerometer, DriftEstimator).
    out : path
        The ``.ssp`` to write (replaced whole: written to a temporary file, then moved).
    start_values : dict, optional
        FMU name -> {parameter: value}; default :func:`chain_start_values`.
    n, Ts : int, float
        Samples and sample period of the default experiment.
    """
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    start_values = chain_start_values(Ts=Ts) if start_values is None else start_values
    tree = system_structure(fmus, start_values, n, Ts)
    with tempfile.NamedTemporaryFile(dir=out.parent, suffix=".ssp.part", delete=False) as tmp:
        part = Path(tmp.name)
    try:
        entries = [("SystemStructure.ssd",
                    ET.tostring(tree.getroot(), encoding="utf-8", xml_declaration=True))]
        entries += [("resources/%s.fmu" % name, Path(fmus[name]).read_bytes())
                    for name in FMU_NAMES]
        entries += [(ssv_path(name), parameter_set_document(
            start_values[name], _types(fmus[name]))) for name in FMU_NAMES
            if start_values.get(name)]
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            for filename, data in entries:  # a fixed date, as in the FMUs: the same bytes
                info = zipfile.ZipInfo(filename, date_time=(1980, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16
                info.compress_type = zipfile.ZIP_DEFLATED
                z.writestr(info, data)
        os.chmod(part, 0o644)  # as the FMUs; NamedTemporaryFile creates it 0600
        shutil.move(str(part), str(out))
    finally:
        part.unlink(missing_ok=True)
    return out


def _types(fmu):
    """{variable: "Real" or "Integer"} of the FMU ``fmu`` (its model description)."""
    from driftfmu.fmu_src.schemas import read_model_description
    return {v.name: v.type for v in read_model_description(str(fmu)).modelVariables}


def parameter_values(start_values=None):
    """The archive's parameter values, {component: {parameter: value}}: the start values of
    the letter's Gaussian run (:func:`chain_start_values`, which are the FMUs' defaults) with
    ``start_values`` over them, as ``driftfmu.simulate`` takes them: a plain name (``"a2"``)
    goes to every component that has the parameter, ``"Accelerometer.a2"`` to one.

    Each value is checked against its parameter's rule, declared type and range before
    anything is built; the chain's components share one sample period ``Ts``, the archive's
    communication step.

    Raises
    ------
    driftfmu.simulations.errors.UsageError
        A name that is no parameter of the components, a value that is not allowed (one line
        naming the component and the parameter, and what is allowed), or components given
        different ``Ts``.
    """
    from types import SimpleNamespace

    from driftfmu._api import _start_value_problem
    from driftfmu.fmu_src.native_build import slave_class
    from driftfmu.simulations.errors import UsageError
    if start_values is not None and not hasattr(start_values, "items"):
        raise UsageError("start_values = %r is not a mapping; allowed: a dict of parameter "
                         "names and values, e.g. {\"a2\": 0.02, \"seed\": 7}" % (start_values,))
    params = {n: {s["name"]: SimpleNamespace(type=s["type"], min=s.get("min"), max=s.get("max"))
                  for s in slave_class(n).VARIABLES if s["causality"] == "parameter"}
              for n in FMU_NAMES}
    values = chain_start_values()
    for key, value in (start_values or {}).items():
        if not isinstance(key, str):
            raise UsageError("start value %r is not a parameter name; allowed: names such as "
                             "'a2' or 'Accelerometer.a2'" % (key,))
        fmu, dot, var = key.partition(".")
        if dot and fmu in FMU_NAMES:
            targets = [fmu] if var in params[fmu] else []
        else:
            var = key
            targets = [n for n in FMU_NAMES if var in params[n]]
        if not targets:
            raise UsageError("start value %r is not a parameter of %s; allowed: %s" % (
                key, " or ".join(FMU_NAMES), ", ".join(sorted(
                    {v for n in FMU_NAMES for v in params[n]}))))
        for t in targets:
            problem = _start_value_problem(var, value, params[t][var]) or \
                _declared_range_problem(var, value, params[t][var])
            if problem:
                raise UsageError("start value %s.%s" % (t, problem))
            values[t][var] = int(value) if params[t][var].type == "Integer" else float(value)
    periods = {n: values[n]["Ts"] for n in FMU_NAMES}
    if len(set(periods.values())) > 1:
        raise UsageError("start values give the components different sample periods (%s); "
                         "allowed: one Ts for the chain, the archive's communication step"
                         % ", ".join("%s.Ts = %r" % kv for kv in periods.items()))
    return values


def _declared_range_problem(name, value, variable):
    """Why ``value`` is outside the ``min``/``max`` that ``variable`` declares (beyond its
    parameter's rule, e.g. the ADXL203 stand-in's ``fc <= 2500``, which the FMU checks when it
    initialises), or None."""
    low, high = variable.min, variable.max
    if (low is None or value >= low) and (high is None or value <= high):
        return None
    return "%s = %r is out of range; allowed: %s (the model description's range)" % (
        name, value, " and ".join(b for b in (None if low is None else "%s >= %r" % (name, low),
                                              None if high is None else "%s <= %r" % (name, high))
                                  if b))


def parameter_set(ssp):
    """The archive's parameter values (each component's ``.ssv``, bound from the ``.ssd``) as
    one fmpy ``ParameterSet`` named ``<Component>.<var>``.

    fmpy reads the SSD's ParameterBindings (and the ``.ssv`` files they reference) but
    ``simulate_ssp`` applies only a parameter set passed to it, with names prefixed by the
    component: this builds that set.
    """
    from fmpy.ssp.ssd import Parameter, ParameterSet, find_components, read_ssd

    ssd = read_ssd(str(ssp))
    merged = ParameterSet(name=SYSTEM)
    for comp in find_components(ssd.system):
        for binding in comp.parameterBindings:
            for pset in binding.parameterValues:
                for p in pset.parameters:
                    q = Parameter(name="%s.%s" % (comp.name, p.name))
                    q.type, q.value = p.type, p.value
                    merged.parameters.append(q)
    return merged


def simulate(ssp, n, Ts=1e-3):
    """Simulate ``n`` rows of the archive with ``fmpy.ssp.simulation.simulate_ssp``, its start
    values applied; returns fmpy's structured array (columns ``<Component>.<connector>``).

    The archive is checked first (:func:`driftfmu.simulations.fmucheck.check_ssp`: its FMUs as
    the masters check an FMU, each parameter by component and name, each connection): a
    problem is one FileProblem line naming the archive, the component and the parameter, not
    fmpy's bare ``KeyError`` or "fmi2ExitInitializationMode failed with status 3"."""
    from fmpy.ssp.simulation import simulate_ssp

    from driftfmu.simulations import fmucheck
    fmucheck.check_ssp(ssp)

    # simulate_ssp makes rows at t = 0, Ts, ... while t < stop_time (t summed step by step);
    # its FMUs log through fmpy's printing logger: what they print is kept, and a failure
    # says the last error they logged (a GUID that is not the binary's), not fmpy's bare
    # "Failed to instantiate model"
    import contextlib
    import io
    import sys
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed), _extracted_in_a_work_folder():
            result = simulate_ssp(str(ssp), start_time=0.0, stop_time=(n - 0.5) * Ts,
                                  step_size=Ts, parameter_set=parameter_set(ssp))
    except Exception as exc:
        sys.stdout.write(printed.getvalue())
        errors = [line for line in printed.getvalue().splitlines()
                  if line.startswith(("[ERROR]", "[FATAL]"))]
        from driftfmu.simulations.cosim import CoSimulationError
        raise CoSimulationError("%s: fmpy's simulate_ssp failed: %s%s" % (
            ssp, (str(exc).strip().splitlines() or [type(exc).__name__])[0],
            ": " + errors[-1].split("] ", 1)[-1] if errors else "")) from exc
    sys.stdout.write(printed.getvalue())
    return result


#: One simulate_ssp at a time swaps fmpy's extract (:func:`_extracted_in_a_work_folder`).
_EXTRACT_LOCK = threading.Lock()


@contextlib.contextmanager
def _extracted_in_a_work_folder():
    """fmpy's ``simulate_ssp`` extracts the archive and each FMU into ``tempfile.mkdtemp()``
    folders and removes them only when the run succeeds (a refused instantiation left four in
    TMPDIR): for the call, they go into a work folder of driftfmu's (simulations/folders.py),
    removed whatever happens, and by the next run's sweep after a kill."""
    import fmpy.ssp.simulation as fmpy_ssp

    from driftfmu.simulations import folders
    with _EXTRACT_LOCK, folders.temporary("driftfmu_ssp_run_") as folder:
        extract = fmpy_ssp.extract

        def into_folder(filename, unzipdir=None, **kwargs):
            return extract(filename, unzipdir=unzipdir or tempfile.mkdtemp(dir=folder),
                           **kwargs)
        fmpy_ssp.extract = into_folder
        try:
            yield
        finally:
            fmpy_ssp.extract = extract


def jacobi_reference(n, a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, seed=1, Ts=1e-3,
                     x0=0.0, P0=None, estimator=1, initial="zero", **general):
    """What a Jacobi master such as fmpy's ``simulate_ssp`` shows for the chain, from models/.

    Returns ``{"time", "<Component>.<connector>": list}`` for the rows ``i = 0 .. n-1`` (see
    the module docstring for the timing): the Excitation's ``x``, the Accelerometer's input
    ``x`` and output ``z``, the DriftEstimator's input ``z`` and its outputs, all read after
    the step from ``t_i``.

    ``initial`` is what the connected inputs hold for the first step: ``"zero"`` (fmpy: the
    connectors start at 0) or ``"outputs"`` (libcosim: the outputs read after initialisation
    are copied along the connections, ``x_1`` and the Accelerometer's ``z`` of ``x_1``, which
    libcosim's initialisation passed along in Initialization Mode).

    ``general``: the general model's ``a3, a4, B, drive, Qu, Xu, fu`` (as
    :func:`chain_start_values`); with ``B != 0`` the known input ``u`` is a connection too,
    delayed like the others (the columns ``Excitation.u`` and ``DriftEstimator.u``).  The
    Accelerometer's slow errors (:data:`driftfmu.models.chain.SENSOR_ERRORS_OFF`, bound as its
    start values, ``theta`` and ``T`` those of its unconnected inputs and of the
    DriftEstimator's, which removes the tilt's offset, models.chain.wired_offset) advance with the FMU's
    own sample counter and the input it holds, as its ``z``: the sample it commits in a step
    and the pending one it shows after it both see the input set before the step.
    """
    unknown = set(general) - set(GENERAL_OFF)
    if unknown:
        raise TypeError("unknown parameter(s) %s" % ", ".join(sorted(unknown)))
    g = dict(GENERAL_OFF, **general)
    a3, a4, B = g["a3"], g["a4"], g["B"]
    if P0 is None:
        P0 = Q / (1.0 - A * A)
    model = {k: v for k, v in general.items() if k not in chain.SENSOR_ERRORS_OFF}
    xs = chain.simulate(n + 1, seed, a0=a0, a1=a1, a2=a2, A=A, Q=Q, R=R, x0=x0, P0=P0,
                        Ts=Ts, **model)["x"]  # x_1 .. x_{n+1}
    slow = chain.SensorErrors(seed, a0, a1, a2, R, a3, a4, Ts,
                              {k: v for k, v in general.items()
                               if k in chain.SENSOR_ERRORS_OFF})

    def accelerometer(u, k):
        """z_k of the input u held, from the committed error state (not committing)."""
        v = sensor.measurement_noise(seed, k)
        if slow.plain:
            return sensor.measure(u, a0, a1, a2, R, v, a3, a4)
        committed = slow.state
        z = slow.measure(u, v, k)
        slow.state = committed
        return z

    def commit(u, k):
        """The Accelerometer commits sample k with the input u (its error state moves)."""
        if not slow.plain:
            slow.measure(u, sensor.measurement_noise(seed, k), k)
    us = [excitation.input_sample(g["drive"], seed, k, g["Qu"], g["Xu"], g["fu"], Ts)
          for k in range(1, n + 2)]          # u_1 .. u_{n+1}
    wired = B != 0.0
    cols = {c: [] for c in ("time", "Excitation.x", "Accelerometer.x", "Accelerometer.z",
                            "DriftEstimator.z") + tuple("DriftEstimator." + c
                                                        for c in DRIFT_OUTPUTS)
            + (("Excitation.u", "DriftEstimator.u") if wired else ())}
    if initial == "zero":
        u_acc = u_est = u_in = 0.0           # fmpy: the connectors start at 0
    elif initial == "outputs":
        u_acc = xs[0]                        # x_1, and z of sample 1 from x_1: the outputs
        u_est = accelerometer(u_acc, 1)      # read in Initialization Mode follow the inputs
        u_in = us[0] if wired else 0.0       # set there; u_1

    else:
        raise ValueError("initial = %r is not allowed; allowed: 'zero' or 'outputs'"
                         % (initial,))
    committed = chain.estimator_init(x0, P0)
    # the tilt and temperature, bound at both FMUs' inputs: the estimator removes the tilt's
    # offset before filtering (models.chain.wired_offset)
    g_all = dict(chain.SENSOR_ERRORS_OFF, **{k: v for k, v in general.items()
                                             if k in chain.SENSOR_ERRORS_OFF})
    offset = chain.wired_offset(g_all["theta"], g_all["T"], a1, a2, a3, a4)
    t = 0.0
    for i in range(n):
        x = xs[i + 1]                        # x_{i+2}
        commit(u_acc, i + 1)                 # sample i+1, committed in the step from t_i
        z = accelerometer(u_acc, i + 2)      # the pending sample i+2 it shows after it
        z_est = u_est if offset is None else u_est - offset
        committed = chain.estimator_step(committed, z_est, a0, a1, a2, A, Q, R, a3, a4, B, u_in)
        shown = chain.estimator_step(committed, z_est, a0, a1, a2, A, Q, R, a3, a4, B, u_in)
        dcs = drift.estimates(shown.drift, a2, a3, a4)
        dc = drift.select(dcs, estimator)
        values = (shown.x, shown.P) + tuple(dcs) + (dc, chain.compensate(z_est, dc))
        u_acc, u_est = x, z                  # the connections, after every FMU has stepped
        if wired:
            cols["Excitation.u"].append(us[i + 1])      # u_{i+2}, beside x_{i+2}
            cols["DriftEstimator.u"].append(us[i + 1])  # the input it holds from now on
            u_in = us[i + 1]
        cols["time"].append(t)
        cols["Excitation.x"].append(x)
        cols["Accelerometer.x"].append(u_acc)
        cols["Accelerometer.z"].append(z)
        cols["DriftEstimator.z"].append(u_est)
        for c, v in zip(DRIFT_OUTPUTS, values):
            cols["DriftEstimator." + c].append(v)
        t += Ts                              # as simulate_ssp advances its clock
    return cols
