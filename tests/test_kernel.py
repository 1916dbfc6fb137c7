"""The compiled batch kernel (simulations/kernel.py, batch_kernel.c): bit for bit the NumPy batch
engine, models.adxl203.simulate and the FMUs, over random parameters; NumPy when switched off."""
import numpy as np
import pytest

from driftfmu.models import adxl203, excitation, harmonic
from driftfmu.simulations import batch, kernel


@pytest.fixture(scope="module")
def lib():
    found = kernel.library()
    if found is None:
        pytest.skip("no C compiler (cc): the kernel cannot be compiled")
    return found


def _random_params(rng, runs, kind):
    return dict(a0=rng.normal(size=runs), a1=rng.uniform(0.5, 2.0, runs),
                a2=rng.uniform(0.0, 0.3, runs), A=rng.uniform(-0.95, 0.95, runs),
                Q=rng.uniform(1e-3, 1.0, runs), R=rng.uniform(1e-6, 1e-2, runs),
                x0=rng.normal(size=runs), Ts=rng.uniform(1e-4, 1e-2, runs), kind=kind,
                X=rng.uniform(0.1, 2.0, runs), f=rng.uniform(1.0, 40.0, runs),
                phi=rng.uniform(0.0, 6.3, runs), filter_A=rng.uniform(-0.5, 0.5, runs),
                filter_Q=rng.uniform(1e-3, 1.0, runs))


def _same(a, b):
    assert sorted(a) == sorted(b)
    for key in a:
        assert a[key].shape == b[key].shape and a[key].tobytes() == b[key].tobytes(), key


@pytest.mark.parametrize("kind", [excitation.GAUSSIAN, excitation.SINUSOIDAL])
@pytest.mark.parametrize("runs, n", [(1, 1), (13, 257), (40, 64)])
def test_kernel_equals_numpy_engine_over_random_parameters(lib, kind, runs, n):
    rng = np.random.default_rng(1000 * kind + runs)
    seeds = batch.run_seeds(int(rng.integers(0, 10 ** 6)), runs)
    kw = _random_params(rng, runs, kind)
    want = batch.simulate(n, seeds, record=batch.TRAJECTORIES, kernel="numpy", **kw)
    got = batch.simulate(n, seeds, record=batch.TRAJECTORIES, kernel="c", **kw)
    _same(want, got)


def _general_cases(rng, runs):
    """The general model's parameters: a3 and a4 shared or per run (some runs at 0), the known
    input's two drives with B shared or per run, B without an input, all of it on a sine."""
    some = rng.random(runs) > 0.3
    return [dict(a3=0.02, a4=0.01),
            dict(a4=rng.uniform(0.0, 0.05, runs) * some),
            dict(a3=rng.uniform(-0.05, 0.05, runs)),
            dict(B=0.5, drive=excitation.GAUSSIAN, Qu=0.2),
            dict(B=rng.uniform(-1.0, 1.0, runs), drive=excitation.SINUSOIDAL, Xu=1.2, fu=37.0,
                 a3=0.01),
            dict(B=0.7),
            dict(a3=0.02, a4=0.01, B=0.4, drive=excitation.GAUSSIAN, Qu=0.3,
                 kind=excitation.SINUSOIDAL, X=1.1, f=30.0)]


@pytest.mark.parametrize("record", [(), batch.TRAJECTORIES])
@pytest.mark.parametrize("case", range(7))
def test_kernel_equals_numpy_engine_for_the_general_model(lib, case, record):
    rng = np.random.default_rng(50 + case)
    runs = 23
    kw = dict(a2=rng.uniform(0.0, 0.1, runs), A=0.6, Q=0.05, R=1e-3, x0=0.1)
    kw.update(_general_cases(rng, runs)[case])
    seeds = batch.run_seeds(int(rng.integers(0, 10 ** 6)), runs)
    _same(batch.simulate(300, seeds, record=record, kernel="numpy", **kw),
          batch.simulate(300, seeds, record=record, kernel="c", **kw))


