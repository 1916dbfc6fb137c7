"""The public API (driftfmu.build_fmus, driftfmu.simulate, the experiments) against models/."""
import inspect
import os
import re
from pathlib import Path

import numpy as np
import pytest

import driftfmu
from driftfmu.models import chain

N = 300


@pytest.fixture(scope="module")
def fmu_dir(python_fmus, native_fmus, tmp_path_factory):
    """A folder in the layout build_fmus writes, linking the session's FMUs."""
    d = tmp_path_factory.mktemp("api_fmus")
    for name, path in python_fmus.items():
        (d / path.name).symlink_to(path)
    for v, paths in native_fmus.items():
        (d / "native" / ("fmi%d" % v)).mkdir(parents=True)
        for name, path in paths.items():
            (d / "native" / ("fmi%d" % v) / path.name).symlink_to(path)
    return d


def _stop(n, Ts=1e-3):
    return (n - 1) * Ts


@pytest.mark.integration
def test_simulate_the_chain_equals_models_sample_by_sample(fmu_dir):
    result = driftfmu.simulate(stop_time=_stop(N), start_values={"a2": 0.05, "seed": 7},
                               fmu_dir=fmu_dir)
    assert result.dtype.names[0] == "time"
    assert result.shape == (N,)
    np.testing.assert_array_equal(result["time"], np.arange(N) * 1e-3)
    ref = chain.simulate(N, 7, a2=0.05)
    for c in ("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"):
        np.testing.assert_array_equal(result[c], np.asarray(ref[c]), err_msg=c)


@pytest.mark.integration
def test_a_run_that_stops_where_it_starts_is_its_first_communication_point(fmu_dir):
    """stop_time = start_time (the bound of stop_time >= start_time; one ulp below it is
    refused, above): one row, at the start, models/' first sample."""
    result = driftfmu.simulate(stop_time=0.0, start_values={"seed": 7}, fmu_dir=fmu_dir)
    assert result.shape == (1,) and result["time"].tolist() == [0.0]
    ref = chain.simulate(1, 7)
    for c in ("x", "z", "x_hat", "dc_ekf1"):
        np.testing.assert_array_equal(result[c], np.asarray(ref[c]), err_msg=c)


@pytest.mark.integration
@pytest.mark.parametrize("fmi_version", [2, 3])
def test_native_backend_gives_the_python_fmus_bits(fmu_dir, fmi_version):
    kw = dict(stop_time=_stop(N), start_values={"seed": 3}, fmu_dir=fmu_dir)
    python = driftfmu.simulate(**kw)
    native = driftfmu.simulate(backend="native", fmi_version=fmi_version, **kw)
    assert native.dtype == python.dtype
    for c in python.dtype.names:
        np.testing.assert_array_equal(native[c], python[c], err_msg=c)


@pytest.mark.integration
def test_custom_excitation_from_an_array_equals_models(fmu_dir):
    # the chain without the Excitation FMU, x from a NumPy array: the same run as models/
    ref = chain.simulate(N, 5)
    signal = np.zeros(N, dtype=[("time", float), ("x", float)])
    signal["time"] = np.arange(N) * 1e-3
    signal["x"] = ref["x"]
    result = driftfmu.simulate(["Accelerometer", "DriftEstimator"], stop_time=_stop(N),
                               start_values={"seed": 5}, input=signal, output=["z", "dc_ekf1"],
                               fmu_dir=fmu_dir)
    assert result.dtype.names == ("time", "z", "dc_ekf1")
    np.testing.assert_array_equal(result["z"], np.asarray(ref["z"]))
    np.testing.assert_array_equal(result["dc_ekf1"], np.asarray(ref["dc_ekf1"]))


