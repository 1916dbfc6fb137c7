"""The Python API has every guard the command line has (issue 31), with the same lines.

Sizes that cannot fit are refused before anything is allocated; a keyword a function does not
take is one line naming the function and every keyword it takes; text and True/False are not
numbers; ``identify`` takes one path as one recording; an error says its reason once, with no
file name that has nothing to do with it (issue 30).  The table at the end gives the command
line and the API the same bad settings and compares their lines."""
import json
import math
import os
import re
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import driftfmu
from driftfmu.simulations import budget
from driftfmu.simulations.cli import main
from driftfmu.simulations.errors import UnknownKeywordError, UsageError

ROOT = Path(__file__).resolve().parent.parent


def _recording(path, f=150.0, Ts=1e-3, n=2000, a2=0.01, seed=1):
    """A small CSV recording ``time, x, z`` of a sinusoid at ``f`` through a quadratic sensor."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * Ts
    x = np.sin(2 * np.pi * f * t + 0.3)
    z = 0.1 + x + a2 * x * x + 1e-3 * rng.standard_normal(n)
    np.savetxt(path, np.c_[t, x, z], delimiter=",", header="time,x,z", comments="",
               fmt="%.17g")
    return path


# -- sizes: refused before anything is allocated -------------------------------------------------

#: Calls whose size cannot fit any machine: each must be refused at once with an estimate.
HUGE = {
    "montecarlo": "driftfmu.montecarlo(runs=10**9, n=1000)",
    "montecarlo_summary_only": "driftfmu.montecarlo(runs=10**11, n=1000, summary_only=True)",
    "montecarlo_sinusoidal": "driftfmu.montecarlo('sinusoidal', runs=10**9, n=1000)",
    "dual_axis_batch": "driftfmu.experiment_dual_axis(runs=10**9, engine='batch')",
    "dual_axis_fmu": "driftfmu.experiment_dual_axis(runs=10**5, n=10**6)",
    "run_gaussian": "driftfmu.run_gaussian(n=10**10)",
    "run_sinusoidal": "driftfmu.run_sinusoidal(n=10**10)",
    "sweep": "driftfmu.sweep(runs=10**10)",
    "adxl203": "driftfmu.experiment_adxl203(n=10**10)",
    "identify": "driftfmu.identify('../huge.csv', f=150.0)",
}


@pytest.fixture(scope="module")
def huge(tmp_path_factory):
    """What each call of :data:`HUGE` raised, run in one process whose address space is capped
    at 3 GB, each call stopped after 30 s of processor time (a call that allocated its size
    fails there with a MemoryError, one that started running is stopped: a missing check
    cannot fill the machine's memory or run for ever); ``huge.csv`` is a sparse file of 50 GB,
    which takes no room on the disk."""
    d = tmp_path_factory.mktemp("huge")
    with open(d / "huge.csv", "wb") as fh:
        fh.truncate(50 * 10 ** 9)
    script = (
        "import json, os, resource, signal, sys\n"
        "for limit, value in ((resource.RLIMIT_AS, 3 * 10**9), (resource.RLIMIT_CPU, 600)):\n"
        "    hard = resource.getrlimit(limit)[1]\n"
        "    resource.setrlimit(limit, (value if hard == resource.RLIM_INFINITY\n"
        "                               else min(value, hard), hard))\n"
        "def running(signum, frame):\n"
        "    raise TimeoutError('still running after 30 s of processor time')\n"
        "signal.signal(signal.SIGPROF, running)\n"
        "import driftfmu\n"
        "out = {}\n"
        "for name, call in json.loads(sys.argv[1]).items():\n"
        "    os.mkdir(name)\n"
        "    os.chdir(name)  # what the call makes, it makes there\n"
        "    signal.setitimer(signal.ITIMER_PROF, 30)  # one call that runs stops alone\n"
        "    try:\n"
        "        eval(call)\n"
        "        out[name] = ['returned', '']\n"
        "    except BaseException as exc:\n"
        "        out[name] = [type(exc).__name__, str(exc)]\n"
        "    signal.setitimer(signal.ITIMER_PROF, 0)\n"
        "    os.chdir('..')\n"
        "print(json.dumps(out))\n")
    r = subprocess.run([sys.executable, "-c", script, json.dumps(HUGE)], cwd=d,
                       capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1]), d


@pytest.mark.parametrize("name", sorted(HUGE))
def test_a_size_that_cannot_fit_is_refused_before_it_allocates(name, huge):
    """``montecarlo(runs=10**9, n=1000)`` grew to 23 GB until the kernel killed it (a raw
    MemoryError under a memory limit), ``run_gaussian(n=10**10)`` started running: now one
    line with the estimate and what fits, and nothing made (no FMUs built, no folder)."""
    results, folder = huge
    kind, text = results[name]
    assert kind == "UsageError", (kind, text)
    assert "\n" not in text and " needs about " in text and "allowed: a run that fits" in text
    assert os.listdir(folder / name) == []  # no FMUs built, nothing written


def _small_machine(monkeypatch):
    """A machine of 1 MB for the size checks, where the command itself takes nothing: a run
    over 0.8 MB is refused, and one that is not (a check missing) is still a small run."""
    monkeypatch.setattr(budget, "available_memory", lambda: 1e6)
    monkeypatch.setattr(budget, "BASE_MEMORY", 0)


@pytest.mark.parametrize("command", ["gaussian", "sinusoidal"])
def test_a_long_api_run_writes_no_note_to_standard_error(command, monkeypatch, capsys):
    """The command announces a long run with a ``driftfmu: note:`` line; the function does not
    (its caller reports through ``progress``); the run itself is left out (a stand-in)."""
    from driftfmu.simulations import gaussian, sinusoidal
    monkeypatch.setattr(budget, "RUN_SECONDS", {"python": 1.0, "native": 1.0})  # 1000 s
    monkeypatch.setattr(gaussian, "run_gaussian", lambda **kw: "ran")
    monkeypatch.setattr(sinusoidal, "run_sinusoidal", lambda **kw: "ran")
    budget.check_run(command, 1000, None)
    assert capsys.readouterr().err.startswith("driftfmu: note: run %s --n 1000: " % command)
    assert getattr(driftfmu, "run_" + command)(n=1000) == "ran"
    assert capsys.readouterr().err == ""


def test_the_api_names_its_keywords_and_the_command_line_its_options(monkeypatch):
    """One estimate for both; each says how to proceed in its own spelling."""
    _small_machine(monkeypatch)
    with pytest.raises(UsageError) as api:
        driftfmu.montecarlo(runs=100, n=100)
    assert str(api.value) == (
        "montecarlo('gaussian', runs=100, n=100) needs about 1.2 MB of memory; this machine "
        "has 1 MB of memory available; allowed: a run that fits: at most runs=66 at n=100; or "
        "summary_only=True, which keeps per-run summaries instead of trajectories; or fewer "
        "runs or a smaller n")
    with pytest.raises(UsageError) as cli:
        budget.check_montecarlo("gaussian", 100, 100, None, None)
    assert str(cli.value).startswith("montecarlo gaussian --runs 100 --n 100 needs about 1.2 MB "
                                     "of memory; this machine has 1 MB of memory available; "
                                     "allowed: a run that fits: at most --runs 66 at --n 100; "
                                     "or --summary-only, which keeps")


# -- keywords ---------------------------------------------------------------------------------

#: (function, bad keywords, the call as the line names it, keywords the line must list).
KEYWORDS = [
    ("run_gaussian", dict(n=10, a2x=1), "run_gaussian()",
     "out n backend fmu_dir progress a0 a1 a2 A Q R seed Ts x0 P0 estimator a3 a4 B drive Qu "
     "Xu fu"),
    ("run_sinusoidal", dict(bogus=1), "run_sinusoidal()",
     "out n backend fmu_dir progress X f phi Ts seed a0 a1 a2 R process Qh A Q P0 x0 estimator "
     "preset sensor Xy phiy B drive Qu Xu fu"),
    ("montecarlo", dict(a5=1), "montecarlo('gaussian')",
     "kind runs n out engine progress a0 a1 a2 A Q R seed Ts x0 P0 scheduler client workers "
     "fmu_dir backend summary_only a3 a4 B drive Qu Xu fu"),
    ("montecarlo", dict(kind="sinusoidal", P0=1.0), "montecarlo('sinusoidal')",
     "kind runs n out engine progress a0 a1 a2 R X f Ts seed A Q scheduler client workers "
     "fmu_dir backend summary_only a3 a4"),
    ("sweep", dict(bogus=1), "sweep()",
     "a2 R runs n out progress a0 a1 Q A seed Ts engine scheduler client workers chunk fmu_dir "
     "a4 a3 B drive Qu Xu fu"),
    ("experiment_adxl203", dict(bogus=1), "experiment_adxl203()",
     "out progress freqs sets held_out n Ts seed fmu_dir workers backend order"),
    ("experiment_dual_axis", dict(bogus=1), "experiment_dual_axis()",
     "out progress points runs engine seed fmu_dir workers scheduler backend n Ts f X Xy phi A "
     "Q Qy a0 a1 a2 bx R a0y a1y a2y by Ry Qh"),
    ("identify", dict(files=["a.csv"], f=150.0, bogus=1), "identify()",
     "files f held_out out order"),
    ("allan", dict(column="z", tau=[1.0]), "allan()",
     "source column time taus per_decade out unit stop_time start_values backend fmu_dir "
     "progress"),
    ("simulate", dict(stop_time=1.0, bogus=1), "simulate()",
     "fmus stop_time step_size start_values input output backend fmi_version fmu_dir "
     "start_time"),
    ("build_fmus", dict(nmes=["Excitation"]), "build_fmus()",
     "out_dir backend fmi_version names log cross_check ssp cache"),
]


@pytest.mark.parametrize("name, kwargs, call, listed", KEYWORDS,
                         ids=["%s-%s" % (k[0], "-".join(k[1])) for k in KEYWORDS])
def test_an_unknown_keyword_names_the_function_and_every_keyword_it_takes(
        name, kwargs, call, listed, tmp_path, monkeypatch):
    """``run_gaussian(n=10, a2x=1)`` raised a bare KeyError, ``montecarlo(a5=1)`` listed only
    ``a3, a4, B, drive, Qu, Xu, fu``, ``experiment_adxl203(bogus=1)`` named an internal
    function; Python's own TypeError lists nothing."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UnknownKeywordError) as info:
        getattr(driftfmu, name)(**kwargs)
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)
    text = str(info.value)
    assert "\n" not in text and text.startswith("%s got an unexpected keyword argument" % call)
    allowed = text.split("; allowed: ")[1].split(", ")
    assert set(listed.split()) <= set(allowed), set(listed.split()) - set(allowed)
    assert os.listdir(tmp_path) == []


