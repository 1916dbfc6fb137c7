"""What simulations/fmucheck.py checks in an FMU or SSP someone else made, on FMUs on paper
(tests/paperfmu.py: the model description driftfmu's builder writes from a model's table and a
real shared library of this machine as the binary), so that the everyday loop's unit tier and
the mutation check see every check without building an FMU: the campaign's edits
(tests/tampering.py), the archive's bounds on both sides, each binary format cut at its
headers, segments and sections, the model description against the tables, SSP parameters and
connections by component and name, and a zip bomb under 200 MB.  tests/test_files.py runs the
same edits through every entry point with real FMUs."""
import math
import os
import struct
import zipfile
from pathlib import Path

import pytest

import paperfmu
import tampering as T
from driftfmu.simulations import fmucheck
from driftfmu.simulations.errors import FileProblem

MODELS = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    folder = tmp_path_factory.mktemp("paper")
    return {(m, v): paperfmu.paper_fmu(folder / ("%s_%d.fmu" % (m, v)), m, v)
            for m in MODELS for v in (2, 3)}


def _one_line(text, path):
    assert "\n" not in text and text.startswith(str(path)), text
    return text


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("model", MODELS)
def test_the_fmus_driftfmu_builds_pass_every_check(paper, model, fmi):
    found = fmucheck.inspect(paper[model, fmi], expected=model)
    assert found.problems == [] and found.md is not None
    assert any("against driftfmu's %s table" % model in c for c in found.checked)
    assert fmucheck.check_fmu(paper[model, fmi]) is not None


def _edits(everything):
    """(edit, model, FMI version): every applicable one, or (the loop) each edit on both FMI
    versions with the models in turn."""
    cases = []
    for e in T.EDITS:
        if e in ("the GUID changed", "the instantiation token changed"):
            continue  # (a well-formed file: its binary refuses it; tests/test_files.py)
        for v in (2, 3):
            models = [m for m in MODELS if T.applies(e, m, v)]
            cases += [(e, m, v) for m in models] if everything else \
                [(e, models[len(cases) % len(models)], v)]
    return cases


def _every_edit(edit, model, fmi, paper, tmp_path):
    make, _, harmless = T.EDITS[edit]
    path = make(paper[model, fmi], tmp_path / ("%s.fmu" % model))
    if harmless:
        assert fmucheck.check_fmu(path, expected=model, validate=False) is not None
        return
    with pytest.raises(FileProblem) as info:
        fmucheck.check_fmu(path, expected=model, validate=False)
    _one_line(str(info.value), path)


@pytest.mark.parametrize("edit, model, fmi", _edits(False))
def test_every_edit_is_one_line_naming_the_file_or_harmless(edit, model, fmi, paper, tmp_path):
    _every_edit(edit, model, fmi, paper, tmp_path)


@pytest.mark.qualification
@pytest.mark.parametrize("edit, model, fmi", _edits(True))
def test_every_edit_of_every_model_is_one_line_naming_the_file_or_harmless(edit, model, fmi,
                                                                          paper, tmp_path):
    _every_edit(edit, model, fmi, paper, tmp_path)


@pytest.mark.parametrize("fmi", [2, 3])
def test_what_each_edit_is_called(paper, tmp_path, fmi):
    said = {}
    for edit in ("swapped value references", "a variable removed", "a variable added",
                 "A = 1.5", "Ts = 0", "estimator = 7", "a start value in range, not the FMU's",
                 "a declared max widened", "a causality changed",
                 "the model identifier changed", "the model name changed",
                 "the binary cut in half", "the binary renamed", "modelDescription.xml twice"):
        path = T.EDITS[edit][0](paper["DriftEstimator", fmi], tmp_path / "DriftEstimator.fmu")
        with pytest.raises(FileProblem) as info:
            fmucheck.check_fmu(path, expected="DriftEstimator")
        said[edit] = str(info.value)[len(str(path)) + 2:]
    folder = "linux64" if fmi == 2 else "x86_64-linux"
    md = "modelDescription.xml: "
    assert said["swapped value references"].startswith(
        md + "x_hat has the value reference 15, which is P's; expected: 14, as in driftfmu's "
        "DriftEstimator: a host reads and writes by value reference")
    assert said["a variable removed"].startswith(
        md + "it has no variable dc_class2; expected: every variable of driftfmu's "
        "DriftEstimator (dc_class2: Real output, value reference 38)")
    assert said["a variable added"].startswith(
        md + "it declares a variable extra (value reference 999) that driftfmu's "
        "DriftEstimator does not have; expected: only the 39 variables")
    assert said["A = 1.5"] == (
        md + "the start value of A is 1.5, outside its declared range; expected: A >= "
        "-0.9999999999999999 and A <= 0.9999999999999999 (driftfmu's rule for A: A > -1 and "
        "A < 1)")
    assert said["Ts = 0"] == (md + "the start value of Ts is 0, outside its declared range; "
                              "expected: Ts >= 1e-09")
    assert said["estimator = 7"] == (md + "the start value of estimator is 7, outside its "
                                     "declared range; expected: estimator >= 1 and "
                                     "estimator <= 3")
    assert said["a start value in range, not the FMU's"].startswith(
        md + "the start value of Ts is 0.002; expected: 0.001, the value the FMU's code starts "
        "Ts at (driftfmu's DriftEstimator)")
    assert said["a declared max widened"].startswith(
        md + "max of A is 5; expected: 0.9999999999999999, as in driftfmu's DriftEstimator")
    assert said["a causality changed"].startswith(
        md + "x_hat has causality local; expected: output")
    assert said["the model identifier changed"].startswith(
        md + "the modelIdentifier is Renamed; expected: DriftEstimator")
    assert said["the model name changed"].startswith(
        md + "the modelName is Renamed; expected: DriftEstimator, the name of the model its "
        "modelIdentifier names (driftfmu's DriftEstimator)")
    assert said["the binary cut in half"].startswith(
        "binaries/%s/DriftEstimator.so: truncated: the file has " % folder)
    assert said["the binary renamed"].startswith(
        "its modelIdentifier 'DriftEstimator' names binaries/%s/DriftEstimator.so, which the "
        "archive does not have; binaries/%s/ holds Renamed.so" % (folder, folder))
    assert said["modelDescription.xml twice"].startswith(
        "modelDescription.xml: the archive holds a member of this name twice")


