"""Mutation check: every fault on a list must make the test suite fail.

Each fault of ``tools/mutations.toml`` is one exact textual replacement in one file.  The
worktree is copied once to a temporary folder (without .git, build outputs and caches); for each
fault the replacement is applied to the copy (the pattern must occur exactly once: a pattern
that is not found, or found twice, is an error before anything runs, so the list is kept up to
date with the code), the tests are run against the copy (``PYTHONPATH`` = the copy,
``pytest -x``, a timeout per fault) and the file is restored.  A fault may carry ``also``: more
replacements in other files, applied with it (the same fault in both twins, the Python model and
its native C port, so that the tests comparing the twins bit for bit cannot see it).  The
unmutated copy is run first and must pass.

A fault counts as caught only by independent evidence: every run leaves out the tests that
compare the native C twins with models/ bit for bit (:data:`TWIN_TESTS`), which see any fault
applied to one twin alone whether or not the science is guarded.  A fault whose change no
independent test can see (a sub-ulp change of a kernel, visible only in the bits) says so with
``twin_evidence = true`` and keeps those tests; the report marks it.  A fault that only a
master's run of real FMUs can show names those tests and sets ``integration = true``: its run
keeps the tests marked ``integration`` of its selection, which every other run leaves out.

The report is a table: fault, file, the first test that failed.  Exit status 0 when every
fault was caught, 1 when one survived (or timed out), 2 for a bad list or a failing
baseline, 130 when stopped by SIGINT or SIGTERM.

Time: the unmutated run of each test selection is timed (bounded only by ``--baseline-timeout``,
default an hour), and a fault's run may take :data:`TIMEOUT_FACTOR` times its selection's
baseline, at least :data:`TIMEOUT_FLOOR` seconds, so a loaded machine stretches the bound with
the work; ``--timeout`` sets a fixed bound instead.  Each pytest runs in a session (process
group) of its own, with its pytest-xdist workers and whatever they start: a run that times out,
and every run when mutate.py is stopped (SIGINT, SIGTERM), is ended by killing its whole group,
so no worker is left running.

Usage::

    python3 tools/mutate.py            # the full list (about 10 minutes on 2 cores)
    python3 tools/mutate.py --short    # the faults marked short = true (CI, about a minute)
    python3 tools/mutate.py --check    # only check that every pattern matches exactly once
    python3 tools/mutate.py --only ekf-linear-innovation sensor-H-without-2a2x
    python3 tools/mutate.py --markdown # the report as a Markdown table (for docs/evidence.md)
    python3 tools/mutate.py --ignore-glob 'tests/test_evidence_*'   # without those tests
    python3 tools/mutate.py --timeout 900   # a fixed bound per fault instead of 3 x baseline
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
#: build or load FMUs (those test the FMI plumbing; the slaves' step logic runs in Python); the
#: qualification tier (tests/conftest.py) is left out as in every run without --qualification.
DEFAULT_TESTS = ("tests",)
DEFAULT_MARKERS = "not integration"
#: Left out of every run: compares the C port built for Linux with the same C built for Windows
#: (under wine, minutes); no fault in the Python tree can change what it compares.
#: Also: a wall-clock bound on connecting to a Dask scheduler, which a loaded machine's slow
#: import of dask can exceed, and which no fault on the list can change.
DESELECT = ("tests/test_native_models.py::test_windows_build_under_wine_prints_the_linux_bits",
            "tests/test_batch.py::test_unreachable_scheduler_fails_fast_and_clearly")
#: Left out of every run unless a fault sets ``twin_evidence``: the C twins against models/ bit
#: for bit.  They catch a fault applied to the Python twin alone by plumbing, not by evidence.
TWIN_TESTS = ("tests/test_native_models.py",)
#: Left out of every run: the mutation check's own tests (they run mutate.py on a tree of their
#: own; no fault on the list is in tools/).
SELF_TESTS = ("tests/test_mutate.py",)
#: A fault's run may take this many times the unmutated run of its tests ...
TIMEOUT_FACTOR = 3.0
#: ... and at least this many seconds (a fault may slow the tests without failing them).
TIMEOUT_FLOOR = 120.0
#: The unmutated runs' bound (seconds): they are the measure, and may be slow on a loaded machine.
BASELINE_TIMEOUT = 3600.0
#: Seconds a killed run's group gets between SIGTERM and SIGKILL.
GRACE = 5.0
IGNORE = shutil.ignore_patterns(".git", "__pycache__", ".pytest_cache", "*.pyc", "*.egg-info",
                                "results", "out", "target", "fmus", "cross-check", "tmp",
                                ".venv", ".hypothesis")


def edits(fault):
    """The replacements of a fault: ``(file, find, replace)``, its own first, then ``also``."""
    return [(fault["file"], fault["find"], fault["replace"])] + \
        [(a["file"], a["find"], a["replace"]) for a in fault.get("also", [])]


def load(path=LIST):
    """The faults of the list: dicts with id, file, find, replace, why, short, tests, also,
    twin_evidence."""
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
        for a in f.get("also", []):
            lacking = [k for k in ("file", "find", "replace") if k not in a]
            if lacking:
                sys.exit("%s: fault %r: an 'also' entry lacks %s"
                         % (path, f["id"], ", ".join(lacking)))
        f.setdefault("short", False)
        f.setdefault("tests", list(DEFAULT_TESTS))
        f.setdefault("also", [])
        f.setdefault("twin_evidence", False)
        f.setdefault("integration", False)
        if f["integration"] and f["tests"] == list(DEFAULT_TESTS):
            sys.exit("%s: fault %r runs integration tests: name them (tests)" % (path, f["id"]))
    return faults


def check(faults, root=ROOT):
    """Problems of the list against the tree at ``root``: each pattern must occur exactly once."""
    problems = []
    for f in faults:
        for name, find, replace in edits(f):
            path = os.path.join(root, name)
            if not os.path.isfile(path):
                problems.append("%s: file %s does not exist" % (f["id"], name))
                continue
            with open(path, encoding="utf-8") as fh:
                n = fh.read().count(find)
            if n != 1:
                problems.append("%s: pattern found %d times in %s (must be exactly once): %r"
                                % (f["id"], n, name, find))
            if find == replace:
                problems.append("%s: replacement equals the pattern" % f["id"])
        if len({name for name, _, _ in edits(f)}) != len(edits(f)):
            problems.append("%s: two replacements in one file (make them one)" % f["id"])
    return problems


def fault_timeout(baseline_seconds, fixed=None):
    """Seconds a fault's run may take: ``fixed`` (``--timeout``) when given, else
    :data:`TIMEOUT_FACTOR` times the unmutated run of the same tests, at least
    :data:`TIMEOUT_FLOOR`."""
    if fixed is not None:
        return fixed
    return max(TIMEOUT_FLOOR, TIMEOUT_FACTOR * baseline_seconds)


def kill_group(p, grace=GRACE):
    """End ``p`` (started with ``start_new_session=True``) and everything in its process group:
    SIGTERM, then SIGKILL after ``grace`` seconds for what is still there."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(p.pid, sig)
        except ProcessLookupError:  # the group is gone
            return
        deadline = time.monotonic() + grace
        while time.monotonic() < deadline:
            p.poll()  # reap the leader: a zombie still counts as a member of its group
            try:
                os.killpg(p.pid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.05)


