"""Figures and printed lines name what they show: the letter's sensor is called the letter's, the
general sensor (a3, a4) is named with its terms wherever a drift is defined by them, titles and
drifts carry units, and no note or title is cryptic or crowded."""
import matplotlib
import pytest

matplotlib.use("Agg")

from driftfmu.simulations import dual_axis, gaussian, montecarlo, output, sweep  # noqa: E402
from driftfmu.simulations.cli import main  # noqa: E402


@pytest.fixture
def drawn(closed_figures, monkeypatch):
    """Every figure the code closes, kept for inspection; figures drawn in this process."""
    monkeypatch.setattr(output, "fork_is_cheap", lambda: False)
    return closed_figures


def texts(fig):
    """Every text of a figure: caption, axes titles and labels, legend entries, notes."""
    out = [fig._suptitle.get_text() if fig._suptitle else ""]
    for ax in fig.axes:
        out += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        out += [t.get_text().replace("\n", " ") for t in ax.texts]
        legend = ax.get_legend()
        if legend is not None:
            out += [t.get_text() for t in legend.get_texts()]
    for legend in fig.legends:
        out += [t.get_text() for t in legend.get_texts()]
    return "\n".join(t.replace("\n", " ") for t in out).replace("\u00a0", " ")


@pytest.mark.integration
def test_one_run_names_the_letters_sensor_or_the_general_one(python_fmus, tmp_path, drawn):
    fmu_dir = python_fmus["Excitation"].parent
    gaussian.run_gaussian(out=tmp_path / "letter", n=200, fmu_dir=fmu_dir)
    gaussian.run_gaussian(out=tmp_path / "general", n=200, fmu_dir=fmu_dir, a3=0.01, a4=0.05)
    letter, general = (texts(f) for f in drawn)
    assert "(the letter's Fig. 1)" in letter and "realised  a2·mean(x²)" in letter
    assert "expected  a2·E[x²]" in letter
    assert "letter's Fig. 1" not in general
    assert "the general sensor (a3 = 0.01 V/g³, a4 = 0.05 V/g⁴" in general
    assert "realised  mean(a2 x² + a3 x³ + a4 x⁴)" in general
    assert "expected  E[a2 x² + a3 x³ + a4 x⁴]" in general
    assert "a2·mean(x²)" not in general and "a2·E[x²]" not in general
    for text in (letter, general):  # the caption's values carry their units
        assert "a1 = 1 V/g, a2 = 0.01 V/g², Q = 0.01 g², R = 0.0001 V²" in text


def test_a_population_names_the_realised_drift_it_is_judged_against(tmp_path, drawn):
    montecarlo.montecarlo_gaussian(runs=20, n=100, workers=1, out=tmp_path / "letter")
    montecarlo.montecarlo_gaussian(runs=20, n=100, workers=1, out=tmp_path / "general", a4=0.05)
    montecarlo.montecarlo_sinusoidal(runs=20, n=100, workers=1, out=tmp_path / "sine", a3=0.02)
    letter, general, sine = (texts(f) for f in drawn)
    assert "the letter's Fig. 1 as a population" in letter
    assert "estimation error against the realised drift a2·mean(x²)" in letter
    assert "letter's Fig. 1" not in general and "a4 = 0.05 V/g⁴" in general
    assert "against the realised drift mean(a2 x² + a4 x⁴)" in general
    assert "beside the realised drift mean(a2 x² + a4 x⁴)" in general
    assert "a2·mean(x²)" not in general
    assert "a3 = 0.02 V/g³" in sine and "mean(a2 x² + a3 x³)" in sine
    assert "a2·mean(x²)" not in sine


