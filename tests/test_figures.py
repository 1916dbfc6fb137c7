"""Every figure the commands write, rendered small and checked for what a reviewer would look at
first: no warnings while drawing, axes labelled (with units), a caption-like title, every series
drawn with finite data inside the axes, legends off the axes, and no text cut off at the edge of
the image."""
import warnings

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from driftfmu.models import chain, drift  # noqa: E402
from driftfmu.simulations import adxl203, montecarlo, output, sweep  # noqa: E402


@pytest.fixture
def figures(closed_figures):
    """Render with warnings as errors; keep each figure the code closes, for inspection."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield closed_figures


def _check(fig, series):
    """The checks every figure passes; ``series`` are legend labels each axes must draw, as
    {axes index: [label prefix, ...]}."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    assert fig._suptitle is not None and len(fig._suptitle.get_text()) > 30  # a caption
    axes = [ax for ax in fig.axes if ax.get_visible()]
    for ax in axes:
        assert ax.get_ylabel().strip(), ax.get_title()
        assert "[" in ax.get_ylabel() and "]" in ax.get_ylabel(), ax.get_ylabel()  # units
        assert ax.get_title().strip() or len(axes) == 1  # panels say what they show
    # an x label on the bottom axes of each column (shared x axes label only the last row)
    assert all(ax.get_xlabel().strip() for ax in axes
               if not any(o is not ax and ax.get_shared_x_axes().joined(ax, o)
                          and o.get_position().y0 < ax.get_position().y0 for o in axes))
    for i, labels in series.items():
        ax = axes[i]
        lines = {line.get_label(): line for line in ax.get_lines()}
        x0, x1 = sorted(ax.get_xlim())
        y0, y1 = sorted(ax.get_ylim())
        for prefix in labels:
            found = [line for name, line in lines.items() if name.startswith(prefix)]
            assert found, (prefix, sorted(lines))
            x, y = (np.asarray(v, dtype=float) for v in found[0].get_data())
            inside = np.isfinite(x) & np.isfinite(y) & (x >= x0) & (x <= x1) & (y >= y0) \
                & (y <= y1)
            assert inside.any(), prefix  # drawn, and inside the view
        legend = ax.get_legend()
        if legend is not None:
            overlap = legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
            assert not overlap, "legend on the data: %s" % ax.get_title()
    # nothing clipped without a mark: a labelled curve that leaves the y range has its
    # triangles on the frame and a note (output.mark_clipping)
    for ax in axes:
        y0, y1 = sorted(ax.get_ylim())
        x0, x1 = sorted(ax.get_xlim())
        marks = {line.get_label()[len("_clipped "):] for line in ax.get_lines()
                 if line.get_label().startswith("_clipped ")}
        for line in ax.get_lines():
            if line.get_label().startswith(("_child", "_nolegend_", "_clipped")):
                continue  # axhline/axvline helpers, and the marks
            x, y = (np.asarray(v, dtype=float) for v in line.get_data())
            if x.shape != y.shape:
                continue
            ok = np.isfinite(x) & np.isfinite(y) & (x >= x0) & (x <= x1)
            if ax.get_yscale() == "log":
                ok &= y > 0
            if (ok & ((y < y0) | (y > y1))).any():
                assert line.get_label().lstrip("_") in marks, "clipped without a mark: %s in %r" % (
                    line.get_label(), ax.get_title())
                assert any("off the scale" in text for _, text in output.clipping_notes(ax))
    for ax in axes:
        _check_notes(ax, renderer, page)
    # labels written on the data (margins, "k = 250") stay inside their axes, not over the
    # tick labels or cut at the frame
    for ax in axes:
        frame = ax.get_window_extent(renderer)
        for t in ax.texts:
            if t.get_text().strip() and t.get_label() != output.CLIPPING_NOTE:
                b = t.get_window_extent(renderer)
                assert b.x0 >= frame.x0 - 1 and b.x1 <= frame.x1 + 1 and b.y0 >= frame.y0 - 1 \
                    and b.y1 <= frame.y1 + 1, "label off its axes: %r" % t.get_text()
    # what is drawn of each axes (tick labels, axis labels, title, legend, annotations) and
    # the caption lie inside the image
    for box in [ax.get_tightbbox(renderer) for ax in axes] + \
            [fig._suptitle.get_window_extent(renderer)]:
        assert box.x0 >= page.x0 - 1 and box.x1 <= page.x1 + 1 and box.y0 >= page.y0 - 1 \
            and box.y1 <= page.y1 + 1, "clipped: %s outside %s" % (box, page)


