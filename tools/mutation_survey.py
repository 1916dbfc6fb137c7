"""Mutation survey: generated faults in every function of the package, each run against the
tests that reach it.

``tools/mutate.py`` runs faults written by hand (and the C twins' faults, which no Python tool
reaches); this generates them, the way a mutation tool does, in every function and method of
``driftfmu/``, ``simulations/``, ``fmu_src/`` and ``models/`` (found by parsing the files, not
listed), with the operators of :data:`OPERATORS`.

Each mutant runs against the tests that reach its function, and only those: a run of the loop
under coverage.py (``tools/survey_coverage.py``: one context per test, subprocesses included,
the FMUs' bundled copies of ``models/`` and ``fmu_src/`` mapped back) records which test runs
which line.  The record is kept in a cache keyed by the content of the tree (the four packages,
``tests/``, ``pyproject.toml`` and this tool's plugin), so it is made once per tree.  A mutant
runs first against the tests that reach its function and are not marked ``integration``; a
mutant that passes them, or whose function only ``integration`` tests reach, runs against
those.  Only tests that passed in the record are selected; the C twins' bit-for-bit
comparisons (``mutate.TWIN_TESTS``) and this tool's own tests are never selected.  Each run is a
pytest forked from this process (the libraries imported once), in a copy of the tree, bounded by
:data:`TIMEOUT_FLOOR` plus :data:`TIMEOUT_FACTOR` times the selected tests' seconds in the
record (a mutant that runs past it counts as caught: "timeout").

A survivor is looked up in the triage file (:data:`TRIAGE`, ``tools/survivors.toml``), keyed by
file, function, operator, the original and the mutated source text (and ``nth`` when the same
text occurs more than once in one function): ``verdict = "equivalent"`` with its ``reason``, or
``verdict = "test"`` with the ``test`` that catches it (a survivor so triaged is reported as a
regression: its test no longer catches it).  A survivor that no entry covers is *untriaged*;
the exit status is 1 while one remains.  Entries that match no mutant of the tree are reported
as stale.

Usage::

    python3 tools/mutation_survey.py --changed main            # the functions your change touches
    python3 tools/mutation_survey.py --since-release --budget 600   # CI: changed since the release
    python3 tools/mutation_survey.py --file models/ekf.py      # one module
    python3 tools/mutation_survey.py                           # the whole tree (hours: background)
    python3 tools/mutation_survey.py --list --changed main     # the mutants, without running them
    python3 tools/mutation_survey.py --check-triage            # stale triage entries only
    python3 tools/mutation_survey.py --changed main --only 9 35 --against tests/test_new.py

Exit status: 0 when no untriaged survivor remains, 1 when one does, 2 for a usage error, a
broken triage file or a record that fails, 130 when stopped.
"""
import argparse
import ast
import copy as _copy
import fnmatch
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import mutate  # noqa: E402  (the copy, the process groups, the twin tests left out)

try:
    import tomllib
except ImportError:  # Python < 3.11
    tomllib = None

ROOT = mutate.ROOT
#: The folders whose functions are mutated.
PACKAGES = ("driftfmu", "simulations", "fmu_src", "models")
#: The triage file: known survivors and their verdicts; ``[release] base`` is the commit of the
#: last release (``--since-release``).
TRIAGE = os.path.join(ROOT, "tools", "survivors.toml")
#: What the record's cache key reads besides the packages.
KEYED = ("tests", "pyproject.toml", "tools/survey_coverage.py")
#: A mutant's run may take this many seconds ...
TIMEOUT_FLOOR = 120.0
#: ... plus this many times the seconds its tests took in the record.
TIMEOUT_FACTOR = 3.0
#: Never selected: the twins' bit comparisons (plumbing, not evidence), this tool's own runs,
#: and mutate.py's wall-clock exception.
NEVER = tuple(mutate.TWIN_TESTS) + tuple(mutate.SELF_TESTS)

#: The operators and what each does.
OPERATORS = {
    "constant": "a numeric constant c becomes 2 c (1 if c = 0)",
    "offbyone": "an integer constant c becomes c + 1 and c - 1",
    "sign": "+ and - swapped; a unary minus removed",
    "drop": "a term of a sum or difference dropped",
    "compare": "== / !=, != / >, < / <=, > / >=, is / is not, in / not in",
    "swap": "two neighbouring positional arguments of a call swapped",
    "default": "a keyword argument of a call left out (the callee's default taken)",
    "last": "the last positional argument of a call left out",
    "boolean": "and / or swapped",
    "not": "a not removed",
    "return": "a returned value replaced by None",
    "if": "an if's (or a conditional expression's) condition forced True, then False",
    "delete": "a raise, or a call of unlink / remove / rmtree / fsync / close / flush / release "
              "/ chmod / kill / terminate as a statement, replaced by pass",
}
_SWAP = {ast.Add: ast.Sub, ast.Sub: ast.Add}
_COMPARE = {ast.Eq: ast.NotEq, ast.NotEq: ast.Gt, ast.Lt: ast.LtE, ast.LtE: ast.Lt,
            ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Is: ast.IsNot, ast.IsNot: ast.Is,
            ast.In: ast.NotIn, ast.NotIn: ast.In}
_DELETABLE = frozenset({"unlink", "remove", "rmtree", "rmdir", "fsync", "close", "flush",
                        "release", "chmod", "fchmod", "kill", "terminate"})
_FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)


# ---------------------------------------------------------------- the functions and mutants

def source_files(root=ROOT, packages=PACKAGES):
    """The Python files of the packages, relative to ``root``, sorted."""
    out = []
    for package in packages:
        for folder, dirs, files in os.walk(os.path.join(root, package)):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__")
            out += [os.path.relpath(os.path.join(folder, f), root).replace(os.sep, "/")
                    for f in files if f.endswith(".py")]
    return sorted(out)


def functions(tree):
    """``(qualified name, node)`` of every function and method in ``tree``, nested ones as
    ``outer.inner``, in source order."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, _FUNCTIONS + (ast.ClassDef,)):
                name = prefix + child.name
                if isinstance(child, _FUNCTIONS):
                    out.append((name, child))
                visit(child, name + ".")
            elif not isinstance(child, ast.Lambda):
                visit(child, prefix)
    visit(tree, "")
    return out


def _own_nodes(fn):
    """``(node, the innermost statement holding it)`` of ``fn``'s body that are its own: not
    in a nested function or class (those are functions of their own), not in its docstring,
    signature, decorators or an f-string."""
    body = fn.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        body = body[1:]
    out = []
    stack = [(node, node) for node in reversed(body)]
    while stack:
        node, statement = stack.pop()
        if isinstance(node, _FUNCTIONS + (ast.ClassDef, ast.JoinedStr)):
            continue
        out.append((node, statement))
        if isinstance(node, ast.stmt):
            # a compound statement's header: its own lines up to its first inner statement
            statement = node
        stack.extend((child, child if isinstance(child, ast.stmt) else statement)
                     for child in reversed(list(ast.iter_child_nodes(node))))
    return out


def _variants(node):
    """``(operator, replacement text)`` of one node; the replacement is the text of the
    mutated node (``ast.unparse``), ``pass`` for a deleted statement."""
    out = []

    def add(operator, new):
        out.append((operator, ast.unparse(new) if isinstance(new, ast.AST) else new))

    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        add("constant", repr(type(node.value)(2 * node.value) if node.value != 0
                             else type(node.value)(1)))
        if type(node.value) is int:
            add("offbyone", repr(node.value + 1))
            add("offbyone", repr(node.value - 1))
    elif isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
        new = _copy.copy(node)
        new.op = _SWAP[type(node.op)]()
        add("sign", new)
        add("drop", node.left if isinstance(node.op, ast.Sub) else node.right)
        if isinstance(node.op, ast.Add):
            add("drop", node.left)
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        add("sign", node.operand)
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        add("not", node.operand)
    elif isinstance(node, ast.BoolOp):
        new = _copy.copy(node)
        new.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        add("boolean", new)
    elif isinstance(node, ast.Compare):
        for i, op in enumerate(node.ops):
            if type(op) in _COMPARE:
                new = _copy.copy(node)
                new.ops = node.ops[:i] + [_COMPARE[type(op)]()] + node.ops[i + 1:]
                add("compare", new)
    elif isinstance(node, ast.Call):
        args = node.args
        for i in range(len(args) - 1):
            if any(isinstance(a, ast.Starred) for a in args[i:i + 2]):
                continue
            new = _copy.copy(node)
            new.args = args[:i] + [args[i + 1], args[i]] + args[i + 2:]
            add("swap", new)
        for i, kw in enumerate(node.keywords):
            if kw.arg is not None:
                new = _copy.copy(node)
                new.keywords = node.keywords[:i] + node.keywords[i + 1:]
                add("default", new)
        if len(args) >= 2 and not isinstance(args[-1], ast.Starred):
            new = _copy.copy(node)
            new.args = args[:-1]
            add("last", new)
    return out


def _statement_variants(node):
    """``(operator, the node whose text is replaced, replacement)`` of statements."""
    out = []
    if isinstance(node, ast.Return) and node.value is not None \
            and not (isinstance(node.value, ast.Constant) and node.value.value is None):
        out.append(("return", node.value, "None"))
    elif isinstance(node, (ast.If, ast.IfExp)):
        out.append(("if", node.test, "True"))
        out.append(("if", node.test, "False"))
    elif isinstance(node, ast.Raise):
        out.append(("delete", node, "pass"))
    elif isinstance(node, ast.Expr) and isinstance(node.value, ast.Call):
        func = node.value.func
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
        if name in _DELETABLE:
            out.append(("delete", node, "pass"))
    return out


def _header(statement):
    """The lines of a statement that run whenever any of it runs: a simple statement's all,
    a compound one's up to its first inner statement (the test of an if, a for's iterable)."""
    inner = [c.lineno for c in ast.iter_child_nodes(statement) if isinstance(c, ast.stmt)]
    last = min(inner) - 1 if inner else statement.end_lineno
    return [statement.lineno, max(statement.lineno, last)]


def _col(line, col):
    """Character offset of the UTF-8 byte offset ``col`` in ``line`` (ast counts bytes)."""
    return len(line.encode("utf-8")[:col].decode("utf-8", "replace"))


def _span(offsets, lines, node):
    return (offsets[node.lineno - 1] + _col(lines[node.lineno - 1], node.col_offset),
            offsets[node.end_lineno - 1] + _col(lines[node.end_lineno - 1], node.end_col_offset))


def _normal(text):
    return " ".join(text.split())


def file_mutants(root, name, wanted=None):
    """The mutants of the file ``name`` (relative to ``root``), of the functions in ``wanted``
    (qualified names; None: all): dicts ``file, function, line, operator, original, mutated,
    nth, start, end, replacement, first, last`` (``first``-``last``: the function's lines)."""
    with open(os.path.join(root, name), encoding="utf-8") as fh:
        text = fh.read()
    lines = text.splitlines(keepends=True)
    offsets = [0]
    for line in lines:
        offsets.append(offsets[-1] + len(line))
    out = []
    for qualname, fn in functions(ast.parse(text)):
        if wanted is not None and qualname not in wanted:
            continue
        seen, count = set(), {}
        for node, statement in _own_nodes(fn):
            edits = [(op, node, rep) for op, rep in _variants(node)] + \
                _statement_variants(node)
            for operator, target, replacement in edits:
                start, end = _span(offsets, lines, target)
                original = text[start:end]
                if _normal(replacement) == _normal(ast.unparse(target)) \
                        or (start, end, replacement) in seen:
                    continue
                seen.add((start, end, replacement))
                mutated = _normal(replacement)
                if operator not in ("constant", "offbyone", "delete", "return", "if") \
                        and "\n" not in original:
                    replacement = "(%s)" % replacement
                key = (operator, _normal(ast.unparse(target)), mutated)
                count[key] = count.get(key, 0) + 1
                out.append(dict(file=name, function=qualname, line=target.lineno,
                                operator=operator, original=key[1], mutated=key[2],
                                nth=count[key], start=start, end=end, replacement=replacement,
                                first=fn.lineno, last=fn.end_lineno,
                                lines=_header(statement)))
    return out


def mutant_source(root, m):
    """The text of ``m``'s file with ``m`` applied, or None when that does not parse."""
    with open(os.path.join(root, m["file"]), encoding="utf-8") as fh:
        text = fh.read()
    source = text[:m["start"]] + m["replacement"] + text[m["end"]:]
    try:
        ast.parse(source)
    except SyntaxError:
        return None
    return source


def mutants(root=ROOT, scope=None):
    """Every mutant of the tree at ``root``; ``scope``: {file: set of function names or None
    (all)} to keep only those.  Numbered from 1 in this order."""
    out = []
    for name in source_files(root):
        if scope is not None and name not in scope:
            continue
        out += file_mutants(root, name, None if scope is None else scope[name])
    for number, m in enumerate(out, start=1):
        m["number"] = number
    return out


def key(m):
    """The triage key of a mutant (stable across edits elsewhere in the file)."""
    return (m["file"], m["function"], m["operator"], m["original"], m["mutated"])


# ---------------------------------------------------------------- the change

def merge_base(root, base):
    p = subprocess.run(["git", "merge-base", base, "HEAD"], cwd=root, capture_output=True,
                       text=True)
    if p.returncode:
        raise SystemExit("survey: no common ancestor of %s and HEAD: %s"
                         % (base, p.stderr.strip()))
    return p.stdout.strip()


def changed_lines(root, base):
    """{file: set of lines of the working tree that differ from ``base``'s merge base with
    HEAD} for the packages' Python files (an untracked file: all its lines); a deletion marks
    the lines either side of it."""
    start = merge_base(root, base)
    p = subprocess.run(["git", "diff", "-U0", "--no-color", "--no-ext-diff", start, "--"]
                       + list(PACKAGES), cwd=root, capture_output=True, text=True, check=True)
    out, name = {}, None
    for line in p.stdout.splitlines():
        if line.startswith("+++ "):
            name = line[6:] if line.startswith("+++ b/") else None
            if name is not None and not name.endswith(".py"):
                name = None
        elif line.startswith("@@") and name is not None:
            m = re.match(r"@@ -\d+(?:,\d+)? \+(\d+)(?:,(\d+))? @@", line)
            first, count = int(m.group(1)), int(m.group(2) or "1")
            lines = range(first, first + count) if count else (first, first + 1)
            out.setdefault(name, set()).update(lines)
    untracked = subprocess.run(["git", "ls-files", "--others", "--exclude-standard", "--"]
                               + list(PACKAGES), cwd=root, capture_output=True, text=True,
                               check=True).stdout.split()
    for name in untracked:
        if name.endswith(".py"):
            with open(os.path.join(root, name), encoding="utf-8") as fh:
                out[name] = set(range(1, len(fh.read().splitlines()) + 2))
    return out


def changed_functions(root, base):
    """{file: set of qualified names} of the functions with a line that differs from
    ``base`` (a nested function's change is its own, not its outer function's)."""
    out = {}
    for name, lines in changed_lines(root, base).items():
        path = os.path.join(root, name)
        if not os.path.isfile(path):
            continue
        with open(path, encoding="utf-8") as fh:
            found = functions(ast.parse(fh.read()))
        for qualname, fn in found:
            first = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
            own = set(range(first, fn.end_lineno + 1))
            for other, inner in found:  # lines of nested functions are theirs
                if other.startswith(qualname + "."):
                    own -= set(range(min([inner.lineno] + [d.lineno for d in
                                                             inner.decorator_list]),
                                     inner.end_lineno + 1))
            if own & lines:
                out.setdefault(name, set()).add(qualname)
    return out


# ---------------------------------------------------------------- the triage file

def load_triage(path=TRIAGE):
    """``(entries, release base)`` of the triage file; SystemExit on a malformed entry."""
    if tomllib is None:
        raise SystemExit("tools/mutation_survey.py needs Python 3.11 (tomllib)")
    if not os.path.exists(path):
        return [], None
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    entries = data.get("survivor", [])
    for i, e in enumerate(entries, start=1):
        missing = [k for k in ("file", "function", "operator", "original", "mutated",
                               "verdict") if k not in e]
        if missing:
            raise SystemExit("%s: survivor %d lacks %s" % (path, i, ", ".join(missing)))
        if e["verdict"] == "equivalent" and not e.get("reason"):
            raise SystemExit("%s: survivor %d (%s:%s) is equivalent without a reason"
                             % (path, i, e["file"], e["function"]))
        if e["verdict"] == "test" and not e.get("test"):
            raise SystemExit("%s: survivor %d (%s:%s) names no test"
                             % (path, i, e["file"], e["function"]))
        if e["verdict"] not in ("equivalent", "test"):
            raise SystemExit("%s: survivor %d: verdict %r (allowed: equivalent, test)"
                             % (path, i, e["verdict"]))
        if e["operator"] not in OPERATORS:
            raise SystemExit("%s: survivor %d: operator %r (allowed: %s)"
                             % (path, i, e["operator"], ", ".join(OPERATORS)))
    return entries, data.get("release", {}).get("base")


def _matches(entry, m):
    return (entry["file"], entry["function"], entry["operator"], _normal(entry["original"]),
            _normal(entry["mutated"])) == key(m) and entry.get("nth", m["nth"]) == m["nth"]


def triage_of(entries, m):
    return next((e for e in entries if _matches(e, m)), None)


def stale(entries, everything):
    """The entries that match no mutant of ``everything``."""
    return [e for e in entries if not any(_matches(e, m) for m in everything
                                          if m["file"] == e["file"])]


# ---------------------------------------------------------------- the record: who reaches what

def tree_key(root=ROOT):
    """A hash of what the record depends on: the packages, the tests, pyproject, the plugin."""
    h = hashlib.sha256()
    paths = []
    for top in PACKAGES + KEYED:
        full = os.path.join(root, top)
        if os.path.isfile(full):
            paths.append(top)
        for folder, dirs, files in os.walk(full):
            dirs[:] = sorted(d for d in dirs if d not in ("__pycache__", ".pytest_cache",
                                                          ".hypothesis"))
            paths += [os.path.relpath(os.path.join(folder, f), root) for f in files
                      if not f.endswith((".pyc", ".so", ".o"))]
    for rel in sorted(paths):
        h.update(rel.replace(os.sep, "/").encode() + b"\0")
        with open(os.path.join(root, rel), "rb") as fh:
            h.update(hashlib.sha256(fh.read()).digest())
    return h.hexdigest()[:20]


def cache_dir():
    return os.environ.get("DRIFTFMU_SURVEY_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "driftfmu",
        "survey")


_BUNDLED = re.compile(r"/drift_[0-9a-f]+/(.+\.py)$")


def _tree_name(path, copy):
    """The tree's name of a measured file: its own, or the source of an FMU's bundled copy
    (``.../drift_<hash>/models/x.py``, ``.../drift_<hash>/<Slave>.py``); None for others."""
    path = path.replace(os.sep, "/")
    prefix = copy.replace(os.sep, "/").rstrip("/") + "/"
    if path.startswith(prefix):
        name = path[len(prefix):]
        return name if name.split("/")[0] in PACKAGES else None
    m = _BUNDLED.search(path)
    if not m or m.group(1).endswith("__init__.py"):
        return None
    return m.group(1) if m.group(1).startswith("models/") else "fmu_src/" + m.group(1)


def record(root, tests=("tests",), workers="2", log=print):
    """Run ``tests`` (the loop's, without :data:`NEVER`) on a copy of ``root`` under coverage;
    return the record: ``tests`` (node id -> [passed, integration, seconds]) and ``lines``
    ({file: {line: [node ids]}})."""
    tmp, copy = mutate.make_copy(root)
    try:
        data = os.path.join(tmp, "coverage", "data")
        os.makedirs(os.path.dirname(data))
        rc = os.path.join(tmp, "coveragerc")
        include = ["%s/%s/*" % (copy, p) for p in PACKAGES] + ["*/drift_*/*"]
        with open(rc, "w") as fh:
            fh.write("[run]\nparallel = True\npatch = subprocess\ndata_file = %s\n"
                     "disable_warnings = no-data-collected, module-not-measured\n"
                     "include =\n%s\n" % (data, "".join("    %s\n" % i for i in include)))
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([copy, os.path.join(copy, "tools")]),
                   PYTHONDONTWRITEBYTECODE="1", DRIFTFMU_KERNEL="numpy",
                   SURVEY_COVERAGE_RC=rc, SURVEY_COVERAGE_DATA=data)
        env.pop("COVERAGE_PROCESS_CONFIG", None)
        cmd = [sys.executable, "-m", "pytest", "-p", "survey_coverage", "-q",
               "-p", "no:cacheprovider", "-n", str(workers)] + \
            ["--deselect=" + d for d in mutate.DESELECT] + \
            ["--ignore-glob=" + g for g in NEVER] + list(tests)
        log("survey: recording which test reaches which line (%s)" % " ".join(tests))
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=copy, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True)
        try:
            out, _ = p.communicate()
        except BaseException:
            mutate.kill_group(p)
            p.communicate()
            raise
        mutate.kill_group(p, grace=1.0)
        if p.returncode not in (0, 1):
            raise SystemExit("survey: the recording run failed (pytest exit %d): %s"
                             % (p.returncode, " / ".join(out.strip().splitlines()[-3:])))
        summary = [ln for ln in out.splitlines() if re.search(r"\d+ (passed|failed)", ln)]
        log("survey: recorded in %.0f s (%s)" % (time.perf_counter() - t0,
                                                  (summary or ["no summary"])[-1].strip()))
        result, failed = {}, []
        folder = os.path.dirname(data)
        for f in os.listdir(folder):
            if f.endswith(".tests"):
                with open(os.path.join(folder, f)) as fh:
                    for line in fh:
                        t = json.loads(line)
                        result[t["test"]] = [t["outcome"] == "passed", t["integration"],
                                             t["seconds"]]
                        if t["outcome"] == "failed":
                            failed.append(t["test"])
        if failed:  # (their lines count as reached by no test: the survey shows such mutants)
            log("survey: failed under coverage, so not used: %s" % ", ".join(sorted(failed)))
        import coverage
        combined = coverage.CoverageData(basename=os.path.join(tmp, "combined"))
        for f in os.listdir(folder):
            if f.startswith("data.") and not f.endswith(".tests"):
                part = coverage.CoverageData(basename=os.path.join(folder, f))
                part.read()
                combined.update(part)
        lines = {}
        for measured in combined.measured_files():
            name = _tree_name(measured, copy)
            if name is None:
                continue
            target = lines.setdefault(name, {})
            for lineno, contexts in combined.contexts_by_lineno(measured).items():
                ids = target.setdefault(str(lineno), [])
                ids += [c for c in contexts if c and c not in ids]
        return {"tests": result, "lines": lines}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def cached_record(root, tests=("tests",), workers="2", log=print, refresh=False):
    """:func:`record`, cached by :func:`tree_key` (and the selection)."""
    k = tree_key(root)
    if tuple(tests) != ("tests",):
        k += "-" + hashlib.sha256("\0".join(tests).encode()).hexdigest()[:8]
    path = os.path.join(cache_dir(), "%s.json" % k)
    if not refresh and os.path.exists(path):
        with open(path) as fh:
            log("survey: which test reaches which line: %s (cached)" % path)
            return json.load(fh)
    result = record(root, tests, workers, log)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path + ".part", "w") as fh:
        json.dump(result, fh)
    os.replace(path + ".part", path)
    return result