def test_sweep_figures_give_units_and_the_realised_drifts_terms(tmp_path, drawn):
    sweep.sweep(a2=[0.01, 0.1], R=[1e-4, 1e-3], runs=5, n=50, workers=1, a4=0.02,
                out=tmp_path / "s")
    for fig in drawn:
        text = texts(fig)
        assert "a4 = 0.02 V/g⁴, a1 = 1 V/g, Q = 0.01 g², A = 0" in text, text
        assert "against the realised drift mean(a2 x² + a4 x⁴)" in text
        assert "a2·mean(x²)" not in text
    drawn.clear()
    sweep.sweep(a4=[0.0, 0.01], a2=[0.02], R=[1e-4], runs=5, n=50, workers=1,
                out=tmp_path / "a4")
    text = texts(drawn[0])
    assert "a2 = 0.02 V/g², a1 = 1 V/g" in text and "mean(a2 x² + a4 x⁴)" in text


def test_dual_axis_figure_states_its_worst_error_and_the_criterion(tmp_path, drawn):
    s = dual_axis.run_dual_axis(out=tmp_path / "d", points=3, runs=4, n=400, engine="batch",
                                workers=1)
    text = texts(drawn[0])
    assert "outside this range" not in text
    worst = [t for t in text.splitlines() if t.startswith("every point within ±")]
    assert len(worst) == 2 and all(t.endswith("the criterion is ±2 %") for t in worst), worst
    fig = drawn[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:  # the notes stay inside their axes
        frame = ax.get_window_extent(renderer)
        for t in ax.texts:
            box = t.get_window_extent(renderer)
            assert frame.x0 <= box.x0 and box.x1 <= frame.x1, t.get_text()
    assert s["claims"]["dual_within_band_everywhere"]


def test_titles_stand_clear_of_the_marks_on_the_top_edge(tmp_path, drawn):
    """fig1.png: a curve off the top of its axes is marked by triangles on the top edge; the
    axes' title is lifted above them, not drawn through them."""
    montecarlo.montecarlo_gaussian(runs=20, n=100, workers=1, out=tmp_path / "m")
    fig = drawn[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    checked = 0
    for ax in fig.axes:
        top = ax.get_window_extent(renderer).y1
        marks = [line for line in ax.get_lines() if line.get_label().startswith("_clipped")
                 and line.get_marker() == "^"]
        if not marks:
            continue
        highest = max(m.get_window_extent(renderer).y1 for m in marks)
        assert highest > top  # the triangles reach above the frame...
        title = ax.title.get_window_extent(renderer)
        # ...and the title clears them by at least 4 points (it was 1 point)
        assert title.y0 - highest >= 4 * fig.dpi / 72, (ax.get_title(), title.y0, highest)
        checked += 1
    assert checked >= 2
    # the caption stays above every axes' title
    caption = fig._suptitle.get_window_extent(renderer)
    assert all(caption.y0 >= ax.title.get_window_extent(renderer).y1 for ax in fig.axes)


@pytest.mark.integration
def test_printed_drifts_have_units_and_the_closed_form_only_for_the_letters_sensor(
        python_fmus, tmp_path, capsys):
    fmu_dir = str(python_fmus["Excitation"].parent)
    assert main(["run", "gaussian", "--n", "200", "--fmu-dir", fmu_dir,
                 "--out", str(tmp_path / "l")]) == 0
    letter = capsys.readouterr().out
    assert main(["run", "gaussian", "--n", "200", "--a4", "0.05", "--fmu-dir", fmu_dir,
                 "--out", str(tmp_path / "g")]) == 0
    general = capsys.readouterr().out
    for text in (letter, general):
        assert "final drift [V]: EKF1 " in text
    assert "(expected 10 log10(1 + R/(a1^2 Q)) = 0.0432 dB)" in letter
    gap = [line for line in general.splitlines() if line.startswith("EKF1-EKF2 gap")]
    assert gap and "10 log10" not in gap[0], gap


def test_the_sweep_table_gives_its_units(tmp_path, capsys):
    assert main(["sweep", "--a2", "0.01", "--R", "1e-4", "--runs", "4", "--n", "30",
                 "--workers", "1", "--out", str(tmp_path / "s")]) == 0
    head = capsys.readouterr().out.splitlines()[:2]
    assert head[0].split()[:3] == ["a2", "R", "expected"], head
    assert head[1].split()[:4] == ["[V/g^2]", "[V^2]", "drift", "[V]"], head
    assert "mean |error| [V]" in head[0]