#: How tests/conftest.py starts the line that fails a run whose tests all passed but left
#: files in its temporary folder.
LEFT_BEHIND = "ERROR: the tests left "


def only_left_files(returncode, out):
    """True when a run whose tests all passed failed only for the files it left in its
    temporary folder (tests/conftest.py): no test fails, so nothing is caught by it."""
    return returncode == 1 and any(ln.startswith(LEFT_BEHIND) for ln in out.splitlines())


_FAILED = re.compile(r"^(FAILED|ERROR) (.+?)(?: - .*)?$")  # ids may hold spaces


def pytest_args(tests, ignore=(), twins=False, integration=False):
    """pytest's arguments for a run of ``tests`` on the copy: stop at the first failure, the
    everyday loop's markers (with ``integration``: its integration tests too), without this
    tool's own tests, ``ignore`` and, unless ``twins``, :data:`TWIN_TESTS`."""
    ignore = tuple(ignore) + SELF_TESTS + (() if twins else TWIN_TESTS)
    markers = [] if integration else ["-m", DEFAULT_MARKERS]
    return ["-x", "-q", "-rfE", "-p", "no:cacheprovider"] + markers + \
        ["--deselect=" + d for d in DESELECT] + ["--ignore-glob=" + g for g in ignore] + \
        list(tests)


