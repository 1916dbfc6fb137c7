"""``driftfmu sweep``: the grid equals the batch engine point by point, a Dask cluster gives the
same bits as local workers, closed forms and the letter's claims hold, files and errors."""
import math

import numpy as np
import pytest

from driftfmu.simulations import batch, sweep
from driftfmu.simulations.cli import main

A2 = [0.01, 0.1]
R = [1e-4, 1e-2]
RUNS = 50
N = 200
Q = 0.01
KW = dict(a2=A2, R=R, runs=RUNS, n=N, seed=3, Q=Q)
GRID_KEYS = ("grid_dc1", "grid_dc2", "grid_dc3", "grid_zbar", "grid_x2bar")


@pytest.fixture(scope="module")
def local():
    return sweep.sweep(workers=2, chunk=64, **KW)


def test_shapes(local):
    assert local["grid_a2"].shape == (2,) and local["grid_R"].shape == (2,)
    for key in GRID_KEYS:
        assert local[key].shape == (2, 2, RUNS), key
    for col in sweep.CSV_COLUMNS:
        assert local["table"][col].shape == (4,), col


def test_every_grid_point_equals_the_batch_engine_on_the_same_seeds(local):
    seeds = batch.run_seeds(3, RUNS)
    for i, a2 in enumerate(A2):
        for j, r in enumerate(R):
            want = batch.simulate(N, seeds, a2=a2, R=r, Q=Q)
            for key, name in zip(GRID_KEYS, ("dc_ekf1", "dc_ekf2", "dc_ekf3", "zbar", "x2bar")):
                assert np.array_equal(local[key][i, j], want["final_" + name]), (i, j, key)


def test_table_holds_the_mean_absolute_errors(local):
    t = local["table"]
    i, j, row = 1, 0, 2  # a2 slowest
    assert (t["a2"][row], t["R"][row]) == (A2[i], R[j])
    dc1 = local["grid_dc1"][i, j]
    realised = A2[i] * local["grid_x2bar"][i, j]
    assert t["mae_ekf1_realised"][row] == pytest.approx(np.mean(np.abs(dc1 - realised)),
                                                        rel=1e-12)
    assert t["mae_ekf1_empirical"][row] == pytest.approx(
        np.mean(np.abs(dc1 - local["grid_zbar"][i, j])), rel=1e-12)
    assert t["mae_ekf3_expected"][row] == pytest.approx(
        np.mean(np.abs(local["grid_dc3"][i, j] - A2[i] * Q)), rel=1e-12)


def test_ekf1_minus_ekf2_is_a2_times_the_stationary_posterior_variance(local):
    # A = 0: x- = 0, so H = a1, P- = Q and P+ = Q R / (a1^2 Q + R) at every sample, exactly
    for i, a2 in enumerate(A2):
        for j, r in enumerate(R):
            gap = local["grid_dc1"][i, j] - local["grid_dc2"][i, j]
            want = a2 * Q * r / (Q + r)
            assert np.max(np.abs(gap / want - 1.0)) < 1e-9


def test_ekf1_is_unbiased_against_the_realised_drift(local):
    for i in range(2):
        for j in range(2):
            err = local["grid_dc1"][i, j] - A2[i] * local["grid_x2bar"][i, j]
            # 5 standard errors of the mean over the runs
            assert abs(err.mean()) < 5 * err.std(ddof=1) / math.sqrt(RUNS)


def test_letters_claims_smaller_a2_and_R_better_and_ekf1_beats_ekf3(local):
    t = local["table"]
    mae1 = t["mae_ekf1_realised"].reshape(2, 2)
    mae3 = t["mae_ekf3_realised"].reshape(2, 2)
    assert np.all(mae1 < mae3)
    assert np.all(np.diff(mae1, axis=0) > 0) and np.all(np.diff(mae1, axis=1) > 0)
    assert np.all(np.diff(mae3, axis=0) > 0) and np.all(np.diff(mae3, axis=1) > 0)


def test_in_process_equals_worker_processes(local):
    single = sweep.sweep(workers=1, **KW)
    for key in GRID_KEYS:
        assert np.array_equal(single[key], local[key]), key


@pytest.mark.qualification  # a Dask cluster of worker processes
def test_local_dask_cluster_equals_local_workers(local, tmp_path):
    LocalCluster = pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] "
                                       "is not installed").LocalCluster
    import dask  # its scratch folder in this test's, not dask-scratch-space in TMPDIR
    with dask.config.set({"temporary-directory": str(tmp_path)}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                         dashboard_address=None) as cluster:
        done = []
        remote = sweep.sweep(scheduler=cluster.scheduler_address, chunk=64,
                             progress=done.append, **KW)
    for key in GRID_KEYS:
        assert np.array_equal(remote[key], local[key]), key
    assert done[-1] == 4 * RUNS


