"""The batch engine: bit for bit the FMU co-simulation and models/ run by run, whatever the
block size, the chunking or the workers; clear errors for bad input."""

import os

import numpy as np
import pytest

from driftfmu.models import chain, excitation
from driftfmu.simulations import batch

N = 200


def _columns(res, r):
    return {c: res[c][r] for c in batch.TRAJECTORIES}


# -- seeds ------------------------------------------------------------------------------------
def test_run_seed_convention():
    assert batch.run_seed(7, 0) == 7 and batch.run_seed(7, 3) == 10
    seeds = batch.run_seeds(7, 4)
    assert seeds.dtype == np.uint64
    assert seeds.tolist() == [batch.run_seed(7, r) for r in range(4)]
    assert batch.run_seeds(batch.SEED_MAX, 1).tolist() == [batch.SEED_MAX]


@pytest.mark.parametrize("seed, runs", [(-1, 3), (batch.SEED_MAX, 2)])
def test_seeds_outside_the_fmu_range_are_refused(seed, runs):
    with pytest.raises(ValueError, match="seed"):
        batch.run_seeds(seed, runs)


@pytest.mark.parametrize("runs", [0, -3, 2.5, True])
def test_runs_below_one_are_refused(runs):
    with pytest.raises(ValueError, match="runs"):
        batch.run_seeds(1, runs)


# -- same bits as models/ run by run ----------------------------------------------------------
def test_gaussian_batch_equals_models_run_by_run():
    seeds = batch.run_seeds(3, 4)
    a2 = np.array([0.001, 0.01, 0.1, 0.3])
    R = np.array([1e-6, 1e-4, 1e-3, 1e-2])
    res = batch.simulate(N, seeds, a2=a2, R=R, A=0.6, Q=0.02, x0=0.1,
                         record=batch.TRAJECTORIES)
    for r in range(4):
        ref = chain.simulate(N, int(seeds[r]), a2=float(a2[r]), R=float(R[r]), A=0.6, Q=0.02,
                             x0=0.1)
        for c in batch.TRAJECTORIES:
            assert np.array_equal(res[c][r], np.asarray(ref[c])), (r, c)
        assert res["final_x_hat"][r] == ref["x_hat"][-1]
        assert res["final_zbar"][r] == ref["dc_empirical"][-1]
        assert float(a2[r]) * res["final_x2bar"][r] == ref["dc_realised"][-1]


def test_sinusoidal_batch_equals_models_run_by_run():
    seeds = batch.run_seeds(9, 3)
    phi = batch.sine_phase(seeds)
    res = batch.simulate(N, seeds, kind=excitation.SINUSOIDAL, X=0.8, f=120.0, phi=phi,
                         filter_A=0.0, filter_Q=0.32, record=batch.TRAJECTORIES)
    for r in range(3):
        assert phi[r] == batch.sine_phase(int(seeds[r]))
        ref = chain.simulate(N, int(seeds[r]), kind=excitation.SINUSOIDAL, X=0.8, f=120.0,
                             phi=float(phi[r]), filter_A=0.0, filter_Q=0.32)
        for c in batch.TRAJECTORIES:
            assert np.array_equal(res[c][r], np.asarray(ref[c])), (r, c)


def test_block_size_and_batch_size_do_not_change_the_bits():
    seeds = batch.run_seeds(1, 6)
    whole = batch.simulate(N, seeds, block=batch.BLOCK, record=("x", "dc_ekf1"))
    for block in (1, 7, N + 5):
        other = batch.simulate(N, seeds, block=block, record=("x", "dc_ekf1"))
        for key in whole:
            assert np.array_equal(whole[key], other[key]), (block, key)
    one = batch.simulate(N, seeds[2:3], record=("x", "dc_ekf1"))
    for key in whole:
        assert np.array_equal(whole[key][2:3], one[key])


def test_finals_are_the_last_samples():
    res = batch.simulate(50, batch.run_seeds(4, 3), record=batch.TRAJECTORIES)
    for name in ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3"):
        assert np.array_equal(res["final_" + name], res[name][:, -1]), name
    assert np.array_equal(res["final_zbar"], res["dc_empirical"][:, -1])
    assert np.array_equal(0.01 * res["final_x2bar"], res["dc_realised"][:, -1])