def test_an_fmu_of_another_model_under_our_name_is_named(paper, tmp_path):
    """Both names changed (no table applies): a file named after one of driftfmu's models is
    refused by its name; under another name it is an FMU like any other."""
    def both(text):
        return text.replace('modelName="DriftEstimator"', 'modelName="Renamed"').replace(
            'modelIdentifier="DriftEstimator"', 'modelIdentifier="Renamed"')
    src = paper["DriftEstimator", 3]
    path = T.rewrite(src, tmp_path / "DriftEstimator.fmu", both, members={
        T.binary(src): lambda d: None}, add={T.binary(src).replace("DriftEstimator.so",
                                                                  "Renamed.so"):
                                             paperfmu.library()})
    with pytest.raises(FileProblem, match="it is an FMU of the model 'Renamed'; expected: "
                       "driftfmu's DriftEstimator \\(the file's name says so\\)"):
        fmucheck.check_fmu(path, expected=fmucheck.expected_model(path))
    from driftfmu.simulations import doctor
    findings = doctor.diagnose(path)
    assert (doctor.FAIL, "it is an FMU of the model 'Renamed', not driftfmu's DriftEstimator "
            "that its file's name says; driftfmu's masters refuse it under this name") \
        in findings, findings
    other = path.rename(tmp_path / "Mine.fmu")
    assert fmucheck.check_fmu(other, expected=fmucheck.expected_model(other)) is not None


def test_a_value_reference_shared_is_named_before_fmpys_bare_key_error(paper, tmp_path):
    """fmpy's parser said "KeyError: '14'" for an FMI 3.0 output given another's value
    reference: the table is checked first and names the variable."""
    path = T.EDITS["one value reference for two outputs"][0](paper["DriftEstimator", 3],
                                                              tmp_path / "DriftEstimator.fmu")
    found = fmucheck.inspect(path)
    assert found.problems[0].startswith("%s: modelDescription.xml: x_hat has the value "
                                        "reference 15, which is P's" % path), found.problems
    assert any("cannot be read (KeyError" in p for p in found.problems), found.problems


def test_a_start_value_on_both_sides_of_a_declared_bound():
    """FMI 2.0's bounds are closed: min itself is in range, the double below it is not (and
    max likewise); an integer start must be a whole number."""
    from driftfmu.models.parameters import next_float

    def desc(start, kind="Real", low="-1.5", high="2.5"):
        return fmucheck.Description(2, "Foreign", "Foreign", "g", [fmucheck.Variable(
            "p", 0, kind, "parameter", "fixed", start, low, high)])
    for start, bad in ((-1.5, False), (next_float(-1.5, -2.0), True), (2.5, False),
                       (next_float(2.5, 3.0), True), (0.0, False)):
        assert bool(fmucheck.range_problems(desc(repr(start)))) == bad, start
    assert fmucheck.range_problems(desc("1.0", "Integer", "1", "3")) != []  # not an integer
    assert fmucheck.range_problems(desc("2", "Integer", "1", "3")) == []
    assert fmucheck.range_problems(desc("4", "Integer", "1", "3"))[0][0] == \
        "the start value of p is 4, outside its declared range"
    assert fmucheck.range_problems(desc("0", "Integer", None, None)) == []
    assert fmucheck.table_problems(desc("0")) == []  # (no table: driftfmu has no Foreign)


# -- the archive, by its declarations ------------------------------------------------------------

def _patch_central(path, name, offset, value, fmt):
    """Overwrite a field of ``name``'s central directory entry (``offset`` from its start)."""
    data = bytearray(path.read_bytes())
    encoded = name.encode()
    at = next(i for i in range(len(data)) if data[i:i + 4] == b"PK\x01\x02"
              and data[i + 46:i + 46 + len(encoded)] == encoded)
    struct.pack_into(fmt, data, at + offset, value)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("field, offset, value, fmt, words", [
    ("encrypted", 8, 1, "<H", "the member is encrypted"),
    ("method 99", 10, 99, "<H", "the member is compressed by method 99, which cannot be "
                                "read")])
def test_members_zipfile_cannot_read_are_named(field, offset, value, fmt, words, paper,
                                               tmp_path):
    path = T.rewrite(paper["Accelerometer", 2], tmp_path / "Accelerometer.fmu")
    _patch_central(path, "documentation/index.html", offset, value, fmt)
    with pytest.raises(FileProblem, match="documentation/index.html: %s" % words):
        fmucheck.check_fmu(path)


@pytest.mark.parametrize("extra, refused", [(0, False), (1, True)])
def test_the_member_bound_on_both_sides(extra, refused, paper, tmp_path, monkeypatch):
    bound = 1 << 20  # (above every member of the paper FMU)
    path = T.rewrite(paper["Accelerometer", 2], tmp_path / "Accelerometer.fmu",
                     add={"resources/data.bin": bytes(bound + extra)})
    monkeypatch.setattr(fmucheck, "MAX_MEMBER", bound)
    monkeypatch.setattr(fmucheck, "MAX_ARCHIVE", 1 << 30)
    with zipfile.ZipFile(path) as z:
        problem = fmucheck.archive_problem(path, z)
    if refused:
        assert problem.startswith("%s: resources/data.bin: the member declares 1.0 MiB "
                                  "(%d bytes) uncompressed" % (path, bound + 1)), problem
        assert problem.endswith("expected: members of at most 1 MiB")
    else:
        assert problem is None


