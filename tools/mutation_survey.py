"""Mechanical mutation survey: generated faults in the general sensor's math and references.

``tools/mutate.py`` runs faults written by hand; this generates them, the way a mutation tool
does, in the functions listed in :data:`TARGETS` (models/ and the references and statistics of
simulations/ that the letter's general sensor goes through), with the operators of
:func:`mutants`:

- ``constant``: a numeric constant ``c`` becomes ``2 c`` (``1`` if ``c = 0``): a wrong
  coefficient or exponent;
- ``sign``: ``+`` and ``-`` swapped;
- ``drop``: a term of a sum or difference dropped (``a + b`` becomes ``b``, then ``a``;
  ``a - b`` becomes ``a``);
- ``compare``: ``==`` becomes ``!=``, ``!=`` becomes ``>`` (a test for "not zero" that takes
  only the positive values), ``<`` becomes ``<=``, ``>`` becomes ``>=`` (and back);
- ``swap``: two neighbouring positional arguments of a call swapped;
- ``default``: a keyword argument of a call left out (the callee's default taken instead);
- ``last``: the last positional argument of a call left out, where that still calls.

Each mutant is the source of one node replaced by its mutated form (``ast.unparse``) in a copy of
the tree; mutants that unparse to the same text are left out.  The tests run against the copy
(``pytest -x -n 0 -m "not integration"`` on :data:`TESTS`, then for a mutant that passes them
on :data:`THEN`; without the C twins' bit-for-bit comparisons, and on the batch engine's NumPy
path, as ``tools/mutate.py``), one mutant after another; the report lists every mutant, caught
or not (and by which test), and the survivors.

Usage::

    python3 tools/mutation_survey.py --list             # the mutants, without running them
    python3 tools/mutation_survey.py --out survey.json  # run them all (CPU-heavy: background)
    python3 tools/mutation_survey.py --only 12 40 41    # some, by number
    python3 tools/mutation_survey.py --function models/drift.py:update
"""
import argparse
import ast
import json
import os
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import mutate  # noqa: E402  (the copy, the process groups, the twin tests left out)

ROOT = mutate.ROOT

#: The functions mutated: (file, dotted name) -- the general sensor's math in models/ and the
#: references and statistics of simulations/ that report it.
TARGETS = (
    ("models/excitation.py", "gauss_markov"),
    ("models/excitation.py", "input_sample"),
    ("models/excitation.py", "state_moments"),
    ("models/sensor.py", "higher"),
    ("models/sensor.py", "h"),
    ("models/sensor.py", "dh_dx"),
    ("models/sensor.py", "drift"),
    ("models/ekf.py", "predict"),
    ("models/drift.py", "posterior_moments"),
    ("models/drift.py", "update"),
    ("models/drift.py", "estimates"),
    ("models/drift.py", "references"),
    ("models/chain.py", "expected_drift"),
    ("models/harmonic.py", "estimator_step"),
    ("models/harmonic.py", "estimator_predict"),
    ("models/adxl203.py", "sensitivity"),
    ("models/adxl203.py", "config"),
    ("models/adxl203.py", "sense"),
    ("models/identify.py", "_coefficient_map"),
    ("models/identify.py", "standard_errors"),
    ("simulations/batch.py", "_realised"),
    ("simulations/sweep.py", "references"),
    ("simulations/sinusoidal.py", "expected_drift"),
    ("simulations/adxl203.py", "margin"),
)

#: The tests every mutant runs against first: the general sensor's evidence (fast) ...
TESTS = ("tests/test_evidence_general_references.py", "tests/test_evidence_general_filter.py",
         "tests/test_evidence_general_steps.py", "tests/test_evidence_general_experiments.py",
         "tests/test_evidence_caches.py")
