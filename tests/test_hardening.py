"""What a hostile or careless host does to the Python side of the FMUs (issue 9): crafted and
foreign FMU states, overflowing inputs, outputs in Initialization Mode, declared ranges, rejected
calls that must change nothing, ``python -OO``, and memory kept per instantiation."""
import gc
import json
import math
import os
import subprocess
import sys
import textwrap
import tracemalloc
import zipfile
from xml.etree import ElementTree as ET

import pytest

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.DualDriftEstimator import DualDriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.models import parameters, sensor
from driftfmu.simulations.cosim import Instance
from waiting import BOUND

SLAVES = {"Excitation": Excitation, "Accelerometer": Accelerometer,
          "DriftEstimator": DriftEstimator, "DualDriftEstimator": DualDriftEstimator}
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# -- helpers on the Python slave classes ---------------------------------------------------------
def vr(slave, name):
    return next(v.value_reference for v in slave.vars.values() if v.name == name)


def kind(slave, name):
    return type(slave.vars[vr(slave, name)]).__name__


def put(slave, name, value):
    call = slave.set_real if kind(slave, name) == "Real" else slave.set_integer
    call([vr(slave, name)], [value])


def get(slave, name):
    call = slave.get_real if kind(slave, name) == "Real" else slave.get_integer
    return call([vr(slave, name)])[0]


def messages(slave):
    out = [m.msg for m in slave.log_queue]
    slave.log_queue.clear()
    return out


def ready(cls, **start):
    s = cls(instance_name="s")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    for name, value in start.items():
        put(s, name, value)
    s.exit_initialization_mode()
    assert not messages(s)
    return s


def snapshot(slave):
    """Everything observable: the FMU state as serialised, and every variable as read."""
    values = [get(slave, s["name"]) for s in slave.VARIABLES]   # (refreshes the outputs)
    state = json.dumps(slave._get_fmu_state(), sort_keys=True)
    return state, values


# -- FMU states ----------------------------------------------------------------------------------
@pytest.mark.parametrize("crafted", [
    {"k": 1, "_call": 0},
    {"k": 1, "get_real": 0},
    {"k": 1},
    None,
    [1, 2, 3],
    "a string",
])
@pytest.mark.parametrize("cls", sorted(SLAVES.values(), key=lambda c: c.__name__))
def test_crafted_state_is_refused_and_changes_nothing(cls, crafted):
    s = ready(cls)
    s.do_step(0.0, 1e-3)
    before = snapshot(s)
    s._set_fmu_state(crafted)
    text = messages(s)[-1]
    assert "fmi2SetFMUstate" in text and ("not an FMU state of %s" % cls.__name__ in text
                                          or "not of %s" % cls.__name__ in text)
    assert snapshot(s) == before
    assert s.do_step(1e-3, 1e-3) and not messages(s)   # and it still works


def _state_of(s):
    return json.loads(json.dumps(s._get_fmu_state()))


@pytest.mark.parametrize("field,value,text", [
    ("_call", 0, "unknown fields ['_call']"),
    ("get_real", 0, "unknown fields ['get_real']"),
    ("k", "1", "k = '1' is not a sample index"),
    ("k", 0, "k = 0 is not a sample index"),
    ("k", True, "k = True is not a sample index"),
    ("z", "nan", "z = 'nan' is not a finite number"),
    ("x_hat", 1e309, "x_hat = inf is not a finite number"),
    ("estimator", 1.5, "estimator = 1.5 is not an integer"),
    ("time", [0.0, -1.0, 0.0], "time = [0.0, -1.0, 0.0] is not [t_start, elapsed >= 0"),
    ("flags", {"initialised": 1}, "flags = {'initialised': 1} is not"),
    ("_state", [0.0, 0.01], "hidden state _state = [0.0, 0.01] is not valid"),
    ("_state", [0.0, 0.01, [1, 0.0, 0.0, "x", 0.0]], "hidden state _state"),
    ("R", -1.0, "R = -1.0 is out of range; allowed: R > 0"),
    ("k", 7, "k = 7 and at_sample = True do not match the time 0.001 s after the start (the "
             "next sample there is k = 2)"),
    ("version", "0.0.0", "has version '0.0.0'"),
    ("guid", "0", "has guid '0'"),
    ("model", "Accelerometer", "this is an FMU state of model 'Accelerometer', not of "
                               "DriftEstimator"),
])
def test_state_fields_are_checked_before_anything_is_set(field, value, text):
    s = ready(DriftEstimator)
    s.do_step(0.0, 1e-3)
    good = _state_of(s)
    s.do_step(1e-3, 1e-3)
    before = snapshot(s)
    bad = dict(good, **{field: value})
    s._set_fmu_state(bad)
    log = messages(s)
    assert any(text in m for m in log), log
    assert snapshot(s) == before
    s._set_fmu_state(good)                  # the good state still restores
    assert not messages(s)


