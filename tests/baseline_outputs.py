"""What the project computes with every new parameter at its default, as SHA-256 digests of the
bits: the outputs of every slave (the FMUs' Python classes, driven through parameter sets, input
values and communication steps of their own, with FMU states saved and restored), of models/'
chains (chain, the ADXL203 stand-in, the dual-axis sensor), of the batch engine (NumPy and the
compiled kernel) and of the public functions that need no built FMU (montecarlo, sweep).

``tests/data/baseline_outputs.json`` holds the digests computed from main's code before issue 42
(the sensor's drift taxonomy) changed anything; tests/test_nothing_moves.py recomputes them and
compares.  The three montecarlo digests were recorded again when its EKF1-EKF2 gap in dB came to
be computed by models._ops.log instead of NumPy's log10, whose results on arrays differ in the
last bits from one CPU to another (AVX-512 against AVX2): every other number of those results
kept its bits.  Regenerate only when a change is meant to move these numbers::

    PYTHONPATH=$PWD python3 tests/baseline_outputs.py > tests/data/baseline_outputs.json

Everything here is self-contained (its own parameter draws), so that a test helper that changes
does not change what is digested.
"""
import hashlib
import json
import random
import struct
import sys

import numpy as np

#: Slaves by FMU name (imported lazily: pythonfmu is needed).
NAMES = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")


def _digest_floats(values):
    """SHA-256 of the IEEE 754 bits of ``values`` (a sequence or array of floats)."""
    return hashlib.sha256(np.ascontiguousarray(np.asarray(values, dtype=np.float64))
                          .tobytes()).hexdigest()


def _digest_json(value):
    """SHA-256 of a JSON text of ``value`` whose floats are written by their bits."""
    def plain(v):
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in sorted(v.items())}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if isinstance(v, np.ndarray):
            return _digest_floats(v) if v.dtype.kind == "f" else v.tolist()
        if isinstance(v, (float, np.floating)):
            return struct.pack("<d", float(v)).hex()
        if isinstance(v, (np.integer,)):
            return int(v)
        return v
    return hashlib.sha256(json.dumps(plain(value), sort_keys=True).encode()).hexdigest()


def _slave(name):
    import importlib
    return getattr(importlib.import_module("driftfmu.fmu_src." + name), name)


def _values(name, rng):
    """A parameter set of slave ``name`` drawn from ``rng`` (in range)."""
    if name == "Excitation":
        return dict(kind=rng.choice((1, 2)), A=rng.uniform(-0.95, 0.95), Q=rng.uniform(0, 0.1),
                    x0=rng.uniform(-1, 1), X=rng.uniform(0, 2), f=rng.uniform(1, 120),
                    phi=rng.uniform(-3, 3), Xy=rng.uniform(0, 1), phiy=rng.uniform(-3, 3),
                    Ts=rng.choice((1e-3, 2.5e-3, 1e-4)), seed=rng.randrange(2 ** 31),
                    Qy=rng.choice((0.0, rng.uniform(0, 0.1))), rho=rng.uniform(-1, 1))
    if name == "Accelerometer":
        Ts = rng.choice((1e-3, 1e-4))
        on = (lambda: rng.random() < 0.5)
        p = dict(a0=rng.uniform(-1, 3), a1=rng.uniform(0.2, 2), a2=rng.uniform(-0.1, 0.1),
                 R=10.0 ** rng.uniform(-8, -1), a3=rng.uniform(-0.01, 0.01) if on() else 0.0,
                 cross=rng.uniform(-0.05, 0.05) if on() else 0.0,
                 fc=min(rng.uniform(1, 2500), 0.4 / Ts) if on() else 0.0,
                 Vs=rng.uniform(3, 6) if on() else 0.0, bits=rng.randint(1, 24) if on() else 0,
                 density=10.0 ** rng.uniform(-6, -3) if on() else 0.0, Ts=Ts,
                 noise=rng.choice((0, 1)), seed=rng.randrange(2 ** 31), axes=rng.choice((1, 2)),
                 a4=rng.uniform(-0.01, 0.01) if on() else 0.0)
        if rng.random() < 0.3:
            p.update(cross=0.0, fc=0.0, Vs=0.0, bits=0, density=0.0, a3=0.0, a4=0.0, dual=1,
                     bx=rng.uniform(-0.1, 0.1), by=rng.uniform(-0.1, 0.1),
                     a0y=rng.uniform(-1, 1), a1y=rng.uniform(0.5, 2), a2y=rng.uniform(-0.1, 0.1),
                     Ry=10.0 ** rng.uniform(-6, -2))
        return p
    if name == "DualDriftEstimator":
        return dict(a0=rng.uniform(-1, 1), a1=rng.uniform(0.5, 2), a2=rng.uniform(-0.1, 0.1),
                    bx=rng.uniform(-0.1, 0.1), R=10.0 ** rng.uniform(-6, -2),
                    a0y=rng.uniform(-1, 1), a1y=rng.uniform(0.5, 2), a2y=rng.uniform(-0.1, 0.1),
                    by=rng.uniform(-0.1, 0.1), Ry=10.0 ** rng.uniform(-6, -2),
                    A=rng.uniform(-0.9, 0.9), Q=rng.uniform(0.001, 0.1),
                    Qy=rng.uniform(0.001, 0.1), rho=rng.uniform(-1, 1), x0=rng.uniform(-0.5, 0.5),
                    y0=rng.uniform(-0.5, 0.5), P0=rng.uniform(0, 0.1), P0y=rng.uniform(0, 0.1),
                    Ts=rng.choice((1e-3, 1e-4)), estimator=rng.randint(1, 3),
                    process=rng.choice((1, 2)), f=rng.uniform(1, 300),
                    Qh=10.0 ** rng.uniform(-10, -4))
    return dict(a0=rng.uniform(-1, 1), a1=rng.uniform(0.5, 2), a2=rng.uniform(-0.1, 0.1),
                A=rng.uniform(-0.9, 0.9), Q=rng.uniform(0.001, 0.1), R=10.0 ** rng.uniform(-6, -2),
                x0=rng.uniform(-0.5, 0.5), P0=rng.uniform(0, 0.1), Ts=rng.choice((1e-3, 1e-4)),
                estimator=rng.randint(1, 3), process=rng.choice((1, 2)), f=rng.uniform(1, 300),
                Qh=10.0 ** rng.uniform(-10, -4))