def test_kernel_scalar_parameters_and_default_p0_equal_numpy(lib):
    seeds = batch.run_seeds(3, 9)
    for kw in (dict(), dict(a2=0.1, R=1e-3, A=0.5), dict(P0=0.3, x0=0.2)):
        _same(batch.simulate(100, seeds, record=("dc_ekf1", "x"), kernel="numpy", **kw),
              batch.simulate(100, seeds, record=("dc_ekf1", "x"), kernel="c", **kw))


@pytest.mark.parametrize("record", [(), ("dc_ekf1", "x")])
def test_kernel_calls_of_any_length_give_the_same_bits(lib, monkeypatch, record):
    """The kernel is called over blocks of samples: 1/32 of n for a progress report, about
    KERNEL_CALL sample-runs otherwise; a run's bits do not depend on where blocks end."""
    rng = np.random.default_rng(7)
    seeds = batch.run_seeds(5, 37)
    kw = _random_params(rng, 37, excitation.GAUSSIAN)
    want = batch.simulate(700, seeds, record=record, kernel="numpy", **kw)
    _same(want, batch.simulate(700, seeds, record=record, kernel="c", **kw))  # one call
    _same(want, batch.simulate(700, seeds, record=record, kernel="c", progress=lambda k: None,
                               **kw))
    monkeypatch.setattr(batch, "KERNEL_CALL", 1)  # blocks of BLOCK samples
    _same(want, batch.simulate(700, seeds, record=record, kernel="c", **kw))


def test_kernel_progress_reaches_n(lib):
    seen = []
    batch.simulate(1000, batch.run_seeds(1, 3), progress=seen.append, kernel="c")
    assert seen == sorted(seen) and seen[-1] == 1000 and len(seen) > 1


def test_switched_off_kernel_gives_numpy_and_c_is_refused(lib, monkeypatch):
    monkeypatch.setenv("DRIFTFMU_KERNEL", "numpy")
    assert kernel.library() is None
    seeds = batch.run_seeds(2, 4)
    _same(batch.simulate(50, seeds, record=("z",)),
          batch.simulate(50, seeds, record=("z",), kernel="numpy"))
    with pytest.raises(RuntimeError, match="kernel is not available.*DRIFTFMU_KERNEL=numpy"):
        batch.simulate(50, seeds, kernel="c")
    with pytest.raises(ValueError, match="kernel = 'fortran' is not allowed; allowed: auto"):
        batch.simulate(50, seeds, kernel="fortran")


def _adxl_values(rng, process, axes, extras):
    seed = int(rng.integers(1, 10 ** 6))
    f = float(rng.uniform(50.0, 200.0))
    if rng.uniform() < 0.5:
        ex = dict(kind=excitation.SINUSOIDAL, X=float(rng.uniform(0.5, 1.6)), f=f,
                  phi=float(rng.uniform(0, 6.3)), Xy=float(rng.uniform(0, 0.1)),
                  phiy=float(rng.uniform(0, 6.3)), seed=seed)
    else:
        ex = dict(kind=excitation.GAUSSIAN, A=float(rng.uniform(-0.9, 0.9)),
                  Q=float(rng.uniform(0.01, 0.5)), x0=float(rng.normal()), seed=seed)
    sp = dict(adxl203.ADXL203, seed=seed + 1, axes=axes, noise=int(rng.uniform() < 0.8))
    if not extras:
        sp.update(adxl203.EXTRAS_OFF, axes=axes, a0=0.1, R=1e-3)
    es = dict(a0=float(sp["a0"]), a1=1.0, a2=float(rng.uniform(0.0, 0.05)), R=1e-4,
              process=process, f=f, Qh=1e-3, x0=0.0, P0=float(rng.uniform(0.1, 3.0)),
              A=float(rng.uniform(-0.5, 0.5)), Q=float(rng.uniform(0.01, 1.0)),
              estimator=int(rng.integers(1, 4)))
    return ex, sp, es


