"""The slave classes, exercised in Python without building FMUs (as PythonFMU tests its own).

The bad-input tests also run through the FMUs (the ``make`` fixture): the slave class itself,
the pythonfmu FMU and its native (C) twin, each driven through the same calls, with the same
messages expected."""
import json
import math
import random
import struct

import pytest

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.DualDriftEstimator import DualDriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.fmu_src import slave_base
from driftfmu.fmu_src.slave_base import SlaveBase
from driftfmu.models import chain

from test_hardening import ready

OUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")
SLAVES = {"Excitation": Excitation, "Accelerometer": Accelerometer,
          "DriftEstimator": DriftEstimator}


class _Variable:
    def __init__(self, v):
        self.name, self.value_reference, self.kind = v.name, v.valueReference, v.type


class _Message:
    def __init__(self, msg):
        self.msg = msg


class FmuSlave:
    """An FMU (fmpy's FMU2Slave) behind the slave API these tests use: ``vars``,
    ``get_real``/``set_real``/..., the FMI calls returning True/False, ``log_queue``, and
    ``_get_fmu_state`` (the serialised state)."""

    def __init__(self, path, instance_name):
        from driftfmu.simulations.cosim import Instance
        self.instance_name = instance_name
        self._inst = Instance(instance_name, path)
        self.fmu = self._inst.fmu
        self.vars = {v.valueReference: _Variable(v) for v in self._inst.md.modelVariables}
        self.log_queue = _Queue(self._inst.messages)

    def _ok(self, call, *args):
        try:
            call(*args)
            return True
        except Exception:
            return False

    def _get(self, call, vrs):
        try:
            return call(vrs)
        except Exception:
            return [math.nan] * len(vrs)

    def get_real(self, vrs):
        return self._get(self.fmu.getReal, vrs)

    def get_integer(self, vrs):
        return self._get(self.fmu.getInteger, vrs)

    def set_real(self, vrs, values):
        self._ok(self.fmu.setReal, vrs, values)

    def set_integer(self, vrs, values):
        self._ok(self.fmu.setInteger, vrs, values)

    def setup_experiment(self, start_time):
        return self._ok(self.fmu.setupExperiment, None, start_time)

    def enter_initialization_mode(self):
        return self._ok(self.fmu.enterInitializationMode)

    def exit_initialization_mode(self):
        return self._ok(self.fmu.exitInitializationMode)

    def do_step(self, t, h):
        return self._ok(lambda: self.fmu.doStep(currentCommunicationPoint=t,
                                                communicationStepSize=h))

    def _get_fmu_state(self):
        state = self.fmu.getFMUstate()
        try:
            return bytes(self.fmu.serializeFMUstate(state))
        finally:
            self.fmu.freeFMUstate(state)


class _Queue:
    """``log_queue`` of an FmuSlave: the error messages as the slave logs them
    ("<instance>: <message>")."""

    def __init__(self, messages):
        self._messages = messages

    def __iter__(self):
        for m in self._messages:
            yield _Message(m.split("] ", 1)[1] if "] " in m else m)

    def clear(self):
        del self._messages[:]


@pytest.fixture(params=["slave", "python", "native"])
def make(request):
    """``make(cls, name)``: a slave of class ``cls`` (``slave``), or the FMU built from it
    (``python``: the pythonfmu FMU; ``native``: its C twin), as an object with the slave API."""
    if request.param == "slave":
        return lambda cls, name: cls(instance_name=name)
    fmus = request.getfixturevalue("built_fmus" if request.param == "python" else "native_fmus")
    if request.param == "native":
        fmus = fmus[2]
    made = []

    def make_fmu(cls, name):
        if cls.__name__ not in fmus:
            pytest.skip("%s has no %s FMU" % (cls.__name__, request.param))
        made.append(FmuSlave(fmus[cls.__name__], name))
        return made[-1]
    request.addfinalizer(lambda: [s._inst.free() for s in made])  # (and their folders)
    return make_fmu