#: Inputs of each slave as main had them (a later input, e.g. the tilt, keeps its start value).
INPUTS = {"Excitation": ("u_in",), "Accelerometer": ("x", "y"), "DriftEstimator": ("z", "u"),
          "DualDriftEstimator": ("z_x", "z_y")}
#: Outputs appended after the digests were recorded, left out of them: the DriftEstimator's bias
#: state and class-2 offset (issue 43, whose own digests of main's outputs are in
#: tests/test_bias_off_bits.py; they are 0 with the bias state off and no class-2 input,
#: tests/test_bias_fmu.py).
LATER_OUTPUTS = {"DriftEstimator": ("b_hat", "P_bb", "P_xb", "dc_class2")}


def slave_run(name, values, seed, steps=80):
    """Digest of the outputs of slave ``name`` with ``values``: random inputs and steps
    (whole samples and fractions), a state saved at step 25 and restored at step 50."""
    cls = _slave(name)
    s = cls(instance_name=name)
    for n, v in values.items():
        setattr(s, n, v)
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    s.exit_initialization_mode()
    if not s._initialised:
        raise RuntimeError("%s refused %r" % (name, values))
    vr = {spec["name"]: i for i, spec in enumerate(s.VARIABLES)}
    outputs = [spec["name"] for spec in s.VARIABLES if spec["causality"] == "output"
               and spec["name"] not in LATER_OUTPUTS.get(name, ())]
    rng = random.Random(seed)
    Ts = s.Ts
    record, saved = [], None
    t = 0.0
    for i in range(steps):
        for n in INPUTS[name]:
            s.set_real([vr[n]], [rng.uniform(-1.5, 3.0)])
        record.extend(s.get_real([vr[n] for n in outputs]))
        if i == 25:
            saved = s._get_fmu_state()
        if i == 50:
            s._set_fmu_state(saved)
        h = Ts * rng.choice((1, 1, 2, 3, 0.5, 0.25, 1.5)) if rng.random() < 0.7 else \
            Ts * rng.uniform(0.05, 3.5)
        if s.do_step(t, h) is False:
            raise RuntimeError("%s refused a step" % name)
        t += h
    record.extend(s.get_real([vr[n] for n in outputs]))
    return _digest_floats(record)


def slave_digests():
    from driftfmu.models import adxl203
    out = {}
    rng = random.Random(4242)
    for name in NAMES:
        out["slave %s defaults" % name] = slave_run(name, {}, 1)
        for case in range(6):
            out["slave %s case %d" % (name, case)] = slave_run(name, _values(name, rng),
                                                               100 + case)
    out["slave Accelerometer adxl203"] = slave_run("Accelerometer",
                                                   dict(adxl203.ADXL203, Ts=1e-4, seed=5), 7)
    return out