@pytest.mark.parametrize("extra, refused", [(0, False), (1, True)])
def test_the_archive_bound_on_both_sides(extra, refused, paper, tmp_path, monkeypatch):
    path = paper["Accelerometer", 2]
    with zipfile.ZipFile(path) as z:
        total = sum(i.file_size for i in z.infolist())
    monkeypatch.setattr(fmucheck, "MAX_ARCHIVE", total - extra)
    with zipfile.ZipFile(path) as z:
        problem = fmucheck.archive_problem(path, z)
    assert (problem is not None) == refused, problem
    if refused:
        assert problem == "%s: its members declare %s uncompressed in all; expected: an " \
            "archive of at most %s" % (path, fmucheck.size_text(total),
                                       fmucheck.size_text(total - 1)), problem


@pytest.mark.parametrize("extra, refused", [(0, False), (1, True)])
def test_the_read_bound_on_both_sides(extra, refused, paper, tmp_path, monkeypatch):
    path = paper["Accelerometer", 2]
    with zipfile.ZipFile(path) as z:
        size = z.getinfo("modelDescription.xml").file_size
        monkeypatch.setattr(fmucheck, "MAX_READ", size - extra)
        if refused:
            with pytest.raises(FileProblem) as info:
                fmucheck.read_member(path, z, "modelDescription.xml")
            assert str(info.value).endswith(
                "modelDescription.xml: the member declares %s uncompressed; expected: at most "
                "%s" % (fmucheck.size_text(size), fmucheck.size_text(size - 1)))
            assert "(%d bytes)" % size in str(info.value) and "(%d bytes)" % (size - 1) in \
                str(info.value)
        else:
            assert len(fmucheck.read_member(path, z, "modelDescription.xml")) == size


def test_a_member_that_holds_more_than_it_declares_fails_its_crc(paper, tmp_path):
    """zipfile stops at the declared size: a member that would inflate further is cut there
    and its CRC does not match, so it is named, not read on."""
    path = T.rewrite(paper["Accelerometer", 2], tmp_path / "Accelerometer.fmu",
                     add={"resources/big.bin": bytes(100000)})
    _patch_central(path, "resources/big.bin", 24, 1000, "<I")  # declared 1000 bytes
    with zipfile.ZipFile(path) as z:
        assert fmucheck.member_error(z, "resources/big.bin") is not None


def test_a_3_gib_zip_bomb_is_refused_by_the_doctor_within_200_mb(paper, tmp_path, report):
    import peakrss
    bomb = T.zip_bomb(paper["Excitation", 2], tmp_path / "Excitation.fmu")
    rc, out, err, peak = peakrss.run(["doctor", bomb])
    assert rc == 1, out + err
    assert "[PROBLEM] %s: resources/bomb.bin: the member declares 3 GiB uncompressed, " % bomb \
        in out, out
    assert peak < 200 * 2 ** 20, peak
    with pytest.raises(FileProblem, match="the member declares 3 GiB uncompressed"):
        fmucheck.check_fmu(bomb)
    report("doctor on a 3 GiB zip bomb: peak RSS %.0f MB" % (peak / 2 ** 20))


# -- binaries: whole, of the format, for the machine ----------------------------------------------

def _pe(sections=((0x200, 0x200),), machine=0x8664, dll=True):
    """A minimal PE32+ image: DOS header, PE header, optional header (SizeOfHeaders 0x200),
    the section table, the sections' raw data."""
    data = bytearray(0x200 + sum(size for _, size in sections))
    data[0:2] = b"MZ"
    struct.pack_into("<I", data, 0x3C, 0x40)
    data[0x40:0x44] = b"PE\0\0"
    struct.pack_into("<HHIIIHH", data, 0x44, machine, len(sections), 0, 0, 0, 240,
                     0x2022 if dll else 0x0022)
    struct.pack_into("<H", data, 0x58, 0x20B)
    struct.pack_into("<I", data, 0x58 + 60, 0x200)
    for i, (raw, size) in enumerate(sections):
        struct.pack_into("<8sIIII", data, 0x58 + 240 + 40 * i, b".text", size,
                         0x1000 * (i + 1), size, raw)
    return bytes(data)


def _macho(cpu=0x01000007, filetype=6, filesize=0x200):
    cmd = struct.pack("<II16sQQQQiiII", 0x19, 72, b"__TEXT", 0, 0x1000, 0, filesize, 5, 5, 0,
                      0)
    head = struct.pack("<IiiIIIII", 0xFEEDFACF, cpu, 3, filetype, 1, len(cmd), 0, 0)
    return (head + cmd).ljust(filesize, b"\0")


def _fat(*slices):
    header = struct.pack(">II", 0xCAFEBABE, len(slices))
    offset, table, body = 0x1000, b"", b""
    for data in slices:
        cpu = struct.unpack_from("<i", data, 4)[0]
        table += struct.pack(">iiIII", cpu, 3, offset + len(body), len(data), 12)
        body += data
    return (header + table).ljust(offset, b"\0") + body


def _problem(data, system):
    return fmucheck.binary_problem(lambda o, n: data[o:o + n], len(data), system, "x86_64")


@pytest.mark.parametrize("system, whole", [
    ("Linux", paperfmu.library()), ("Windows", _pe()), ("Darwin", _macho()),
    ("Darwin", _fat(_macho(cpu=0x0100000C), _macho()))])