#: ... and what a mutant that passes them runs against then: the earlier tests of the general
#: sensor and the evidence of the letter's special case.
THEN = ("tests/test_identify_order.py", "tests/test_general_sensor.py", "tests/test_harmonic.py",
        "tests/test_models.py", "tests/test_evidence_ekf.py", "tests/test_input_wiring.py",
        "tests/test_adxl203.py", "tests/test_adxl203_order.py", "tests/test_evidence_references.py",
        "tests/test_evidence_identify.py", "tests/test_montecarlo_general.py",
        "tests/test_sweep_a4.py", "tests/test_evidence_statistics.py")

_SWAP = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
         ast.Pow: ast.Mult}
_COMPARE = {ast.Eq: ast.NotEq, ast.NotEq: ast.Gt, ast.Lt: ast.LtE, ast.LtE: ast.Lt,
            ast.Gt: ast.GtE, ast.GtE: ast.Gt}


def _function(tree, dotted):
    node = tree
    for part in dotted.split("."):
        node = next(n for n in ast.iter_child_nodes(node)
                    if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and n.name == part)
    return node


def _variants(node):
    """``(operator, mutated node)`` of one node (a copy each)."""
    import copy
    out = []
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        new = copy.copy(node)
        new.value = type(node.value)(2 * node.value) if node.value != 0 else type(node.value)(1)
        out.append(("constant", new))
    elif isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
        new = copy.copy(node)
        new.op = _SWAP[type(node.op)]()
        out.append(("sign", new))
        out.append(("drop", node.left if isinstance(node.op, ast.Sub) else node.right))
        if isinstance(node.op, ast.Add):
            out.append(("drop", node.left))
    elif isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
        new = copy.copy(node)
        new.ops = [_COMPARE[type(node.ops[0])]()]
        out.append(("compare", new))
    elif isinstance(node, ast.Call):
        args = node.args
        for i in range(len(args) - 1):
            if any(isinstance(a, ast.Starred) for a in args[i:i + 2]):
                continue
            new = copy.copy(node)
            new.args = args[:i] + [args[i + 1], args[i]] + args[i + 2:]
            out.append(("swap", new))
        for i, kw in enumerate(node.keywords):
            if kw.arg is not None:
                new = copy.copy(node)
                new.keywords = node.keywords[:i] + node.keywords[i + 1:]
                out.append(("default", new))
        if len(args) >= 2 and not isinstance(args[-1], ast.Starred):
            new = copy.copy(node)
            new.args = args[:-1]
            out.append(("last", new))
    return out


def _docstring(fn):
    body = fn.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        return body[0].value
    return None


def mutants(root=ROOT, targets=TARGETS):
    """Every mutant of :data:`TARGETS`: dicts ``number, file, function, line, operator,
    original, mutated`` and the mutated file's text ``source``."""
    out = []
    for name, dotted in targets:
        with open(os.path.join(root, name), encoding="utf-8") as fh:
            text = fh.read()
        lines = text.splitlines(keepends=True)
        offsets = [0]
        for line in lines:
            offsets.append(offsets[-1] + len(line))
        fn = _function(ast.parse(text), dotted)
        doc = _docstring(fn)
        # the body only: a default in the signature is the "default" operator's, at the calls
        signature = {id(n) for n in ast.walk(fn.args)}
        seen = set()
        for node in ast.walk(fn):
            if node is doc or not hasattr(node, "end_lineno") or node is fn \
                    or id(node) in signature:
                continue
            if isinstance(node, ast.Constant) and isinstance(getattr(node, "value", None), str):
                continue
            start = offsets[node.lineno - 1] + _col(lines[node.lineno - 1], node.col_offset)
            end = offsets[node.end_lineno - 1] + _col(lines[node.end_lineno - 1],
                                                      node.end_col_offset)
            original = text[start:end]
            for operator, new in _variants(node):
                mutated = ast.unparse(new)
                if mutated == ast.unparse(node) or (start, end, mutated) in seen:
                    continue
                if isinstance(node, ast.Constant) or "\n" in original:
                    replacement = mutated
                else:
                    replacement = "(%s)" % mutated
                source = text[:start] + replacement + text[end:]
                try:
                    ast.parse(source)
                except SyntaxError:
                    continue
                seen.add((start, end, mutated))
                out.append(dict(number=len(out) + 1, file=name, function=dotted,
                                line=node.lineno, operator=operator, original=original,
                                mutated=mutated, source=source))
    return out