def model_digests():
    from driftfmu.models import adxl203, chain, excitation, harmonic
    out = {}
    cases = {"gaussian": dict(), "gaussian A": dict(A=0.7, Q=0.02, seed=3, a2=0.05),
             "sine": dict(kind=excitation.SINUSOIDAL, X=1.2, f=120.0, phi=0.3, seed=4),
             "general": dict(a3=0.01, a4=0.002, B=0.5, drive=1, Qu=0.01, seed=5),
             "general sine input": dict(a4=0.003, B=0.4, drive=2, Xu=0.5, fu=37.0, seed=6)}
    for label, kw in cases.items():
        kw = dict(kw)
        seed = kw.pop("seed", 1)
        cols = chain.simulate(1500, seed, **kw)
        out["chain %s" % label] = _digest_json(cols)
    ex = dict(kind=excitation.SINUSOIDAL, X=1.02, f=200.0, phi=1.3, Xy=0.51, phiy=-0.7, seed=11)
    sp = dict(adxl203.ADXL203, seed=11, noise=1)
    es = dict(a0=2.5, a1=1.0, a2=0.01, R=1.2e-5, process=harmonic.HARMONIC, f=200.0, Qh=1e-8,
              P0=1.0, estimator=1)
    out["adxl203 preset"] = _digest_json(adxl203.simulate(3000, ex, sp, es, 1e-4))
    out["adxl203 plain"] = _digest_json(adxl203.simulate(2000, dict(seed=3), dict(seed=3),
                                                         dict(estimator=2), 1e-3))
    return out


def batch_digests():
    from driftfmu.models import excitation
    from driftfmu.simulations import batch
    out = {}
    seeds = batch.run_seeds(17, 24)
    cases = {"gaussian": dict(), "gaussian A": dict(A=0.5, Q=0.03, a2=np.linspace(0.001, 0.3, 24)),
             "sine": dict(kind=excitation.SINUSOIDAL, X=1.1, f=90.0,
                          phi=batch.sine_phase(seeds)),
             "general": dict(a3=0.01, a4=np.where(np.arange(24) % 2, 0.002, 0.0), B=0.3,
                             drive=2, Xu=0.4, fu=50.0)}
    for label, kw in cases.items():
        for kernel in ("numpy", "c"):
            try:
                res = batch.simulate(400, seeds, record=batch.TRAJECTORIES, kernel=kernel, **kw)
            except RuntimeError:  # no C compiler: the kernel's digest is the NumPy one's
                res = batch.simulate(400, seeds, record=batch.TRAJECTORIES, kernel="numpy",
                                     **kw)
            out["batch %s" % label] = out.get("batch %s" % label) or _digest_json(res)
            if _digest_json(res) != out["batch %s" % label]:
                raise RuntimeError("the kernel and NumPy differ: %s" % label)
        res = batch.simulate(400, seeds, kernel="auto", **kw)
        out["batch %s finals" % label] = _digest_json(res)
    return out


def api_digests():
    import driftfmu
    out = {}
    res = driftfmu.montecarlo("gaussian", runs=40, n=300, seed=3, workers=1)
    res["summary"].pop("seconds")
    out["montecarlo gaussian"] = _digest_json(res)
    res = driftfmu.montecarlo("sinusoidal", runs=30, n=300, seed=5, workers=1)
    res["summary"].pop("seconds")
    out["montecarlo sinusoidal"] = _digest_json(res)
    res = driftfmu.montecarlo("gaussian", runs=20, n=200, seed=3, workers=1, a4=0.01, B=0.2,
                              drive=1, Qu=0.01)
    res["summary"].pop("seconds")
    out["montecarlo general"] = _digest_json(res)
    res = driftfmu.sweep(a2=(0.001, 0.01, 0.1), R=(1e-5, 1e-3), runs=12, n=200, workers=1)
    res.pop("seconds")
    out["sweep"] = _digest_json(res)
    res = driftfmu.sweep(R=(1e-4,), a4=(0.0, 0.01), runs=8, n=150, workers=1)
    res.pop("seconds")
    out["sweep a4"] = _digest_json(res)
    return out


def digests():
    """Every digest, by name."""
    out = {}
    out.update(slave_digests())
    out.update(model_digests())
    out.update(batch_digests())
    out.update(api_digests())
    return out


if __name__ == "__main__":
    json.dump(digests(), sys.stdout, indent=1, sort_keys=True)
    sys.stdout.write("\n")
