"""The ``driftfmu`` command is a thin layer over the public API: each sub-command parses its
options, calls the matching ``driftfmu`` function (looked up on the package at call time, so a
replaced function is the one called) and writes nothing that function does not write."""
import inspect
import math
import os
from pathlib import Path

import numpy as np
import pytest

import driftfmu
from driftfmu.simulations.cli import main
from driftfmu.simulations.errors import DataError

STOP = "stopped by the test, inside the API"

#: (command line, API function, arguments the call must bind); "{tmp}" is the test's folder.
COMMANDS = [
    (["build", "--out", "{tmp}/fmus", "--cross-check", "{tmp}/cc"], "build_fmus",
     {"out_dir": "{tmp}/fmus", "backend": "python", "cross_check": "{tmp}/cc", "ssp": None}),
    (["run", "gaussian", "--n", "7", "--a2", "0.03", "--a3", "0.002", "--B", "0.5",
      "--drive", "1", "--Qu", "0.2", "--backend", "native", "--out", "{tmp}/o"], "run_gaussian",
     {"out": "{tmp}/o", "n": 7, "backend": "native", "parameters": {
         "a2": 0.03, "a3": 0.002, "B": 0.5, "drive": 1, "Qu": 0.2, "a4": 0.0}}),
    (["run", "sinusoidal", "--n", "9", "--f", "50", "--preset", "adxl203", "--out", "{tmp}/o"],
     "run_sinusoidal", {"out": "{tmp}/o", "n": 9, "parameters": {"f": 50.0,
                                                                 "preset": "adxl203"}}),
    (["run", "sinusoidal", "--n", "9", "--process", "1", "--B", "1", "--drive", "2", "--Xu",
      "0.5", "--fu", "150", "--out", "{tmp}/o"],
     "run_sinusoidal", {"out": "{tmp}/o", "n": 9, "parameters": {
         "process": 1, "B": 1.0, "drive": 2, "Xu": 0.5, "fu": 150.0, "Qu": 0.0}}),
    # every other option of run sinusoidal away from its default, each reaching its keyword
    (["run", "sinusoidal", "--n", "9", "--X", "0.7", "--phi", "0.3", "--Ts", "0.002",
      "--seed", "5", "--a0", "0.1", "--a1", "1.5", "--a2", "0.02", "--R", "2e-4", "--Qh", "3e-8",
      "--A", "0.5", "--Q", "0.04", "--P0", "0.06", "--estimator", "2", "--Xy", "0.25",
      "--phiy", "0.4", "--fmu-dir", "{tmp}/f", "--backend", "native", "--out", "{tmp}/o"],
     "run_sinusoidal", {"out": "{tmp}/o", "n": 9, "fmu_dir": "{tmp}/f", "backend": "native",
                        "parameters": {"X": 0.7, "f": 150.0, "phi": 0.3, "Ts": 0.002,
                                       "seed": 5, "a0": 0.1, "a1": 1.5, "a2": 0.02,
                                       "R": 2e-4, "process": 2, "Qh": 3e-8, "A": 0.5,
                                       "Q": 0.04, "P0": 0.06, "estimator": 2,
                                       "Xy": 0.25, "phiy": 0.4}}),
    (["montecarlo", "gaussian", "--runs", "3", "--n", "5", "--summary-only", "--a3", "0.002",
      "--out", "{tmp}/o"],
     "montecarlo", {"kind": "gaussian", "runs": 3, "n": 5, "out": "{tmp}/o",
                    "parameters": {"summary_only": True, "a3": 0.002}}),
    (["montecarlo", "sinusoidal", "--runs", "2", "--n", "5", "--f", "40", "--engine", "fmu",
      "--out", "{tmp}/o"], "montecarlo",
     {"kind": "sinusoidal", "runs": 2, "engine": "fmu", "parameters": {"f": 40.0}}),
    (["sweep", "--a2", "0.01", "0.02", "--R", "1e-4", "--runs", "2", "--n", "5",
      "--out", "{tmp}/o"], "sweep",
     {"a2": [0.01, 0.02], "R": [1e-4], "runs": 2, "n": 5, "out": "{tmp}/o"}),
    (["sweep", "--a4", "0.001", "0.002", "--R", "1e-4", "--runs", "2", "--n", "5",
      "--out", "{tmp}/o"], "sweep",
     {"a2": [0.01], "parameters": {"a4": [0.001, 0.002]}}),
    (["experiment", "adxl203", "--sets", "4", "--n", "600", "--freqs", "100,150",
      "--order", "3", "--out", "{tmp}/o"], "experiment_adxl203",
     {"out": "{tmp}/o", "settings": {"sets": 4, "held_out": 1, "n": 600,
                                     "freqs": [100.0, 150.0], "order": 3}}),
    (["experiment", "dual-axis", "--points", "2", "--runs", "1", "--out", "{tmp}/o"],
     "experiment_dual_axis", {"out": "{tmp}/o", "settings": {"points": 2, "runs": 1}}),
    (["identify", "{tmp}/a.csv", "{tmp}/b.csv", "--f", "50", "--held-out", "1", "--order", "3",
      "--out", "{tmp}/o"], "identify",
     {"files": ["{tmp}/a.csv", "{tmp}/b.csv"], "f": 50.0, "held_out": 1, "order": 3,
      "out": "{tmp}/o"}),
    (["allan", "{tmp}/a.csv", "--column", "x", "--taus", "0.5,2", "--out", "{tmp}/o"], "allan",
     {"source": "{tmp}/a.csv", "column": "x", "taus": [0.5, 2.0], "out": "{tmp}/o",
      "time": "time", "per_decade": None, "start_values": None}),
    (["allan", "--start-values", "Q", "0", "seed", "4", "--stop-time", "7", "--column",
      "z_comp", "--backend", "native", "--per-decade", "5", "--out", "{tmp}/o"], "allan",
     {"source": None, "column": "z_comp", "start_values": {"Q": 0, "seed": 4},
      "stop_time": 7.0, "backend": "native", "per_decade": 5, "taus": "octave"}),
]


