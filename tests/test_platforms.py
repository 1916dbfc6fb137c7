"""The native FMUs' binaries for every platform (issue 17), checked by reading them: each is a
shared library of the right format and architecture, exports every FMI function under the name
its platform's hosts look up (and nothing else of ours), imports nothing beyond the system's
libraries; the FMU holds exactly the binaries its documentation and build description list.

The binaries that can run here run elsewhere: x86-64 Linux everywhere, x86-64 Windows under wine
and aarch64 Linux under qemu-user (tests/test_native.py).  The readers themselves
(fmu_src/binaries.py) are checked against binutils on the binaries binutils can read.

With ``DRIFTFMU_REQUIRE_PLATFORMS=1`` (set by .ci/run) a missing cross-compiler or tool fails
these tests instead of skipping them.
"""
import io
import os
import re
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from driftfmu.fmu_src import binaries, native_build
from driftfmu.fmu_src.native_build import NAMES, PLATFORMS

pytestmark = pytest.mark.integration
SUFFIX = {"linux": ".so", "windows": ".dll", "darwin": ".dylib"}


def need(ok, why):
    """Skip (or, in CI, fail) when ``ok`` is false."""
    if not ok:
        (pytest.fail if os.environ.get("DRIFTFMU_REQUIRE_PLATFORMS") else pytest.skip)(why)


def built_platforms():
    """The platforms whose compiler is installed here (the build ships those)."""
    return [p for p in PLATFORMS if native_build.compiler(p) is not None]


def fmi_functions(version):
    """Every function the standard's header declares (fmpy's copy of fmi2Functions.h /
    fmi3Functions.h): what an FMU must export."""
    header = native_build.fmi_headers(version)[0].read_text()
    names = set(re.findall(r"FMI%d_Export\s+fmi%d\w+TYPE\s+(fmi%d\w+);" % ((version,) * 3),
                           header))
    assert len(names) == {2: 44, 3: 75}[version]  # the header read as it should be
    return names


@pytest.fixture(scope="module")
def fmu_sets(native_fmus_all):
    """{"fmi2": {name: path}, "fmi2-aarch64": {...}, "fmi3": {...}} (the ARM set when built)."""
    arm_dir = native_fmus_all[2][NAMES[0]].parent.parent / native_build.FMI2_ARM
    sets = {"fmi2": native_fmus_all[2], "fmi3": native_fmus_all[3]}
    if arm_dir.is_dir():
        sets[native_build.FMI2_ARM] = {n: arm_dir / ("%s.fmu" % n) for n in NAMES}
    return sets


def expected_binaries(kind, name):
    """{archive path: [platform of each slice]} the FMU of ``kind`` must hold, and nothing else."""
    have = built_platforms()
    if kind == "fmi3":
        return {"binaries/%s/%s%s" % (p, name, SUFFIX[p.split("-")[1]]): [p] for p in have}
    folders = native_build.FMI2_FOLDERS if kind == "fmi2" else native_build.FMI2_ARM_FOLDERS
    out = {"binaries/%s/%s%s" % (f, name, SUFFIX[p.split("-")[1]]): [p]
           for p, f in folders.items() if p in have}
    darwin = [p for p in native_build.FMI2_DARWIN if p in have]
    if darwin:
        out["binaries/darwin64/%s.dylib" % name] = darwin
    return out


def test_every_platform_has_a_compiler_here():
    need(len(built_platforms()) == len(PLATFORMS),
         "no compiler for %s (pip install \"driftfmu[native]\")"
         % ", ".join(sorted(set(PLATFORMS) - set(built_platforms()))))


@pytest.mark.qualification
def test_the_fmi2_fmus_for_arm_are_built_when_zig_is_there(fmu_sets):
    need("aarch64-linux" in built_platforms(),
         "zig is not installed (pip install \"driftfmu[native]\")")
    assert set(fmu_sets[native_build.FMI2_ARM]) == set(NAMES)
    assert all(p.is_file() for p in fmu_sets[native_build.FMI2_ARM].values())


