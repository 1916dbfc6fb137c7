"""The bias state in the batch engine (``batch.simulate(bias=1, ...)``): NumPy and the compiled
kernel give the same bits, run ``r`` is the chain of seed ``r`` through models/ on floats and
the DriftEstimator slave fed with that chain's outputs, and a covariance past double precision
stops both engines with the same error."""
import numpy as np
import pytest

from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.models import bias, chain, covariance, drift, excitation
from driftfmu.simulations import batch, kernel
from driftfmu.simulations.errors import UsageError

from test_bias import PAST_PRECISION
from test_slaves import get, set_var

CASES = [dict(bias=1, Qb=1e-8, tau_b=0.0, b0=0.01, Pb0=1e-3),
         dict(bias=1, Qb=1e-7, tau_b=0.02, Pb0=1e-2, A=0.7, a2=0.05, a3=0.01, a4=0.02, B=0.5,
              drive=excitation.SINUSOIDAL, Xu=0.4, fu=30.0),
         dict(bias=1, Qb=np.array([0.0, 1e-9, 1e-6, 1e-4] * 4), tau_b=np.linspace(0, 1, 16),
              Pb0=1e-4, a2=0.1)]


def _kernel():
    if kernel.library() is None:
        pytest.skip("no C compiler: the compiled kernel is not available")


@pytest.mark.parametrize("case", range(len(CASES)))
def test_numpy_and_the_kernel_give_the_same_bits(case):
    _kernel()
    seeds = batch.run_seeds(50, 16)
    record = batch.TRAJECTORIES + batch.BIAS_OUTPUTS
    a = batch.simulate(250, seeds, kernel="numpy", record=record, **CASES[case])
    b = batch.simulate(250, seeds, kernel="c", record=record, **CASES[case])
    assert sorted(a) == sorted(b)
    for key in a:
        assert a[key].tobytes() == b[key].tobytes(), key
    assert {"final_b_hat", "final_P_bb", "final_P_xb", "b_hat"} <= set(a)


@pytest.mark.parametrize("case", [0, 1])
def test_a_run_is_the_chain_of_its_seed_and_the_slaves_bits(case):
    kw = dict(CASES[case])
    n, seeds = 150, batch.run_seeds(70, 3)
    out = batch.simulate(n, seeds, record=("b_hat", "x_hat", "dc_ekf1"), kernel="numpy", **kw)
    chain_kw = {k: kw[k] for k in ("A", "a2", "a3", "a4", "B", "drive", "Xu", "fu") if k in kw}
    A, Q = kw.get("A", 0.0), 0.01
    Fb = bias.factor(kw["tau_b"], 1e-3)
    for r, seed in enumerate(seeds):
        cols = chain.simulate(n, int(seed), **chain_kw)
        us = [excitation.input_sample(kw.get("drive", 0), int(seed), k, 0.0, kw.get("Xu", 0.0),
                                      kw.get("fu", 0.0), 1e-3) for k in range(1, n + 1)]
        st = chain.estimator_init(0.0, Q / (1 - A * A))
        b = bias.init(kw.get("b0", 0.0), kw["Pb0"])
        s = DriftEstimator(instance_name="d")  # the FMU's slave class with the same values
        s.setup_experiment(0.0)
        s.enter_initialization_mode()
        for name in ("bias", "Qb", "tau_b", "b0", "Pb0", "A", "a2", "a3", "a4", "B"):
            if name in kw:
                set_var(s, name, kw[name])
        set_var(s, "P0", Q / (1 - A * A))
        s.exit_initialization_mode()
        for k in range(n):
            z, u = cols["z"][k], us[k]
            st, b = bias.estimator_step(st, b, z, 0.0, 1.0, kw.get("a2", 0.01), A, Q, 1e-4, Fb,
                                        kw["Qb"], kw.get("a3", 0.0), kw.get("a4", 0.0),
                                        kw.get("B", 0.0), u)
            assert (out["x_hat"][r, k], out["b_hat"][r, k]) == (st.x, b.b), (r, k)
            set_var(s, "z", z)
            set_var(s, "u", u)
            assert (get(s, "x_hat"), get(s, "b_hat")) == (st.x, b.b), (r, k)
            assert s.do_step(k * 1e-3, 1e-3)
        dc1 = drift.estimates(st.drift, kw.get("a2", 0.01), kw.get("a3", 0.0),
                              kw.get("a4", 0.0))[0]
        assert (out["final_P_bb"][r], out["final_P_xb"][r], out["final_dc_ekf1"][r]) == \
            (b.Pbb, b.Pxb, dc1)


@pytest.mark.parametrize("engine", ["numpy", "c"])
def test_a_covariance_past_double_precision_stops_the_batch_with_the_same_error(engine):
    if engine == "c":
        _kernel()
    seeds = batch.run_seeds(5, 4)
    kw = dict(PAST_PRECISION, bias=1, Qb=PAST_PRECISION["Qb"], Pb0=PAST_PRECISION["Pb0"])
    with pytest.raises(covariance.CovarianceError) as info:
        batch.simulate(5, seeds, kernel=engine, **kw)
    text = str(info.value)
    assert text.startswith("P_bb of the bias filter would be -") and \
        "at sample 2 in run 0 (seed 5), a negative variance" in text, text
    batch.simulate(1, seeds, kernel=engine, **kw)  # (sample 1 is valid)


def test_without_the_bias_state_nothing_is_added_and_its_outputs_cannot_be_recorded():
    out = batch.simulate(20, batch.run_seeds(1, 2), kernel="numpy")
    assert not {"final_b_hat", "final_P_bb", "final_P_xb"} & set(out)
    with pytest.raises(UsageError, match=r"cannot record \['b_hat'\]"):
        batch.simulate(20, batch.run_seeds(1, 2), record=("b_hat",))
    with pytest.raises(UsageError, match="bias = 2 is out of range; allowed: an integer bias"):
        batch.simulate(20, batch.run_seeds(1, 2), bias=2)


@pytest.mark.parametrize("kw,text", [
    (dict(Qb=-1e-12), "Qb = -1e-12 is out of range; allowed: Qb >= 0"),
    (dict(Pb0=np.array([1e-4, -1e-4])), "Pb0 = -0.0001 is out of range; allowed: Pb0 >= 0"),
    (dict(tau_b=-1.0), "tau_b = -1.0 is out of range; allowed: tau_b >= 0"),
])
def test_bad_bias_parameters_are_refused_in_one_line(kw, text):
    with pytest.raises(UsageError) as info:
        batch.simulate(5, batch.run_seeds(1, 2), bias=1, **kw)
    assert str(info.value) == text
    batch.simulate(5, batch.run_seeds(1, 2), bias=1, **{k: 0.0 * np.asarray(v) for k, v in
                                                          kw.items()})  # (the bound itself)
