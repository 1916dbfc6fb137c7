"""SSP archives that carry the user's parameter values (docs/hosts.md, "SSP hosts and their
parameter sets"): ``driftfmu build --ssp FILE --start-values a2 0.02 seed 7`` (and
``driftfmu.build_fmus(ssp=..., start_values=...)``) writes each component's values as a parameter
set of its own, ``resources/<Component>.ssv``, referenced from the ``.ssd``; fmpy reads and
applies them, and its run equals our master's with the same values and coupling; every value
is checked against its parameter's rule and range before anything is built (one line naming
the component and the parameter, exit status 2)."""
import os
import shlex
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import driftfmu
from driftfmu.fmu_src import ssp
from driftfmu.simulations.cli import main
from driftfmu.simulations.errors import UsageError
from recipes import commands

N = 100
USER = {"a2": 0.02, "seed": 7}


def _one_error_line(err):
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    return lines[0]


# -- the values: merged over the FMUs' defaults, checked, one Ts ---------------------------------

def test_a_plain_name_goes_to_every_component_that_has_it_a_dotted_one_to_one():
    values = ssp.parameter_values({"a2": 0.02, "seed": 7, "DriftEstimator.R": 3e-4})
    assert values["Accelerometer"]["a2"] == values["DriftEstimator"]["a2"] == 0.02
    assert values["Excitation"]["seed"] == values["Accelerometer"]["seed"] == 7
    assert isinstance(values["Excitation"]["seed"], int)
    assert "seed" not in values["DriftEstimator"]
    assert values["DriftEstimator"]["R"] == 3e-4 and values["Accelerometer"]["R"] == 1e-4
    # a parameter the letter's run does not set (the ADXL203 stand-in's fc) goes in too
    assert ssp.parameter_values({"fc": 50.0})["Accelerometer"]["fc"] == 50.0
    assert ssp.parameter_values() == ssp.chain_start_values()


@pytest.mark.parametrize("given, words", [
    ({"a2": "abc"}, "start value Accelerometer.a2 = 'abc' is not a number"),
    ({"R": -1.0}, "start value Accelerometer.R = -1.0 is out of range; allowed:"),
    ({"DriftEstimator.R": 0.0}, "start value DriftEstimator.R = 0.0 is out of range"),
    ({"seed": 7.5}, "start value Excitation.seed = 7.5 is not an integer; allowed: an integer "
                    "seed >= 0"),
    ({"seed": 2147483648}, "start value Excitation.seed = 2147483648 is out of range"),
    ({"rho": 1.0000000000000002}, "start value Excitation.rho = 1.0000000000000002 is out of"),
    ({"fc": 2500.0000000000005}, "start value Accelerometer.fc"),
    ({"b9": 1.0}, "start value 'b9' is not a parameter of Excitation or Accelerometer or "
                  "DriftEstimator; allowed: A, B, E_tau, P0, Pb0, "),
    ({"Accelerometer.P0": 1.0}, "start value 'Accelerometer.P0' is not a parameter"),
    ({"x": 1.0}, "start value 'x' is not a parameter"),        # an output, not a parameter
    ({"Excitation.Ts": 2e-3}, "different sample periods (Excitation.Ts = 0.002, "
                              "Accelerometer.Ts = 0.001"),
    ({7: 1.0}, "start value 7 is not a parameter name"),
])
def test_a_value_that_is_not_allowed_is_refused_naming_component_and_parameter(given, words):
    with pytest.raises(UsageError) as exc:
        ssp.parameter_values(given)
    assert words in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("given", [{"seed": 0}, {"seed": 2147483647}, {"rho": 1.0},
                                   {"rho": -1.0}, {"fc": 2500.0}, {"R": 5e-324},
                                   {"Ts": 2e-3}, {"A": 0.9999999999999999}])
def test_the_bounds_themselves_are_allowed(given):
    values = ssp.parameter_values(given)
    (name, value), = given.items()
    assert any(v.get(name) == value for v in values.values())