def test_deserialised_bytes_are_checked_when_the_shim_asks_and_restored_when_set():
    """The Python side of fmi2DeSerializeFMUstate's check: the class reads bytes into a
    Deserialised (never raising), SHIM_VR = [1] makes the next fmi2SetFMUstate only check it
    (the loader shim's check: nothing changes), and an fmi2SetFMUstate restores it; without the
    shim's word (an FMU built without the shim) the set checks and restores at once, and bytes
    that are no state are refused with the reason."""
    from driftfmu.fmu_src.slave_base import SHIM_VR, Deserialised
    s = ready(DriftEstimator)
    s.do_step(0.0, 1e-3)
    data = json.dumps(s._get_fmu_state()).encode()
    s.do_step(1e-3, 1e-3)
    moved = snapshot(s)
    d = DriftEstimator._fmu_state_from_bytes(data)
    assert type(d) is Deserialised and d.why is None
    s.set_real([SHIM_VR], [1.0])
    s._set_fmu_state(d)               # the check: nothing changed, nothing said
    assert not messages(s) and snapshot(s) == moved
    s._set_fmu_state(d)               # the set
    assert not messages(s) and s.k == 2
    s.do_step(1e-3, 1e-3)
    assert snapshot(s) == moved
    for garbage in (b"hello", b"", b"[1, 2]"):
        bad = DriftEstimator._fmu_state_from_bytes(garbage)
        for shim in (True, False):
            if shim:
                s.set_real([SHIM_VR], [1.0])
            s._set_fmu_state(bad)
            said = messages(s)
            assert len(said) == 1 and "not an FMU state of DriftEstimator" in said[0], said
            assert ("fmi2DeSerializeFMUstate" if shim else "fmi2SetFMUstate") in said[0]
            assert snapshot(s) == moved
    assert DriftEstimator._fmu_state_to_bytes(d) == data


def test_missing_field_is_refused():
    s = ready(Accelerometer)
    good = _state_of(s)
    del good["_lp"]
    s._set_fmu_state(good)
    assert "missing fields ['_lp']" in messages(s)[-1]


@pytest.mark.parametrize("source,target", [("Accelerometer", "DriftEstimator"),
                                           ("DriftEstimator", "Excitation"),
                                           ("Excitation", "Accelerometer")])
def test_state_of_another_model_is_refused(source, target):
    a, b = ready(SLAVES[source]), ready(SLAVES[target])
    before = snapshot(b)
    b._set_fmu_state(_state_of(a))
    assert ("this is an FMU state of model %r, not of %s" % (source, target)) in messages(b)[-1]
    assert snapshot(b) == before


@pytest.mark.parametrize("cls", sorted(SLAVES.values(), key=lambda c: c.__name__))
def test_state_before_initialisation_round_trips(cls):
    s = cls(instance_name="s")
    state = _state_of(s)                      # before initialisation: no hidden state yet
    assert state["model"] == cls.__name__ and state["guid"] == str(s.guid)
    assert state["flags"]["initialised"] is False
    t = cls(instance_name="t")
    t.setup_experiment(0.0)
    t.enter_initialization_mode()
    t.exit_initialization_mode()
    t.do_step(0.0, 1e-3)
    t._set_fmu_state(state)
    assert not messages(t)
    assert t.do_step(0.0, 1e-3) is False     # back before initialisation: cannot step
    assert "initialisation did not complete" in messages(t)[0]