@pytest.mark.parametrize("process", [harmonic.GAUSS_MARKOV, harmonic.HARMONIC])
@pytest.mark.parametrize("axes, extras", [(1, False), (2, True), (1, True)])
def test_adxl203_chain_equals_models(lib, process, axes, extras):
    rng = np.random.default_rng(7 * process + 3 * axes + extras)
    for _ in range(2):
        ex, sp, es = _adxl_values(rng, process, axes, extras)
        Ts = 1e-4
        want = adxl203.simulate(400, ex, sp, es, Ts)
        got = kernel.adxl203_simulate(lib, 400, ex, sp, es, Ts)
        for c in kernel.COLUMNS:
            assert np.asarray(want[c]).tobytes() == got[c].tobytes(), c


def test_adxl203_kernel_refuses_an_unknown_estimator(lib):
    with pytest.raises(ValueError, match="estimator = 4"):
        kernel.adxl203_simulate(lib, 10, {}, {}, dict(estimator=4), 1e-3)


@pytest.mark.integration
@pytest.mark.parametrize("kind", [excitation.GAUSSIAN, excitation.SINUSOIDAL])
def test_kernel_equals_the_fmus_sample_by_sample(lib, built_fmus, kind):
    fmu_dir = built_fmus["Excitation"].parent
    rng = np.random.default_rng(kind)
    seeds = batch.run_seeds(int(rng.integers(0, 10 ** 6)), 2)
    a2 = rng.uniform(0.0, 0.3, 2)
    R = rng.uniform(1e-6, 1e-2, 2)
    kw = dict(kind=kind, A=0.4, X=1.2, f=40.0)
    if kind == excitation.SINUSOIDAL:
        kw.update(filter_A=0.0, filter_Q=0.7)
    res = batch.simulate(150, seeds, a2=a2, R=R, record=batch.TRAJECTORIES, kernel="c", **kw)
    for r in range(2):
        fmu = batch.fmu_simulate(150, int(seeds[r]), a2=float(a2[r]), R=float(R[r]),
                                 fmu_dir=fmu_dir, record=batch.TRAJECTORIES, **kw)
        for c in batch.TRAJECTORIES + tuple("final_" + f for f in batch.FINALS):
            assert np.array_equal(np.asarray(fmu[c]), res[c][r]), (r, c)


def _dual_values(rng, process, kind):
    from driftfmu.models import dualaxis
    f = float(rng.uniform(5.0, 60.0))
    ex = dict(kind=kind, A=float(rng.uniform(-0.9, 0.9)), Q=float(rng.uniform(0.01, 0.5)),
              Qy=float(rng.uniform(0.0, 0.5)), rho=float(rng.uniform(-0.9, 0.9)),
              x0=float(rng.normal()), X=float(rng.uniform(0.3, 1.5)), f=f,
              phi=float(rng.uniform(0, 6.3)), Xy=float(rng.uniform(0, 1.0)),
              phiy=float(rng.uniform(0, 6.3)))
    poly = dict(a0=float(rng.normal()), a1=float(rng.uniform(0.5, 1.5)),
                a2=float(rng.uniform(0, 0.2)), bx=float(rng.uniform(-0.1, 0.1)),
                R=float(rng.uniform(1e-5, 1e-2)), a0y=float(rng.normal()),
                a1y=float(rng.uniform(0.5, 1.5)), a2y=float(rng.uniform(0, 0.2)),
                by=float(rng.uniform(-0.1, 0.1)), Ry=float(rng.uniform(1e-5, 1e-2)))
    sp = dict(poly, noise=int(rng.uniform() < 0.8))
    es = dict(poly, A=ex["A"], Q=ex["Q"], Qy=float(rng.uniform(0.01, 0.5)), rho=ex["rho"],
              x0=0.1, y0=-0.2, P0=float(rng.uniform(0.01, 1.0)),
              P0y=float(rng.uniform(0.01, 1.0)), f=f, Qh=1e-3, process=process,
              estimator=int(rng.integers(1, 4)))
    assert set(es) <= set(dualaxis.estimator_values())
    return ex, sp, es


