"""docs/performance.md is what the benchmarks recorded: every row names a benchmark that exists,
every benchmark has its table, and the page is what benchmarks/figures.py renders from
benchmarks/figures.json and the page's text."""
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS = ROOT / "benchmarks"
pytestmark = pytest.mark.skipif(not (BENCHMARKS / "figures.py").is_file(),
                                reason="no benchmarks/ (an installed package)")


@pytest.fixture(scope="module")
def figures():
    spec = importlib.util.spec_from_file_location("bench_figures", BENCHMARKS / "figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def scripts():
    return sorted(p.name for p in BENCHMARKS.glob("bench_*.py"))


def test_every_recorded_table_names_a_benchmark_that_exists(figures):
    data = figures.read()
    assert data["benchmarks"], "benchmarks/figures.json records nothing"
    for key, entry in data["benchmarks"].items():
        name = entry["benchmark"]
        assert (BENCHMARKS / name).is_file(), "%s: no benchmarks/%s" % (key, name)
        assert entry["command"].startswith("python benchmarks/%s" % name), entry["command"]
        for field in ("date", "machine", "load_average", "rows"):
            assert entry[field], (key, field)
        for row in entry["rows"]:
            assert row["figure"] and isinstance(row["value"], (int, float)), (key, row)
            assert (row["ratio"] is None) == (row["baseline"] is None) or \
                row["unit"] == "×", ("a ratio names what it is against", key, row)


def test_every_benchmark_records_its_table_and_the_page_shows_it(figures):
    data = figures.read()
    recorded = {e["benchmark"] for e in data["benchmarks"].values()}
    markers = figures.MARKER.findall(figures.TEMPLATE.read_text(encoding="utf-8"))
    for name in scripts():
        source = (BENCHMARKS / name).read_text(encoding="utf-8")
        assert "figures.record(" in source, "%s does not record its figures" % name
        assert name in recorded, "%s has no rows in benchmarks/figures.json" % name
        assert name in markers, "the page's text has no table of %s" % name
    assert sorted(set(markers)) == sorted(markers), "a table twice"
    assert set(markers) <= set(scripts())


def test_the_page_is_what_the_data_renders(figures):
    page = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    assert page == figures.render(), (
        "docs/performance.md is stale: python benchmarks/figures.py renders it")
    # no table a benchmark did not write: every table row's figure is a recorded one
    rows = {r["figure"] for e in figures.read()["benchmarks"].values() for r in e["rows"]}
    goals = _goal_rows(page)
    for cell in re.findall(r"^\| (?!figure \|)(?!---)(.+?) \| ", page, re.M):
        assert cell in rows or cell in goals, "a row no benchmark recorded: %s" % cell


def _goal_rows(page):
    """The first cells of the goals table (text of the page, not figures)."""
    goals = page[page.index("## The goals"):page.index("## The FMUs' step")]
    return set(re.findall(r"^\| (.+?) \| ", goals, re.M))


def test_a_row_is_rendered_with_its_command_machine_date_and_baseline(figures, tmp_path):
    entry = {"benchmark": "bench_step.py", "command": "python benchmarks/bench_step.py",
             "date": "2030-01-02 03:04 UTC", "machine": "a machine", "load_average": [0.5, 0.7],
             "note": None,
             "rows": [figures.row("a step", 12.34, "µs", "the floor", 1.25, "<= 1.3", True)]}
    template = tmp_path / "page.md.in"
    template.write_text("# P\n\n<!-- figures: bench_step.py -->\n\n<!-- figures: bench_x.py -->\n")
    text = figures.render({"benchmarks": {"bench_step.py": entry}}, template)
    assert "`python benchmarks/bench_step.py`, 2030-01-02 03:04 UTC; a machine; load average " \
           "0.5 before, 0.7 after." in text
    assert "| a step | 12.3 µs | 1.25× | the floor | ≤ 1.3: met |" in text
    assert "(`bench_x.py` has no recorded figures: run `python benchmarks/bench_x.py`.)" in text