# -- tasks and workers --------------------------------------------------------------------------
@pytest.mark.parametrize("kernel", ["auto", "numpy"])
def test_tasks_on_workers_equal_one_batch(kernel, monkeypatch):
    """Tasks in the compiled kernel run in threads of this process (its calls release the
    GIL), the others in worker processes; either way the runs are those of one batch."""
    from driftfmu.simulations import kernel as compiled
    threads = kernel == "auto" and compiled.library() is not None
    pools = []
    for name in ("thread_pool", "process_pool"):
        real = getattr(batch, name)
        monkeypatch.setattr(batch, name, lambda w, real=real, name=name:
                            pools.append(name) or real(w))
    seeds = batch.run_seeds(2, 300)
    a2 = np.linspace(0.001, 0.3, 300)
    whole = batch.simulate(100, seeds, a2=a2, R=1e-3, kernel="numpy")
    tasks = batch.make_tasks(100, seeds, {"a2": a2}, {"R": 1e-3, "kernel": kernel}, chunk=70)
    assert [len(t["seeds"]) for t in tasks] == [70, 70, 70, 70, 20]
    assert [batch.in_kernel(t) for t in tasks] == [threads] * 5
    done = []
    got = batch.gather(batch.run_tasks(tasks, workers=2, progress=done.append))
    assert pools == ["thread_pool" if threads else "process_pool"]
    assert sorted(done) == done and done[-1] == 300
    for key in batch.FINALS:
        assert np.array_equal(got["final_" + key], whole["final_" + key]), key


def test_bad_input_is_refused_with_a_clear_message():
    seeds = batch.run_seeds(1, 2)
    with pytest.raises(ValueError, match="cannot record"):
        batch.simulate(10, seeds, record=("y",))
    with pytest.raises(ValueError, match="R = 0.0 is out of range; allowed: R > 0"):
        batch.check_parameters({"R": np.array([1e-4, 0.0])})
    with pytest.raises(ValueError, match="a2 is empty"):
        batch.check_parameters({"a2": []})
    with pytest.raises(ValueError, match="workers"):
        batch.run_tasks(batch.make_tasks(10, seeds, {}, {}), workers=0)
    with pytest.raises(ValueError, match="engine"):
        batch.run_task({"engine": "gpu", "n": 1, "seeds": seeds, "kwargs": {}, "record": ()})


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:1", "no-such-host.invalid:8786", ""])
def test_unreachable_scheduler_fails_fast_and_clearly(address, monkeypatch):
    pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] is not installed")
    # "fast": every network wait is bounded by the timeout (checked on the calls, not timed)
    probes = []
    probe = batch._probe
    monkeypatch.setattr(batch, "_probe", lambda s, t: probes.append(t) or probe(s, t))
    with pytest.raises(ConnectionError, match="no Dask scheduler answered at"):
        batch.connect(address, timeout=1.5)
    assert probes in ([], [1.5])  # [] : refused before any network call (an empty address)
    assert (probes == []) == (address == "")


# -- the FMUs themselves ------------------------------------------------------------------------
@pytest.mark.integration
def test_batch_equals_fmu_cosimulation_sample_by_sample(built_fmus):
    fmu_dir = built_fmus["Excitation"].parent
    seeds = batch.run_seeds(21, 3)
    a2 = np.array([0.01, 0.1, 0.3])
    R = np.array([1e-4, 1e-3, 1e-5])
    res = batch.simulate(N, seeds, a2=a2, R=R, A=0.3, record=batch.TRAJECTORIES)
    for r in range(3):
        fmu = batch.fmu_simulate(N, int(seeds[r]), a2=float(a2[r]), R=float(R[r]), A=0.3,
                                 fmu_dir=fmu_dir, record=batch.TRAJECTORIES)
        for c in batch.TRAJECTORIES + tuple("final_" + f for f in batch.FINALS):
            assert np.array_equal(np.asarray(fmu[c]), res[c][r]), (r, c)


@pytest.mark.integration
def test_sinusoidal_batch_equals_fmu_cosimulation(built_fmus):
    fmu_dir = built_fmus["Excitation"].parent
    seeds = batch.run_seeds(5, 2)
    phi = batch.sine_phase(seeds)
    kw = dict(kind=excitation.SINUSOIDAL, X=1.0, f=150.0, filter_A=0.0, filter_Q=0.5)
    res = batch.simulate(N, seeds, phi=phi, record=batch.TRAJECTORIES, **kw)
    for r in range(2):
        fmu = batch.fmu_simulate(N, int(seeds[r]), phi=float(phi[r]), fmu_dir=fmu_dir,
                                 record=batch.TRAJECTORIES, **kw)
        for c in batch.TRAJECTORIES + tuple("final_" + f for f in batch.FINALS):
            assert np.array_equal(np.asarray(fmu[c]), res[c][r]), (r, c)


@pytest.mark.integration
def test_fmu_engine_tasks_on_workers_equal_the_batch_engine(built_fmus):
    fmu_dir = built_fmus["Excitation"].parent
    seeds = batch.run_seeds(8, 4)
    per_run = {"a2": np.array([0.01, 0.02, 0.05, 0.1])}
    common = {"R": 1e-3}
    want = batch.simulate(60, seeds, record=("dc_ekf1",), **per_run, **common)
    tasks = batch.make_tasks(60, seeds, per_run, common, record=("dc_ekf1",), chunk=2,
                             engine="fmu", fmu_dir=fmu_dir)
    got = batch.gather(batch.run_tasks(tasks, workers=2))
    for key in want:
        assert np.array_equal(got[key], want[key]), key