def selection(rec, m):
    """``(unit tests, integration tests)`` that run ``m``'s statement (and so reach its
    function) and passed in the record, each in the order of their seconds (fastest
    first).  A test that does not run the statement cannot tell the mutant from the original."""
    reached = set()
    first, last = m["lines"]
    for lineno, ids in rec["lines"].get(m["file"], {}).items():
        if first <= int(lineno) <= last:
            reached.update(ids)
    tests = rec["tests"]
    passed = [t for t in reached if t in tests and tests[t][0]
              and not any(t.startswith(n) for n in NEVER)]
    passed.sort(key=lambda t: (tests[t][2], t))
    return ([t for t in passed if not tests[t][1]], [t for t in passed if tests[t][1]])


# ---------------------------------------------------------------- the runs

def _preload():
    """What every run imports, imported once here: each run forks from this process.  Not
    driftfmu: each run imports the copy's."""
    import numpy  # noqa: F401
    import pytest  # noqa: F401
    for name in ("scipy.integrate", "scipy.stats", "hypothesis", "filterpy.kalman",
                 "matplotlib", "fmpy"):
        try:
            __import__(name)
        except ImportError:
            pass


class _Only:
    """pytest plugin: keep exactly the node ids asked for, in their order (a path alone: all of
    its tests)."""

    def __init__(self, ids):
        self.ids = {t: i for i, t in enumerate(ids)}
        self.whole = {t for t in ids if "::" not in t}

    def _id(self, item):
        """The id of ``ids`` that names ``item``: its node id, or the node id of its test
        function without the parameters (``--against tests/t.py::test_f`` names every
        ``test_f[...]``); None."""
        for key in (item.nodeid, item.nodeid.split("[", 1)[0]):
            if key in self.ids:
                return key
        return None

    def pytest_collection_modifyitems(self, config, items):
        if self.whole:
            return
        keep = [it for it in items if self._id(it) is not None]
        drop = [it for it in items if self._id(it) is None]
        keep.sort(key=lambda it: self.ids[self._id(it)])
        items[:] = keep
        if drop:
            config.hook.pytest_deselected(items=drop)


