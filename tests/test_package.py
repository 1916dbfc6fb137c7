"""The distribution: one import namespace, a wheel and an sdist that carry what ``driftfmu build``
needs and nothing a build or a run writes, and an sdist that rebuilds the same wheel.

CI also installs the wheel into a fresh virtual environment and runs the suite against it; there
``DRIFTFMU_EXPECT_INSTALLED=1`` makes :func:`test_suite_runs_against_the_installed_package` check
that the code under test is the installed one, not a checkout's.
"""
import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import zipfile
from pathlib import Path

import pytest

import driftfmu
from driftfmu.fmu_src import builder
from waiting import BOUND

ROOT = Path(__file__).resolve().parent.parent
integration = pytest.mark.integration


def _wheel(source, out):
    """Build a wheel of ``source`` (a folder) into ``out`` with the running pip; its path."""
    result = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                             "--no-build-isolation", "--wheel-dir", str(out), str(source)],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    (wheel,) = Path(out).glob("driftfmu-*.whl")
    return wheel


def _contents(wheel):
    """name -> SHA-256 of every file of a wheel but its RECORD (which lists those hashes)."""
    with zipfile.ZipFile(wheel) as archive:
        return {n: hashlib.sha256(archive.read(n)).hexdigest() for n in archive.namelist()
                if not n.endswith(".dist-info/RECORD")}


@pytest.fixture(scope="module")
def dists(tmp_path_factory):
    """``(wheel from the checkout, sdist, wheel built from the unpacked sdist)``."""
    if not (ROOT / "pyproject.toml").exists():
        pytest.skip("not a source checkout")
    tmp = tmp_path_factory.mktemp("dist")
    # a clean copy of the tracked tree, so files a developer left lying around do not count
    tree = tmp / "tree"
    for name in source_files(ROOT):
        if (ROOT / name).is_file():
            (tree / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, tree / name)
    wheel = _wheel(tree, tmp / "wheel")
    subprocess.run([sys.executable, "-c",
                    "from setuptools import build_meta as b; import sys; "
                    "b.build_sdist(sys.argv[1])", str(tmp / "sdist")],
                   cwd=tree, check=True, capture_output=True, text=True)
    (sdist,) = (tmp / "sdist").glob("driftfmu-*.tar.gz")
    with tarfile.open(sdist) as archive:
        archive.extractall(tmp / "unpacked")
    (unpacked,) = (tmp / "unpacked").iterdir()
    rebuilt = _wheel(unpacked, tmp / "rebuilt")
    return wheel, sdist, rebuilt


#: What a build or a run writes into a source tree (the .gitignore's entries, and the folders
#: the README's commands make): left out of the clean copy when there is no git checkout.
WRITTEN = ("__pycache__", ".pytest_cache", ".venv", "dist", "out", "results", ".git")
WRITTEN_BUILD = ("fmus", "tmp", "cross-check")


def source_files(root):
    """The relative names of a source tree's files: from git when ``root`` is a git checkout
    (tracked and untracked, without the ignored); otherwise (an unpacked sdist, an exported
    tree, as a packager has it) every file but what a build or a run writes."""
    try:
        r = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                            "--exclude-standard"], cwd=root, capture_output=True)
    except OSError:  # no git at all
        r = None
    if r is not None and r.returncode == 0 and (Path(root) / ".git").exists():
        return sorted(filter(None, r.stdout.decode().split("\0")))
    names = []
    for dirpath, dirnames, filenames in os.walk(root):
        rel = Path(dirpath).relative_to(root)
        dirnames[:] = [d for d in dirnames if d not in WRITTEN and not d.endswith(".egg-info")
                       and not (rel == Path("build") and d in WRITTEN_BUILD)]
        names += [(rel / f).as_posix() for f in filenames
                  if not f.endswith((".pyc", ".ssp"))]
    return sorted(names)