def test_a_whole_library_passes_and_every_cut_is_named(system, whole):
    """Cut by one byte, at every page and at every header: truncated, naming the size; whole:
    nothing."""
    assert _problem(whole, system) is None
    cuts = sorted({len(whole) - 1, len(whole) // 2, 64, 24, 4} | set(range(4096, len(whole),
                                                                         65536)))
    for cut in cuts:
        why = _problem(whole[:cut], system)
        assert why is not None and (why.startswith("truncated: the file has %d bytes" % cut)
                                    or why.startswith("not ")), (cut, why)
    assert _problem(whole[:len(whole) - 1], system).startswith("truncated")


@pytest.mark.parametrize("system, data, words", [
    ("Linux", b"MZ" + bytes(100), "not an ELF shared library (102 bytes, starting b'MZ"),
    ("Linux", b"", "an empty file"),
    ("Windows", _pe(machine=0xAA64), "a PE library for machine 0xaa64; this machine is x86_64"),
    ("Windows", _pe(dll=False), "a PE image that is not a DLL"),
    ("Windows", _pe(sections=((0x200, 0x200), (0x500, 0x200))), "truncated: the file has "
                                                                "1536 bytes, its section 1"),
    ("Darwin", _macho(cpu=0x0100000C), "a Mach-O library for cpu 0x100000c; this machine is "
                                       "x86_64"),
    ("Darwin", _macho(filetype=2), "a Mach-O file of type 2, not a dylib or bundle"),
    ("Darwin", _fat(_macho(cpu=0x0100000C)), "a universal Mach-O library without a slice for "
                                             "x86_64"),
    ("Darwin", _macho()[:0x100] + bytes(0), "truncated: the file has 256 bytes, its segment"),
])
def test_a_library_of_another_format_or_machine_is_named(system, data, words):
    assert _problem(data, system).startswith(words), _problem(data, system)


def _elf_edit(offset, fmt, value):
    data = bytearray(paperfmu.library())
    struct.pack_into(fmt, data, offset, value)
    return bytes(data)


@pytest.mark.parametrize("data, words", [
    (_elf_edit(4, "<B", 1), "a 32-bit little-endian ELF file"),
    (_elf_edit(16, "<H", 2), "an ELF file of type 2, not a shared library"),
    (_elf_edit(18, "<H", 183), "an ELF library for aarch64; this machine is x86_64"),
    (_elf_edit(54, "<H", 40), "an ELF library without a valid program header table"),
    (_elf_edit(58, "<H", 40), "an ELF library with section headers of 40 bytes"),
])
def test_an_elf_file_that_is_not_this_machines_library_is_named(data, words):
    assert _problem(data, "Linux").startswith(words), _problem(data, "Linux")
    assert fmucheck.binary_problem(lambda o, n: data[o:o + n], len(data), "Linux", "any") \
        is None or words[:20] not in ("an ELF library for a",)


def test_a_big_endian_elf_file_is_named_by_its_byte_order():
    """EI_DATA (byte 5) 2: big-endian; the byte after it (EI_VERSION, 1) says nothing of it."""
    data = _elf_edit(5, "<B", 2)
    assert _problem(data, "Linux") == "a 64-bit big-endian ELF file; this host loads 64-bit " \
        "little-endian libraries", _problem(data, "Linux")


def test_a_mach_o_load_command_past_the_declared_size_is_named():
    """One load command 8 bytes longer than sizeofcmds allows (the file holds its bytes)."""
    data = bytearray(_macho())
    struct.pack_into("<I", data, 32 + 4, 80)  # cmdsize of the one LC_SEGMENT_64: 72 -> 80
    assert _problem(bytes(data), "Darwin") == "a Mach-O library whose load commands do not " \
        "fit their declared size", _problem(bytes(data), "Darwin")
    struct.pack_into("<I", data, 20, 80)  # sizeofcmds 80 too: it fits
    assert _problem(bytes(data), "Darwin") is None


def test_a_section_past_the_end_is_named_though_the_segments_fit():
    """The section header table inside the file, but one section's bytes past its end."""
    data = bytearray(paperfmu.library())
    shoff, = struct.unpack_from("<Q", data, 40)
    shnum, = struct.unpack_from("<H", data, 60)
    for i in range(shnum):
        at = shoff + 64 * i
        kind, = struct.unpack_from("<I", data, at + 4)
        if kind not in (0, 8):
            struct.pack_into("<Q", data, at + 32, len(data))  # sh_size: to past the end
            break
    why = _problem(bytes(data), "Linux")
    assert why.startswith("truncated: the file has %d bytes, its section %d" % (len(data), i))


