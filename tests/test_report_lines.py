"""The ``report`` fixture's lines (~60 "BAD INPUT ... failed" lines printed past the capture read
as failures): they are listed after the session under their own heading, with their test's
name, and not in the middle of the progress dots; a quiet run (-q) leaves them out."""
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from waiting import BOUND

ROOT = Path(__file__).resolve().parent.parent


def _run(tmp_path, *options):
    for name in ("conftest.py", "leftovers.py"):  # the suite's conftest and what it imports
        (tmp_path / name).write_text((ROOT / "tests" / name).read_text())
    (tmp_path / "test_x.py").write_text(textwrap.dedent("""
        def test_a(report):
            report("refused, as it must be: bad -> error")

        def test_b():
            pass
    """))
    # its temporary folder (and its pytest's folders) in this test's
    r = subprocess.run([sys.executable, "-m", "pytest", *options, "-p", "no:cacheprovider",
                        "-p", "no:xdist", str(tmp_path)], capture_output=True, text=True,
                       cwd=tmp_path, timeout=BOUND, env=dict(os.environ, TMPDIR=str(tmp_path)))
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout.splitlines()


def test_report_lines_come_after_the_session_under_a_heading(tmp_path):
    lines = _run(tmp_path, "-ra")
    heading = next(i for i, line in enumerate(lines) if "what passing tests saw" in line)
    progress = next(line for line in lines if line.startswith("test_x.py "))
    assert progress.startswith("test_x.py ..")  # the progress line has no report line in it
    assert [line for line in lines[heading + 1:] if line][0] == \
        "test_x.py::test_a: refused, as it must be: bad -> error"
    assert sum("refused, as it must be" in line for line in lines) == 1


def test_a_quiet_run_prints_no_report_lines(tmp_path):
    lines = _run(tmp_path, "-q")
    assert not any("what passing tests saw" in line or "refused, as it must be" in line
                   for line in lines), lines
    assert lines[-1].startswith("2 passed")