def test_start_values_without_an_archive_are_refused(tmp_path):
    with pytest.raises(UsageError, match="start_values with ssp"):
        driftfmu.build_fmus(tmp_path / "fmus", start_values=USER)
    with pytest.raises(UsageError, match="not a mapping"):
        driftfmu.build_fmus(tmp_path / "fmus", ssp=tmp_path / "c.ssp", start_values=[1])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, words", [
    (["--start-values", "a2", "0.02"], "--start-values with --ssp"),
    (["--ssp", "c.ssp", "--start-values", "a2", "0.02", "seed"], "a name without a value"),
    (["--ssp", "c.ssp", "--start-values", "R", "-1"], "Accelerometer.R = -1 is out of range"),
    (["--ssp", "c.ssp", "--start-values", "seed", "x7"], "Excitation.seed = 'x7' is not a"),
    (["--ssp", "c.ssp", "--start-values", "gain", "2"], "'gain' is not a parameter of"),
])
def test_the_command_refuses_in_one_line_before_anything_is_built(argv, words, tmp_path,
                                                                  monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(["build", "--out", "fmus"] + argv)
    assert exc.value.code == 2
    assert words in _one_error_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


# -- the archive: SSV files bound from the .ssd, applied by fmpy --------------------------------

@pytest.fixture(scope="module")
def user_archive(tmp_path_factory):
    """docs/hosts.md's ``driftfmu build --ssp build/DriftChain.ssp --start-values a2 0.02 seed
    7``, as a user runs it (in a folder of its own)."""
    line, = commands("ssp-start-values")
    argv = shlex.split(line)
    assert argv[:2] == ["driftfmu", "build"] and argv[-5:] == ["--start-values", "a2", "0.02",
                                                               "seed", "7"]
    folder = tmp_path_factory.mktemp("ssp_user")
    here = os.getcwd()
    os.chdir(folder)
    try:
        assert main(argv[1:]) == 0
    finally:
        os.chdir(here)
    return folder / "build" / "DriftChain.ssp", folder / "build" / "fmus"


@pytest.mark.integration
def test_the_archive_binds_each_components_parameter_set_from_its_ssv(user_archive):
    from fmpy.ssp.ssd import find_components, read_ssd
    archive, _ = user_archive
    ssd = read_ssd(str(archive))  # the .ssd and every .ssv it references, schema-validated
    for comp in find_components(ssd.system):
        binding, = comp.parameterBindings
        assert binding.source == "resources/%s.ssv" % comp.name
        pset, = binding.parameterValues
        assert pset.name == ssp.SYSTEM
    with zipfile.ZipFile(archive) as z:
        root = ET.fromstring(z.read("SystemStructure.ssd"))
        assert root.find(".//{%s}ParameterValues" % ssp.NS["ssd"]) is None  # none inline
    values = {p.name: p.value for p in ssp.parameter_set(archive).parameters}
    assert values["Accelerometer.a2"] == values["DriftEstimator.a2"] == "0.02"
    assert values["Excitation.seed"] == values["Accelerometer.seed"] == "7"


@pytest.mark.integration
def test_fmpy_runs_the_users_sensor_from_the_archive(user_archive, report):
    """fmpy's ``simulate_ssp`` with the archive's parameter sets equals our master with the
    same values and the same (Jacobi) coupling bit for bit; its excitation, which no
    connection feeds, is ``driftfmu.simulate``'s with the same values one row later; the
    archive of the defaults gives other numbers."""
    from driftfmu.simulations.cosim import cosimulate
    archive, fmus = user_archive
    got = ssp.simulate(archive, N)
    paths = {n: fmus / ("%s.fmu" % n) for n in ssp.FMU_NAMES}
    per_fmu = ssp.parameter_values(USER)
    record = {"Excitation": ["x"], "Accelerometer": ["z"],
              "DriftEstimator": list(ssp.DRIFT_OUTPUTS)}
    ours = cosimulate(paths, ssp.CONNECTIONS, N + 1, 1e-3, start_values=per_fmu,
                      record=record, coupling="jacobi")
    for key in ours:
        if key != "time":
            assert np.array_equal(np.asarray(got[key]), np.asarray(ours[key][1:])), key
    want = driftfmu.simulate(stop_time=N * 1e-3, start_values=USER, fmu_dir=fmus)
    assert np.array_equal(np.asarray(got["Excitation.x"]), want["x"][1:])
    defaults = ssp.simulate(ssp.build_ssp(paths, archive.with_name("defaults.ssp"), n=N), N)
    assert not np.array_equal(np.asarray(defaults["Excitation.x"]), want["x"][1:])
    report("SSP with --start-values a2 0.02 seed 7 (resources/<Component>.ssv): fmpy "
           "simulate_ssp equals our master with the same values and Jacobi coupling bit for "
           "bit, %d rows" % N)


@pytest.mark.integration
def test_omsimulator_runs_the_users_sensor_from_the_archive(user_archive, native_fmus,
                                                            tmp_path, report):
    """OMSimulator's command line applies the parameter sets of ``resources/<Component>.ssv``
    and gives ``driftfmu.simulate``'s numbers with the same values bit for bit (Python and
    native FMI 2.0 archives)."""
    from importers import drivers
    try:
        drivers.omsimulator()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))
    archive, fmus = user_archive
    native = ssp.build_ssp({n: native_fmus[2][n] for n in ssp.FMU_NAMES},
                           tmp_path / "native.ssp", n=N, start_values=ssp.parameter_values(USER))
    want = driftfmu.simulate(stop_time=(N - 1) * 1e-3, start_values=USER, fmu_dir=fmus)
    for kind, path in (("python", archive), ("native FMI 2.0", native)):
        proc, cols = drivers.run_omsimulator_ssp(path, tmp_path / kind.split()[0],
                                                 (N - 1) * 1e-3, ssp.OMS_RESULT_FILE)
        assert proc.returncode == 0 and cols is not None, (kind, proc.stdout + proc.stderr)
        assert len(cols["time"]) == N, (kind, len(cols["time"]))
        for col in ["Excitation.x", "Accelerometer.z"] + ["DriftEstimator.%s" % c for c in
                                                          ssp.DRIFT_OUTPUTS]:
            assert np.array_equal(cols[col], want[col.split(".")[1]]), (kind, col)
        report("SSP OMSimulator with --start-values a2 0.02 seed 7: the %s archive equals "
               "driftfmu.simulate with the same values bit for bit, %d points" % (kind, N))


