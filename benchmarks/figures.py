"""The page of current figures: each benchmark records its rows in ``benchmarks/figures.json``,
and ``docs/performance.md`` is rendered from that file and the page's text,
``benchmarks/performance.md.in``.

A benchmark run as a script (``python benchmarks/bench_step.py ...``) replaces its own entry
(the command it was run with, the machine, the date, the load average, its rows) and renders the
page again; ``--no-record`` leaves both alone.  ``python benchmarks/run_all.py`` runs every
benchmark.  By hand:

    python benchmarks/figures.py            # render docs/performance.md from the data file
    python benchmarks/figures.py --check    # exit 1 if the page is not what the data renders

A row is one figure: what it is, its value and unit, and, when it is a ratio, the baseline it
is a ratio against (measured in the same run) and the goal the project holds it to.
"""
import datetime
import json
import os
import platform
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE / "figures.json"
TEMPLATE = HERE / "performance.md.in"
PAGE = HERE.parent / "docs" / "performance.md"
#: The marker in the page's text where a benchmark's table goes.
MARKER = re.compile(r"^<!-- figures: (bench_\w+\.py) -->$", re.M)


def cpu():
    """The CPU's model name (Linux), or what the platform says."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def machine():
    """What the figures were measured on, in one line."""
    try:
        import numpy
        numpy_version = ", NumPy %s" % numpy.__version__
    except ImportError:  # pragma: no cover
        numpy_version = ""
    return "%s, %d cores, %s, Python %s%s" % (cpu(), os.cpu_count() or 0, platform.system(),
                                             platform.python_version(), numpy_version)


def load():
    """The 1-minute load average (what else ran on the machine), or None."""
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:  # pragma: no cover
        return None


def row(figure, value, unit, baseline=None, ratio=None, goal=None, met=None):
    """One figure: ``figure`` says what was measured, ``value`` in ``unit``; a ratio row names
    its ``baseline`` (what the ratio is against, measured in the same run) and ``ratio`` (value
    over baseline, or as ``figure`` says); ``goal`` (text such as ``"<= 1.3"``) and ``met``."""
    return {"figure": figure, "value": value, "unit": unit, "baseline": baseline,
            "ratio": ratio, "goal": goal, "met": met}


def command(script, argv):
    """The command that produces a benchmark's rows, as a user types it from the project
    root."""
    argv = list(sys.argv[1:] if argv is None else argv)
    argv = [a for a in argv if a != "--no-record"]
    return " ".join(["python", "benchmarks/%s" % Path(script).name] +
                    [a if re.fullmatch(r"[\w.,/=:+-]+", a) else "'%s'" % a for a in argv])


def read(path=DATA):
    if not Path(path).is_file():
        return {"benchmarks": {}}
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def record(script, argv, rows, load_before=None, note=None, variant=None, data=DATA,
           page=PAGE):
    """Replace the entry of ``script`` (a benchmark's ``__file__``) in the data file with
    ``rows`` and render the page again.  ``argv``: the benchmark's arguments (None: this
    process's); ``note``: a sentence the table's caption adds; ``variant``: for a benchmark
    with several tables (``bench_adxl203.py`` per backend), which one this is."""
    if argv is not None and "--no-record" in argv or argv is None and "--no-record" in sys.argv:
        return
    name = Path(script).name
    if isinstance(load_before, (tuple, list)):  # os.getloadavg(): the 1-minute figure
        load_before = load_before[0]
    if load_before is not None:
        load_before = round(load_before, 2)
    figures = read(data)
    figures["benchmarks"][name if variant is None else "%s %s" % (name, variant)] = {
        "benchmark": name,
        "command": command(name, argv),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(),
        "load_average": [load_before, load()],
        "note": note,
        "rows": rows,
    }
    figures["benchmarks"] = dict(sorted(figures["benchmarks"].items()))
    text = json.dumps(figures, indent=1, ensure_ascii=False) + "\n"
    rendered = render(figures)
    Path(data).write_text(text, encoding="utf-8")
    Path(page).write_text(rendered, encoding="utf-8")
    print("recorded in %s; %s rendered" % (Path(data).name, Path(page).name))


def number(value):
    """A figure for people: 3 significant digits, thousands separated."""
    if value is None:
        return ""
    if isinstance(value, str):
        return value
    if value == 0 or not (abs(value) < 1e15):
        return "%g" % value
    if abs(value) >= 1000:
        return "{:,.0f}".format(value)
    return "%.3g" % value


def ratio_text(ratio):
    if ratio is None:
        return ""
    if 0 < ratio < 1:
        return "%s (%s× faster)" % (number(ratio), number(1.0 / ratio))
    return "%s×" % number(ratio)


def table(name, entry):
    """The Markdown of one benchmark: its caption (command, machine, date) and its table."""
    lo, hi = entry["load_average"]
    lines = ["`%s`, %s; %s; load average %s before, %s after." % (
        entry["command"], entry["date"], entry["machine"], lo, hi)]
    if entry.get("note"):
        lines[0] += " " + entry["note"]
    lines += ["", "| figure | value | ratio | against (measured in the same run) | goal |",
              "|---|---|---|---|---|"]
    for r in entry["rows"]:
        goal = (r["goal"] or "").replace("<=", "≤").replace(">=", "≥")
        if goal and r["met"] is not None:
            goal += ": %s" % ("met" if r["met"] else "**not met**")
        lines.append("| %s | %s %s | %s | %s | %s |" % (
            r["figure"], number(r["value"]), r["unit"], ratio_text(r["ratio"]),
            r["baseline"] or "", goal))
    return "\n".join(lines)


def render(figures=None, template=TEMPLATE):
    """The page: the template with each ``<!-- figures: bench_x.py -->`` marker replaced by
    that benchmark's table (or a line saying it has not been recorded)."""
    figures = read() if figures is None else figures
    text = Path(template).read_text(encoding="utf-8")

    def one(match):
        name = match.group(1)
        entries = [e for e in figures["benchmarks"].values() if e["benchmark"] == name]
        if not entries:
            return "(`%s` has no recorded figures: run `python benchmarks/%s`.)" % (name, name)
        return "\n\n".join(table(name, e) for e in entries)
    return MARKER.sub(one, text)


def main(argv=None):
    check = "--check" in (sys.argv[1:] if argv is None else argv)
    text = render()
    if check:
        if PAGE.read_text(encoding="utf-8") != text:
            sys.exit("docs/performance.md is not what benchmarks/figures.json renders: run "
                     "python benchmarks/figures.py")
        return
    PAGE.write_text(text, encoding="utf-8")
    print("rendered %s" % PAGE)


if __name__ == "__main__":
    main()