def start_forked(copy, tests, out_path):
    """Fork a child that runs ``tests`` (node ids) in ``copy`` (a session of its own); its
    pid."""
    pid = os.fork()
    if pid:
        return pid
    code = 3
    try:
        os.setsid()
        fd = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.chdir(copy)
        os.environ.update(PYTHONPATH=copy, PYTHONDONTWRITEBYTECODE="1", DRIFTFMU_KERNEL="numpy")
        os.environ.pop("COVERAGE_PROCESS_CONFIG", None)
        sys.path.insert(0, copy)
        sys.dont_write_bytecode = True
        import pytest
        files = sorted({t.split("::")[0] for t in tests})
        code = int(pytest.main(["-n", "0", "-x", "-q", "-rfE", "-p", "no:cacheprovider",
                                "-p", "no:randomly"] + files, plugins=[_Only(tests)]))
    except BaseException:  # (nothing may escape into the parent's code)
        code = 3
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def _kill(pgid):
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(pgid, sig)
        except ProcessLookupError:
            return
        time.sleep(0.2)


LEFT_BEHIND = mutate.LEFT_BEHIND


def _result(returncode, out):
    first = next((m.group(2) for m in map(mutate._FAILED.match, out.splitlines()) if m), None)
    if returncode == 0:
        return "passed", None
    if returncode == 1 and first:
        return "failed", first
    if mutate.only_left_files(returncode, out):  # every test passed: the mutant is not caught
        return "passed", None
    if returncode == 5:
        return "not run", "no test collected"
    tail = [ln for ln in out.splitlines() if ln.strip()][-3:]
    return "error", first or " / ".join(tail)[:160]


