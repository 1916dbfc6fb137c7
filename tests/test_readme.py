"""The README front page: its first 40 lines answer each kind of user, and every code block in it
is executed here or marked ``<!-- not run: reason -->`` just above it."""
import contextlib
import io
import os
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"

pytestmark = pytest.mark.skipif(not README.is_file(), reason="no README.md (installed package)")

NOT_RUN = re.compile(r"^<!-- not run: (\S.*\S) -->$")


def _blocks():
    """(language, code, line number, marker reason or None) of every fenced block."""
    lines = README.read_text(encoding="utf-8").split("\n")
    out, i = [], 0
    while i < len(lines):
        m = re.match(r"^```(\w*)\s*$", lines[i])
        if m:
            j = i + 1
            while not lines[j].startswith("```"):
                j += 1
            marker = NOT_RUN.match(lines[i - 1]) if i else None
            out.append((m.group(1), "\n".join(lines[i + 1:j]), i + 1,
                        marker.group(1) if marker else None))
            i = j
        i += 1
    return out


BLOCKS = _blocks()


def test_first_40_lines_answer_each_user():
    head = "\n".join(README.read_text(encoding="utf-8").split("\n")[:40])
    # the tool user: which command and which file
    assert "driftfmu build --native" in head
    assert "build/fmus/native/fmi2/<Model>.fmu" in head and "fmi3/<Model>.fmu" in head
    # the script user: what to import and call
    assert "import driftfmu" in head and "driftfmu.simulate(" in head
    # the researcher: the commands that reproduce the letter
    for command in ("driftfmu run gaussian", "driftfmu sweep", "driftfmu experiment adxl203"):
        assert command in head, command


def test_every_code_block_is_run_or_says_why_not():
    assert BLOCKS
    for language, code, line, reason in BLOCKS:
        assert language in ("bash", "python"), "README line %d: block language %r" % (line,
                                                                                       language)
        if reason is None:
            for command in _commands(language, code):
                assert command[0] == "driftfmu", (
                    "README line %d runs %r, which this test cannot; mark the block "
                    "<!-- not run: reason -->" % (line, " ".join(command)))


def _commands(language, code):
    if language != "bash":
        return []
    return [shlex.split(c, comments=True) for c in code.split("\n")
            if shlex.split(c, comments=True)]


@pytest.fixture(scope="module")
def workdir(python_fmus, tmp_path_factory):
    """An empty folder with build/fmus holding the session's Python FMUs."""
    d = tmp_path_factory.mktemp("readme")
    (d / "build" / "fmus").mkdir(parents=True)
    for path in python_fmus.values():
        (d / "build" / "fmus" / path.name).symlink_to(path)
    return d


RUN = [(language, code, line) for language, code, line, reason in BLOCKS if reason is None]


@pytest.mark.integration
@pytest.mark.parametrize("language, code, line", RUN, ids=["line %d" % b[2] for b in RUN])
def test_readme_block_runs(language, code, line, workdir, monkeypatch):
    monkeypatch.chdir(workdir)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    if language == "python":
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            exec(compile(code, "README.md line %d" % line, "exec"), {"__name__": "__readme__"})
        # a print whose comment shows its output prints exactly that
        shown = [m.group(1) for m in re.finditer(r"^print\(.*\)\s+# (\(.*\))$", code, re.M)]
        lines = printed.getvalue().splitlines()
        for expected in shown:
            assert expected in lines, (expected, lines)
        return
    from driftfmu.simulations.cli import main
    for command in _commands(language, code):
        assert main(command[1:]) == 0, command
        if "--out" in command:
            out = Path(command[command.index("--out") + 1])
            assert out.is_dir() and any(out.iterdir()), command