@pytest.mark.integration
def test_input_is_held_between_its_rows_and_dotted_start_values_reach_one_fmu(fmu_dir):
    signal = np.array([(0.0, 1.0), (0.0045, 2.0)], dtype=[("time", float), ("x", float)])
    result = driftfmu.simulate(["Accelerometer"], stop_time=0.009, input=signal,
                               start_values={"noise": 0, "Accelerometer.a2": 0.5, "a0": 0.1},
                               output=["Accelerometer.z"], fmu_dir=fmu_dir)
    x = np.where(np.arange(10) * 1e-3 < 0.0045, 1.0, 2.0)
    np.testing.assert_array_equal(result["z"], 0.1 + x + 0.5 * x * x)


@pytest.mark.integration
def test_a_name_recorded_from_two_fmus_is_qualified(fmu_dir):
    result = driftfmu.simulate(["DriftEstimator", "DualDriftEstimator"], stop_time=0.002,
                               output=["x_hat", "P"], fmu_dir=fmu_dir)
    assert result.dtype.names == ("time", "DriftEstimator.x_hat", "P",
                                  "DualDriftEstimator.x_hat")


@pytest.mark.parametrize("kwargs, words", [
    (dict(fmus=["Excitation", "Nope"]), ["'Nope'", "DriftEstimator"]),
    (dict(fmus=[]), ["fmus = []"]),
    (dict(step_size=0.0), ["step_size = 0.0", "> 0"]),
    (dict(stop_time=-1.0), ["stop_time = -1.0"]),
    (dict(backend="java"), ["backend = 'java'", "'native'"]),
    (dict(fmi_version=3), ["fmi_version = 3", "allowed: 2"]),
    (dict(fmus="DriftEstimator"), ["fmus = 'DriftEstimator'", "a sequence of FMU names"]),
    (dict(fmus=None), ["fmus = None", "a sequence of FMU names"]),
    (dict(stop_time="1"), ["stop_time = '1' is not a number"]),
    (dict(stop_time=True), ["stop_time = True is not a number"]),
    (dict(step_size=None, start_time="0"), ["start_time = '0' is not a number"]),
    (dict(stop_time=-5e-324), ["stop_time = -5e-324 are not allowed", "stop_time >= start_time"]),
])
def test_simulate_refuses_bad_settings_before_building(kwargs, words, tmp_path):
    with pytest.raises(ValueError) as info:
        driftfmu.simulate(fmu_dir=tmp_path / "none", **kwargs)
    for word in words:
        assert word in str(info.value)
    assert not (tmp_path / "none").exists()


@pytest.mark.integration
@pytest.mark.parametrize("kwargs, words", [
    (dict(start_values={"nope": 1.0}), ["'nope'", "a2"]),
    (dict(input=np.zeros(3, dtype=[("time", float), ("x", float)])),
     ["'x'", "Excitation"]),
    (dict(input=np.zeros(3, dtype=[("t", float), ("x", float)])), ["'time'"]),
    (dict(output=["nope"]), ["'nope'"]),
    # start values are checked before any FMU runs: one line, what is allowed (an Integer out
    # of its 32 bits would reach the FMU wrapped, as another seed, through fmpy)
    (dict(start_values={"seed": 2 ** 40}), ["seed = 1099511627776 is out of range",
                                             "seed <= 2147483647"]),
    (dict(start_values={"seed": 2 ** 32 + 5}), ["seed = 4294967301 is out of range"]),
    (dict(start_values={"seed": 1.9}), ["seed = 1.9 is not an integer"]),
    (dict(start_values={"seed": -1.5}), ["seed = -1.5 is not an integer"]),
    (dict(start_values={"kind": 1.5}), ["kind = 1.5 is not an integer; allowed: an integer"]),
    (dict(start_values={"seed": -1}), ["seed = -1 is out of range", "seed >= 0"]),
    (dict(start_values={"a2": float("nan")}), ["a2 = nan is not finite"]),
    (dict(start_values={"Q": float("inf")}), ["Q = inf is not finite", "Q >= 0"]),
    (dict(start_values={"R": 0}), ["R = 0 is out of range", "R > 0"]),
    (dict(start_values={"a1": 0}), ["a1 = 0 is out of range", "a1 != 0"]),
    (dict(start_values={"a2": "x"}), ["a2 = 'x' is not a number"]),
    (dict(start_values={"a2": None}), ["a2 = None is not a number"]),
    (dict(start_values={"a2": True}), ["a2 = True is not a number"]),
    (dict(start_values={"estimator": 4}), ["estimator = 4 is not allowed", "estimator <= 3"]),
    (dict(start_values={"estimator": 2.5}), ["estimator = 2.5 is not an integer", "an integer"]),
    (dict(input=np.array([(0.0, 1.0), (0.001, np.nan)], dtype=[("time", float), ("z", float)]),
          fmus=["DriftEstimator"]), ["input field 'z'", "not finite"]),
    (dict(input=[1, 2, 3]), ["input has fields ()", "'time'"]),
    (dict(start_values=[1, 2]), ["start_values = [1, 2] is not a mapping", "allowed: a dict"]),
])
def test_simulate_refuses_bad_names_and_values(fmu_dir, kwargs, words):
    with pytest.raises(ValueError) as info:
        driftfmu.simulate(stop_time=0.002, fmu_dir=fmu_dir, **kwargs)
    assert "\n" not in str(info.value)
    for word in words:
        assert word in str(info.value)