@pytest.mark.qualification
def test_fmpy_validate_passes_the_fmi2_fmus_for_arm(fmu_sets):
    import sys
    if native_build.FMI2_ARM not in fmu_sets:
        need(False, "the FMI 2.0 FMUs for ARM are not built (no zig)")
    for path in fmu_sets[native_build.FMI2_ARM].values():
        result = subprocess.run([sys.executable, "-m", "fmpy.cli", "validate", str(path)],
                                capture_output=True, text=True)
        assert result.stdout.strip() == "No problems found.", result.stdout + result.stderr


@pytest.mark.parametrize("kind", ["fmi2", native_build.FMI2_ARM, "fmi3"])
@pytest.mark.parametrize("name", NAMES)
@pytest.mark.qualification
def test_fmu_holds_exactly_the_binaries_it_lists(fmu_sets, kind, name):
    if kind not in fmu_sets:
        need(False, "the FMI 2.0 FMUs for ARM are not built (no zig)")
    path = fmu_sets[kind][name]
    expected = expected_binaries(kind, name)
    with zipfile.ZipFile(path) as archive:
        files = archive.namelist()
        listed = archive.read("documentation/binaries.txt").decode()
        build = archive.read("sources/buildDescription.xml") if kind == "fmi3" else None
        data = {p: archive.read(p) for p in expected}
    assert {f for f in files if f.startswith("binaries/")} == set(expected)
    assert "documentation/binaries.txt" in files
    index = archive_text(path, "documentation/index.html")
    assert "binaries: %s." % ", ".join(sorted({p.split("/")[1] for p in expected})) in index
    assert set(re.findall(r"^(binaries/\S+)", listed, re.M)) == set(expected)
    for p, blob in data.items():  # each line names its size
        assert "%s  (%d bytes" % (p, len(blob)) in listed
    missing = [p for p in PLATFORMS if p not in built_platforms()]
    assert ("Not built on this machine" in listed) == bool(missing)
    if build is not None:
        configs = ET.fromstring(build).findall("BuildConfiguration")
        assert configs[0].get("platform") is None      # the one for any compiler comes first
        assert "-ffp-contract=off" in configs[0].find("SourceFileSet").get("compilerOptions")
        assert sorted(c.get("platform") for c in configs[1:]) == sorted(built_platforms())
        for c in configs[1:]:
            assert "-ffp-contract=off" in c.get("description"), c.get("description")


REQUIRED_IMPORTS = {
    "linux": lambda lib: set(lib.imports) <= {"libc.so.6", "libm.so.6"},
    # x86-64: mingw-w64 against msvcrt; aarch64: zig's mingw-w64 against the UCRT, which is part
    # of every Windows 10 and 11 (api-ms-win-crt-*: the UCRT's API sets), Windows on ARM included
    "windows": lambda lib: all(i.lower() in ("kernel32.dll", "msvcrt.dll")
                               or i.lower().startswith("api-ms-win-crt-") for i in lib.imports),
    "darwin": lambda lib: lib.imports == ["/usr/lib/libSystem.B.dylib"],
}
#: Symbols the Mach-O linker defines in every dylib (not ours).
LINKER_SYMBOLS = {"darwin": {"__dso_handle", "_mh_dylib_header"}}