def run_tests(copy, tests, timeout, ignore=(), twins=False, integration=False):
    """Run pytest on the copy, without :data:`TWIN_TESTS` unless ``twins``, without the
    integration tests unless ``integration``; return (status, first failing test or None,
    seconds)."""
    # DRIFTFMU_KERNEL=numpy: the batch engine runs models/ (the faults' target) instead of the
    # compiled kernel, the C port that a fault in models/ leaves as it is
    env = dict(os.environ, PYTHONPATH=copy, PYTHONDONTWRITEBYTECODE="1", DRIFTFMU_KERNEL="numpy")
    cmd = [sys.executable, "-m", "pytest"] + pytest_args(tests, ignore, twins, integration)
    t0 = time.perf_counter()
    # its own session: the timeout, SIGINT and SIGTERM end pytest and its xdist workers alike
    p = subprocess.Popen(cmd, cwd=copy, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        out, _ = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        kill_group(p)
        p.communicate()
        return "timeout", None, time.perf_counter() - t0
    except BaseException:  # SIGINT, SIGTERM (SystemExit), anything: leave nothing running
        kill_group(p)
        p.communicate()
        raise
    seconds = time.perf_counter() - t0
    kill_group(p, grace=1.0)  # what a passed or failed run left behind in its group
    first = next((m.group(2) for m in map(_FAILED.match, out.splitlines()) if m), None)
    if p.returncode == 0:
        return "passed", None, seconds
    if p.returncode == 1 and first:
        return "failed", first, seconds
    if only_left_files(p.returncode, out):  # every test passed: the fault is not caught
        return "passed", None, seconds
    if p.returncode in (4, 5):  # usage error, no tests collected: nothing was tested
        return "not run", "pytest exit status %d" % p.returncode, seconds
    # collection errors, internal errors: the copy does not even import or run
    tail = [ln for ln in out.splitlines() if ln.strip()][-3:]
    return "error", first or " / ".join(tail)[:120], seconds


def make_copy(root=ROOT):
    """Copy the tree at ``root`` (without .git, build outputs, caches) to a temporary folder;
    return (that folder, the copy)."""
    tmp = tempfile.mkdtemp(prefix="driftfmu-mutate-")
    copy = os.path.join(tmp, "tree")
    shutil.copytree(root, copy, ignore=IGNORE, symlinks=True)
    return tmp, copy


def main(argv=None):
    ap = argparse.ArgumentParser(description="Apply each fault of tools/mutations.toml to a "
                                 "copy of the tree and check that the tests catch it.")
    ap.add_argument("--list", default=None,
                    help="fault list (TOML; default: tools/mutations.toml of --root)")
    ap.add_argument("--root", default=ROOT,
                    help="the tree to copy and mutate (default: this checkout, %(default)s)")
    ap.add_argument("--short", action="store_true", help="only the faults marked short")
    ap.add_argument("--only", nargs="+", metavar="ID", help="only these faults")
    ap.add_argument("--check", action="store_true", help="only check the patterns")
    ap.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                    help="a fixed bound per fault (default: %g times the unmutated run of the "
                    "same tests, at least %g s)" % (TIMEOUT_FACTOR, TIMEOUT_FLOOR))
    ap.add_argument("--baseline-timeout", type=float, default=BASELINE_TIMEOUT,
                    metavar="SECONDS", help="bound of each unmutated run (default: %(default)g)")
    ap.add_argument("--markdown", action="store_true", help="print the report as Markdown")
    ap.add_argument("--ignore-glob", action="append", default=[], metavar="GLOB",
                    help="run every fault on the default selection without the test files "
                    "matching GLOB (e.g. 'tests/test_evidence_*': which faults only those "
                    "catch); may be repeated")
    args = ap.parse_args(argv)
    for name in ("timeout", "baseline_timeout"):
        value = getattr(args, name)
        if value is not None and not value > 0:
            ap.error("--%s %r: allowed: seconds > 0" % (name.replace("_", "-"), value))
    root = os.path.abspath(args.root)
    args.list = args.list or os.path.join(root, "tools", "mutations.toml")

    faults = load(args.list)
    problems = check(faults, root)  # the whole list, always: a stale pattern fails even --short
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
        faults = [dict(f, tests=list(DEFAULT_TESTS), integration=False) for f in faults]
    if args.check:
        print("mutate: all %d patterns match exactly once" % len(load(args.list)))
        return 0

    return stoppable("mutate", _run, args, faults, root)