def test_a_run_that_cannot_fit_in_memory_is_refused_before_it_starts(fmu_dir):
    with pytest.raises(ValueError) as info:
        driftfmu.simulate(stop_time=1e12, fmu_dir=fmu_dir)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith("simulate(stop_time=1000000000000.0, step_size=0.001), recording "
                           "17 values at each of 1000000000000001 communication points, needs "
                           "about "), text
    assert "of memory; this machine has" in text and "allowed: a run that fits: at most " \
        "about" in text, text


def test_an_empty_fmu_dir_is_refused_not_the_current_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for empty in ("", "  "):
        with pytest.raises(ValueError, match="fmu_dir = .* is empty; allowed: a folder path"):
            driftfmu.simulate(fmu_dir=empty)
    assert os.listdir(tmp_path) == []


def test_build_fmus_refuses_what_it_cannot_build(tmp_path):
    for kwargs, word in [(dict(backend="java"), "backend"), (dict(fmi_version=3), "fmi_version"),
                         (dict(names=["Nope"]), "Nope")]:
        with pytest.raises(ValueError, match=word):
            driftfmu.build_fmus(tmp_path / "out", **kwargs)
    for kwargs, word in [(dict(backend="native", fmi_version=()), "fmi_version"),
                         (dict(backend="native", fmi_version=(2, 4)), "fmi_version = 4"),
                         (dict(names=["Excitation"], ssp=tmp_path / "c.ssp"), "ssp needs"),
                         (dict(backend="native", fmi_version=3, ssp=tmp_path / "c.ssp"),
                          "fmi_version 2")]:
        with pytest.raises(ValueError, match=word):
            driftfmu.build_fmus(tmp_path / "out", **kwargs)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_build_fmus_refuses_a_file_in_the_way_before_it_builds(tmp_path, monkeypatch):
    """It built every FMU, then raised NotADirectoryError naming its staging folder."""
    from driftfmu.fmu_src import builder
    monkeypatch.setattr(builder, "build_fmus", lambda *a, **k: pytest.fail("built"))
    (tmp_path / "afile.txt").write_text("mine")
    for kwargs, said in ((dict(out_dir=tmp_path / "afile.txt"), "out_dir"),
                         (dict(out_dir=tmp_path / "afile.txt" / "sub"), "out_dir"),
                         (dict(out_dir=tmp_path / "o", ssp=tmp_path / "afile.txt" / "c.ssp"),
                          "ssp"),
                         (dict(out_dir=tmp_path / "o", cross_check=tmp_path / "afile.txt"),
                          "cross_check")):
        with pytest.raises(ValueError) as info:
            driftfmu.build_fmus(**kwargs)
        assert str(info.value).startswith("%s = " % said) and (
            "%s is an existing file; allowed: " % (tmp_path / "afile.txt")) in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile.txt"]
    assert (tmp_path / "afile.txt").read_text() == "mine"