class Chain:
    """The three slaves wired as the master wires the FMUs."""

    def __init__(self, start=None, make=None):
        make = make or (lambda cls, name: cls(instance_name=name))
        self.e = make(Excitation, "e")
        self.a = make(Accelerometer, "a")
        self.d = make(DriftEstimator, "d")
        for s in self.slaves:
            for name, value in (start or {}).get(s.instance_name, {}).items():
                set_var(s, name, value)
            s.setup_experiment(0.0)
            s.enter_initialization_mode()
            s.exit_initialization_mode()

    @property
    def slaves(self):
        return (self.e, self.a, self.d)

    def propagate(self):
        set_var(self.a, "x", get(self.e, "x"))
        set_var(self.d, "z", get(self.a, "z"))
        return (get(self.e, "x"), get(self.a, "z")) + tuple(get(self.d, n) for n in OUTS)

    def step(self, t, h):
        return [s.do_step(t, h) for s in self.slaves]


def vr(slave, name):
    return next(v.value_reference for v in slave.vars.values() if v.name == name)


def _is_real(v):
    return getattr(v, "kind", type(v).__name__) == "Real"


def get(slave, name):
    v = slave.vars[vr(slave, name)]
    return (slave.get_real if _is_real(v) else slave.get_integer)([v.value_reference])[0]


def set_var(slave, name, value):
    v = slave.vars[vr(slave, name)]
    (slave.set_real if _is_real(v) else slave.set_integer)([v.value_reference], [value])


def messages(slave):
    out = [m.msg for m in slave.log_queue]
    slave.log_queue.clear()
    return out


def run(c, n, Ts=1e-3):
    rows = [c.propagate()]
    for k in range(2, n + 1):
        assert c.step((k - 2) * Ts, Ts) == [True, True, True]
        rows.append(c.propagate())
    return rows


def test_slaves_equal_models_sample_by_sample():
    rows = run(Chain(), 400)
    ref = chain.simulate(400, 1)
    for i, col in enumerate(("x", "z") + OUTS):
        assert [r[i] for r in rows] == ref[col], col


def test_variables_table_is_complete():
    for cls in (Excitation, Accelerometer, DriftEstimator, DualDriftEstimator):
        for spec in cls.VARIABLES:
            assert spec["description"] and "[" in spec["description"], spec["name"]
        names = {s["name"] for s in cls.VARIABLES}
        for out, deps in cls.DEPENDENCIES.items():
            assert out in names and set(deps) <= names


@pytest.mark.parametrize("slave_cls,name,value,text", [
    (DriftEstimator, "R", -1.0, "R = -1.0 is out of range; allowed: R > 0"),
    (DriftEstimator, "Q", -0.5, "Q = -0.5 is out of range; allowed: Q >= 0"),
    (DriftEstimator, "estimator", 4, "estimator = 4 is out of range; allowed: 1 <= estimator <= 3"),
    (Accelerometer, "a1", 0.0, "a1 = 0.0 is out of range; allowed: a1 != 0"),
    (Excitation, "A", 1.5, "A = 1.5 is out of range; allowed: A > -1 and A < 1"),
    (Excitation, "Ts", 0.0, "Ts = 0.0 is out of range; allowed: Ts >= 1e-09"),
    (Excitation, "rho", -1.5, "rho = -1.5 is out of range; allowed: rho >= -1 and rho <= 1"),
    (Accelerometer, "a1y", 0.0, "a1y = 0.0 is out of range; allowed: a1y != 0"),
    (Accelerometer, "dual", 2, "dual = 2 is out of range; allowed: an integer dual >= 0 and "
     "dual <= 1"),
    (DualDriftEstimator, "R", -1.0, "R = -1.0 is out of range; allowed: R > 0"),
    (DualDriftEstimator, "Qy", -0.5, "Qy = -0.5 is out of range; allowed: Qy >= 0"),
    (DualDriftEstimator, "estimator", 0,
     "estimator = 0 is out of range; allowed: 1 <= estimator <= 3"),
])
def test_bad_parameter_is_logged_at_end_of_initialisation(make, slave_cls, name, value, text):
    s = make(slave_cls, "s")
    set_var(s, name, value)
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    assert any(text in m for m in messages(s))
    assert s.do_step(0.0, 1e-3) is False
    refused = messages(s)[0]  # an FMU's state machine may refuse the step first, in its words
    assert "initialisation did not complete" in refused or (
        isinstance(s, FmuSlave) and "fmi2DoStep is not allowed in" in refused), refused


