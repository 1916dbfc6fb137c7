"""tools/mutate.py: a fault's time bound scales with the unmutated run, and a stopped or timed
out run leaves none of its processes behind (pytest, its xdist workers, what they started).

Each test runs mutate.py on a tiny tree of its own (``--root``): one fault, one test that
records the pids of its pytest, its workers and a child it starts, and that hangs when told to
(``HANG=1``) or when the fault is applied."""
import importlib.util
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from waiting import BOUND, sigint_default, wait_for

ROOT = Path(__file__).resolve().parent.parent
MUTATE = ROOT / "tools" / "mutate.py"

pytest.importorskip("xdist")
if sys.version_info < (3, 11):
    pytest.skip("tools/mutate.py needs Python 3.11 (tomllib)", allow_module_level=True)

TREE = {
    "tools/mutations.toml": '[[fault]]\nid = "x-two"\nfile = "models/__init__.py"\n'
                            'find = "X = 1"\nreplace = "X = 2"\nwhy = "a fault that hangs"\n',
    "driftfmu/__init__.py": "import os\n__path__.append(os.path.dirname(os.path.dirname("
                            "os.path.abspath(__file__))))\n",
    "models/__init__.py": "X = 1\n",
    "fmu_src/__init__.py": "",
    "fmu_src/slave_base.py": "",
    "pytest.ini": "[pytest]\naddopts = -p xdist -n 2\n",
    # every pytest process of the run (the controller, both workers) records its pid
    "tests/conftest.py": "import os\nwith open(os.environ['PIDS'], 'a') as fh:\n"
                         "    fh.write('%d\\n' % os.getpid())\n",
    "tests/test_tiny.py": (
        "import os, subprocess, time\n"
        "import driftfmu.models as m\n\n"
        "def test_tiny():\n"
        "    if m.X == 1 and not os.environ.get('HANG'):\n"
        "        return\n"
        "    child = subprocess.Popen(['sleep', '600'])\n"
        "    with open(os.environ['PIDS'], 'a') as fh:\n"
        "        fh.write('%d\\n' % child.pid)\n"
        "    open(os.environ['PIDS'] + '.hanging', 'w').close()\n"
        "    time.sleep(600)\n"),
}


def _tree(tmp_path):
    root = tmp_path / "tree"
    for name, text in TREE.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def _alive(pid):
    """True while ``pid`` runs (a zombie, exited but not yet reaped, counts as gone)."""
    try:
        with open("/proc/%d/stat" % pid) as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def _mutate(tmp_path, *args, hang=False):
    pids = tmp_path / "pids"
    env = dict(os.environ, PIDS=str(pids), TMPDIR=str(tmp_path))
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("HANG", None)
    if hang:
        env["HANG"] = "1"
    p = subprocess.Popen([sys.executable, str(MUTATE), "--root", str(_tree(tmp_path)), *args],
                         env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=sigint_default)
    return p, pids


def _recorded(pids):
    return [int(line) for line in pids.read_text().split()] if pids.exists() else []


def _none_left(pids):
    """[] once every recorded process is gone (waited for up to :data:`waiting.BOUND`), else
    those still alive (killed, so that they do not outlive the test)."""
    def left():
        return [pid for pid in _recorded(pids) if _alive(pid)]
    try:
        wait_for(lambda: not left(), "end of the recorded processes", poll=0.1)
    except AssertionError:
        pass
    alive = left()
    for pid in alive:  # do not leave them to the next test either
        os.kill(pid, signal.SIGKILL)
    return alive


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
@pytest.mark.qualification  # runs of the mutation check itself
def test_a_signal_stops_the_running_tests_and_their_workers(signum, tmp_path):
    p, pids = _mutate(tmp_path, hang=True)
    try:
        # the baseline's test hangs
        wait_for(Path(str(pids) + ".hanging").exists, "the hanging test", p, poll=0.05)
        assert len(_recorded(pids)) == 4  # pytest, two workers, the test's child
        p.send_signal(signum)
        out, err = p.communicate(timeout=BOUND)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == 130, err
    assert err.strip().splitlines()[-1].startswith("mutate: stopped"), err
    assert _none_left(pids) == []
    assert not list(tmp_path.glob("driftfmu-mutate-*"))  # the copy is removed


