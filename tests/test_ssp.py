"""The chain as an SSP archive: schema-valid, loaded and simulated by fmpy's SSP support.

fmpy's ``simulate_ssp`` is a Jacobi master (each connection delays its signal by one step, see
fmu_src/ssp.py); its rows are compared to 1e-12 with :func:`driftfmu.fmu_src.ssp.jacobi_reference`, and
the signal no connection feeds (the excitation) with our master's rows shifted by one.
"""
import shutil
import subprocess
import time
import zipfile
from pathlib import Path

import pytest

from driftfmu.fmu_src import ssp
from importers import drivers
from driftfmu.simulations.cli import main
from driftfmu.simulations.gaussian import run_gaussian

pytestmark = pytest.mark.integration

N = 200
TOLERANCE = 1e-12


@pytest.fixture(scope="module")
def archive(built_fmus, tmp_path_factory):
    return ssp.build_ssp(built_fmus, tmp_path_factory.mktemp("ssp") / "DriftChain.ssp", n=N)


def _max_diff(a, b):
    assert len(a) == len(b), (len(a), len(b))
    return max(abs(float(x) - float(y)) for x, y in zip(a, b))


def test_archive_is_schema_valid_and_holds_the_wired_chain(archive):
    from fmpy.ssp.ssd import find_components, get_connections, read_ssd
    ssd = read_ssd(str(archive))                       # validates against the SSP 1.0 schema
    comps = find_components(ssd.system)
    assert [c.name for c in comps] == list(ssp.FMU_NAMES)
    assert [c.source for c in comps] == ["resources/%s.fmu" % n for n in ssp.FMU_NAMES]
    links = {(a.parent.name, a.name, b.parent.name, b.name)
             for a, b in get_connections(ssd.system)}
    assert links == set(ssp.CONNECTIONS)
    with zipfile.ZipFile(archive) as z:
        assert {"resources/%s.fmu" % n for n in ssp.FMU_NAMES} <= set(z.namelist())
    values = {p.name: p.value for p in ssp.parameter_set(archive).parameters}
    assert values["Excitation.seed"] == "1" and float(values["DriftEstimator.P0"]) == 0.01


def test_fmpy_simulates_the_archive_as_the_jacobi_reference(archive, built_fmus, report):
    res = ssp.simulate(archive, N)
    ref = ssp.jacobi_reference(N)
    assert len(res) == N
    diffs = {c: _max_diff(res[c], ref[c]) for c in ref}
    report("SSP fmpy.ssp simulate_ssp: DriftChain.ssp, %d steps, max |diff| vs the Jacobi "
           "reference = %.3g" % (N, max(diffs.values())))
    assert max(diffs.values()) <= TOLERANCE, diffs
    # the excitation is fed by no connection: our master's rows, one row later
    master = run_gaussian(n=N + 1, fmu_dir=built_fmus["Excitation"].parent,
                          plot=False)["columns"]
    assert _max_diff(res["Excitation.x"], master["x"][1:]) <= TOLERANCE
    # the connections delay z by one step: not our master's z (documented, not hidden)
    assert _max_diff(res["Accelerometer.z"], master["z"][1:]) > 1e-6


def test_fmpy_ssp_equals_our_master_with_the_same_coupling(archive, built_fmus, report):
    """fmpy's SSP run of the archive and our fmpy master (simulations.cosim) run of the same
    FMUs with the same (Jacobi) coupling give the same rows; our master's row i + 1 is fmpy's row
    i, whose time label is the start of the step."""
    from driftfmu.simulations.cosim import cosimulate

    res = ssp.simulate(archive, N)
    start = ssp.chain_start_values()
    record = {"Excitation": ["x"], "Accelerometer": ["z"],
              "DriftEstimator": list(ssp.DRIFT_OUTPUTS)}
    ours = cosimulate({n: built_fmus[n] for n in ssp.FMU_NAMES}, ssp.CONNECTIONS, N + 1, 1e-3,
                      start_values=start, record=record, coupling="jacobi")
    diffs = {key: _max_diff(res[key], ours[key][1:]) for key in ours if key != "time"}
    report("SSP fmpy.ssp simulate_ssp vs our master (simulations.cosim, coupling='jacobi'): "
           "%d steps, %d signals, max |diff| = %.3g" % (N, len(diffs), max(diffs.values())))
    assert max(diffs.values()) <= TOLERANCE, diffs