@pytest.mark.parametrize("slave_cls,switch", [(Excitation, "kind"), (DriftEstimator, "process")])
def test_nyquist_check_leaves_a_bad_Ts_to_its_own_message(slave_cls, switch):
    s = slave_cls(instance_name="s")
    set_var(s, switch, 2)
    set_var(s, "Ts", 0.0)
    s.exit_initialization_mode()
    assert any("Ts = 0.0 is out of range; allowed: Ts >= 1e-09" in m for m in messages(s))
    assert not [m for m in messages(s) if "internal error" in m or "Nyquist" in m]


def test_nyquist_is_checked_for_the_sinusoid():
    s = Excitation(instance_name="s")
    set_var(s, "kind", 2)
    set_var(s, "f", 600.0)
    s.exit_initialization_mode()
    assert any("at or above the Nyquist rate" in m and "f = 600.0" in m for m in messages(s))


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_input_is_rejected_and_outputs_stay_finite(make, value):
    c = Chain(make=make)
    c.propagate()
    before = get(c.d, "z")
    set_var(c.d, "z", value)
    assert "z = %r is not finite" % value in messages(c.d)[0]
    assert get(c.d, "z") == before
    assert all(math.isfinite(get(c.d, n)) for n in OUTS)


def test_parameter_cannot_change_after_initialisation(make):
    c = Chain(make=make)
    set_var(c.a, "R", 0.5)
    assert "R is a fixed parameter" in messages(c.a)[0]
    assert get(c.a, "R") == 1e-4


@pytest.mark.parametrize("h", [math.nan, math.inf, -math.inf, 0.0, -1e-3])
def test_step_must_be_finite_and_positive(h):
    c = Chain()
    before = [s._get_fmu_state() for s in c.slaves]
    assert c.step(0.0, h) == [False, False, False]
    assert messages(c.e)[0] == "e: communication step h = %r s; allowed: a finite h > 0" % h
    assert [s._get_fmu_state() for s in c.slaves] == before


def test_step_of_too_many_samples_is_refused_and_changes_nothing():
    c = Chain()
    before = [s._get_fmu_state() for s in c.slaves]
    assert c.step(0.0, 1e300) == [False, False, False]
    text = messages(c.d)[0]
    assert "h = 1e+300 s spans more than 1000000 sample instants of Ts = 0.001 s" in text
    assert "allowed: at most MAX_SAMPLES_PER_STEP = 1000000" in text
    assert [s._get_fmu_state() for s in c.slaves] == before
    assert c.step(0.0, 1e-3) == [True, True, True]  # still usable


def test_fmu_state_restores_hidden_state_bit_for_bit():
    c = Chain()
    run(c, 50)
    states = [json.loads(json.dumps(s._get_fmu_state())) for s in c.slaves]  # as serialised
    after = [c.step(0.049 + i * 1e-3, 1e-3) and c.propagate() for i in range(30)]
    for s, st in zip(c.slaves, states):
        s._set_fmu_state(st)
    again = [c.step(0.049 + i * 1e-3, 1e-3) and c.propagate() for i in range(30)]
    assert again == after


