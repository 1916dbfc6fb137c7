"""The chain as one FMU (docs/hosts.md, "The chain as one FMU"): the FMU Manipulation Toolbox's
``fmucontainer`` builds a container FMU from the ``DriftChain.json`` that ``driftfmu build``
writes beside the FMUs (fmu_src/container.py), and that container, run in fmpy, gives
``driftfmu.simulate``'s numbers bit for bit: Python and native FMUs inside, FMI 2.0 and 3.0
containers.  Its step of Ts/2 is what makes it exact: at Ts the sequential container commits
each sample of the DriftEstimator with the next sample's measurement."""
import json
import shlex
import shutil
import subprocess
import sys

import numpy as np
import pytest

import driftfmu
from driftfmu.fmu_src import container, native_build
from recipes import commands

TS = 1e-3
N = 200
STOP = (N - 1) * TS
#: The user's sensor: every parameter the container takes is set, in each FMU that has it.
START = {"a2": 0.02, "seed": 7, "A": 0.6, "R": 2e-4}


def _fmucontainer():
    """The ``fmucontainer`` command: beside this Python's, else on PATH; skip without it."""
    from pathlib import Path
    beside = Path(sys.executable).with_name("fmucontainer")
    found = str(beside) if beside.is_file() else shutil.which("fmucontainer")
    if found is None:
        pytest.skip("fmucontainer is not installed; pip install fmu-manipulation-toolbox "
                    "(in the dev extra)")
    return found


def _folder(tmp_path, fmus, description=None):
    """The three FMUs and their ``DriftChain.json`` (as ``driftfmu build`` writes it) in a
    folder of their own."""
    d = tmp_path / "fmus"
    d.mkdir()
    for name in container.NAMES:
        shutil.copy(fmus[name], d / ("%s.fmu" % name))
    if description is None:
        container.write(d)
    else:
        (d / container.FILENAME).write_text(json.dumps(description))
    return d


