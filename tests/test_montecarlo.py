"""``driftfmu montecarlo``: trajectories per run equal the batch engine, the settle statistic
equals the single-run one, the letter's Fig. 1 claims over a population, files and errors."""
import math

import numpy as np
import pytest

from driftfmu.models import drift
from driftfmu.simulations import batch, gaussian, montecarlo
from driftfmu.simulations.cli import main

RUNS = 50
N = 300
KEYS = ("fig1_x", "fig1_z", "fig1_dc1", "fig1_dc2", "fig1_dc3")


@pytest.fixture(scope="module")
def gauss():
    return montecarlo.montecarlo_gaussian(runs=RUNS, n=N, seed=2, workers=2)


@pytest.fixture(scope="module")
def sine():
    return montecarlo.montecarlo_sinusoidal(runs=RUNS, n=N, seed=2, workers=2)


def test_gaussian_trajectories_are_the_batch_engines(gauss):
    for key in KEYS:
        assert gauss[key].shape == (RUNS, N), key
    want = batch.simulate(N, batch.run_seeds(2, RUNS), record=montecarlo.RECORD)
    for key, name in montecarlo.GAUSSIAN_KEYS.items():
        assert np.array_equal(gauss[key], want[name]), key


def test_settled_from_equals_the_single_run_statistic(gauss):
    est, ref = gauss["fig1_dc3"][:10], gauss["fig1_dc_realised"][:10]
    # add a row that never settles and one that is always inside the band
    est = np.vstack([est, 2 * ref[0], ref[0]])
    ref = np.vstack([ref, ref[0], ref[0]])
    got = montecarlo.settled_from(est, ref)
    want = [gaussian.settled_from(list(e), list(r)) for e, r in zip(est, ref)]
    assert [None if g == N + 1 else int(g) for g in got] == want
    assert want[-2] is None and want[-1] == 1


def test_runs_shorter_than_the_settle_sample_are_not_counted_as_settled():
    est = np.array([[1.0, 1.0, 1.0], [5.0, 1.0, 1.0], [1.0, 1.0, 5.0]])
    ref = np.ones_like(est)
    traj = {"dc_ekf1": est, "dc_ekf2": est, "dc_ekf3": est, "dc_realised": ref}
    s = montecarlo.summarise(traj, ("realised",))
    assert s["settled_fraction"]["realised"]["ekf1"] == pytest.approx(2 / 3)


def test_letters_fig1_claims_over_the_population(gauss):
    s = gauss["summary"]
    assert s["settled_fraction"]["realised"]["ekf1"] == 1.0
    assert s["settled_fraction"]["realised"]["ekf2"] == 1.0
    assert s["settled_fraction"]["realised"]["ekf3"] < 1.0
    # the gap: 10 log10(1 + R/(a1^2 Q)) to within 5 standard errors over the runs plus the
    # finite-n bias of a ratio of running means (a few per cent at n = 300)
    g = s["ekf1_ekf2_gap_db"]
    expected = drift.expected_gap_db(1.0, 0.01, 1e-4)
    assert g["expected"] == expected
    assert abs(g["mean"] - expected) < 5 * g["std"] / math.sqrt(RUNS) + 0.05 * expected
    assert g["max_abs"] < 0.05 * 2  # "< 0.05 dB", with room for the spread of single runs


def test_sinusoidal_runs(sine):
    assert sine["sine_dc1"].shape == (RUNS, N)
    phi = sine["sine_phi"]
    assert np.all((0.0 <= phi) & (phi < 2 * math.pi)) and len(np.unique(phi)) == RUNS
    assert phi[3] == batch.sine_phase(batch.run_seed(2, 3))
    want = batch.simulate(N, batch.run_seeds(2, RUNS), kind=2, phi=phi, filter_A=0.0,
                          filter_Q=0.5, record=("dc_ekf1",))
    assert np.array_equal(sine["sine_dc1"], want["dc_ekf1"])
    s = sine["summary"]
    assert s["settled_fraction"]["realised"]["ekf1"] == 1.0
    # EKF1 against the expected drift a2 X^2 / 2 at the last sample: within 5 % on every run
    assert np.all(np.abs(sine["sine_dc1"][:, -1] / s["dc_expected"] - 1.0) < 0.05)


def test_bad_input():
    with pytest.raises(ValueError, match="runs = 0 is out of range; allowed: an integer runs >= 1"):
        montecarlo.montecarlo_gaussian(runs=0)
    with pytest.raises(ValueError, match="R = 0 is out of range"):
        montecarlo.montecarlo_gaussian(runs=2, n=5, R=0)
    with pytest.raises(ValueError, match="Nyquist"):
        montecarlo.montecarlo_sinusoidal(runs=2, n=5, f=600.0)


