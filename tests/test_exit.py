"""A process that used the FMUs exits cleanly.

pythonfmu 0.7.0 releases a global shared_ptr twice at process exit (once from its static
destructor, once from a library destructor); the freed control block is then written to, and
glibc aborts the host some of the time ("corrupted double-linked list").  The loader shim
releases it once, first.  valgrind sees the invalid access every time, not some of the time.
"""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration
HOST = Path(__file__).parent / "hosts" / "one_fmu.py"


def _errors_in_fmu_code(log):
    """valgrind error blocks whose stack passes through an FMU binary."""
    blocks = re.split(r"==\d+== \n", log)
    return [b for b in blocks if re.search(r"Invalid (read|write|free)", b)
            and re.search(r"binaries/linux64/|finalizePythonInterpreter", b)]


@pytest.mark.qualification
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_no_invalid_memory_access_at_exit(built_fmus):
    r = subprocess.run(["valgrind", "--num-callers=12", sys.executable, str(HOST),
                        str(built_fmus["Excitation"])], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    bad = _errors_in_fmu_code(r.stderr)
    assert not bad, "\n".join(bad)


def test_many_instances_then_exit_with_status_0(built_fmus):
    for name, fmu in built_fmus.items():
        r = subprocess.run([sys.executable, str(HOST), str(fmu), "200"], capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 0 and "corrupted" not in r.stderr, (name, r.stderr[-2000:])
