"""Mutation check: every fault on a list must make the test suite fail.

Each fault of ``tools/mutations.toml`` is one exact textual replacement in one file.  The
worktree is copied once to a temporary folder (without .git, build outputs and caches); for each
fault the replacement is applied to the copy (the pattern must occur exactly once: a pattern
that is not found, or found twice, is an error before anything runs, so the list is kept up to
date with the code), the tests are run against the copy (``PYTHONPATH`` = the copy,
``pytest -x``, a timeout per fault) and the file is restored.  The unmutated copy is run first
and must pass.  The report is a table: fault, file, the first test that failed.  Exit status 0
when every fault was caught, 1 when one survived (or timed out), 2 for a bad list or a failing
baseline.

Usage::

    python3 tools/mutate.py            # the full list (about 10 minutes on 2 cores)
    python3 tools/mutate.py --short    # the faults marked short = true (CI, about a minute)
    python3 tools/mutate.py --check    # only check that every pattern matches exactly once
    python3 tools/mutate.py --only ekf-linear-innovation sensor-H-without-2a2x
    python3 tools/mutate.py --markdown # the report as a Markdown table (for docs/evidence.md)
    python3 tools/mutate.py --ignore-glob 'tests/test_evidence_*'   # without those tests
"""
import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

try:
    import tomllib
except ImportError:  # Python < 3.11
    tomllib = None

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LIST = os.path.join(ROOT, "tools", "mutations.toml")
#: What every run selects unless a fault names its own tests: the suite without the tests that
#: build or load FMUs (those test the FMI plumbing; the slaves' step logic runs in Python).
DEFAULT_TESTS = ("tests",)
DEFAULT_MARKERS = "not integration"
#: Left out of every run: compares the C port built for Linux with the same C built for Windows
#: (under wine, minutes); no fault in the Python tree can change what it compares.
DESELECT = ("tests/test_native_models.py::test_windows_build_under_wine_prints_the_linux_bits",)
TIMEOUT = 300
IGNORE = shutil.ignore_patterns(".git", "__pycache__", ".pytest_cache", "*.pyc", "*.egg-info",
                                "results", "out", "target", "fmus", "cross-check", "tmp")


def load(path=LIST):
    """The faults of the list: dicts with id, file, find, replace, why, short, tests."""
    if tomllib is None:
        sys.exit("tools/mutate.py needs Python 3.11 (tomllib)")
    with open(path, "rb") as fh:
        faults = tomllib.load(fh).get("fault", [])
    seen = set()
    for f in faults:
        missing = [k for k in ("id", "file", "find", "replace", "why") if k not in f]
        if missing:
            sys.exit("%s: fault %r lacks %s" % (path, f.get("id"), ", ".join(missing)))
        if f["id"] in seen:
            sys.exit("%s: fault id %r appears twice" % (path, f["id"]))
        seen.add(f["id"])
        f.setdefault("short", False)
        f.setdefault("tests", list(DEFAULT_TESTS))
    return faults


def check(faults, root=ROOT):
    """Problems of the list against the tree at ``root``: each pattern must occur exactly once."""
    problems = []
    for f in faults:
        path = os.path.join(root, f["file"])
        if not os.path.isfile(path):
            problems.append("%s: file %s does not exist" % (f["id"], f["file"]))
            continue
        with open(path, encoding="utf-8") as fh:
            n = fh.read().count(f["find"])
        if n != 1:
            problems.append("%s: pattern found %d times in %s (must be exactly once): %r"
                            % (f["id"], n, f["file"], f["find"]))
        if f["find"] == f["replace"]:
            problems.append("%s: replacement equals the pattern" % f["id"])
    return problems


_FAILED = re.compile(r"^(FAILED|ERROR) (.+?)(?: - .*)?$")  # ids may hold spaces


def run_tests(copy, tests, timeout, ignore=()):
    """Run pytest on the copy; return (status, first failing test or None, seconds)."""
    # DRIFTFMU_KERNEL=numpy: the batch engine runs models/ (the faults' target) instead of the
    # compiled kernel, the C port that a fault in models/ leaves as it is
    env = dict(os.environ, PYTHONPATH=copy, PYTHONDONTWRITEBYTECODE="1", DRIFTFMU_KERNEL="numpy")
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-rfE", "-p", "no:cacheprovider",
           "-m", DEFAULT_MARKERS] + ["--deselect=" + d for d in DESELECT] + \
        ["--ignore-glob=" + g for g in ignore] + list(tests)
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=copy, env=env, capture_output=True, text=True,
                           timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", None, time.perf_counter() - t0
    seconds = time.perf_counter() - t0
    out = p.stdout + p.stderr
    first = next((m.group(2) for m in map(_FAILED.match, out.splitlines()) if m), None)
    if p.returncode == 0:
        return "passed", None, seconds
    if p.returncode == 1 and first:
        return "failed", first, seconds
    if p.returncode in (4, 5):  # usage error, no tests collected: nothing was tested
        return "not run", "pytest exit status %d" % p.returncode, seconds
    # collection errors, internal errors: the copy does not even import or run
    tail = [ln for ln in out.splitlines() if ln.strip()][-3:]
    return "error", first or " / ".join(tail)[:120], seconds


