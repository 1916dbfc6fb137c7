"""A master over the slave classes themselves (what the Python FMUs run, without building
them): the same arguments and results as ``simulations.cosim.cosimulate`` (Gauss-Seidel: the
connections copied in their order, then the outputs recorded, then every slave stepped).

Tests that check what a master *reports* (its references, summary and printed lines) put it in
place of the FMUs with :func:`use_slaves`, so that they run without FMUs, in the everyday loop
and in the mutation check (which leaves out the tests that build or load FMUs).
"""
from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation

from test_hardening import get, put, ready

SLAVES = {"Excitation": Excitation, "Accelerometer": Accelerometer,
          "DriftEstimator": DriftEstimator}


def cosimulate_slaves(fmus, connections, n_steps, step_size, start_values=None, record=None,
                      progress=None, **_ignored):
    """``cosimulate`` over the slave classes named by the keys of ``fmus``."""
    slaves = {name: ready(SLAVES[name], **(start_values or {}).get(name, {})) for name in fmus}
    out = {"time": []}
    record = record or {}
    for name, names in record.items():
        for v in names:
            out["%s.%s" % (name, v)] = []
    t = 0.0
    for i in range(n_steps):
        for src, o, dst, inp in connections:
            put(slaves[dst], inp, get(slaves[src], o))
        out["time"].append(t)
        for name, names in record.items():
            for v in names:
                out["%s.%s" % (name, v)].append(get(slaves[name], v))
        for s in slaves.values():
            assert s.do_step(t, step_size), [m.msg for m in s.log_queue]
        t = (i + 1) * step_size
        if progress is not None:
            progress(i + 1)
    return out


def use_slaves(monkeypatch, *modules):
    """Make ``modules`` (e.g. ``simulations.gaussian``, ``simulations.sinusoidal``) run the
    slave classes in place of the FMUs: their ``master`` and ``fmu_paths``."""
    for module in modules:
        monkeypatch.setattr(module, "master", lambda backend="python": cosimulate_slaves)
        monkeypatch.setattr(module, "fmu_paths", lambda fmu_dir, backend="python": {
            n: n for n in SLAVES})