def test_the_same_fmus_give_the_same_archive_bytes_at_another_time(archive, built_fmus,
                                                                   tmp_path):
    """No time stamp inside: the archive of the same FMUs, written seconds later from copies
    with new modification times, is equal byte for byte (a reproducible build)."""
    copies = {}
    for name, fmu in built_fmus.items():
        copies[name] = tmp_path / Path(fmu).name
        shutil.copyfile(fmu, copies[name])  # a new modification time
    second = int(time.time())
    while int(time.time()) == second:
        time.sleep(0.05)
    again = ssp.build_ssp(copies, tmp_path / "again.ssp", n=N)
    assert again.read_bytes() == archive.read_bytes()


def test_start_values_in_the_archive_are_applied(built_fmus, tmp_path):
    params = dict(a2=0.02, A=0.5, Q=0.02, R=2e-4, seed=7, estimator=2)
    path = ssp.build_ssp(built_fmus, tmp_path / "other.ssp", n=50,
                         start_values=ssp.chain_start_values(**params))
    res = ssp.simulate(path, 50)
    ref = ssp.jacobi_reference(50, **params)
    diffs = {c: _max_diff(res[c], ref[c]) for c in ref}
    assert max(diffs.values()) <= TOLERANCE, diffs
    assert _max_diff(res["Excitation.x"], ssp.jacobi_reference(50)["Excitation.x"]) > 1e-3


def test_libcosim_loads_the_archive_with_its_own_ssp_parser(built_fmus, tmp_path, report):
    try:
        drivers.libcosim()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    params = dict(a2=0.02, A=0.5, Q=0.02, seed=7)            # proves the bindings are applied
    path = ssp.build_ssp(built_fmus, tmp_path / "DriftChain.ssp", n=N,
                         start_values=ssp.chain_start_values(**params))
    record = {"Excitation": ["x"], "Accelerometer": ["z"], "DriftEstimator": ssp.DRIFT_OUTPUTS}
    cols = drivers.run_libcosim_ssp(path, tmp_path, N, 1e-3, record)
    # libcosim is a Jacobi master too, but copies the outputs read after initialisation along
    # the connections before the first step (fmpy starts the connectors at 0)
    ref = ssp.jacobi_reference(N, initial="outputs", **params)
    diffs = {c: _max_diff(v, ref[c]) for c, v in cols.items()}
    report("SSP libcosim (libcosimpy): loaded DriftChain.ssp with its own SSP parser, %d steps, "
           "max |diff| vs the Jacobi reference = %.3g" % (N, max(diffs.values())))
    assert max(diffs.values()) <= TOLERANCE, diffs


def test_cli_build_writes_the_archive(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["build", "--out", "fmus", "--ssp"]) == 0
    assert (tmp_path / "build" / "DriftChain.ssp").is_file()
    assert main(["build", "--out", "fmus", "--ssp", "chain.ssp"]) == 0
    assert (tmp_path / "chain.ssp").is_file()
    assert "SSP" in capsys.readouterr().out


#: The general model with the known input (issue 16): B != 0 wires Excitation.u ->
#: DriftEstimator.u in the archive.
GENERAL = dict(a2=0.05, A=0.6, Q=0.05, R=1e-3, seed=3, a3=0.02, a4=0.03, B=0.8, drive=1, Qu=0.3)


@pytest.fixture(scope="module")
def general_archive(built_fmus, tmp_path_factory):
    return ssp.build_ssp(built_fmus, tmp_path_factory.mktemp("ssp_u") / "DriftChain.ssp", n=N,
                         start_values=ssp.chain_start_values(**GENERAL))