@pytest.mark.parametrize("n", ["5", True, b"5"])
def test_a_count_that_is_not_a_number_is_refused(n, tmp_path):
    """``run_gaussian(n="5")`` raised "unsupported operand type(s) for //" from the master."""
    with pytest.raises(ValueError, match="n = %s is not a number; allowed: an integer n >= 1"
                       % re.escape(repr(n))):
        driftfmu.run_gaussian(n=n, fmu_dir=tmp_path / "fmus")
    assert os.listdir(tmp_path) == []


def _fake_native(out_dir, names, fmi_versions, log, **kw):
    """Writes what build_native_fmus writes, without a compiler."""
    built = {}
    for v in fmi_versions:
        (Path(out_dir) / ("fmi%d" % v)).mkdir(parents=True, exist_ok=True)
        built[v] = {}
        for n in names:
            path = Path(out_dir) / ("fmi%d" % v) / ("%s.fmu" % n)
            path.write_bytes(b"fmu")
            log("built %s" % path)
            built[v][n] = str(path)
    return built


def test_build_fmus_of_several_fmi_versions_keys_them_by_folder(tmp_path, monkeypatch):
    from driftfmu.fmu_src import native_build
    monkeypatch.setattr(native_build, "build_native_fmus", _fake_native)
    lines = []
    one = driftfmu.build_fmus(tmp_path, backend="native", fmi_version=3, names=["Excitation"],
                              log=lines.append)
    assert one == {"Excitation": tmp_path / "native" / "fmi3" / "Excitation.fmu"}
    both = driftfmu.build_fmus(tmp_path, backend="native", fmi_version=(2, 3),
                               names=["Excitation", "Accelerometer"], log=lines.append)
    assert sorted(both) == ["fmi2/Accelerometer", "fmi2/Excitation", "fmi3/Accelerometer",
                            "fmi3/Excitation"]
    assert both["fmi2/Accelerometer"] == tmp_path / "native" / "fmi2" / "Accelerometer.fmu"
    assert len(lines) == 5


def test_a_failed_build_leaves_no_folder_it_created(tmp_path, monkeypatch):
    from driftfmu.fmu_src import native_build

    def half(out_dir, **kw):
        _fake_native(out_dir, **kw)
        raise RuntimeError("the compiler broke")
    monkeypatch.setattr(native_build, "build_native_fmus", half)
    (tmp_path / "mine.txt").write_text("keep")
    with pytest.raises(RuntimeError, match="compiler broke"):
        driftfmu.build_fmus(tmp_path, backend="native", fmi_version=(2, 3),
                            cross_check=tmp_path / "cc" / "x")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt"]


@pytest.mark.integration
def test_run_gaussian_is_simulate_plus_the_reference_checks(fmu_dir):
    res = driftfmu.run_gaussian(n=N, fmu_dir=fmu_dir, seed=2)
    sim = driftfmu.simulate(stop_time=_stop(N), start_values={"seed": 2}, fmu_dir=fmu_dir)
    np.testing.assert_array_equal(np.asarray(res["columns"]["dc_ekf1"]), sim["dc_ekf1"])
    assert res["summary"]


def test_public_names_are_exactly_all_and_typed():
    public = {n for n, v in vars(driftfmu).items()
              if not n.startswith("_") and callable(v) and not inspect.ismodule(v)}
    assert public == set(driftfmu.__all__) - {"__version__"}
    for name in public:
        signature = inspect.signature(getattr(driftfmu, name))
        assert signature.return_annotation is not inspect.Signature.empty, name
