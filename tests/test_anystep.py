"""Any communication step: the sampled-data rule of fmu_src/slave_base.py against models/.

Random step sequences (shorter than Ts, 2.5 Ts, mixed) must give, at every communication point,
what a reference computed sample by sample from models/ gives with the same held inputs: sample
``k`` (instant ``(k - 1) Ts``) is processed with the inputs set at the communication point that
starts the step it falls in; at a sample instant the outputs are that sample's (feedthrough),
between instants they hold the last sample's; the DriftEstimator updates with ``z`` at the first
instant of a step and predicts through the others.
"""
import math
import random
from fractions import Fraction

import pytest

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.models import adxl203, chain, drift, excitation, harmonic

TS = 1e-3
OUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp")

#: (Excitation, Accelerometer, DriftEstimator) start values of the two chains tested.
LETTER = ({}, {}, {})
ADXL = (dict(kind=2, X=1.0, f=150.0, phi=0.3, Xy=0.5, phiy=1.0, seed=3),
        dict(adxl203.ADXL203, seed=3),
        dict(a0=2.5, a1=1.0, a2=0.01, R=1e-4, process=2, f=150.0, x0=0.0, P0=1.0))


def _vr(slave, name):
    return next(v.value_reference for v in slave.vars.values() if v.name == name)


def _set(slave, name, value):
    v = slave.vars[_vr(slave, name)]
    call = slave.set_real if type(v).__name__ == "Real" else slave.set_integer
    call([v.value_reference], [value])


def _get(slave, name):
    return slave.get_real([_vr(slave, name)])[0]


def _chain(start):
    slaves = (Excitation(instance_name="e"), Accelerometer(instance_name="a"),
              DriftEstimator(instance_name="d"))
    for s, values in zip(slaves, start):
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        for name, value in values.items():
            _set(s, name, value)
        s.exit_initialization_mode()
        assert not s.log_queue, [m.msg for m in s.log_queue]
    return slaves


def _point(slaves):
    """Gauss-Seidel at one communication point: x -> Accelerometer, z -> DriftEstimator."""
    e, a, d = slaves
    _set(a, "x", _get(e, "x"))
    _set(a, "y", _get(e, "y"))
    _set(d, "z", _get(a, "z"))
    return (_get(e, "x"), _get(a, "z"), _get(a, "z_y")) + tuple(_get(d, n) for n in OUTS)


def run_fmus(start, quotients):
    """The three slaves stepped by ``h_i = q_i Ts``; one row per communication point."""
    slaves = _chain(start)
    rows, t = [_point(slaves)], 0.0
    for q in quotients:
        h = float(q) * TS
        assert [s.do_step(t, h) for s in slaves] == [True, True, True], \
            [m.msg for s in slaves for m in s.log_queue]
        t += h
        rows.append(_point(slaves))
    return rows


def reference(start, quotients):
    """The same rows, sample by sample from models/ (positions in samples kept exact)."""
    ex = dict(kind=excitation.GAUSSIAN, A=0.0, Q=0.01, x0=0.0, X=1.0, f=150.0, phi=0.0,
              Xy=0.0, phiy=0.0, seed=1)
    ex.update(start[0])
    sp = adxl203.sensor_parameters(**start[1])
    cfg = adxl203.config(Ts=TS, **{k: v for k, v in sp.items() if k != "Ts"})
    es = dict(a0=0.0, a1=1.0, a2=0.01, A=0.0, Q=0.01, R=1e-4, x0=0.0, P0=0.01, estimator=1,
              process=1, f=150.0, Qh=1e-8)
    es.update(start[2])
    C, S = harmonic.rotation(es["f"], TS)
    model = dict(process=es["process"], A=es["A"], Q=es["Q"], C=C, S=S, Qh=es["Qh"])

    def x_of(k, x_prev):
        if ex["kind"] == excitation.GAUSSIAN:
            return excitation.gaussian_sample(x_prev, ex["A"], ex["Q"], ex["seed"], k), 0.0
        return (excitation.sine(k, ex["X"], ex["f"], TS, ex["phi"]),
                excitation.sine(k, ex["Xy"], ex["f"], TS, ex["phiy"]))

    def sense(lp, lpy, x, y, k):
        v = adxl203.noise(sp["seed"], k, 1) if sp["noise"] else 0.0
        lp, z = adxl203.measure(lp, x, y, v, cfg)
        zy = 0.0
        if sp["axes"] == 2:
            vy = adxl203.noise(sp["seed"], k, 2) if sp["noise"] else 0.0
            lpy, zy = adxl203.measure(lpy, y, x, vy, cfg)
        return lp, lpy, z, zy

    def outs(state, z):
        dcs = drift.estimates(state.drift, es["a2"])
        dc = drift.select(dcs, es["estimator"])
        return (state.x, state.P) + tuple(dcs) + (dc, chain.compensate(z, dc))

    positions = [Fraction(0)]
    for q in quotients:
        positions.append(positions[-1] + q)
    xs, x = [None], ex["x0"]                        # xs[k] = (x_k, y_k)
    for k in range(1, math.floor(positions[-1]) + 2):
        xy = x_of(k, x)
        x = xy[0]
        xs.append(xy)
    lp = lpy = None
    state = harmonic.estimator_init(es["process"], es["x0"], es["P0"])
    shown_a = shown_d = None
    rows = []
    for i, p in enumerate(positions):
        J = math.floor(p) + 1                       # the latest instant at or before t_i
        x, y = xs[J]
        if p == math.floor(p):                      # at instant J: J is pending
            z, zy = sense(lp, lpy, x, y, J)[2:]
            shown_a = (z, zy)
            shown_d = outs(harmonic.estimator_step(state, z, es["a0"], es["a1"], es["a2"],
                                                   es["R"], **model), z)
        z_in = shown_a[0]                           # what the master sets at t_i
        rows.append((x, shown_a[0], shown_a[1]) + shown_d)
        if i == len(quotients):
            break
        first_k = math.ceil(p) + 1                  # instants in [t_i, t_{i+1})
        for k in range(first_k, math.ceil(positions[i + 1]) + 1):
            lp, lpy, z, zy = sense(lp, lpy, x, y, k)
            shown_a = (z, zy)
            if k == first_k:
                state = harmonic.estimator_step(state, z_in, es["a0"], es["a1"], es["a2"],
                                                es["R"], **model)
            else:
                state = harmonic.estimator_predict(state, **model)
            shown_d = outs(state, z_in)
    return rows