@pytest.mark.qualification  # runs of the mutation check itself
def test_a_baseline_over_its_bound_is_killed_with_its_workers(tmp_path):
    p, pids = _mutate(tmp_path, "--baseline-timeout", "10", hang=True)
    out, err = p.communicate(timeout=BOUND)
    assert p.returncode == 2, err
    assert "over --baseline-timeout 10 s" in err
    # pytest, two workers, the test's child (fewer when a loaded machine is slower than 10 s)
    assert 1 <= len(_recorded(pids)) <= 4 and _none_left(pids) == []


@pytest.mark.qualification  # runs of the mutation check itself
def test_a_fault_that_hangs_times_out_and_is_killed_with_its_workers(tmp_path):
    p, pids = _mutate(tmp_path, "--timeout", "10")
    out, err = p.communicate(timeout=BOUND)
    assert p.returncode == 1, out + err
    assert "a fault may take 10 s" in out
    assert "x-two" in out and "TIMEOUT" in out
    # the baseline's pytest and workers (3), the fault's (3) and its hanging test's child
    # (fewer of the fault's when a loaded machine is slower than 10 s)
    assert 4 <= len(_recorded(pids)) <= 7 and _none_left(pids) == []


def test_the_bound_per_fault_scales_with_the_baseline():
    spec = importlib.util.spec_from_file_location("mutate", MUTATE)
    mutate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mutate)
    assert mutate.fault_timeout(10.0) == mutate.TIMEOUT_FLOOR
    assert mutate.fault_timeout(400.0) == mutate.TIMEOUT_FACTOR * 400.0 > 400.0
    assert mutate.fault_timeout(400.0, fixed=50.0) == 50.0


def test_a_bound_that_is_not_positive_is_a_usage_error(tmp_path):
    p = subprocess.run([sys.executable, str(MUTATE), "--timeout", "0"], capture_output=True,
                       text=True, timeout=BOUND)
    assert p.returncode == 2
    assert "--timeout 0.0: allowed: seconds > 0" in p.stderr.strip().splitlines()[-1]


def _tool(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / ("%s.py" % name))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_fault_of_the_list_matches_the_tree_and_names_tests_that_exist():
    """The list kept with the code (CI checks it before its short run; here in the loop): every
    pattern occurs once, every selection exists, and the general sensor's faults of issue 32
    are there, the C twin changed with the Python one where there is one, some in CI's list."""
    mutate = _tool("mutate")
    faults = mutate.load()
    assert mutate.check(faults) == []
    for f in faults:
        for t in f["tests"]:
            assert (ROOT / t.split("::")[0]).exists(), (f["id"], t)
    general = [f for f in faults if "test_evidence_general_" in " ".join(f["tests"])
               or "test_evidence_caches" in " ".join(f["tests"])]
    assert len(general) >= 30
    assert sum(f["short"] for f in general) >= 5
    twins = {"models/sensor.py": "sensor.c", "models/adxl203.py": "adxl203.c",
             "models/harmonic.py": "harmonic.c", "fmu_src/DriftEstimator.py":
             "DriftEstimator_step.c", "simulations/batch.py": "batch_kernel.c"}
    for f in general:
        if f["file"] in twins and f["id"] != "general-estimator-sample-predicts-without-u":
            assert any(a["file"].endswith(twins[f["file"]]) for a in f["also"]), f["id"]


def test_the_copy_leaves_out_the_virtual_environment_and_caches(tmp_path):
    mutate = _tool("mutate")
    root = tmp_path / "root"
    for name in ("models/a.py", ".venv/lib/big.so", ".hypothesis/constants/x", ".git/HEAD"):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text("x")
    tmp, copy = mutate.make_copy(str(root))
    try:
        assert sorted(p.name for p in Path(copy).iterdir()) == ["models"]
    finally:
        import shutil
        shutil.rmtree(tmp)




# ---------------------------------------------------------------- tools/mutation_survey.py

