"""``driftfmu doctor``: plain-words diagnosis of whether an FMU runs on this host."""
import zipfile

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