def _check_notes(ax, renderer, page):
    """A note of what is off the scale (output.mark_clipping) covers no point of any curve,
    nor the legend; beside the axes it stays in the image."""
    for note, _ in output.clipping_notes(ax):
        box = note.get_window_extent(renderer)
        for line in ax.get_lines():
            if line.get_label().startswith(("_child", "_nolegend_", "_clipped")):
                continue
            xy = ax.transData.transform(np.column_stack(line.get_data()).astype(float))
            xy = xy[np.all(np.isfinite(xy), axis=1)]
            covered = (xy[:, 0] > box.x0) & (xy[:, 0] < box.x1) & (xy[:, 1] > box.y0) & \
                (xy[:, 1] < box.y1)
            assert not covered.any(), "the note covers %s" % line.get_label()
        legend = ax.get_legend()
        if legend is not None and legend is not note:
            assert not box.overlaps(legend.get_window_extent(renderer))
        assert box.x0 >= page.x0 and box.x1 <= page.x1 and box.y0 >= page.y0 and \
            box.y1 <= page.y1


def _one_run(n=400, **kw):
    cols = chain.simulate(n, 1, **kw)
    a2 = kw.get("a2", 0.01)
    expected = a2 * (0.5 if kw.get("kind") == 2 else kw.get("Q", 0.01))
    cols = dict(cols)
    cols["dc_empirical"], cols["dc_realised"], cols["dc_expected"] = drift.references(
        cols["x"], cols["z"], 0.0, a2, expected)
    return cols


@pytest.mark.parametrize("kind", [1, 2])
def test_drift_png(figures, tmp_path, kind):
    cols = _one_run(kind=kind, Q=0.01 if kind == 1 else 0.5)
    output.plot_drift(tmp_path / "drift.png", cols, "Drift estimates of one run, kind %d, "
                      "with enough words to be a caption" % kind)
    (fig,) = figures
    _check(fig, {0: ["realised", "expected", "EKF1", "EKF2", "EKF3"],
                 1: ["empirical", "EKF1"]})
    assert (tmp_path / "drift.png").stat().st_size > 10000


def test_drift_png_marks_what_its_range_clips(figures, tmp_path):
    # a Gaussian run: the empirical drift z̄ - a0 starts far outside the bottom panel's range
    # (its linear term a1 x̄ dwarfs the drift for k < 100)
    cols = _one_run(n=2000, kind=1, Q=0.01)
    output.plot_drift(tmp_path / "drift.png", cols, "Drift estimates of one Gaussian run, "
                      "with enough words to be a caption")
    (fig,) = figures
    _check(fig, {0: ["EKF1"], 1: ["empirical", "EKF1"]})
    bottom = fig.axes[1]
    marks = [line for line in bottom.get_lines() if line.get_label().startswith("_clipped empirical")]
    assert marks and all(np.all(np.asarray(m.get_xdata()) < 200) for m in marks)
    note = [text for _, text in output.clipping_notes(bottom) if "off the scale" in text]
    assert note and "empirical" in note[0]


@pytest.mark.parametrize("off", [1, 12, 13, 40])
def test_a_clipped_curve_gets_at_most_twelve_marks_from_its_first_to_its_last(off):
    """Marks of one curve and side: one per sample off the scale up to 12, then 12 spread
    from the first such sample to the last (both sides of the bound)."""
    fig, ax = plt.subplots()
    x = np.arange(100.0)
    y = np.zeros(100)
    y[20:20 + off] = 5.0
    ax.plot(x, y, label="drift")
    ax.set_ylim(-1, 1)
    ax.set_xlim(0, 99)
    try:
        output.mark_clipping(ax)
        (marks,) = [line for line in ax.get_lines() if line.get_label() == "_clipped drift"]
        xs = np.asarray(marks.get_xdata())
        assert xs.size == min(off, 12)
        assert xs[0] == 20 and xs[-1] == 20 + off - 1
        assert np.all(np.diff(xs) > 0) and np.all(np.asarray(marks.get_ydata()) == 1)
    finally:
        plt.close(fig)


def test_drift_png_of_one_sample_draws_without_warning(figures, tmp_path):
    output.plot_drift(tmp_path / "drift.png", _one_run(n=1), "One sample: still a figure, "
                      "without a warning from matplotlib")
    assert len(figures) == 1


