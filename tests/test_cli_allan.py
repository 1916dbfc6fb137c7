"""``driftfmu allan`` and ``driftfmu.allan``: the signal from a CSV file, an array or a
co-simulation; the table, the figure and the reading written whole or not at all; every bad
input one line (exit status 2), nothing written, both sides of every bound."""
import json
import math
import os
import re

import numpy as np
import pytest

import driftfmu
from driftfmu.simulations import allan as sim_allan
from driftfmu.simulations import cli as sim_cli
from driftfmu.simulations import output
from driftfmu.simulations.cli import main
from driftfmu.simulations.errors import UsageError

TS = 0.01


def _csv(path, n=4096, Ts=TS, seed=1, t=None, z=None, header="time,x,z", fmt="%.17g"):
    """A recording time, x, z: z white noise of density 1e-3 plus an offset."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * Ts if t is None else np.asarray(t, dtype=float)
    z = 0.5 + 1e-3 / math.sqrt(Ts) * rng.standard_normal(len(t)) if z is None else z
    np.savetxt(path, np.column_stack([t, np.zeros(len(t)), z]), delimiter=",",
               header=header, comments="", fmt=fmt)
    return str(path)


def _cli(argv, capsys):
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code
    out, err = capsys.readouterr()
    return status, out, [line for line in err.strip().splitlines() if line.strip()]


def _refused(argv, api_call, said, tmp_path, capsys):
    """The command line exits 2 with one line saying ``said``; the API raises a ValueError of
    the same line; neither writes its --out."""
    out = tmp_path / "out"
    status, _, err = _cli(argv + ["--out", str(out)], capsys)
    assert status == 2 and len(err) == 1, err
    assert said in err[0], err[0]
    with pytest.raises(ValueError) as info:
        api_call(out)
    assert re.sub(r"^driftfmu: error: (argument --[\w-]+: )?", "", err[0]) == str(info.value)
    assert not out.exists()


# -- a CSV file: what is written and printed --------------------------------------------------

def test_csv_writes_the_table_the_reading_and_the_figure(tmp_path, capsys):
    rec = _csv(tmp_path / "rec.csv", n=20000)
    out = tmp_path / "res"
    status, printed, err = _cli(["allan", rec, "--out", str(out), "--unit", "V"], capsys)
    assert status == 0, err
    assert sorted(os.listdir(out)) == ["allan.csv", "allan.json", "allan.png"]
    table = np.genfromtxt(out / "allan.csv", delimiter=",", names=True)
    assert table.dtype.names == sim_allan.CSV_COLUMNS
    assert list(table["m"]) == [2 ** j for j in range(14)]  # octaves up to n / 2
    np.testing.assert_allclose(table["tau"], table["m"] * TS, rtol=1e-12)
    assert np.all(table["low"] < table["adev"]) and np.all(table["adev"] < table["high"])
    assert list(table["terms"]) == [20000 - 2 * m + 1 for m in table["m"]]
    reading = json.loads((out / "allan.json").read_text())
    assert reading["N"]["value"] == pytest.approx(1e-3, rel=0.05)
    assert reading["K"]["value"] is None and reading["K"]["reason"]
    assert reading["samples"] == 20000 and reading["Ts"] == pytest.approx(TS, rel=1e-12)
    assert reading["source"] == rec and reading["unit"] == "V"
    lines = printed.splitlines()
    assert lines[0] == "wrote %s/allan.csv, allan.json, allan.png" % out
    assert lines[3].split()[:2] == ["0.01", "1"] and len(lines) == 3 + 14 + 3
    assert lines[-3].startswith("N = %.4g V/√Hz (68 %%: " % reading["N"]["value"])
    assert lines[-1].startswith("K: not resolved (no 2 consecutive tau with a local slope")


def test_the_api_returns_and_writes_what_the_command_does(tmp_path, capsys):
    rec = _csv(tmp_path / "rec.csv", n=3000)
    r = driftfmu.allan(rec, out=tmp_path / "api")
    assert _cli(["allan", rec, "--out", str(tmp_path / "cli")], capsys)[0] == 0
    for name in ("allan.csv", "allan.json"):
        assert (tmp_path / "api" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes()
    assert r["m"] == [2 ** j for j in range(11)] and r["unit"] is None
    # an array, as simulate returns it, gives the same numbers
    t, z = np.loadtxt(rec, delimiter=",", skiprows=1, usecols=(0, 2), unpack=True)
    data = np.zeros(len(t), dtype=[("time", float), ("z", float)])
    data["time"], data["z"] = t, z
    a = driftfmu.allan(data)
    assert a["adev"] == r["adev"] and a["N"] == r["N"] and a["source"] == "an array"


def test_taus_per_decade_all_and_a_list(tmp_path):
    rec = _csv(tmp_path / "rec.csv", n=200)
    assert driftfmu.allan(rec, per_decade=3)["m"] == [1, 2, 5, 10, 22, 46, 100]
    assert driftfmu.allan(rec, taus="all")["m"] == list(range(1, 101))
    r = driftfmu.allan(rec, taus=[1.0, 0.03, 0.01, 0.03])
    assert r["m"] == [1, 3, 100] and r["tau"] == pytest.approx([0.01, 0.03, 1.0], rel=1e-12)
    # the reading comes from the octaves whatever the table holds
    assert r["reading"] == driftfmu.allan(rec)["reading"]


def test_progress_counts_the_taus(tmp_path):
    rec = _csv(tmp_path / "rec.csv", n=400)
    seen = []
    driftfmu.allan(rec, taus="all", progress=seen.append)
    assert seen[-1] == 200 and seen == sorted(seen)


# -- bad input: one line, exit 2, nothing written; both sides of each bound -------------------

def test_a_csv_without_the_column(tmp_path, capsys):
    rec = _csv(tmp_path / "rec.csv", n=50)
    _refused(["allan", rec, "--column", "w"], lambda out: driftfmu.allan(rec, "w", out=out),
             "missing column(s) w: its first row, the header, holds 'time', 'x', 'z'; allowed: "
             "a header row with columns time, w, separated by commas",
             tmp_path, capsys)
    _refused(["allan", rec, "--time", "t"], lambda out: driftfmu.allan(rec, time="t", out=out),
             "missing column(s) t", tmp_path, capsys)
    assert driftfmu.allan(rec, "x")["adev"][0] == 0.0  # a column that is there


def test_time_not_strictly_increasing(tmp_path, capsys):
    t = np.arange(50) * TS
    t[20] = t[19]
    rec = _csv(tmp_path / "rec.csv", t=t)
    _refused(["allan", rec], lambda out: driftfmu.allan(rec, out=out),
             "time is not strictly increasing", tmp_path, capsys)
    t = np.arange(50) * TS
    t[20], t[21] = t[21], t[20]
    rec = _csv(tmp_path / "swap.csv", t=t)
    _refused(["allan", rec], lambda out: driftfmu.allan(rec, out=out),
             "time is not strictly increasing", tmp_path, capsys)


@pytest.mark.parametrize("step, refused", [(0.5e-6, False), (0.99e-6, False), (1.5e-6, True),
                                           (1e-3, True)])
def test_time_uniform_within_one_millionth(step, refused, tmp_path, capsys):
    """One step longer than the others by ``step`` of Ts (its mean moves by step/n)."""
    t = np.arange(1000) * TS
    t[500:] += step * TS
    rec = _csv(tmp_path / "rec.csv", t=t)
    if refused:
        _refused(["allan", rec], lambda out: driftfmu.allan(rec, out=out),
                 "time is not uniformly sampled (steps from", tmp_path, capsys)
    else:
        assert driftfmu.allan(rec)["Ts"] == pytest.approx(TS, rel=2e-6)


def test_times_as_a_spreadsheet_writes_them_pass(tmp_path):
    """Decimal times with six digits (rounded, as a spreadsheet or a logger writes them) are
    uniform within their rounding: 0.000001 s in 0.01 s is 1e-4 of Ts, refused.  At Ts = 1 s
    with six decimals, accepted."""
    t = np.round(np.arange(3000) * 0.1 + 0.05, 6)
    rec = _csv(tmp_path / "rec.csv", t=t, fmt="%.6f")
    assert driftfmu.allan(rec)["Ts"] == pytest.approx(0.1, rel=1e-9)
    t = np.arange(3000) / 3.0  # thirds of a second, six decimals: steps 0.333333, 0.333334
    rec = _csv(tmp_path / "third.csv", t=t, fmt="%.6f")
    with pytest.raises(UsageError, match="not uniformly sampled"):
        driftfmu.allan(rec)


def test_fewer_samples_than_two_clusters(tmp_path, capsys):
    one = _csv(tmp_path / "one.csv", n=1)
    _refused(["allan", one], lambda out: driftfmu.allan(one, out=out),
             "1 sample(s); allowed: at least 2 (two clusters of one sample)", tmp_path, capsys)
    empty = tmp_path / "empty.csv"
    empty.write_text("time,x,z\n")
    _refused(["allan", str(empty)], lambda out: driftfmu.allan(empty, out=out),
             "0 data row(s); allowed: at least 1", tmp_path, capsys)
    two = _csv(tmp_path / "two.csv", n=2)
    r = driftfmu.allan(two)
    assert r["m"] == [1] and r["terms"] == [1] and r["edf"][0] >= 1.0
    assert all(r[k]["value"] is None for k in "NBK")


@pytest.mark.parametrize("cell", ["nan", "NaN", "", "inf", "-inf", "1e400", "abc"])
def test_a_value_that_is_not_a_finite_number(cell, tmp_path, capsys):
    rec = tmp_path / "rec.csv"
    rows = ["time,x,z"] + ["%r,0,%r" % (k * TS, 0.5 + 1e-3 * k) for k in range(10)]
    rows[6] = "%r,0,%s" % (5 * TS, cell)
    rec.write_text("\n".join(rows) + "\n")
    _refused(["allan", str(rec)], lambda out: driftfmu.allan(rec, out=out),
             "line 7, column z: %r is not a finite number; allowed: finite numbers only" % cell,
             tmp_path, capsys)


@pytest.mark.parametrize("edit", ["repeated", "swapped", "all equal", "backwards"])
def test_an_arrays_time_not_strictly_increasing(edit):
    """driftfmu.simulate's array (not a CSV file): a time that repeats, goes back or stands
    still is refused as not increasing; the same times in order pass."""
    data = np.zeros(50, dtype=[("time", float), ("z", float)])
    data["time"] = np.arange(50) * TS
    data["z"] = np.sin(np.arange(50.0))
    assert driftfmu.allan(data)["adev"][0] > 0.0
    t = data["time"]
    if edit == "repeated":
        t[20] = t[19]
    elif edit == "swapped":
        t[20], t[21] = t[21], t[20]
    elif edit == "all equal":
        t[:] = 0.0
    else:
        t[:] = t[::-1].copy()
    with pytest.raises(UsageError) as info:
        driftfmu.allan(data)
    assert str(info.value) == ("time is not strictly increasing; allowed: uniformly sampled, "
                               "increasing time")


def test_a_nan_in_an_array(tmp_path):
    data = np.zeros(10, dtype=[("time", float), ("z", float)])
    data["time"] = np.arange(10) * TS
    data["z"][4] = np.nan
    with pytest.raises(UsageError, match=r"^z\[4\] = nan is not a finite number"):
        driftfmu.allan(data)
    data["z"][4] = 0.0
    data["time"][9] = np.inf
    with pytest.raises(UsageError, match=r"^time\[9\] = inf is not a finite number"):
        driftfmu.allan(data)
    with pytest.raises(UsageError, match=r"the array has no field 'w' \(column = 'w'\); "
                                         r"allowed: one of time, z"):
        driftfmu.allan(data, "w")


@pytest.mark.parametrize("taus, said", [
    ("0.005", "tau = 0.005 s is not a multiple of the sample period"),  # m = 1/2
    ("0.015", "tau = 0.015 s is not a multiple of the sample period Ts = 0.01 s"),
    ("0.01,0.51", "tau = 0.51 s is outside the data (100 samples at Ts = 0.01 s: at least two "
                  "clusters); allowed: m Ts with 1 <= m <= 50 (0.01 s to 0.5 s)"),
    ("0", "taus has 0.0, which is not a number > 0"),
    ("-0.01", "taus has -0.01, which is not a number > 0"),
    ("x", "taus has 'x', which is not a number > 0"),
    ("decade", "taus has 'decade', which is not a number > 0"),
])
def test_a_tau_outside_the_data(taus, said, tmp_path, capsys):
    rec = _csv(tmp_path / "rec.csv", n=100)
    values = taus if taus in ("decade",) else [
        float(v) if re.fullmatch(r"[-0-9.e]+", v) else v for v in taus.split(",")]
    if taus == "decade":
        said_api = "taus = 'decade' is not allowed"
        status, _, err = _cli(["allan", rec, "--taus", taus, "--out", str(tmp_path / "o")],
                              capsys)
        assert status == 2 and len(err) == 1 and said in err[0]
        with pytest.raises(UsageError, match=said_api):
            driftfmu.allan(rec, taus=taus)
        return
    _refused(["allan", rec, "--taus", taus], lambda out: driftfmu.allan(rec, taus=values,
                                                                         out=out),
             said, tmp_path, capsys)


def test_the_bounds_of_tau_themselves_pass(tmp_path):
    rec = _csv(tmp_path / "rec.csv", n=100)
    r = driftfmu.allan(rec, taus=[0.01, 0.5, 0.03 * (1 + 5e-7)])
    assert r["m"] == [1, 3, 50] and r["terms"] == [99, 95, 1]
    with pytest.raises(UsageError, match="not a multiple"):
        driftfmu.allan(rec, taus=[0.03 * (1 + 5e-6)])
    odd = _csv(tmp_path / "odd.csv", n=101)  # two clusters of 50, one sample over
    assert driftfmu.allan(odd, taus=[0.5])["m"] == [50]
    with pytest.raises(UsageError, match=r"1 <= m <= 50 "):
        driftfmu.allan(odd, taus=[0.51])


@pytest.mark.parametrize("argv, kwargs, said", [
    (["--per-decade", "0"], dict(per_decade=0), "per_decade = 0 is out of range; allowed: an "
                                                "integer per_decade >= 1"),
    (["--per-decade", "2", "--taus", "all"], dict(per_decade=2, taus="all"),
     "; allowed: one of them"),
    (["--stop-time", "5"], dict(stop_time=5.0), "for a co-simulation"),
    (["--start-values", "Q", "0"], dict(start_values={"Q": 0.0}), "for a co-simulation"),
])
def test_settings_that_do_not_go_together(argv, kwargs, said, tmp_path, capsys):
    rec = _csv(tmp_path / "rec.csv", n=100)
    out = tmp_path / "out"
    status, _, err = _cli(["allan", rec] + argv + ["--out", str(out)], capsys)
    assert status == 2 and len(err) == 1 and said in err[0], err
    with pytest.raises(ValueError, match=re.escape(said)):
        driftfmu.allan(rec, out=out, **kwargs)
    assert not out.exists()


@pytest.mark.parametrize("kwargs, said", [
    (dict(source=5), "source = 5 is not allowed; allowed: None (a co-simulation), the path"),
    (dict(source=""), "source = '' is empty"),
    (dict(column=3), "column = 3 is not allowed"),
    (dict(column=" "), "column = ' ' is not allowed"),
    (dict(unit=1), "unit = 1 is not allowed"),
    (dict(stop_time=0.0), "stop_time = 0.0 is not allowed; allowed: a finite number > 0"),
    (dict(stop_time=math.inf), "stop_time = inf is not allowed"),
    (dict(backend="java"), "backend = 'java' is not allowed"),
    (dict(taus=[]), "taus = [] is empty"),
    (dict(taus=5), "taus = 5 is not allowed"),
    (dict(progress=3), "progress = 3 is not callable"),
])
def test_the_api_refuses_before_anything_runs(kwargs, said, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError) as info:
        driftfmu.allan(**kwargs)
    assert "\n" not in str(info.value) and said in str(info.value), str(info.value)
    assert os.listdir(tmp_path) == []  # no FMU built, nothing written


def test_docs_cli_names_the_options_as_the_help_does(capsys):
    # docs/cli.md's row of the command: every option with the value it takes, as `driftfmu
    # allan --help` shows it (a user reads one and types what the other says)
    from pathlib import Path
    docs = (Path(__file__).parent.parent / "docs" / "cli.md").read_text(encoding="utf-8")
    (row,) = [line for line in docs.splitlines() if line.startswith("| `driftfmu allan ")]
    synopsis = row.split("`")[1].replace("\\|", "|")
    options = re.findall(r"\[(--[\w-]+)(?: ([^\]]*?))?(?: \.\.\.)?\]", synopsis)
    assert {o for o, _ in options} >= {"--taus", "--start-values", "--column"}, synopsis
    with pytest.raises(SystemExit) as exc:
        main(["allan", "--help"])
    assert exc.value.code == 0
    usage = " ".join(capsys.readouterr().out.split("\n\n")[0].split())
    for option, value in options:
        assert "[%s %s" % (option, value) in usage, (option, value, usage)


def test_start_values_need_pairs_and_numbers(capsys, tmp_path):
    for argv, said in ((["--start-values", "Q"], "a name without a value"),
                       (["--start-values", "Q", "zero"], "'zero' is not a number")):
        status, _, err = _cli(["allan"] + argv + ["--out", str(tmp_path / "o")], capsys)
        assert status == 2 and len(err) == 1 and said in err[0], err
    assert sim_cli.start_values(["seed", "3", "R", "1e-6"], numbers=True) == {"seed": 3, "R": 1e-6}
    assert sim_cli.start_values(["seed", "x"]) == {"seed": "x"}  # named by the check that follows


# -- all or nothing ----------------------------------------------------------------------------

def test_a_failure_while_writing_leaves_the_old_results(tmp_path, monkeypatch):
    rec = _csv(tmp_path / "rec.csv", n=300)
    out = tmp_path / "out"
    driftfmu.allan(rec, out=out)
    before = {p: (out / p).read_bytes() for p in os.listdir(out)}
    (out / "mine.txt").write_text("keep")

    def broken(path, result, title):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(sim_allan, "plot", broken)
    other = _csv(tmp_path / "other.csv", n=500, seed=9)
    with pytest.raises(OSError):
        driftfmu.allan(other, out=out)
    assert {p: (out / p).read_bytes() for p in os.listdir(out) if p != "mine.txt"} == before
    assert (out / "mine.txt").read_text() == "keep"
    assert not [p for p in os.listdir(tmp_path) if p.startswith(output.STAGE)]


# -- the figure ------------------------------------------------------------------------------------

def test_the_figure_names_its_lines_values_and_what_is_not_resolved(tmp_path, closed_figures):
    from test_figure_labels import texts  # (tests/ is on sys.path: no package)
    rng = np.random.default_rng(3)
    n, K = 2 ** 17, 2e-3
    z = 1e-3 / math.sqrt(TS) * rng.standard_normal(n) + np.cumsum(
        K * math.sqrt(TS) * rng.standard_normal(n))
    rec = _csv(tmp_path / "rec.csv", t=np.arange(n) * TS, z=z)
    r = driftfmu.allan(rec, out=tmp_path / "o", unit="mV")
    text = texts(closed_figures[-1])
    assert "N = %.4g mV/√Hz  (white noise, slope -1/2, at τ = 1 s)" % r["N"]["value"] in text
    assert "K = %.4g mV/√s  (random walk, slope +1/2, at τ = 3 s)" % r["K"]["value"] in text
    assert "overlapping Allan deviation of z (68 % intervals)" in text
    assert "Allan deviation σ(τ) [mV]" in text and "averaging time τ [s]" in text
    assert "Allan deviation of z: 131072 samples at Ts = 0.01 s, from /" in text
    ax = closed_figures[-1].axes[0]
    assert not ax.texts  # nothing off the scale: the lines are drawn where they are on it
    lo, hi = ax.get_xlim()
    assert lo < 1.0 and hi > 3.0  # the two points the figures are read at
    white = _csv(tmp_path / "white.csv", n=5000)
    driftfmu.allan(white, out=tmp_path / "w")
    text = texts(closed_figures[-1])
    assert "K: not resolved (no 2 consecutive tau" in text and "B: not resolved (no floor" in text


def _white_and_random_walk(path, n=2 ** 17, K=2e-3, seed=3):
    """White noise of density 1e-3 plus a random walk of ``K``: N and K resolved, B not."""
    rng = np.random.default_rng(seed)
    z = 1e-3 / math.sqrt(TS) * rng.standard_normal(n) + np.cumsum(
        K * math.sqrt(TS) * rng.standard_normal(n))
    return _csv(path, t=np.arange(n) * TS, z=z)


def test_each_figures_line_its_fitted_stretch_and_its_reading_point_share_its_colour(
        tmp_path, closed_figures):
    # docs/results.md: each figure's line dashed over the whole range, thick over the tau it
    # was fitted on, a diamond where it is read, all in the figure's own colour; the estimates
    # are dots smaller than the diamonds; a figure not resolved is a legend line, nothing drawn
    from matplotlib.colors import same_color
    r = driftfmu.allan(_white_and_random_walk(tmp_path / "rec.csv"), out=tmp_path / "o")
    ax = closed_figures[-1].axes[0]
    (estimates,) = [c for c in ax.containers if c.get_label().startswith("overlapping")]
    dots = estimates.lines[0]
    colours = [dots.get_color()]
    for name in ("N", "B", "K"):   # all three resolved: the floor where the two lines cross
        fig_ = r[name]
        read_at = {"N": 1.0, "K": 3.0}.get(name, math.sqrt(fig_["tau_from"] * fig_["tau_to"]))
        (dashed,) = [ln for ln in ax.get_lines() if ln.get_label().startswith(name + " = ")]
        (thick,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) > 1
                    and ln.get_xdata()[0] == fig_["tau_from"]
                    and ln.get_xdata()[-1] == fig_["tau_to"]]
        (diamond,) = [ln for ln in ax.get_lines() if ln.get_marker() == "D"
                      and list(ln.get_xdata()) == [read_at]]
        assert dashed.get_linestyle() == "--" and thick.get_linestyle() == "-"
        assert thick.get_linewidth() > 2 * dashed.get_linewidth()
        assert same_color(thick.get_color(), dashed.get_color()), name
        assert same_color(diamond.get_color(), dashed.get_color()), name
        assert dots.get_markersize() < diamond.get_markersize()
        colours.append(dashed.get_color())
    assert not any(same_color(a, b) for i, a in enumerate(colours) for b in colours[i + 1:])
    # white noise alone: K and B not resolved; their legend lines have nothing beside them, and
    # nothing is drawn for them
    r = driftfmu.allan(_csv(tmp_path / "white.csv", n=5000), out=tmp_path / "w")
    assert r["N"]["value"] is not None and r["K"]["value"] is r["B"]["value"] is None
    ax = closed_figures[-1].axes[0]
    legend = ax.get_legend()
    for name in ("K", "B"):
        (i,) = [i for i, t in enumerate(legend.get_texts())
                if t.get_text().startswith(name + ": not resolved")]
        handle = legend.legend_handles[i]
        assert handle.get_linestyle() == "None" and handle.get_marker() in ("None", "", " ")
        (empty,) = [ln for ln in ax.get_lines()
                    if ln.get_label().startswith(name + ": not resolved")]
        assert len(empty.get_xdata()) == 0


def test_the_figure_is_1080_by_720_pixels(tmp_path):
    # docs/results.md: 9 x 6 in at 120 dpi (the PNG's header: width, height)
    driftfmu.allan(_csv(tmp_path / "rec.csv", n=1000), out=tmp_path / "o")
    head = (tmp_path / "o" / "allan.png").read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    assert (int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")) == (1080, 720)


# -- a co-simulation ------------------------------------------------------------------------------

@pytest.mark.integration
def test_a_co_simulation_of_the_sensor_at_rest_reads_its_noise(fmus_in_build_layout, tmp_path,
                                                               capsys):
    """With Q = 0 the excitation is 0 and z is a0 plus the sensor's white noise of variance
    R: N = sqrt(R Ts).  z_comp runs the DriftEstimator too; native and Python FMUs agree."""
    argv = ["allan", "--start-values", "Q", "0", "R", "1e-6", "seed", "5", "--stop-time", "20",
            "--fmu-dir", str(fmus_in_build_layout), "--out", str(tmp_path / "o")]
    status, printed, err = _cli(argv + ["--backend", "native"], capsys)
    assert status == 0, err
    reading = json.loads((tmp_path / "o" / "allan.json").read_text())
    assert reading["samples"] == 20001 and reading["unit"] == "V"
    assert reading["source"] == ("a co-simulation of Excitation -> Accelerometer (native FMUs, "
                                 "Q = 0, R = 1e-06, seed = 5)")
    N = reading["N"]
    assert abs(math.log(N["value"] / math.sqrt(1e-6 * 1e-3))) <= 4 * N["se_log"]
    python = driftfmu.allan(start_values={"Q": 0, "R": 1e-6, "seed": 5}, stop_time=2.0,
                            fmu_dir=fmus_in_build_layout)
    native = driftfmu.allan(start_values={"Q": 0, "R": 1e-6, "seed": 5}, stop_time=2.0,
                            fmu_dir=fmus_in_build_layout, backend="native")
    assert python["adev"] == native["adev"]
    comp = driftfmu.allan(column="z_comp", start_values={"Q": 0, "R": 1e-6}, stop_time=2.0,
                          fmu_dir=fmus_in_build_layout, backend="native")
    assert comp["source"].startswith("a co-simulation of Excitation -> Accelerometer -> "
                                     "DriftEstimator")
    with pytest.raises(UsageError, match=r"output 'zz' is not a variable of"):
        driftfmu.allan(column="zz", stop_time=0.1, fmu_dir=fmus_in_build_layout)
