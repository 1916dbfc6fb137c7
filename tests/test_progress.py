"""Progress that tells (issue 19): every long phase shows progress (the dual-axis validation
no longer sits at 100 %), and when standard error is not a terminal (a CI log) plain lines
come at intervals instead of nothing until the end."""
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from driftfmu.simulations import cli
from waiting import BOUND, sigint_default

ROOT = Path(__file__).resolve().parent.parent


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_plain_lines_come_at_intervals_with_percent_and_time_left():
    clock, out = Clock(), io.StringIO()
    p = cli.Progress(1000, "runs", "run", every=10.0, stream=out, clock=clock)
    clock.t = 5.0
    p(100)
    # the first work done, and 900 runs more at this pace are 45 s: a long phase says so at
    # once, not after its first interval
    assert out.getvalue() == ("driftfmu: progress: runs 10 % (100/1000 runs), 5 s, about 45 s "
                              "left at this pace\n")
    clock.t = 10.0
    p(250)
    assert out.getvalue().count("\n") == 1  # one line per interval
    clock.t = 15.0
    p(300)
    # 300 runs in 15 s: 700 more take 35 s
    assert out.getvalue().splitlines()[-1] == (
        "driftfmu: progress: runs 30 % (300/1000 runs), 15 s, about 35 s left at this pace")
    clock.t = 20.0
    p(500)
    assert out.getvalue().count("\n") == 2
    clock.t = 25.0
    p(600)
    assert out.getvalue().count("\n") == 3


def test_a_short_phase_stays_silent_and_a_long_one_speaks_at_its_first_work_done():
    clock, out = Clock(), io.StringIO()
    p = cli.Progress(1000, "runs", "run", every=30.0, stream=out, clock=clock)
    clock.t = 0.02
    p(10)  # 990 more at this pace: 2 s, less than a line's interval
    clock.t = 1.9
    p(1000)
    assert out.getvalue() == ""
    p = cli.Progress(1000, "sets", "set", every=30.0, stream=out, clock=clock)
    clock.t = 3.0
    p(1)  # in the first seconds: not yet
    assert out.getvalue() == ""
    clock.t = 5.0
    p(2)  # 3.1 s into the phase, and 998 more sets at this pace: a long phase speaks
    assert out.getvalue() == ("driftfmu: progress: sets 0 % (2/1000 sets), 3 s, about 25.8 min "
                              "left at this pace\n")
    clock.t = 7.0
    p(3)
    assert out.getvalue().count("\n") == 1  # then one line an interval
    clock.t = 100.0
    p = cli.Progress(1, "co-simulation", "sample", every=30.0, stream=out, clock=clock)
    clock.t = 110.0
    p(1)  # done within its interval: nothing to announce
    assert out.getvalue().count("\n") == 1


def test_the_first_line_of_a_long_phase_says_the_time_left_however_slow_the_first_unit():
    """A machine so busy that the first set is done only after 40 s (a load of 12 on two
    cores): the phase's first line comes with it, and says how long the rest takes at that
    pace."""
    clock, out = Clock(), io.StringIO()
    p = cli.Progress(150, "sets", "set", every=30.0, stream=out, clock=clock)
    clock.t = 40.0
    p(1)
    assert out.getvalue() == ("driftfmu: progress: sets 1 % (1/150 sets), 40 s, about 99.3 min "
                              "left at this pace\n")


def test_a_new_phase_restarts_the_count_and_is_announced_in_a_long_run():
    clock, out = Clock(), io.StringIO()
    p = cli.Progress(10, "runs", "run", every=10.0, stream=out, clock=clock)
    clock.t = 30.0
    p(10)
    cli.start_phase(p, "validation", 4, "point")
    lines = out.getvalue().splitlines()
    assert lines[-2:] == ["driftfmu: progress: runs 100 % (10/10 runs), 30 s",
                          "driftfmu: progress: validation 0 % (0/4 points), 0 s"]
    clock.t = 35.0
    p(1)  # 15 s more at this pace: longer than an interval, said at once
    assert out.getvalue().splitlines()[-1] == ("driftfmu: progress: validation 25 % (1/4 "
                                               "points), 5 s, about 15 s left at this pace")
    clock.t = 45.0
    p(2)
    assert out.getvalue().splitlines()[-1] == ("driftfmu: progress: validation 50 % (2/4 points), "
                                               "15 s, about 15 s left at this pace")
    cli.start_phase(lambda done: None, "x", 1)  # a plain callable has no phases: ignored
    cli.start_phase(None, "x", 1)