@pytest.mark.parametrize("process", [harmonic.GAUSS_MARKOV, harmonic.HARMONIC])
@pytest.mark.parametrize("kind", [excitation.GAUSSIAN, excitation.SINUSOIDAL])
def test_dual_axis_chain_equals_numpy_over_random_parameters(lib, process, kind):
    from driftfmu.models import dualaxis
    rng = np.random.default_rng(10 * process + kind)
    for _ in range(2):
        ex, sp, es = _dual_values(rng, process, kind)
        seeds = batch.run_seeds(int(rng.integers(0, 10 ** 6)), 5)
        want = batch.dual_simulate(120, seeds, ex, sp, es, 1e-3, record=dualaxis.COLUMNS,
                                   kernel="numpy")
        got = batch.dual_simulate(120, seeds, ex, sp, es, 1e-3, record=dualaxis.COLUMNS,
                                  kernel="c")
        _same(want, got)


def test_dual_axis_per_run_values_fall_back_to_numpy(lib):
    seeds = batch.run_seeds(4, 3)
    ex = dict(kind=excitation.SINUSOIDAL, phi=np.array([0.1, 0.2, 0.3]), Xy=0.5)
    assert kernel.dual_simulate(lib, 10, seeds, ex, {}, {}, 1e-3) is None
    _same(batch.dual_simulate(40, seeds, ex, {}, {}, 1e-3, record=("x",), kernel="numpy"),
          batch.dual_simulate(40, seeds, ex, {}, {}, 1e-3, record=("x",), kernel="c"))


def test_dual_axis_kernel_refuses_an_unknown_process(lib):
    with pytest.raises(ValueError, match="process = 7"):
        kernel.dual_simulate(lib, 10, batch.run_seeds(1, 2), {}, {}, dict(process=7), 1e-3)


def test_sweep_and_montecarlo_give_the_same_bits_with_the_kernel_or_numpy(lib, monkeypatch):
    from driftfmu.simulations import montecarlo, sweep
    kw = dict(a2=(0.01, 0.1), R=(1e-4, 1e-2), runs=6, n=80, workers=1, plot=False)
    mc = dict(runs=4, n=60, workers=1, plot=False)
    with_kernel = sweep.sweep(**kw), montecarlo.montecarlo_gaussian(**mc)
    monkeypatch.setenv("DRIFTFMU_KERNEL", "numpy")
    without = sweep.sweep(**kw), montecarlo.montecarlo_gaussian(**mc)
    for a, b in zip(with_kernel, without):
        keys = [k for k in a if isinstance(a[k], np.ndarray)]
        assert keys
        for key in keys:
            assert a[key].tobytes() == b[key].tobytes(), key
    for col in with_kernel[0]["table"]:
        assert with_kernel[0]["table"][col].tobytes() == without[0]["table"][col].tobytes()


def test_the_kernel_has_no_fused_multiply_add(lib):
    """-ffp-contract=off forbids fusing a*b + c; the kernel is compiled without the SLP
    vectoriser, whose complex-arithmetic patterns fuse anyway on GCC 12 (kernel.SPEED_FLAGS):
    no FMA instruction in the library, where it can be disassembled (x86-64 with objdump)."""
    import platform
    import re
    import shutil
    import subprocess
    if platform.machine() not in ("x86_64", "AMD64") or not shutil.which("objdump"):
        pytest.skip("needs x86-64 and objdump")
    # the library as loaded: by the descriptor it was checked through (simulations/trust.py),
    # which objdump gets too
    fds = ((int(lib._name.rsplit("/", 1)[1]),) if lib._name.startswith("/proc/self/fd/")
           else ())
    text = subprocess.run(["objdump", "-d", lib._name], capture_output=True, text=True,
                          check=True, pass_fds=fds).stdout
    assert "Disassembly of section .text" in text, text[:500]
    fused = sorted(set(re.findall(r"\bv?f(?:n?m(?:add|sub)\w*)", text)))
    assert fused == [], fused