def _make(folder, fmi=2):
    """Run the page's command for an FMI ``fmi`` container (docs/hosts.md, its first line
    FMI 2.0, its second FMI 3.0) on ``folder``; return the container's path."""
    line = commands("fmucontainer")[fmi - 2]
    assert ("-fmi 3" in line) == (fmi == 3), line
    argv = shlex.split(line.replace("build/fmus", shlex.quote(str(folder))))
    assert argv[0] == "fmucontainer"
    done = subprocess.run([_fmucontainer()] + argv[1:], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    path = folder / container.CONTAINER
    assert path.is_file(), done.stdout + done.stderr
    return path


def _container_start(path, start):
    """``start`` (plain names) as the container's parameters: every FMU's that has it."""
    from fmpy import read_model_description
    names = {v.name for v in read_model_description(str(path)).modelVariables
             if v.causality == "parameter"}
    out = {}
    for key, value in start.items():
        for fmu in container.NAMES:
            if "%s.%s" % (fmu.lower(), key) in names:
                out["%s.%s" % (fmu.lower(), key)] = value
    return out


def _run(path, start=START):
    """fmpy runs the container (with its own logger: fmpy 0.3.32's logger proxy keeps a
    ``logger=`` callable in a global that outlives the run, and the next FMU that logs in this
    process calls it after it is freed: a segmentation fault)."""
    from fmpy import simulate_fmu
    return simulate_fmu(str(path), stop_time=STOP, output_interval=TS,
                        start_values=_container_start(path, start))


def _fmus(kind, python_fmus, native_fmus):
    return python_fmus if kind == "python" else native_fmus[int(kind[-1])]


@pytest.mark.integration
@pytest.mark.parametrize("kind, fmi", [("python", 2), ("python", 3), ("native-fmi2", 2),
                                       ("native-fmi3", 3), ("native-fmi2", 3),
                                       ("native-fmi3", 2)])
def test_the_container_of_the_chain_gives_simulates_numbers_bit_for_bit(
        kind, fmi, python_fmus, native_fmus, tmp_path, report):
    fmus = _fmus(kind, python_fmus, native_fmus)
    path = _make(_folder(tmp_path, fmus), fmi)
    got = _run(path)
    backend, version = ("python", 2) if kind == "python" else ("native", int(kind[-1]))
    want = driftfmu.simulate(stop_time=STOP, start_values=START, backend=backend,
                             fmi_version=version, fmu_dir=_layout(tmp_path, fmus, kind))
    assert len(got) == len(want) == N
    assert np.array_equal(got["time"], want["time"])
    for name in want.dtype.names[1:]:
        assert np.array_equal(got[name], want[name]), (kind, fmi, name)
    report("container (fmucontainer, %s FMUs in an FMI %d.0 container, step Ts/2): %d outputs "
           "x %d samples equal driftfmu.simulate bit for bit"
           % (kind, fmi, len(want.dtype.names) - 1, N))


def _layout(tmp_path, fmus, kind):
    """``fmus`` in the layout ``driftfmu.simulate``'s ``fmu_dir`` reads."""
    d = tmp_path / "layout"
    sub = d if kind == "python" else d / "native" / ("fmi%s" % kind[-1])
    sub.mkdir(parents=True)
    for name in container.NAMES:
        (sub / ("%s.fmu" % name)).symlink_to(fmus[name])
    return d


@pytest.mark.integration
def test_the_container_exposes_every_output_and_every_parameter(native_fmus, tmp_path):
    from fmpy import read_model_description
    path = _make(_folder(tmp_path, native_fmus[2]))
    md = read_model_description(str(path))
    by = {}
    for v in md.modelVariables:
        by.setdefault(v.causality, set()).add(v.name)
    slaves = {n: native_build.slave_class(n) for n in container.NAMES}
    outputs = {s["name"] for n in container.NAMES for s in slaves[n].VARIABLES
               if s["causality"] == "output"}
    assert by["output"] == outputs
    assert by["parameter"] == {"%s.%s" % (n.lower(), s["name"]) for n in container.NAMES
                               for s in slaves[n].VARIABLES if s["causality"] == "parameter"}
    # the inputs no connection drives (driftfmu._api.CONNECTIONS), named as the container
    # names them: qualified with their FMU where two FMUs have an input of that name
    from driftfmu._api import CONNECTIONS
    driven = {(d, i) for _, _, d, i in CONNECTIONS}
    free = [(n, s["name"]) for n in container.NAMES for s in slaves[n].VARIABLES
            if s["causality"] == "input" and (n, s["name"]) not in driven]
    count = {}
    for _, name in free:
        count[name] = count.get(name, 0) + 1
    assert "u_in" in {name for _, name in free}
    assert by["input"] == {name if count[name] == 1 else "%s.%s" % (n, name) for n, name in free}


def test_the_description_follows_the_tables(monkeypatch):
    """A variable added to a slave's table appears in the description: an output as an
    output, an input that no connection drives as an input; a name two FMUs output is
    qualified with its FMU."""
    slave = native_build.slave_class("Accelerometer")
    extra = (dict(slave.VARIABLES[0], name="q_extra", causality="input"),
             dict(slave.VARIABLES[0], name="x_hat", causality="output"))
    monkeypatch.setattr(slave, "VARIABLES", tuple(slave.VARIABLES) + extra)
    d = container.description()
    assert ["q_extra", "Accelerometer.fmu", "q_extra"] in d["input"]
    assert ["Accelerometer.fmu", "x_hat", "Accelerometer.x_hat"] in d["output"]
    assert ["DriftEstimator.fmu", "x_hat", "DriftEstimator.x_hat"] in d["output"]
    assert ["Accelerometer.fmu", "z", "z"] in d["output"]
    assert not any(row[2] == "x" for row in d["input"])  # x is wired from the Excitation


def test_the_description_steps_at_half_the_sample_period():
    d = container.description()
    assert d["step_size"] == TS / 2 and d["sequential"] is True
    assert d["auto_parameter"] is True and d["mt"] is False
    assert container.description(Ts=4e-3)["step_size"] == 2e-3
    assert d["fmu"] == ["Excitation.fmu", "Accelerometer.fmu", "DriftEstimator.fmu"]
    assert json.loads(container.text(d)) == d


def test_the_description_file_has_a_line_per_setting_and_per_row_of_a_list():
    """The file a user reads and edits: a line per setting, and a list (the FMUs, the links,
    the inputs, the outputs) a row per line, so that a change shows as the rows it touches."""
    d = container.description()
    lines = container.text(d).splitlines()
    lists = {k: v for k, v in d.items() if isinstance(v, list)}
    assert set(lists) == {"fmu", "link", "input", "output"}
    assert len(lines) == 2 + len(d) + sum(len(v) + 1 for v in lists.values())
    for key, rows in lists.items():
        at = lines.index('  "%s": [' % key)
        listed = lines[at + 1:at + 1 + len(rows)]
        assert [json.loads(line.strip().rstrip(",")) for line in listed] == rows
        assert lines[at + 1 + len(rows)] in ("  ],", "  ]")
    assert '  "step_size": %s,' % json.dumps(d["step_size"]) in lines


@pytest.mark.integration
def test_at_a_step_of_ts_the_container_commits_the_next_measurement(native_fmus, tmp_path):
    """Why the step is Ts/2: at Ts the sequential container sets the DriftEstimator's z to the
    measurement of t + h before it steps from t, so the filter's sums take each measurement
    twice (x and z stay right: the Excitation and the Accelerometer keep no such sum)."""
    d = dict(container.description(), step_size=TS)
    path = _make(_folder(tmp_path, native_fmus[2], d))
    got = _run(path)
    want = driftfmu.simulate(stop_time=STOP, start_values=START, backend="native",
                             fmu_dir=_layout(tmp_path, native_fmus[2], "native-fmi2"))
    assert np.array_equal(got["z"], want["z"])
    assert np.max(np.abs(got["dc_ekf1"] - want["dc_ekf1"])) > 1e-6


def _fake_native(out_dir, names, fmi_versions, log, cache=None):
    """native_build.build_native_fmus without a compiler: a file per FMU."""
    from pathlib import Path
    built = {}
    for v in fmi_versions:
        built[v] = {}
        for n in names:
            path = Path(out_dir) / ("fmi%d" % v) / ("%s.fmu" % n)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(b"fmu")
            built[v][n] = path
    return built


def test_build_writes_the_description_beside_the_chains_fmus(tmp_path, monkeypatch):
    monkeypatch.setattr(native_build, "build_native_fmus", _fake_native)
    driftfmu.build_fmus(tmp_path / "all", backend="native", fmi_version=(2, 3))
    for v in (2, 3):
        text = (tmp_path / "all" / "native" / ("fmi%d" % v) / container.FILENAME).read_text()
        assert json.loads(text) == container.description()
    driftfmu.build_fmus(tmp_path / "some", backend="native", fmi_version=2,
                        names=["Excitation", "Accelerometer"])
    assert not (tmp_path / "some" / "native" / "fmi2" / container.FILENAME).exists()