def test_state_restores_between_sample_instants_bit_for_bit():
    a = ready(DriftEstimator)
    put(a, "z", 0.3)
    a.do_step(0.0, 0.4e-3)                   # between instants
    saved = _state_of(a)
    rows = []
    for h in (0.7e-3, 1.3e-3, 0.25e-3):
        put(a, "z", h * 100)
        a.do_step(0.0, h)
        rows.append([get(a, n) for n in ("x_hat", "P", "dc", "z_comp")])
    a._set_fmu_state(saved)
    again = []
    for h in (0.7e-3, 1.3e-3, 0.25e-3):
        put(a, "z", h * 100)
        a.do_step(0.0, h)
        again.append([get(a, n) for n in ("x_hat", "P", "dc", "z_comp")])
    assert again == rows and not messages(a)


# -- overflow: an output that would not be finite is an error, nothing changes -----------------
def test_estimator_measurement_that_overflows_is_refused():
    s = ready(DriftEstimator)
    before = snapshot(s)
    put(s, "z", 1e200)                        # finite: accepted as an input
    assert not messages(s)
    get(s, "dc")
    text = messages(s)[-1]
    assert "would be inf at sample 1" in text and "dc_ekf1" in text, text
    assert s.do_step(0.0, 1e-3) is False
    assert "would be inf at sample 1" in messages(s)[-1]
    put(s, "z", 0.0)                          # a good input: everything as before the bad one
    assert snapshot(s)[1] == before[1]
    assert s.do_step(0.0, 1e-3) is True and all(math.isfinite(get(s, n)) for n in
                                               ("x_hat", "P", "dc_ekf1", "dc", "z_comp"))


def test_filtered_accelerometer_overflow_is_refused():
    s = ready(Accelerometer, fc=100.0)
    put(s, "x", 1e200)
    get(s, "z")
    text = messages(s)[-1]
    assert "z would be nan at sample 1" in text, text   # a3 u^3 = 0 * inf
    assert s.do_step(0.0, 1e-3) is False and "z would be nan" in messages(s)[-1]
    put(s, "x", 0.5)
    assert s.do_step(0.0, 1e-3) is True and math.isfinite(get(s, "z")) and not messages(s)


def test_quantised_accelerometer_overflow_names_the_output():
    s = ready(Accelerometer, bits=12, a2=1e308)
    put(s, "x", 2.0)
    get(s, "z")                                # the ADC cannot round inf: named all the same
    assert "z would be inf at sample 1" in messages(s)[-1]


def test_plain_accelerometer_a2_overflow_at_sample_one_is_refused():
    s = ready(Accelerometer, a2=1e308)
    put(s, "x", 2.0)
    assert get(s, "z") == 0.0                  # the previous value: nothing was computed
    assert "z would be inf at sample 1 (t = 0.0 s)" in messages(s)[-1]


def test_overflow_inside_a_long_step_changes_nothing():
    s = ready(DriftEstimator, process=2, Qh=1e307, P0=0.0)
    assert math.isfinite(get(s, "P")) and not messages(s)
    before = snapshot(s)
    assert s.do_step(0.0, 30e-3) is False     # the covariance grows by Qh per predict
    assert "P would be nan at sample 30 (t = 0.029 s)" in messages(s)[-1]
    assert snapshot(s) == before


def test_parameter_combination_with_non_finite_effective_value_is_refused():
    s = Accelerometer(instance_name="s")
    s.enter_initialization_mode()
    put(s, "a1", 1.7e308)
    put(s, "Vs", 6.0)                          # scales a1 by S(6 V)/S(5 V) = 1.22: inf
    s.exit_initialization_mode()
    assert any("effective a1 = inf" in m for m in messages(s))


# -- outputs in Initialization Mode --------------------------------------------------------------
INIT_CASES = {
    "Excitation": (dict(kind=2, X=2.0, f=100.0, phi=0.5, Xy=1.0, phiy=0.2, drive=1, Qu=0.5), {}),
    "Accelerometer": (dict(a0=5.0, a2=0.1, axes=2, cross=0.1, fc=100.0), dict(x=1.0, y=-0.5)),
    "DriftEstimator": (dict(a0=0.2, a2=0.05, x0=0.3, P0=0.2, bias=1, b0=0.01, Pb0=0.02,
                            kT_bias=1e-3), dict(z=1.5, theta=0.2, T=300.0)),
    "DualDriftEstimator": (dict(a0=0.2, a2=0.05, bx=0.02, by=0.03, x0=0.3, y0=-0.2, P0=0.2,
                                P0y=0.3, rho=0.4), dict(z_x=1.5, z_y=-0.7)),
}