def test_archive_with_B_has_the_input_connection_and_fmpy_gives_the_jacobi_reference(
        general_archive, built_fmus, tmp_path, monkeypatch, report):
    from fmpy.ssp.ssd import get_connections, read_ssd
    ssd = read_ssd(str(general_archive))               # schema-valid
    links = {(a.parent.name, a.name, b.parent.name, b.name)
             for a, b in get_connections(ssd.system)}
    assert links == set(ssp.CONNECTIONS) | {("Excitation", "u", "DriftEstimator", "u")}
    res = ssp.simulate(general_archive, N)
    ref = ssp.jacobi_reference(N, **GENERAL)
    assert "DriftEstimator.u" in ref and any(v != 0.0 for v in ref["DriftEstimator.u"])
    diffs = {c: _max_diff(res[c], ref[c]) for c in ref}
    report("SSP fmpy.ssp simulate_ssp with B = 0.8 (Excitation.u -> DriftEstimator.u): %d "
           "steps, max |diff| vs the Jacobi reference = %.3g" % (N, max(diffs.values())))
    assert max(diffs.values()) == 0.0, diffs
    # the same archive without the u connection: the filter predicts with u = 0
    monkeypatch.setattr(ssp, "connections", lambda start_values: ssp.CONNECTIONS)
    bare = ssp.build_ssp(built_fmus, tmp_path / "bare.ssp", n=N,
                         start_values=ssp.chain_start_values(**GENERAL))
    assert _max_diff(ssp.simulate(bare, N)["DriftEstimator.x_hat"],
                     ref["DriftEstimator.x_hat"]) > 1e-3


def test_archive_without_B_has_no_input_connection():
    start = ssp.chain_start_values(**dict(GENERAL, B=0.0))
    assert ssp.connections(start) == ssp.CONNECTIONS
    assert ssp.connections(ssp.chain_start_values(**GENERAL))[-1] == \
        ("Excitation", "u", "DriftEstimator", "u")
    with pytest.raises(TypeError, match="Bu"):
        ssp.jacobi_reference(5, Bu=1.0)


def test_libcosim_runs_the_archive_with_the_input(general_archive, tmp_path, report):
    try:
        drivers.libcosim()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    # outputs only: libcosim's observer shows an input before the connections copy into it
    record = {"Excitation": ["x", "u"], "Accelerometer": ["z"],
              "DriftEstimator": ssp.DRIFT_OUTPUTS}
    cols = drivers.run_libcosim_ssp(general_archive, tmp_path, N, 1e-3, record)
    ref = ssp.jacobi_reference(N, initial="outputs", **GENERAL)
    diffs = {c: _max_diff(v, ref[c]) for c, v in cols.items()}
    report("SSP libcosim with B = 0.8 (Excitation.u -> DriftEstimator.u): %d steps, max |diff| "
           "vs the Jacobi reference = %.3g" % (N, max(diffs.values())))
    assert max(diffs.values()) == 0.0, diffs


#: The Accelerometer's slow errors (issue 42): its parameters bound as start values, and the
#: tilt and temperature as the start values of its inputs (bound without a connector).
ERRORS = dict(a2=0.02, seed=5, bias_on=0.03, random_walk=0.01, bias_gm=0.02, tau_gm=0.01,
              flicker=0.01, tau_min=0.002, tau_max=2.0, d_inf=0.05, E_tau=0.01, theta=0.2,
              T=305.0, kT_bias=0.001, kT_scale=0.002, range=1.5, bits=14)


@pytest.fixture(scope="module")
def errors_archive(built_fmus, tmp_path_factory):
    return ssp.build_ssp(built_fmus, tmp_path_factory.mktemp("ssp_e") / "DriftChain.ssp", n=N,
                         start_values=ssp.chain_start_values(**ERRORS))