@pytest.mark.parametrize("kind", ["fmi2", native_build.FMI2_ARM, "fmi3"])
@pytest.mark.qualification
def test_every_binary_is_a_library_for_its_platform_exporting_every_fmi_function(fmu_sets,
                                                                                 kind):
    if kind not in fmu_sets:
        need(False, "the FMI 2.0 FMUs for ARM are not built (no zig)")
    version = 3 if kind == "fmi3" else 2
    required = fmi_functions(version)
    fmt = {"linux": "ELF", "windows": "PE", "darwin": "Mach-O"}
    checked = 0
    for name, path in fmu_sets[kind].items():
        with zipfile.ZipFile(path) as archive:
            for member, platforms in expected_binaries(kind, name).items():
                slices = binaries.inspect(archive.read(member))
                assert [s.arch + "-" + p.split("-")[1] for s, p in zip(slices, platforms)] \
                    == platforms, (member, [s.arch for s in slices])
                assert len(slices) == len(platforms)
                for lib, platform in zip(slices, platforms):
                    system = platform.split("-")[1]
                    where = (name, kind, member, platform)
                    assert lib.format == fmt[system] and lib.kind == "shared library", where
                    assert lib.exports - LINKER_SYMBOLS.get(system, set()) == required, where
                    assert REQUIRED_IMPORTS[system](lib), (where, lib.imports)
                    if platform == "aarch64-linux":  # any aarch64 Linux since 2014
                        assert binaries.glibc_version(lib) <= (2, 17), where
                    if system == "darwin":
                        assert lib.notes["minos"] <= ((10, 15, 0) if lib.arch == "x86_64"
                                                      else (11, 0, 0)), where
                        assert lib.notes["install_name"] == "@rpath/%s.dylib" % name, where
                        # Apple silicon loads only signed code (zig's linker signs ad hoc)
                        assert lib.arch != "aarch64" or lib.notes["code_signature"], where
                    checked += 1
    assert checked >= len(NAMES) * (2 if kind == "fmi2" else 1)


@pytest.mark.qualification
def test_binaries_are_reproducible_and_darwin64_is_universal_of_the_thin_builds(native_fmus_all,
                                                                               tmp_path):
    """Compiled again elsewhere, every binary of an FMU comes out byte for byte the same (no
    build path or time inside); the FMI 2.0 ``darwin64`` library is the universal binary of the
    two thin macOS builds, each slice at a 2^14-aligned offset."""
    import struct
    name = "Excitation"
    for version in (2, 3):
        with tempfile_dir(tmp_path) as work:
            sources = work / "sources"
            c_files = native_build.stage_sources(name, version, sources)
            again = {p: native_build.compile_library(
                p, sources, c_files, work / p / (name + PLATFORMS[p][0]))[0].read_bytes()
                for p in built_platforms()}
        with zipfile.ZipFile(native_fmus_all[version][name]) as archive:
            if version == 3:
                for p, data in again.items():
                    assert archive.read("binaries/%s/%s%s" % (p, name, PLATFORMS[p][0])) \
                        == data, p
                continue
            for p, folder in native_build.FMI2_FOLDERS.items():
                member = "binaries/%s/%s%s" % (folder, name, PLATFORMS[p][0])
                assert p not in again or archive.read(member) == again[p], p
            darwin = [p for p in native_build.FMI2_DARWIN if p in again]
            if not darwin:
                continue
            fat = archive.read("binaries/darwin64/%s.dylib" % name)
        assert fat == binaries.universal([again[p] for p in darwin])
        magic, count = struct.unpack_from(">II", fat, 0)
        assert (magic, count) == (0xCAFEBABE, len(darwin))
        for i, p in enumerate(darwin):
            _, _, offset, size, align = struct.unpack_from(">iiIII", fat, 8 + 20 * i)
            assert align == 14 and offset % (1 << 14) == 0
            assert fat[offset:offset + size] == again[p]
    need(all(p in built_platforms() for p in native_build.FMI2_DARWIN), "zig is not installed")


def archive_text(path, member):
    with zipfile.ZipFile(path) as archive:
        return archive.read(member).decode()


class tempfile_dir:
    """A fresh folder under ``tmp_path`` (a context manager, for symmetry with the builder)."""

    def __init__(self, tmp_path):
        self.path = Path(tmp_path) / "work"

    def __enter__(self):
        self.path.mkdir()
        return self.path

    def __exit__(self, *exc):
        shutil.rmtree(self.path)


# -- the readers, checked against binutils where binutils reads the format ------------------------