@pytest.mark.parametrize("name", sorted(INIT_CASES))
def test_every_output_in_initialization_mode_is_sample_one(name):
    params, inputs = INIT_CASES[name]
    s = SLAVES[name](instance_name="s")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    for n, v in dict(params, **inputs).items():
        put(s, n, v)
    outputs = [spec["name"] for spec in s.VARIABLES if spec["causality"] == "output"]
    during = {n: get(s, n) for n in outputs}
    s.exit_initialization_mode()
    after = {n: get(s, n) for n in outputs}
    assert not messages(s)
    assert during == after
    starts = {spec["name"]: spec["start"] for spec in s.VARIABLES}
    assert all(during[n] != starts[n] for n in outputs), during   # computed, not the start


def test_accelerometer_output_in_initialization_mode_follows_the_inputs():
    s = Accelerometer(instance_name="s")
    s.enter_initialization_mode()
    put(s, "a0", 5.0)
    put(s, "x", 1.0)
    z = get(s, "z")
    assert z == sensor.measure(1.0, 5.0, 1.0, 0.01, 1e-4, sensor.measurement_noise(1, 1))
    put(s, "x", 2.0)                           # and follows a new input at once
    assert get(s, "z") == sensor.measure(2.0, 5.0, 1.0, 0.01, 1e-4,
                                         sensor.measurement_noise(1, 1))


def test_bad_parameter_in_initialization_mode_is_named_when_an_output_is_read():
    s = Excitation(instance_name="s")
    s.enter_initialization_mode()
    put(s, "Q", -1.0)
    get(s, "x")
    assert "cannot compute the outputs in Initialization Mode: Q = -1.0 is out of range" \
        in messages(s)[-1]


# -- declared ranges agree with what is accepted -------------------------------------------------
def _outside(value, side, integer):
    if integer:
        return value - 1 if side == "min" else value + 1
    return parameters.next_float(value, -math.inf if side == "min" else math.inf)