class Slot:
    """One copy of the tree and the mutant running in it."""

    def __init__(self, root):
        self.tmp, self.copy = mutate.make_copy(root)
        self.out = os.path.join(self.tmp, "pytest.out")
        self.pid = None

    def apply(self, m, source):
        self.path = os.path.join(self.copy, m["file"])
        with open(self.path, encoding="utf-8") as fh:
            self.original = fh.read()
        with open(self.path, "w", encoding="utf-8") as fh:
            fh.write(source)

    def restore(self):
        with open(self.path, "w", encoding="utf-8") as fh:
            fh.write(self.original)

    def start(self, tests, timeout):
        self.pid = start_forked(self.copy, tests, self.out)
        self.deadline = time.monotonic() + timeout
        self.t0 = time.perf_counter()

    def poll(self):
        """None while running, else (status, first failing test)."""
        done, status = os.waitpid(self.pid, os.WNOHANG)
        if not done:
            if time.monotonic() < self.deadline:
                return None
            _kill(self.pid)
            os.waitpid(self.pid, 0)
            self.pid = None
            return "timeout", None
        _kill(self.pid)  # what the run left behind in its session
        self.pid = None
        with open(self.out, encoding="utf-8", errors="replace") as fh:
            return _result(os.waitstatus_to_exitcode(status), fh.read())

    def stop(self):
        if self.pid is not None:
            _kill(self.pid)
            try:
                os.waitpid(self.pid, 0)
            except ChildProcessError:
                pass
            self.pid = None

    def remove(self):
        self.stop()
        shutil.rmtree(self.tmp, ignore_errors=True)


