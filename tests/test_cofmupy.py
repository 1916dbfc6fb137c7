"""cofmupy as a co-simulation host (docs/hosts.md, "cofmupy"): the configuration and the script
of the page, run as written on the Python and native FMUs, give ``driftfmu.simulate``'s rows
bit for bit at the sample instants; at a step of Ts they do not; an Integer parameter of an
FMI 2.0 FMU in the ``initialization`` is refused with the FMU's reason.

cofmupy pins fmpy 0.3.20 and pythonfmu 0.6.3, so it lives in a virtual environment of its own:
``DRIFTFMU_COFMUPY_PYTHON`` names its interpreter (.ci/run makes one); without it, this Python
if it has cofmupy, else the tests skip and say how to get it."""
import importlib.util
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

import driftfmu
from recipes import recipe

pytestmark = pytest.mark.integration

TS = 1e-3
CHAIN = ("Excitation", "Accelerometer", "DriftEstimator")
#: Appended to the page's script: its results as JSON, every double whole (repr).
DUMP = """
import json
json.dump({("%s.%s" % k if isinstance(k, tuple) else k): [float(x) for x in v]
           for k, v in results.items()}, open("results.json", "w"))
"""


def _python():
    given = os.environ.get("DRIFTFMU_COFMUPY_PYTHON")
    if given:
        if not os.access(given, os.X_OK):
            pytest.skip("DRIFTFMU_COFMUPY_PYTHON=%s is not an executable; allowed: the Python "
                        "of a virtual environment with cofmupy" % given)
        return given
    if importlib.util.find_spec("cofmupy") is not None:
        return sys.executable
    pytest.skip("cofmupy is not installed: python3 -m venv ~/cofmupy && ~/cofmupy/bin/pip "
                "install cofmupy, then DRIFTFMU_COFMUPY_PYTHON=~/cofmupy/bin/python (cofmupy "
                "pins fmpy 0.3.20 and pythonfmu 0.6.3, hence a virtual environment of its own)")


def _config(integers=True):
    """The page's configuration; without the Integer parameters (``seed``) for FMI 2.0."""
    config = json.loads(recipe("cofmupy-config"))
    if not integers:
        for fmu in config["fmus"]:
            fmu["initialization"] = {k: v for k, v in fmu.get("initialization", {}).items()
                                     if not isinstance(v, int)}
    return config


def _run(tmp_path, fmus, config, script):
    for name in CHAIN:
        shutil.copy(fmus[name], tmp_path / ("%s.fmu" % name))
    (tmp_path / "chain.json").write_text(json.dumps(config))
    (tmp_path / "run.py").write_text(script + DUMP)
    # cofmupy extracts each FMU into the temporary folder and leaves it there (docs/hosts.md):
    # its own temporary folder, counted
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    done = subprocess.run([_python(), "run.py"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600, env=dict(os.environ, TMPDIR=str(tmp)))
    if done.returncode == 0:
        assert len(os.listdir(tmp)) == len(CHAIN), (
            "cofmupy left %s in its temporary folder: docs/hosts.md says one extraction per "
            "FMU" % sorted(os.listdir(tmp)))
    return done, (json.loads((tmp_path / "results.json").read_text())
                  if done.returncode == 0 else None)


def _start_values(config):
    return {"%s.%s" % (f["id"], k): v for f in config["fmus"]
            for k, v in f.get("initialization", {}).items()}


def _at_instants(results):
    t = np.array(results["time"])
    rows = np.flatnonzero(np.abs(t / TS - np.rint(t / TS)) < 1e-6)
    return rows


def _fmus(kind, python_fmus, native_fmus):
    return python_fmus if kind == "python" else native_fmus[int(kind[-1])]


@pytest.mark.parametrize("kind", ["python", "native-fmi2", "native-fmi3"])
def test_cofmupy_runs_the_chain_as_the_page_says_bit_for_bit(kind, python_fmus, native_fmus,
                                                              fmus_in_build_layout, tmp_path,
                                                              report):
    config = _config(integers=kind == "native-fmi3")
    done, got = _run(tmp_path, _fmus(kind, python_fmus, native_fmus), config,
                     recipe("cofmupy-run"))
    assert done.returncode == 0, done.stdout + done.stderr
    rows = _at_instants(got)
    stop = got["time"][rows[-1]]
    backend, version = ("python", 2) if kind == "python" else ("native", int(kind[-1]))
    want = driftfmu.simulate(stop_time=round(stop / TS) * TS, backend=backend,
                             fmi_version=version, fmu_dir=fmus_in_build_layout,
                             start_values=_start_values(config))
    assert len(rows) == len(want) >= 2000
    compared = 0
    for name in CHAIN:
        for field in want.dtype.names[1:]:
            key = "%s.%s" % (name, field)
            if key in got:
                assert np.array_equal(np.array(got[key])[rows], want[field]), (kind, key)
                compared += 1
    assert compared == len(want.dtype.names) - 1
    report("cofmupy (Gauss-Seidel, step Ts/2, %s FMUs): %d outputs x %d samples equal "
           "driftfmu.simulate bit for bit" % (kind, compared, len(rows)))


def test_at_a_step_of_ts_cofmupy_commits_the_next_measurement(native_fmus, fmus_in_build_layout,
                                                              tmp_path):
    config = _config(integers=False)
    script = recipe("cofmupy-run").replace("step_size=0.0005", "step_size=0.001")
    assert script != recipe("cofmupy-run")
    done, got = _run(tmp_path, native_fmus[2], config, script)
    assert done.returncode == 0, done.stdout + done.stderr
    # a row labelled t holds the outputs at t + Ts: driftfmu.simulate's next row
    want = driftfmu.simulate(stop_time=0.5, backend="native", fmu_dir=fmus_in_build_layout,
                             start_values=_start_values(config))
    n = len(want) - 1
    assert np.array_equal(np.array(got["Accelerometer.z"][:n]), want["z"][1:])
    assert np.max(np.abs(np.array(got["DriftEstimator.dc_ekf1"][:n])
                         - want["dc_ekf1"][1:])) > 1e-6


def test_an_integer_parameter_of_an_fmi2_fmu_is_refused_with_the_fmus_reason(native_fmus,
                                                                             tmp_path):
    done, _ = _run(tmp_path, native_fmus[2], _config(integers=True), recipe("cofmupy-run"))
    assert done.returncode != 0
    assert "seed, an Integer variable, not a Real variable" in done.stdout + done.stderr