def _declared(fmu):
    with zipfile.ZipFile(fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    for v in root.find("ModelVariables"):
        element = v[0]
        if v.get("causality") != "parameter":
            continue
        for side in ("min", "max"):
            if element.get(side) is not None:
                integer = element.tag == "Integer"
                value = (int if integer else float)(element.get(side))
                yield v.get("name"), side, value, integer


def _initialises(cls, name, value):
    s = cls(instance_name="s")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    if cls is Excitation and name in ("f",):
        put(s, "kind", 2)
    put(s, name, value)
    s.exit_initialization_mode()
    return s._initialised, messages(s)


@pytest.mark.parametrize("name", sorted(SLAVES))
def test_declared_min_and_max_are_accepted_and_just_outside_is_refused(built_fmus, name, report):
    cls = SLAVES[name]
    checked = []
    for variable, side, value, integer in _declared(built_fmus[name]):
        ok, log = _initialises(cls, variable, value)
        assert ok, (variable, side, value, log)
        outside = _outside(value, side, integer)
        ok, log = _initialises(cls, variable, outside)
        assert not ok, (variable, side, outside)
        assert any(("%s = %r" % (variable, outside)) in m and "allowed" in m for m in log), log
        checked.append("%s %s=%r" % (variable, side, value))
    report("DECLARED RANGES %s: %s" % (name, ", ".join(checked)))
    assert "Ts min=1e-09" in checked


def test_ts_of_the_smallest_double_is_refused():
    ok, log = _initialises(Excitation, "Ts", 2.2e-308)
    assert not ok and "Ts = 2.2e-308 is out of range; allowed: Ts >= 1e-09" in log[-1]


# -- rejected calls change nothing ---------------------------------------------------------------
def test_set_real_with_one_bad_reference_sets_nothing():
    s = ready(Accelerometer)
    put(s, "x", 0.25)
    s.set_real([vr(s, "x"), 999], [0.75, 1.0])
    assert "value reference 999 does not exist" in messages(s)[-1]
    assert get(s, "x") == 0.25
    s.set_real([vr(s, "x"), vr(s, "z")], [0.75, 1.0])
    assert "z is an output" in messages(s)[-1] and get(s, "x") == 0.25
    s.set_real([vr(s, "x"), vr(s, "y")], [0.75, math.nan])
    assert "y = nan is not finite" in messages(s)[-1] and get(s, "x") == 0.25


def test_set_integer_with_one_bad_reference_sets_nothing():
    s = Accelerometer(instance_name="s")
    s.set_integer([vr(s, "seed"), 999], [7, 1])
    assert get(s, "seed") == 1 and "value reference 999 does not exist" in messages(s)[-1]
    s.set_integer([vr(s, "seed"), vr(s, "a0")], [7, 1])
    assert get(s, "seed") == 1 and "a0, a Real variable, not an Integer" in messages(s)[-1]


def test_value_references_print_unsigned():
    s = ready(Accelerometer)
    s.get_real([-2 ** 31, -1])                 # how pythonfmu passes 2^31 and 2^32 - 1
    text = messages(s)[-1]
    assert "2147483648" in text and "4294967295" in text and "-1 " not in text


def test_step_after_terminate_is_refused():
    s = ready(Excitation)
    s.terminate()
    assert s.do_step(0.0, 1e-3) is False
    assert "the instance is terminated" in messages(s)[-1]
    put(s, "seed", 3)
    assert any("the instance is terminated" in m for m in messages(s))
    assert get(s, "seed") == 1


# -- the built FMUs in fmpy (the C path through pythonfmu and the loader shim) ---------------------
def _ready(built_fmus, name):
    inst = Instance(name, built_fmus[name])
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.fmu.exitInitializationMode()
    return inst


def test_fmu_state_pointer_and_bytes_of_another_fmu_are_refused(built_fmus):
    acc, est = _ready(built_fmus, "Accelerometer"), _ready(built_fmus, "DriftEstimator")
    est.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    before = est.fmu.getReal([est.vrs["x_hat"], est.vrs["R"]])
    foreign = acc.fmu.getFMUstate()
    with pytest.raises(Exception, match="status 3"):
        est.fmu.setFMUstate(foreign)
    # the loader shim refuses a pointer it did not hand out before anything reads it
    assert "is not a live state of this loaded copy" in est.messages[-1]
    blob = acc.fmu.serializeFMUstate(foreign)
    with pytest.raises(Exception, match="status 3"):  # refused as the bytes are read
        est.fmu.deSerializeFMUstate(blob)
    assert "this is an FMU state of model 'Accelerometer'" in est.messages[-1]
    assert est.fmu.getReal([est.vrs["x_hat"], est.vrs["R"]]) == before
    est.fmu.doStep(currentCommunicationPoint=1e-3, communicationStepSize=1e-3)
    acc.fmu.freeFMUstate(foreign)
    acc.free()
    est.free()


def test_fmu_state_before_initialisation_and_after_reset(built_fmus):
    for name in ("Accelerometer", "DriftEstimator"):
        inst = Instance(name, built_fmus[name])
        fresh = inst.fmu.getFMUstate()             # fmi2Fatal before the fix
        inst.fmu.setupExperiment(startTime=0.0)
        inst.fmu.enterInitializationMode()
        inst.fmu.exitInitializationMode()
        inst.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        inst.fmu.reset()
        after_reset = inst.fmu.getFMUstate()
        inst.fmu.setFMUstate(fresh)
        blob = inst.fmu.serializeFMUstate(after_reset)
        state = json.loads(blob.decode())
        assert state["flags"]["initialised"] is False
        # the state names the FMU it belongs to: the model description's GUID and version
        assert (state["model"], state["guid"], state["version"]) == (
            name, inst.md.guid, inst.md.version)
        inst.fmu.freeFMUstate(fresh)
        inst.fmu.freeFMUstate(after_reset)
        inst.free()


def test_fmu_outputs_in_initialization_mode_and_unsigned_references(built_fmus, report):
    inst = Instance("acc", built_fmus["Accelerometer"])
    fmu = inst.fmu
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([inst.vrs["a0"], inst.vrs["x"]], [5.0, 1.0])
    z = fmu.getReal([inst.vrs["z"]])[0]
    assert z == sensor.measure(1.0, 5.0, 1.0, 0.01, 1e-4, sensor.measurement_noise(1, 1))
    fmu.exitInitializationMode()
    for ref in (2 ** 31, 2 ** 32 - 1):
        with pytest.raises(Exception, match="status 3"):
            fmu.getReal([ref])
        report("BIG REFERENCE %d -> %s" % (ref, inst.messages[-1]))
        assert "value reference %d does not exist" % ref in inst.messages[-1]
    with pytest.raises(Exception, match="status 3"):
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=math.nan)
    assert "communication step h = nan s; allowed: a finite h > 0" in inst.messages[-1]
    inst.free()