def test_multi_sample_step_advances_the_sample_index():
    c = Chain()
    c.propagate()
    assert c.step(0.0, 5e-3) == [True, True, True]
    x, z = c.propagate()[:2]
    ref = chain.simulate(6, 1)
    assert (x, z) == (ref["x"][5], ref["z"][5])


def test_output_cannot_be_set(make):
    c = Chain(make=make)
    set_var(c.a, "z", 1.0)
    assert "z is an output; only parameters and inputs can be set" in messages(c.a)[0]


def _general_path(cls):
    """``cls`` with the do_step of before its common-step fast path: every step through
    ``_step`` (same class name and module, so the same GUID and FMU state)."""
    def do_step(self, current_time, step_size):
        try:
            self._step(step_size)
        except Exception as exc:
            return self._failed("_step", exc)
        return True
    return type(cls.__name__, (cls,), {"do_step": do_step, "__module__": cls.__module__})


#: Configurations the fast paths must agree with the general ones in (parameters set in
#: Initialization Mode): the defaults and each branch of a slave's sample.
PATH_CONFIGS = [
    (Excitation, {}), (Excitation, {"drive": 1, "Qu": 0.5, "B": 0.3, "Qy": 0.01, "rho": 0.5}),
    (Excitation, {"kind": 2, "drive": 0}),
    (Accelerometer, {}), (Accelerometer, {"fc": 100.0, "axes": 2, "a3": 0.01}),
    (Accelerometer, {"dual": 1}), (Accelerometer, {"noise": 0}),
    (DriftEstimator, {}), (DriftEstimator, {"process": 2, "estimator": 3, "a3": 0.01}),
    (DriftEstimator, {"B": 0.5, "a4": 0.001, "estimator": 2}),
    (DriftEstimator, {"bias": 1, "Qb": 1e-8, "tau_b": 0.1, "a2": 0.05, "estimator": 3}),
    (DriftEstimator, {"kT_bias": 1e-3, "kT_scale": 1e-4, "process": 2}),
    (DualDriftEstimator, {}), (DualDriftEstimator, {"process": 2}),
]


def _observed(s):
    """Everything a call may change: the FMU state, the pending sample, the flags."""
    return json.dumps(s._get_fmu_state()), repr(s._pending), s._dirty, messages(s)


@pytest.mark.parametrize("cls,config", PATH_CONFIGS,
                         ids=["%s-%d" % (c.__name__, i) for i, (c, _) in enumerate(PATH_CONFIGS)])
def test_the_fast_paths_give_the_general_paths_bits_and_refusals(cls, config):
    """A slave and the same slave through the general paths only (every step by ``_step``)
    driven by the same random calls (steps of whole, near-whole, fractional and bad sizes;
    inputs finite, overflowing or not finite; reads; states) agree after every call, in the
    results, the FMU state, the pending sample and the log lines."""
    import random
    import zlib
    rng = random.Random(zlib.crc32(repr((cls.__name__, sorted(config.items()))).encode()))
    fast, general = cls(instance_name="s"), _general_path(cls)(instance_name="s")
    pair = (fast, general)
    reals = {s["name"]: vr_ for vr_, s in fast._specs.items() if s["type"] == "Real"}
    inputs = [vr_ for vr_, s in fast._specs.items() if s["causality"] == "input"]
    ints = {s["name"]: vr_ for vr_, s in fast._specs.items() if s["type"] == "Integer"}
    Ts = fast.Ts
    steps = [Ts] * 12 + [Ts * (1 + 5e-7), Ts * (1 - 5e-7), Ts * (1 + 3e-6), 0.3 * Ts,
                         0.7 * Ts, 2 * Ts, 2.5 * Ts, 1e-9 * Ts, 1, math.nan, math.inf, -Ts, 0.0]
    values = [lambda: rng.gauss(0.0, 1.0)] * 6 + [lambda: 1e200, lambda: -1e300,
                                                   lambda: math.nan, lambda: math.inf]
    for s in pair:
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        for name, value in config.items():
            (s.set_integer if name in ints else s.set_real)(
                [(ints if name in ints else reals)[name]], [value])
        s.exit_initialization_mode()
    assert _observed(fast) == _observed(general)
    saved = None
    for i in range(1500):
        r = rng.random()
        if r < 0.35:
            h = rng.choice(steps)
            call = ("do_step", 0.0, h)
        elif r < 0.6:
            vrs = rng.sample(inputs, rng.randint(1, len(inputs)))
            call = ("set_real", vrs, [rng.choice(values)() for _ in vrs])
        elif r < 0.9:
            call = ("get_real", rng.sample(sorted(reals.values()), rng.randint(1, 3)))
        elif r < 0.94 or saved is None:
            saved = fast._get_fmu_state()
            call = ("_get_fmu_state",)
        elif r < 0.985:
            call = ("_set_fmu_state", json.loads(json.dumps(saved)))
        else:
            call = ("terminate",)
        results = [getattr(s, call[0])(*call[1:]) for s in pair]
        if call[0] == "get_real":
            results = [[repr(v) for v in res] for res in results]  # (nan == nan)
        assert results[0] == results[1], (i, call)
        assert _observed(fast) == _observed(general), (i, call)