def make_copy(root=ROOT):
    tmp = tempfile.mkdtemp(prefix="driftfmu-mutate-")
    copy = os.path.join(tmp, "tree")
    shutil.copytree(root, copy, ignore=IGNORE, symlinks=True)
    return tmp, copy


def main(argv=None):
    ap = argparse.ArgumentParser(description="Apply each fault of tools/mutations.toml to a "
                                 "copy of the tree and check that the tests catch it.")
    ap.add_argument("--list", default=LIST, help="fault list (TOML; default: %(default)s)")
    ap.add_argument("--short", action="store_true", help="only the faults marked short")
    ap.add_argument("--only", nargs="+", metavar="ID", help="only these faults")
    ap.add_argument("--check", action="store_true", help="only check the patterns")
    ap.add_argument("--timeout", type=float, default=TIMEOUT,
                    help="seconds per fault (default: %(default)s)")
    ap.add_argument("--markdown", action="store_true", help="print the report as Markdown")
    ap.add_argument("--ignore-glob", action="append", default=[], metavar="GLOB",
                    help="run every fault on the default selection without the test files "
                    "matching GLOB (e.g. 'tests/test_evidence_*': which faults only those "
                    "catch); may be repeated")
    args = ap.parse_args(argv)

    faults = load(args.list)
    problems = check(faults)  # the whole list, always: a stale pattern fails even --short
    if problems:
        for p in problems:
            print("mutate: " + p, file=sys.stderr)
        return 2
    if args.only:
        unknown = set(args.only) - {f["id"] for f in faults}
        if unknown:
            print("mutate: unknown fault id(s) %s" % ", ".join(sorted(unknown)), file=sys.stderr)
            return 2
        faults = [f for f in faults if f["id"] in args.only]
    elif args.short:
        faults = [f for f in faults if f["short"]]
    if args.ignore_glob:
        faults = [dict(f, tests=list(DEFAULT_TESTS)) for f in faults]
    if args.check:
        print("mutate: all %d patterns match exactly once" % len(load(args.list)))
        return 0

    # SIGTERM as an exception, so the running pytest is killed and the copy removed
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    tmp, copy = make_copy()
    try:
        where = subprocess.run([sys.executable, "-c", "import driftfmu.models as m, "
                                "driftfmu.fmu_src.slave_base as s; print(m.__file__); "
                                "print(s.__file__)"], cwd=copy, capture_output=True, text=True,
                               env=dict(os.environ, PYTHONPATH=copy))
        paths = where.stdout.split()
        if where.returncode or len(paths) != 2 or not all(p.startswith(copy) for p in paths):
            print("mutate: the copy does not import its own code (%s)"
                  % (where.stdout + where.stderr).strip(), file=sys.stderr)
            return 2
        selections = sorted({tuple(f["tests"]) for f in faults})
        for tests in selections:
            status, first, seconds = run_tests(copy, tests, args.timeout, args.ignore_glob)
            if status != "passed":
                print("mutate: the unmutated copy does not pass %s (%s: %s)"
                      % (" ".join(tests), status, first), file=sys.stderr)
                return 2
            print("baseline %s: passed in %.0f s" % (" ".join(tests), seconds), flush=True)
        rows = []
        for f in faults:
            path = os.path.join(copy, f["file"])
            with open(path, encoding="utf-8") as fh:
                original = fh.read()
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(original.replace(f["find"], f["replace"], 1))
            try:
                status, first, seconds = run_tests(copy, f["tests"], args.timeout,
                                                   args.ignore_glob)
            finally:
                with open(path, "w", encoding="utf-8") as fh:
                    fh.write(original)
            caught = status in ("failed", "error")
            rows.append((f, caught, status, first, seconds))
            print("%-34s %-8s %5.0f s  %s" % (f["id"], "caught" if caught else status.upper(),
                                             seconds, first or ""), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    survived = [r for r in rows if not r[1]]
    print()
    if args.markdown:
        print("| fault | file | what it does | caught by (first failing test) |")
        print("|---|---|---|---|")
        for f, caught, status, first, _ in rows:
            print("| `%s` | `%s` | %s | %s |" % (f["id"], f["file"], f["why"],
                                               "`%s`" % first if caught else
                                               "**%s**" % status.upper()))
    else:
        width = max(len(r[0]["id"]) for r in rows)
        for f, caught, status, first, _ in rows:
            print("%-*s  %-28s  %s" % (width, f["id"], f["file"],
                                       first if caught else status.upper()))
    print("\n%d of %d faults caught%s" % (len(rows) - len(survived), len(rows),
                                          "" if not survived else "; SURVIVED: " +
                                          ", ".join(r[0]["id"] for r in survived)))
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