def _col(line, col):
    """Character offset of the UTF-8 byte offset ``col`` in ``line`` (ast counts bytes)."""
    return len(line.encode("utf-8")[:col].decode("utf-8", "replace"))


def _preload():
    """What every run imports, imported once here: each run forks from this process (saving
    seconds of imports per mutant on a loaded machine).  Not driftfmu: each run imports the
    copy's."""
    import numpy  # noqa: F401
    import pytest  # noqa: F401
    for name in ("scipy.integrate", "scipy.stats", "hypothesis", "filterpy.kalman",
                 "matplotlib"):
        try:
            __import__(name)
        except ImportError:
            pass


def _kill(pgid):
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(pgid, sig)
        except ProcessLookupError:
            return
        time.sleep(0.5)


def run_forked(copy, tests, timeout):
    """:func:`run` in a child forked from this process (a session of its own, killed whole on
    a timeout or a stop): ``(status, first failing test, seconds)``."""
    out_path = os.path.join(os.path.dirname(copy), "pytest.out")
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # the child: the copy's code, pytest in this process
        code = 3
        try:
            os.setsid()
            fd = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            os.dup2(fd, 1)
            os.dup2(fd, 2)
            os.chdir(copy)
            os.environ.update(PYTHONPATH=copy, PYTHONDONTWRITEBYTECODE="1",
                              DRIFTFMU_KERNEL="numpy")
            sys.path.insert(0, copy)
            sys.dont_write_bytecode = True
            import pytest
            code = int(pytest.main(["-n", "0"] + mutate.pytest_args(tests)))
        except BaseException:  # (nothing may escape into the parent's code)
            code = 3
        finally:
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
    try:
        deadline = time.monotonic() + timeout
        while True:
            done, status = os.waitpid(pid, os.WNOHANG)
            if done:
                break
            if time.monotonic() > deadline:
                _kill(pid)
                os.waitpid(pid, 0)
                return "timeout", None, time.perf_counter() - t0
            time.sleep(0.05)
    except BaseException:  # SIGINT, SIGTERM: the child's whole session goes too
        _kill(pid)
        try:
            os.waitpid(pid, 0)
        except ChildProcessError:
            pass
        raise
    _kill(pid)  # what the run left behind in its session
    returncode = os.waitstatus_to_exitcode(status)
    with open(out_path, encoding="utf-8", errors="replace") as fh:
        out = fh.read()
    return _result(returncode, out, time.perf_counter() - t0)


def _result(returncode, out, seconds):
    first = next((m.group(2) for m in map(mutate._FAILED.match, out.splitlines()) if m), None)
    if returncode == 0:
        return "passed", None, seconds
    if returncode == 1 and first:
        return "failed", first, seconds
    tail = [ln for ln in out.splitlines() if ln.strip()][-3:]
    return "error", first or " / ".join(tail)[:160], seconds


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--list", action="store_true", help="list the mutants, run nothing")
    ap.add_argument("--only", nargs="+", type=int, metavar="N", help="only these mutants")
    ap.add_argument("--function", nargs="+", metavar="FILE:NAME",
                    help="only the mutants of these functions")
    ap.add_argument("--out", help="write the report (JSON) here as it grows")
    ap.add_argument("--timeout", type=float, default=None,
                    help="seconds per mutant (default: 3 x the unmutated run, at least 120)")
    ap.add_argument("--tests", nargs="+", default=list(TESTS), help="the test selection")
    ap.add_argument("--then", nargs="*", default=list(THEN),
                    help="the selection a mutant that passes --tests runs against then")
    ap.add_argument("--no-fork", action="store_true",
                    help="start a new Python for every run (default where os.fork exists: "
                         "fork each run from this process, the libraries imported once)")
    args = ap.parse_args(argv)
    found = mutants()
    if args.function:
        wanted = {tuple(f.split(":", 1)) for f in args.function}
        found = [m for m in found if (m["file"], m["function"]) in wanted]
    if args.only:
        found = [m for m in found if m["number"] in set(args.only)]
    if args.list:
        for m in found:
            print("%4d %-26s %-20s %4d %-9s %s -> %s" % (
                m["number"], m["file"], m["function"], m["line"], m["operator"],
                " ".join(m["original"].split()), m["mutated"]))
        print("%d mutants" % len(found))
        return 0
    return mutate.stoppable("survey", _survey, args, found)


