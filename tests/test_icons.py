"""Every FMU carries an icon (fmu_src/icons.py): ``model.png`` at the archive root, and FMI 3.0's
``terminalsAndIcons/icon.png``; a valid PNG of the declared size, one per model, the same bytes
from build to build."""
import io
import zipfile

import pytest

from driftfmu.fmu_src import icons


def _png(data, what):
    from PIL import Image
    assert data[:8] == b"\x89PNG\r\n\x1a\n", what
    image = Image.open(io.BytesIO(data))
    image.verify()  # the whole file: chunks and their checksums
    image = Image.open(io.BytesIO(data))
    assert image.format == "PNG" and image.size == (icons.SIZE, icons.SIZE), what
    image.load()
    colours = image.convert("RGB").getcolors(maxcolors=1 << 16)
    assert colours is None or len(colours) > 8, what  # a drawing, not a blank square
    return image


def _kinds(python_fmus, native_fmus):
    yield "python", 2, python_fmus
    for v, fmus in native_fmus.items():
        yield "native-fmi%d" % v, v, fmus


@pytest.mark.integration
def test_every_fmu_of_every_kind_carries_its_icon(python_fmus, native_fmus):
    seen = {}
    for kind, version, fmus in _kinds(python_fmus, native_fmus):
        assert len(fmus) >= 3, kind
        for name, path in fmus.items():
            with zipfile.ZipFile(path) as z:
                names = set(z.namelist())
                assert "model.png" in names, (kind, name)
                data = z.read("model.png")
                _png(data, (kind, name))
                if version == 3:
                    assert z.read("terminalsAndIcons/icon.png") == data, (kind, name)
                else:
                    assert not any(n.startswith("terminalsAndIcons/") for n in names), kind
            assert data == icons.png(name), (kind, name)  # the model's, the same bytes
            seen.setdefault(name, set()).add(data)
    assert all(len(v) == 1 for v in seen.values())  # one icon per model across kinds
    assert len({next(iter(v)) for v in seen.values()}) == len(seen)  # and a different one each


def test_an_icon_is_the_same_bytes_when_drawn_again():
    first = {n: icons.png(n) for n in ("Excitation", "Accelerometer", "DriftEstimator")}
    icons.png.cache_clear()
    assert {n: icons.png(n) for n in first} == first


def test_a_model_without_a_drawing_of_its_own_still_gets_a_named_block():
    _png(icons.png("SomeNewModel"), "a model the drawings do not know")
    assert icons.entries("SomeNewModel", 3)["terminalsAndIcons/icon.png"] == \
        icons.png("SomeNewModel")
    assert set(icons.entries("SomeNewModel", 2)) == {"model.png"}


def _glyph(name):
    """The axes ``icons._draw`` draws model ``name``'s glyph in (data coordinates 0..1)."""
    from matplotlib.figure import Figure
    ax = Figure().add_axes((0, 0, 1, 1))
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    icons._draw(ax, name)
    return ax


def test_the_blocks_frame_is_a_bold_line_of_about_3_5_px():
    # lw 2.5 pt at 100 dpi: 3.5 px, three of them fully dark at mid-height on either side
    from PIL import Image
    image = Image.open(io.BytesIO(icons.png("SomeNewModel"))).convert("RGBA")
    y = icons.SIZE // 2
    for columns in (range(0, 20), range(icons.SIZE - 20, icons.SIZE)):
        dark = [x for x in columns if image.getpixel((x, y))[3] == 255
                and image.getpixel((x, y))[0] < 128]
        assert len(dark) >= 3, columns
        assert max(dark) - min(dark) == len(dark) - 1 and len(dark) <= 4  # one line


def test_the_glyphs_labels_and_their_font_sizes():
    sizes = {}
    for name in ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator"):
        sizes.update({t.get_text(): t.get_fontsize() for t in _glyph(name).texts})
    assert sizes == {"x(t)": 11, "z = h(x)": 10, "EKF dc": 10}


def test_each_glyphs_label_is_centred_under_it():
    """The label sits on the block's middle line (x = 0.5, centred) below its glyph's lines:
    a label off the middle is cut off by the block's edge."""
    for name in ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator"):
        ax = _glyph(name)
        (label,) = ax.texts
        x, y = label.get_position()
        assert (x, label.get_horizontalalignment()) == (0.5, "center"), name
        lowest = min(v for line in ax.get_lines() for v in line.get_ydata())
        assert 0.0 <= y < lowest, name


def test_the_sensors_characteristic_spans_its_axes_both_sides_of_zero():
    ax = _glyph("Accelerometer")
    curve, horizontal, vertical = ax.get_lines()
    x, y = (list(v) for v in curve.get_data())
    # x from -1 to 1 drawn over the horizontal axis line, from end to end, through the origin
    assert (min(x), max(x)) == pytest.approx(tuple(horizontal.get_xdata()))
    assert list(vertical.get_xdata()) == [0.5, 0.5] and 0.5 in [round(v, 12) for v in x]
    assert y[x.index(min(x))] < 0.3 < y[-1]  # the bent characteristic: below, then above
    # the model's curve bold (2 pt), like every glyph's; its axes thin (1 pt)
    assert (curve.get_linewidth(), horizontal.get_linewidth(), vertical.get_linewidth()) == \
        (2, 1, 1)


def test_the_dual_estimators_glyph_draws_one_trace_pair_per_axis_apart():
    single = _glyph("DriftEstimator").get_lines()
    dual = _glyph("DualDriftEstimator").get_lines()
    assert len(single) == 2 and len(dual) == 4
    # the single estimator's pair in the middle; the dual one's two pairs above and below it
    mid = [sum(line.get_ydata()) / len(line.get_ydata()) for line in single]
    upper = [sum(line.get_ydata()) / len(line.get_ydata()) for line in dual[:2]]
    lower = [sum(line.get_ydata()) / len(line.get_ydata()) for line in dual[2:]]
    assert all(u > m + 0.1 and m > lo + 0.1 for u, m, lo in zip(upper, mid, lower))
    assert all(0 < v < 1 for line in dual for v in line.get_ydata())