@pytest.mark.qualification
def test_elf_reader_agrees_with_nm_and_readelf(native_fmus_all, tmp_path):
    need(shutil.which("nm") and shutil.which("readelf"), "binutils is not installed")
    with zipfile.ZipFile(native_fmus_all[3]["DriftEstimator"]) as archive:
        for platform in ("x86_64-linux", "aarch64-linux"):
            member = "binaries/%s/DriftEstimator.so" % platform
            if member not in archive.namelist():
                continue
            so = tmp_path / (platform + ".so")
            so.write_bytes(archive.read(member))
            lib, = binaries.inspect(so.read_bytes())
            nm = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True,
                                text=True, check=True).stdout
            assert lib.exports == {line.split()[-1] for line in nm.splitlines()
                                   if line.split()[1] in "TW"}
            dynamic = subprocess.run(["readelf", "-dW", str(so)], capture_output=True,
                                     text=True, check=True).stdout
            assert lib.imports == re.findall(r"\(NEEDED\).*\[(.+)\]", dynamic)


@pytest.mark.qualification
def test_pe_reader_agrees_with_objdump(native_fmus_all, tmp_path):
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    need(objdump, "x86_64-w64-mingw32-objdump is not installed")
    dll = tmp_path / "DriftEstimator.dll"
    with zipfile.ZipFile(native_fmus_all[2]["DriftEstimator"]) as archive:
        dll.write_bytes(archive.read("binaries/win64/DriftEstimator.dll"))
    lib, = binaries.inspect(dll.read_bytes())
    dump = subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True,
                          check=True).stdout
    table = dump[dump.index("[Ordinal/Name Pointer] Table"):]
    names = set(re.findall(r"^\s*\[\s*\d+\] (fmi2\w+)$", table, re.M))
    assert names and lib.exports == names
    assert [d.lower() for d in lib.imports] == [
        d.lower() for d in re.findall(r"DLL Name: (\S+)", dump)]


def test_readers_refuse_what_is_not_a_library():
    with pytest.raises(binaries.BinaryFormatError, match="not an ELF, PE or Mach-O"):
        binaries.inspect(b"#!/bin/sh\n")
    with pytest.raises(binaries.BinaryFormatError, match="thin 64-bit Mach-O"):
        binaries.universal([b"\x7fELF" + bytes(60)])


# -- the Python FMUs ship only the binary that is tested ------------------------------------------

def test_python_fmus_ship_only_the_linux_binaries(built_fmus):
    for name, path in built_fmus.items():
        with zipfile.ZipFile(path) as archive:
            folders = {n.split("/")[1] for n in archive.namelist()
                       if n.startswith("binaries/") and n.count("/") >= 2}
        assert folders == {"linux64"}, (name, folders)


# -- a machine with only the host's compiler ---------------------------------------------------

@pytest.mark.qualification  # a build of every FMU
def test_without_zig_and_mingw_the_build_ships_what_it_can_and_names_the_rest(monkeypatch,
                                                                            tmp_path):
    monkeypatch.setattr(native_build, "zig_command", lambda: None)
    monkeypatch.setenv("MINGW_CC", "no-such-mingw-gcc")
    lines = []
    built = native_build.build_native_fmus(tmp_path, names=("Excitation",), log=lines.append)
    warning, = [line for line in lines if line.startswith("warning")]
    for p in PLATFORMS:
        assert (p in warning) == (p != "x86_64-linux"), (p, warning)
    assert 'pip install "driftfmu[native]"' in warning and "gcc-mingw-w64-x86-64" in warning
    assert not (tmp_path / native_build.FMI2_ARM).exists()
    for version, folder in ((2, "linux64"), (3, "x86_64-linux")):
        with zipfile.ZipFile(built[version]["Excitation"]) as archive:
            names = archive.namelist()
            listed = archive.read("documentation/binaries.txt").decode()
        assert [n for n in names if n.startswith("binaries/")] == [
            "binaries/%s/Excitation.so" % folder]
        assert "Not built on this machine (no compiler for them): %s." % ", ".join(
            p for p in PLATFORMS if p != "x86_64-linux") in listed
    assert sum(" kB: " in line for line in lines) == 2   # each FMU's size is printed