@pytest.mark.parametrize("cls", [Excitation, Accelerometer, DriftEstimator, DualDriftEstimator])
def test_show_assigns_the_outputs_in_the_order_of_OUTPUTS(cls):
    """``OUTPUTS`` names every output variable once, and a slave's ``show`` (written out for
    speed) assigns a tuple of them, or of a prefix of them, as the base class's does."""
    declared = [s["name"] for s in cls.VARIABLES if s["causality"] == "output"]
    assert sorted(cls.OUTPUTS) == sorted(declared) and len(set(cls.OUTPUTS)) == len(declared)
    shortest = 1 if cls is Accelerometer else len(cls.OUTPUTS)
    for n in range(shortest, len(cls.OUTPUTS) + 1):
        mine, base = cls(instance_name="s"), cls(instance_name="s")
        values = tuple(float(i + 10) for i in range(n))
        mine.show(values)
        SlaveBase.show(base, values)
        assert [getattr(mine, v) for v in declared] == [getattr(base, v) for v in declared]
        assert [getattr(mine, v) for v in cls.OUTPUTS[:n]] == list(values)


def test_the_estimators_hidden_check_follows_the_process_model():
    """DriftEstimator checks its hidden state after a sample only for the harmonic model (whose
    d, P12, P22 reach no output); prepare picks the check again whenever process may change."""
    from driftfmu.models import harmonic
    s = DriftEstimator(instance_name="s")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    assert s.get_real([vr(s, "x_hat")]) == [0.0] and s.hidden_valid is None
    set_var(s, "process", harmonic.HARMONIC)
    s.get_real([vr(s, "x_hat")])
    assert s.hidden_valid.__func__ is DriftEstimator.hidden_valid
    state = harmonic.estimator_init(harmonic.HARMONIC, 0.0, 1.0)
    assert s.hidden_valid({"_state": state._replace(P12=math.inf)}) is False
    set_var(s, "process", harmonic.GAUSS_MARKOV)
    s.exit_initialization_mode()
    assert s.hidden_valid is None and "hidden_valid" in s.__dict__


# -- Blocks: what depends on k alone, computed for many samples at once ------------------------
def _bits(values):
    return [struct.pack("<d", v) for v in values]