@pytest.mark.integration
def test_fmu_engine_equals_batch_engine(built_fmus):
    kw = dict(a2=[0.01, 0.3], R=[1e-3], runs=2, n=50, seed=11)
    fmu = sweep.sweep(engine="fmu", workers=2, fmu_dir=built_fmus["Excitation"].parent, **kw)
    want = sweep.sweep(**kw)
    for key in GRID_KEYS:
        assert np.array_equal(fmu[key], want[key]), key


def test_files_are_written(local, tmp_path):
    sweep.write(tmp_path, local)
    with np.load(tmp_path / "sweep.npz") as z:
        assert set(z.files) == {"grid_a2", "grid_R"} | set(GRID_KEYS)
        assert z["grid_dc1"].shape == (2, 2, RUNS)
        assert np.array_equal(z["grid_zbar"], local["grid_zbar"])
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert lines[0].split(",") == list(sweep.CSV_COLUMNS)
    assert len(lines) == 5
    for fig in ("fig2.png", "fig3.png"):
        assert (tmp_path / fig).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("kw, match", [
    (dict(a2=[]), "a2 grid is empty"),
    (dict(R=[]), "R grid is empty"),
    (dict(R=[1e-4, 0.0]), r"R = 0.0 is out of range; allowed: R > 0"),
    (dict(R=[-1e-3]), r"R = -0.001 is out of range"),
    (dict(runs=0), "runs = 0 is out of range; allowed: an integer runs >= 1"),
    (dict(engine="gpu"), "engine = 'gpu' is not allowed"),
    (dict(seed=2 ** 31 - 10, runs=20), "seed"),
    (dict(a2=[0.01, 0.02, 0.01]), r"the a2 grid has 0.01 more than once; allowed: distinct"),
    (dict(R=[1e-4, 1e-4]), r"the R grid has 0.0001 more than once"),
    pytest.param(dict(Q=-1e-300), r"Q = -1e-300 is out of range; allowed: Q >= 0",
                 id="Q below 0"),
    pytest.param(dict(Q=float("nan")), r"Q = nan is not finite; allowed: a finite value with "
                 r"Q >= 0", id="Q nan"),
])
def test_bad_input_is_refused_before_anything_runs(kw, match):
    args = dict(KW, **kw)
    with pytest.raises(ValueError, match=match):
        sweep.sweep(**args)


def test_a_sweep_without_process_noise_runs():
    """Q = 0, the bound of Q >= 0 (one past it is refused above): the sweep runs."""
    res = sweep.sweep(**dict(KW, Q=0.0, runs=2, n=20))
    assert res["grid_dc1"].shape == (2, 2, 2) and np.all(np.isfinite(res["grid_zbar"]))


def test_cli_writes_the_files_and_prints_its_wall_time(tmp_path, capsys):
    out = tmp_path / "sw"
    assert main(["sweep", "--a2", "0.01", "0.1", "--R", "1e-4", "--runs", "20", "--n", "50",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "ns per sample-run" in text and "sample-runs in" in text
    assert sorted(p.name for p in out.iterdir()) == ["fig2.png", "fig3.png", "sweep.csv",
                                                     "sweep.npz"]


@pytest.mark.parametrize("argv", [["--R", "0"], ["--R", "-1e-4"], ["--runs", "0"], ["--a2"],
                                  ["--workers", "0"]])
def test_cli_bad_options_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["sweep"] + argv)
    assert exc.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_cli_unreachable_scheduler_exits_1_quickly_and_writes_nothing(tmp_path, capsys,
                                                                      monkeypatch):
    pytest.importorskip("dask.distributed", reason="the extra driftfmu[dask] is not installed")
    out = tmp_path / "none"
    probes = []  # "quickly": the connection attempt is bounded (checked on the call, not timed)
    probe = batch._probe
    monkeypatch.setattr(batch, "_probe", lambda s, t: probes.append((s, t)) or probe(s, t))
    assert main(["sweep", "--runs", "2", "--n", "5", "--scheduler", "tcp://127.0.0.1:1",
                 "--out", str(out)]) == 1
    assert probes == [("tcp://127.0.0.1:1", batch.CONNECT_TIMEOUT)]
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no Dask scheduler answered at 'tcp://127.0.0.1:1'" in err[0]
    assert not out.exists() or not any(out.iterdir())


def test_an_a2_grid_with_zero_and_negative_values_is_drawn_without_a_warning(tmp_path):
    """a2 = 0 alone gave six "Data has no positive values, and therefore cannot be log-scaled"
    warnings and empty figures; a negative a2 was dropped from the log axis."""
    import warnings
    for i, a2 in enumerate(([0.0], [-0.01, 0.0, 0.01])):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            sweep.sweep(**dict(KW, a2=a2, out=tmp_path / str(i)))
        assert [str(w.message) for w in seen] == []
        for fig in ("fig2.png", "fig3.png"):
            assert (tmp_path / str(i) / fig).read_bytes()[:4] == b"\x89PNG"