def stoppable(name, run, *args):
    """``run(*args)`` with SIGINT and SIGTERM (a background job ignores SIGINT) as exceptions,
    so that the running pytest's group is killed (:func:`run_tests`) and the copy removed; a
    second signal while that happens is ignored.  130 when stopped."""
    def stop(signum, frame):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise KeyboardInterrupt
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    try:
        return run(*args)
    except KeyboardInterrupt:
        print("%s: stopped; the running tests were killed, the copy removed" % name,
              file=sys.stderr)
        return 130


def _run(args, faults, root):
    """Baselines, then every fault; the report.  ``main`` handles the signals."""
    tmp, copy = make_copy(root)
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
        selections = sorted({(tuple(f["tests"]), f["twin_evidence"], f["integration"])
                             for f in faults})
        timeouts = {}
        for tests, twins, integration in selections:
            status, first, seconds = run_tests(copy, tests, args.baseline_timeout,
                                               args.ignore_glob, twins, integration)
            if status != "passed":
                print("mutate: the unmutated copy does not pass %s (%s: %s)"
                      % (" ".join(tests), status,
                         first or "over --baseline-timeout %g s" % args.baseline_timeout),
                      file=sys.stderr)
                return 2
            timeouts[tests, twins, integration] = fault_timeout(seconds, args.timeout)
            print("baseline %s: passed in %.0f s; a fault may take %.0f s" % (
                " ".join(tests), seconds, timeouts[tests, twins, integration]), flush=True)
        rows = []
        for f in faults:
            originals = {}
            try:
                for name, find, replace in edits(f):
                    path = os.path.join(copy, name)
                    with open(path, encoding="utf-8") as fh:
                        originals[path] = fh.read()
                    with open(path, "w", encoding="utf-8") as fh:
                        fh.write(originals[path].replace(find, replace, 1))
                status, first, seconds = run_tests(
                    copy, f["tests"],
                    timeouts[tuple(f["tests"]), f["twin_evidence"], f["integration"]],
                    args.ignore_glob, f["twin_evidence"], f["integration"])
            finally:
                for path, original in originals.items():
                    with open(path, "w", encoding="utf-8") as fh:
                        fh.write(original)
            caught = status in ("failed", "error")
            rows.append((f, caught, status, first, seconds))
            print("%-34s %-8s %5.0f s  %s%s" % (f["id"], "caught" if caught else status.upper(),
                                               seconds, first or "",
                                               " (twin bits)" if f["twin_evidence"] else ""),
                  flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    survived = [r for r in rows if not r[1]]
    print()
    if args.markdown:
        print("| fault | file | what it does | caught by (first failing test) |")
        print("|---|---|---|---|")
        for f, caught, status, first, _ in rows:
            print("| `%s` | `%s` | %s | %s |" % (
                f["id"], "`, `".join(name for name, _, _ in edits(f)), f["why"],
                ("`%s`" % first + (" (twin bits)" if f["twin_evidence"] else ""))
                if caught else "**%s**" % status.upper()))
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