def test_blocks_give_the_float_paths_bits_in_any_order_of_samples():
    """Forward across block ends, backwards (a state restored), jumps, and the samples outside
    the blocks' range (0, past 2**62): every value has the bits of the float path."""
    from driftfmu.models import excitation, noise
    rng = random.Random(2024)
    size = slave_base.Blocks.SIZE
    order = (list(range(1, 2 * size + 3)) + list(range(3 * size, size - 5, -1))
             + [rng.randint(1, 10 ** 9) for _ in range(200)] + [0, 2 ** 62 + 7, 5])
    for f in (lambda k: noise.normal(123456789, noise.STREAM_MEASUREMENT, k),
              lambda k: excitation.sine(k, 1.5, 150.0, 1e-4, 0.7),
              lambda k: excitation.input_sample(1, 42, k, 0.3)):
        block = slave_base.Blocks(f)
        assert _bits([block(k) for k in order]) == _bits([f(k) for k in order])
        assert all(type(block(k)) is float for k in order[:5])


def test_a_blocks_run_is_its_values_from_k_to_the_blocks_end_or_n_of_them():
    """Blocks.run(k) is the values from sample k to the end of its block; run(k, n) the first n
    of them, or all where fewer are left (n on both sides of what is left, n = 0 and 1); each
    with the float path's bits."""
    from driftfmu.models import noise
    f = lambda k: noise.normal(7, noise.STREAM_MEASUREMENT, k)  # noqa: E731
    size = slave_base.Blocks.SIZE
    block = slave_base.Blocks(f)
    assert _bits(block.run(1)) == _bits([f(k) for k in range(1, size + 1)])
    k = size - 3  # four values left in the block of 1 .. SIZE
    assert len(block.run(k)) == 4
    for n, want in ((0, 0), (1, 1), (3, 3), (4, 4), (5, 4), (10 ** 6, 4)):
        got = block.run(k, n)
        assert len(got) == want and _bits(got) == _bits([f(j) for j in range(k, k + want)]), n
    assert _bits(block.run(size + 2, 2)) == _bits([f(size + 2), f(size + 3)])  # the next block
    # no run where f runs on the one k: a block that is not all finite, and a sample past
    # 2**62 (the one beyond a block that ends there included)
    import numpy as np
    bad = slave_base.Blocks(lambda k: np.where(np.asarray(k) == 9, math.inf, 0.5))
    assert bad.run(3) is None and bad.run(3, 2) is None
    top = slave_base.Blocks(f)
    k0 = 2 ** 62 - 10
    assert len(top.run(k0)) == size  # the block k0 .. k0 + SIZE - 1
    assert top.run(k0 + size) is None and top.run(k0 + size, 1) is None


def test_blocks_run_f_sample_by_sample_without_numpy(monkeypatch):
    monkeypatch.setattr(slave_base, "_NUMPY", None)
    calls = []
    block = slave_base.Blocks(lambda k: calls.append(k) or k * 0.5)
    assert [block(k) for k in (1, 2, 3, 2)] == [0.5, 1.0, 1.5, 1.0]
    assert calls == [1, 2, 3, 2]


def test_numpy_is_used_only_where_its_arrays_give_the_float_bits(monkeypatch):
    """The once-per-process check of the host's NumPy: it passes here, it covers the draws'
    tails, and a function whose array path has other bits turns the blocks off."""
    import numpy as np
    assert slave_base._exact_numpy() is np
    draws = [slave_base._SELF_TEST[0](k) for k in range(1, 257)]
    assert min(draws) < -1.98 and max(draws) > 1.98  # both tails of Acklam's quantile

    def other_bits(k):  # an array path one ulp off at one sample
        if isinstance(k, np.ndarray):
            return np.where(k == 200, np.nextafter(0.5, 1.0), 0.5)
        return 0.5

    monkeypatch.setattr(slave_base, "_SELF_TEST", slave_base._SELF_TEST + (other_bits,))
    assert slave_base._exact_numpy() is None
    monkeypatch.setattr(slave_base, "_NUMPY", False)
    calls = []
    block = slave_base.Blocks(lambda k: calls.append(k) or 1.0)
    assert block(7) == 1.0 and calls == [7]  # the one sample, not a block