def test_the_build_cache_reuses_a_library_only_for_the_same_sources_and_compiler(tmp_path,
                                                                                 monkeypatch):
    """``build_native_fmus(cache=...)`` (the test suite's second build, every platform, reuses
    the first's libraries): the same FMU bytes as without the cache; a library in the cache is
    what goes into the FMU (a planted one shows it is not compiled again, whatever the build
    folder); another source byte, compiler command, compiler version or platform is another
    key."""
    cache = tmp_path / "cache"

    def build(folder, **kw):
        fmu = native_build.build_native_fmus(tmp_path / folder, names=("Excitation",),
                                             fmi_versions=(3,), platforms=("x86_64-linux",),
                                             log=lambda line: None, **kw)[3]["Excitation"]
        return fmu.read_bytes()

    plain = build("plain")
    assert build("first", cache=cache) == plain
    entry, = cache.iterdir()
    assert entry.name.startswith("x86_64-linux-")
    assert build("second", cache=cache) == plain
    entry.write_bytes(native_build.cache_entry(b"planted"))
    with zipfile.ZipFile(io.BytesIO(build("third", cache=cache))) as archive:
        assert archive.read("binaries/x86_64-linux/Excitation.so") == b"planted"
    keys = []
    for i, change in enumerate((None, "source", None)):
        sources = tmp_path / ("sources%d" % i)
        c_files = native_build.stage_sources("Excitation", 3, sources)
        if change == "source":
            (sources / c_files[0]).write_bytes((sources / c_files[0]).read_bytes() + b"\n")
        keys.append(native_build._cache_key("x86_64-linux", sources, c_files))
    assert keys[0] == keys[2] != keys[1]   # the folder is not in the key, the bytes are
    monkeypatch.setenv("CC", "gcc -DOTHER")
    assert native_build._cache_key("x86_64-linux", sources, c_files) != keys[2]
    monkeypatch.delenv("CC")
    assert native_build._cache_key("x86_64-windows", sources, c_files) != keys[2]
    # the same command after the compiler was upgraded (the test suite keeps the cache from
    # run to run): another key
    assert native_build.compiler_version(("cc",))  # it answers --version
    monkeypatch.setattr(native_build, "compiler_version", lambda command: "cc 99.0")
    assert native_build._cache_key("x86_64-linux", sources, c_files) != keys[2]


def _build_excitation(folder, **kw):
    """The FMI 3.0 Excitation for x86-64 Linux alone, built into ``folder``."""
    return native_build.build_native_fmus(folder, names=("Excitation",), fmi_versions=(3,),
                                          platforms=("x86_64-linux",), log=lambda line: None,
                                          **kw)[3]["Excitation"]


@pytest.fixture(scope="module")
def cached_excitation(tmp_path_factory):
    """(bytes of a build without a cache, the cache entry a build with a cache wrote): built
    once for the four damages below."""
    tmp = tmp_path_factory.mktemp("damaged_cache")
    plain = _build_excitation(tmp / "plain").read_bytes()
    _build_excitation(tmp / "first", cache=tmp / "cache")
    entry, = (tmp / "cache").iterdir()
    return plain, entry


@pytest.mark.parametrize("damage", ["flipped byte"] + [
    pytest.param(d, marks=pytest.mark.qualification) for d in ("cut short", "old format", "empty")])