def test_the_source_files_are_found_without_git(tmp_path, monkeypatch):
    for name in ("pyproject.toml", "models/a.py", "build/README.md", "results/x/results.csv",
                 "build/fmus/Excitation.fmu", "models/__pycache__/a.cpython-311.pyc",
                 "driftfmu.egg-info/PKG-INFO", "build/DriftChain.ssp", "dist/x.whl"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("x")
    assert source_files(tmp_path) == ["build/README.md", "models/a.py", "pyproject.toml"]
    monkeypatch.setenv("PATH", "")  # and with no git on the PATH
    assert source_files(tmp_path) == ["build/README.md", "models/a.py", "pyproject.toml"]


@integration
@pytest.mark.qualification  # builds the wheel and the sdist
def test_wheel_installs_only_the_driftfmu_namespace(dists):
    wheel, _, _ = dists
    tops = {name.split("/")[0] for name in _contents(wheel)}
    assert tops == {"driftfmu", "driftfmu-%s.dist-info" % driftfmu.__version__}, tops


@integration
@pytest.mark.qualification  # builds the wheel and the sdist
def test_wheel_carries_what_the_builder_bundles(dists):
    wheel, _, _ = dists
    names = set(_contents(wheel))
    for name in builder.NAMES:
        assert "driftfmu/fmu_src/%s.py" % name in names
    for path in builder.source_files(builder.NAMES[0]):
        relative = path.relative_to(builder.SRC_DIR.parent).as_posix()
        assert "driftfmu/" + relative in names, relative
    assert "driftfmu/fmu_src/loader/fmi2_shim.c" in names
    assert "driftfmu/simulations/batch_kernel.c" in names  # compiled by simulations/kernel.py
    assert "driftfmu/__main__.py" in names
    assert not [n for n in names if "__pycache__" in n or n.endswith((".fmu", ".ssp", ".so"))]


@integration
@pytest.mark.qualification  # builds the wheel and the sdist
def test_sdist_has_no_build_outputs_and_rebuilds_the_same_wheel(dists):
    wheel, sdist, rebuilt = dists
    with tarfile.open(sdist) as archive:
        members = [m.name.split("/", 1)[1] for m in archive.getmembers() if "/" in m.name]
    assert not [m for m in members if m.startswith(("build/fmus", "build/cross-check",
                                                    "results/"))]
    assert {"LICENSE", "README.md", "pyproject.toml", "tests/conftest.py"} <= set(members)
    assert _contents(rebuilt) == _contents(wheel)


def test_version_is_written_once():
    text = (ROOT / "pyproject.toml").read_text() if (ROOT / "pyproject.toml").exists() else ""
    if text:
        assert 'dynamic = ["version"]' in text and "driftfmu.__version__" in text
    from importlib.metadata import version
    assert version("driftfmu") == driftfmu.__version__


@integration
def test_built_fmus_carry_the_package_version(built_fmus):
    import fmpy
    for path in built_fmus.values():
        assert fmpy.read_model_description(str(path)).version == driftfmu.__version__


def test_python_dash_m_driftfmu_is_the_command():
    result = subprocess.run([sys.executable, "-m", "driftfmu", "--help"], capture_output=True,
                            text=True, timeout=BOUND)
    assert result.returncode == 0 and result.stdout.startswith("usage: driftfmu"), result.stderr
    result = subprocess.run([sys.executable, "-m", "driftfmu", "no-such-command"],
                            capture_output=True, text=True, timeout=BOUND)
    assert result.returncode == 2


def test_suite_runs_against_the_code_it_means():
    """From a checkout the suite tests the checkout's code; with DRIFTFMU_EXPECT_INSTALLED=1
    (CI's run against the wheel) it tests the installed package, and nothing else of ours is
    installed at the top level of site-packages."""
    files = [Path(m.__file__).resolve() for m in (driftfmu, builder)]
    if os.environ.get("DRIFTFMU_EXPECT_INSTALLED") == "1":
        purelib = Path(sysconfig.get_paths()["purelib"]).resolve()
        for f in files:
            assert purelib in f.parents, f
        assert not [p for p in ("models", "simulations", "fmu_src") if (purelib / p).exists()]
    else:
        for f in files:
            assert ROOT in f.parents, "testing %s, not the checkout at %s" % (f, ROOT)


def test_what_the_readme_commands_make_is_git_ignored():
    if not (ROOT / ".gitignore").exists():
        pytest.skip("not a source checkout")
    ignored = (ROOT / ".gitignore").read_text().split()
    for made in ("/.venv/", "/dist/", "/results/", "/build/fmus/", "*.egg-info/"):
        assert made in ignored, made
