"""The ``report`` fixture's lines (issue 19: ~60 "BAD INPUT ... failed" lines printed past the
capture read as failures): they are listed after the session under their own heading, with
their test's name, and not in the middle of the progress dots."""
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_report_lines_come_after_the_session_under_a_heading(tmp_path):
    (tmp_path / "conftest.py").write_text((ROOT / "tests" / "conftest.py").read_text())
    (tmp_path / "test_x.py").write_text(textwrap.dedent("""
        def test_a(report):
            report("refused, as it must be: bad -> error")

        def test_b():
            pass
    """))
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        "-p", "no:xdist", str(tmp_path)], capture_output=True, text=True,
                       cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    heading = next(i for i, line in enumerate(lines) if "what passing tests saw" in line)
    assert lines[0].startswith("..")  # the progress line has no report line in it
    assert lines[heading + 1] == "test_x.py::test_a: refused, as it must be: bad -> error"
    assert sum("refused, as it must be" in line for line in lines) == 1