def _survey(args, found):
    tmp, copy = mutate.make_copy(ROOT)
    rows = []
    forked = hasattr(os, "fork") and not args.no_fork
    if forked:
        _preload()
    execute = run_forked if forked else mutate.run_tests  # (a new Python, pytest-xdist's -n)
    try:
        where = subprocess.run([sys.executable, "-c", "import driftfmu.models as m; "
                                "print(m.__file__)"], cwd=copy, capture_output=True, text=True,
                               env=dict(os.environ, PYTHONPATH=copy))
        if where.returncode or not where.stdout.strip().startswith(copy):
            print("survey: the copy does not import its own code (%s)"
                  % (where.stdout + where.stderr).strip(), file=sys.stderr)
            return 2
        selections = [args.tests] + ([args.then] if args.then else [])
        timeouts = []
        for tests in selections:
            status, first, seconds = execute(copy, tests, mutate.BASELINE_TIMEOUT)
            if status != "passed":
                print("survey: the unmutated copy does not pass %s (%s: %s)"
                      % (" ".join(tests), status, first), file=sys.stderr)
                return 2
            timeouts.append(args.timeout or max(mutate.TIMEOUT_FLOOR,
                                                mutate.TIMEOUT_FACTOR * seconds))
            print("baseline %s: passed in %.0f s; a mutant may take %.0f s"
                  % (" ".join(tests), seconds, timeouts[-1]), flush=True)
        for m in found:
            path = os.path.join(copy, m["file"])
            with open(path, encoding="utf-8") as fh:
                original = fh.read()
            try:
                with open(path, "w", encoding="utf-8") as fh:
                    fh.write(m["source"])
                seconds = 0.0
                for stage, (tests, timeout) in enumerate(zip(selections, timeouts), start=1):
                    status, first, spent = execute(copy, tests, timeout)
                    seconds += spent
                    if status in ("failed", "error"):
                        break
            finally:
                with open(path, "w", encoding="utf-8") as fh:
                    fh.write(original)
            row = {k: v for k, v in m.items() if k != "source"}
            row.update(status=status, caught=status in ("failed", "error"), first=first,
                       stage=stage, seconds=round(seconds, 1))
            rows.append(row)
            print("%4d %-8s %4.0f s %s:%s:%d %s -> %s | %s" % (
                m["number"], "caught" if row["caught"] else status.upper(), seconds, m["file"],
                m["function"], m["line"], " ".join(m["original"].split())[:50],
                m["mutated"][:50], first or ""), flush=True)
            if args.out:
                with open(args.out, "w") as fh:
                    json.dump(rows, fh, indent=1)
    finally:
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)
    survived = [r for r in rows if not r["caught"]]
    print("\n%d mutants, %d caught, %d survived" % (len(rows), len(rows) - len(survived),
                                                   len(survived)))
    for r in survived:
        print("SURVIVED %4d %s:%s:%d %s: %s -> %s" % (r["number"], r["file"], r["function"],
                                                       r["line"], r["operator"],
                                                       " ".join(r["original"].split()),
                                                       r["mutated"]))
    return 1 if survived else 0


if __name__ == "__main__":
    sys.exit(main())