# -- without building: model descriptions from the tables, the command's plumbing -------------

def _description_only_fmus(folder):
    """Archives holding only the chain's model descriptions (generated from the tables, as
    the native build writes them): enough for the SSD and the SSV files."""
    from driftfmu.fmu_src import native_build
    fmus = {}
    for name in ssp.FMU_NAMES:
        xml = native_build.fmi2_model_description(native_build.slave_class(name),
                                                  native_build.token(name, 2), ["all.c"],
                                                  log=lambda line: None)
        fmus[name] = folder / ("%s.fmu" % name)
        with zipfile.ZipFile(fmus[name], "w") as z:
            z.writestr("modelDescription.xml", xml)
    return fmus


def test_each_components_values_are_its_ssv_bound_from_the_ssd(tmp_path):
    from fmpy.ssp.ssd import find_components, read_ssd
    fmus = _description_only_fmus(tmp_path)
    archive = ssp.build_ssp(fmus, tmp_path / "chain.ssp", n=N,
                            start_values=ssp.parameter_values(USER))
    ssd = read_ssd(str(archive))  # the .ssd and the .ssv files, schema-validated
    sources = {c.name: [b.source for b in c.parameterBindings]
               for c in find_components(ssd.system)}
    assert sources == {n: ["resources/%s.ssv" % n] for n in ssp.FMU_NAMES}
    values = {p.name: (p.type, p.value) for p in ssp.parameter_set(archive).parameters}
    assert values["Accelerometer.a2"] == values["DriftEstimator.a2"] == ("Real", "0.02")
    assert values["Excitation.seed"] == values["Accelerometer.seed"] == ("Integer", "7")
    assert values["DriftEstimator.R"] == ("Real", "0.0001")  # the defaults are there too
    with zipfile.ZipFile(archive) as z:
        root = ET.fromstring(z.read("resources/Accelerometer.ssv"))
    assert root.get("name") == ssp.SYSTEM


def test_the_command_hands_its_values_to_the_archive(tmp_path, monkeypatch):
    """``driftfmu build --ssp FILE --start-values a2 0.02 seed 7`` gives the archive those
    values (the builds themselves replaced: nothing is compiled)."""
    from driftfmu.fmu_src import builder
    from test_cli_checks import _fake_python_build
    seen = {}

    def fake_ssp(fmus, out, start_values=None, n=2000, Ts=1e-3):
        seen.update(start_values=start_values, Ts=Ts)
        out.write_bytes(b"ssp")
        return out
    monkeypatch.setattr(builder, "build_fmus", _fake_python_build)
    monkeypatch.setattr(ssp, "build_ssp", fake_ssp)
    assert main(["build", "--out", str(tmp_path / "fmus"), "--ssp", str(tmp_path / "c.ssp"),
                 "--start-values", "a2", "0.02", "seed", "7", "Ts", "0.002"]) == 0
    assert seen["start_values"] == ssp.parameter_values(dict(USER, Ts=0.002))
    assert seen["start_values"]["Accelerometer"]["a2"] == 0.02 and seen["Ts"] == 0.002
    assert main(["build", "--out", str(tmp_path / "fmus2"), "--ssp", str(tmp_path / "d.ssp")]) == 0
    assert seen["start_values"] == ssp.parameter_values() and seen["Ts"] == 1e-3
