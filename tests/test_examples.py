"""Every example in examples/ runs and gives the result it claims (FMPy's tests/test_examples.py
style: each example is a function with show_plot=False that returns its result)."""
import importlib.util
import math
import os
from pathlib import Path

import numpy as np
import pytest

from driftfmu.models import chain

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(not EXAMPLES.is_dir(), reason="no examples/ folder")]


def _example(name):
    spec = importlib.util.spec_from_file_location("example_" + name, EXAMPLES / (name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def fmu_dir(fmus_in_build_layout):
    """The session's FMUs in the layout of build/fmus."""
    return fmus_in_build_layout


def _custom_input_checks(result):
    t = result["time"]
    x = 0.6 * np.sin(2 * np.pi * 7.0 * t) + 0.3 * np.sin(2 * np.pi * 31.0 * t) + 0.05 * t
    realised = 0.02 * np.mean(x ** 2)
    assert result.dtype.names == ("time", "z", "x_hat", "dc_ekf1", "z_comp")
    assert result.shape == (4000,)
    # z follows the array's x through the sensor (noise sd 0.01 V)
    assert np.abs(result["z"] - (x + 0.02 * x * x)).max() < 6 * 0.01
    # EKF1 finds the drift of the custom excitation within 5 %
    assert abs(result["dc_ekf1"][-1] - realised) < 0.05 * realised
    np.testing.assert_array_equal(result["z_comp"], result["z"] - result["dc_ekf1"])


def test_custom_input(fmu_dir):
    result = _example("custom_input").simulate_custom_input(show_plot=False, fmu_dir=fmu_dir)
    _custom_input_checks(result)
    native = _example("custom_input").simulate_custom_input(show_plot=False, fmu_dir=fmu_dir,
                                                            backend="native")
    for c in result.dtype.names:
        np.testing.assert_array_equal(native[c], result[c], err_msg=c)


def test_native_c_loop_equals_models_bit_for_bit(fmu_dir):
    out = _example("native_c_loop").run_c_style_loop(show_plot=False, fmu_dir=fmu_dir, n=500,
                                                     seed=3)
    ref = chain.simulate(500, 3)
    for c in ("x", "z", "dc_ekf1"):
        np.testing.assert_array_equal(out[c], np.asarray(ref[c]), err_msg=c)
    np.testing.assert_allclose(out["time"], np.arange(500) * 1e-3, rtol=0, atol=1e-15)


def test_identify_a2_finds_the_sensor(fmu_dir, tmp_path):
    module = _example("identify_a2")
    summary = module.identify_a2(show_plot=False, fmu_dir=fmu_dir, folder=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec1.csv", "rec2.csv", "rec3.csv"]
    model, true = summary["model"], module.TRUE
    # standard errors of the mean of two fits of 2001 samples, X = 1 g, white noise sd(R)
    from driftfmu.models.identify import standard_errors
    se = {k: v / math.sqrt(2) for k, v in standard_errors(math.sqrt(true["R"]), 1.0, 2001).items()}
    for name in ("a0", "a1", "a2"):
        assert abs(model[name] - true[name]) < 4.5 * se[name], (name, model[name], se[name])
    assert summary["margin_db"] >= 5.0  # the letter's claim on the held-out recording


def test_dask_sweep_equals_the_local_sweep_and_shows_the_letters_trend():
    pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] is not installed")
    import driftfmu
    result = _example("dask_sweep").dask_sweep(show_plot=False, runs=100, n=400)
    local = driftfmu.sweep(a2=[1e-3, 1e-2, 1e-1], R=[1e-6, 1e-4, 1e-2], runs=100, n=400,
                           workers=1)
    for key in ("grid_dc1", "grid_dc3", "grid_x2bar"):
        np.testing.assert_array_equal(result[key], local[key], err_msg=key)
    error = result["ekf1_error"]
    assert error.shape == (3, 3)
    # the letter's Fig. 2: smaller a2 gives a smaller EKF1 error, at every R
    assert (np.diff(error, axis=0) > 0).all(), error


def test_notebook_runs(fmu_dir, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    nb = nbformat.read(str(EXAMPLES / "custom_input.ipynb"), as_version=4)
    monkeypatch.setenv("DRIFTFMU_FMU_DIR", str(fmu_dir))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(ROOT)}}).execute()
    text = "".join(o.get("text", "") for cell in nb.cells if cell.cell_type == "code"
                   for o in cell.get("outputs", []))
    assert "fields: ('time', 'z', 'x_hat', 'dc_ekf1', 'z_comp')" in text
    import re
    ekf1, realised = map(float, re.search(r"EKF1 drift (\S+) V, realised a2 mean\(x\^2\) (\S+) V",
                                          text).groups())
    assert abs(ekf1 - realised) < 0.05 * realised