@pytest.mark.parametrize("into_the_run, said", [(9.75, False), (10.0, True)])
def test_a_new_phase_is_announced_only_when_the_run_has_taken_an_interval(into_the_run, said):
    """A phase starting ``every`` seconds or more into the run (counted from the run's start,
    not from the clock's zero: time.monotonic reads the seconds since the machine booted) is
    announced at once; one starting sooner stays silent, as a short run should."""
    clock, out = Clock(), io.StringIO()
    clock.t = 86400.0  # a machine up for a day
    p = cli.Progress(10, "runs", "run", every=10.0, stream=out, clock=clock)
    clock.t += into_the_run
    cli.start_phase(p, "validation", 4, "point")
    assert out.getvalue() == ("driftfmu: progress: validation 0 % (0/4 points), 0 s\n"
                              if said else "")


def test_the_time_left_counts_from_the_start_of_the_work_not_its_set_up():
    """A run that first builds its FMUs for 60 s, then co-simulates 100 samples in 10 s: 900
    samples are 90 s more, not the 630 s that counting the build would say."""
    clock, out = Clock(), io.StringIO()
    p = cli.Progress(1000, "co-simulation", "sample", every=1.0, stream=out, clock=clock)
    clock.t = 60.0
    cli.start_work(p)
    clock.t = 70.0
    p(100)
    assert out.getvalue().splitlines() == [
        "driftfmu: progress: co-simulation 10 % (100/1000 samples), 70 s, about 90 s left at "
        "this pace"]
    cli.start_work(lambda done: None)  # a plain callable has no work phases: ignored
    cli.start_work(None)


def test_the_first_units_done_count_for_all_that_run_beside_them():
    """Two workers start two sets at once: when the first is done after 10 s, so is (about)
    the second, and the 8 left of 10 take 40 s, not 90 s; later the sets done count alone."""
    clock, out = Clock(), io.StringIO()
    p = cli.Progress(10, "sets", "set", every=0.0, stream=out, clock=clock)
    cli.start_work(p, at_once=2)
    clock.t = 10.0
    p(1)
    clock.t = 20.0
    p(4)
    assert [line.split(", ")[-1] for line in out.getvalue().splitlines()] == [
        "about 45 s left at this pace", "about 30 s left at this pace"]
    p.phase("validation", 3, "point")  # a new phase runs one unit at a time again
    assert p.at_once == 1 and p.work_started == 20.0


class Bar:
    def __init__(self):
        self.n, self.total, self.desc, self.unit = 0, 5, "runs", " run"

    def update(self, k):
        self.n += k

    def reset(self, total):
        self.n, self.total = 0, total

    def set_description(self, desc):
        self.desc = desc


def test_on_a_terminal_the_bar_follows_the_phases():
    bar = Bar()
    p = cli.Progress(5, "runs", "run", bar=bar)
    p(5)
    assert bar.n == 5
    p.phase("validation", 3, "point")
    assert (bar.n, bar.total, bar.desc, bar.unit) == (0, 3, "validation", " point")
    p(2)
    assert bar.n == 2