@pytest.mark.parametrize("past", [0, 1])
def test_a_section_that_ends_at_the_files_end_is_whole_and_one_byte_more_is_not(past):
    """Both sides of the bound: a section's bytes may reach the last byte of the file."""
    data = bytearray(paperfmu.library())
    shoff, = struct.unpack_from("<Q", data, 40)
    shnum, = struct.unpack_from("<H", data, 60)
    at = next(shoff + 64 * i for i in range(shnum)
              if struct.unpack_from("<I", data, shoff + 64 * i + 4)[0] not in (0, 8))
    offset, = struct.unpack_from("<Q", data, at + 24)
    struct.pack_into("<Q", data, at + 32, len(data) - offset + past)  # sh_size
    why = _problem(bytes(data), "Linux")
    if past:
        assert why.startswith("truncated: the file has %d bytes, its section %d reaches byte "
                              "%d " % (len(data), (at - shoff) // 64, len(data) + 1)), why
    else:
        assert why is None, why


@pytest.mark.parametrize("phnum", [0, 1])
def test_an_elf_library_needs_one_program_header_at_least(phnum):
    """Both sides of the bound: no program header is no library a loader maps; one is."""
    data = _elf_edit(56, "<H", phnum)  # e_phnum (libm's first one is its first PT_LOAD)
    why = _problem(data, "Linux")
    if phnum:
        assert why is None, why
    else:
        assert why == "an ELF library without a valid program header table (0 entries of 56 " \
            "bytes)", why


def test_a_cut_library_without_section_headers_is_named_by_its_segments():
    """A library stripped of its section headers (``sstrip``; the loader needs only the
    program headers) and cut: the loaded segment that reaches past the end is named."""
    data = bytearray(paperfmu.library())
    struct.pack_into("<Q", data, 40, 0)           # e_shoff
    struct.pack_into("<HHH", data, 58, 64, 0, 0)  # e_shentsize, e_shnum, e_shstrndx
    assert _problem(bytes(data), "Linux") is None
    cut = bytes(data[:len(data) // 2])
    assert _problem(cut, "Linux").startswith("truncated: the file has %d bytes, its loaded "
                                             "segment " % len(cut)), _problem(cut, "Linux")


def test_the_binaries_of_an_unpacked_fmu_are_checked_on_disk(paper, tmp_path):
    folder = tmp_path / "unpacked"
    with zipfile.ZipFile(paper["DriftEstimator", 2]) as z:
        z.extractall(folder)
    desc = T.model_of(paper["DriftEstimator", 2])
    fmucheck.check_binaries("X.fmu", folder, desc)  # whole: nothing
    lib = folder / "binaries" / "linux64" / "DriftEstimator.so"
    (folder / "binaries" / "linux64" / "helper.so").write_bytes(lib.read_bytes()[:5000])
    with pytest.raises(FileProblem, match="X.fmu: binaries/linux64/helper.so: truncated"):
        fmucheck.check_binaries("X.fmu", folder, desc)
    (folder / "binaries" / "linux64" / "helper.so").unlink()
    lib.rename(lib.with_name("Other.so"))
    with pytest.raises(FileProblem, match="names binaries/linux64/DriftEstimator.so, which the "
                       "archive does not have; binaries/linux64/ holds Other.so"):
        fmucheck.check_binaries("X.fmu", folder, desc)


# -- SSPs: parameters by component and name ------------------------------------------------------

@pytest.fixture
def ssp(paper, tmp_path):
    from driftfmu.fmu_src.ssp import build_ssp
    fmus = {m: paper[m, 2] for m in ("Excitation", "Accelerometer", "DriftEstimator")}
    return build_ssp(fmus, tmp_path / "chain.ssp", n=5, start_values={
        "Excitation": {"A": 0.5}, "Accelerometer": {"a2": 0.02, "R": 1e-4},
        "DriftEstimator": {"estimator": 2, "A": 0.5}})


SSD = "SystemStructure.ssd"
#: the parameter sets build_ssp writes, one per component, bound from the system structure
EXC, ACC, DE = ("resources/%s.ssv" % m for m in ("Excitation", "Accelerometer",
                                                 "DriftEstimator"))


def _ssd(ssp, edit, name="edited.ssp", member=SSD):
    """``ssp`` with ``edit`` applied to its ``member`` (the system structure, or a parameter
    set); the edit must change it."""
    def change(data):
        text = data.decode()
        edited = edit(text)
        assert edited != text, "the edit found nothing to change in %s" % member
        return edited.encode()
    return T.rewrite(ssp, ssp.with_name(name), members={member: change})


def test_our_ssp_passes(ssp, tmp_path):
    fmucheck.check_ssp(ssp)
    problems, checked, fmus = fmucheck.inspect_ssp(ssp, tmp_path)
    assert problems == [] and list(fmus) == ["Excitation", "Accelerometer", "DriftEstimator"]
    assert "5 parameters" in checked[0] and "2 connections" in checked[1], checked


R = '<ssv:Parameter name="R"><ssv:Real value="0.0001" /></ssv:Parameter>'


@pytest.mark.parametrize("member, edit, words", [
    (ACC, lambda t: t.replace(R, R.replace("0.0001", "-1"), 1),
     "component Accelerometer: R = -1 is out of range; expected: R > 0"),
    (ACC, lambda t: t.replace(R, R.replace("0.0001", "0"), 1),
     "component Accelerometer: R = 0 is out of range; expected: R > 0"),
    (ACC, lambda t: t.replace(R, R.replace("0.0001", "5e-324"), 1), None),
    (DE, lambda t: t.replace('<ssv:Parameter name="estimator"><ssv:Integer value="2" />',
                         '<ssv:Parameter name="estimator"><ssv:Integer value="4" />', 1),
     "component DriftEstimator: estimator = 4 is outside its declared range; expected: "
     "estimator >= 1 and estimator <= 3"),
    (DE, lambda t: t.replace('<ssv:Parameter name="estimator"><ssv:Integer value="2" />',
                         '<ssv:Parameter name="estimator"><ssv:Integer value="3" />', 1), None),
    (DE, lambda t: t.replace('<ssv:Parameter name="estimator"><ssv:Integer value="2" />',
                         '<ssv:Parameter name="estimator"><ssv:Real value="2.0" />', 1),
     "component DriftEstimator: estimator is given as Real; the FMU declares it Integer"),
    (ACC, lambda t: t.replace('<ssv:Parameter name="a2">', '<ssv:Parameter name="a22">', 1),
     "component Accelerometer has no variable 'a22' to set; expected: one of its parameters: "),
    (DE, lambda t: t.replace('<ssv:Parameter name="estimator">', '<ssv:Parameter name="x_hat">', 1),
     "component DriftEstimator: x_hat is an output variable"),
    (EXC, lambda t: t.replace('<ssv:Parameter name="A"><ssv:Real value="0.5" />',
                         '<ssv:Parameter name="A"><ssv:Real value="nan" />', 1),
     "component Excitation: A = nan is out of range"),
    (EXC, lambda t: t.replace('<ssv:Parameter name="A"><ssv:Real value="0.5" />',
                         '<ssv:Parameter name="A"><ssv:Real value="abc" />', 1),
     "component Excitation: A = 'abc' is not a number"),
    (SSD, lambda t: t.replace('endConnector="z"', 'endConnector="zz"', 1),
     "a connection's end is DriftEstimator.zz, which that FMU does not have"),
    (SSD, lambda t: t.replace('startConnector="z"', 'startConnector="x_hat"', 1),
     "a connection's start is Accelerometer.x_hat, which that FMU does not have"),
    (SSD, lambda t: t.replace('endConnector="x"', 'endConnector="a2"', 1),
     "a connection's end is Accelerometer.a2, a parameter variable"),
    (SSD, lambda t: t.replace('startElement="Excitation"', 'startElement="Nobody"', 1),
     "a connection's start is component 'Nobody', which the system does not have"),
    (SSD, lambda t: t.replace('source="resources/Excitation.fmu"', 'source="resources/E.fmu"', 1),
     "component Excitation has the source 'resources/E.fmu', which the archive does not have"),
    (SSD, lambda t: t[:len(t) // 2], "SystemStructure.ssd: is not well-formed XML"),
])
def test_ssp_parameters_and_connections_by_component_and_name(member, edit, words, ssp):
    """Each edit where the SSP holds what it edits: a parameter in the parameter set its
    component binds (resources/<Component>.ssv), a connection or a component in the system
    structure."""
    edited = _ssd(ssp, edit, member=member)
    if words is None:  # both sides of a bound: the edge value is allowed
        fmucheck.check_ssp(edited)
        return
    with pytest.raises(FileProblem) as info:
        fmucheck.check_ssp(edited)
    named = words if words.startswith(member) else "%s: %s" % (member, words)  # (the member
    assert named in _one_line(str(info.value), edited), str(info.value)  # that holds it)


@pytest.mark.parametrize("value, words", [
    ("0.001", None), ("-1", "component Accelerometer: R = -1 is out of range; expected: R > 0")])
def test_a_parameter_set_inline_in_the_system_structure_is_checked(value, words, ssp):
    """The Accelerometer's parameter set moved from its SSV file into the system structure
    (a ParameterBinding with ParameterValues, as other tools write it): checked the same."""
    import zipfile
    with zipfile.ZipFile(ssp) as z:
        pset = z.read(ACC).decode()
    pset = pset[pset.index("<ssv:ParameterSet"):].replace(R, R.replace("0.0001", value), 1)
    binding = '<ssd:ParameterBinding source="%s" />' % ACC
    inline = '<ssd:ParameterBinding><ssd:ParameterValues>%s</ssd:ParameterValues>' \
        '</ssd:ParameterBinding>' % pset
    edited = T.rewrite(_ssd(ssp, lambda t: t.replace(binding, inline, 1)),
                       ssp.with_name("inline.ssp"), members={ACC: lambda _: None})
    if words is None:
        fmucheck.check_ssp(edited)
        return
    with pytest.raises(FileProblem) as info:
        fmucheck.check_ssp(edited)
    assert "SystemStructure.ssd: " + words in _one_line(str(info.value), edited), \
        str(info.value)


def test_a_parameter_file_the_ssp_binds_is_checked(ssp):
    """A ParameterBinding with ``source`` (an SSV file in the archive): read with the bound
    and checked as the inline ones; a missing one is named."""
    ssv = ('<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameter'
           'Values" version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="R"><ssv:Real '
           'value="%s" /></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    binding = '<ssd:ParameterBinding source="resources/acc.ssv" />'

    def edit(t):
        at = t.index("<ssd:ParameterBindings>", t.index('name="Accelerometer"'))
        return t[:at] + "<ssd:ParameterBindings>" + binding + t[at + len(
            "<ssd:ParameterBindings>"):]
    for value, ok in (("0.001", True), ("-2", False)):
        edited = T.rewrite(_ssd(ssp, edit, "bound.ssp"), ssp.with_name("with_ssv.ssp"),
                           add={"resources/acc.ssv": ssv % value})
        if ok:
            fmucheck.check_ssp(edited)
        else:
            with pytest.raises(FileProblem, match="resources/acc.ssv: component Accelerometer: "
                               "R = -2 is out of range"):
                fmucheck.check_ssp(edited)
    with pytest.raises(FileProblem, match="component Accelerometer binds the parameter file "
                       "resources/acc.ssv, which the archive does not have"):
        fmucheck.check_ssp(_ssd(ssp, edit, "unbound.ssp"))


def test_an_ssp_whose_fmu_is_edited_names_the_member(ssp, paper, tmp_path):
    edited_fmu = T.EDITS["swapped value references"][0](paper["DriftEstimator", 2],
                                                         tmp_path / "DriftEstimator.fmu")
    edited = T.rewrite(ssp, tmp_path / "x.ssp", members={
        "resources/DriftEstimator.fmu": lambda _: edited_fmu.read_bytes()})
    with pytest.raises(FileProblem) as info:
        fmucheck.check_ssp(edited)
    assert str(info.value).startswith("%s: resources/DriftEstimator.fmu: modelDescription.xml: "
                                      "x_hat has the value reference 15" % edited)


def test_an_archive_without_a_system_structure_is_named(paper, tmp_path):
    with pytest.raises(FileProblem, match="it has no SystemStructure.ssd"):
        fmucheck.check_ssp(paper["Excitation", 2])
    with pytest.raises(FileProblem, match="is not a zip archive"):
        bad = tmp_path / "x.ssp"
        bad.write_bytes(b"PK\x03\x04 cut")
        fmucheck.check_ssp(bad)


def test_a_folder_or_a_missing_file_is_refused_saying_what_to_give(tmp_path):
    """An FMU or SSP unzipped to a folder is refused, saying to give the archive itself; a
    path that does not exist, saying which kind of file."""
    folder = tmp_path / "Accelerometer.fmu"
    folder.mkdir()
    missing = tmp_path / "missing.ssp"
    for check, path, line in (
            (fmucheck.check_fmu, folder, "%s: is a folder; expected: the FMU file itself (the "
             "zip archive, not the folder it was unzipped to)"),
            (fmucheck.check_ssp, folder, "%s: is a folder; expected: the SSP file itself (the "
             "zip archive, not the folder it was unzipped to)"),
            (fmucheck.check_fmu, missing, "%s: does not exist; expected: an FMU file"),
            (fmucheck.check_ssp, missing, "%s: does not exist; expected: an SSP file")):
        with pytest.raises(FileProblem) as info:
            check(path)
        assert str(info.value) == line % path


def test_sizes_are_said_in_words():
    assert fmucheck.size_text(3 << 30) == "3 GiB"
    assert fmucheck.size_text(16 * 2 ** 20) == "16 MiB"
    assert fmucheck.size_text(1536) == "1.5 KiB (1536 bytes)"
    assert fmucheck.size_text(1000) == "1000 bytes"
    assert math.isclose(fmucheck.MAX_MEMBER / 2 ** 20, 256)
    assert Path(fmucheck.__file__).name == "fmucheck.py"


# -- the entry points call the checks (without building an FMU) ---------------------------------

def _cut(paper, tmp_path, model="Accelerometer"):
    src = paper[model, 2]
    return T.EDITS["the binary cut in half"][0](src, tmp_path / ("%s.fmu" % model))


def test_the_master_checks_the_unpacked_binary_before_loading_it(paper, tmp_path, monkeypatch):
    """cosim.Instance: the library on disk is checked after it is unpacked and before fmpy
    loads it (were the archive's check passed, a file cut after it is still caught)."""
    from driftfmu.fmu_src import schemas
    from driftfmu.simulations import cosim
    path = _cut(paper, tmp_path)
    monkeypatch.setattr(fmucheck, "check_fmu", lambda p, expected=None, validate=True:
                        schemas.read_model_description(p, validate=False))

    def loaded(*args, **kwargs):
        raise AssertionError("the library was loaded")
    monkeypatch.setattr(cosim, "FMU2Slave", loaded)
    with pytest.raises(FileProblem, match="binaries/linux64/Accelerometer.so: truncated"):
        cosim.Instance("Accelerometer", path)


def test_the_fast_master_checks_the_unpacked_binary_before_loading_it(paper, tmp_path,
                                                                      monkeypatch):
    from driftfmu.simulations import fastcosim
    path = _cut(paper, tmp_path)
    monkeypatch.setattr(fastcosim, "checked_fmu", lambda p, validate: None)
    monkeypatch.setattr(fastcosim, "_UNPACKED", {})
    with pytest.raises(FileProblem, match="binaries/linux64/Accelerometer.so: truncated"):
        fastcosim.unpacked(str(path))


def test_an_fmu_that_cannot_be_instantiated_says_the_fmus_own_reason():
    from driftfmu.simulations.cosim import not_instantiated
    said = str(not_instantiated("X.fmu", Exception("Failed to instantiate model"), [
        "X [warning] something else",
        "X [error] X: fmi2Instantiate: fmuGUID \"{1}\" does not match this FMU"]))
    assert said.startswith("X.fmu: the FMU could not be instantiated on this host: X: "
                           "fmi2Instantiate: fmuGUID \"{1}\" does not match this FMU; expected:")
    said = str(not_instantiated("X.fmu", OSError(8, "Exec format error"), []))
    assert "on this host: Exec format error; expected" in said


def test_an_fmu_that_logged_a_fatal_error_is_named_by_it_not_by_a_later_line():
    # fmi2Fatal is logged as [fatal]; a warning or info line after it is not the reason
    from driftfmu.simulations.cosim import not_instantiated
    said = str(not_instantiated("X.fmu", Exception("Failed to instantiate model"), [
        "X [fatal] X: out of memory",
        "X [warning] X: the instance is not usable"]))
    assert "on this host: X: out of memory; expected" in said
    said = str(not_instantiated("X.fmu", Exception("Failed to instantiate model"), [
        "X [ok] X: loaded",
        "X [warning] X: the instance is not usable"]))
    assert "on this host: Failed to instantiate model; expected" in said


def test_the_apis_variables_are_read_from_a_checked_fmu(paper, tmp_path):
    from driftfmu._api import _variables
    path = T.EDITS["swapped value references"][0](paper["DriftEstimator", 2],
                                                   tmp_path / "DriftEstimator.fmu")
    with pytest.raises(FileProblem, match="x_hat has the value reference 15"):
        _variables(path)
    assert "x_hat" in _variables(paper["DriftEstimator", 2])


def test_an_fmu_is_checked_once_per_process_until_its_file_changes(paper, tmp_path,
                                                                    monkeypatch):
    """check_fmu keeps its answer by the file's identity: a second call reads nothing; a file
    changed (or replaced) in place is checked anew; a missing file is never kept."""
    import shutil
    path = tmp_path / "Accelerometer.fmu"
    shutil.copyfile(paper["Accelerometer", 2], path)
    monkeypatch.setattr(fmucheck, "_CHECKED", {})
    seen = []
    real = fmucheck.inspect
    monkeypatch.setattr(fmucheck, "inspect", lambda *a: seen.append(a) or real(*a))
    md = fmucheck.check_fmu(str(path), "Accelerometer")
    assert fmucheck.check_fmu(str(path), "Accelerometer") is md and len(seen) == 1
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
    assert fmucheck.check_fmu(str(path), "Accelerometer") is not md and len(seen) == 2
    for _ in range(2):
        with pytest.raises(FileProblem):
            fmucheck.check_fmu(str(tmp_path / "missing.fmu"), "Accelerometer")
    assert len(seen) == 4


def test_an_ssp_is_checked_once_per_process_until_its_file_changes(ssp, monkeypatch):
    """check_ssp keeps a passed archive by the file's identity: a second call inspects
    nothing; a file changed in place is checked anew; one with a problem is never kept."""
    monkeypatch.setattr(fmucheck, "_SSP_CHECKED", set())
    seen = []
    real = fmucheck.inspect_ssp
    monkeypatch.setattr(fmucheck, "inspect_ssp",
                        lambda *a, **k: seen.append(a[0]) or real(*a, **k))
    fmucheck.check_ssp(ssp)
    fmucheck.check_ssp(ssp)
    assert seen == [ssp]
    st = ssp.stat()
    os.utime(ssp, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
    fmucheck.check_ssp(ssp)
    fmucheck.check_ssp(ssp)
    assert seen == [ssp, ssp]
    edited = _ssd(ssp, lambda t: t.replace(R, R.replace("0.0001", "-1"), 1), member=ACC)
    for _ in range(2):
        with pytest.raises(FileProblem, match="R = -1 is out of range"):
            fmucheck.check_ssp(edited)
    assert seen == [ssp, ssp, edited, edited]


def test_inputs_refuses_an_edited_fmu(paper, tmp_path, capsys):
    from driftfmu.simulations.cli import main
    path = T.EDITS["a variable removed"][0](paper["Accelerometer", 2],
                                             tmp_path / "Accelerometer.fmu")
    result = tmp_path / "r.csv"
    result.write_text("time,x,y\n0,1,0\n0.001,2,0\n")
    assert main(["inputs", str(path), str(result), "--output-file", str(tmp_path / "o.csv")]) \
        == 2
    err = capsys.readouterr().err
    assert err.startswith("driftfmu: error: %s: modelDescription.xml: it has no variable z_y"
                          % path), err


def test_the_ssp_runner_checks_before_fmpy_runs(ssp):
    from driftfmu.fmu_src import ssp as ssp_module
    edited = _ssd(ssp, lambda t: t.replace(R, R.replace("0.0001", "-1"), 1), member=ACC)
    with pytest.raises(FileProblem, match="component Accelerometer: R = -1 is out of range"):
        ssp_module.simulate(edited, 5)


def test_the_ssp_runner_leaves_nothing_in_the_temporary_folder_when_fmpy_fails(
        ssp, tmp_path, monkeypatch):
    """fmpy's simulate_ssp fails on the FMUs on paper (no functions in their binaries) after
    it extracted the archive and its FMUs: those folders went into TMPDIR for good; now into
    a work folder of driftfmu's that goes with the call."""
    import tempfile
    from driftfmu.fmu_src import ssp as ssp_module
    from driftfmu.simulations.cosim import CoSimulationError
    tmp = tmp_path / "tmp"
    tmp.mkdir(mode=0o700)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    with pytest.raises(CoSimulationError, match="fmpy's simulate_ssp failed"):
        ssp_module.simulate(ssp, 5)
    assert [str(p.relative_to(tmp)) for p in tmp.rglob("*")] == []  # (the private folder
    # goes with its last work folder)


def test_the_doctor_takes_an_ssp_for_an_ssp(ssp, capsys):
    """It said "will NOT run ... no modelDescription.xml" for the SSP driftfmu builds (the FMUs
    on paper do not instantiate, so its verdict here is NOT run, for that reason alone)."""
    from driftfmu.simulations import doctor
    assert doctor.report(ssp) == 1
    out = capsys.readouterr().out
    assert "[  ok  ] an SSP archive with 3 components: Excitation (resources/Excitation.fmu)" \
        in out, out
    assert "no modelDescription.xml" not in out
    assert out.splitlines()[-1].startswith("verdict: this SSP will NOT run on this host as it "
                                           "is: resources/Excitation.fmu: instantiating it"), out


def test_simulates_input_is_held_by_the_rule_of_the_times():
    """simulate's input rows (times.held_rows): a running sum from 1e4 s, whose sums pass their
    points by up to 7e-10 of a step, holds each row from its own point; on both sides of the
    tolerance a row is at the point or after it."""
    import numpy as np
    from driftfmu.simulations import times
    start, step, n = 1e4, 1e-3, 400
    summed, t = [], start
    for _ in range(n):
        summed.append(t)
        t += step
    summed = np.array(summed)
    assert np.any((summed - start) / step > np.arange(n) + 1e-9)  # (the rule of before: late)
    assert np.array_equal(times.held_rows(summed, start, step, n), np.arange(n))
    for k in (1, 17, 399):
        g = start + k * step
        tol = times.tolerance(g, start, step)
        for side, held in ((0.25, k), (4.0, k - 1)):
            rows = summed.copy()
            rows[k] = g + side * tol * step
            assert times.held_rows(rows, start, step, n)[k] == held, (k, side)
    assert np.array_equal(times.held_rows(np.array([0.5]), 0.0, 0.1, 3), [0, 0, 0])
