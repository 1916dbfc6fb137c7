"""What real masters do to an FMU: reset, many instances, state save/restore, long steps,
thousands of instantiations, and errors that must reach the host's logger."""
import gc
import os

import pytest

from driftfmu.fmu_src.builder import NAMES
from driftfmu.models import chain
from driftfmu.simulations.cosim import Instance
from driftfmu.simulations.gaussian import CONNECTIONS, FMU_NAMES

pytestmark = pytest.mark.integration
OUTS = ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]


@pytest.fixture
def built_fmus(backend_fmus):
    """Every test of this module runs on every backend: the pythonfmu FMUs and their native
    twins, FMI 2.0 and FMI 3.0 (``backend_fmus``, tests/conftest.py)."""
    return backend_fmus


class Wired:
    """The three FMUs in one process, wired like the master wires them."""

    def __init__(self, built_fmus, suffix="", logging_on=False):
        self.inst = {n: Instance(n + suffix, built_fmus[n], logging_on=logging_on)
                     for n in FMU_NAMES}
        for i in self.inst.values():
            i.fmu.setupExperiment(startTime=0.0)
            i.fmu.enterInitializationMode()
            i.fmu.exitInitializationMode()
        self.t = 0.0

    def propagate(self):
        for s, o, d, i in CONNECTIONS:
            src, dst = self.inst[s], self.inst[d]
            dst.fmu.setReal([dst.vrs[i]], src.fmu.getReal([src.vrs[o]]))
        e, a, d = (self.inst[n] for n in FMU_NAMES)
        return tuple(e.fmu.getReal([e.vrs["x"]]) + a.fmu.getReal([a.vrs["z"]])
                     + d.fmu.getReal([d.vrs[n] for n in OUTS]))

    def step(self, h=1e-3):
        for i in self.inst.values():
            i.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h
        return self.propagate()

    def run(self, n):
        return [self.propagate()] + [self.step() for _ in range(n - 1)]

    def free(self):
        for i in self.inst.values():
            i.free()


def reference(n, seed=1):
    ref = chain.simulate(n, seed)
    return [tuple(ref[c][k] for c in ["x", "z"] + OUTS) for k in range(n)]


def test_reset_returns_an_instance_to_its_start(built_fmus):
    w = Wired(built_fmus)
    first = w.run(40)
    for i in w.inst.values():
        i.fmu.reset()
        i.fmu.setupExperiment(startTime=0.0)
        i.fmu.enterInitializationMode()
        i.fmu.exitInitializationMode()
    w.t = 0.0
    assert w.run(40) == first == reference(40)
    w.free()


def test_instances_in_one_process_stay_independent(built_fmus):
    a, b = Wired(built_fmus, "_a"), Wired(built_fmus, "_b")
    # b gets another seed and another a2; interleave their steps
    for inst in b.inst.values():
        inst.fmu.reset()
        inst.fmu.setupExperiment(startTime=0.0)
        inst.fmu.enterInitializationMode()
    b.inst["Excitation"].set({"seed": 7})
    b.inst["Accelerometer"].set({"seed": 7, "a2": 0.05})
    b.inst["DriftEstimator"].set({"a2": 0.05})
    for inst in b.inst.values():
        inst.fmu.exitInitializationMode()
    ra, rb = [a.propagate()], [b.propagate()]
    for _ in range(59):
        ra.append(a.step())
        rb.append(b.step())
    assert ra == reference(60)
    ref_b = chain.simulate(60, 7, a2=0.05)
    assert [r[0] for r in rb] == ref_b["x"] and [r[2 + 2] for r in rb] == ref_b["dc_ekf1"]
    a.free()
    b.free()


@pytest.mark.parametrize("serialise", [False, True])
def test_fmu_state_continues_bit_for_bit(built_fmus, serialise):
    w = Wired(built_fmus)
    w.run(100)
    saved = {}
    for n, i in w.inst.items():
        st = i.fmu.getFMUstate()
        if serialise:
            blob = i.fmu.serializeFMUstate(st)
            i.fmu.freeFMUstate(st)
            st = i.fmu.deSerializeFMUstate(blob)
        saved[n] = st
    t = w.t
    after = [w.step() for _ in range(50)]
    for n, i in w.inst.items():
        i.fmu.setFMUstate(saved[n])
        i.fmu.freeFMUstate(saved[n])
    w.t = t
    assert [w.step() for _ in range(50)] == after == reference(150)[100:]
    w.free()