def test_a_command_in_a_log_writes_progress_lines(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), DRIFTFMU_PROGRESS_EVERY="0")
    r = subprocess.run([sys.executable, "-m", "driftfmu", "montecarlo", "gaussian", "--runs",
                        "600", "--n", "200", "--workers", "1", "--out", "res"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert any(line.startswith("driftfmu: progress: montecarlo (batch engine) ") and "runs)" in
               line for line in lines), r.stderr
    assert any(line.startswith("driftfmu: progress: the summary, the files and the figure")
               for line in lines), r.stderr


@pytest.mark.integration
def test_the_dual_axis_validation_is_a_phase_of_its_own(built_fmus):
    from driftfmu.simulations import dual_axis
    seen = []

    class Recorder:
        def __call__(self, done):
            seen.append(done)

        def phase(self, desc, total, unit=None):
            seen.append((desc, total, unit))
    fmu_dir = Path(built_fmus["Excitation"]).parent
    dual_axis.run_dual_axis(points=2, runs=1, engine="fmu", fmu_dir=str(fmu_dir), workers=1,
                            progress=Recorder(), plot=False, n=40)
    i = next(i for i, s in enumerate(seen) if isinstance(s, tuple))
    desc, total, unit = seen[i]
    assert desc.startswith("validation") and unit == "point"
    assert seen[i - 1] == total * 1  # the runs: 2 sweeps x 2 points x 1 run
    assert seen[i + 1:] == list(range(1, total + 1))  # then the validation, point by point


def _stderr_lines(proc, lines):
    """Read ``proc``'s standard error into the queue ``lines``, line by line, until it ends."""
    for line in proc.stderr:
        lines.put(line.rstrip("\n"))
    lines.put(None)


@pytest.mark.integration
def test_a_long_experiment_says_how_long_it_will_take_and_shows_its_first_set(python_fmus,
                                                                             tmp_path):
    """``experiment adxl203`` sized to take many minutes (each of its phases too, on an idle
    machine as on a busy one) says so at its start (an estimate from its sizes) and writes its
    first progress line within its first seconds, not after the interval of 30 s: the test
    waits for the two lines (not for a time), then stops it."""
    import queue
    import signal
    import threading
    env = {k: v for k, v in os.environ.items() if k != "DRIFTFMU_PROGRESS_EVERY"}
    env["PYTHONPATH"] = str(ROOT)
    proc = subprocess.Popen(
        [sys.executable, "-m", "driftfmu", "experiment", "adxl203", "--freqs", "100",
         "--sets", "1000", "--n", "20000", "--workers", "1",
         "--fmu-dir", str(python_fmus["Excitation"].parent), "--out", str(tmp_path / "res")],
        cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        preexec_fn=sigint_default)
    lines = queue.Queue()
    threading.Thread(target=_stderr_lines, args=(proc, lines), daemon=True).start()
    seen = []
    try:
        while not any(line.startswith("driftfmu: progress: ") for line in seen):
            line = lines.get(timeout=BOUND)
            assert line is not None, "ended without a progress line: %s" % seen
            seen.append(line)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=BOUND)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    note, progress = seen[0], seen[-1]
    assert note.startswith("driftfmu: note: experiment adxl203 --sets 1000 --n 20000 at 1 "
                           "frequency: about "), seen
    assert note.endswith(" (estimates)") and (" min " in note or " s " in note), note
    import re
    assert re.fullmatch(r"driftfmu: progress: sets \d+ % \(\d+/1000 sets\), \d+ s, about "
                        r"[0-9.]+ (s|min) left at this pace", progress), progress
    assert len(seen) == 2, seen


class Recorder:
    """A progress callback that records its calls: the units done, and ("work", at_once)."""

    def __init__(self):
        self.seen = []

    def __call__(self, done):
        self.seen.append(done)

    def work(self, at_once=1):
        self.seen.append(("work", at_once))


@pytest.mark.parametrize("workers, at_once", [(1, 2), (2, 4)])
def test_the_pool_says_when_its_work_starts_and_how_many_runs_it_runs_at_once(workers, at_once):
    from driftfmu.simulations import batch
    tasks = batch.make_tasks(10, batch.run_seeds(1, 6), {}, dict(kernel="numpy"), chunk=2)
    progress = Recorder()
    batch.run_tasks(tasks, workers=workers, progress=progress)
    assert progress.seen[0] == ("work", at_once)
    assert sorted(progress.seen[1:]) == [2, 4, 6]


@pytest.mark.integration
@pytest.mark.parametrize("fast", [False, True])
def test_a_co_simulation_says_when_its_steps_start(python_fmus, fast):
    from driftfmu.simulations import cosim, fastcosim, sinusoidal
    progress = Recorder()
    master = fastcosim.cosimulate_fast if fast else cosim.cosimulate
    master({k: str(v) for k, v in python_fmus.items() if k != "DualDriftEstimator"},
           sinusoidal.CONNECTIONS, 200, 1e-3, progress=progress)
    assert progress.seen[0] == ("work", 1) and progress.seen[-1] == 200
    assert progress.seen.count(("work", 1)) == 1
