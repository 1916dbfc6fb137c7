"""``driftfmu doctor`` gives every "will NOT run" a reason in words and a verdict line that
repeats it (issue 19): a broken modelDescription.xml, a missing resources/ folder, a truncated
binary."""
import glob
import os
import zipfile
from pathlib import Path

import numpy
import pytest

from driftfmu.simulations import doctor
from driftfmu.simulations.cli import main


def _rewrite(src, dst, drop=(), replace=None):
    replace = replace or {}
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            if any(item.filename.startswith(d) for d in drop):
                continue
            data = zin.read(item.filename)
            if item.filename in replace:
                data = replace[item.filename](data)
            zout.writestr(item, data)
    return dst


def _a_shared_library():
    found = sorted(glob.glob(os.path.join(os.path.dirname(numpy.__file__), "**", "*.so"),
                             recursive=True), key=os.path.getsize)
    if not found:
        pytest.skip("no shared library to test with")
    return Path(found[-1]).read_bytes()


@pytest.mark.skipif(not os.uname().sysname == "Linux", reason="ELF checks are for Linux")
def test_a_truncated_or_foreign_binary_is_named_from_its_bytes():
    whole = _a_shared_library()
    assert doctor._binary_problem(whole, len(whole)) is None
    half = whole[:len(whole) // 2]
    why = doctor._binary_problem(half, len(half))
    assert why.startswith("truncated: the file has %d bytes" % len(half)), why
    assert "not an ELF shared library" in doctor._binary_problem(b"MZ" + b"\0" * 100, 102)
    assert doctor._binary_problem(b"", 0) == "an empty file"
    bits32 = whole[:4] + b"\x01" + whole[5:]
    assert "32-bit" in doctor._binary_problem(bits32, len(bits32))


def _verdict(fmu, capsys):
    with pytest.raises(SystemExit) as info:
        main(["doctor", str(fmu)])
    out = capsys.readouterr().out
    assert info.value.code == 1, out
    verdict = [line for line in out.splitlines() if line.startswith("verdict:")]
    assert len(verdict) == 1, out
    return out, verdict[0]


def test_the_python_an_fmu_was_built_with_is_named_only_when_it_differs(tmp_path):
    """A Python version in the build record other than this process's is named; the same
    version, or no record (a native FMU), says nothing of it."""
    import json
    import sys

    import paperfmu
    here = "%d.%d" % sys.version_info[:2]
    line = ("this process runs Python %s; the FMU was built with %%s — fine for Python hosts, "
            "whose own interpreter runs the FMU's code" % here)
    fmu = paperfmu.paper_fmu(tmp_path / "Excitation.fmu", "Excitation")
    said = [msg for _, msg in doctor.diagnose(fmu)]
    assert not [m for m in said if "the FMU was built with" in m], said
    for version, named in (("3.9.7", "3.9"), ("%s.1" % here, None)):
        with_record = tmp_path / ("Excitation_%s.fmu" % version)
        with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(with_record, "w") as zout:
            for item in zin.infolist():
                zout.writestr(item, zin.read(item.filename))
            zout.writestr("resources/driftfmu_build.json",
                          json.dumps({"python_version": version, "loader": "C"}))
        said = [msg for _, msg in doctor.diagnose(with_record)]
        assert "built by driftfmu with Python %s (C loader)" % version in said, said
        assert [m for m in said if "the FMU was built with" in m] == \
            ([line % named] if named else []), said


def test_a_start_value_outside_its_declared_range_is_named_once(tmp_path):
    """A start value past its declared max is named (the first such one only: one line); one
    at the max is not."""
    import paperfmu
    fmu = paperfmu.paper_fmu(tmp_path / "paper.fmu", "Accelerometer")
    noise = '<Integer min="0" max="1" start="1" />'  # noise: 1 on, 0 off
    vs = '<Real unit="V" min="0.0" max="6.0" start="0.0" />'

    def said(name, edits):
        edited = _rewrite(fmu, tmp_path / name, replace={"modelDescription.xml": lambda data: (
            data.decode().replace(noise, edits[0]).replace(vs, edits[1]).encode())})
        return [msg for level, msg in doctor.diagnose(edited) if level == doctor.FAIL
                and "outside its declared range" in msg]

    at_max = ('<Integer min="0" max="1" start="1" />', '<Real unit="V" min="0.0" max="6.0" '
              'start="6.0" />')
    assert said("Accelerometer.fmu", at_max) == []
    past = ('<Integer min="0" max="1" start="2" />', '<Real unit="V" min="0.0" max="6.0" '
            'start="6.5" />')
    assert said("Accelerometer_past.fmu", past) == [
        "its modelDescription.xml: the start value of noise is 2, outside its declared "
        "range; expected: noise >= 0 and noise <= 1. A host would start the FMU outside what "
        "it declares"]


def test_an_archive_is_an_ssp_only_with_a_system_structure_and_no_model_description(tmp_path):
    """A zip archive with neither modelDescription.xml nor SystemStructure.ssd is named an FMU
    without a model description (not diagnosed as an SSP); an FMU that also carries a
    SystemStructure.ssd is diagnosed as the FMU it is."""
    import paperfmu
    neither = tmp_path / "Accelerometer.fmu"
    with zipfile.ZipFile(neither, "w") as zf:
        zf.writestr("resources/readme.txt", "no model description here")
    assert doctor.diagnose(neither) == [(doctor.FAIL, "%s has no modelDescription.xml"
                                         % neither)]
    fmu = paperfmu.paper_fmu(tmp_path / "paper.fmu", "Accelerometer")
    both = tmp_path / "with_ssd" / "Accelerometer.fmu"
    both.parent.mkdir()
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(both, "w") as zout:
        for item in zin.infolist():
            zout.writestr(item, zin.read(item.filename))
        zout.writestr("SystemStructure.ssd", "<not read/>")
    said = doctor.diagnose(both)
    assert said[0][0] == doctor.OK and said[0][1].startswith(
        "FMI 2.0 co-simulation FMU 'Accelerometer'"), said


@pytest.mark.parametrize("edited, more", [
    pytest.param(("Ts",), "", id="one"),
    pytest.param(("Ts", "a3"), " (and 1 more difference)", id="two"),
    pytest.param(("Ts", "a3", "fc"), " (and 2 more differences)", id="three")])
def test_the_differences_from_the_table_past_the_first_are_counted_in_words(edited, more,
                                                                            tmp_path):
    """The first difference of a model description from driftfmu's table is named, the others
    counted: none, "1 more difference" (two found), "2 more differences" (three found)."""
    import paperfmu
    fmu = paperfmu.paper_fmu(tmp_path / "paper.fmu", "Accelerometer")
    starts = {"Ts": ('unit="s" min="1e-09" start="0.001"', 'unit="s" min="1e-09" start="0.002"'),
              "a3": ('unit="V/g3" start="0.0"', 'unit="V/g3" start="0.5"'),
              "fc": ('unit="Hz" min="0.0" max="2500.0" start="0.0"',
                     'unit="Hz" min="0.0" max="2500.0" start="10.0"')}

    def edit(data):
        text = data.decode()
        for name in edited:
            assert text.count(starts[name][0]) == 1, name
            text = text.replace(*starts[name])
        return text.encode()

    fmu = _rewrite(fmu, tmp_path / "Accelerometer.fmu", replace={"modelDescription.xml": edit})
    said = [msg for level, msg in doctor.diagnose(fmu) if level == doctor.FAIL
            and "is not driftfmu's Accelerometer" in msg]
    assert len(said) == 1, said
    assert said[0].startswith("its modelDescription.xml is not driftfmu's Accelerometer as its "
                              "code runs: the start value of Ts is 0.002; expected: 0.001,"), said
    assert said[0].endswith("%s. A host would be silently wrong; rebuild the FMU (driftfmu "
                            "build)" % more), said


@pytest.mark.integration
def test_a_broken_model_description_is_named_with_a_verdict(built_fmus, tmp_path, capsys):
    bad = _rewrite(built_fmus["Excitation"], tmp_path / "Excitation.fmu",
                   replace={"modelDescription.xml": lambda data: data[:len(data) // 2]})
    out, verdict = _verdict(bad, capsys)
    assert "modelDescription.xml cannot be read" in out and "rebuild it (driftfmu build)" in out
    assert "will NOT run" in verdict and "modelDescription.xml cannot be read" in verdict


@pytest.mark.integration
def test_a_missing_resources_folder_is_named(built_fmus, tmp_path, capsys):
    bad = _rewrite(built_fmus["Excitation"], tmp_path / "Excitation.fmu", drop=("resources/",))
    out, verdict = _verdict(bad, capsys)
    assert "no resources/ folder" in out and "resources/driftfmu_build.json" in out
    assert "no resources/ folder" in verdict


@pytest.mark.integration
def test_a_truncated_native_binary_is_named_not_ok(native_fmus, tmp_path, capsys):
    src = native_fmus[2]["Excitation"]
    bad = _rewrite(src, tmp_path / "Excitation.fmu",
                   replace={"binaries/linux64/Excitation.so": lambda data: data[:len(data) // 2]})
    out, verdict = _verdict(bad, capsys)
    assert "[  ok  ] it has a binary" not in out
    assert "binaries/linux64/Excitation.so is damaged: truncated" in out
    assert "damaged" in verdict
    assert "exit status -7" not in out


@pytest.mark.parametrize("end, timeout, said", [
    ("import os, signal; os.kill(os.getpid(), signal.SIGSEGV)", 120, "crashed that host"),
    ("import time; time.sleep(60)", 1, "did not finish in 1 s")])
def test_a_host_that_crashes_or_hangs_leaves_no_extracted_fmu(end, timeout, said, tmp_path,
                                                              monkeypatch):
    """The instantiation check's child extracts the FMU into a folder the doctor made and
    removes (the child removed it itself before, which a crash or the time limit skipped)."""
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    code = ("import sys; from pathlib import Path\n"
            "(Path(sys.argv[2]) / 'modelDescription.xml').write_text('extracted')\n" + end)
    status, text = doctor._run_instantiate(code, tmp_path / "x.fmu", timeout=timeout)
    assert status == doctor.FAIL and said in text, text
    assert list(tmp_path.iterdir()) == []


def test_a_module_imported_at_import_time_is_not_also_counted_as_imported_later():
    # doctor reads a slave's imports: those at import time, and those only inside functions
    # (a module imported both ways is an import-time one)
    source = ("import numpy\nimport json\n\n\ndef f():\n    import numpy\n    import scipy.signal\n"
              "    from lxml import etree\n")
    assert doctor._imports(source) == ({"numpy", "json"}, {"scipy", "lxml"})