def test_a_damaged_cache_entry_is_compiled_again_and_replaced_never_shipped(
        damage, cached_excitation, tmp_path):
    """An entry whose library no longer matches the checksum written with it (a file damaged on
    disk or cut short), or without one: the build compiles the library again, ships the bytes
    of a build without a cache and replaces the entry with a whole one."""
    plain, written = cached_excitation
    cache = tmp_path / "cache"
    cache.mkdir()
    entry = cache / written.name
    whole = written.read_bytes()
    library = native_build._read_cache_entry(written)
    assert library is not None and whole == native_build.cache_entry(library)
    damaged = {"flipped byte": whole[:-100] + bytes([whole[-100] ^ 1]) + whole[-99:],
               "cut short": whole[:len(whole) // 2], "old format": library, "empty": b""}[damage]
    entry.write_bytes(damaged)
    assert native_build._read_cache_entry(entry) is None
    assert _build_excitation(tmp_path / "second", cache=cache).read_bytes() == plain
    assert entry.read_bytes() == whole


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                    reason="only root can give a file to another user")
@pytest.mark.parametrize("damage", ["another user's", "writable by others"])
def test_a_cache_entry_another_user_could_have_written_is_compiled_again_never_shipped(
        damage, cached_excitation, tmp_path):
    """A whole entry with a planted library (its checksum right) that another user owns, or
    that others may write: the build compiles the library again, ships the bytes of a build
    without a cache and replaces the entry with one of this user's (simulations/trust.py)."""
    plain, written = cached_excitation
    cache = tmp_path / "cache"
    cache.mkdir()
    entry = cache / written.name
    entry.write_bytes(native_build.cache_entry(b"planted"))
    if damage == "another user's":
        os.chown(entry, 4242, 4242)
    else:
        entry.chmod(0o666)
    assert _build_excitation(tmp_path / "second", cache=cache).read_bytes() == plain
    assert entry.read_bytes() == written.read_bytes()
    assert (entry.stat().st_uid, entry.stat().st_mode & 0o777) == (os.geteuid(), 0o600)


def test_a_cache_entry_that_cannot_be_replaced_leaves_no_part_of_the_write(
        cached_excitation, tmp_path):
    """The entry's name taken by a folder (not empty: no rename replaces it): the library
    written beside it cannot take its place; the build ships the bytes of a build without a
    cache, and the part it wrote is removed (the cache holds what it held)."""
    plain, written = cached_excitation
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / written.name).mkdir()
    (cache / written.name / "a file").write_text("in the way")
    assert _build_excitation(tmp_path / "second", cache=cache).read_bytes() == plain
    assert sorted(os.listdir(cache)) == [written.name]
    assert os.listdir(cache / written.name) == ["a file"]


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="no /proc/self/fd to count")
def test_reading_cache_entries_leaves_no_descriptor_open(tmp_path):
    """Each entry read (a whole one, a folder, one others may write, a symbolic link, none)
    closes what it opened: a long build reads one entry per library."""
    whole = tmp_path / "whole"
    whole.write_bytes(native_build.cache_entry(b"a library"))
    whole.chmod(0o600)
    (tmp_path / "folder").mkdir()
    shared = tmp_path / "shared"
    shared.write_bytes(whole.read_bytes())
    shared.chmod(0o666)
    (tmp_path / "link").symlink_to(whole)
    want = {"whole": b"a library", "folder": None, "shared": None, "link": None,
            "missing": None}
    before = sorted(os.listdir("/proc/self/fd"))
    for _ in range(3):
        for name, data in want.items():
            assert native_build._read_cache_entry(tmp_path / name) == data, name
    assert sorted(os.listdir("/proc/self/fd")) == before