def test_a_misspelt_keyword_gets_its_closest_name():
    with pytest.raises(TypeError, match=r"'a2x' \(did you mean 'a2'\?\); allowed: out, n,"):
        driftfmu.run_gaussian(n=10, a2x=1)


def test_the_signatures_stay_the_functions_own():
    import inspect
    assert list(inspect.signature(driftfmu.identify).parameters) == ["files", "f", "held_out",
                                                                     "out", "order"]
    assert driftfmu.simulate.__name__ == "simulate" and "Co-simulate" in \
        driftfmu.simulate.__doc__


# -- types: text and True/False are not numbers --------------------------------------------------

#: Small runs: were a check missing, the call would run briefly, not for minutes.
SMALL_MC = dict(runs=2, n=10)
SMALL_SWEEP = dict(a2=[0.01], R=[1e-4], runs=2, n=10)
SMALL_ADXL = dict(freqs=[100.0], sets=3, n=600)
SMALL_DUAL = dict(points=2, runs=1, n=50)

@pytest.mark.parametrize("name, kwargs, said", [
    ("run_gaussian", dict(n=True), "n = True is not a number; allowed: an integer n >= 1"),
    ("run_gaussian", dict(n=2.0), "n = 2.0 is not an integer; allowed: an integer n >= 1"),
    ("run_gaussian", dict(n=10, seed=1.5), "seed = 1.5 is not an integer"),
    ("run_gaussian", dict(n=10, estimator=True), "estimator = True is not allowed; allowed: 1, "
                                                 "2, 3"),
    ("run_gaussian", dict(n=10, progress=5), "progress = 5 is not callable"),
    ("run_sinusoidal", dict(f="150"), "f = '150' is not a number; allowed: 0 < f < 1/(2 Ts)"),
    ("run_sinusoidal", dict(sensor={"a5": 1.0}), "sensor has 'a5'; allowed: a0, a1, a2, a3"),
    ("run_sinusoidal", dict(sensor={"fc": "x"}), "fc = 'x' is not a number"),
    ("montecarlo", dict(runs="10"), "runs = '10' is not a number; allowed: an integer runs >= 1"),
    ("montecarlo", dict(runs=True), "runs = True is not a number"),
    ("montecarlo", dict(SMALL_MC, summary_only="yes"), "summary_only = 'yes' is not allowed; "
                                                       "allowed: True or False"),
    ("montecarlo", dict(SMALL_MC, workers=0), "workers = 0 is out of range; allowed: "
                                              "an integer workers >= 1"),
    ("montecarlo", dict(SMALL_MC, engine="gpu"), "engine = 'gpu' is not allowed; allowed: "
                                                 "'batch', 'fmu'"),
    ("sweep", dict(SMALL_SWEEP, a2=["0.1"]), "a2 = '0.1' is not a number; allowed: any finite "
                                             "value"),
    ("sweep", dict(SMALL_SWEEP, R=[True]), "R = True is not a number; allowed: R > 0"),
    ("sweep", dict(SMALL_SWEEP, chunk=2.5), "chunk = 2.5 is not an integer; allowed: "
                                            "an integer chunk >= 1"),
    ("experiment_adxl203", dict(SMALL_ADXL, sets="6"), "sets = '6' is not an integer; "
                                                       "allowed: an integer sets >= 1"),
    ("experiment_adxl203", dict(SMALL_ADXL, freqs=["100"]), "freqs has '100', which is not a "
                                                            "number"),
    ("experiment_adxl203", dict(SMALL_ADXL, freqs="100,150"), "freqs = '100,150' is not "
                                                              "allowed"),
    ("experiment_adxl203", dict(SMALL_ADXL, order=True), "order = True is not allowed; "
                                                         "allowed: 2, 3, 4"),
    ("experiment_dual_axis", dict(SMALL_DUAL, points=True), "points = True is not an integer"),
    ("experiment_dual_axis", dict(SMALL_DUAL, runs=1.0), "runs = 1.0 is not an integer"),
    ("identify", dict(files=["a.csv"], f="150"), "f = '150' is not a number"),
    ("identify", dict(files=["a.csv"], f=150.0, held_out=True), "held_out = True is not an "
                                                                "integer"),
    ("identify", dict(files=["a.csv"], f=150.0, order=5), "order = 5 is not allowed; "
                                                          "allowed: 2, 3, 4"),
    ("identify", dict(files=5, f=150.0), "files = 5 is not allowed"),
    ("identify", dict(files=[], f=150.0), "files = [] is empty"),
    ("identify", dict(files=[None], f=150.0), "files[0] = None is not a path"),
    ("build_fmus", dict(names="Excitation"), "names = 'Excitation' is not allowed; allowed: "
                                             "a sequence of FMU names"),
    ("build_fmus", dict(fmi_version=2.0), "fmi_version = 2.0 is not allowed; allowed: 2"),
    ("build_fmus", dict(out_dir=""), "out_dir = '' is empty"),
    ("simulate", dict(output="z"), "output = 'z' is not allowed; allowed: a sequence"),
    ("simulate", dict(stop_time=1e300, step_size=1e-300), "more communication points than "
                                                          "can be counted"),
])
def test_a_value_of_the_wrong_type_is_refused_before_anything_runs(name, kwargs, said,
                                                                   tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError) as info:
        getattr(driftfmu, name)(**kwargs)
    text = str(info.value)
    assert "\n" not in text and said in text, text
    assert os.listdir(tmp_path) == []  # nothing built, nothing written


