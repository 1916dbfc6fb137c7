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