def test_the_cache_key_does_not_name_where_ziglang_is_installed(tmp_path, monkeypatch):
    """ziglang in another virtual environment (another Python running ``-m ziglang``, clang's
    ``InstalledDir`` elsewhere) is the same compiler: the same key.  Another ziglang version,
    or another clang version, is another key."""
    import importlib.metadata
    sources = tmp_path / "sources"
    c_files = native_build.stage_sources("Excitation", 3, sources)
    versions = {"ziglang": "0.17.1"}
    monkeypatch.setattr(native_build, "zig_command",
                        lambda: [sys.executable, "-m", "ziglang", "cc"])
    monkeypatch.setattr(importlib.metadata, "version", lambda name: versions[name])

    def key(python, installed, clang="22.1.8"):
        monkeypatch.setattr(sys, "executable", python)
        monkeypatch.setattr(native_build, "compiler_version", lambda command: (
            "clang version %s\nTarget: aarch64-unknown-linux-musl\nThread model: posix\n"
            "InstalledDir: %s/site-packages/ziglang\n" % (clang, installed)))
        return native_build._cache_key("aarch64-linux", sources, c_files)

    first = key("/home/me/a/bin/python", "/home/me/a/lib")
    assert key("/home/me/b/bin/python", "/home/me/b/lib") == first
    assert key("/home/me/b/bin/python", "/home/me/b/lib", clang="22.1.9") != first
    versions["ziglang"] = "0.17.2"
    assert key("/home/me/a/bin/python", "/home/me/a/lib") != first


def test_asking_a_compiler_its_version_leaves_nothing_in_the_current_folder(tmp_path,
                                                                            monkeypatch):
    """``zig cc -target <macOS> --version`` writes an empty ``a.o`` into its working folder:
    the cache key's question runs elsewhere, so a build leaves nothing in the user's folder."""
    monkeypatch.chdir(tmp_path)
    for platform in PLATFORMS:
        chosen = native_build.compiler(platform)
        if chosen is not None:
            native_build.compiler_version.cache_clear()
            native_build.compiler_version(tuple(chosen[0]))
    assert os.listdir(tmp_path) == []


@pytest.mark.qualification  # a build of every FMU
def test_a_cache_that_cannot_be_written_does_not_fail_the_build(tmp_path):
    """A library cache that cannot be written (here a path under a file) is skipped: the build
    succeeds with the bytes of a build without a cache, and leaves no part of a write."""
    (tmp_path / "file").write_text("not a folder")
    fmu = native_build.build_native_fmus(tmp_path / "out", names=("Excitation",),
                                         fmi_versions=(3,), platforms=("x86_64-linux",),
                                         log=lambda line: None, cache=tmp_path / "file" / "c")
    plain = native_build.build_native_fmus(tmp_path / "plain", names=("Excitation",),
                                           fmi_versions=(3,), platforms=("x86_64-linux",),
                                           log=lambda line: None)
    assert fmu[3]["Excitation"].read_bytes() == plain[3]["Excitation"].read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "out", "plain"]


def test_prune_cache_removes_entries_unused_for_its_days_and_stale_parts(tmp_path):
    """Only the cache's own files: a folder of the user's set as the cache loses nothing."""
    now = time.time()
    entries = {"fresh": ("a", "", 0), "old": ("b", "", 31 * 86400),
               "recent": ("c", "", 29 * 86400), "stale part": ("d", ".123.part", 7200),
               "young part": ("e", ".456.part", 60)}
    for what, (digit, part, age) in entries.items():
        for name in ("x86_64-linux-%s%s" % (digit * 64, part), "mine %s%s" % (what, part)):
            (tmp_path / name).write_bytes(b"x")
            os.utime(tmp_path / name, (now - age, now - age))
    native_build.prune_cache(tmp_path)
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(["mine %s%s" % (w, e[1]) for w, e in entries.items()] + [
        "x86_64-linux-%s%s" % (entries[w][0] * 64, entries[w][1])
        for w in ("fresh", "recent", "young part")])
    native_build.prune_cache(tmp_path / "missing")  # nothing to prune: no error