def test_archive_with_the_slow_errors_binds_them_and_fmpy_gives_the_jacobi_reference(
        errors_archive, report):
    from fmpy.ssp.ssd import find_components, read_ssd
    ssd = read_ssd(str(errors_archive))                # schema-valid
    values = {p.name: p.value for p in ssp.parameter_set(errors_archive).parameters}
    for name in ("bias_on", "random_walk", "bias_gm", "flicker", "d_inf", "theta", "T",
                 "kT_scale", "range", "bits"):
        assert float(values["Accelerometer." + name]) == ERRORS[name], name
    acc = next(c for c in find_components(ssd.system) if c.name == "Accelerometer")
    assert {c.name for c in acc.connectors} >= {"z", "x", "bias_gm", "range"}
    assert not {"theta", "T"} & {c.name for c in acc.connectors}  # (unconnected inputs)
    res = ssp.simulate(errors_archive, N)
    ref = ssp.jacobi_reference(N, **ERRORS)
    diffs = {c: _max_diff(res[c], ref[c]) for c in ref}
    report("SSP fmpy.ssp simulate_ssp with every slow error on: %d steps, max |diff| vs the "
           "Jacobi reference = %.3g" % (N, max(diffs.values())))
    assert max(diffs.values()) == 0.0, diffs
    plain = ssp.jacobi_reference(N, a2=0.02, seed=5)
    assert _max_diff(ref["Accelerometer.z"], plain["Accelerometer.z"]) > 0.1


def test_libcosim_runs_the_archive_with_the_slow_errors(errors_archive, tmp_path, report):
    try:
        drivers.libcosim()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    record = {"Excitation": ["x"], "Accelerometer": ["z"], "DriftEstimator": ssp.DRIFT_OUTPUTS}
    cols = drivers.run_libcosim_ssp(errors_archive, tmp_path, N, 1e-3, record)
    ref = ssp.jacobi_reference(N, initial="outputs", **ERRORS)
    diffs = {c: _max_diff(v, ref[c]) for c, v in cols.items()}
    report("SSP libcosim with every slow error on: %d steps, max |diff| vs the Jacobi "
           "reference = %.3g" % (N, max(diffs.values())))
    assert max(diffs.values()) == 0.0, diffs


# -- OpenModelica's OMSimulator and ecos ------------------------------------------------------
def _oms(node, tag):
    return node.find("%s" % "/".join("{%s}%s" % (ssp.NS[p], t) for p, t in
                                      (part.split(":") for part in tag.split("/"))))


def test_archive_carries_openmodelicas_annotation_and_one_parameter_set_name(general_archive):
    """What OMSimulator's importer needs (its vendor annotation on the system: a weakly coupled
    system stepped at Ts by its fixed-step master; on the default experiment its result file
    with a buffer size it can use) and what ecos needs (the components' start values in one
    named parameter set), in a schema-valid archive."""
    import xml.etree.ElementTree as ET
    from fmpy.ssp.ssd import read_ssd
    read_ssd(str(general_archive))                      # validates against the SSP 1.0 schema
    with zipfile.ZipFile(general_archive) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    for parent, info in ((_oms(root, "ssd:System"), {}),
                         (_oms(root, "ssd:DefaultExperiment"),
                          {"resultFile": "DriftChain_res.mat", "loggingInterval": "0.0",
                           "bufferSize": "10"})):
        annotation = _oms(parent, "ssd:Annotations/ssc:Annotation")
        assert annotation.get("type") == "org.openmodelica"
        simulation = _oms(annotation, "oms:Annotations/oms:SimulationInformation")
        assert simulation.attrib == info
    master = _oms(root, "ssd:System/ssd:Annotations/ssc:Annotation/oms:Annotations/"
                        "oms:SimulationInformation/oms:FixedStepMaster")
    assert master.attrib == {"description": "oms-ma", "stepSize": "0.001",
                             "relativeTolerance": "0.0001"}
    bindings = root.iter("{%s}ParameterBinding" % ssp.NS["ssd"])
    assert [b.get("source") for b in bindings] == ["resources/%s.ssv" % n for n in ssp.FMU_NAMES]
    with zipfile.ZipFile(general_archive) as z:
        sets = [ET.fromstring(z.read("resources/%s.ssv" % n)) for n in ssp.FMU_NAMES]
    assert [s.tag for s in sets] == ["{%s}ParameterSet" % ssp.NS["ssv"]] * 3
    assert [s.get("name") for s in sets] == [ssp.SYSTEM] * 3


def _ssp_archives(built_fmus, native_fmus, tmp_path):
    fmus = {"python": built_fmus, "native FMI 2.0": native_fmus[2]}
    return {kind: ssp.build_ssp({n: f[n] for n in ssp.FMU_NAMES}, tmp_path / kind.split()[0] /
                                "DriftChain.ssp", n=N, start_values=ssp.chain_start_values(
                                    **GENERAL)) for kind, f in fmus.items()}


