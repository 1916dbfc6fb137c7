"""The Python FMUs in a C host: one Python thread state per host thread (fmu_src/loader).

pythonfmu 0.7.0 starts Python in a thread of its own, so a C host's thread had no Python thread
state and every FMI call created one and destroyed it again (most of the C host's step time,
benchmarks/bench_fmu_hosts.py).  The loader shim now gives each calling thread one state for
good and deletes it when the thread ends.  tests/hosts/thread_host.c steps one FMU from two
threads in turn and reports the thread states it saw.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import fmpy
import pytest

from test_build import HOSTS, LIBDIR, clean_env, errors_in, host_args, run, value_of

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def thread_host(tmp_path_factory):
    """The compiled tests/hosts/thread_host.c."""
    cc = shutil.which(os.environ.get("CC", "cc"))
    if not cc:
        pytest.skip("no C compiler to build the thread host")
    exe = tmp_path_factory.mktemp("thread_host") / "thread_host"
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([cc, "-std=c99", "-o", str(exe), str(HOSTS / "thread_host.c"),
                    "-I%s" % headers, "-ldl", "-lpthread"], check=True)
    return str(exe)


def fields(output, key):
    """``{first word: second word}`` of the lines starting with ``key``."""
    return {line.split()[1]: line.split()[2] for line in output.splitlines()
            if line.startswith(key + " ")}


@pytest.mark.parametrize("name", ["Excitation", "DriftEstimator"])
def test_each_host_thread_keeps_one_python_thread_state(python_fmus, thread_host, name,
                                                         tmp_path):
    args = host_args(python_fmus[name], tmp_path)
    code, output = run([thread_host, *args], clean_env(LD_LIBRARY_PATH=LIBDIR))
    assert code == 0 and not errors_in(output), output
    # the same thread state after every call of a thread, not a new one per call (nor none)
    assert fields(output, "STATE") == {"A": "1", "B": "1"}, output
    # a thread's state is deleted when the thread ends: none is left behind
    threads = fields(output, "THREADS")
    assert threads["after-A"] == threads["before"] == threads["after-B"], output
    # and the results are those of a Python host, bit for bit
    code, reference = run([sys.executable, str(HOSTS / "ctypes_host.py"), *args], clean_env())
    assert code == 0 and not errors_in(reference), reference
    assert value_of(output) == value_of(reference)


@pytest.mark.parametrize("numpy_there", [False, True], ids=["without-numpy", "with-numpy"])
@pytest.mark.parametrize("name", ["Excitation", "Accelerometer"])
def test_a_c_hosts_python_gives_the_bits_of_a_python_host(python_fmus, thread_host, name,
                                                          numpy_there, tmp_path):
    """In a C host the FMUs compute their draws sample by sample for the first
    slave_base.Blocks.WARM_UP samples (no NumPy import for a short run), then in blocks of
    samples, or all sample by sample where the host's Python has no NumPy: the bits of a
    Python host (blocks from the start) either way."""
    from driftfmu.fmu_src.slave_base import Blocks
    hidden = tmp_path / "no_numpy"
    (hidden / "numpy").mkdir(parents=True)
    tried = tmp_path / "numpy_was_tried"
    (hidden / "numpy" / "__init__.py").write_text(
        "open(%r, 'w').close()\nraise ImportError('no NumPy in this host')\n" % str(tried))
    args = host_args(python_fmus[name], tmp_path)
    args[4] = str(Blocks.WARM_UP + 2 * Blocks.SIZE + 7)  # past the warm-up, across blocks
    env = clean_env(LD_LIBRARY_PATH=LIBDIR) if numpy_there else \
        clean_env(LD_LIBRARY_PATH=LIBDIR, PYTHONPATH=str(hidden))
    code, output = run([thread_host, *args], env)
    assert code == 0 and not errors_in(output), output
    assert tried.exists() != numpy_there  # the FMU looked for NumPy and went without it
    code, reference = run([sys.executable, str(HOSTS / "ctypes_host.py"), *args], clean_env())
    assert code == 0 and not errors_in(reference), reference
    assert value_of(output) == value_of(reference)