def test_the_user_cache_folder(monkeypatch, tmp_path):
    monkeypatch.delenv("DRIFTFMU_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        assert native_build.user_cache() == tmp_path / "xdg" / "driftfmu" / "native-libraries"
    monkeypatch.setenv("DRIFTFMU_CACHE", str(tmp_path / "mine"))
    assert native_build.user_cache() == tmp_path / "mine"


@pytest.mark.parametrize("flag", [[], ["--no-cache"]])
def test_cli_build_native_uses_the_user_cache_unless_told_not_to(flag, monkeypatch, tmp_path):
    import driftfmu
    from driftfmu.simulations.cli import main
    monkeypatch.setenv("DRIFTFMU_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(native_build, "compiler_problem", lambda platform: None)
    calls = []
    monkeypatch.setattr(driftfmu, "build_fmus", lambda out, **kw: calls.append(kw) or {})
    assert main(["build", "--native", "--out", str(tmp_path / "fmus")] + flag) == 0
    python, native = calls
    assert "cache" not in python and native["backend"] == "native"
    assert native["cache"] == (None if flag else tmp_path / "cache")


def test_without_any_compiler_for_x86_64_linux_the_build_says_what_to_install(monkeypatch,
                                                                             tmp_path):
    monkeypatch.setattr(native_build, "zig_command", lambda: None)
    monkeypatch.setenv("CC", "no-such-cc")
    with pytest.raises(native_build.NativeBuildError,
                       match="no x86_64-linux compiler: CC='no-such-cc' is not an installed "
                       "program, zig is not installed; allowed: CC naming an installed C "
                       "compiler, or Debian: apt-get install gcc, or the extra "
                       "driftfmu\\[native\\] \\(pip install \"driftfmu\\[native\\]\": ziglang, "
                       "a C compiler for every platform\\)"):
        native_build.build_native_fmus(tmp_path, names=("Excitation",), log=lambda line: None)
    with pytest.raises(native_build.NativeBuildError, match="platforms mac are not known"):
        native_build.build_native_fmus(tmp_path, platforms=("x86_64-linux", "mac"))


@pytest.mark.qualification
def test_doctor_tells_an_fmi2_fmu_for_another_architecture(fmu_sets, capsys):
    """FMI 2.0's linux64 names no architecture: the doctor reads the binary and says whose it
    is (the FMI 2.0 FMU for ARM on this x86-64 machine: a problem, with the FMU to take)."""
    import platform as host
    from driftfmu.simulations.cli import main
    if host.machine().lower() not in ("x86_64", "amd64"):
        pytest.skip("the check below is written for an x86-64 machine")
    assert main(["doctor", str(fmu_sets["fmi2"]["DriftEstimator"])]) == 0
    assert "binaries/linux64/DriftEstimator.so, x86_64" in capsys.readouterr().out
    if native_build.FMI2_ARM not in fmu_sets:
        need(False, "the FMI 2.0 FMUs for ARM are not built (no zig)")
    with pytest.raises(SystemExit) as info:
        main(["doctor", str(fmu_sets[native_build.FMI2_ARM]["DriftEstimator"])])
    out = capsys.readouterr().out
    assert info.value.code == 1
    assert ("binaries/linux64/DriftEstimator.so is for aarch64, this machine is x86_64 (FMI 2.0 "
            "names no architecture" in out), out
    # not instantiated as well: fmpy's "cannot open shared object file" for a file that is
    # there would only repeat the problem in misleading words
    assert "not instantiated in a Python host: its binary for this platform cannot be loaded" \
        in out and "shared object" not in out, out


def test_native_fmus_built_on_demand_take_the_libraries_driftfmu_build_keeps(tmp_path,
                                                                              monkeypatch):
    """``run --backend native`` / ``simulate(backend="native")`` with no native FMUs built
    them without the cache (26 s where ``driftfmu build --native`` took 6 s)."""
    calls = []
    monkeypatch.setenv("DRIFTFMU_CACHE", str(tmp_path / "kept"))
    monkeypatch.setattr(native_build, "build_native_fmus",
                        lambda folder, **kw: calls.append((folder, kw)))
    native_build.native_fmu_paths(tmp_path / "fmus", 3)
    (folder, kw), = calls
    assert folder == tmp_path / "fmus" / "native" and kw["fmi_versions"] == (3,)
    assert kw["cache"] == tmp_path / "kept" == native_build.user_cache()