def timeout_for(rec, tests):
    return TIMEOUT_FLOOR + TIMEOUT_FACTOR * sum(rec["tests"].get(t, [0, 0, 0.0])[2]
                                                for t in tests)


def with_named_test(tests, entry):
    """The unit tests of a selection, with the test that the triage ``entry`` says catches the
    mutant first: the record sees the lines run in this process only, not those a test runs
    in the worker processes of a pool (the FMU runs of an experiment), so that test may
    reach the line unseen."""
    if entry is None or entry.get("verdict") != "test" or entry["test"] in tests:
        return tests
    return [entry["test"]] + list(tests)


def run_all(root, found, rec, jobs=1, budget=None, log=print, against=None, entries=()):
    """Run each mutant of ``found`` against its selection: stage 1 the unit tests that reach
    it (and the test its triage entry names, :func:`with_named_test`), stage 2 (when it
    passes them or has none) the integration tests.  Rows in the order of ``found``; a mutant
    not started within ``budget`` seconds gets status "not run"."""
    _preload()
    slots = [Slot(root) for _ in range(max(1, jobs))]
    t0 = time.monotonic()
    rows = {}
    pending = list(found)
    running = {}  # slot index -> [mutant, stage, stages, seconds]
    try:
        while pending or running:
            for i, slot in enumerate(slots):
                if i in running or not pending:
                    continue
                if budget is not None and time.monotonic() - t0 > budget:
                    for m in pending:
                        rows[m["number"]] = _row(m, "not run", "over --budget", 0, 0.0, [])
                    pending = []
                    break
                m = pending.pop(0)
                if m.get("beyond_limit"):
                    rows[m["number"]] = _row(m, "not run", "over --limit", 0, 0.0, [])
                    continue
                unit, integration = selection(rec, m) if against is None else (against, [])
                if against is None:
                    unit = with_named_test(unit, triage_of(entries, m))
                stages = [s for s in (unit, integration) if s]
                source = mutant_source(root, m)
                if source is None:
                    rows[m["number"]] = _row(m, "invalid", "does not parse", 0, 0.0, [])
                    continue
                if not stages:
                    rows[m["number"]] = _row(m, "unreached", "no test runs line %d"
                                             % m["line"], 0, 0.0, [])
                    log(_line(rows[m["number"]]))
                    continue
                slot.apply(m, source)
                slot.start(stages[0], timeout_for(rec, stages[0]))
                running[i] = [m, 1, stages, 0.0]
            for i in list(running):
                result = slots[i].poll()
                if result is None:
                    continue
                m, stage, stages, seconds = running[i]
                seconds += time.perf_counter() - slots[i].t0
                status, first = result
                if status == "passed" and stage < len(stages):
                    slots[i].start(stages[stage], timeout_for(rec, stages[stage]))
                    running[i] = [m, stage + 1, stages, seconds]
                    continue
                slots[i].restore()
                del running[i]
                kinds = ["unit" if not rec["tests"].get(s[0], [0, 0])[1] else "integration"
                         for s in stages]
                rows[m["number"]] = _row(m, status, first, stage, seconds, kinds,
                                         sum(len(s) for s in stages[:stage]))
                log(_line(rows[m["number"]]))
            if running:
                time.sleep(0.05)
    finally:
        for slot in slots:
            slot.remove()
    return [rows[m["number"]] for m in found]