def test_the_survey_generates_each_kind_of_mutant(tmp_path):
    """Every operator, each mutant parses and differs; docstrings, signatures, f-strings and
    nested functions are not the function's own."""
    survey = _tool("mutation_survey")
    (tmp_path / "m.py").write_text(
        "import os\n\n"
        "def f(a, b, c=1.0):\n"
        '    """Docstring 2.0 is not mutated."""\n'
        "    if a != 0.0 and not b:\n"
        "        return g(a, b, c=c) + 2.0 * a - b\n"
        "    if a is None or a in (3, -b):\n"
        "        raise ValueError(f'{a + 7}')\n"
        "    os.unlink(b)\n"
        "    return h(a, b)\n\n"
        "def outer():\n"
        "    def inner():\n"
        "        return 5\n"
        "    return inner\n")
    found = survey.file_mutants(str(tmp_path), "m.py")
    assert {m["operator"] for m in found} == set(survey.OPERATORS)
    mutated = {(m["function"], m["operator"], m["mutated"]) for m in found}
    for expected in [("f", "compare", "a > 0.0"), ("f", "swap", "g(b, a, c=c)"),
                     ("f", "default", "g(a, b)"), ("f", "constant", "4.0"),
                     ("f", "drop", "g(a, b, c=c) + 2.0 * a"), ("f", "last", "h(a)"),
                     ("f", "boolean", "a != 0.0 or not b"), ("f", "not", "b"),
                     ("f", "return", "None"), ("f", "if", "True"), ("f", "if", "False"),
                     ("f", "delete", "pass"), ("f", "compare", "a is not None"),
                     ("f", "compare", "a not in (3, -b)"), ("f", "sign", "b"),
                     ("f", "offbyone", "4"), ("f", "offbyone", "2"),
                     ("outer.inner", "offbyone", "6"), ("outer", "return", "None")]:
        assert expected in mutated, expected
    assert not [m for m in found if m["function"] == "outer" and m["mutated"] in "456"]
    assert not [m for m in found if "7" in m["original"] and m["operator"] != "delete"]
    texts = set()
    for m in found:
        source = survey.mutant_source(str(tmp_path), m)
        compile(source, "m.py", "exec")
        assert "Docstring 2.0" in source and "c=1.0" in source
        texts.add(source)
    assert len(texts) == len(found)
    # the same text twice in one function: told apart by nth
    assert [m["nth"] for m in found if m["operator"] == "sign" and m["original"] == "-b"] == [1]


def _git(root, *args):
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=root,
                   check=True, capture_output=True)


def test_changed_picks_exactly_the_functions_whose_lines_differ(tmp_path):
    survey = _tool("mutation_survey")
    (tmp_path / "models").mkdir()
    before = ("def f(x):\n    return x + 1\n\n"
              "def g(x):\n    y = x * 2\n    return y\n\n"
              "class C:\n    def method(self):\n        a = 1\n        b = 2\n"
              "        return a + b\n\n"
              "def outer():\n    def inner():\n        return 3\n    return inner\n\n"
              "def last(x):\n    return x\n")
    (tmp_path / "models" / "m.py").write_text(before)
    (tmp_path / "models" / "same.py").write_text("def s():\n    return 1\n")
    _git(tmp_path, "init", "-q", "-b", "main")
    _git(tmp_path, "add", "-A")
    _git(tmp_path, "commit", "-q", "-m", "base")
    _git(tmp_path, "checkout", "-q", "-b", "change")
    after = (before.replace("y = x * 2", "y = x * 3")           # g: a changed line
             .replace("        a = 1\n", "")                     # C.method: a deleted line
             .replace("return 3", "return 4")                   # outer.inner, not outer
             + "\ndef new(x):\n    return -x\n")                # a new function
    (tmp_path / "models" / "m.py").write_text(after)
    _git(tmp_path, "commit", "-q", "-am", "change")
    (tmp_path / "models" / "untracked.py").write_text("def u():\n    return 2\n")
    changed = survey.changed_functions(str(tmp_path), "main")
    assert changed == {"models/m.py": {"g", "C.method", "outer.inner", "new"},
                       "models/untracked.py": {"u"}}
    # and only their mutants are surveyed
    found = survey.mutants(str(tmp_path), changed)
    assert {m["function"] for m in found} == {"g", "C.method", "outer.inner", "new", "u"}


def test_the_selection_is_the_tests_that_run_the_mutated_line():
    survey = _tool("mutation_survey")
    rec = {"tests": {"tests/test_a.py::t1": [True, False, 2.0],
                     "tests/test_a.py::t0": [True, False, 1.0],
                     "tests/test_b.py::slow": [True, True, 9.0],
                     "tests/test_a.py::broken": [False, False, 1.0],
                     "tests/test_native_models.py::bits": [True, False, 1.0]},
           "lines": {"models/m.py": {"3": ["tests/test_a.py::t1", "tests/test_a.py::t0",
                                           "tests/test_b.py::slow", "tests/test_a.py::broken",
                                           "tests/test_native_models.py::bits"],
                                     "5": ["tests/test_b.py::slow"]}}}
    m = dict(file="models/m.py", lines=[3, 3])
    # fastest first, integration apart, a failing test and the twins' bits never
    assert survey.selection(rec, m) == (["tests/test_a.py::t0", "tests/test_a.py::t1"],
                                        ["tests/test_b.py::slow"])
    assert survey.selection(rec, dict(m, lines=[5, 6])) == ([], ["tests/test_b.py::slow"])
    assert survey.selection(rec, dict(m, lines=[4, 4])) == ([], [])