def _random_quotients(seed, n):
    rng = random.Random(seed)
    choices = [Fraction(1, 4), Fraction(1, 2), Fraction(3, 4), Fraction(1), Fraction(1),
               Fraction(2), Fraction(5, 2), Fraction(3, 2), Fraction(4), Fraction(3, 10),
               Fraction(7, 10)]
    return [rng.choice(choices) for _ in range(n)]


SEQUENCES = {
    "h = 0.3 Ts": [Fraction(3, 10)] * 60,
    "h = 2.5 Ts": [Fraction(5, 2)] * 40,
    "h = Ts/4": [Fraction(1, 4)] * 40,
    "h = Ts/3": [Fraction(1, 3)] * 45,
    "mixed, seed 1": _random_quotients(1, 120),
    "mixed, seed 2": _random_quotients(2, 120),
}


@pytest.mark.parametrize("start", [LETTER, ADXL], ids=["letter", "adxl203"])
@pytest.mark.parametrize("name", sorted(SEQUENCES))
def test_any_step_sequence_equals_the_held_input_reference(start, name):
    quotients = SEQUENCES[name]
    got = run_fmus(start, quotients)
    want = reference(start, quotients)
    assert len(got) == len(want)
    for i, (g, w) in enumerate(zip(got, want)):
        assert g == w, (i, g, w)


@pytest.mark.parametrize("name", sorted(SEQUENCES))
def test_excitation_at_every_sample_instant_is_the_whole_sample_run(name):
    quotients = SEQUENCES[name]
    positions = [Fraction(0)]
    for q in quotients:
        positions.append(positions[-1] + q)
    whole = chain.simulate(math.floor(positions[-1]) + 1, 1)["x"]
    rows = run_fmus(LETTER, quotients)
    at_instants = 0
    for p, row in zip(positions, rows):
        assert row[0] == whole[math.floor(p)]  # at an instant: that sample; else the last one
        at_instants += p == math.floor(p)
    assert at_instants > 5, at_instants


def test_whole_sample_reference_is_the_chain_of_models():
    # the reference itself, with h = Ts, is models.chain.simulate: it can tell steps apart
    rows = reference(LETTER, [Fraction(1)] * 50)
    ref = chain.simulate(51, 1)
    assert [r[0] for r in rows] == ref["x"] and [r[1] for r in rows] == ref["z"]
    assert [r[3] for r in rows] == ref["x_hat"] and [r[5] for r in rows] == ref["dc_ekf1"]
    assert reference(LETTER, [Fraction(5, 2)] * 20) != reference(LETTER, [Fraction(1)] * 20)


def test_steps_of_whole_samples_in_any_mix_are_bit_identical_to_unit_steps():
    quotients = [Fraction(1), Fraction(3), Fraction(2), Fraction(1), Fraction(5)]
    rows = run_fmus(LETTER, quotients)
    unit = run_fmus(LETTER, [Fraction(1)] * 12)
    positions = [0, 1, 4, 6, 7, 12]
    # the instants at communication points of both runs agree in x and z (the estimator saw
    # fewer measurements in the coarse run, so only the excitation and sensor are compared)
    for p, row in zip(positions, rows):
        assert row[:3] == unit[p][:3]


@pytest.mark.integration
@pytest.mark.parametrize("name", ["mixed, seed 2", "h = 0.3 Ts"])
def test_built_fmus_in_fmpy_follow_the_rule(built_fmus, name):
    """The same through pythonfmu's C++ and the loader shim, in fmpy."""
    from driftfmu.simulations.cosim import Instance
    quotients = SEQUENCES[name]
    inst = [Instance(n, built_fmus[n]) for n in ("Excitation", "Accelerometer", "DriftEstimator")]
    for i in inst:
        i.fmu.setupExperiment(startTime=0.0)
        i.fmu.enterInitializationMode()
        i.fmu.exitInitializationMode()
    e, a, d = inst

    def point():
        a.fmu.setReal([a.vrs["x"], a.vrs["y"]], e.fmu.getReal([e.vrs["x"], e.vrs["y"]]))
        d.fmu.setReal([d.vrs["z"]], a.fmu.getReal([a.vrs["z"]]))
        return tuple(e.fmu.getReal([e.vrs["x"]]) + a.fmu.getReal([a.vrs["z"], a.vrs["z_y"]])
                     + d.fmu.getReal([d.vrs[n] for n in OUTS]))

    rows, t = [point()], 0.0
    for q in quotients:
        for i in inst:
            i.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=float(q) * TS)
        t += float(q) * TS
        rows.append(point())
    assert rows == reference(LETTER, quotients)
    for i in inst:
        i.free()