@pytest.mark.parametrize("which", ["gaussian", "sinusoidal"])
def test_fig1_and_sine_png(figures, tmp_path, which):
    if which == "gaussian":
        montecarlo.montecarlo_gaussian(runs=64, n=300, workers=1, out=tmp_path)
    else:
        montecarlo.montecarlo_sinusoidal(runs=64, n=300, workers=1, out=tmp_path)
    (fig,) = figures
    _check(fig, {0: ["EKF1", "EKF2", "EKF3"], 1: ["EKF1", "realised"],
                 2: ["empirical", "realised"]})
    # linear drift axes in mV (no symmetric-log axis), and the EKF1 median not hidden under
    # the realised drift's: thinner and drawn on top of it
    assert all(ax.get_yscale() == "linear" for ax in fig.axes)
    middle = {line.get_label().split(" median")[0]: line for line in fig.axes[1].get_lines()}
    ekf1, realised = middle["EKF1"], middle["realised"]
    assert ekf1.get_zorder() > realised.get_zorder()
    assert ekf1.get_linewidth() < realised.get_linewidth()
    assert ekf1.get_color() != realised.get_color()
    # the median and both percentile lines of each estimator: 3 lines each, none hidden in a
    # filled band
    top = fig.axes[0]
    assert len([c for c in top.collections if c.get_label().startswith("EKF")]) == 0
    assert len([line for line in top.get_lines() if line.get_color() in ("C0", "C1", "C2")
                and not line.get_label().startswith("_clipped")]) == 9
    assert any(t.get_text() == "k = 250" for t in top.texts)  # the claim's sample, labelled


def test_fig2_fig3_png(figures, tmp_path, monkeypatch):
    monkeypatch.setattr(output, "fork_is_cheap", lambda: False)  # both figures in this process
    sweep.sweep(a2=[1e-3, 1e-2, 1e-1], R=[1e-6, 1e-4, 1e-2], runs=16, n=200, workers=1,
                out=tmp_path)
    assert len(figures) == 2
    for fig in figures:
        _check(fig, {i: ["R = 1e-06", "R = 1e-04", "R = 1e-02", "the drift"] for i in (0, 1)})
    # one scale: EKF1 (fig2) against EKF3 (fig3) can be compared by eye
    limits = {tuple(np.round(np.log10(ax.get_ylim()), 9)) for fig in figures for ax in fig.axes}
    assert len(limits) == 1, limits
    # every curve distinguishable even where curves coincide: its own colour, dash and marker
    # size (coincident hollow markers show as concentric rings)
    for fig in figures:
        for ax in fig.axes:
            curves = [line for line in ax.get_lines() if line.get_label().startswith("R = ")]
            assert len(curves) == 3
            for attr in ("get_color", "get_linestyle", "get_markersize", "get_marker"):
                values = [getattr(c, attr)() for c in curves]
                assert len({str(v) for v in values}) == len(values), (attr, values)
            assert all(c.get_markerfacecolor() == "none" for c in curves)
    # log axes labelled at the decades with superscripts (not mathtext, which cost a quarter
    # of the drawing): 10⁻³ 10⁻² 10⁻¹ along a2
    for fig in figures:
        for ax in fig.axes:
            labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
            assert {"10\u207b\u00b3", "10\u207b\u00b2", "10\u207b\u00b9"} <= set(labels), labels
            assert not any("$" in t.get_text() for t in ax.get_yticklabels())


def test_decade_labels():
    assert [output.decade_label(v) for v in (1e-3, 1e-12, 1.0, 10.0, 1e5)] == [
        "10\u207b\u00b3", "10\u207b\u00b9\u00b2", "10\u2070", "10\u00b9", "10\u2075"]
    assert [output.decade_label(v) for v in (2e-3, 0.5, 0.0)] == ["0.002", "0.5", "0"]


def _per(freqs, held_out=3):
    rng = np.random.default_rng(1)
    per, traces = [], []
    for f in freqs:
        emp = list(0.011 + 3e-4 * rng.standard_normal(held_out))
        ekf = [e + 5e-5 * rng.standard_normal() for e in emp]
        rms = float(np.sqrt(np.mean((np.array(ekf) - emp) ** 2)))
        per.append({"frequency": f, "dc_empirical": emp, "dc_ekf1": ekf,
                    "drift_mean": float(np.mean(emp)), "difference_rms": rms,
                    "margin_db": 10 * np.log10(np.mean(emp) / rms)})
        k = np.unique(np.geomspace(1, 6000, 100).astype(int))
        traces.append([list(zip(k, e * (1 - np.exp(-k / 50.0)))) for e in emp])
    return per, traces


