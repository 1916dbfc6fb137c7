"""The time a long run announces before it starts (simulations/budget.py): the CPU seconds of its
work spread over the cores its workers get on this machine now, and the command's own.  How
close it comes to the run is measured, not tested (benchmarks/bench_estimates.py: within a
factor of 2); these tests hold the arithmetic."""
import pytest

from driftfmu.simulations import budget


@pytest.fixture
def two_cores(monkeypatch):
    """A machine of two cores whose load average (the last minute's) the test sets."""
    monkeypatch.setattr(budget.os, "cpu_count", lambda: 2)

    def load(value):
        monkeypatch.setattr(budget.os, "getloadavg", lambda: (value, value, value))
    load(0.0)
    return load


@pytest.mark.parametrize("workers, load, cores", [
    (1, 0.0, 1.0), (2, 0.0, 2.0), (8, 0.0, 2.0),  # an idle machine: a core each, at most 2
    (2, 1.0, 2.0),  # the load of this command itself
    (2, 3.0, 2.0 * 2 / (2.0 + 2)),  # two busy processes besides: half of the two cores
    (2, 13.0, 2.0 * 2 / (12.0 + 2)),  # a loop and two busy loops besides: a seventh
    (1, 13.0, 2.0 * 1 / (12.0 + 1)),
])
def test_the_cores_a_run_gets_are_shared_with_what_the_machine_runs(two_cores, workers, load,
                                                                    cores):
    two_cores(load)
    assert budget.cores_for(workers) == pytest.approx(cores, rel=1e-12)
    assert budget.cores_for(workers, load=load) == pytest.approx(cores, rel=1e-12)


def test_a_machine_without_a_load_average_counts_as_idle(two_cores, monkeypatch):
    def no_load():
        raise OSError("no load average")
    monkeypatch.setattr(budget.os, "getloadavg", no_load)
    assert budget.cores_for(2) == 2.0


def test_the_experiment_s_estimate_is_its_work_on_the_cores_it_gets(two_cores):
    sets, n = 5 * 30, 60000
    idle = budget.check_adxl203((100, 125, 150, 175, 200), 30, n, None, None,
                                announce=False)["seconds"]
    work = budget.ADXL203_SECONDS["python"] * sets * n
    assert idle == pytest.approx(work / 2 + budget.ADXL203_COMMAND_SECONDS, rel=1e-12)
    # the default run, 51 s on an idle machine of two cores: within a factor of 2 (it said
    # 4 min)
    assert 51 / 2 < idle < 2 * 51
    two_cores(13.0)  # seven times busier: the work and the command's own take longer
    busy = budget.check_adxl203((100, 125, 150, 175, 200), 30, n, None, None,
                                announce=False)["seconds"]
    assert busy == pytest.approx(work / (4 / 14) + budget.ADXL203_COMMAND_SECONDS / (2 / 13),
                                 rel=1e-12)
    two_cores(0.0)  # one worker: one core
    assert budget.check_adxl203((100,), 30, n, 1, None, announce=False)["seconds"] == \
        pytest.approx(budget.ADXL203_SECONDS["python"] * 30 * n
                      + budget.ADXL203_COMMAND_SECONDS, rel=1e-12)


@pytest.mark.parametrize("check, runs", [
    (lambda engine, backend: budget.check_montecarlo("gaussian", 100, 1000, 2, None,
                                                     announce=False, engine=engine,
                                                     backend=backend), 100),
    (lambda engine, backend: budget.check_sweep(30, 100, 1000, 2, None, announce=False,
                                                engine=engine, backend=backend), 3000),
])
def test_the_fmu_engine_is_estimated_as_co_simulations(two_cores, check, runs):
    """The FMU engine co-simulates run by run: its runs cost what ``driftfmu run`` costs per
    sample (of its backend), far more than the batch engine's."""
    for backend in ("python", "native"):
        fmu = check("fmu", backend)["seconds"] - budget.COMMAND_SECONDS
        assert fmu == pytest.approx(runs * budget.RUN_SECONDS[backend] * 1000 / 2, rel=1e-12)
    batch = check("batch", "python")["seconds"] - budget.COMMAND_SECONDS
    assert fmu > 10 * batch


def test_the_announcement_says_the_estimate(two_cores, capsys):
    two_cores(13.0)
    est = budget.check_adxl203((100, 125, 150, 175, 200), 30, 60000, None, None)
    err = capsys.readouterr().err
    assert err == ("driftfmu: note: experiment adxl203 --sets 30 --n 60000 at 5 frequencies: "
                   "about %s of memory, %s on disk, %s (estimates)\n"
                   % (budget.size(est["memory"]), budget.size(0), budget.duration(
                       est["seconds"])))
