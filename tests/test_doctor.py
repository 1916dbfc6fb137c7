"""``driftfmu doctor``: plain-words diagnosis of whether an FMU runs on this host."""
import zipfile
from pathlib import Path

import pytest

from driftfmu.simulations import doctor
from driftfmu.simulations.cli import main

pytestmark = pytest.mark.integration


def _rewrite(src, dst, drop=(), add=None):
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            if not any(item.filename.startswith(d) for d in drop):
                zout.writestr(item, zin.read(item.filename))
        for name, data in (add or {}).items():
            zout.writestr(name, data)
    return dst


def test_built_fmu_is_healthy(built_fmus, capsys):
    assert main(["doctor", str(built_fmus["DriftEstimator"])]) == 0
    out = capsys.readouterr().out
    print(out)
    assert "verdict: this FMU will run on this host" in out
    assert "needs only the standard library" in out
    assert "libpython" in out


def test_missing_binary_is_a_problem(built_fmus, tmp_path, capsys):
    broken = _rewrite(built_fmus["Accelerometer"], tmp_path / "Accelerometer.fmu",
                      drop=("binaries/linux64/",))
    with pytest.raises(SystemExit) as info:
        main(["doctor", str(broken)])
    out = capsys.readouterr().out
    print(out)
    assert info.value.code == 1
    assert "no binary for this platform (linux64)" in out


def test_foreign_import_is_named(built_fmus, tmp_path):
    bad = _rewrite(built_fmus["Excitation"], tmp_path / "Excitation.fmu",
                   add={"resources/extra.py": "import surely_not_a_module_xyz\n"})
    findings = doctor.diagnose(bad)
    assert any(level == doctor.FAIL and "surely_not_a_module_xyz" in msg
               for level, msg in findings)


def test_not_an_fmu(tmp_path):
    p = tmp_path / "x.fmu"
    p.write_text("hello")
    assert doctor.diagnose(p) == [(doctor.FAIL, "%s is not an FMU: not a zip archive" % p)]


@pytest.mark.parametrize("damage", ["deflate stream", "crc"])
def test_a_damaged_archive_is_a_named_problem_not_a_crash(built_fmus, tmp_path, capsys, damage):
    """Bytes overwritten inside one entry's compressed data (a broken download or copy): the
    doctor names the file and the entry instead of stopping with zlib's message."""
    fmu = tmp_path / "copy of.fmu"
    data = bytearray(Path(built_fmus["DriftEstimator"]).read_bytes())
    with zipfile.ZipFile(built_fmus["DriftEstimator"]) as z:
        info = z.getinfo("binaries/linux64/DriftEstimator.so")
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    if damage == "crc":  # the CRC-32 of the central directory changed: the data inflate fine
        name = info.filename.encode()
        at = next(i for i in range(len(data)) if data[i:i + 4] == b"PK\x01\x02"
                  and data[i + 46:i + 46 + len(name)] == name)
        data[at + 16] ^= 0xFF
    else:
        data[start + 2000:start + 2050] = bytes(50)
    fmu.write_bytes(bytes(data))
    assert doctor.report(fmu) == 1
    out = capsys.readouterr().out
    assert "[PROBLEM] %s is damaged: binaries/linux64/DriftEstimator.so (" % fmu in out
    assert "verdict: this FMU will NOT run on this host as it is: %s is damaged" % fmu in out


def test_a_folder_is_refused_with_what_is_allowed(tmp_path, capsys):
    folder = tmp_path / "un. zipped"  # a ". " in the path does not cut the verdict short
    folder.mkdir()
    assert doctor.report(folder) == 1
    out = capsys.readouterr().out
    assert ("verdict: this FMU will NOT run on this host as it is: %s is a folder, not an FMU"
            % folder) in out


def test_an_empty_path_is_a_usage_error(capsys):
    from driftfmu.simulations.cli import main
    assert main(["doctor", ""]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["driftfmu: error: FMU '' is empty; allowed: the path of a .fmu file"]


def test_a_model_description_that_does_not_validate_says_what_fails(built_fmus, tmp_path,
                                                                     capsys):
    """fmpy's ValidationError reads "Failed to validate modelDescription.xml:" and keeps what
    failed in .problems: the doctor quotes those, whole, also in the verdict; the advice to
    rebuild is for driftfmu's own FMUs."""
    with zipfile.ZipFile(built_fmus["Excitation"]) as z:
        md = z.read("modelDescription.xml").decode()
    start, end = md.index("<ModelVariables>"), md.index("</ModelVariables>")
    bad = md[:start] + "<ModelVariables>" + md[end:]  # no variable at all
    fmu = _rewrite(built_fmus["Excitation"], tmp_path / "Excitation.fmu",
                   drop=("modelDescription.xml",), add={"modelDescription.xml": bad})
    with pytest.raises(SystemExit) as info:
        main(["doctor", str(fmu)])
    out = capsys.readouterr().out
    assert info.value.code == 1
    assert "Failed to validate modelDescription.xml:)" not in out, out
    assert "Missing child element(s). Expected is ( ScalarVariable )." in out, out
    assert "If it is one of driftfmu's FMUs, rebuild it (driftfmu build)" in out
    verdict = next(line for line in out.splitlines() if line.startswith("verdict:"))
    assert verdict.endswith("Expected is ( ScalarVariable ).)"), verdict


def test_a_binary_that_cannot_load_is_not_instantiated_too(built_fmus, tmp_path, capsys):
    """No binary for this platform: the problem is named once, not again in fmpy's words."""
    broken = _rewrite(built_fmus["Accelerometer"], tmp_path / "Accelerometer.fmu",
                      drop=("binaries/linux64/",))
    with pytest.raises(SystemExit):
        main(["doctor", str(broken)])
    out = capsys.readouterr().out
    assert "not instantiated in a Python host" in out and "Failed to load" not in out, out