def test_fig4_png_shows_every_held_out_set_of_every_frequency(figures, tmp_path):
    freqs = (100.0, 125.0, 150.0, 175.0, 200.0)
    per, traces = _per(freqs)
    adxl203.plot_fig4(tmp_path / "fig4.png", per, traces, 25, 6000, 1e-4)
    (fig,) = figures
    _check(fig, {0: ["empirical", "EKF1"], 1: ["%g Hz" % f for f in freqs]})
    left = fig.axes[0]
    marks = [line for line in left.get_lines() if line.get_linestyle() in ("None", "none", "")]
    assert len(marks) == 2 * len(freqs)  # markers, not lines joining discrete sets
    assert sum(len(line.get_xdata()) for line in marks) == 2 * 3 * len(freqs)
    # right: every held-out set of every frequency (not one of them), each over its own
    # empirical drift, against one reference line that needs no matching
    right = fig.axes[1]
    traces = [line for line in right.get_lines() if "Hz" in line.get_label()
              and not line.get_label().startswith("_clipped")]
    assert len(traces) == 3 * len(freqs)
    refs = [line for line in right.get_lines() if "empirical drift" in line.get_label()]
    assert len(refs) == 1 and set(refs[0].get_ydata()) == {100.0}
    assert "[%]" in right.get_ylabel()


def test_fig5_png(figures, tmp_path):
    per, _ = _per((100.0, 150.0, 200.0))
    adxl203.plot_fig5(tmp_path / "fig5.png", per)
    (fig,) = figures
    _check(fig, {0: ["drift", "rms(EKF1"]})
    ax = fig.axes[0]
    assert "dB re 1 V" in ax.get_ylabel() and "|value|" not in ax.get_ylabel()
    # the convention on the axis, in one line; its reason in the caption: 10 log10 of a
    # voltage, as the letter
    assert ax.get_ylabel() == "10·log10(v / 1 V) [dB re 1 V]"
    caption = " ".join(fig._suptitle.get_text().split())
    assert "10 log10(v / 1 V) of a voltage, as the letter (20 log10 would double every " \
        "value)" in caption
    assert len([t for t in ax.texts if t.get_text().endswith(" dB")]) == 3


def test_fig5_curves_arrows_and_margins_are_10_log10_of_the_values(figures, tmp_path):
    per, _ = _per((100.0, 150.0, 200.0))
    adxl203.plot_fig5(tmp_path / "fig5.png", per)
    (fig,) = figures
    ax = fig.axes[0]
    drift = np.array([abs(p["drift_mean"]) for p in per])
    diff = np.array([p["difference_rms"] for p in per])
    lines = {line.get_label(): line for line in ax.get_lines()}
    (d,) = [v for k, v in lines.items() if k.startswith("drift")]
    (r,) = [v for k, v in lines.items() if k.startswith("rms(EKF1")]
    assert np.allclose(d.get_ydata(), 10 * np.log10(drift), rtol=0, atol=1e-12)
    assert np.allclose(r.get_ydata(), 10 * np.log10(diff), rtol=0, atol=1e-12)
    arrows = [t for t in ax.texts if t.get_text() == ""]
    labels = [t for t in ax.texts if t.get_text().endswith(" dB")]
    assert len(arrows) == len(labels) == 3
    for p, a, b, arrow, label in zip(per, drift, diff, arrows, labels):
        f = p["frequency"]
        # the arrow spans the margin, from the drift down to the difference
        assert arrow.xy == pytest.approx((f, 10 * np.log10(b)))
        assert arrow.xyann == pytest.approx((f, 10 * np.log10(a)))
        # the margin, labelled halfway (in dB) and 4 points right of the arrow, level with it
        assert label.get_text() == "%.1f dB" % (10 * np.log10(a / b))
        assert label.xy == pytest.approx((f, 5 * np.log10(a * b)))
        assert label.get_anncoords() == "offset points" and tuple(label.xyann) == (4, 0)
        assert (label.get_ha(), label.get_va()) == ("left", "center")


