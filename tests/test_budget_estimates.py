"""The size checks' estimates are their documented per-item costs (simulations/budget.py), term
by term, and a refused run names the largest one that fits by the documented rule.

Each estimate is checked at settings where every term of its sum is of a different size (so a
term left out, or one counted with the wrong multiplier, changes it), with and without a result
folder (disk is counted only with one), at worker counts on both sides of the work there is.
The machine's memory is fixed here (``available_memory``), so that what is refused, and the
largest run that fits, follow from the rule alone: the memory that grows with the run may be
``MEMORY_SHARE`` of the memory available, less the command's own ``BASE_MEMORY``.
"""
import math

import pytest

from driftfmu.simulations import budget
from driftfmu.simulations.errors import UsageError
from driftfmu.simulations.montecarlo import FIGURE_RUNS

B = budget


@pytest.fixture
def machine(monkeypatch):
    """An idle machine (load average 0) with 4 cores, 20 GB of memory available and 1 TB of
    free disk."""
    monkeypatch.setattr(B.os, "cpu_count", lambda: 4)
    monkeypatch.setattr(B.os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    monkeypatch.setattr(B, "available_memory", lambda: 20e9)
    monkeypatch.setattr(B, "free_disk", lambda folder: 1e12)


@pytest.mark.parametrize("out", [None, "results/x"])
@pytest.mark.parametrize("workers", [1, 3, None])
def test_montecarlo_keeping_every_trajectory(machine, out, workers):
    runs, n = 5000, 7
    got = B.check_montecarlo("gaussian", runs, n, workers, out, announce=False)
    cores = min(workers or 4, runs)
    assert got == {"memory": B.BASE_MEMORY + B.MONTECARLO_MEMORY * runs * n,
                   "disk": B.MONTECARLO_DISK * runs * n if out else 0,
                   "seconds": B.MONTECARLO_SECONDS * runs * n / cores + B.COMMAND_SECONDS}


@pytest.mark.parametrize("out", [None, "results/x"])
@pytest.mark.parametrize("workers,runs", [(1, 5000), (3, 5000), (None, 5000), (3, 300)])
def test_montecarlo_keeping_summaries(machine, out, workers, runs):
    n = 7
    got = B.check_montecarlo("gaussian", runs, n, workers, out, summary_only=True,
                             announce=False)
    cores = min(workers or 4, runs)
    kept = min(runs, FIGURE_RUNS)
    chunk = min(runs, 4096) * min(cores, 2)   # the workers' chunks while they reduce them
    assert got == {"memory": B.BASE_MEMORY + B.MONTECARLO_MEMORY * (kept + chunk) * n
                   + B.SUMMARY_BYTES * runs,
                   "disk": B.MONTECARLO_DISK * kept * n + B.SUMMARY_BYTES * runs if out else 0,
                   "seconds": B.MONTECARLO_SECONDS * runs * n / cores + B.COMMAND_SECONDS}


@pytest.mark.parametrize("out", [None, "results/x"])
def test_sweep_adxl203_and_dual_axis(machine, out):
    got = B.check_sweep(6, 50, 300, 2, out, announce=False)
    assert got == {"memory": B.BASE_MEMORY + B.SWEEP_MEMORY * 300,
                   "disk": B.SWEEP_DISK * 300 if out else 0,
                   "seconds": B.SWEEP_SECONDS * 300 * 300 / 2 + B.COMMAND_SECONDS}
    got = B.check_adxl203((100.0, 200.0), 3, 1000, None, out, backend="native", announce=False)
    assert got == {"memory": B.BASE_MEMORY + (B.ADXL203_WORKER_MEMORY + B.ADXL203_MEMORY * 1000)
                   * 4, "disk": B.ADXL203_DISK if out else 0,
                   "seconds": B.ADXL203_SECONDS["native"] * 6 * 1000 / 4
                   + B.ADXL203_COMMAND_SECONDS}
    total = 2 * 3 * 40  # two sweeps of 3 points of 40 runs
    for engine, memory, per in (("batch", B.DUAL_BATCH_MEMORY * total, "batch"),
                                ("fmu", B.DUAL_FMU_MEMORY * total * 100, "native")):
        got = B.check_dual_axis(3, 40, 100, engine, 2, out, backend="native", announce=False)
        assert got == {"memory": B.BASE_MEMORY + memory, "disk": B.DUAL_DISK if out else 0,
                       "seconds": B.DUAL_SECONDS[per] * total * 100 / 2 + B.COMMAND_SECONDS}


def test_a_long_run_is_announced_only_when_asked(machine, capsys):
    runs, n = 200000, 1000   # 1000 s on one core: over LONG
    B.check_montecarlo("gaussian", runs, n, 1, None, summary_only=True, announce=False)
    assert capsys.readouterr().err == ""
    B.check_montecarlo("gaussian", runs, n, 1, None, summary_only=True)
    assert capsys.readouterr().err.startswith("driftfmu: note: montecarlo gaussian --runs "
                                              "200000 --n 1000 --summary-only: about ")
    B.check_montecarlo("gaussian", 100, 10, 1, None)  # short and small: nothing
    assert capsys.readouterr().err == ""


def _room(share_of):
    """The memory a run may grow into on the fixed machine, as a share of ``share_of``."""
    return (B.MEMORY_SHARE * 20e9 - B.BASE_MEMORY) / share_of


@pytest.mark.parametrize("api", [False, True])
def test_a_run_that_does_not_fit_is_refused_with_the_largest_that_fits(machine, api):
    runs, n = 10 ** 6, 1000
    with pytest.raises(UsageError) as e:
        B.check_montecarlo("gaussian", runs, n, 2, None, api=api, announce=False)
    grows = B.MONTECARLO_MEMORY * runs * n
    fits = int(runs * _room(grows))
    text = str(e.value)
    assert text.startswith(("montecarlo('gaussian', runs=1000000, n=1000) needs about "
                            if api else "montecarlo gaussian --runs 1000000 --n 1000 needs "
                            "about ") + "%s of memory; this machine has 20 GB of memory "
                           "available" % B.size(B.BASE_MEMORY + grows)), text
    assert ("at most runs=%d at n=1000" if api else "at most --runs %d at --n 1000") % fits \
        in text
    assert ("summary_only=True" if api else "--summary-only") in text
    # one run too long: the samples that fit, at one run
    n = 10 ** 9
    with pytest.raises(UsageError) as e:
        B.check_montecarlo("gaussian", 1, n, 2, None, api=api, announce=False)
    fits = max(1, int(n * _room(B.MONTECARLO_MEMORY * n)))
    assert ("at most n=%d at runs=1" if api else "at most --n %d at --runs 1") % fits \
        in str(e.value)
    # summaries: the runs that fit at this n
    runs, n = 10 ** 9, 10
    with pytest.raises(UsageError) as e:
        B.check_montecarlo("gaussian", runs, n, 2, None, summary_only=True, api=api,
                           announce=False)
    chunk = 4096 * 2
    memory = B.MONTECARLO_MEMORY * (FIGURE_RUNS + chunk) * n + B.SUMMARY_BYTES * runs
    room = _room(memory) * memory - B.MONTECARLO_MEMORY * (FIGURE_RUNS + chunk) * n
    assert ("at most runs=%d at n=10" if api else "at most --runs %d at --n 10") \
        % int(room // B.SUMMARY_BYTES) in str(e.value)


def test_a_run_whose_results_do_not_fit_on_disk_is_refused(machine, monkeypatch):
    monkeypatch.setattr(B, "free_disk", lambda folder: 1e6)
    runs, n = 1000, 100
    with pytest.raises(UsageError) as e:
        B.check_montecarlo("gaussian", runs, n, 2, "results/x", announce=False)
    disk = B.MONTECARLO_DISK * runs * n
    assert "needs about %s of disk" % B.size(disk) in str(e.value)
    assert "at most --runs %d at --n 100" % int(runs * 1e6 / disk) in str(e.value)
    # without a result folder nothing is written: not refused
    assert B.check_montecarlo("gaussian", runs, n, 2, None, announce=False)["disk"] == 0
    assert math.isfinite(B.check_sweep(6, 1000, 100, 2, None, announce=False)["seconds"])


def test_each_long_run_is_announced_in_the_callers_words_only_when_asked(machine, capsys):
    long_runs = [  # (check, what the note says it is), each over LONG on one core
        (lambda **kw: B.check_montecarlo("gaussian", 20000, 1000, 1, None, **kw),
         "montecarlo gaussian --runs 20000 --n 1000: about "),
        (lambda **kw: B.check_montecarlo("gaussian", 20000, 1000, 1, None, api=True, **kw),
         "montecarlo('gaussian', runs=20000, n=1000): about "),
        (lambda **kw: B.check_montecarlo("gaussian", 200000, 1000, 1, None, summary_only=True,
                                         api=True, **kw),
         "montecarlo('gaussian', runs=200000, n=1000, summary_only=True): about "),
        (lambda **kw: B.check_sweep(1000, 10000, 1000, 1, None, **kw),
         "sweep of 1000 grid points x --runs 10000 --n 1000: about "),
        (lambda **kw: B.check_sweep(1000, 10000, 1000, 1, None, api=True, **kw),
         "sweep(runs=10000, n=1000) of 1000 grid points: about "),
    ]
    for check, what in long_runs:
        check(announce=False)
        assert capsys.readouterr().err == "", what
        check()
        assert capsys.readouterr().err.startswith("driftfmu: note: " + what), what


@pytest.mark.parametrize("api", [False, True])
def test_each_refusal_says_how_to_proceed(machine, api):
    runs_, n_ = ("runs", "n") if api else ("--runs", "--n")
    with pytest.raises(UsageError) as e:
        B.check_montecarlo("gaussian", 10 ** 9, 10, 2, None, summary_only=True, api=api,
                           announce=False)
    assert str(e.value).endswith("; or fewer %s or a smaller %s" % (runs_, n_)), str(e.value)
    with pytest.raises(UsageError) as e:
        B.check_sweep(1000, 10 ** 6, 10, 2, None, api=api, announce=False)
    text = str(e.value)
    assert text.startswith("sweep(runs=1000000, n=10) of 1000 grid points needs about " if api
                           else "sweep of 1000 grid points x --runs 1000000 --n 10 needs about ")
    assert text.endswith("; or fewer grid points"), text
    share = _room(B.SWEEP_MEMORY * 1000 * 10 ** 6)
    assert ("at most %s for the 1000 grid points" % (
        ("runs=%d" if api else "--runs %d") % int(10 ** 6 * share))) in text


@pytest.mark.parametrize("api", [False, True])
def test_the_experiments_notes_and_refusals_in_the_callers_words(machine, capsys, api):
    # experiment adxl203: one frequency, two; long (over LONG); too large (refused)
    for freqs, at in (((100.0,), "1 frequency"), ((100.0, 200.0), "2 frequencies")):
        B.check_adxl203(freqs, 400, 10 ** 6, 1, None, api=api, announce=False)
        assert capsys.readouterr().err == ""
        B.check_adxl203(freqs, 400, 10 ** 6, 1, None, api=api)
        assert capsys.readouterr().err.startswith(
            "driftfmu: note: " + ("experiment_adxl203(sets=400, n=1000000) at %s: about " if api
                                  else "experiment adxl203 --sets 400 --n 1000000 at %s: "
                                  "about ") % at)
    n = 10 ** 8
    with pytest.raises(UsageError) as e:
        B.check_adxl203((100.0,), 4, n, 2, None, api=api, announce=False)
    grows = (B.ADXL203_WORKER_MEMORY + B.ADXL203_MEMORY * n) * 2
    text = str(e.value)
    assert ("at most %s; or a smaller %s or fewer %s" % (
        ("n=%d" if api else "--n %d") % int(n * _room(grows)), *(
            ("n", "workers") if api else ("--n", "--workers")))) in text, text
    # experiment dual-axis: batch and FMU engines
    for engine, runs in (("batch", 10 ** 5), ("fmu", 100)):  # each over LONG on one core
        B.check_dual_axis(5, runs, 1000, engine, 1, None, api=api, announce=False)
        assert capsys.readouterr().err == ""
        B.check_dual_axis(5, runs, 1000, engine, 1, None, api=api)
        assert capsys.readouterr().err.startswith("driftfmu: note: " + (
            "experiment_dual_axis(points=5, runs=%d, n=1000, engine=%r): about " % (runs, engine)
            if api else "experiment dual-axis --points 5 --runs %d --n 1000 --engine %s: "
            "about " % (runs, engine)))
    points, runs = 10, 10 ** 7
    with pytest.raises(UsageError) as e:
        B.check_dual_axis(points, runs, 100, "batch", 2, None, api=api, announce=False)
    share = _room(B.DUAL_BATCH_MEMORY * 2 * points * runs)
    assert str(e.value).endswith("at most %s; or fewer %s or %s" % (
        ("runs=%d" if api else "--runs %d") % int(runs * share),
        *(("points", "runs") if api else ("--points", "--runs")))), str(e.value)
    # one run too many samples: the samples that fit (FMU engine), the points (batch)
    with pytest.raises(UsageError) as e:
        B.check_dual_axis(points, 1, 10 ** 9, "fmu", 2, None, api=api, announce=False)
    share = _room(B.DUAL_FMU_MEMORY * 2 * points * 10 ** 9)
    assert ("at most %s at %s; or fewer %s or %s, or a smaller %s" % (
        ("n=%d" if api else "--n %d") % max(1, int(10 ** 9 * share)),
        "runs=1" if api else "--runs 1",
        *(("points", "runs", "n") if api else ("--points", "--runs", "--n")))) \
        in str(e.value), str(e.value)
    with pytest.raises(UsageError) as e:
        B.check_dual_axis(10 ** 9, 1, 100, "batch", 2, None, api=api, announce=False)
    share = _room(B.DUAL_BATCH_MEMORY * 2 * 10 ** 9)
    assert ("at most %s at %s" % (("points=%d" if api else "--points %d")
                                  % max(1, int(10 ** 9 * share)),
                                  "runs=1" if api else "--runs 1")) in str(e.value)


def test_a_backend_without_its_own_figure_is_estimated_as_the_python_fmus(machine):
    """The slowest figure stands in for a backend the tables do not name."""
    assert B.check_adxl203((100.0,), 3, 1000, 1, None, backend="elsewhere", announce=False) == \
        B.check_adxl203((100.0,), 3, 1000, 1, None, backend="python", announce=False)
    assert B.check_dual_axis(2, 3, 100, "fmu", 1, None, backend="elsewhere", announce=False) \
        == B.check_dual_axis(2, 3, 100, "fmu", 1, None, backend="python", announce=False)


@pytest.mark.parametrize("api", [False, True])
def test_drift_classes_refused_names_the_runs_or_the_samples_at_one_run_that_fit(machine, api):
    """``experiment drift-classes`` keeps every case's runs (7 cases): a refusal names the runs
    that fit while at least one does (``runs x share >= 1``), else the samples that fit in one
    run.  Both sides of that bound: 2 runs at exactly half the room (share 0.5: 1 run fits) and
    at one sample more (share just below 0.5: no whole run fits); and results that do not fit
    on disk at all name the smallest run the experiment takes (n = 2)."""
    runs = 2
    n = int(_room(B.DRIFT_CLASSES_MEMORY * 7 * runs) / 0.5)   # 7,500,000: share exactly 0.5
    for n_, fits in ((n, "runs=1" if api else "--runs 1"), (n + 1, None)):
        with pytest.raises(UsageError) as e:
            B.check_drift_classes(runs, n_, 1, None, api=api, announce=False)
        text = str(e.value)
        assert text.startswith("experiment_drift_classes(runs=2, n=%d) needs about " % n_ if api
                               else "experiment drift-classes --runs 2 --n %d needs about "
                               % n_), text
        if fits is None:
            share = _room(B.DRIFT_CLASSES_MEMORY * 7 * runs * n_)
            assert share < 0.5
            fits = ("n=%d at runs=1" if api else "--n %d at --runs 1") \
                % max(2, int(n_ * runs * share))
        assert text.endswith("allowed: a run that fits: at most %s; or fewer %s or a smaller %s"
                             % ((fits,) + (("runs", "n") if api else ("--runs", "--n")))), text
    # results that do not fit on disk at all: the smallest run the experiment takes (n = 2)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(B, "free_disk", lambda folder: 1.0)
        with pytest.raises(UsageError) as e:
            B.check_drift_classes(1, 1000, 1, "results/x", api=api, announce=False)
    assert ("at most n=2 at runs=1;" if api else "at most --n 2 at --runs 1;") in str(e.value)
