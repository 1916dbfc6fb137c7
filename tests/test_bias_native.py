"""The bias state and the class-2 offset in the built FMUs: the pythonfmu FMU and the native
twins (FMI 2.0 and 3.0) give the slave class's bits over random inputs (z, the tilt theta and the
temperature T) and steps, and an FMU state serialised in one instance and deserialised in
another continues with the same bits; a native state whose bias part does not fit its
parameters is refused with the reason.
"""
import random

import pytest

from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.simulations.cosim import Instance

from test_slaves import get, set_var  # noqa: F401

pytestmark = pytest.mark.integration

CONFIGS = [dict(bias=1, Qb=1e-8, tau_b=0.05, b0=0.002, Pb0=1e-3, A=0.6, a2=0.05, a3=0.01,
                B=0.3, kT_bias=1e-3, kT_scale=2e-4, T0=300.0),
           dict(bias=1, Qb=0.0, a2=0.2, estimator=2),
           dict(kT_bias=-2e-3, process=2, f=40.0, estimator=3)]


def _instance(path, name, values):
    inst = Instance(name, path)
    inst.fmu.setupExperiment(startTime=0.0)
    inst.fmu.enterInitializationMode()
    inst.set(values)
    inst.fmu.exitInitializationMode()
    return inst


def _outputs(inst):
    return inst.fmu.getReal([inst.vrs[n] for n in DriftEstimator.OUTPUTS])


def _slave(values):
    s = DriftEstimator(instance_name="d")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    for n, v in values.items():
        set_var(s, n, v)
    s.exit_initialization_mode()
    return s


def _inputs(rng):
    return dict(z=rng.gauss(0.02, 0.1), u=rng.gauss(0, 1), theta=rng.choice((0.0, 0.3, -0.2)),
                T=rng.uniform(290, 310))


@pytest.mark.parametrize("config", range(len(CONFIGS)))
def test_the_fmus_give_the_slaves_bits_and_carry_the_state_across_instances(backend_fmus,
                                                                           config):
    values = CONFIGS[config]
    rng = random.Random(4601 + config)
    plan = [(_inputs(rng), 1e-3 * rng.choice((1, 1, 2, 0.5, 2.5))) for _ in range(120)]
    ref = _slave(values)
    inst = _instance(backend_fmus["DriftEstimator"], "d", values)
    t, saved, rows = 0.0, None, []
    try:
        for i, (inputs, h) in enumerate(plan):
            inst.set(inputs)
            for n, v in inputs.items():
                set_var(ref, n, v)
            got, want = _outputs(inst), [get(ref, n) for n in DriftEstimator.OUTPUTS]
            assert got == want, (i, inputs)
            rows.append(got)
            if i == 60:
                state = inst.fmu.getFMUstate()
                saved = bytes(inst.fmu.serializeFMUstate(state))
                inst.fmu.freeFMUstate(state)
            inst.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            assert ref.do_step(t, h)
            t += h
        assert any(r[7] != 0.0 for r in rows) == (values.get("bias") == 1)  # b_hat moves
        assert any(r[10] != 0.0 for r in rows)                             # dc_class2 too
        # the state saved at step 60, deserialised in a fresh instance: the same bits again
        other = _instance(backend_fmus["DriftEstimator"], "d2", values)
        try:
            state = other.fmu.deSerializeFMUstate(saved)
            other.fmu.setFMUstate(state)
            other.fmu.freeFMUstate(state)
            t = sum(h for _, h in plan[:60])
            for i, (inputs, h) in enumerate(plan[60:80], start=60):
                other.set(inputs)
                assert _outputs(other) == rows[i], i
                other.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
                t += h
        finally:
            other.fmu.terminate()
            other.free()
    finally:
        inst.fmu.terminate()
        inst.free()


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("path,value,text", [
    ("h.bias.b", 0.25, "hidden bias = (0.25, 0.0, 0.0) does not belong to bias = 0; allowed: "
                       "(0.0, 0.0, 0.0) with bias = 0 (no bias state)"),
    ("h.bias_pending.Pbb", 1e-3, "hidden bias_pending = (0.0, 0.0, 0.001) does not belong to "
                                 "bias = 0"),
])
def test_a_native_state_with_a_bias_part_and_bias_0_is_refused(native_fmus, version, path,
                                                               value, text):
    from fuzz import native_state as ns
    path_fmu = native_fmus[version]["DriftEstimator"]
    inst = _instance(path_fmu, "d", {})
    try:
        inst.fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        state = inst.fmu.getFMUstate()
        data = bytes(inst.fmu.serializeFMUstate(state))
        inst.fmu.freeFMUstate(state)
        S = ns.snapshot_type(inst.unzipdir)
        with pytest.raises(Exception):
            inst.fmu.deSerializeFMUstate(ns.crafted(S, data, path, value))
        assert any(text in m for m in inst.messages), inst.messages
        assert "refused" in inst.messages[-1] and "nothing was changed" in inst.messages[-1]
        # and with the bias state on, the same values are a valid state
        on = _instance(path_fmu, "d2", dict(bias=1, Pb0=0.0, b0=0.25))
        try:
            state = on.fmu.getFMUstate()
            good = bytes(on.fmu.serializeFMUstate(state))
            on.fmu.freeFMUstate(state)
            assert ns.read(S, good).h.bias.b == 0.25
            on.fmu.freeFMUstate(on.fmu.deSerializeFMUstate(good))
        finally:
            on.free()
    finally:
        inst.free()
