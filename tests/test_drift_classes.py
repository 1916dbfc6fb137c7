"""``driftfmu experiment drift-classes``: each of the letter's drift classes, alone and all
together, is removed from ``z_comp`` down to a bound derived from the settings, and really is
in ``z`` before (docs/results.md, "The drift classes"; docs/method.md, section 12).

The statistical claims run on :func:`driftfmu.simulations.drift_classes.reference` (the same
models/ functions on arrays as the FMUs, which the experiment checks bit for bit: the test of
the FMU path below) at three fixed seeds and a shorter run than the experiment's; the bounds
follow the run's length (:func:`~driftfmu.simulations.drift_classes.sigma`)."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import driftfmu
from driftfmu.models import bias as bias_model
from driftfmu.models import errors
from driftfmu.simulations import batch
from driftfmu.simulations import drift_classes as dcl
from driftfmu.simulations.errors import UsageError

#: The tests' settings: the experiment's, with runs of 20,000 samples (the settled window the
#: last 10,000: 10 s).
S = dict(dcl.LETTER, **dict(dcl.DEFAULTS, n=20000))
SEEDS = batch.run_seeds(1, 3)
#: The cases whose drift is deterministic (its size known in advance); classes 4 and all
#: together have a drawn turn-on bias and walks.
DETERMINISTIC = ("class 1", "class 2", "class 2, coefficients off",
                 "class 2, coefficients off, bias state", "class 3")


@pytest.fixture(scope="module")
def runs():
    """The window means of every case at the three seeds."""
    out = {}
    for case in dcl.CASES:
        cols = dcl.reference(case, S, SEEDS, S["n"])
        cols["a2"] = dcl.case_values(case, S)[0]["a2"]
        out[case] = dcl.window_means(cols, S, S["settle"])
    return out


@pytest.mark.parametrize("case", dcl.CASES)
def test_the_residual_drift_is_within_its_bound(runs, case):
    """At every seed ``|residual - expected| <= 4 sigma`` (the stated fraction of the drift's
    size: ``fraction_bound = 4 sigma / D``, docs/results.md)."""
    m = runs[case]
    bound = dcl.bound(case, S)
    expected = dcl.expected_residual(case, S)
    assert np.all(np.abs(m["residual"] - expected) <= bound), (m["residual"], expected, bound)
    # the stated fraction is a real reduction of the drift (the wrong coefficients without the
    # bias state leave their error by design)
    if case != "class 2, coefficients off":
        assert dcl.bound(case, S) / dcl.drift_size(case, S) < 0.6


@pytest.mark.parametrize("case", DETERMINISTIC)
def test_the_uncompensated_drift_is_really_there(runs, case):
    """Two-sided: the drift in ``z`` is at least half its nominal size at every seed (its
    spread is far below that: sigma of the window's mean), and, compensated, it falls to the
    bound."""
    m = runs[case]
    size = dcl.drift_size(case, S)
    if case == "class 2, coefficients off":  # the drift is the offset; what is left, its error
        size = abs(m["drift"][0])
    assert np.all(np.abs(m["drift"]) >= 0.5 * size), (m["drift"], size)
    assert np.all(np.abs(m["drift"]) > 2.0 * dcl.bound(case, S))


@pytest.mark.parametrize("case", ("class 4", "all classes"))
def test_the_drawn_drift_is_really_there(runs, case):
    """Class 4's drift is drawn (turn-on bias, walks): over the three seeds its root mean square
    is at least a quarter of its nominal size (chi-square with 3 degrees of freedom below 3/16:
    a 2 % chance at random seeds), and 10 bounds."""
    m = runs[case]
    rms = math.sqrt(float(np.mean(m["drift"] ** 2)))
    assert rms >= 0.25 * dcl.drift_size(case, S)
    assert rms >= 10.0 * dcl.bound(case, S)


def test_the_estimate_tells_the_classes_apart(runs):
    """All together: EKF1's ``dc`` is class 1's ``a2 mean(x^2)`` (within class 1's own bound),
    ``dc_class2`` the class-2 offset, and the bias state the rest."""
    m = runs["all classes"]
    one = dcl.bound("class 1", S)
    assert np.all(np.abs(m["dc"] - m["class1_true"]) <= one)
    c = dcl.CLASS2
    offset = errors.class2_offset(c["theta"], c["T"], S["a1"], S["a2"], c["T0"], c["kT_bias"],
                                  c["kT_scale"])
    assert np.all(m["dc_class2"] == offset)
    rest = m["drift"] - m["class1_true"] - offset
    assert np.all(np.abs(m["b_hat"] - rest) <= dcl.bound("all classes", S) + one)


def test_the_bias_state_absorbs_the_class2_coefficients_error(runs):
    """Coefficients 10 % off: without the bias state the residual is the offset's error (two-
    sided, within the bound of it), with it the residual is within its bound and smaller at
    every seed."""
    off = runs["class 2, coefficients off"]["residual"]
    on = runs["class 2, coefficients off, bias state"]["residual"]
    error = dcl.expected_residual("class 2, coefficients off", S)
    assert abs(error) > 10 * dcl.bound("class 2, coefficients off, bias state", S) / 4
    assert np.all(np.abs(off - error) <= dcl.bound("class 2, coefficients off", S))
    assert np.all(np.abs(on) <= dcl.bound("class 2, coefficients off, bias state", S))
    assert np.all(np.abs(on) < 0.5 * np.abs(off))
    rows = [{"case": "class 2, coefficients off", "residuals": list(off)},
            {"case": "class 2, coefficients off, bias state", "residuals": list(on)}]
    assert dcl.absorbs(rows)
    rows[1]["residuals"][1] = 2 * off[1]
    assert not dcl.absorbs(rows)


@pytest.mark.parametrize("case", ("class 1", "class 3", "class 4"))
def test_sigma_is_the_spread_of_the_residual(case):
    """The bound is not loose: over 16 seeds the residuals' standard deviation (about 0)
    lies within [0.4, 1.6] sigma (chi-square with 16 degrees of freedom: sqrt(chi2/16) is
    within [0.5, 1.45] at 99.8 %; the margin covers sigma's steady-state approximations)."""
    s = dict(S, n=10000)
    cols = dcl.reference(case, s, batch.run_seeds(101, 16), s["n"])
    cols["a2"] = dcl.case_values(case, s)[0]["a2"]
    r = dcl.window_means(cols, s, s["settle"])["residual"]
    spread = math.sqrt(float(np.mean(r ** 2)))
    assert 0.4 * dcl.sigma(case, s) <= spread <= 1.6 * dcl.sigma(case, s), \
        (spread, dcl.sigma(case, s))


def test_the_reference_of_class_1_is_the_chain_of_models_at_a_correlated_excitation():
    """Class 1 alone is the letter's chain: :func:`reference` equals models.chain.simulate (the
    batch engine's and the FMUs' definition) bit for bit, also at ``A = 0.9``, where the
    filter's start (``x0 = 0``, ``P0 = Q / (1 - A^2)``) shows in its first estimates."""
    from driftfmu.models import chain
    s = dict(S, n=400, A=0.9, Q=0.0019)
    ref = dcl.reference("class 1", s, SEEDS, s["n"])
    ch = chain.simulate(s["n"], SEEDS, a0=s["a0"], a1=s["a1"], a2=s["a2"], A=0.9, Q=0.0019,
                        R=s["R"], Ts=s["Ts"])
    for mine, theirs in (("x", "x"), ("z", "z"), ("x_hat", "x_hat"), ("dc", "dc_ekf1"),
                         ("z_comp", "z_comp")):
        assert ref[mine].tobytes() == np.asarray(ch[theirs]).tobytes(), mine
    # the start matters here: the first estimate from a prior P0 = Q, not Q / (1 - A^2), differs
    other = chain.simulate(2, SEEDS, a2=s["a2"], A=0.9, Q=0.0019, R=s["R"], P0=0.0019)
    assert np.all(np.asarray(other["x_hat"])[:, 0] != ref["x_hat"][:, 0])


# -- the formulas, by hand ---------------------------------------------------------------------

def test_window_start_and_means_take_the_samples_after_the_settling_share():
    assert dcl.window_start(10, 0.5) == 5 and dcl.window_start(11, 0.5) == 5
    assert dcl.window_start(10, 0.0) == 0 and dcl.window_start(10, 0.99) == 9
    s = dict(S, a0=0.5, a1=2.0, R=0.04)
    n = 10
    # two runs (rows), each its own means: the second's state three times the first's
    x = np.arange(n, dtype=float)[None, :] / 10 * np.array([[1.0], [3.0]])
    v = np.ones((2, n))
    d = np.array([[9.0] * 5 + [1.0, 2.0, 3.0, 4.0, 5.0],   # first half unlike the second
                  [9.0] * 5 + [2.0, 4.0, 6.0, 8.0, 10.0]])
    cols = {"x": x, "v": v, "z": 0.5 + 2.0 * x + 0.2 * v + d,
            "z_comp": 0.5 + 2.0 * x + 0.2 * v + d / 4, "dc": np.array([[1.0], [1.5]]) * np.ones(n),
            "b_hat": np.full((2, n), 2.0), "dc_class2": np.full((2, n), 0.25), "a2": 0.5}
    dd, rr = dcl.drift_and_residual(cols, s)
    np.testing.assert_allclose(dd, d, atol=1e-12)
    np.testing.assert_allclose(rr, d / 4, atol=1e-12)
    m = dcl.window_means(cols, s, 0.5)
    np.testing.assert_allclose(m["drift"], [3.0, 6.0], atol=1e-12)
    np.testing.assert_allclose(m["residual"], [0.75, 1.5], atol=1e-12)
    np.testing.assert_allclose(m["estimate"], [3.25, 3.75], atol=1e-12)
    # class 1's true part per run: a2 mean(x^2) over the window (0.255 and 9 times that)
    np.testing.assert_allclose(m["class1_true"], [0.5 * 0.51, 0.5 * 9 * 0.51], rtol=1e-12)


def test_sigma_by_hand():
    """Each part of :func:`sigma` against its formula computed here."""
    s = dict(S, n=1000, settle=0.3)
    W, ks = 700, 300
    vx, R = s["Q"], s["R"]
    P = vx * R / (vx + R)
    one = s["a2"] * math.sqrt((2 * vx * vx + 4 * vx * P) * (1 / W + 1 / ks))
    assert dcl.sigma("class 1", s) == pytest.approx(one, rel=1e-12)
    r = vx + R
    _, est = dcl.case_values("class 2, coefficients off, bias state", s)
    c = dcl.CLASS2
    dT = c["T"] - c["T0"]
    scale = (c["kT_scale"] * dT) ** 2 * vx / W
    const = 1 / (1 / est["Pb0"] + ks / r)
    assert dcl.sigma("class 2, coefficients off, bias state", s) == pytest.approx(
        math.sqrt(const + scale), rel=1e-12)
    assert dcl.sigma("class 2", s) == pytest.approx(math.sqrt(scale), rel=1e-12)
    _, est = dcl.case_values("class 3", s)
    Qb = est["Qb"]
    p = (Qb + math.sqrt(Qb * Qb + 4 * Qb * r)) / 2
    g = p / (p + r)
    assert dcl.sigma("class 3", s) == pytest.approx(math.sqrt(g * r * (2 - g) / (g * W)),
                                                    rel=1e-12)
    assert dcl.bound("class 3", s) == 4 * dcl.sigma("class 3", s)


def test_drift_size_by_hand():
    """Each case's nominal drift size :func:`drift_size` (the denominator of the table's
    ``fraction_bound``) against its formula computed here, at a correlated excitation
    (``sigma_x^2 = Q / (1 - A^2)``, not ``Q``) and a window whose middle is ``t = (k_s + n) Ts
    / 2 = 0.65 s``."""
    s = dict(S, n=1000, settle=0.3, A=0.9, Q=0.0019)
    ks, Ts = 300, s["Ts"]
    vx = 0.0019 / (1 - 0.81)
    c2, c3, c4 = dcl.CLASS2, dcl.CLASS3, dcl.CLASS4

    def offset(a2, kT_bias, kT_scale):
        return errors.class2_offset(c2["theta"], c2["T"], s["a1"], a2, c2["T0"], kT_bias,
                                    kT_scale)
    one = s["a2"] * vx
    two = offset(0.0, c2["kT_bias"], c2["kT_scale"])
    off = abs(offset(0.0, 1.1 * c2["kT_bias"], 1.1 * c2["kT_scale"]) - two)
    three = c3["d_inf"] * (1 - math.exp(-ks * Ts * vx / c3["E_tau"]))
    four2 = (c4["bias_on"] ** 2 + c4["bias_gm"] ** 2 + c4["flicker"] ** 2
             + c4["random_walk"] ** 2 * 0.65)
    every = one + offset(s["a2"], c2["kT_bias"], c2["kT_scale"]) + three
    for case, size in (("class 1", one), ("class 2", two), ("class 2, coefficients off", off),
                       ("class 2, coefficients off, bias state", off), ("class 3", three),
                       ("class 4", math.sqrt(four2)),
                       ("all classes", math.sqrt(every ** 2 + four2))):
        assert dcl.drift_size(case, s) == pytest.approx(size, rel=1e-12), case


def test_qb_follows_the_guidance():
    """Class 4: ``Qb = K^2 Ts`` for a walk alone, plus each Gauss-Markov process's
    ``sigma^2 (1 - exp(-2 Ts / tau))``; class 3: the walk that grows by ``d_inf`` over the
    exposure's time constant; all together: their sum."""
    Ts = 1e-3
    walk = errors.config(Ts=Ts, random_walk=0.02)
    assert dcl._random_walk_qb(walk) == pytest.approx(bias_model.qb_random_walk(0.02, Ts))
    gm = errors.config(Ts=Ts, bias_gm=0.01, tau_gm=5.0)
    assert dcl._random_walk_qb(gm) == pytest.approx(bias_model.qb_gauss_markov(0.01, 5.0, Ts))
    flicker = errors.config(Ts=Ts, flicker=0.005, tau_min=1.0, tau_max=100.0)
    assert flicker.fl_n > 1
    assert dcl._random_walk_qb(flicker) == pytest.approx(sum(
        bias_model.qb_gauss_markov(flicker.fl_sigma, tau, Ts)
        for tau in errors.flicker_taus(1.0, 100.0)), rel=1e-9)
    assert dcl.qb_exposure(0.1, 0.05, 0.01, Ts) == pytest.approx(0.1 ** 2 / 5.0 * Ts)
    q3 = dcl.case_values("class 3", S)[1]["Qb"]
    q4 = dcl.case_values("class 4", S)[1]["Qb"]
    assert dcl.case_values("all classes", S)[1]["Qb"] == pytest.approx(q3 + q4)
    c4 = dcl.CLASS4
    e4 = errors.config(Ts=S["Ts"], **c4)
    assert dcl.case_values("class 4", S)[1]["Pb0"] == pytest.approx(
        c4["bias_on"] ** 2 + c4["bias_gm"] ** 2 + e4.fl_n * e4.fl_sigma ** 2)


def test_the_estimator_gets_the_sensors_tilt_and_temperature():
    """The wiring: in every case with class 2, the DriftEstimator's theta and T are the
    Accelerometer's; the coefficients are the sensor's, or off by ``wrong``."""
    for case in dcl.CASES:
        start = dcl.start_values(case, S, 7)
        acc, est = start["Accelerometer"], start["DriftEstimator"]
        for name in ("theta", "T", "T0"):
            assert est.get(name) == acc.get(name), (case, name)
        if "off" in case:
            assert est["kT_bias"] == pytest.approx(acc["kT_bias"] * (1 + S["wrong"]))
            assert est["kT_scale"] == pytest.approx(acc["kT_scale"] * (1 + S["wrong"]))
        elif "theta" in acc:
            assert (est["kT_bias"], est["kT_scale"]) == (acc["kT_bias"], acc["kT_scale"])
        assert (est.get("bias") == 1) == (case not in ("class 1", "class 2",
                                                       "class 2, coefficients off"))


def test_expected_residual_is_the_offsets_error():
    c = dcl.CLASS2
    true2 = errors.class2_offset(c["theta"], c["T"], 1.0, 0.0, c["T0"], c["kT_bias"],
                                 c["kT_scale"])
    wrong = errors.class2_offset(c["theta"], c["T"], 1.0, 0.0, c["T0"], 1.1 * c["kT_bias"],
                                 1.1 * c["kT_scale"])
    assert dcl.expected_residual("class 2, coefficients off", S) == pytest.approx(
        true2 - wrong, rel=1e-12)
    assert true2 - wrong < -0.01  # about 15 mV
    assert dcl.expected_residual("class 2, coefficients off, bias state", S) == 0.0


# -- the figure ----------------------------------------------------------------------------------

def _figure(tmp_path, closed_figures):
    """drift_classes.png of made-up block means (the figure's input, no FMU run): each case's
    true drift 10 mV and more, its estimate a little below, its residual a few mV."""
    s = dict(dcl.LETTER, **dict(dcl.DEFAULTS, n=4000, block=1000))
    t = [0.5, 1.5, 2.5, 3.5]
    traces, rows = {}, []
    for i, case in enumerate(dcl.CASES):
        drift = [0.01 * (i + 1) * (1 + 0.1 * j) for j in range(4)]
        traces[case] = {"t": t, "drift": drift, "estimate": [0.95 * d for d in drift],
                        "residual": [0.002 * (-1) ** j * (i + 1) for j in range(4)]}
        rows.append({"case": case, "residual": 1e-4 * (i + 1), "drift": drift[-1], "runs": 1})
    dcl.plot_drift_classes(tmp_path / "drift_classes.png", {"settings": s, "cases": rows},
                           traces)
    (fig,) = closed_figures
    return fig


def _curves(ax):
    """The axes' data curves (not the zero lines, not the clipping marks)."""
    return [line for line in ax.get_lines() if not line.get_label().startswith("_")]


def _zero_lines(ax):
    return [line for line in ax.get_lines() if line.get_label().startswith("_child")
            and list(line.get_ydata()) == [0.0, 0.0]]


def test_the_figure_draws_each_curve_in_the_colour_the_results_page_names(tmp_path,
                                                                          closed_figures):
    """docs/results.md: the true drift black, the estimate blue, the residual of ``z_comp``
    red; for class 2 the three variants' residuals on an axis of their own (right), each its
    own colour and dash."""
    from matplotlib.colors import same_color
    fig = _figure(tmp_path, closed_figures)
    panels, twins = fig.axes[:len(dcl.PANELS)], fig.axes[len(dcl.PANELS):]
    assert len(twins) == 1  # class 2's right axis, the only one
    right = twins[0]
    for ax, (title, cases) in zip(panels, dcl.PANELS):
        curves = {line.get_label(): line for line in _curves(ax)}
        assert same_color(curves["true drift"].get_color(), "black"), title
        assert same_color(curves["estimate dc + b_hat + dc_class2"].get_color(), "tab:blue")
        if len(cases) == 1:
            assert same_color(curves["residual of z_comp"].get_color(), "tab:red"), title
        else:
            assert ax.get_shared_x_axes().joined(ax, right)
            residuals = _curves(right)
            assert [line.get_label() for line in residuals] == [
                "residual of z_comp (%s, right axis)" % dcl._short(c) for c in cases]
            assert same_color(residuals[0].get_color(), "tab:red")
            styles = {(line.get_color(), line.get_linestyle()) for line in residuals}
            colours = [line.get_color() for line in residuals]
            assert len(styles) == 3 and len(set(colours)) == 3
            assert not any(same_color(c, "black") or same_color(c, "tab:blue")
                           for c in colours)


def test_the_figures_zero_lines_are_thinner_than_its_curves(tmp_path, closed_figures):
    """Each axes' zero line (the panel's black one, the right axis's grey one) is a reference
    drawn under the data: thinner than every curve of its axes, so that a residual near 0 is
    not hidden by it, and neutral (black or grey), not in a curve's colour."""
    from matplotlib.colors import to_rgba
    fig = _figure(tmp_path, closed_figures)
    for ax in fig.axes:
        zeros, curves = _zero_lines(ax), _curves(ax)
        assert len(zeros) == 1 and curves, ax.get_title()
        r, g, b, _ = to_rgba(zeros[0].get_color())
        assert r == g == b, (ax.get_title(), zeros[0].get_color())
        assert zeros[0].get_linewidth() < min(line.get_linewidth() for line in curves), \
            (ax.get_title(), zeros[0].get_linewidth())


# -- through the FMUs ----------------------------------------------------------------------------

@pytest.mark.integration
def test_the_experiment_through_the_fmus_equals_the_reference(built_fmus, tmp_path):
    """Every case through the Python FMUs, the outputs equal models/ bit for bit; the files
    are written, the table has a row per case; the progress counts the runs, then the
    validation as a phase of its own, case by case."""
    fmu_dir = built_fmus["DriftEstimator"].parent
    out = tmp_path / "out"
    seen = []

    class Recorder:
        def __call__(self, done):
            seen.append(done)

        def phase(self, desc, total, unit=None):
            seen.append((desc, total, unit))
    s = driftfmu.experiment_drift_classes(out=out, n=300, runs=1, workers=1, fmu_dir=fmu_dir,
                                          progress=Recorder())
    assert s["validation"]["bit_identical"] and s["validation"]["max_abs_diff"] == 0.0
    assert sorted(p.name for p in out.iterdir()) == ["drift_classes.csv", "drift_classes.json",
                                                     "drift_classes.png"]
    assert [r["case"] for r in json.loads((out / "drift_classes.json").read_text())["cases"]] \
        == list(dcl.CASES)
    table = np.genfromtxt(out / "drift_classes.csv", delimiter=",", names=True)
    assert list(table["case"]) == list(range(1, len(dcl.CASES) + 1))
    phase = [i for i, v in enumerate(seen) if isinstance(v, tuple)]
    assert len(phase) == 1, seen
    i = phase[0]
    assert seen[i] == ("validation (FMU outputs against models/)", len(dcl.CASES), "case")
    assert sorted(seen[:i]) == list(range(1, len(dcl.CASES) + 1))  # the runs: 7 cases x 1 run
    assert seen[i + 1:] == list(range(1, len(dcl.CASES) + 1))  # then the cases' validation
    # the class-2 offset the estimator removed is the one the sensor's tilt and temperature make
    row = {r["case"]: r for r in s["cases"]}["class 2"]
    c = dcl.CLASS2
    assert row["dc_class2"] == pytest.approx(errors.class2_offset(
        c["theta"], c["T"], 1.0, 0.0, c["T0"], c["kT_bias"], c["kT_scale"]), rel=1e-12)


@pytest.mark.integration
def test_a_correlated_excitation_through_the_fmus_equals_the_reference(built_fmus):
    """``A`` and ``Q`` are settings of the experiment: at ``A = 0.9`` (where the filter's prior
    ``P0 = Q / (1 - A^2)`` and start ``x0 = 0`` shape its first steps; at the letter's ``A = 0``
    the first prediction forgets both) the FMUs still equal models/ bit for bit."""
    fmu_dir = built_fmus["DriftEstimator"].parent
    s = driftfmu.experiment_drift_classes(n=40, runs=1, workers=1, fmu_dir=fmu_dir, A=0.9,
                                          Q=0.0019)
    assert s["validation"]["bit_identical"] and s["validation"]["max_abs_diff"] == 0.0
    assert (s["settings"]["A"], s["settings"]["Q"]) == (0.9, 0.0019)


@pytest.mark.integration
def test_without_the_plot_the_experiment_writes_its_table_and_summary_only(built_fmus,
                                                                           tmp_path,
                                                                           monkeypatch):
    """``plot=False``: drift_classes.csv and drift_classes.json, no figure drawn."""
    def no_plot(*args):
        raise AssertionError("the figure was drawn with plot=False")
    monkeypatch.setattr(dcl, "plot_drift_classes", no_plot)
    out = tmp_path / "out"
    dcl.run_drift_classes(out=out, fmu_dir=built_fmus["DriftEstimator"].parent, workers=1,
                          plot=False, n=40, runs=1)
    assert sorted(p.name for p in out.iterdir()) == ["drift_classes.csv", "drift_classes.json"]


# -- refusals ------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv, text", [
    (["--settle", "1.5"], "settle = 1.5 is not allowed; allowed: a number in [0, 1)"),
    (["--wrong", "abc"], "wrong = 'abc' is not allowed; allowed: a number in [0, 1)"),
    (["--runs", "0"], "runs"),
    (["--n", "1"], "n"),
])
def test_the_command_refuses_bad_options_in_one_line(argv, text, tmp_path):
    p = subprocess.run([sys.executable, "-m", "driftfmu", "experiment", "drift-classes",
                        "--out", str(tmp_path / "o"), "--fmu-dir", str(tmp_path / "f")] + argv,
                       capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 2, p
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and text in lines[0], p.stderr
    assert not (tmp_path / "o").exists() and not (tmp_path / "f").exists()


@pytest.mark.parametrize("kwargs, text", [
    (dict(settle=1.0), "settle = 1.0 is not allowed"),
    (dict(wrong=-0.1), "wrong = -0.1 is not allowed"),
    (dict(runs=0), "runs"),
    (dict(block=0), "block"),
    (dict(n=3, settle=0.9), "leaves 1 samples in the settled window"),
])
def test_the_api_refuses_bad_settings(kwargs, text, tmp_path):
    with pytest.raises(UsageError, match=text.replace("(", r"\(").replace(".", r"\.")):
        driftfmu.experiment_drift_classes(fmu_dir=tmp_path / "f", **kwargs)
    assert not (tmp_path / "f").exists()


def test_the_api_refuses_an_unknown_keyword():
    with pytest.raises(TypeError, match="frobnicate"):
        driftfmu.experiment_drift_classes(frobnicate=1)


# -- the tilt and temperature wired to the DriftEstimator (masters, batch) -------------------------

def test_the_wired_offset_is_the_tilts():
    """With ``theta = 0`` nothing (the estimator filters ``z`` itself); otherwise ``a1 sin theta
    + a2 sin^2 theta`` (with a3, a4 their terms), whatever the temperature (the estimator's own
    coefficients are off)."""
    from driftfmu.models import chain
    assert chain.wired_offset(0.0, 330.0, 1.0, 0.01) is None
    g = math.sin(0.3)
    assert chain.wired_offset(0.3, 298.15, 1.0, 0.01) == pytest.approx(g + 0.01 * g * g,
                                                                       rel=1e-15)
    assert chain.wired_offset(0.3, 340.0, 2.0, 0.1, 0.05, 0.02) == pytest.approx(
        2 * g + 0.1 * g ** 2 + 0.05 * g ** 3 + 0.02 * g ** 4, rel=1e-14)


@pytest.mark.parametrize("kernel", ["numpy", "c"])
def test_a_tilted_batch_run_estimates_x_without_the_tilt(kernel):
    """The batch engine (NumPy and the kernel) removes the tilt's offset before filtering:
    ``x_hat`` follows ``x`` (its mean error about 0, not the ``sin theta = 0.30 g`` an unwired
    filter reads as state), and the bits equal models.chain.simulate's, run by run."""
    from driftfmu.models import chain
    from driftfmu.simulations import kernel as kern
    if kernel == "c" and kern.library() is None:
        pytest.skip("no C compiler: the compiled kernel is not available")
    seeds = batch.run_seeds(5, 4)
    res = batch.simulate(2000, seeds, A=0.9, Q=0.0019, theta=0.3, T=310.0, kernel=kernel,
                         record=("x", "x_hat"))
    err = (res["x_hat"] - res["x"])[:, 200:]
    # the filter's error: sd about sqrt(P) = 0.01 g per sample; its mean over 7200 samples
    # (correlated over ~10) is within 0.01 g of 0, thirty times below the tilt's 0.3 g
    assert abs(float(err.mean())) < 0.01
    ref = chain.simulate(2000, int(seeds[2]), A=0.9, Q=0.0019, theta=0.3, T=310.0)
    assert np.asarray(ref["x_hat"]).tobytes() == res["x_hat"][2].tobytes()
    # z_comp of the chain: z less the tilt's offset and the drift estimate
    off = chain.wired_offset(0.3, 310.0, 1.0, 0.01)
    z_comp = np.asarray(ref["z_comp"])
    dc = np.asarray(ref["dc_ekf1"])
    assert z_comp.tobytes() == ((np.asarray(ref["z"]) - off) - dc).tobytes()


def test_the_masters_start_values_give_the_estimator_the_sensors_tilt_and_temperature():
    """run gaussian, the FMU engine and the SSP's bindings (gaussian.start_values): the
    DriftEstimator's theta and T are the Accelerometer's when set, and absent (its defaults)
    when not: the letter's run sets what it always set."""
    from driftfmu.simulations import gaussian
    start = gaussian.start_values(theta=0.3, T=310.0)
    assert start["DriftEstimator"]["theta"] == start["Accelerometer"]["theta"] == 0.3
    assert start["DriftEstimator"]["T"] == start["Accelerometer"]["T"] == 310.0
    only_t = gaussian.start_values(T=310.0, kT_bias=0.01)
    assert only_t["DriftEstimator"]["T"] == 310.0 and "theta" not in only_t["DriftEstimator"]
    assert "kT_bias" not in only_t["DriftEstimator"]  # (its coefficients: the user's)
    plain = gaussian.start_values()
    assert "theta" not in plain["DriftEstimator"] and "T" not in plain["DriftEstimator"]


def test_the_masters_start_values_refuse_a_name_they_do_not_know():
    """A misspelt parameter (the SSP's bindings and the benchmarks call start_values directly,
    without run_gaussian's keyword check) is a TypeError that names it, not a bare KeyError
    from deep inside; a known one at its off value sets nothing."""
    from driftfmu.simulations import gaussian
    with pytest.raises(TypeError, match=r"^unknown parameter\(s\) T_sensor, thta; allowed: "
                       r"a0, a1, a2, A, Q, R, seed, Ts, x0, P0, estimator, (\w+, )+\w+$") as err:
        gaussian.start_values(thta=0.3, T_sensor=310.0)
    allowed = set(str(err.value).split("allowed: ")[1].split(", "))
    assert set(gaussian.GENERAL_OFF) | {"theta", "T", "a3", "B", "bias_on"} <= allowed
    for name in sorted(allowed):  # every name it allows is one start_values takes
        gaussian.start_values(**{name: 1 if name in ("seed", "estimator") else 0.5})
    assert "theta" not in gaussian.start_values(theta=0.0)["DriftEstimator"]


@pytest.mark.integration
def test_run_gaussian_gives_the_estimator_the_sensors_tilt_and_temperature(built_fmus):
    """The FMUs equal models/ with the tilt wired (else run_gaussian's check fails), and
    z_comp has no tilt offset left."""
    fmu_dir = built_fmus["DriftEstimator"].parent
    res = driftfmu.run_gaussian(n=400, theta=0.3, T=310.0, fmu_dir=fmu_dir)
    z_comp = np.asarray(res["columns"]["z_comp"])
    # x white (A = 0, Q = 0.01): the mean of z_comp over 400 samples is within 4 sd of 0
    assert abs(float(z_comp.mean())) < 4 * math.sqrt(0.0101 / 400)


def test_the_ssps_reference_removes_the_wired_tilt():
    """The SSP binds the tilt at both components (:func:`gaussian.start_values`); its Jacobi
    reference (what fmpy's simulate_ssp must show, tests/test_ssp.py) filters ``z`` less the
    tilt's offset: ``z_comp = z - offset - dc`` and ``x_hat`` without the 0.2 rad tilt's
    0.199 g."""
    from driftfmu.fmu_src import ssp
    from driftfmu.models import chain
    ref = ssp.jacobi_reference(600, A=0.9, Q=0.0019, seed=3, theta=0.2, T=305.0)
    off = chain.wired_offset(0.2, 305.0, 1.0, 0.01)
    z = np.asarray(ref["DriftEstimator.z"])
    dc = np.asarray(ref["DriftEstimator.dc"])
    # row i shows the outputs of the step from t_i, computed from the input held in it: the z
    # the connection delivered after the step before (row i - 1's DriftEstimator.z)
    assert np.asarray(ref["DriftEstimator.z_comp"])[1:].tobytes() == \
        ((z[:-1] - off) - dc[1:]).tobytes()
    err = np.asarray(ref["DriftEstimator.x_hat"]) - np.asarray(ref["Excitation.x"])
    # (the estimator's input is delayed a step by the Jacobi connections: x_hat follows the
    # previous sample's x; the mean error stays far below the tilt)
    assert abs(float(err[100:].mean())) < 0.02