def test_fmus_run_any_step_in_fmpy(built_fmus):
    # fmpy's own driver with a step that is no whole number of sample periods, the default
    # experiment's stop time and the Compliance Checker's 500 output points over it
    from fmpy import simulate_fmu
    for name in ("Excitation", "DriftEstimator", "DualDriftEstimator"):
        for step in (None, 0.7e-3, 2.0 / 500):  # None: fmpy's default from the experiment
            result = simulate_fmu(str(built_fmus[name]), output_interval=step)
            assert len(result) > 400 and all(math.isfinite(v) for row in result
                                             for v in list(row)[1:])


def test_fmus_work_under_python_OO(built_fmus, tmp_path):
    script = textwrap.dedent("""
        import math, sys
        from fmpy import simulate_fmu
        assert sys.flags.optimize == 2 or sys.exit("not -OO")
        for path in sys.argv[1:]:
            r = simulate_fmu(path, stop_time=0.02, output_interval=1.5e-3)
            names = r.dtype.names[1:]
            if len(r) < 10 or not all(math.isfinite(row[n]) for row in r for n in names):
                sys.exit("bad result from %s" % path)
        print("ok")
    """)
    (tmp_path / "oo.py").write_text(script)
    env = dict(os.environ, PYTHONPATH=ROOT)
    run = subprocess.run([sys.executable, "-OO", str(tmp_path / "oo.py")]
                         + [str(built_fmus[n]) for n in SLAVES],
                         capture_output=True, text=True, timeout=BOUND, env=env)
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr[-2000:]


# -- memory the Python side keeps per instantiation ----------------------------------------------
@pytest.mark.qualification
@pytest.mark.parametrize("name", ["DriftEstimator"])
def test_python_memory_kept_per_instantiation_and_error(built_fmus, name, report):
    inst = Instance(name, built_fmus[name])
    fmu = inst.fmu
    ours = [tracemalloc.Filter(True, "*/resources/drift_*", all_frames=True),
            tracemalloc.Filter(True, "*/resources/%s_*" % name, all_frames=True)]

    def cycle(error):
        fmu.fmi2FreeInstance(fmu.component)
        fmu.instantiate(callbacks=inst._callbacks)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        if error:
            try:
                fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=math.nan)
            except Exception:
                pass
        inst.messages.clear()

    figures = {}
    n = 100
    for error in (False, True):
        for _ in range(50):
            cycle(error)
        gc.collect()
        tracemalloc.start(8)
        try:
            snapshots = []
            for _ in range(3):  # the slope between the 2nd and 3rd snapshot: per cycle, not
                for _ in range(n):  # what one instance alive at a snapshot holds
                    cycle(error)
                gc.collect()
                snapshots.append(tracemalloc.take_snapshot())
        finally:
            tracemalloc.stop()
        first, last = snapshots[1], snapshots[2]
        total = sum(s.size_diff for s in last.compare_to(first, "filename")) / n
        mine = sum(s.size_diff for s in last.filter_traces(ours).compare_to(
            first.filter_traces(ours), "filename")) / n
        figures[error] = (total, mine)
    report("MEMORY (tracemalloc, in-process fmpy) %s: %.0f B per instantiate/free cycle in all, "
           "%.0f B of it allocated by the FMU's Python code; with one logged error per cycle "
           "%.0f B (%.0f B by the FMU's code); the rest is kept by pythonfmu 0.7.0's C++ "
           "(strings it passes to Python and never releases)"
           % (name, figures[False][0], figures[False][1], figures[True][0], figures[True][1]))
    assert figures[False][1] < 32 and figures[True][1] < 32   # our code keeps (almost) nothing
    assert figures[False][0] < 4096 and figures[True][0] - figures[False][0] < 256
    inst.free()
