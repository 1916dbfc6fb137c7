"""The test run leaves nothing in the temporary folder (issue 41): every process of the run has
the run's own temporary folder as ``TMPDIR`` (tests/conftest.py), and a test that leaves a file
or folder there fails the run, naming it."""
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest

from waiting import BOUND

HERE = Path(__file__).resolve().parent

LEAVES = textwrap.dedent("""
    import os, tempfile

    def test_leaves_a_folder():
        if os.environ.get("LEAVE"):
            tempfile.mkdtemp(prefix="left-behind-")
        with tempfile.TemporaryDirectory(prefix="removed-"):
            pass
""")


@pytest.mark.parametrize("leave", [False, True])
def test_a_test_that_leaves_a_folder_in_the_temporary_folder_fails_the_run(tmp_path, leave):
    tests = tmp_path / "tests"
    tests.mkdir()
    shutil.copy(HERE / "conftest.py", tests / "conftest.py")
    (tests / "test_leaves.py").write_text(LEAVES)
    outer = tmp_path / "tmp"  # the run's TMPDIR: its own folder goes inside, and then goes
    outer.mkdir()
    env = dict(os.environ, TMPDIR=str(outer),
               PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))
    env.pop("LEAVE", None)
    env.pop("DRIFTFMU_TEST_NATIVE_CACHE", None)
    if leave:
        env["LEAVE"] = "1"
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "-o", "addopts=", "--rootdir", str(tmp_path), str(tests)],
                       env=env, capture_output=True, text=True, timeout=BOUND, cwd=tmp_path)
    assert "1 passed" in r.stdout, r.stdout + r.stderr
    if leave:
        assert r.returncode == 1, r.stdout + r.stderr
        error = r.stderr.strip().splitlines()[-1]
        assert error.startswith("ERROR: the tests left 1 file(s) or folder(s) in the "
                                "temporary folder (TMPDIR): left-behind-"), r.stderr
    else:
        assert r.returncode == 0, r.stdout + r.stderr
        assert "ERROR" not in r.stderr
    # the run's own folder is gone either way; pytest's own stay where they were
    assert [f for f in os.listdir(outer) if not f.startswith("pytest-of-")] == []


PRIVATE = textwrap.dedent("""
    import os
    from driftfmu.simulations import folders

    def test_uses_the_private_folder():
        os.close(folders.private_subfolder("locks"))  # (what a commit keeps: not left)
        if os.environ.get("LEAVE"):
            folders.make("driftfmu_left_")  # a work folder never removed
""")


@pytest.mark.skipif(not hasattr(os, "geteuid"), reason="the private folder is POSIX's")
@pytest.mark.parametrize("leave", [False, True])
def test_a_work_folder_left_in_driftfmus_private_folder_fails_the_run(tmp_path, leave):
    """driftfmu's private folder (driftfmu-<uid>) stays by design with its locks and compiled
    libraries: that alone passes; a work folder left in it fails the run, named."""
    tests = tmp_path / "tests"
    tests.mkdir()
    shutil.copy(HERE / "conftest.py", tests / "conftest.py")
    (tests / "test_private.py").write_text(PRIVATE)
    outer = tmp_path / "tmp"
    outer.mkdir()
    env = dict(os.environ, TMPDIR=str(outer),
               PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))
    env.pop("LEAVE", None)
    env.pop("DRIFTFMU_TEST_NATIVE_CACHE", None)
    if leave:
        env["LEAVE"] = "1"
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "-o", "addopts=", "--rootdir", str(tmp_path), str(tests)],
                       env=env, capture_output=True, text=True, timeout=BOUND, cwd=tmp_path)
    assert "1 passed" in r.stdout, r.stdout + r.stderr
    if leave:
        assert r.returncode == 1, r.stdout + r.stderr
        error = r.stderr.strip().splitlines()[-1]
        assert error.startswith("ERROR: the tests left 1 file(s) or folder(s) in the "
                                "temporary folder (TMPDIR): driftfmu-%d/driftfmu_left_"
                                % os.geteuid()), r.stderr
    else:
        assert r.returncode == 0 and "ERROR" not in r.stderr, r.stdout + r.stderr
    assert [f for f in os.listdir(outer) if not f.startswith("pytest-of-")] == []


def test_this_run_has_a_temporary_folder_of_its_own():
    assert os.path.basename(tempfile.gettempdir()).startswith("driftfmu-test-run-")
    assert os.environ["TMPDIR"] == tempfile.gettempdir()
