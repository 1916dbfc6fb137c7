"""Resource locations: every file URI form FMI 2.0 allows works, in folders whose names have
``+``, ``#``, spaces, ``%`` and non-ASCII letters, in fmpy and in a C host; unusable ones give
NULL and a message (more of those in tests/fuzz/cases.py)."""
import urllib.parse
from pathlib import Path

import fmpy
import numpy as np
import pytest

import fuzz

pytestmark = pytest.mark.integration
STEPS = 20
#: Folder names hosts get wrong: '+' and '#' (URI syntax), spaces, '%' (pythonfmu turns "%20"
#: into a space), non-ASCII letters (percent-encoded UTF-8 bytes).
FOLDERS = ["tmp+dir #1 ä", "sp ace", "a%20b", "100%", "Grüße ß", "日本"]


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    exe = fuzz.compile_host(tmp_path_factory.mktemp("uri_host"))
    if exe is None:
        pytest.skip("no C compiler to build the host")
    return exe


@pytest.fixture(scope="module")
def plain(built_fmus, tmp_path_factory):
    """The Accelerometer unzipped into a folder with a plain name."""
    return fuzz.unzip(built_fmus["Accelerometer"], tmp_path_factory.mktemp("plain") / "fmu")


def encoded(path):
    """``file:///`` + every byte of the absolute path after its first '/' percent-encoded."""
    return "file:///" + urllib.parse.quote(str(path)[1:], safe="")


def uri_forms(folder):
    """Every form of a resource location we accept, for the resources folder ``folder``."""
    p = str(folder)
    return {
        "file:///abs (as fmpy and pathlib encode it)": Path(p).as_uri(),
        "file:/abs": "file:" + urllib.parse.quote(p),
        "file://localhost/abs": "file://localhost" + urllib.parse.quote(p),
        "FILE://LocalHost/abs (scheme and host case-insensitive)":
            "FILE://LocalHost" + urllib.parse.quote(p),
        "every byte percent-encoded, '/' too": encoded(p),
        "'+' and '#' left as they are": "file://" + urllib.parse.quote(p, safe="/+#"),
        "not encoded at all": "file://" + p,
        "trailing slash": Path(p).as_uri() + "/",
        "a plain absolute path": p,
    }


def c_host_value(host, model, uri):
    """Run the C host with resource location ``uri``: (result, z after STEPS steps or None)."""
    lines = ["load 0 %s %s" % (fuzz.word(model.dir), model.identifier),
             "inst 0 0 uri 1 %s %s" % (model.guid, fuzz.word(uri))]
    lines += fuzz.initialise(model, 0, {"x": 0.75})
    lines += ["step 0 %r %r" % (k * model.Ts, model.Ts) for k in range(STEPS)]
    lines += ["getr 0 1 %d" % model.vr["z"], "free 0"]
    result = fuzz.run_script(host, lines)
    values = list(result.values().values())
    return result, (float(values[-1][0]) if values else None)


@pytest.fixture(scope="module")
def reference(host, plain):
    result, value = c_host_value(host, plain, "DEFAULT")
    assert value is not None, result.output
    return value


@pytest.fixture(scope="module")
def unzipped(built_fmus, tmp_path_factory):
    """folder name -> the Accelerometer unzipped into a folder of that name (once each)."""
    cache = {}

    def get(folder):
        if folder not in cache:
            root = tmp_path_factory.mktemp("uri") / folder
            cache[folder] = fuzz.unzip(built_fmus["Accelerometer"], root)
        return cache[folder]
    return get


def _folders_and_forms():
    """Every (folder, URI form) pair; the everyday loop runs a covering set (each form and
    each folder at least once), the qualification the rest of the product."""
    forms = list(uri_forms("/x"))
    cover = {(FOLDERS[i % len(FOLDERS)], form) for i, form in enumerate(forms)}
    cover |= {(folder, forms[i % len(forms)]) for i, folder in enumerate(FOLDERS)}
    return [pytest.param(folder, form, id="%s-%s" % (folder, form),
                         marks=() if (folder, form) in cover else pytest.mark.qualification)
            for folder in FOLDERS for form in forms]


@pytest.mark.parametrize("folder, form", _folders_and_forms())
def test_each_uri_form_in_the_c_host(host, unzipped, reference, folder, form):
    model = unzipped(folder)
    uri = uri_forms(Path(model.dir) / "resources")[form]
    result, value = c_host_value(host, model, uri)
    assert result.problems() == [] and "INST 0 ok" in result.lines, (uri, result.output)
    assert value == reference


def test_unusable_locations_give_null_and_say_what_is_allowed(host, plain):
    resources = Path(plain.dir) / "resources"
    for uri in ["http://localhost" + str(resources), "file://server" + str(resources),
                "resources", "file:resources", "file://" + str(resources) + "/missing",
                "file://" + plain.dir, "NULL"]:
        result = fuzz.run_script(host, [
            "load 0 %s %s" % (fuzz.word(plain.dir), plain.identifier),
            "inst 0 0 uri 1 %s %s" % (plain.guid, fuzz.word(uri))])
        assert "INST 0 null" in result.lines and result.problems() == [], (uri, result.output)
        message = next(line for line in result.lines if line.startswith("LOG 3"))
        assert "allowed: a file URI of this FMU's resources folder" in message
        if uri != "NULL":
            assert uri in message


@pytest.mark.parametrize("folder", FOLDERS)
def test_fmpy_simulates_the_unzipped_fmus(built_fmus, tmp_path, folder):
    """fmpy passes a percent-encoded file:/// URI (pathlib's as_uri)."""
    for name, fmu in built_fmus.items():
        plain = tmp_path / "plain" / name
        odd = tmp_path / folder / name
        fmpy.extract(str(fmu), unzipdir=str(plain))
        fmpy.extract(str(fmu), unzipdir=str(odd))
        expected = fmpy.simulate_fmu(str(plain), stop_time=0.05, output_interval=1e-3)
        got = fmpy.simulate_fmu(str(odd), stop_time=0.05, output_interval=1e-3)
        assert got.dtype.names == expected.dtype.names
        for column in expected.dtype.names:
            assert np.array_equal(got[column], expected[column]), (name, column)