@pytest.mark.integration
def test_fmu_engine_equals_batch_engine(built_fmus):
    kw = dict(runs=2, n=40, seed=9, fmu_dir=built_fmus["Excitation"].parent)
    for fn in (montecarlo.montecarlo_gaussian, montecarlo.montecarlo_sinusoidal):
        fmu = fn(engine="fmu", workers=2, **kw)
        want = fn(**kw)
        for key in want:
            if isinstance(want[key], np.ndarray):
                assert np.array_equal(fmu[key], want[key]), (fn.__name__, key)


@pytest.mark.parametrize("kind, files", [("gaussian", "fig1.png"), ("sinusoidal", "sine.png")])
def test_cli_writes_files_and_prints_the_summary(kind, files, tmp_path, capsys):
    out = tmp_path / kind
    assert main(["montecarlo", kind, "--runs", "20", "--n", "260", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "settled by 250" in text and "EKF1-EKF2 gap" in text
    assert sorted(p.name for p in out.iterdir()) == sorted(["montecarlo.npz", "summary.json",
                                                            files])
    with np.load(out / "montecarlo.npz") as z:
        key = "fig1_dc1" if kind == "gaussian" else "sine_dc1"
        assert z[key].shape == (20, 260)


@pytest.mark.parametrize("argv", [["gaussian", "--runs", "0"], ["sinusoidal", "--R", "0"],
                                  ["gaussian", "--engine", "gpu"]])
def test_cli_bad_options_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["montecarlo"] + argv)
    assert exc.value.code == 2


def test_montecarlo_sinusoidal_filters_with_the_Q_given():
    """Q given is the filter's (default X^2 / 2): its summary says so and the estimates differ."""
    given = montecarlo.montecarlo_sinusoidal(runs=2, n=40, Q=0.3, plot=False)
    default = montecarlo.montecarlo_sinusoidal(runs=2, n=40, plot=False)
    assert given["summary"]["parameters"]["Q"] == 0.3
    assert default["summary"]["parameters"]["Q"] == 0.5
    assert not np.array_equal(given["sine_dc1"], default["sine_dc1"])


def test_the_gap_in_db_is_log10_to_a_few_ulp_and_takes_no_cpus_simd():
    """montecarlo's dB (10 log10 of EKF1/EKF2) is models._ops.log's, the same bits on every
    machine (NumPy's log10 of an array takes the CPU's SIMD code, which differs in the last bits
    between AVX-512 and AVX2): within 4 ulp of math.log10 over ratios from 1e-300 to 1e300, the
    float path's bits on arrays, and log10's answers at 0, inf, negative numbers and nan."""
    from driftfmu.models import _ops, errors
    rng = np.random.default_rng(11)
    ratios = np.concatenate([10.0 ** rng.uniform(-300, 300, 3000),
                             rng.uniform(0.5, 2.0, 3000), [1.0, 10.0, 5e-324, 1.7e308]])
    got = montecarlo._db(ratios)
    for r, g in zip(ratios, got):
        want = 10.0 * math.log10(r)
        assert abs(g - want) <= 4 * math.ulp(want) + 1e-300, r
        assert g == montecarlo._db_of(float(r)) == 10.0 * (_ops.log(float(r)) / errors.LN10)
    assert montecarlo._db(np.array([])).size == 0
    assert montecarlo._db_of(0.0) == -math.inf and montecarlo._db_of(math.inf) == math.inf
    assert all(math.isnan(montecarlo._db_of(v)) for v in (-1.0, -math.inf, math.nan))


def test_the_gap_summary_keeps_only_finite_positive_ratios():
    """summary's gap statistics over the runs whose final EKF1/EKF2 ratio is finite and
    positive (as 10 log10 was finite for them): a run with EKF2 = 0 and one with a negative
    EKF1 are left out of the mean, std and max; of_means is 10 log10 of the means' ratio."""
    traj = dict(final_dc_ekf1=np.array([2.0, 1.0, -1.0, 4.0]),
                final_dc_ekf2=np.array([1.0, 0.0, 1.0, 2.0]))
    for e in ("ekf1", "ekf2", "ekf3"):
        for ref in ("empirical", "realised"):
            traj["settled_%s_%s" % (ref, e)] = np.array([1, 1, 1, 1])
    traj.update(dc_ekf1=np.zeros((4, 10)), dc_empirical=np.zeros((4, 10)),
                dc_realised=np.zeros((4, 10)))
    s = montecarlo.summarise(traj, ("realised", "empirical"))
    g = s["ekf1_ekf2_gap_db"]
    assert g["mean"] == pytest.approx(10.0 * math.log10(2.0), rel=1e-15)
    assert g["std"] == 0.0 and g["max_abs"] == g["mean"]
    assert g["of_means"] == pytest.approx(10.0 * math.log10(1.5 / 1.0), rel=1e-15)
