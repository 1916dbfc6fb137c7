"""simulations/fastcosim.py: the compiled C loop is written whole or not at all, even by a
worker stopped (SIGTERM) in the middle of writing it; a worker stopped while it makes a folder
leaves none."""
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from waiting import BOUND

ROOT = Path(__file__).resolve().parent.parent

# A process-pool worker (batch._worker_init: SIGTERM removes its registered folders, then
# os._exit) compiles the loop; SIGTERM arrives just before the library is put in its place
# (the rename into the libraries folder), after every move before it (the loop once moved it
# beside its place first).
_STOPPED_WORKER = textwrap.dedent("""
    import os, signal, sys, time
    from driftfmu.simulations import batch, fastcosim
    batch._worker_init()

    real = os.rename

    def stopped(src, dst, **kwargs):  # the rename into the libraries folder (dst_dir_fd)
        if "dst_dir_fd" not in kwargs:
            return real(src, dst, **kwargs)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(60)
    os.rename = stopped
    fastcosim.loop_library()
    sys.exit("not stopped")
""")


@pytest.mark.skipif(shutil.which(os.environ.get("CC", "cc").split()[0]) is None,
                    reason="no C compiler")
def test_a_worker_stopped_while_writing_the_loop_library_leaves_no_file(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
    p = subprocess.run([sys.executable, "-c", _STOPPED_WORKER], env=env, capture_output=True,
                       text=True, timeout=BOUND)
    assert p.returncode == 128 + signal.SIGTERM, p.stderr
    # no .part file, no work folder, no half library: the (empty) libraries folder at most
    private = "driftfmu-%d" % os.geteuid()
    assert os.listdir(tmp) == [private]
    assert os.listdir(tmp / private) == ["libraries"]
    assert os.listdir(tmp / private / "libraries") == []


# A pool worker (batch._worker_init: SIGTERM removes its registered folders, then os._exit) with
# another thread that has SIGTERM unblocked (a real worker has OpenBLAS's, started by
# _blas.set_threads) is sent SIGTERM while it makes an FMU folder, after the mkdir and before
# the folder is registered; the other thread takes it (delivered to itself before pthread_kill
# returns), and the worker goes on once it has.
_STOPPED_WHILE_MAKING = textwrap.dedent("""
    import signal, sys, threading
    from driftfmu.simulations import batch, cosim, folders
    batch._worker_init()
    go, sent = threading.Event(), threading.Event()

    def other():
        go.wait()
        signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
        sent.set()
    threading.Thread(target=other, daemon=True).start()

    def checkpoint(what):
        if what == "make lock file":  # the folder is made, not yet locked nor registered
            go.set()
            sent.wait()
    folders.checkpoint = checkpoint
    cosim.new_extract_folder(prefix="driftfmu_fast_")
    sys.exit("not stopped")
""")


def test_a_worker_stopped_while_it_makes_a_folder_leaves_no_folder(tmp_path):
    # CI: SIGTERM to an experiment's command left an empty driftfmu_fast_* folder: blocking
    # SIGTERM in the worker's thread held back neither the signal (another thread took it) nor
    # the handler, which then ran between the folder's mkdir and its registration
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp), PYTHONPATH=str(ROOT))
    p = subprocess.run([sys.executable, "-c", _STOPPED_WHILE_MAKING], env=env,
                       capture_output=True, text=True, timeout=BOUND)
    assert p.returncode == 128 + signal.SIGTERM, p.stderr
    private = tmp / ("driftfmu-%d" % os.geteuid())
    assert not private.exists() or os.listdir(private) == [], os.listdir(private)


def test_the_loop_library_is_compiled_once_into_the_private_libraries_folder(tmp_path,
                                                                           monkeypatch):
    import hashlib
    from driftfmu.simulations import fastcosim, folders
    monkeypatch.setattr(fastcosim, "_LOOP_LIBRARY", [])
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    if fastcosim.loop_library() is None:
        pytest.skip("no C compiler")
    # named by the hash of its source, flags and compiler (tests/test_evidence_caches.py) and
    # by the SHA-256 of its bytes
    libraries = tmp_path / ("driftfmu-%d" % os.geteuid()) / "libraries"
    library, = libraries.iterdir()
    digest = hashlib.sha256(library.read_bytes()).hexdigest()
    assert library.name == "%s-%s.so" % (fastcosim.loop_target(), digest)
    assert fastcosim.loop_target().startswith("loop-")
    assert [p.name for p in tmp_path.iterdir()] == [libraries.parent.name]
    assert (libraries.stat().st_mode & 0o777, library.stat().st_mode & 0o777) == (0o700, 0o700)
    assert folders.sweep(folders.TEMPORARY, again=True) == [] and library.exists()


def _unpack_in_worker(path):
    from driftfmu.simulations import fastcosim
    return fastcosim.unpacked(path)[0]


@pytest.mark.integration
def test_a_worker_process_removes_the_fmus_it_unpacked_when_it_ends(native_fmus, tmp_path,
                                                                     monkeypatch):
    """A pool worker ends through multiprocessing's os._exit, which runs no atexit handler:
    the folders ``unpacked`` made there went with no one (every ``experiment adxl203`` left
    its workers' FMUs in the temporary directory).  Both start methods of the pool (a fork
    server started earlier keeps its temporary directory: the folders are checked by name)."""
    import multiprocessing.util
    from driftfmu.simulations import batch, fastcosim
    # multiprocessing's own folder (the fork server's socket) in the temporary directory, before
    # it is tmp_path: a socket's path has at most 107 bytes, and tmp_path under a TMPDIR of a
    # few more letters than /tmp is too long for it ("AF_UNIX path too long")
    multiprocessing.util.get_temp_dir()
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    # what this process unpacked before (another test in this pytest worker) is not the pool
    # workers' to remove: they would take it from the fork instead of unpacking their own
    monkeypatch.setattr(fastcosim, "_UNPACKED", {})
    fmu = str(native_fmus[2]["Accelerometer"])
    for threads in (False, True):  # fork (one thread), forkserver (another thread runs)
        if threads:
            import threading
            stop = threading.Event()
            other = threading.Thread(target=stop.wait)
            other.start()
        try:
            with batch.process_pool(2) as pool:
                folders = list(pool.map(_unpack_in_worker, [fmu] * 4))
                assert all(os.path.isdir(f) for f in folders), (threads, folders)
        finally:
            if threads:
                stop.set()
                other.join()
        assert folders and not any(os.path.exists(f) for f in folders), folders
        assert not list(tmp_path.glob("**/driftfmu_fast_*"))  # nor in the private folder