def test_pool_workers_run_one_blas_thread():
    """One worker per core, each with one BLAS thread: OpenBLAS's default, a thread per core in
    every worker, oversubscribes the cores (the ADXL203 experiment took 1.6 times as long)."""
    from driftfmu.models import _blas
    if not _blas.libraries():
        pytest.skip("no OpenBLAS found in this process (another BLAS, or not Linux)")
    with _blas.threads(2):   # what a 2-core machine starts with, whatever this one has
        with batch.process_pool(2) as pool:
            counts = [pool.submit(_blas.counts).result() for _ in range(2)]
    # each worker's every OpenBLAS at one thread (a worker started by a fork server may have
    # loaded fewer BLAS libraries than this process: only NumPy's)
    assert len(counts) == 2 and all(c and set(c) == {1} for c in counts), counts


def _holds(folder):
    from driftfmu.simulations import cosim
    return folder in cosim.EXTRACTED


def test_a_stopped_worker_leaves_its_parents_fmu_folders(monkeypatch):
    """A worker told to stop removes the FMU folders it extracted, not the ones it inherited
    from the process that forked it: those are still in use there (the fast master keeps its
    unpacked FMUs for later runs), and a stopped pool once removed them under the parent."""
    import time
    from driftfmu.simulations import cosim
    import multiprocessing
    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork here: a worker inherits nothing")
    # forked, even when this process runs other threads (pytest-xdist's), which would make
    # the pool start its workers through a fork server, where they inherit nothing to remove
    monkeypatch.setattr(batch, "mp_context", lambda preload=None:
                        multiprocessing.get_context("fork"))
    mine = cosim.new_extract_folder(prefix="driftfmu_test_parent_")
    try:
        with pytest.raises(RuntimeError):
            with batch.process_pool(1) as pool:
                assert pool.submit(_holds, mine).result()   # inherited by the fork
                pool.submit(time.sleep, 60)
                raise RuntimeError("stop the pool")   # stop_pool: SIGTERM to the worker
        assert os.path.isdir(mine) and mine in cosim.EXTRACTED
    finally:
        cosim._remove(mine)


def _stopped_pool(record=None):
    """A pool of one worker stopped (stop_pool) while its task runs and another is queued;
    ``record``: a list that gets the thread of each close of the task pipe's read end."""
    import threading
    import time
    reader = None
    with pytest.raises(RuntimeError):
        with batch.process_pool(1) as pool:
            assert pool.submit(int, "7").result() == 7  # the worker runs
            pool.submit(time.sleep, 60)
            pool.submit(time.sleep, 60)
            if record is not None:
                reader = pool._call_queue._reader
                close = reader.close

                def recorded():  # who asks (the feeder thread holds the method bound)
                    record.append(threading.current_thread().name)
                    close()
                reader.close = recorded
            raise RuntimeError("stop the pool")
    return reader


def test_a_stopped_pools_task_pipe_is_closed_by_its_manager_thread_alone(monkeypatch):
    """The executor's threads close the task pipe's read end (the manager when it finds the
    pool broken, CPython's terminate_broken; the feeder when the manager shuts the queue
    down); stop_pool closing it too, from this thread, closed the descriptor twice when the
    two met (CI: an EBADF traceback from the manager thread)."""
    import multiprocessing
    import threading
    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork here")
    monkeypatch.setattr(batch, "mp_context", lambda preload=None:
                        multiprocessing.get_context("fork"))
    record = []
    reader = _stopped_pool(record)
    # closed (by the manager, or by the feeder when the manager shut the queue down), not here
    assert reader.closed and threading.current_thread().name not in record, record


def test_pools_stopped_one_after_another_raise_nothing_in_any_thread(monkeypatch):
    """Twelve pools stopped while their tasks run: no thread ends with an exception (the
    manager's close of the task pipe and stop_pool's once raced: EBADF)."""
    import multiprocessing
    import threading
    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork here")
    # forked (a fork server, chosen when other threads run, keeps a folder to this process's end)
    monkeypatch.setattr(batch, "mp_context", lambda preload=None:
                        multiprocessing.get_context("fork"))
    raised = []
    monkeypatch.setattr(threading, "excepthook", lambda args: raised.append(
        "%s: %r" % (args.thread, args.exc_value)))
    for _ in range(12):
        _stopped_pool()
    assert raised == []


def test_a_cluster_that_cannot_tell_its_threads_runs_one_task_at_a_time():
    class Counted:
        def nthreads(self):
            return {"tcp://a": 2, "tcp://b": 3}

    class Silent:
        def nthreads(self):
            raise AttributeError("no nthreads")

    assert batch._cluster_threads(Counted()) == 5
    assert batch._cluster_threads(Silent()) == 1


def test_estimate_refuses_a1_zero_and_accepts_a_negative_one():
    zs = np.zeros((2, 5))
    with pytest.raises(batch.UsageError, match=r"a1 = 0\.0 is out of range; allowed: a1 != 0"):
        batch.estimate(zs, a1=0.0)
    assert batch.estimate(zs, a1=-1.0)["final_x_hat"].shape == (2,)
