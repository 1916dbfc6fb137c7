"""Internal (not a stable API; use driftfmu.build_fmus instead).

The chain Excitation -> Accelerometer -> DriftEstimator as one FMU: the description that the FMU
Manipulation Toolbox's ``fmucontainer`` (PyPI ``fmu-manipulation-toolbox``) builds a container
FMU from, generated from the slaves' ``VARIABLES`` tables and the chain's connections.

``driftfmu build`` writes it as ``DriftChain.json`` beside the three FMUs (:data:`FILENAME`), and

    fmucontainer -container DriftChain.json -fmu-directory build/fmus            (FMI 2.0)
    fmucontainer -container DriftChain.json -fmu-directory build/fmus -fmi 3     (FMI 3.0)

makes ``build/fmus/DriftChain.fmu``.  The description asks for

* ``"sequential": true``: the container steps the FMUs one after the other in the order of the
  ``"fmu"`` list (Gauss-Seidel), each with the outputs its predecessors computed in the same
  container step;
* ``"step_size"``: the container's internal step, :data:`STEP_FRACTION` of the sample period
  ``Ts`` (:func:`step_size`).  The sequential container sets an FMU's inputs from the outputs
  its predecessors have at the end of the step (``t + h``) before it steps the FMU from ``t``.
  At ``h = Ts`` the DriftEstimator would then commit sample ``k`` with the measurement of sample
  ``k + 1``; with ``h <= Ts / 2`` no step that starts at a sample instant reaches the next one,
  so every sample is committed with its own inputs and the container gives the numbers of
  ``driftfmu.simulate`` bit for bit (docs/hosts.md, tests/test_container.py);
* every output of the three FMUs as an output of the container (:func:`outputs`), every input
  that no connection drives as an input (:func:`inputs`), and the FMUs' parameters as the
  container's parameters (``"auto_parameter"``: the toolbox names them
  ``<fmu name in lower case>.<parameter>``, e.g. ``accelerometer.a2``).
"""
import json
from pathlib import Path

#: The FMUs of the chain, in the order the container steps them.
NAMES = ("Excitation", "Accelerometer", "DriftEstimator")
#: The file ``driftfmu build`` writes beside the FMUs, and the container it describes.
FILENAME = "DriftChain.json"
CONTAINER = "DriftChain.fmu"
#: The container's step as a fraction of the sample period Ts (at most 1/2, see the docstring).
STEP_FRACTION = 0.5


def _slave(name):
    from driftfmu.fmu_src.native_build import slave_class
    return slave_class(name)


def connections(names=NAMES):
    """The chain's connections between ``names``: (source, output, destination, input), those
    of ``driftfmu.simulate`` (``driftfmu._api.CONNECTIONS``) whose two FMUs are in ``names``."""
    from driftfmu._api import CONNECTIONS
    return [c for c in CONNECTIONS if c[0] in names and c[2] in names]


def _names_of(kind, names):
    """(FMU, variable, the container's name) for every ``kind`` variable of ``names`` in
    table order; a name that two FMUs have becomes ``<FMU>.<variable>`` (as the fields of
    ``driftfmu.simulate``'s result)."""
    rows = [(n, s["name"]) for n in names for s in _slave(n).VARIABLES if s["causality"] == kind]
    count = {}
    for _, v in rows:
        count[v] = count.get(v, 0) + 1
    return [(n, v, v if count[v] == 1 else "%s.%s" % (n, v)) for n, v in rows]


def outputs(names=NAMES):
    """Every output of ``names``: [(FMU, output, the container's output)]."""
    return _names_of("output", names)


def inputs(names=NAMES):
    """Every input of ``names`` that no connection drives: [(FMU, input, the container's
    input)]."""
    driven = {(d, i) for _, _, d, i in connections(names)}
    return [row for row in _names_of("input", names) if row[:2] not in driven]


def step_size(Ts=None):
    """The container's step for the sample period ``Ts`` (default: the FMUs' default Ts)."""
    if Ts is None:
        Ts = next(s["start"] for s in _slave(NAMES[0]).VARIABLES if s["name"] == "Ts")
    return STEP_FRACTION * float(Ts)


def description(names=NAMES, Ts=None, container=CONTAINER):
    """The ``fmucontainer`` JSON description of the chain (a dict)."""
    fmu = {n: "%s.fmu" % n for n in names}
    return {
        "name": container,
        "step_size": step_size(Ts),
        "sequential": True,
        "mt": False,
        "auto_link": False,
        "auto_input": False,
        "auto_output": False,
        "auto_parameter": True,
        "fmu": [fmu[n] for n in names],
        "link": [[fmu[s], o, fmu[d], i] for s, o, d, i in connections(names)],
        "input": [[exposed, fmu[n], v] for n, v, exposed in inputs(names)],
        "output": [[fmu[n], v, exposed] for n, v, exposed in outputs(names)],
    }


def write(folder, Ts=None):
    """Write :data:`FILENAME` into ``folder`` (that holds the chain's FMUs); return its path."""
    path = Path(folder) / FILENAME
    path.write_text(text(description(Ts=Ts)))
    return path


def text(data):
    """``data`` (a :func:`description`) as JSON with one row of a list per line."""
    lines = ["{"]
    for i, (key, value) in enumerate(data.items()):
        end = "," if i < len(data) - 1 else ""
        if isinstance(value, list):
            rows = [json.dumps(row) for row in value]
            lines.append('  "%s": [' % key)
            lines += ["    %s%s" % (row, "," if j < len(rows) - 1 else "")
                      for j, row in enumerate(rows)]
            lines.append("  ]%s" % end)
        else:
            lines.append('  "%s": %s%s' % (key, json.dumps(value), end))
    return "\n".join(lines + ["}", ""])
