"""``experiment adxl203 --order 2|3|4`` (issue 16): the filter runs with the identified cubic
(and quartic) term; the JSON says which order; the default is today's (the stored summary of
tests/test_adxl203.py, which now also says ``order: 2``).  The compiled kernel's ADXL203 chain
takes the filter's ``a3, a4`` and equals models/ bit for bit."""
import json

import numpy as np
import pytest

from driftfmu.models import adxl203, harmonic
from driftfmu.simulations import adxl203 as experiment
from driftfmu.simulations import kernel
from driftfmu.simulations.cli import main


@pytest.fixture(scope="module")
def lib():
    lib = kernel.library()
    if lib is None:
        pytest.skip("no C compiler for the kernel")
    return lib


@pytest.mark.parametrize("a3, a4", [(0.0018, 0.0), (0.0018, -4e-4), (0.0, 3e-4)])
def test_kernel_adxl203_chain_with_the_filters_a3_a4_equals_models(lib, a3, a4):
    ex = dict(experiment.set_drive(123, 150.0))
    sp = dict(adxl203.ADXL203, seed=123, noise=1)
    es = dict(experiment.estimator_values(dict(a0=2.5, a1=0.99, a2=0.0096, R=2e-5), 150.0,
                                          1e-4), a3=a3, a4=a4)
    want = adxl203.simulate(600, ex, sp, es, 1e-4)
    got = kernel.adxl203_simulate(lib, 600, ex, sp, es, 1e-4)
    for c in kernel.COLUMNS:
        assert np.asarray(want[c]).tobytes() == got[c].tobytes(), c
    # ... and the terms reach the filter: not the quadratic model's estimates
    plain = adxl203.simulate(600, ex, sp, dict(es, a3=0.0, a4=0.0), 1e-4)
    assert not np.array_equal(plain["dc_ekf1"], want["dc_ekf1"])
    assert not np.array_equal(plain["x_hat"], want["x_hat"])


def test_estimator_values_carry_the_fitted_higher_terms_only_when_fitted():
    es = experiment.estimator_values(dict(a0=1.0, a1=1.0, a2=0.01, R=1e-4), 100.0, 1e-4)
    assert "a3" not in es and "a4" not in es and es["process"] == harmonic.HARMONIC
    es = experiment.estimator_values(dict(a0=1.0, a1=1.0, a2=0.01, R=1e-4, a3=0.002), 100.0,
                                     1e-4)
    assert es["a3"] == 0.002 and "a4" not in es


@pytest.mark.parametrize("kwargs, match", [
    (dict(order=5), "order = 5 is not allowed; allowed: 2, 3, 4"),
    (dict(order=4, freqs=(1500.0,)), "order 4 needs harmonic 4 of f = 1500 Hz"),
])
def test_bad_order_fails_before_anything_is_written(tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        experiment.run_adxl203(out=tmp_path / "out", fmu_dir=tmp_path / "nofmus", **kwargs)
    assert not (tmp_path / "out").exists() and not (tmp_path / "nofmus").exists()


def test_cli_refuses_an_unknown_order(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["experiment", "adxl203", "--order", "5"])
    assert exc.value.code == 2


@pytest.mark.integration
def test_order_3_runs_the_filter_with_the_identified_cubic_term(built_fmus, tmp_path):
    kw = dict(freqs=(100.0, 175.0), sets=5, held_out=2, n=4000, workers=2,
              fmu_dir=built_fmus["Excitation"].parent)
    assert main(["experiment", "adxl203", "--freqs", "100,175", "--sets", "5", "--held-out",
                 "2", "--n", "4000", "--workers", "2", "--order", "3", "--fmu-dir",
                 str(kw["fmu_dir"]), "--out", str(tmp_path)]) == 0
    s = json.loads((tmp_path / "adxl203.json").read_text())
    assert s["settings"]["order"] == 3 and "of order 3" in s["identification"]
    # the summary names the terms the filter runs with: a3, and no a4 (that is order 4's)
    assert s["identification"].endswith(", of order 3: the filter runs with its a3")
    # the FMUs (DriftEstimator with a3) equal the reference, every held-out set
    assert s["validation"]["max_abs_diff"] == 0.0
    truth = adxl203.config(**adxl203.ADXL203).a3
    for p in s["per_frequency"]:
        m = p["model"]
        assert set(m) >= {"a0", "a1", "a2", "a3", "R"} and "a4" not in m
        # the averaged cubic term is the stand-in's to within 15 %: the fit sees the sensor
        # through its output low-pass (1064 Hz), its lag and the cross-axis motion, so it is
        # not the bare a3 within its statistical spread (observed 0.0018-0.0019 against
        # 0.002: a bias at 100 Hz, documented in docs/results.md and docs/method.md section 9);
        # a dropped or doubled term, or one of the wrong sign, fails
        assert 0.85 * truth < m["a3"] < 1.15 * truth, (m["a3"], truth, m["sd_a3"])
    # the figures docs/method.md section 9 and docs/results.md quote for this reduced run
    assert ["%.5f" % p["model"]["a3"] for p in s["per_frequency"]] == ["0.00179", "0.00191"]
    # docs/method.md section 9: at 100 Hz a bias ten times the fits' spread over the sets
    # (2e-5); at 175 Hz the three sets spread by 1e-4, as much as its bias
    low, high = (p["model"] for p in s["per_frequency"])
    assert "%.0e" % low["sd_a3"] == "2e-05" and truth - low["a3"] > 9 * low["sd_a3"]
    assert "%.0e" % high["sd_a3"] == "1e-04" and truth - high["a3"] < 1.5 * high["sd_a3"]
    assert "a3" in s["model"]
    # the filter's model differs from the 2nd-order run's, and so does EKF1; the drift is not
    # the model's: the empirical drift of the held-out sets is the same
    two = experiment.run_adxl203(**kw)
    assert two["settings"]["order"] == 2 and "a3" not in two["model"]
    assert two["identification"].endswith("one model per frequency")   # no order named
    for p3, p2 in zip(s["per_frequency"], two["per_frequency"]):
        assert p3["dc_ekf1"] != p2["dc_ekf1"]
        assert p3["dc_empirical"][0] == pytest.approx(p2["dc_empirical"][0], rel=1e-9, abs=1e-6)


@pytest.mark.integration
def test_order_4_says_the_filter_runs_with_a3_and_a4(built_fmus):
    # the other side of order 3's sentence: order 4 names both higher terms, and has them
    s = experiment.run_adxl203(freqs=(100.0,), sets=3, held_out=1, n=4000, workers=2,
                               fmu_dir=built_fmus["Excitation"].parent, validate=False,
                               plot=False, order=4)
    assert s["settings"]["order"] == 4
    assert s["identification"].endswith(", of order 4: the filter runs with its a3, a4")
    assert {"a3", "a4"} <= set(s["model"]) and {"a3", "a4"} <= set(s["per_frequency"][0]["model"])