def _fill(value, tmp):
    if isinstance(value, str):
        return value.replace("{tmp}", str(tmp))
    if isinstance(value, list):
        return [_fill(v, tmp) for v in value]
    if isinstance(value, dict):
        return {k: _fill(v, tmp) for k, v in value.items()}
    return value


@pytest.mark.parametrize("argv,name,expected", COMMANDS,
                         ids=["-".join(w.lstrip("-") for w in c[0][:3] if w[0].isalpha())
                              for c in COMMANDS])
def test_each_command_calls_its_api_function(argv, name, expected, tmp_path, monkeypatch,
                                             capsys):
    real = getattr(driftfmu, name)
    calls = []

    def fake(*args, **kwargs):
        calls.append(inspect.signature(real).bind(*args, **kwargs))
        raise DataError(STOP)
    monkeypatch.setattr(driftfmu, name, fake)
    for f in ("a.csv", "b.csv"):
        (tmp_path / f).write_text("time,x,z\n")
    before = sorted(os.listdir(tmp_path))
    status = main(_fill(argv, tmp_path))
    err = capsys.readouterr().err
    assert status == 1 and err.strip().splitlines()[-1] == "driftfmu: error: " + STOP, err
    assert len(calls) == 1, "driftfmu %s did not call driftfmu.%s" % (" ".join(argv[:2]), name)
    bound = calls[0]
    bound.apply_defaults()
    for key, value in _fill(expected, tmp_path).items():
        got = bound.arguments[key]
        if isinstance(value, dict):  # the **parameters / **settings the call passed
            for k, v in value.items():
                assert got.get(k) == v, (key, k, got.get(k))
        else:
            assert (str(got) if isinstance(value, str) else got) == value, (key, got)
    if "progress" in bound.arguments:  # the command's progress bar is the API's callback
        assert callable(bound.arguments["progress"])
    assert sorted(os.listdir(tmp_path)) == before  # the command itself wrote nothing


def test_build_native_calls_the_api_once_per_backend(tmp_path, monkeypatch, capsys):
    from driftfmu.fmu_src import native_build
    monkeypatch.setattr(native_build, "compiler_problem", lambda platform: None)
    calls = []

    def build(out_dir, **k):  # writes what it is asked to write, where it is asked to
        calls.append((out_dir, k))
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        (Path(out_dir) / ("%s.txt" % k.get("backend", "python"))).write_text("built")
        if k["ssp"]:
            Path(k["ssp"]).write_text(k.get("backend", "python"))
        return {}
    monkeypatch.setattr(driftfmu, "build_fmus", build)
    out = tmp_path / "fmus"
    assert main(["build", "--native", "--backend", "native", "--out", str(out),
                 "--ssp", str(tmp_path / "c.ssp")]) == 0, capsys.readouterr().err
    backends = [k.get("backend", "python") for _, k in calls]
    assert backends == ["python", "native"]
    assert calls[1][1]["fmi_version"] == (2, 3)
    # both calls write to one staged stand-in of --out, moved into place after the second
    assert calls[0][0] == calls[1][0] != out and calls[0][0].name == out.name
    assert sorted(os.listdir(out)) == ["native.txt", "python.txt"]
    # the SSP holds the --backend FMUs: written by the native call, not by the Python one
    assert calls[0][1]["ssp"] is None and calls[1][1]["ssp"].name == "c.ssp"
    assert (tmp_path / "c.ssp").read_text() == "native"
    assert sorted(os.listdir(tmp_path)) == ["c.ssp", "fmus"]  # no staging folder left


def _recording(path, seed, f=50.0, Ts=1e-3, n=2000):
    """A cubic sensor driven at ``f``: z = 0.1 + x + 0.02 x^2 + 0.005 x^3 + noise."""
    rng = np.random.default_rng(seed)
    t = Ts * np.arange(n)
    x = 1.2 * np.sin(2 * math.pi * f * t + seed)
    z = 0.1 + x + 0.02 * x ** 2 + 0.005 * x ** 3 + rng.normal(0.0, 1e-3, n)
    np.savetxt(path, np.column_stack([t, x, z]), delimiter=",", header="time,x,z",
               comments="")
    return str(path)


def test_identify_writes_exactly_what_the_api_writes(tmp_path, monkeypatch, capsys):
    files = [_recording(tmp_path / ("r%d.csv" % i), i) for i in range(3)]
    direct = driftfmu.identify(files, 50.0, held_out=1, out=tmp_path / "api", order=3)
    real, calls = driftfmu.identify, []
    monkeypatch.setattr(driftfmu, "identify",
                        lambda *a, **k: calls.append(1) or real(*a, **k))
    assert main(["identify"] + files + ["--f", "50", "--held-out", "1", "--order", "3",
                                        "--out", str(tmp_path / "cli")]) == 0
    out = capsys.readouterr().out
    assert calls == [1]
    assert sorted(os.listdir(tmp_path / "cli")) == sorted(os.listdir(tmp_path / "api")) \
        == ["identify.csv", "identify.json"]
    for name in ("identify.csv", "identify.json"):
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "api" / name).read_bytes()
    assert "a3 %.6g" % direct["model"]["a3"] in out