def _row(m, status, first, stage, seconds, kinds, selected=0):
    row = {k: v for k, v in m.items() if k not in ("start", "end", "replacement")}
    row.update(status=status, first=first, stage=stage, seconds=round(seconds, 1),
               selected=selected, kinds=kinds,
               caught=status in ("failed", "error", "timeout"))
    return row


def _line(r):
    return "%5d %-9s %5.0f s %s:%s:%d %s %s -> %s | %s" % (
        r["number"], "caught" if r["caught"] else r["status"].upper(), r["seconds"], r["file"],
        r["function"], r["line"], r["operator"], r["original"][:50], r["mutated"][:50],
        r["first"] or "")


# ---------------------------------------------------------------- the report

def report(rows, entries, everything, log=print):
    """Print the summary; return the untriaged survivors (a survivor whose entry says a test
    catches it counts as one: the test no longer does)."""
    survivors = [r for r in rows if r["status"] in ("passed", "unreached")]
    untriaged, triaged = [], []
    for r in survivors:
        e = triage_of(entries, r)
        (triaged if e is not None and e["verdict"] == "equivalent" else untriaged).append(
            (r, e))
    ran = [r for r in rows if r["status"] not in ("not run", "invalid")]
    log("\n%d mutants, %d ran: %d caught (%d by integration tests, %d timed out), "
        "%d survived (%d equivalent, %d untriaged)%s"
        % (len(rows), len(ran), sum(r["caught"] for r in ran),
           sum(r["caught"] and r["kinds"][r["stage"] - 1] == "integration" for r in ran),
           sum(r["status"] == "timeout" for r in ran), len(survivors), len(triaged),
           len(untriaged), "; %d not run (over --budget)" % sum(
               r["status"] == "not run" for r in rows)
           if any(r["status"] == "not run" for r in rows) else ""))
    by = {}
    for r in ran:
        c = by.setdefault(r["operator"], [0, 0])
        c[0] += r["caught"]
        c[1] += 1
    log("by operator, caught of run: " + ", ".join("%s %d/%d" % (op, c[0], c[1])
                                                    for op, c in sorted(by.items())))
    only = sorted({"%s:%s" % (r["file"], r["function"]) for r in ran
                   if r["kinds"] == ["integration"]})
    if only:
        log("reached by integration tests only: " + ", ".join(only))
    for r, e in untriaged:
        log("UNTRIAGED %s:%s:%d %s: %s -> %s%s%s" % (
            r["file"], r["function"], r["line"], r["operator"], r["original"], r["mutated"],
            "" if r["nth"] == 1 else " (nth = %d)" % r["nth"],
            " (triaged as caught by %s, which no longer catches it)" % e["test"] if e else
            (" (no test runs this line)" if r["status"] == "unreached" else "")))
    for e in stale(entries, everything):
        log("STALE triage entry: %s:%s %s: %s -> %s (no such mutant in the tree)"
            % (e["file"], e["function"], e["operator"], e["original"], e["mutated"]))
    return [r for r, _ in untriaged]


def toml_entries(rows):
    """The untriaged survivors as triage entries to fill in (verdict and reason or test)."""
    out = []
    for r in rows:
        fields = [(k, json.dumps(r[k])) for k in ("file", "function", "operator", "original",
                                                  "mutated")]
        if r["nth"] > 1:
            fields.append(("nth", str(r["nth"])))
        out.append("[[survivor]]\n" + "".join("%s = %s\n" % f for f in fields)
                   + 'verdict = "?"\nreason = ""\n')
    return "\n".join(out)


