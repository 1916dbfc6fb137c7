"""The loader shim's own answers (fmu_src/loader/fmi2_shim.c), seen from a C host."""
import ctypes.util
import os
import sysconfig

import pytest

import fuzz

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    exe = fuzz.compile_host(tmp_path_factory.mktemp("shim_host"))
    if exe is None:
        pytest.skip("no C compiler to build the host")
    return exe


@pytest.fixture(scope="module")
def model(built_fmus, tmp_path_factory):
    return fuzz.unzip(built_fmus["Accelerometer"], tmp_path_factory.mktemp("shim") / "acc")


def logged(result, line_no):
    """The messages logged during the call on script line ``line_no``."""
    out, messages = result.lines, []
    for line in out:
        if line.startswith("S "):
            if int(line.split()[1]) == line_no:
                return messages
            messages = []
        elif line.startswith("LOG "):
            messages.append(line)
    return []


def test_driftfmu_libpython_that_is_not_libpython_is_named(host, model):
    libm = ctypes.util.find_library("m")
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "PYTHONPATH")}
    env.update(DRIFTFMU_LIBPYTHON=libm, LD_LIBRARY_PATH=sysconfig.get_config_var("LIBDIR"))
    result = fuzz.run_script(host, fuzz.header(model) + ["free 0"], env=env)
    assert result.problems() == [] and "INST 0 ok" in result.lines, result.output
    warning = logged(result, 2)[0]
    assert warning.startswith("LOG 1 ")
    assert "DRIFTFMU_LIBPYTHON=%s is not a usable libpython" % libm in warning
    assert "not a libpython (it has no Py_IsInitialized)" in warning


def test_state_machine_status_inquiries_and_states(host, model):
    lines = fuzz.header(model) + [
        "step 0 0 %r" % model.Ts,                    # 4: before initialisation
        "setup 0 1.5", "enter 0", "exit 0",
        "step 0 1.5 %r" % (2 * model.Ts),            # 8
        "status 0 2 r",                              # 9: fmi2LastSuccessfulTime
        "status 0 3 b",                              # 10: fmi2Terminated
        "status 0 0 s",                              # 11: fmi2DoStepStatus
        "gst 0 1", "fst 0 1", "fst 0 1",             # 12-14: freed twice: the second is NULL
        "null 0 fst",                                # 15
        "term 0", "step 0 1.502 0.001",              # 16, 17
        "free 0"]
    result = fuzz.run_script(host, lines)
    assert result.problems() == [], result.output
    status = result.statuses()
    assert status[4] == fuzz.ERROR
    assert logged(result, 4)[0].endswith("fmi2DoStep is not allowed in state Instantiated "
                                         "(FMI 2.0 co-simulation); allowed in: Step Complete")
    assert status[8] == fuzz.OK and status[9] == fuzz.OK and status[10] == fuzz.OK
    assert status[11] == fuzz.DISCARD and "fmi2DoStepStatus" in logged(result, 11)[0]
    assert [status[n] for n in (12, 13, 14, 15)] == [fuzz.OK] * 4
    assert status[17] == fuzz.ERROR and "state Terminated" in logged(result, 17)[0]


def test_last_successful_time_is_the_end_of_the_last_step(host, model):
    lines = fuzz.header(model) + fuzz.initialise(model, 0) + [
        "step 0 0 0.001", "step 0 0.001 0.002", "status 0 2 r",
        "step 0 0.003 nan", "status 0 2 r", "status 0 3 b", "free 0"]
    result = fuzz.run_script(host, lines)
    assert result.problems() == [], result.output
    n = len(lines)
    values, status = result.values(), result.statuses()
    assert float(values[n - 4][0]) == 0.001 + 0.002
    assert status[n - 3] == fuzz.ERROR and float(values[n - 2][0]) == 0.001 + 0.002
    assert float(values[n - 1][0]) == 0.0  # fmi2Terminated: the FMU never asks to stop