def test_communication_step_of_several_sample_periods(built_fmus):
    w = Wired(built_fmus)
    w.propagate()
    row = w.step(h=5e-3)  # five samples in one step: now at sample 6
    ref = reference(6)
    assert row[:2] == ref[5][:2]
    # the estimator saw z at samples 1 and 6 only; its state matches the filter run that way
    from driftfmu.models import ekf
    x, P = ekf.step(0.0, 0.01, ref[0][1], 0.0, 1.0, 0.01, 0.0, 0.01, 1e-4)
    for _ in range(4):
        x, P = ekf.predict(x, P, 0.0, 0.01)
    x, P = ekf.step(x, P, ref[5][1], 0.0, 1.0, 0.01, 0.0, 0.01, 1e-4)
    assert row[2:4] == (x, P)
    w.free()


def test_variable_step_size(built_fmus):
    w = Wired(built_fmus)
    w.propagate()
    rows = [w.step(h) for h in (1e-3, 3e-3, 2e-3)]  # samples 2, 5, 7
    ref = reference(7)
    assert [r[0] for r in rows] == [ref[1][0], ref[4][0], ref[6][0]]
    w.free()


def _rss_bytes():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.qualification
@pytest.mark.parametrize("name", NAMES)
def test_thousand_instantiate_free_cycles_leave_memory_flat(built_fmus, name, report):
    inst = Instance(name, built_fmus[name])
    fmu = inst.fmu

    def cycle():
        fmu.fmi2FreeInstance(fmu.component)
        fmu.instantiate(callbacks=inst._callbacks)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)

    for _ in range(100):  # warm-up: allocator pools, import caches
        cycle()
    gc.collect()
    before = _rss_bytes()
    for _ in range(1000):
        cycle()
    gc.collect()
    growth = _rss_bytes() - before
    bound = 8 * 1024 * 1024  # 8 KiB a cycle at most: a leak of one instance would exceed it
    report("MEMORY %s: resident memory grew %.1f KiB over 1000 instantiate/free cycles "
           "(bound %d KiB)" % (name, growth / 1024, bound // 1024))
    assert growth < bound
    inst.free()


@pytest.mark.parametrize("name", ["DriftEstimator", "DualDriftEstimator"])
def test_errors_reach_the_logger_with_debug_logging_off(built_fmus, name):
    inst = Instance("quiet", built_fmus[name], logging_on=False)
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.set({"R": -2.0})
    with pytest.raises(Exception, match="status 3"):
        inst.fmu.exitInitializationMode()
    print(inst.messages)
    assert any("R = -2.0 is out of range; allowed: R > 0" in m and "[error]" in m
               for m in inst.messages)
    inst.free()


def test_info_messages_stay_quiet_with_debug_logging_off(built_fmus):
    w = Wired(built_fmus)
    w.run(10)
    assert all(not i.messages for i in w.inst.values())
    w.free()


@pytest.mark.parametrize("name", ["Accelerometer", "DualDriftEstimator"])
@pytest.mark.parametrize("call", ["getReal", "getInteger", "setInteger", "getBoolean"])
def test_bad_value_reference_is_an_error_not_a_crash(built_fmus, call, name, report):
    inst = Instance("badref", built_fmus[name])
    fmu = inst.fmu
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    args = {"getReal": ([999],), "getInteger": ([999],), "setInteger": ([999], [1]),
            "getBoolean": ([0],)}[call]  # 0 is the Real a0: not a Boolean
    with pytest.raises(Exception, match="status 3"):
        getattr(fmu, call)(*args)
    report("BAD REFERENCE %s%s -> %s" % (call, args, inst.messages[-1]))
    assert inst.messages and "[error]" in inst.messages[-1]
    # the instance is still usable, and freeing it is safe
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    assert fmu.getReal([inst.vrs["R"]]) == [1e-4]
    inst.free()


@pytest.mark.parametrize("name", NAMES)
def test_garbage_serialised_state_is_refused(built_fmus, name):
    inst = Instance("garbage", built_fmus[name])
    fmu = inst.fmu
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    with pytest.raises(Exception, match="status 3"):  # refused when read or when set
        state = fmu.deSerializeFMUstate(b"not a state")
        fmu.setFMUstate(state)
    assert "not an FMU state of %s" % name in inst.messages[-1]
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    inst.free()