def test_the_test_a_triage_entry_names_runs_first_though_the_record_missed_it():
    """A line that a test runs only in a worker process (the experiments' FMU runs) is not in
    the record: the test the triage entry names is run anyway, first."""
    survey = _tool("mutation_survey")
    named = dict(verdict="test", test="tests/test_d.py::through_the_fmus")
    assert survey.with_named_test(["tests/test_a.py::t0"], named) == [
        "tests/test_d.py::through_the_fmus", "tests/test_a.py::t0"]
    assert survey.with_named_test([], named) == ["tests/test_d.py::through_the_fmus"]
    assert survey.with_named_test(["tests/test_d.py::through_the_fmus"], named) == [
        "tests/test_d.py::through_the_fmus"]  # not twice
    assert survey.with_named_test(["t"], dict(verdict="equivalent", reason="r")) == ["t"]
    assert survey.with_named_test(["t"], None) == ["t"]


def test_an_fmus_bundled_copy_is_mapped_to_the_trees_file():
    survey = _tool("mutation_survey")
    name = survey._tree_name
    assert name("/tmp/x/tree/models/ekf.py", "/tmp/x/tree") == "models/ekf.py"
    assert name("/tmp/x/tree/tests/test_a.py", "/tmp/x/tree") is None
    assert name("/tmp/fmu1/resources/drift_0123456789/models/ekf.py", "/t") == "models/ekf.py"
    assert name("/tmp/fmu1/resources/drift_0123456789/Accelerometer.py", "/t") == \
        "fmu_src/Accelerometer.py"
    assert name("/tmp/fmu1/resources/drift_0123456789/slave_base.py", "/t") == \
        "fmu_src/slave_base.py"
    assert name("/tmp/fmu1/resources/drift_0123456789/__init__.py", "/t") is None


SURVEY_TREE = {
    "driftfmu/__init__.py": TREE["driftfmu/__init__.py"],
    "models/__init__.py": "",
    "models/calc.py": ("def add(a, b):\n    return a + b\n\n\n"
                       "def half(x):\n    if x > 10:\n        return x / 2\n    return x\n"),
    "pyproject.toml": "[tool.pytest.ini_options]\ntestpaths = ['tests']\n",
    "tests/test_calc.py": ("from driftfmu.models.calc import add, half\n\n"
                           "def test_add():\n    assert add(2, 3) == 5\n\n"
                           "def test_half():\n    assert half(4) == 4\n"),
}


def _survey_tree(tmp_path):
    root = tmp_path / "tree"
    for name, text in SURVEY_TREE.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    (root / "tools").mkdir()
    (root / "tools" / "survey_coverage.py").write_text(
        (ROOT / "tools" / "survey_coverage.py").read_text())
    return root


def _run_survey(tmp_path, root, *args):
    env = dict(os.environ, DRIFTFMU_SURVEY_CACHE=str(tmp_path / "cache"))
    env.pop("PYTEST_XDIST_WORKER", None)
    return subprocess.run([sys.executable, str(ROOT / "tools" / "mutation_survey.py"), "--root",
                           str(root), "--record-workers", "0", *args], env=env,
                          capture_output=True, text=True, timeout=BOUND * 4)


