"""The general sensor (issue 16) in the FMUs: a3, a4, B and the known input u.

- the Python FMUs, wired with ``Excitation.u -> DriftEstimator.u`` when ``B != 0``, equal
  :func:`driftfmu.models.chain.simulate` (the master's validation, 1e-12) with ``a3, a4, B != 0``
  and both input kinds;
- the native twins (FMI 2.0 and 3.0) equal the Python FMUs bit for bit on that run;
- new parameters are appended (no value reference moves), declared with ranges and units;
- a dual-axis sensor refuses a4 != 0, in both twins, with the same message.
"""
import pytest

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.models import excitation
from driftfmu.simulations import gaussian
from driftfmu.simulations.fastcosim import cosimulate_fast

GENERAL = dict(a0=0.1, a2=0.05, A=0.6, Q=0.05, R=1e-3, a3=0.02, a4=0.03, B=0.8)
INPUTS = {"gaussian": dict(drive=excitation.GAUSSIAN, Qu=0.3),
          "sinusoidal": dict(drive=excitation.SINUSOIDAL, Xu=0.9, fu=40.0)}


def test_new_variables_are_appended_with_ranges_and_units():
    slow_errors = ("bias_on", "random_walk", "bias_gm", "tau_gm", "flicker", "tau_min",
                   "tau_max", "d_inf", "E_tau", "T0", "kT_bias", "kT_scale", "range", "theta",
                   "T")  # appended after a4 (issue 42)
    tables = {Excitation: ("B", "drive", "Qu", "Xu", "fu", "u", "u_in"),
              Accelerometer: ("a4",) + slow_errors, DriftEstimator: ("a3", "a4", "B", "u")}
    # (appended after them since: the DriftEstimator's bias state and class-2 rows)
    after = {DriftEstimator: len(DriftEstimator.VARIABLES) - 25}
    for cls, names in tables.items():
        rows = {s["name"]: s for s in cls.VARIABLES}
        end = len(cls.VARIABLES) - after.get(cls, 0)
        assert tuple(s["name"] for s in cls.VARIABLES[end - len(names):end]) == names
        for n in names:
            assert "[" in rows[n]["description"], n
    ex = {s["name"]: s for s in Excitation.VARIABLES}
    assert (ex["drive"]["min"], ex["drive"]["max"], ex["Qu"]["min"]) == (0, 2, 0.0)
    assert ex["u"]["causality"] == "output"
    de = {s["name"]: s for s in DriftEstimator.VARIABLES}
    assert de["u"]["causality"] == "input" and de["a4"]["unit"] == "V/g4"
    assert "u" in DriftEstimator.DEPENDENCIES["x_hat"]


@pytest.mark.integration
@pytest.mark.parametrize("kind", sorted(INPUTS))
def test_python_fmus_with_the_input_equal_the_chain(built_fmus, kind):
    res = gaussian.run_gaussian(fmu_dir=built_fmus["Excitation"].parent, n=400, plot=False,
                                **GENERAL, **INPUTS[kind])
    v = res["summary"]["validation"]
    assert v["passed"] and max(v["max_abs_diff"].values()) <= 1e-12
    # the input matters: without the u connection the filter would miss B u
    assert gaussian.INPUT_CONNECTION in gaussian.connections(GENERAL["B"])
    assert gaussian.connections(0.0) == gaussian.CONNECTIONS


@pytest.mark.integration
@pytest.mark.parametrize("version", [2, 3])
def test_native_fmus_with_the_new_parameters_equal_the_python_fmus(built_fmus, native_fmus,
                                                                     version):
    start = gaussian.start_values(**GENERAL, **INPUTS["gaussian"])
    conns = gaussian.connections(GENERAL["B"])
    names = gaussian.FMU_NAMES
    from driftfmu.simulations.cosim import cosimulate
    python = cosimulate({n: built_fmus[n] for n in names}, conns, 300, 1e-3, start_values=start)
    native = cosimulate_fast({n: native_fmus[version][n] for n in names}, conns, 300, 1e-3,
                             start_values=start)
    for key in python:
        assert list(python[key]) == list(native[key]), key
    assert any(v != 0.0 for v in python["Excitation.u"])


def test_dual_axis_refuses_a4():
    acc = Accelerometer(instance_name="a")
    acc.dual, acc.a4 = 1, 0.5
    msgs = [m for m in acc.check_parameters() if "a4" in m]
    assert msgs == ["dual = 1 is not allowed with a4 = 0.5; allowed: dual = 1 with a4 = 0 "
                    "(the bilinear sensor is of 2nd order)"]


@pytest.mark.integration
def test_native_dual_axis_refuses_a4(native_fmus, tmp_path):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    path = native_fmus[2]["Accelerometer"]
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipped = extract(str(path), unzipdir=tmp_path)
    for a4, refused in ((0.0, False), (0.5, True)):
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="a")
        fmu.instantiate()
        fmu.setInteger([vr["dual"]], [1])
        fmu.setReal([vr["a4"]], [a4])
        fmu.setupExperiment(startTime=0.0)
        try:  # refused when initialisation ends (fmi2Error)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            raised = False
        except Exception:
            raised = True
        fmu.freeInstance()
        assert raised == refused, a4


@pytest.mark.integration
def test_cli_run_gaussian_takes_the_general_parameters(built_fmus, tmp_path, capsys):
    import json

    from driftfmu.simulations.cli import main
    fmu_dir = str(built_fmus["Excitation"].parent)
    assert main(["run", "gaussian", "--a3", "0.02", "--a4", "0.03", "--B", "0.8", "--drive",
                 "1", "--Qu", "0.3", "--n", "200", "--fmu-dir", fmu_dir,
                 "--out", str(tmp_path / "o")]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["validation"]["passed"]
    with pytest.raises(SystemExit) as exc:
        main(["run", "gaussian", "--drive", "3", "--fmu-dir", fmu_dir])
    assert exc.value.code == 2 and "drive" in capsys.readouterr().err