def test_omsimulator_command_line_runs_the_archive_with_our_masters_numbers(
        built_fmus, native_fmus, tmp_path, report):
    """``OMSimulator --stopTime=... DriftChain.ssp`` (OpenModelica's importer, as its editor uses
    it) loads both archives as they are, applies every component's start values and gives our
    master's rows bit for bit: its fixed-step master copies the outputs along the connections
    in their order after every step (our Gauss-Seidel timing) and records each point after
    that."""
    try:
        exe = drivers.omsimulator()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.strip()
    master = run_gaussian(n=N, fmu_dir=built_fmus["Excitation"].parent, plot=False,
                          **GENERAL)["columns"]
    columns = {"Excitation.x": "x", "Accelerometer.z": "z"}
    columns.update({"DriftEstimator.%s" % c: c for c in ("x_hat", "P", "dc_ekf1", "dc_ekf2",
                                                         "dc_ekf3", "z_comp")})
    for kind, archive in _ssp_archives(built_fmus, native_fmus, tmp_path).items():
        proc, cols = drivers.run_omsimulator_ssp(archive, archive.parent / "run",
                                                 (N - 1) * 1e-3, ssp.OMS_RESULT_FILE)
        lines = (proc.stdout + proc.stderr).splitlines()
        assert proc.returncode == 0 and cols is not None, (kind, proc.returncode, lines[-20:])
        complaints = [line for line in lines if line.startswith(("error", "warning"))
                      and "could not load the ssd schema file" not in line]  # (an install quirk)
        assert complaints == [], (kind, complaints)
        assert len(cols["time"]) == N, (kind, len(cols["time"]))
        for col, name in columns.items():
            assert list(cols[col]) == list(master[name]), (kind, col)
        report("SSP OMSimulator command line (%s): the %s archive, rc 0, %d points, %d outputs "
               "equal to our master bit for bit" % (version, kind, N, len(columns)))


def test_ecos_applies_every_components_start_values(built_fmus, native_fmus, tmp_path, report,
                                                    monkeypatch):
    """ecos applies one named parameter set per run; the archive gives every component's set
    the system's name, so one ``init(0, "DriftChain")`` applies them all: the excitation is the
    run's (A, Q, seed), the sensor's z is the run's (a2, R, a3, a4, seed) and the estimator
    selects EKF2 (``estimator = 2``)."""
    try:
        drivers.ecos()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    params = dict(GENERAL, estimator=2)
    master = run_gaussian(n=N + 1, fmu_dir=built_fmus["Excitation"].parent, plot=False,
                          **params)["columns"]
    record = {"Excitation": ["x"], "Accelerometer": ["z"], "DriftEstimator": ["dc", "dc_ekf2"]}
    for kind, archive in {k: ssp.build_ssp({n: f[n] for n in ssp.FMU_NAMES},
                                           tmp_path / (k + ".ssp"), n=N,
                                           start_values=ssp.chain_start_values(**params))
                          for k, f in (("python", built_fmus),
                                       ("native", native_fmus[2]))}.items():
        # ecos unpacks the archive into a folder of the temporary folder it leaves there
        monkeypatch.setenv("TMPDIR", str(tmp_path))
        cols, ok = drivers.run_ecos_ssp(archive, N, 1e-3, ssp.SYSTEM, record)
        assert ok, "ecos refused the parameter set %r of the %s archive" % (ssp.SYSTEM, kind)
        # ecos reads an output after the connections set the inputs: x and z are our master's
        # next row (the memory-less sensor follows its input at once)
        assert cols["Excitation.x"] == list(master["x"][1:]), kind
        assert cols["Accelerometer.z"] == list(master["z"][1:]), kind
        assert cols["DriftEstimator.dc"] == cols["DriftEstimator.dc_ekf2"], kind
        report("SSP ecos (ecospy): the %s archive, one parameter set %r applied to all three "
               "components, %d steps" % (kind, ssp.SYSTEM, N))