@pytest.mark.parametrize("freqs, xlim", [
    ((100.0, 150.0, 200.0), (100.0 - 0.4 * 50, 200.0 + 0.6 * 50)),  # the closest two apart
    ((100.0,), (100.0 - 0.4 * 20, 100.0 + 0.6 * 20)),  # one: a fifth of it
    ((5.0,), (5.0 - 0.4, 5.0 + 0.6)),  # (a fifth of it: 1 Hz, the floor)
    ((2.0,), (2.0 - 0.4, 2.0 + 0.6))],  # one below 5 Hz: 1 Hz
    ids=["three", "one of 100 Hz", "one of 5 Hz", "one of 2 Hz"])
def test_fig5_frames_its_frequencies_with_room_for_the_labels(freqs, xlim, figures,
                                                               tmp_path):
    """The frequency axis runs 0.4 steps left of the first frequency and 0.6 right of the last
    (room for the margins' labels); a step is the closest two frequencies apart, or for a
    single frequency a fifth of it but at least 1 Hz."""
    per, _ = _per(freqs)
    adxl203.plot_fig5(tmp_path / "fig5.png", per)
    (fig,) = figures
    assert fig.axes[0].get_xlim() == pytest.approx(xlim, rel=1e-12)


def test_a_laid_out_figure_is_drawn_once_to_the_same_pixels(tmp_path, monkeypatch):
    """``output.savefig`` after ``tight_layout`` draws the figure once (matplotlib's savefig
    draws it twice while the placeholder layout engine that tight_layout leaves is set), and
    the PNG is the one of before, byte for byte."""
    from matplotlib.figure import Figure

    def laid_out():
        fig, ax = plt.subplots(figsize=(5, 3))
        ax.plot(np.arange(50), np.sin(np.arange(50) / 5.0), label="a curve")
        ax.set_xscale("log")
        ax.legend()
        ax.set_title("title")
        fig.tight_layout()
        return fig

    fig = laid_out()
    fig.savefig(tmp_path / "before.png", dpi=100)   # as it was saved before
    plt.close(fig)
    draws = []
    draw = Figure.draw
    monkeypatch.setattr(Figure, "draw", lambda self, r: (draws.append(1), draw(self, r))[1])
    fig = laid_out()
    output.savefig(fig, tmp_path / "now.png", dpi=100)
    plt.close(fig)
    assert len(draws) == 1
    assert (tmp_path / "now.png").read_bytes() == (tmp_path / "before.png").read_bytes()


def test_figures_drawn_beside_each_run_once_and_a_failure_is_raised_here(tmp_path, monkeypatch):
    """``output.draw_beside``: the first job here, the others in a worker; each once; an
    exception in the worker reaches the caller (no figure silently missing)."""
    import functools
    import operator
    from pathlib import Path
    for cheap in (True, False):
        monkeypatch.setattr(output, "fork_is_cheap", lambda: cheap)
        folder = tmp_path / str(cheap)
        folder.mkdir()
        output.draw_beside(*[functools.partial(Path.write_text, folder / name, name)
                             for name in ("a", "b", "c")])
        assert sorted(p.read_text() for p in folder.iterdir()) == ["a", "b", "c"]
        with pytest.raises(ZeroDivisionError):
            output.draw_beside(functools.partial(int, "1"),
                               functools.partial(operator.truediv, 1, 0))


@pytest.mark.parametrize("legend", ["beside", "inside", "none"])
def test_the_note_of_what_is_off_the_scale_covers_no_curve(figures, tmp_path, legend):
    """Curves that fill the lower right corner and leave the scale: the note goes beside the
    axes under a legend that sits there, into a legend placed on the axes, else where it
    covers no point (not in the corner on the data, where it was)."""
    k = np.arange(1, 1001)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(k, 1.0 / k, label="falls into the corner")
    ax.plot(k, np.where(k < 20, 50.0, 0.05 + 0.0 * k), label="starts off the scale")
    ax.set_xscale("log")
    ax.set_ylim(0.0, 1.0)
    ax.set_xlabel("sample k (log scale)")
    ax.set_ylabel("drift [mV]")
    if legend == "beside":
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))
    elif legend == "inside":
        ax.legend(loc="upper right")
    output.caption(fig, "A figure whose curves fill the corner where the note once went")
    output.layout(fig)
    output.savefig(fig, tmp_path / "f.png")
    plt.close(fig)
    (note, text), = output.clipping_notes(ax)
    assert "starts off the scale off the scale above" in text and "at k = 1 to 19" in text
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    assert (note.get_window_extent(renderer).x0
            > ax.get_window_extent(renderer).x1) == (legend == "beside")
    _check_notes(ax, renderer, fig.bbox)