# ---------------------------------------------------------------- the command

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=ROOT, help="the tree (default: this checkout)")
    ap.add_argument("--triage", default=None, help="the triage file (default: "
                    "tools/survivors.toml of --root)")
    scope = ap.add_mutually_exclusive_group()
    scope.add_argument("--changed", metavar="BASE",
                       help="only the functions whose lines differ from BASE (git diff from "
                            "BASE's merge base with HEAD to the working tree)")
    scope.add_argument("--since-release", action="store_true",
                       help="--changed with the base of [release] in the triage file")
    ap.add_argument("--file", nargs="+", metavar="FILE", help="only these files (globs)")
    ap.add_argument("--function", nargs="+", metavar="FILE:NAME",
                    help="only these functions")
    ap.add_argument("--only", nargs="+", type=int, metavar="N", help="only these mutants "
                    "(numbers of --list with the same selection)")
    ap.add_argument("--list", action="store_true", help="list the mutants, run nothing")
    ap.add_argument("--check-triage", action="store_true",
                    help="only check the triage file (entries and stale ones)")
    ap.add_argument("--record-tests", nargs="+", default=["tests"], metavar="PATH",
                    help="the tests whose reach is recorded (default: the loop, tests/)")
    ap.add_argument("--record-workers", default="2", help="pytest-xdist workers of the record")
    ap.add_argument("--refresh", action="store_true", help="record anew, ignoring the cache")
    ap.add_argument("--jobs", type=int, default=1, help="mutants run at once (default 1)")
    ap.add_argument("--budget", type=float, default=None, metavar="SECONDS",
                    help="start no mutant after SECONDS (those left are reported not run)")
    ap.add_argument("--sample-seed", action="store_true",
                    help="print the triage file's [release] base and stop: CI's seed for "
                         "--shuffle, the same order of the mutants from one release to the "
                         "next, so that the survivors of its sample can be answered before CI "
                         "runs (a new function's mutants take their places in that order)")
    ap.add_argument("--limit", type=int, default=None, metavar="N",
                    help="run the first N mutants of the order only (with --shuffle: the same "
                         "N each run, those after reported not run)")
    ap.add_argument("--shuffle", metavar="SEED", help="run the mutants in an order drawn "
                    "from SEED (with --budget: another sample each run)")
    ap.add_argument("--against", nargs="+", metavar="TEST",
                    help="run every mutant against these tests (paths or node ids) instead of "
                         "the recorded selection: does a new test catch these survivors?")
    ap.add_argument("--out", help="write the rows (JSON) here")
    ap.add_argument("--toml", help="write the untriaged survivors here as triage entries")
    args = ap.parse_args(argv)
    if args.jobs < 1 or (args.budget is not None and not args.budget > 0):
        ap.error("--jobs: allowed: 1 or more; --budget: allowed: seconds > 0")
    root = os.path.abspath(args.root)
    try:
        entries, base = load_triage(args.triage or os.path.join(root, "tools",
                                                                "survivors.toml"))
    except SystemExit as e:
        print("survey: %s" % e, file=sys.stderr)
        return 2
    if args.sample_seed:
        if not base:
            print("survey: the triage file has no [release] base", file=sys.stderr)
            return 2
        print(base)
        return 0
    everything = mutants(root)
    if args.check_triage:
        gone = stale(entries, everything)
        for e in gone:
            print("STALE triage entry: %s:%s %s: %s -> %s" % (
                e["file"], e["function"], e["operator"], e["original"], e["mutated"]))
        print("survey: %d triage entries, %d stale" % (len(entries), len(gone)))
        return 1 if gone else 0
    if args.since_release:
        if not base:
            print("survey: the triage file has no [release] base", file=sys.stderr)
            return 2
        args.changed = base
    try:
        scope = changed_functions(root, args.changed) if args.changed else None
    except (SystemExit, subprocess.CalledProcessError) as e:
        print("survey: %s" % e, file=sys.stderr)
        return 2
    found = mutants(root, scope)
    if args.file:
        found = [m for m in found if any(fnmatch.fnmatch(m["file"], g) for g in args.file)]
    if args.function:
        wanted = {tuple(f.split(":", 1)) for f in args.function}
        found = [m for m in found if (m["file"], m["function"]) in wanted]
    if args.only:
        found = [m for m in found if m["number"] in set(args.only)]
    if args.changed:
        print("survey: %d functions changed since %s: %d mutants" % (
            sum(len(v) for v in scope.values()), args.changed, len(found)))
    if args.shuffle:
        found.sort(key=lambda m: hashlib.sha256(("%s\0%r\0%d" % (args.shuffle, key(m),
                                                                 m["nth"])).encode()).digest())
    if args.list:
        # with --shuffle, in the order of the run; with --limit, the mutants the run would run
        for m in found[:args.limit] if args.limit and args.limit > 0 else found:
            print("%5d %s:%s:%d %-8s %s -> %s" % (m["number"], m["file"], m["function"],
                                                  m["line"], m["operator"], m["original"],
                                                  m["mutated"]))
        print("%d mutants in %d functions" % (len(found), len({(m["file"], m["function"])
                                                                 for m in found})))
        return 0
    if args.limit is not None:
        if args.limit < 1:
            print("survey: --limit %d: allowed: 1 or more" % args.limit, file=sys.stderr)
            return 2
        for m in found[args.limit:]:
            m["beyond_limit"] = True
    return mutate.stoppable("survey", _survey, args, root, found, entries, everything)


def _survey(args, root, found, entries, everything):
    if not found:
        report([], entries, everything)
        return 0
    if args.against:
        rec = {"tests": {}, "lines": {}}
    else:
        rec = cached_record(root, args.record_tests, args.record_workers, refresh=args.refresh)
    rows = run_all(root, found, rec, args.jobs, args.budget, against=args.against,
                   entries=entries)
    if args.out:
        with open(args.out, "w") as fh:
            json.dump(rows, fh, indent=1)
    untriaged = report(rows, entries, everything)
    if args.toml and untriaged:
        with open(args.toml, "w") as fh:
            fh.write(toml_entries(untriaged))
    return 1 if untriaged else 0


if __name__ == "__main__":
    sys.exit(main())