@pytest.mark.parametrize("name, kwargs", [
    ("run_gaussian", dict(n=10)), ("montecarlo", SMALL_MC), ("experiment_dual_axis", SMALL_DUAL),
    ("experiment_adxl203", SMALL_ADXL), ("sweep", SMALL_SWEEP), ("run_sinusoidal", dict(n=10))])
def test_out_that_is_a_file_or_empty_is_refused_before_anything_runs(name, kwargs, tmp_path,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.txt").write_text("keep")
    for out, said in (("mine.txt", "out = mine.txt is an existing file"),
                      ("", "out = '' is empty; allowed: a folder path"),
                      (5, "out = 5 is not a path")):
        with pytest.raises(ValueError, match=re.escape(said)):
            getattr(driftfmu, name)(out=out, **kwargs)
    assert os.listdir(tmp_path) == ["mine.txt"] and (tmp_path / "mine.txt").read_text() == "keep"


# -- identify -----------------------------------------------------------------------------------

def test_identify_takes_one_path_as_one_recording(tmp_path):
    """``identify("results.csv", f=150)`` read the string letter by letter ("/: cannot be read
    (Is a directory)").  One recording is enough for a fit (the spread needs two)."""
    path = _recording(tmp_path / "rec.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        as_list = driftfmu.identify([str(path)], f=150.0)
        for one in (str(path), path):
            assert driftfmu.identify(one, f=150.0)["model"] == as_list["model"]
    with pytest.raises(ValueError, match=r"1 file\(s\) with 1 held out; allowed: 0 <= held_out "
                                         "< number of files"):
        driftfmu.identify(path, f=150.0, held_out=1)


def test_identify_refuses_an_order_before_reading_a_file(tmp_path):
    """``identify(order=5)`` said "a.csv: order = 5; allowed: 2, 3, 4" (after reading the
    file), and an order that aliases named the file too."""
    with pytest.raises(UsageError) as info:
        driftfmu.identify([str(tmp_path / "missing.csv")], f=150.0, order=5)
    assert str(info.value) == "order = 5 is not allowed; allowed: 2, 3, 4"
    path = _recording(tmp_path / "rec.csv")
    with pytest.raises(UsageError) as info:
        driftfmu.identify(path, f=150.0, order=4)
    text = str(info.value)
    assert text.startswith("order 4 needs harmonic 4 of f = 150 Hz, 600 Hz, below the Nyquist "
                           "rate 1/(2 Ts) = 500 Hz") and str(path) not in text, text


def test_identify_warns_at_the_callers_line(tmp_path):
    """A doubt about the fit was reported at a line of driftfmu/_api.py."""
    path = _recording(tmp_path / "rec.csv")
    with pytest.warns(UserWarning, match="the model comes from one recording") as caught:
        driftfmu.identify(path, f=150.0)
    assert {w.filename for w in caught} == {__file__}


def test_experiment_adxl203_holds_out_a_sixth_of_the_sets_by_default(monkeypatch):
    """The API held out 5 sets whatever ``sets`` was (``sets=6`` was refused); the command
    line's default is a sixth, at least 1, as the docstring says."""
    import functools
    from driftfmu.simulations import adxl203
    seen = {}
    monkeypatch.setattr(adxl203, "run_adxl203", functools.wraps(adxl203.run_adxl203)(
        lambda **kw: seen.update(kw)))
    driftfmu.experiment_adxl203(sets=6, n=600, freqs=[100.0])
    assert seen["held_out"] == 1
    driftfmu.experiment_adxl203(sets=30, n=600, freqs=[100.0])
    assert seen["held_out"] == 5


# -- an FMU's error says its reason once --------------------------------------------------------

class _Logged:
    def __init__(self, *messages):
        self.messages = list(messages)


@pytest.mark.parametrize("call, entry, first", [
    ("fmi2ExitInitializationMode failed with status 3 (error).",
     "Excitation [error] Excitation: f = 600.0 Hz is at or above the Nyquist rate",
     "fmi2ExitInitializationMode failed with status 3 (error): Excitation: f = 600.0 Hz is at "
     "or above the Nyquist rate"),
    ("fmi3ExitInitializationMode failed with status 3 (error).",
     "Excitation [error] fmi3ExitInitializationMode: f = 600.0 Hz is at or above",
     "fmi3ExitInitializationMode failed with status 3 (error): Excitation: f = 600.0 Hz is at "
     "or above"),
    ("DriftEstimator: reading outputs at communication point 0 (step 0.001 s) failed",
     "DriftEstimator [error] fmi2GetReal: dc_ekf1 would not be finite",
     "DriftEstimator: reading outputs at communication point 0 (step 0.001 s) failed: "
     "fmi2GetReal: dc_ekf1 would not be finite"),
])
def test_a_failed_call_says_the_fmus_reason_once(call, entry, first):
    """The line was "... (error): Excitation [error] Excitation: f = ..." and the same sentence
    again on the next line; what else the FMUs logged still follows."""
    from driftfmu.simulations.cosim import failed
    text = str(failed(RuntimeError(call), {"x": _Logged("x [info] started", entry)}))
    assert text.splitlines() == [first, "  x [info] started"]


@pytest.mark.integration
@pytest.mark.parametrize("backend, fmi_version", [("python", 2), ("native", 2), ("native", 3)])
def test_the_nyquist_error_of_an_fmu_is_one_line(backend, fmi_version, python_fmus,
                                                  native_fmus, tmp_path):
    d = tmp_path / "fmus"
    (d / "native" / ("fmi%d" % fmi_version)).mkdir(parents=True)
    src = python_fmus if backend == "python" else native_fmus[fmi_version]
    dst = d if backend == "python" else d / "native" / ("fmi%d" % fmi_version)
    (dst / "Excitation.fmu").symlink_to(src["Excitation"])
    with pytest.raises(RuntimeError) as info:
        driftfmu.simulate(["Excitation"], stop_time=0.01, start_values={"kind": 2, "f": 600.0},
                          backend=backend, fmi_version=fmi_version, fmu_dir=d)
    text = str(info.value)
    assert text.count("Nyquist") == 1 and "\n" not in text, text
    assert re.search(r"\(error\): Excitation: f = 600.0 Hz is at or above the Nyquist rate",
                     text), text


# -- the command line and the API: the same line for the same bad setting ------------------------

#: (command line, API function, its arguments): a setting both must refuse with one line.
SAME = [
    (["run", "gaussian", "--a2", "abc"], "run_gaussian", dict(a2="abc")),
    (["run", "gaussian", "--R", "0"], "run_gaussian", dict(R=0.0)),
    (["run", "gaussian", "--A", "1"], "run_gaussian", dict(A=1.0)),
    (["run", "gaussian", "--Q", "inf"], "run_gaussian", dict(Q=math.inf)),
    (["run", "gaussian", "--a1", "0"], "run_gaussian", dict(a1=0.0)),
    (["run", "gaussian", "--n", "0"], "run_gaussian", dict(n=0)),
    (["run", "gaussian", "--n", "1.5"], "run_gaussian", dict(n=1.5)),
    (["run", "gaussian", "--seed", "-1"], "run_gaussian", dict(seed=-1)),
    (["run", "gaussian", "--estimator", "4"], "run_gaussian", dict(estimator=4)),
    (["run", "gaussian", "--backend", "java"], "run_gaussian", dict(backend="java")),
    (["run", "gaussian", "--drive", "3"], "run_gaussian", dict(drive=3)),
    (["run", "sinusoidal", "--f", "0"], "run_sinusoidal", dict(f=0.0)),
    (["run", "sinusoidal", "--f", "600"], "run_sinusoidal", dict(f=600.0)),
    (["run", "sinusoidal", "--preset", "x"], "run_sinusoidal", dict(preset="x")),
    (["run", "sinusoidal", "--process", "3"], "run_sinusoidal", dict(process=3)),
    (["montecarlo", "gaussian", "--runs", "0"], "montecarlo", dict(runs=0)),
    (["montecarlo", "gaussian", "--engine", "gpu"], "montecarlo", dict(engine="gpu")),
    (["montecarlo", "gaussian", "--workers", "0"], "montecarlo", dict(workers=0)),
    (["montecarlo", "gaussian", "--scheduler", "nonsense"], "montecarlo",
     dict(scheduler="nonsense")),
    (["montecarlo", "sinusoidal", "--f", "600"], "montecarlo", dict(kind="sinusoidal",
                                                                    f=600.0)),
    (["sweep", "--R", "0"], "sweep", dict(R=[0.0])),
    (["sweep", "--a2", "x"], "sweep", dict(a2=["x"])),
    (["sweep", "--runs", "0"], "sweep", dict(runs=0)),
    (["experiment", "adxl203", "--sets", "0"], "experiment_adxl203", dict(sets=0)),
    (["experiment", "adxl203", "--sets", "6", "--held-out", "5"], "experiment_adxl203",
     dict(sets=6, held_out=5)),
    (["experiment", "adxl203", "--sets", "2"], "experiment_adxl203", dict(sets=2)),
    (["experiment", "adxl203", "--freqs", "0,100"], "experiment_adxl203",
     dict(freqs=[0.0, 100.0])),
    (["experiment", "adxl203", "--freqs", "100,6000"], "experiment_adxl203",
     dict(freqs=[100.0, 6000.0])),
    (["experiment", "adxl203", "--order", "5"], "experiment_adxl203", dict(order=5)),
    (["experiment", "adxl203", "--n", "0"], "experiment_adxl203", dict(n=0)),
    (["experiment", "dual-axis", "--points", "1"], "experiment_dual_axis", dict(points=1)),
    (["experiment", "dual-axis", "--engine", "gpu"], "experiment_dual_axis",
     dict(engine="gpu")),
    (["experiment", "dual-axis", "--Ry", "0"], "experiment_dual_axis", dict(Ry=0.0)),
    (["experiment", "dual-axis", "--f", "600"], "experiment_dual_axis", dict(f=600.0)),
    (["experiment", "drift-classes", "--settle", "1.5"], "experiment_drift_classes",
     dict(settle=1.5)),
    (["experiment", "drift-classes", "--wrong", "-0.1"], "experiment_drift_classes",
     dict(wrong=-0.1)),
    (["experiment", "drift-classes", "--runs", "0"], "experiment_drift_classes", dict(runs=0)),
    (["experiment", "drift-classes", "--n", "1"], "experiment_drift_classes", dict(n=1)),
    (["identify", "{rec}", "--f", "150", "--order", "5"], "identify",
     dict(files=["{rec}"], f=150.0, order=5)),
    (["identify", "{rec}", "--f", "0"], "identify", dict(files=["{rec}"], f=0.0)),
    (["identify", "{rec}", "--f", "600"], "identify", dict(files=["{rec}"], f=600.0)),
    (["identify", "{rec}", "--f", "150", "--order", "4"], "identify",
     dict(files=["{rec}"], f=150.0, order=4)),
    (["identify", "{rec}", "--f", "150", "--held-out", "-1"], "identify",
     dict(files=["{rec}"], f=150.0, held_out=-1)),
    (["allan", "{rec}", "--column", "w"], "allan", dict(source="{rec}", column="w")),
    (["allan", "{rec}", "--taus", "0.0015"], "allan", dict(source="{rec}", taus=[0.0015])),
    (["allan", "{rec}", "--taus", "1.001"], "allan", dict(source="{rec}", taus=[1.001])),
    (["allan", "{rec}", "--taus", "0"], "allan", dict(source="{rec}", taus=[0.0])),
    (["allan", "{rec}", "--per-decade", "0"], "allan", dict(source="{rec}", per_decade=0)),
    (["allan", "--backend", "java"], "allan", dict(backend="java")),
]


def _cli_line(argv, capsys):
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert status == 2 and len(lines) == 1, err
    return lines[0]


def _both(argv, name, kwargs, tmp_path, capsys):
    """The command line's error line and the API's ValueError for one bad setting; ``{rec}``
    stands for a recording.  Neither may have made its out or FMU folder."""
    rec = str(_recording(tmp_path / "rec.csv"))  # 2000 rows, about 110 kB
    fill = lambda v: [fill(x) for x in v] if isinstance(v, list) else (  # noqa: E731
        rec if v == "{rec}" else v)
    out, fmus = tmp_path / "out", tmp_path / "fmus"
    line = _cli_line([fill(a) for a in argv] + ["--out", str(out)]
                     + ([] if argv[0] == "identify" else ["--fmu-dir", str(fmus)]), capsys)
    kwargs = {k: fill(v) for k, v in kwargs.items()}
    if name != "identify":
        kwargs["fmu_dir"] = fmus
    with pytest.raises(ValueError) as info:
        getattr(driftfmu, name)(out=out, **kwargs)
    assert not out.exists() and not fmus.exists()
    return line, info.value


@pytest.mark.parametrize("argv, name, kwargs", SAME, ids=[" ".join(c[0]) for c in SAME])
def test_the_command_line_and_the_api_refuse_a_setting_with_the_same_line(
        argv, name, kwargs, tmp_path, capsys):
    line, error = _both(argv, name, kwargs, tmp_path, capsys)
    assert re.sub(r"^driftfmu: error: (argument --[\w-]+: )?", "", line) == str(error)


def _as_keywords(text):
    """A command line's spelling of its options as the API's keywords."""
    text = text.replace("--summary-only", "summary_only=True")
    text = re.sub(r"--([a-z][\w-]*) (\d+)", lambda m: "%s=%s" % (m.group(1).replace("-", "_"),
                                                                 m.group(2)), text)
    return re.sub(r"--([a-z][\w-]*)", lambda m: m.group(1).replace("-", "_"), text)


#: (command line, API function, its arguments): a size both refuse with the same estimate on a
#: machine of 1 MB (:func:`_small_machine`); each a small run, were a check missing.
SIZES = [
    (["montecarlo", "gaussian", "--runs", "100", "--n", "100"], "montecarlo",
     dict(runs=100, n=100)),
    (["montecarlo", "sinusoidal", "--runs", "20000", "--n", "10", "--summary-only"],
     "montecarlo", dict(kind="sinusoidal", runs=20000, n=10, summary_only=True)),
    (["run", "gaussian", "--n", "1000"], "run_gaussian", dict(n=1000)),
    (["run", "sinusoidal", "--n", "1000"], "run_sinusoidal", dict(n=1000)),
    (["sweep", "--a2", "0.01", "--R", "1e-4", "--runs", "5000", "--n", "10"], "sweep",
     dict(a2=[0.01], R=[1e-4], runs=5000, n=10)),
    (["experiment", "adxl203", "--freqs", "100", "--sets", "3", "--n", "3000", "--workers",
      "2"], "experiment_adxl203", dict(freqs=[100.0], sets=3, n=3000, workers=2)),
    (["experiment", "dual-axis", "--points", "2", "--runs", "1000", "--n", "10", "--engine",
      "batch"], "experiment_dual_axis", dict(points=2, runs=1000, n=10, engine="batch")),
    (["experiment", "dual-axis", "--points", "2", "--runs", "1", "--n", "1000"],
     "experiment_dual_axis", dict(points=2, runs=1, n=1000)),
    (["experiment", "drift-classes", "--runs", "1", "--n", "1000"], "experiment_drift_classes",
     dict(runs=1, n=1000)),
    (["identify", "{rec}", "--f", "150"], "identify", dict(files="{rec}", f=150.0)),
    (["allan", "{rec}"], "allan", dict(source="{rec}")),
]


@pytest.mark.parametrize("argv, name, kwargs", SIZES, ids=[" ".join(c[0]) for c in SIZES])
def test_the_command_line_and_the_api_refuse_a_size_with_the_same_estimate(
        argv, name, kwargs, tmp_path, capsys, monkeypatch):
    """Each is refused by both, with the same figures and the same advice."""
    _small_machine(monkeypatch)
    line, error = _both(argv, name, kwargs, tmp_path, capsys)
    assert isinstance(error, UsageError)
    cli_tail = line.split(" needs about ", 1)[1]
    api_tail = str(error).split(" needs about ", 1)[1]
    assert _as_keywords(cli_tail) == api_tail and "--" not in api_tail


# -- fmu_dir: FMUs built only into a folder of their own -------------------------------------

@pytest.mark.parametrize("call", [
    lambda d: driftfmu.simulate(stop_time=0.002, fmu_dir=d),
    lambda d: driftfmu.simulate(stop_time=0.002, fmu_dir=d, backend="native"),
    lambda d: driftfmu.run_gaussian(n=5, fmu_dir=d),
    lambda d: driftfmu.run_sinusoidal(n=5, fmu_dir=d, backend="native"),
    lambda d: driftfmu.montecarlo(runs=2, n=5, engine="fmu", fmu_dir=d),
    lambda d: driftfmu.experiment_dual_axis(points=2, runs=1, n=5, fmu_dir=d),
    lambda d: driftfmu.experiment_adxl203(freqs=[100.0], sets=3, n=3000, fmu_dir=d),
    lambda d: driftfmu.experiment_drift_classes(n=5, runs=1, fmu_dir=d),
], ids=["simulate", "simulate native", "run_gaussian", "run_sinusoidal native",
        "montecarlo fmu", "dual-axis", "adxl203", "drift-classes"])
def test_fmus_are_not_built_into_a_folder_that_holds_other_files(call, tmp_path):
    """``fmu_dir`` naming a folder of the user's (their project, the working folder) without
    the FMUs: refused with what is missing and how to build it there, and the folder left as
    it was, instead of filled with FMUs unasked."""
    folder = tmp_path / "project"
    folder.mkdir()
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(UsageError, match=r"^fmu_dir %s has no (native/fmi2/)?\w+\.fmu.* and "
                       r"holds other files \(notes\.txt\): driftfmu builds missing FMUs only "
                       r"into a folder of its own; allowed: .*\(driftfmu build( --native)? "
                       r"--out %s\)$" % (re.escape(str(folder)), re.escape(str(folder)))):
        call(str(folder))
    assert os.listdir(folder) == ["notes.txt"]


def test_a_folder_of_fmus_a_new_or_an_empty_one_is_built_into(tmp_path):
    from driftfmu.fmu_src.builder import check_fmu_folder
    ours = tmp_path / "ours"
    (ours / "native" / "fmi2").mkdir(parents=True)
    (ours / "Excitation.fmu").write_bytes(b"")
    (ours / ".driftfmu-stage-x").mkdir()
    (tmp_path / "empty").mkdir()
    for folder in (ours, tmp_path / "empty", tmp_path / "new"):
        check_fmu_folder(folder, ["Accelerometer.fmu"])  # nothing to say: built there
    (ours / "Excitation.fmu.bak").write_bytes(b"")
    with pytest.raises(UsageError, match=r"holds other files \(Excitation\.fmu\.bak\)"):
        check_fmu_folder(ours, ["Accelerometer.fmu"])
    for name in "abcd":
        (ours / name).write_bytes(b"")
    with pytest.raises(UsageError, match=r"holds other files \(Excitation\.fmu\.bak, a, b, "
                                         r"\.\.\.\): "):
        check_fmu_folder(ours, ["Accelerometer.fmu"])


def test_the_command_refuses_such_a_folder_as_a_usage_error(tmp_path, capsys):
    from driftfmu.simulations.cli import main
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["run", "gaussian", "--n", "5", "--fmu-dir", str(tmp_path),
                 "--out", str(tmp_path / "res")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("driftfmu: error: fmu_dir %s has no " % tmp_path) and "\n" not in err
    assert sorted(os.listdir(tmp_path)) == ["notes.txt"]