@pytest.mark.qualification  # runs of the survey itself
def test_a_survivor_is_untriaged_until_the_triage_file_names_it(tmp_path):
    """A planted survivor (``half``'s ``x > 10``: the test only tries 4) is reported untriaged
    and the survey exits 1; triaged as equivalent it exits 0; triaged as caught by a test
    (which does not catch it) it is untriaged again; an entry of no mutant is stale."""
    root = _survey_tree(tmp_path)
    p = _run_survey(tmp_path, root, "--toml", str(tmp_path / "new.toml"))
    assert p.returncode == 1, p.stdout + p.stderr
    assert "UNTRIAGED models/calc.py:half:6 compare: x > 10 -> x >= 10" in p.stdout
    assert "UNTRIAGED models/calc.py:half:7 return: x / 2 -> None (no test runs this line)" \
        in p.stdout
    assert "UNTRIAGED models/calc.py:add" not in p.stdout  # test_add catches every one
    # the record: add's statement is run by test_add alone, half's test by test_half alone,
    # half's return x / 2 by no test
    import json
    survey = _tool("mutation_survey")
    (record,) = (tmp_path / "cache").glob("*.json")
    rec = json.loads(record.read_text())
    found = {(m["function"], m["line"]): m for m in survey.mutants(str(root))}
    assert survey.selection(rec, found["add", 2]) == (["tests/test_calc.py::test_add"], [])
    assert survey.selection(rec, found["half", 6]) == (["tests/test_calc.py::test_half"], [])
    assert survey.selection(rec, found["half", 7]) == ([], [])
    # the entries to fill in: all of them equivalent, one stale entry besides
    entries = (tmp_path / "new.toml").read_text().replace(
        'verdict = "?"\nreason = ""', 'verdict = "equivalent"\nreason = "planted"')
    stale = ('[[survivor]]\nfile = "models/calc.py"\nfunction = "add"\noperator = "sign"\n'
             'original = "a * b"\nmutated = "a / b"\nverdict = "equivalent"\nreason = "x"\n')
    (root / "tools" / "survivors.toml").write_text(entries + "\n" + stale)
    p = _run_survey(tmp_path, root)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "UNTRIAGED" not in p.stdout
    assert "STALE triage entry: models/calc.py:add sign: a * b -> a / b" in p.stdout
    assert "(cached)" in p.stdout  # the record is made once per tree
    # an entry that says a test catches it, when none does: untriaged (a regression)
    (root / "tools" / "survivors.toml").write_text(entries.replace(
        'verdict = "equivalent"\nreason = "planted"\n', 'verdict = "test"\n'
        'test = "tests/test_calc.py::test_half"\n', 1))
    p = _run_survey(tmp_path, root, "--function", "models/calc.py:half")
    assert p.returncode == 1, p.stdout + p.stderr
    assert "which no longer catches it" in p.stdout
    # a test that runs the line where the record cannot see it (a forked process, as a
    # pool's worker), named by
    # the entry of the mutant no recorded test reaches: run, and it catches the mutant
    (root / "tests" / "test_other.py").write_text(
        "import os\nfrom driftfmu.models.calc import half\n\ndef test_half_big():\n"
        "    pid = os.fork()\n    if pid == 0:\n        os._exit(0 if half(20) == 10 else 1)\n"
        "    assert os.waitpid(pid, 0)[1] == 0\n")
    unseen = entries.split("[[survivor]]")
    unseen = "".join("[[survivor]]" + e.replace(
        'verdict = "equivalent"\nreason = "planted"\n',
        'verdict = "test"\ntest = "tests/test_other.py::test_half_big"\n')
        if 'original = "x / 2"' in e else ("[[survivor]]" + e if e.strip() else e)
        for e in unseen)
    (root / "tools" / "survivors.toml").write_text(unseen)
    p = _run_survey(tmp_path, root, "--function", "models/calc.py:half")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "no test runs this line" not in p.stdout


@pytest.mark.qualification  # a run of the survey itself
def test_the_record_names_the_tests_that_failed_under_coverage(tmp_path):
    """A test that fails while the record is made is named in the survey's output (its lines
    then count as reached by no test) and selected for no mutant; one that passes is not
    named."""
    root = _survey_tree(tmp_path)
    (root / "tests" / "test_bad.py").write_text(
        "from driftfmu.models.calc import add\n\ndef test_bad():\n    assert add(1, 1) == 3\n")
    p = _run_survey(tmp_path, root, "--function", "models/calc.py:add")
    out = p.stdout + p.stderr
    assert "survey: failed under coverage, so not used: tests/test_bad.py::test_bad" in out, out
    assert "test_calc.py::test_add" not in out.split("failed under coverage")[1].split("\n")[0]
    import json
    (record,) = (tmp_path / "cache").glob("*.json")
    rec = json.loads(record.read_text())
    assert rec["tests"]["tests/test_bad.py::test_bad"][0] is False
    assert rec["tests"]["tests/test_calc.py::test_add"][0] is True


def test_a_malformed_triage_entry_is_refused(tmp_path):
    survey = _tool("mutation_survey")
    path = tmp_path / "s.toml"
    path.write_text('[[survivor]]\nfile = "models/calc.py"\nfunction = "f"\n'
                    'operator = "sign"\noriginal = "a + b"\nmutated = "a - b"\n'
                    'verdict = "equivalent"\n')
    with pytest.raises(SystemExit, match="equivalent without a reason"):
        survey.load_triage(str(path))
    path.write_text(path.read_text().replace('"equivalent"', '"maybe"'))
    with pytest.raises(SystemExit, match="allowed: equivalent, test"):
        survey.load_triage(str(path))


