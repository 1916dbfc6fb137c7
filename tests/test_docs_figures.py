"""The Results page shows the letter's figures, each made by the command the page names under
it, and tools/docs_figures.py, which makes them, runs exactly those commands."""
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
TOOL = ROOT / "tools" / "docs_figures.py"
pytestmark = pytest.mark.skipif(not TOOL.is_file(), reason="no tools/ (an installed package)")


def figures():
    spec = importlib.util.spec_from_file_location("docs_figures", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return {name: command for command, names in module.FIGURES for name in names}


def test_every_figure_of_the_results_page_is_made_by_the_command_it_names():
    made = figures()
    page = (DOCS / "results.md").read_text(encoding="utf-8")
    shown = re.findall(r"^!\[[^\]]*\]\(([\w.]+\.png)\)\n\n(.*?)(?:\n\n|\Z)", page, re.M | re.S)
    assert {name for name, _ in shown} == set(made), "the page shows %s, the tool makes %s" % (
        sorted(name for name, _ in shown), sorted(made))
    for name, caption in shown:
        assert (DOCS / name).is_file(), "docs/%s: python tools/docs_figures.py %s" % (name, name)
        assert (DOCS / name).read_bytes()[:4] == b"\x89PNG", name
        assert caption.startswith("`%s`" % made[name]), (
            "the caption under %s does not start with its command `%s`: %r"
            % (name, made[name], caption[:80]))
    # the figures of the letter, each in the table of where they are reproduced
    for name in ("drift.png", "fig1.png", "fig2.png", "fig3.png", "fig4.png", "fig5.png"):
        assert "`%s`" % name in page[page.index("### Where each figure"):], name


def test_the_tools_commands_are_commands_of_driftfmu():
    from driftfmu.simulations.cli import make_parser
    parser = make_parser()
    for command in set(figures().values()):
        words = command.split()
        assert words[0] == "driftfmu"
        parser.parse_args(words[1:] + ["--out", "x"])  # exits 2 on an unknown option
