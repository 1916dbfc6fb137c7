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
pytestmark = pytest.mark.qualification  # runs of the mutation check itself
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


def test_a_baseline_over_its_bound_is_killed_with_its_workers(tmp_path):
    p, pids = _mutate(tmp_path, "--baseline-timeout", "10", hang=True)
    out, err = p.communicate(timeout=BOUND)
    assert p.returncode == 2, err
    assert "over --baseline-timeout 10 s" in err
    # pytest, two workers, the test's child (fewer when a loaded machine is slower than 10 s)
    assert 1 <= len(_recorded(pids)) <= 4 and _none_left(pids) == []


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


def test_the_survey_generates_each_kind_of_mutant(tmp_path):
    """tools/mutation_survey.py: a changed constant, a sign, a dropped term, a comparison, two
    arguments swapped, a keyword or a last argument left out; each mutant parses and differs."""
    survey = _tool("mutation_survey")
    (tmp_path / "m.py").write_text(
        "def f(a, b, c=1.0):\n"
        '    """Docstring 2.0 is not mutated."""\n'
        "    if a != 0.0:\n"
        "        return g(a, b, c=c) + 2.0 * a - b\n"
        "    return h(a, b)\n")
    found = survey.mutants(str(tmp_path), (("m.py", "f"),))
    kinds = {m["operator"] for m in found}
    assert kinds == {"constant", "sign", "drop", "compare", "swap", "default", "last"}, kinds
    texts = [m["source"] for m in found]
    assert len(set(texts)) == len(texts)
    for m in found:
        compile(m["source"], "m.py", "exec")
        assert "Docstring 2.0" in m["source"]
    mutated = {(m["operator"], m["mutated"]) for m in found}
    assert ("compare", "a > 0.0") in mutated and ("swap", "g(b, a, c=c)") in mutated
    assert ("default", "g(a, b)") in mutated and ("constant", "4.0") in mutated
    assert ("drop", "g(a, b, c=c) + 2.0 * a") in mutated and ("last", "h(a)") in mutated