def test_the_triage_file_of_the_tree_is_well_formed_and_has_no_stale_entry():
    p = subprocess.run([sys.executable, str(ROOT / "tools" / "mutation_survey.py"),
                        "--check-triage"], capture_output=True, text=True, timeout=BOUND)
    assert p.returncode == 0, p.stdout + p.stderr


def test_the_sample_seed_is_the_release_base_and_is_required(tmp_path):
    """CI's order of the survey's mutants is drawn from ``--sample-seed``: the triage file's
    [release] base, whatever the tree holds; a triage file without one is refused."""
    root = _survey_tree(tmp_path)

    def seed(text):
        (root / "tools" / "survivors.toml").write_text(text)
        return subprocess.run([sys.executable, str(ROOT / "tools" / "mutation_survey.py"),
                               "--root", str(root), "--sample-seed"], capture_output=True,
                              text=True, timeout=BOUND)

    p = seed('[release]\nbase = "0123abc"\n')
    assert (p.returncode, p.stdout) == (0, "0123abc\n"), p.stderr
    p = seed('[release]\nbase = "4567def"\n')
    assert (p.returncode, p.stdout) == (0, "4567def\n"), p.stderr
    p = seed("")
    assert p.returncode == 2 and p.stdout == "", p.stdout
    assert p.stderr.strip() == "survey: the triage file has no [release] base", p.stderr


def test_a_run_whose_tests_pass_but_leave_files_does_not_catch_a_mutant():
    """tests/conftest.py fails a run that leaves files in its temporary folder; for the survey
    and the fault list a mutant is caught by a test that fails, not by that line."""
    survey = _tool("mutation_survey")
    left = ("3 passed in 1.0s\n\nERROR: the tests left 2 file(s) or folder(s) in the temporary "
            "folder (TMPDIR): a, b\n")
    assert survey._result(1, left) == ("passed", None)
    failed = "FAILED tests/test_x.py::test_y - boom\n1 failed, 2 passed\n" + left
    assert survey._result(1, failed) == ("failed", "tests/test_x.py::test_y")
    assert survey._result(1, "INTERNALERROR> boom\n")[0] == "error"
    assert left.splitlines()[-1].startswith(survey.LEFT_BEHIND)
    conftest = (ROOT / "tests" / "conftest.py").read_text()
    assert 'sys.stderr.write("\\n' + survey.LEFT_BEHIND in conftest


def test_against_a_parametrised_tests_function_runs_every_case_of_it_and_nothing_else():
    """--against names tests as paths or node ids; the node id of a parametrised test's
    function names each of its cases (it selected none before, and every mutant passed);
    a case's own id names that case alone; other tests are deselected."""
    survey = _tool("mutation_survey")

    class Item:
        def __init__(self, nodeid):
            self.nodeid = nodeid

    class Hook:
        deselected = []

        def pytest_deselected(self, items):
            self.deselected += [it.nodeid for it in items]

    class Config:
        hook = Hook()

    names = ["t.py::test_f[a]", "t.py::test_f[b]", "t.py::test_g", "t.py::test_ff[a]",
             "u.py::test_f[a]"]
    for ids, kept in ((["t.py::test_g", "t.py::test_f"],
                       ["t.py::test_g", "t.py::test_f[a]", "t.py::test_f[b]"]),
                      (["t.py::test_f[b]"], ["t.py::test_f[b]"]),
                      (["t.py::test_f[a]", "t.py::test_g"], ["t.py::test_f[a]", "t.py::test_g"])):
        items, config = [Item(n) for n in names], Config()
        config.hook.deselected = []
        survey._Only(ids).pytest_collection_modifyitems(config, items)
        assert [it.nodeid for it in items] == kept, ids
        assert sorted(config.hook.deselected) == sorted(set(names) - set(kept))


@pytest.mark.parametrize("limit", ["0", "-1"])
def test_a_limit_below_one_is_refused_in_one_line(tmp_path, limit):
    root = _survey_tree(tmp_path)
    p = _run_survey(tmp_path, root, "--limit", limit)
    assert p.returncode == 2, p.stdout + p.stderr
    assert p.stderr.strip() == "survey: --limit %s: allowed: 1 or more" % limit, p.stderr
