"""The known input u (eq. 1) carried by every master when ``B != 0`` (issue 16).

The filter's prediction is ``x-_k = A x+_{k-1} + B u_k``: the DriftEstimator must get the
Excitation's ``u``.  For each way of running the chain (the public ``driftfmu.simulate``, the
fmpy master and the fast master, the sinusoidal master, the batch engine's FMU path, the SSP
export) a run with ``B != 0`` equals models/ bit for bit, and the same run without the
connection does not (so each test fails when the wiring is dropped).
"""
import numpy as np
import pytest

import driftfmu
from driftfmu.models import chain, excitation

N = 200
#: A run where the input matters: B u is of the order of the process noise.
GENERAL = dict(a0=0.1, a2=0.05, A=0.6, Q=0.05, R=1e-3, a3=0.02, a4=0.03, B=0.8)
INPUT = dict(drive=excitation.GAUSSIAN, Qu=0.3)
COLUMNS = ("x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")


@pytest.fixture(scope="module")
def fmu_dir(python_fmus, native_fmus, tmp_path_factory):
    """A folder in the layout build_fmus writes, linking the session's FMUs."""
    d = tmp_path_factory.mktemp("wiring_fmus")
    for path in python_fmus.values():
        (d / path.name).symlink_to(path)
    for v, paths in native_fmus.items():
        (d / "native" / ("fmi%d" % v)).mkdir(parents=True)
        for path in paths.values():
            (d / "native" / ("fmi%d" % v) / path.name).symlink_to(path)
    return d


@pytest.fixture(scope="module")
def unwired(python_fmus):
    """The Gaussian run of :data:`GENERAL` without the u connection (the filter predicts with
    u = 0): what a master that drops the wiring shows."""
    from driftfmu.simulations.cosim import cosimulate
    from driftfmu.simulations.gaussian import CONNECTIONS, FMU_NAMES, start_values
    raw = cosimulate({n: python_fmus[n] for n in FMU_NAMES}, CONNECTIONS, N, 1e-3,
                     start_values=start_values(seed=4, P0=0.2, **GENERAL, **INPUT))
    return {c: raw["DriftEstimator.%s" % c] for c in ("x_hat", "P", "dc_ekf1")}


def _reference(seed=4, P0=0.2, **kw):
    p = dict(GENERAL, **INPUT)
    p.update(kw)
    return chain.simulate(N, seed, x0=0.0, P0=P0, **p)


@pytest.mark.integration
@pytest.mark.parametrize("backend, fmi_version", [("python", 2), ("native", 2), ("native", 3)])
def test_simulate_carries_u_to_the_filter(fmu_dir, unwired, backend, fmi_version):
    ref = _reference()
    start = dict(GENERAL, **INPUT, seed=4, P0=0.2)
    result = driftfmu.simulate(stop_time=(N - 1) * 1e-3, start_values=start, backend=backend,
                               fmi_version=fmi_version, fmu_dir=fmu_dir)
    for c in COLUMNS:
        np.testing.assert_array_equal(result[c], np.asarray(ref[c]), err_msg=c)
    assert np.any(result["u"] != 0.0)
    assert np.any(np.asarray(unwired["x_hat"]) != result["x_hat"])  # the test can fail