@pytest.mark.parametrize("imported", [False, True])
def test_blocks_wait_for_numpy_only_where_the_host_has_not_imported_it(monkeypatch, imported):
    """A C host's Python has not imported NumPy: the first WARM_UP samples run one by one (a
    short run never imports it); a Python host's blocks start at once."""
    import numpy as np
    monkeypatch.setattr(slave_base, "_numpy_imported", lambda: imported)
    kinds = []

    def f(k):
        kinds.append(type(k))
        return k * 0.25

    block = slave_base.Blocks(f)
    n = slave_base.Blocks.WARM_UP + 10
    assert [block(k) for k in range(1, n + 1)] == [k * 0.25 for k in range(1, n + 1)]
    one_by_one = 0 if imported else slave_base.Blocks.WARM_UP
    assert kinds[:one_by_one] == [int] * one_by_one and kinds[one_by_one] is np.ndarray


def test_a_block_that_is_not_finite_runs_f_sample_by_sample():
    """Where the array path overflows, the float path runs, so a failure is what it was."""
    import numpy as np

    def f(k):
        if isinstance(k, np.ndarray):
            return np.where(k == 5, np.inf, k * 1.0)
        if k == 5:
            raise OverflowError("sample 5")
        return k * 1.0

    block = slave_base.Blocks(f)
    assert block(4) == 4.0 and block(6) == 6.0
    with pytest.raises(OverflowError, match="sample 5"):
        block(5)


#: Slaves whose samples read blocks: each branch of a draw, a sinusoid or a drive.
BLOCK_CONFIGS = PATH_CONFIGS[:6] + [
    (Excitation, {"drive": 2, "Xu": 0.4, "fu": 30.0, "B": 0.2}),
    (Excitation, {"kind": 2, "drive": 1, "Qu": 0.2, "Xy": 0.3, "phiy": 1.0}),
]


@pytest.mark.parametrize("cls,config", BLOCK_CONFIGS,
                         ids=["%s-%d" % (c.__name__, i) for i, (c, _) in enumerate(BLOCK_CONFIGS)])
def test_slaves_give_the_same_bits_with_and_without_blocks(monkeypatch, cls, config):
    """A slave's samples from blocks equal its samples from the float path (NumPy hidden),
    over whole, multi-sample and fractional steps and a state restored backwards."""
    def outputs(numpy_off):
        if numpy_off:
            monkeypatch.setattr(slave_base, "_NUMPY", None)
        s = ready(cls, **config)
        reals = sorted(vr for vr, v in s.vars.items() if _is_real(v))
        rows, t, h, state = [], 0.0, 1e-3, None
        for i in range(2600):
            if cls is Accelerometer:
                set_var(s, "x", math.sin(0.01 * i))
                set_var(s, "y", math.cos(0.02 * i))
            rows.append(s.get_real(reals))
            step = h * (7 if i % 500 == 3 else 0.5 if i % 700 == 9 else 1)
            assert s.do_step(t, step)
            t += step
            if i == 1500:
                state = (s._get_fmu_state(), t)
            if i == 2400:
                s._set_fmu_state(state[0])
                t = state[1]
        monkeypatch.undo()
        return _bits(v for row in rows for v in row)

    assert outputs(False) == outputs(True)


def test_a_state_restore_keeps_the_blocks_and_a_new_parameter_makes_new_ones():
    """A master that rolls back every step pays no new block; a parameter whose bits changed
    (-0.0 is not 0.0: X = -0.0 gives -0.0) gets its own."""
    s = ready(Excitation, kind=2)
    state = s._get_fmu_state()
    sx, sy = s._sx, s._sy
    s.do_step(0.0, 1e-3)
    s._set_fmu_state(state)
    assert (s._sx, s._sy) == (sx, sy)
    assert s.blocks("sx", (s.X, s.f, s.Ts, s.phi), None) is sx
    assert s.blocks("sx", (-0.0, s.f, s.Ts, s.phi), None) is not sx
