"""The three FMUs loaded, stepped and read by importers other than fmpy, against our master.

* JavaFMI (JVM, Maven Central; tests/importers/javafmi): the wired chain, stepped by a Java
  master with the same timing as ours (outputs copied along the connections in order at each
  point), in a child process with libpython on LD_LIBRARY_PATH and no LD_PRELOAD.
* libcosim (C++, PyPI libcosimpy): each FMU on its own with recorded inputs.  libcosim reads
  outputs right after a step and sets inputs before the next (tests/importers/drivers.py), so
  the Excitation and the memory-less Accelerometer are compared with our master row by row and
  the DriftEstimator with the held-input reference of fmu_src/crosscheck.py.

Each test writes one line per importer (steps, largest difference) to the terminal, so the CI
log shows that both importers stepped the FMUs.
"""
import pytest

from driftfmu.fmu_src import crosscheck
from driftfmu.fmu_src.ssp import CONNECTIONS, DRIFT_OUTPUTS, chain_start_values
from importers import drivers
from driftfmu.models import chain
from driftfmu.simulations.gaussian import run_gaussian

pytestmark = pytest.mark.integration

N = 200          # communication points
TS = 1e-3
TOLERANCE = 1e-12


@pytest.fixture(scope="session")
def javafmi_classpath():
    try:
        return drivers.build_javafmi_host()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="session")
def libcosim_ready():
    try:
        drivers.libcosim()
    except drivers.ImporterMissing as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="module")
def master(built_fmus):
    """Our fmpy master's columns for N samples (validated against models/ to 1e-12)."""
    return run_gaussian(n=N, fmu_dir=built_fmus["Excitation"].parent, plot=False)["columns"]


def _max_diff(a, b):
    assert len(a) == len(b), (len(a), len(b))
    return max(abs(x - y) for x, y in zip(a, b))


def test_javafmi_steps_the_wired_chain_like_our_master(built_fmus, javafmi_classpath, master,
                                                       tmp_path, report):
    fmus = {name: built_fmus[name] for name in ("Excitation", "Accelerometer", "DriftEstimator")}
    record = {"Excitation": ["x"], "Accelerometer": ["z"],
              "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}
    cols, summary = drivers.run_javafmi(javafmi_classpath, tmp_path, fmus, N, TS,
                                        start=chain_start_values(), connections=CONNECTIONS,
                                        record=record)
    ref = chain.simulate(N, 1)
    diffs = {"time": _max_diff(cols["time"], master["time"])}
    for name, names in record.items():
        for v in names:
            got = cols["%s.%s" % (name, v)]
            diffs[v] = max(_max_diff(got, master[v]), _max_diff(got, ref[v]))
    worst = max(diffs.values())
    report("IMPORTER JavaFMI 2.24.3 (JVM, Maven Central): wired chain, %d steps, "
           "max |diff| vs fmpy master and models/ = %.3g  [%s]" % (N, worst, summary))
    assert all(d <= TOLERANCE for d in diffs.values()), diffs


def test_libcosim_steps_each_fmu_with_recorded_inputs(built_fmus, libcosim_ready, master,
                                                      report):
    # the FMUs' defaults are the master's settings, so no start values are needed
    assert master["x"] == crosscheck.chain_columns(N)["x"]
    exc = drivers.run_libcosim(built_fmus["Excitation"], "Excitation", N, TS, record=["x"])
    acc = drivers.run_libcosim(built_fmus["Accelerometer"], "Accelerometer", N, TS,
                               inputs={"x": master["x"]}, record=["z"], lookahead=True)
    est = drivers.run_libcosim(built_fmus["DriftEstimator"], "DriftEstimator", N, TS,
                               inputs={"z": master["z"]}, record=list(DRIFT_OUTPUTS))
    held = crosscheck.held_input_reference("DriftEstimator", {"z": master["z"]}, N)
    diffs = {
        "time": _max_diff(exc["time"], master["time"]),
        "x": _max_diff(exc["x"], master["x"]),
        "z": _max_diff(acc["z"], master["z"]),
    }
    diffs.update({v: _max_diff(est[v], held[v]) for v in DRIFT_OUTPUTS})
    # the first row is read before any step: there the held input is the master's own
    diffs["first row"] = max(abs(est[v][0] - master[v][0])
                             for v in ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"))
    worst = max(diffs.values())
    report("IMPORTER libcosim (libcosimpy, C++, PyPI): Excitation, Accelerometer, DriftEstimator "
           "with recorded inputs, %d steps each, max |diff| vs fmpy master "
           "(DriftEstimator: held-input reference) = %.3g" % (N, worst))
    assert all(d <= TOLERANCE for d in diffs.values()), diffs
