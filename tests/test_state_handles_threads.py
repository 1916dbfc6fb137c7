"""Locks of the FMUs' C code under threads, each released together by a barrier in a fresh host
process (tests/hosts/state_host.c, a C host: no Python of its own, no GIL between the threads).

The native FMUs' live states (fmu_src/native/cosimulation.c): every state of the library is in
one list behind a spin lock, and each handle is a serial number issued under it.

A C host (tests/hosts/state_host.c, no Python in the process) gives each of four threads an
instance of its own; released together by a barrier, each gets, sets and frees its instance's
state many times.  With the lock, every call succeeds and every handle is issued once; without
it the list and the serial numbers race: a state is lost from the list (its set or free is
refused), a handle is issued twice, or the process crashes.

The Python FMUs' loader shim (fmu_src/loader/fmi2_shim.c) loads libpython and pythonfmu's
library once under a lock, keeps freed instances in a pool under another (every thread here
instantiates under the same name and resources, so the threads share the pool), and links a
resources folder whose name pythonfmu cannot read ("%20") under a third.
"""
import os
import shutil
import subprocess
from pathlib import Path

import fmpy
import pytest

from test_build import LIBDIR, clean_env
from waiting import BOUND

pytestmark = pytest.mark.integration

HOSTS = Path(__file__).parent / "hosts"


@pytest.fixture(scope="module")
def state_host(tmp_path_factory):
    cc = shutil.which(os.environ.get("CC", "cc"))
    if not cc:
        pytest.skip("no C compiler to build the state host")
    exe = tmp_path_factory.mktemp("state_host") / "state_host"
    subprocess.run([cc, "-std=c99", "-D_POSIX_C_SOURCE=200809L", "-O1", "-o", str(exe),
                    str(HOSTS / "state_host.c"), "-I%s" % (Path(fmpy.__file__).parent /
                                                          "c-code"), "-ldl", "-lpthread"],
                   check=True)
    return str(exe)


@pytest.fixture(scope="module")
def widen(state_host):
    """tests/hosts/widen.c, compiled (an LD_PRELOAD library)."""
    cc = shutil.which(os.environ.get("CC", "cc"))
    out = Path(state_host).parent / "widen.so"
    subprocess.run([cc, "-shared", "-fPIC", "-O1", "-o", str(out), str(HOSTS / "widen.c"),
                    "-ldl"], check=True)
    return str(out)


@pytest.mark.parametrize("name", ["DriftEstimator", "Excitation"])
def test_states_got_set_and_freed_in_threads_at_once(native_fmus, state_host, tmp_path, name):
    threads, rounds = 4, 20000
    fmu = native_fmus[2][name]
    unzipped = tmp_path / name
    fmpy.extract(str(fmu), unzipdir=str(unzipped))
    md = fmpy.read_model_description(str(unzipped), validate=False)
    p = subprocess.run([state_host, str(unzipped), md.coSimulation.modelIdentifier, md.guid,
                        str(threads), str(rounds)], capture_output=True, text=True,
                       timeout=BOUND)
    assert p.returncode == 0, (p.returncode, p.stdout[-2000:], p.stderr[-2000:])
    lines = dict(line.split(" ", 1) for line in p.stdout.splitlines()
                 if line.startswith(("FAILED ", "HANDLES ")))
    assert lines["FAILED"] == "0", p.stdout[-2000:]
    # every handle issued once (a handle is a serial number, never reused)
    assert lines["HANDLES"] == "%d %d" % (threads * rounds, threads * rounds)


@pytest.mark.parametrize("name", ["Excitation", "DriftEstimator"])
def test_python_fmus_instantiated_and_freed_in_threads_at_once(python_fmus, state_host, widen,
                                                               tmp_path, name):
    """The first instantiation of every thread at once, the shim's locked windows held open
    (tests/hosts/widen.c): without the lock of the resources links, two threads make links of
    one name and one instantiation fails.  (Without the load lock two threads load the same
    libraries, which changes nothing visible; the pool's lock guards a window this host does
    not reach often enough to fail without it.)"""
    threads, rounds = 4, 150
    unzipped = tmp_path / "a%20b" / name  # a folder pythonfmu cannot read: the shim links it
    fmpy.extract(str(python_fmus[name]), unzipdir=str(unzipped))
    md = fmpy.read_model_description(str(unzipped), validate=False)
    p = subprocess.run([state_host, str(unzipped), md.coSimulation.modelIdentifier, md.guid,
                        str(threads), str(rounds), "instances",
                        (unzipped / "resources").as_uri()],
                       capture_output=True, text=True, timeout=BOUND,
                       env=clean_env(LD_LIBRARY_PATH=LIBDIR,
                                     LD_PRELOAD=widen))
    assert p.returncode == 0, (p.returncode, p.stdout[-2000:], p.stderr[-2000:])
    lines = dict(line.split(" ", 1) for line in p.stdout.splitlines()
                 if line.startswith(("FAILED ", "HANDLES ")))
    assert lines["FAILED"] == "0", p.stdout[-2000:]
    assert lines["HANDLES"] == "%d %d" % (threads * rounds, threads * rounds)
