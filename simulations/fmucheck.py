"""Internal (not a stable API; use driftfmu.simulate and the driftfmu command instead).

What driftfmu relies on in an FMU someone else could have made, checked before it relies on it.

An FMU that reaches driftfmu may have passed through other tools and other people: unzipped,
edited and zipped again by a modelling tool, copied over a network that cut it short, made to
do harm.  Every entry point that reads one (the masters of ``driftfmu.simulate``, ``driftfmu
run`` and the experiments, ``driftfmu doctor``, the SSP runner, ``driftfmu inputs``) calls
:func:`check_fmu` first, and the masters call :func:`check_binaries` on the unpacked FMU before
its library is loaded.  A file that fails gets one :class:`FileProblem` line naming the file,
the part and what is expected (the command line's exit status 2):

- **The archive**, by what its central directory declares, before a byte of a member is read:
  a zip archive; no member name twice (tools disagree on which one counts), none encrypted or
  compressed by a method zipfile cannot read, none declaring more than :data:`MAX_MEMBER`
  bytes, all together at most :data:`MAX_ARCHIVE`; the members read whole
  (``modelDescription.xml``, an SSP's ``SystemStructure.ssd``) at most :data:`MAX_READ`.  The
  others are streamed in :data:`CHUNK` pieces (their CRC checked on the way), never read whole,
  so a zip bomb (a few MB that declare gigabytes) is refused by its declaration and costs no
  memory; a member that holds more than it declares fails its CRC.
- **The model description**: well-formed XML of FMI 2.0 or 3.0 with a co-simulation
  interface; every start value inside its declared ``min`` and ``max`` (and a whole number for
  an integer variable); and, for an FMU whose ``modelName`` or modelIdentifier is one of
  driftfmu's models (a class of that name with a ``VARIABLES`` table in ``fmu_src/<Name>.py``),
  every variable as that table has it: its name, value reference (its index in the table),
  type, causality, variability, start value, ``min`` and ``max``, no variable the table lacks
  (but FMI 3.0's independent ``time`` after them), and the model's name as both the modelName
  and the modelIdentifier.  The FMU's
  code runs on its table, so a model description that differs makes a host read and write the
  wrong variables (``x_hat`` and ``P`` with swapped value references give swapped columns) or
  take for the FMU's a start value it does not run with.
- **The binaries** for this platform: ``binaries/<platform>/<modelIdentifier><ext>`` is in the
  archive (when the modelIdentifier names none, the files that folder does hold are named);
  before a library is loaded, every library of that folder is a whole shared library of this
  platform's format (ELF on Linux, PE on Windows, Mach-O on macOS) for this processor, whose
  headers, segments and sections lie inside the file (:func:`binary_problem`): a cut library
  that the loader maps stops the host with SIGBUS when a page past its end is touched, which
  no FMU and no master can catch.

The checks of a file are made once per process (:func:`check_fmu` keeps its answer by the
file's identity: path, device, inode, size and times).
"""
import platform
import re
import struct
import zipfile
import zlib
from collections import namedtuple
from pathlib import Path
from xml.etree import ElementTree

from driftfmu.simulations.errors import FileProblem

MiB = 1 << 20
#: Largest member read whole into memory (modelDescription.xml, SystemStructure.ssd, a build
#: record, a bundled module): an FMU of ten thousands of variables has a model description of a
#: few MB.
MAX_READ = 16 * MiB
#: Largest member that is extracted or streamed (a binary, a resource, an FMU inside an SSP).
MAX_MEMBER = 256 * MiB
#: Largest archive, all its members together as declared.
MAX_ARCHIVE = 1024 * MiB
#: The piece in which a member is streamed.
CHUNK = 1 * MiB
#: Compression methods zipfile reads (stored, deflated, bzip2, LZMA).
METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflated",
           zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "LZMA"}
#: What a rebuilt FMU of driftfmu is, for the lines that tell how to get one.
REBUILD = "the file as driftfmu build writes it (rebuild it: driftfmu build)"


def size_text(n):
    """``n`` bytes in words: ``3 GiB``, ``16 MiB``, ``512 bytes``; a size that is no whole
    number of its unit with its bytes too, ``9.6 KiB (9781 bytes)``, so that two sizes a byte
    apart never read alike."""
    for unit, scale in (("GiB", 1 << 30), ("MiB", MiB), ("KiB", 1 << 10)):
        if n >= scale:
            value = n / scale
            if value == int(value):
                return "%d %s" % (value, unit)
            return "%.1f %s (%d bytes)" % (value, unit, n)
    return "%d bytes" % n


def say(path, part, what, expected):
    """The one line of a problem: ``<file>: <part>: <what>; expected: <expected>``."""
    return "%s: %s%s; expected: %s" % (path, part + ": " if part else "", what, expected)


# -- the archive --------------------------------------------------------------------------------

def archive_problem(path, zf, kind="FMU"):
    """Why the archive ``zf`` (at ``path``) cannot be read within the bounds, from its central
    directory alone, or None."""
    seen, total = set(), 0
    for info in zf.infolist():
        name = info.filename
        if name in seen:
            return say(path, name, "the archive holds a member of this name twice (tools "
                       "disagree on which one counts)", "each member once")
        seen.add(name)
        if info.flag_bits & 0x1:
            return say(path, name, "the member is encrypted", "an unencrypted member")
        if info.compress_type not in METHODS:
            return say(path, name, "the member is compressed by method %d, which cannot be "
                       "read" % info.compress_type, "members stored or compressed by %s"
                       % ", ".join(sorted(METHODS.values())))
        if info.file_size > MAX_MEMBER:
            return say(path, name, "the member declares %s uncompressed, %s in the archive"
                       % (size_text(info.file_size), size_text(info.compress_size)),
                       "members of at most %s" % size_text(MAX_MEMBER))
        total += info.file_size
    if total > MAX_ARCHIVE:
        return say(path, "", "its members declare %s uncompressed in all" % size_text(total),
                   "an archive of at most %s" % size_text(MAX_ARCHIVE))
    return None


def open_archive(path, kind="FMU", label=None):
    """The ``zipfile.ZipFile`` of ``path`` once :func:`archive_problem` found nothing;
    :class:`FileProblem` otherwise (also for a file that is no zip archive), naming the file
    ``label`` (default: ``path``)."""
    p = Path(path)
    path = path if label is None else label
    if p.is_dir():
        raise FileProblem(say(path, "", "is a folder", "the %s file itself (the zip archive, "
                              "not the folder it was unzipped to)" % kind))
    if not p.is_file():
        raise FileProblem(say(path, "", "does not exist", "an %s file" % kind))
    try:
        zf = zipfile.ZipFile(p)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError, OSError) as exc:
        raise FileProblem(say(path, "", "is not a zip archive (damaged or cut short: %s)"
                              % (getattr(exc, "strerror", None) or exc),
                              "an %s as driftfmu build writes it, or one rebuilt" % kind)) \
            from None
    problem = archive_problem(path, zf, "an %s" % kind)
    if problem:
        zf.close()
        raise FileProblem(problem)
    return zf


def stream(zf, name):
    """Yield the bytes of member ``name`` in :data:`CHUNK` pieces (zipfile stops at the
    declared size and checks the CRC at the end)."""
    with zf.open(name) as member:
        while True:
            piece = member.read(CHUNK)
            if not piece:
                return
            yield piece


def member_error(zf, name):
    """The error of reading member ``name`` whole (its data damaged, its CRC wrong), streamed,
    in words; None when it reads."""
    try:
        for _ in stream(zf, name):
            pass
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError,
            RuntimeError, ValueError) as exc:
        return str(getattr(exc, "strerror", None) or exc)
    return None


def member_problem(zf, name):
    """Why member ``name`` cannot be read whole and right, or None (:func:`member_error`)."""
    error = member_error(zf, name)
    return None if error is None else "cannot be read from the archive (%s)" % error


def read_member(path, zf, name, bound=None):
    """The bytes of member ``name``, read whole only when it declares at most ``bound`` bytes
    (default :data:`MAX_READ`); :class:`FileProblem` naming the member otherwise, or when it
    cannot be read."""
    bound = MAX_READ if bound is None else bound
    info = zf.getinfo(name)
    if info.file_size > bound:
        raise FileProblem(say(path, name, "the member declares %s uncompressed"
                              % size_text(info.file_size), "at most %s" % size_text(bound)))
    try:
        return b"".join(stream(zf, name))
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError,
            RuntimeError, ValueError) as exc:
        raise FileProblem(say(path, name, "cannot be read from the archive (%s)" % (
            getattr(exc, "strerror", None) or exc), "an archive copied whole")) from None


# -- the model description ----------------------------------------------------------------------

#: One variable as the model description declares it (texts as written; None where absent).
Variable = namedtuple("Variable", "name vr type causality variability start min max")
#: What driftfmu relies on in a model description.
Description = namedtuple("Description", "fmi model identifier token variables")

_FMI2_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")
_FMI3_TYPES = ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
               "Int64", "UInt64", "Boolean", "String", "Binary", "Enumeration", "Clock")
_INTEGERS = ("Integer", "Enumeration", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
             "Int64", "UInt64")
_REALS = ("Real", "Float32", "Float64")
#: A table's type, as FMI 2.0 and FMI 3.0 name it.
TABLE_TYPES = {2: {"Real": "Real", "Integer": "Integer"},
               3: {"Real": "Float64", "Integer": "Int32"}}


def parse_description(path, data):
    """:class:`Description` of the ``modelDescription.xml`` bytes ``data``; FileProblem naming
    what is missing or malformed."""
    part = "modelDescription.xml"
    try:
        root = ElementTree.fromstring(data)
    except ElementTree.ParseError as exc:
        raise FileProblem(say(path, part, "is not well-formed XML (%s)" % exc,
                              REBUILD)) from None
    if root.tag != "fmiModelDescription":
        raise FileProblem(say(path, part, "its root element is <%s>" % root.tag,
                              "<fmiModelDescription>"))
    version = root.get("fmiVersion") or ""
    fmi = {"2.0": 2}.get(version, 3 if version.startswith("3.") else None)
    if fmi is None:
        raise FileProblem(say(path, part, "fmiVersion is %r" % version, "2.0 or 3.0"))
    cs = root.find("CoSimulation")
    if cs is None:
        raise FileProblem(say(path, part, "it has no <CoSimulation> element",
                              "a co-simulation FMU"))
    identifier = cs.get("modelIdentifier") or ""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", identifier):
        raise FileProblem(say(path, part, "the modelIdentifier %r is not a C name" % identifier,
                              "the name of the FMU's binary, a C identifier"))
    variables = []
    container = root.find("ModelVariables")
    for element in (container if container is not None else ()):
        if fmi == 2:
            if element.tag != "ScalarVariable":
                continue
            typed = next((c for c in element if c.tag in _FMI2_TYPES), None)
            kind = typed.tag if typed is not None else None
            attrs = typed if typed is not None else element
        else:
            if element.tag not in _FMI3_TYPES:
                continue
            kind, attrs = element.tag, element
        name = element.get("name")
        vr = element.get("valueReference")
        if name is None or vr is None or not vr.isdigit() or kind is None:
            raise FileProblem(say(path, part, "a variable (%s) has %s" % (
                name or "without a name", "no type element" if kind is None else
                "the value reference %r" % vr), "a name, an unsigned value reference and a "
                "type for every variable"))
        variables.append(Variable(name, int(vr), kind, element.get("causality", "local"),
                                  element.get("variability"), attrs.get("start"),
                                  attrs.get("min"), attrs.get("max")))
    return Description(fmi, root.get("modelName") or "", identifier,
                       root.get("guid") if fmi == 2 else root.get("instantiationToken"),
                       variables)


def _number(text, kind):
    """The value of ``text`` as a variable of ``kind`` holds it, or None when it is not one."""
    if text is None:
        return None
    try:
        if kind in _INTEGERS:
            return int(text.strip())
        if kind in _REALS:
            return float(text.strip())
    except ValueError:
        return None
    return None


def range_problems(desc):
    """Each start value outside its variable's declared ``min``/``max``, or not a number of
    the variable's type."""
    problems = []
    for v in desc.variables:
        if v.type not in _INTEGERS + _REALS or v.start is None:
            continue
        start = _number(v.start, v.type)
        if start is None:
            problems.append(("the start value of %s is %r" % (v.name, v.start),
                             "%s number" % ("an integer" if v.type in _INTEGERS else "a")))
            continue
        low, high = _number(v.min, v.type), _number(v.max, v.type)
        if (low is not None and start < low) or (high is not None and start > high):
            bounds = " and ".join(b for b in (
                None if low is None else "%s >= %s" % (v.name, v.min),
                None if high is None else "%s <= %s" % (v.name, v.max)) if b)
            problems.append(("the start value of %s is %s, outside its declared range"
                             % (v.name, v.start), bounds + _rule(v.name, ours(desc),
                                                                  bounds)))
    return problems


def _rule(name, model, bounds=""):
    """``" (driftfmu's rule for <name>: ...)"`` for a parameter of driftfmu's ``model`` (None:
    not one of driftfmu's) whose rule says more than its declared ``bounds``, else ``""``."""
    from driftfmu.models import parameters
    if model is None or table(model) is None or name not in parameters.PARAMETERS or \
            parameters.allowed(name) in (bounds, "an integer " + bounds):
        return ""
    return " (driftfmu's rule for %s: %s)" % (name, parameters.allowed(name))


_TABLES = {}


def table(model):
    """The ``VARIABLES`` table of driftfmu's model ``model`` (the slave class of
    ``fmu_src/<model>.py``), or None when driftfmu has no model of that name."""
    if model not in _TABLES:
        found = None
        if re.fullmatch(r"[A-Z][A-Za-z0-9_]*", model or ""):
            from driftfmu import fmu_src
            if (Path(fmu_src.__file__).parent / ("%s.py" % model)).is_file():
                import importlib
                module = importlib.import_module("driftfmu.fmu_src.%s" % model)
                found = getattr(getattr(module, model, None), "VARIABLES", None)
        _TABLES[model] = tuple(found) if found else None
    return _TABLES[model]


def ours(desc):
    """The name of driftfmu's model whose table applies to the model description ``desc``: its
    modelName, else its modelIdentifier (driftfmu's FMUs name both after the model, so an FMU
    whose modelName alone was edited is still checked against its table); None for an FMU of
    no model of driftfmu's."""
    for name in (desc.model, desc.identifier):
        if table(name) is not None:
            return name
    return None


def _declared(spec):
    return "%s %s" % (spec["type"], spec["causality"])


def _a(word):
    return ("an " if word[:1] in "AEIOUaeiou" else "a ") + word


def table_problems(desc):
    """How the model description ``desc`` of an FMU of driftfmu's model differs from that
    model's table (:func:`table`): ``[(what, expected)]`` (empty for other models)."""
    name = ours(desc)
    if name is None:
        return []
    specs = table(name)
    model = "driftfmu's %s" % name
    problems = []
    if desc.model != name:
        problems.append(("the modelName is %s" % desc.model,
                         "%s, the name of the model its modelIdentifier names (%s)"
                         % (name, model)))
    if desc.identifier != name:
        problems.append(("the modelIdentifier is %s" % desc.identifier,
                         "%s, the name of %s and of its binary" % (name, model)))
    types = TABLE_TYPES[desc.fmi]
    by_name = {}
    for v in desc.variables:
        by_name.setdefault(v.name, []).append(v)
    index = {s["name"]: vr for vr, s in enumerate(specs)}
    for vr, spec in enumerate(specs):
        found = by_name.get(spec["name"], [])
        if not found:
            problems.append(("it has no variable %s" % spec["name"],
                             "every variable of %s (%s: %s, value reference %d)"
                             % (model, spec["name"], _declared(spec), vr)))
            continue
        v = found[0]
        if len(found) > 1:
            problems.append(("it declares %s %d times" % (v.name, len(found)),
                             "each variable once"))
        if v.vr != vr:
            other = next((s["name"] for i, s in enumerate(specs) if i == v.vr), None)
            problems.append((
                "%s has the value reference %d%s" % (v.name, v.vr, ", which is %s's" % other
                                                     if other else ""),
                "%d, as in %s: a host reads and writes by value reference, so it would get "
                "another variable's values" % (vr, model)))
        if v.type != types[spec["type"]]:
            problems.append(("%s is %s variable" % (v.name, _a(v.type)),
                             "%s, as in %s" % (types[spec["type"]], model)))
        if v.causality != spec["causality"]:
            problems.append(("%s has causality %s" % (v.name, v.causality),
                             "%s, as in %s" % (spec["causality"], model)))
        if v.variability != spec["variability"]:
            problems.append(("%s has variability %s" % (v.name, v.variability),
                             "%s, as in %s" % (spec["variability"], model)))
        if spec["causality"] != "output" and spec["start"] is not None:
            start = _number(v.start, v.type)
            if start != spec["start"] or start is None:
                problems.append((
                    "the start value of %s is %s" % (v.name, v.start),
                    "%r, the value the FMU's code starts %s at (%s); a host would take the "
                    "model description's for it. Other values of %s are start values of a run"
                    % (spec["start"], v.name, model, v.name)))
        for key in ("min", "max"):
            declared, want = _number(getattr(v, key), v.type), spec.get(key)
            if (declared is None) != (want is None) or (want is not None and declared != want):
                problems.append(("%s of %s is %s" % (key, v.name, getattr(v, key)),
                                 "%s, as in %s" % ("none" if want is None else repr(want),
                                                   model)))
    extra = [v for v in desc.variables if v.name not in index
             and not (desc.fmi == 3 and v.name == "time" and v.causality == "independent"
                      and v.vr == len(specs))]
    for v in extra:
        problems.append(("it declares a variable %s (value reference %d) that %s does not have"
                         % (v.name, v.vr, model), "only the %d variables of %s"
                         % (len(specs), model)))
    return problems


# -- the binaries -------------------------------------------------------------------------------

#: Shared-library file name extension per operating system.
EXTENSIONS = {"Linux": ".so", "Darwin": ".dylib", "Windows": ".dll"}
#: This machine's processor as the binary formats name it.
MACHINE = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64", "aarch64": "aarch64"}.get(
    platform.machine().lower(), platform.machine().lower())


def platform_dir(fmi):
    """The folder of this platform's binaries in an FMU of FMI version ``fmi`` (2 or 3)."""
    system = platform.system()
    if fmi == 3:
        return "%s-%s" % (MACHINE, system.lower())
    return {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(system, "unknown") + \
        ("64" if struct.calcsize("P") == 8 else "32")


def binary_member(desc):
    """``binaries/<platform>/<modelIdentifier><ext>``: the library a host loads here."""
    return "binaries/%s/%s%s" % (platform_dir(desc.fmi), desc.identifier,
                                 EXTENSIONS.get(platform.system(), ".so"))


def binary_presence_problem(path, desc, names):
    """``(what, expected)`` when the archive (member ``names``) has no binary for this platform,
    naming what the platform's folder holds instead; None when it has it."""
    binary = binary_member(desc)
    if binary in names:
        return None
    folder = binary.rsplit("/", 1)[0] + "/"
    held = sorted(n[len(folder):] for n in names if n.startswith(folder) and n != folder)
    if held:
        return ("its modelIdentifier %r names %s, which the archive does not have; %s holds %s"
                % (desc.identifier, binary, folder, ", ".join(held)),
                "the binary the modelIdentifier names (the modelIdentifier or the binary was "
                "renamed)")
    present = sorted({n.split("/")[1] for n in names if n.startswith("binaries/")
                      and n.count("/") >= 2 and n.split("/")[1]})
    return ("it has no binary for this platform (%s); it has: %s" % (
        folder[len("binaries/"):-1], ", ".join(present) or "none"),
        "a binary in %s (or build the FMU here: driftfmu build)" % folder)


_ELF_MACHINES = {"x86_64": 62, "aarch64": 183}
_PE_MACHINES = {"x86_64": 0x8664, "aarch64": 0xAA64}
_MACHO_CPUS = {"x86_64": 0x01000007, "aarch64": 0x0100000C}


class _Cut(Exception):
    """A header that reaches past the end of the file."""


def binary_problem(read, size, system=None, machine=None):
    """Why the shared library of ``size`` bytes, read by ``read(offset, count)``, cannot be
    loaded whole on ``system`` (default: this one) and ``machine`` (default: this processor),
    from its headers alone, in words; None when it is whole and of the right format.

    ELF (Linux): a 64-bit little-endian shared object for the processor, its program header
    table, every loaded segment and the dynamic segment, its section header table and every
    section that has bytes in the file inside the file.  PE (Windows): a PE32+ DLL for the
    processor, its headers and every section's raw data inside the file.  Mach-O (macOS): a
    64-bit dylib or bundle (or a universal binary with a slice) for the processor, its load
    commands and every segment's file range inside the file."""
    system = system or platform.system()
    machine = machine or MACHINE
    if size == 0:
        return "an empty file"

    def unpack(fmt, offset):
        count = struct.calcsize(fmt)
        data = read(offset, count) if 0 <= offset and offset + count <= size else b""
        if len(data) != count:
            raise _Cut(offset + count)
        return struct.unpack(fmt, data)

    try:
        if system == "Windows":
            return _pe_problem(read, size, unpack, machine)
        if system == "Darwin":
            return _macho_problem(read, size, unpack, machine)
        return _elf_problem(read, size, unpack, machine)
    except _Cut as cut:
        return ("truncated: the file has %d bytes, its headers reach byte %d (a loader "
                "that maps it stops the host with SIGBUS)" % (size, cut.args[0]))


def _past(what, end, size):
    return ("truncated: the file has %d bytes, %s reaches byte %d (a loader that maps it "
            "stops the host with SIGBUS)" % (size, what, end))


def _elf_problem(read, size, unpack, machine):
    head = read(0, 16)
    if head[:4] != b"\x7fELF":
        return "not an ELF shared library (%d bytes, starting %r)" % (size, bytes(head[:4]))
    if size < 64:
        return _past("its ELF header", 64, size)
    if head[4] != 2 or head[5] != 1:
        return ("a %s-bit %s-endian ELF file; this host loads 64-bit little-endian libraries"
                % ({1: "32", 2: "64"}.get(head[4], "?"), {1: "little", 2: "big"}.get(head[5],
                                                                                       "?")))
    e_type, e_machine = unpack("<HH", 16)
    phoff, shoff = unpack("<QQ", 32)
    phentsize, phnum, shentsize, shnum = unpack("<HHHH", 54)
    if e_type != 3:
        return "an ELF file of type %d, not a shared library (type 3)" % e_type
    want = _ELF_MACHINES.get(machine)
    if want is not None and e_machine != want:
        name = {v: k for k, v in _ELF_MACHINES.items()}.get(e_machine, "machine %d" % e_machine)
        return "an ELF library for %s; this machine is %s" % (name, machine)
    if phnum == 0 or phentsize != 56:
        return "an ELF library without a valid program header table (%d entries of %d " \
               "bytes)" % (phnum, phentsize)
    if phoff + phnum * phentsize > size:
        return _past("its program header table", phoff + phnum * phentsize, size)
    for i in range(phnum):
        p_type, _, p_offset = unpack("<IIQ", phoff + i * phentsize)
        p_filesz, = unpack("<Q", phoff + i * phentsize + 32)
        if p_type in (1, 2) and p_offset + p_filesz > size:  # PT_LOAD, PT_DYNAMIC
            return _past("its %s segment %d" % ("loaded" if p_type == 1 else "dynamic", i),
                         p_offset + p_filesz, size)
    if shnum:
        if shentsize != 64:
            return "an ELF library with section headers of %d bytes, not 64" % shentsize
        if shoff + shnum * shentsize > size:
            return _past("its section header table", shoff + shnum * shentsize, size)
        for i in range(shnum):
            _, sh_type = unpack("<II", shoff + i * shentsize)
            sh_offset, sh_size = unpack("<QQ", shoff + i * shentsize + 24)
            if sh_type not in (0, 8) and sh_offset + sh_size > size:  # (NULL, NOBITS)
                return _past("its section %d" % i, sh_offset + sh_size, size)
    return None


def _pe_problem(read, size, unpack, machine):
    if read(0, 2) != b"MZ":
        return "not a PE library (%d bytes, starting %r)" % (size, bytes(read(0, 4)))
    pe, = unpack("<I", 0x3C)
    if unpack("4s", pe)[0] != b"PE\0\0":
        return "a file starting MZ without a PE header"
    cpu, n_sections, _, _, _, opt_size, characteristics = unpack("<HHIIIHH", pe + 4)
    opt = pe + 24
    magic, = unpack("<H", opt)
    if magic != 0x20B:
        return "a PE file that is not PE32+ (64-bit)"
    want = _PE_MACHINES.get(machine)
    if want is not None and cpu != want:
        return "a PE library for machine 0x%x; this machine is %s" % (cpu, machine)
    if not characteristics & 0x2000:
        return "a PE image that is not a DLL"
    headers, = unpack("<I", opt + 60)
    if headers > size:
        return _past("its headers", headers, size)
    table = opt + opt_size
    if table + 40 * n_sections > size:
        return _past("its section table", table + 40 * n_sections, size)
    for i in range(n_sections):
        _, _, _, raw_size, raw = unpack("<8sIIII", table + 40 * i)
        if raw_size and raw + raw_size > size:
            return _past("its section %d" % i, raw + raw_size, size)
    return None


def _macho_problem(read, size, unpack, machine, base=0, end=None):
    end = size if end is None else end
    magic = read(base, 4)
    if magic == b"\xca\xfe\xba\xbe" and base == 0:  # universal: each slice, this one's checked
        count, = unpack(">I", 4)
        found = None
        for i in range(count):
            cpu, _, offset, length, _ = unpack(">iiIII", 8 + 20 * i)
            if offset + length > size:
                return _past("its slice %d" % i, offset + length, size)
            if cpu == _MACHO_CPUS.get(machine):
                found = (offset, length)
        if found is None:
            return "a universal Mach-O library without a slice for %s" % machine
        return _macho_problem(read, size, unpack, machine, found[0], found[0] + found[1])
    if magic != b"\xcf\xfa\xed\xfe":
        return "not a 64-bit Mach-O library (%d bytes, starting %r)" % (size, bytes(magic))
    cpu, _, filetype, ncmds, sizeofcmds = unpack("<iiIII", base + 4)
    if filetype not in (6, 8):
        return "a Mach-O file of type %d, not a dylib or bundle" % filetype
    want = _MACHO_CPUS.get(machine)
    if want is not None and cpu != want:
        return "a Mach-O library for cpu 0x%x; this machine is %s" % (cpu, machine)
    if base + 32 + sizeofcmds > end:
        return _past("its load commands", base + 32 + sizeofcmds, size)
    at = base + 32
    for _ in range(ncmds):
        cmd, cmdsize = unpack("<II", at)
        if cmdsize < 8 or at + cmdsize > base + 32 + sizeofcmds:
            return "a Mach-O library whose load commands do not fit their declared size"
        if cmd == 0x19:  # LC_SEGMENT_64
            fileoff, filesize = unpack("<QQ", at + 40)
            if base + fileoff + filesize > end:
                return _past("its segment at file offset %d" % fileoff,
                             base + fileoff + filesize, size)
        at += cmdsize
    return None


def file_binary_problem(path, system=None, machine=None):
    """:func:`binary_problem` of the file at ``path``."""
    import os
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        def read(offset, count):
            f.seek(offset)
            return f.read(count)
        return binary_problem(read, size, system, machine)


def member_binary_problem(zf, name, system=None, machine=None):
    """:func:`binary_problem` of the archive member ``name``, streamed (never read whole)."""
    size = zf.getinfo(name).file_size
    member = zf.open(name)
    try:
        def read(offset, count):  # (a backward seek decompresses again from the start)
            member.seek(offset)
            return member.read(count)
        return binary_problem(read, size, system, machine)
    finally:
        member.close()


def check_binaries(path, unzipdir, desc):
    """FileProblem unless the unpacked FMU in ``unzipdir`` (of ``path``, described by
    ``desc``: a :class:`Description` or fmpy's model description) has its binary for this
    platform and every library of that folder is whole and of the right format: called before
    a library is loaded."""
    if not isinstance(desc, Description):
        desc = Description(int(desc.fmiVersion[0]), desc.modelName,
                           desc.coSimulation.modelIdentifier, desc.guid, [])
    root = Path(unzipdir)
    binary = binary_member(desc)
    folder = root / binary.rsplit("/", 1)[0]
    names = [binary.rsplit("/", 1)[0] + "/" + p.name for p in folder.iterdir()] \
        if folder.is_dir() else []
    missing = binary_presence_problem(path, desc, set(names))
    if missing:
        raise FileProblem(say(path, "", *missing))
    ext = EXTENSIONS.get(platform.system(), ".so")
    for name in sorted(names):
        if name.endswith(ext):
            why = file_binary_problem(root / name)
            if why:
                raise FileProblem(say(path, name, why, "a whole shared library for this "
                                      "platform (%s, %s): %s" % (platform.system(), MACHINE,
                                                                 REBUILD)))


# -- the whole FMU -------------------------------------------------------------------------------

#: What :func:`inspect` found in an FMU.
Inspection = namedtuple("Inspection", "desc md problems checked")

_CHECKED = {}


def _identity(path):
    import os
    stat = os.stat(path)
    return (os.path.abspath(path), stat.st_dev, stat.st_ino, stat.st_mtime_ns, stat.st_ctime_ns,
            stat.st_size)


def inspect(path, expected=None, validate=True, binaries=True, machine="any", label=None):
    """Everything :func:`check_fmu` checks, without raising: an :class:`Inspection` with the
    parsed :class:`Description` and fmpy's model description (None where they could not be
    read), the problems found (each one line, :func:`say`) and a line per check made.
    ``expected``: the name of driftfmu's model the caller takes the file for (its file name);
    ``machine``: the processor the binaries must be for (``"any"``: not checked here, as a
    loader refuses a library of another processor in words); ``label``: how the lines name the
    file (default: its path).  FileProblem only when the file is no archive driftfmu reads at
    all."""
    problems, checked = [], []
    zf = open_archive(path, label=label)
    source, path = path, path if label is None else label
    with zf:
        names = set(zf.namelist())
        checked.append("the archive: %d members, each declaring at most %s and %s in all "
                       "(of at most %s and %s), none twice, encrypted or of an unknown "
                       "method" % (len(names), size_text(max((i.file_size for i in
                                                              zf.infolist()), default=0)),
                                   size_text(sum(i.file_size for i in zf.infolist())),
                                   size_text(MAX_MEMBER), size_text(MAX_ARCHIVE)))
        if "modelDescription.xml" not in names:
            problems.append(say(path, "", "it has no modelDescription.xml", "an FMU (a zip "
                                "archive with modelDescription.xml at its root)"))
            return Inspection(None, None, problems, checked)
        try:
            desc = parse_description(path, read_member(path, zf, "modelDescription.xml"))
        except FileProblem as exc:
            return Inspection(None, None, problems + [str(exc)], checked)
        # driftfmu's own checks first: they name the variable (fmpy's parser says "KeyError:
        # 14" of a value reference that two variables share)
        if expected is not None and desc.model != expected and ours(desc) is None:
            # (an FMU of another of driftfmu's models under this name: the master's check of
            # the variables names what it lacks)
            problems.append(say(path, "modelDescription.xml", "it is an FMU of the model %r"
                                % desc.model, "driftfmu's %s (the file's name says so)"
                                % expected))
        for what, want in range_problems(desc)[:1]:
            problems.append(say(path, "modelDescription.xml", what, want))
        found = table_problems(desc)
        for what, want in found[:1]:
            problems.append(say(path, "modelDescription.xml", what, want + (
                " (%d more difference%s from the table)" % (len(found) - 1, "s" * (
                    len(found) > 2)) if len(found) > 1 else "") + "; " + REBUILD))
        md = None
        try:
            from driftfmu.fmu_src.schemas import prime
            prime()
            import fmpy
            md = fmpy.read_model_description(str(source), validate=validate)
        except Exception as exc:  # fmpy's validation (its problems) or its parser's error
            found = [str(p).strip() for p in getattr(exc, "problems", None) or []]
            text = "; ".join(found) or (str(exc).strip().splitlines() or
                                        [type(exc).__name__])[0]
            problems.append(say(path, "modelDescription.xml", "cannot be read (%s: %s)" % (
                type(exc).__name__, text) if not found else "does not validate (%s)" % text,
                "a model description that follows the FMI standard; if the FMU is one of "
                "driftfmu's, %s" % REBUILD))
        checked.append("modelDescription.xml: FMI %d.0 co-simulation, %d variables%s"
                       % (desc.fmi, len(desc.variables),
                          ", validated against the FMI schema" if validate and md else ""))
        if ours(desc) is not None:
            checked.append("modelDescription.xml against driftfmu's %s table: every "
                           "variable's name, value reference, type, causality, variability, "
                           "start value, min and max, the modelName and modelIdentifier"
                           % ours(desc))
        checked.append("every start value within its declared min and max")
        if binaries:
            missing = binary_presence_problem(path, desc, names)
            if missing:
                problems.append(say(path, "", *missing))
            else:
                folder = binary_member(desc).rsplit("/", 1)[0] + "/"
                ext = EXTENSIONS.get(platform.system(), ".so")
                libraries = sorted(n for n in names if n.startswith(folder) and n.endswith(ext))
                for name in libraries:
                    why = member_problem(zf, name) or member_binary_problem(
                        zf, name, machine=machine)
                    if why:
                        problems.append(say(path, name, why, "a whole shared library for "
                                            "this platform (%s, %s): %s"
                                            % (platform.system(), MACHINE, REBUILD)))
                checked.append("%s: %s, each a whole shared library for %s %s (headers, "
                               "segments and sections inside the file)"
                               % (folder[:-1], ", ".join(n[len(folder):] for n in libraries),
                                  platform.system(), MACHINE))
    return Inspection(desc, md, problems, checked)


def expected_model(path):
    """The model of driftfmu that the file at ``path`` is named for (``Excitation.fmu``:
    ``"Excitation"``), or None."""
    stem = Path(path).stem
    return stem if table(stem) is not None else None


def check_fmu(path, expected=None, validate=True):
    """fmpy's model description of the FMU at ``path`` once every check of the module holds
    (:func:`inspect`); :class:`FileProblem` with the first problem otherwise.  Kept per
    process by the file's identity, so a run that loads an FMU many times checks it once."""
    key = (_identity(path) if Path(path).is_file() else None, expected, validate)
    if key[0] is not None and key in _CHECKED:
        return _CHECKED[key]
    found = inspect(path, expected, validate)
    if found.problems:
        raise FileProblem(found.problems[0])
    _CHECKED[key] = found.md
    return found.md


# -- SSP archives -------------------------------------------------------------------------------

def _local(tag):
    """An element's tag without its namespace."""
    return tag.rsplit("}", 1)[-1]


def _children(element, name):
    return [c for c in (element if element is not None else ()) if _local(c.tag) == name]


def _child(element, name):
    found = _children(element, name)
    return found[0] if found else None


#: SSV types and the FMI types a parameter of that type may set.
SSV_TYPES = {"Real": _REALS, "Integer": ("Integer", "Int8", "UInt8", "Int16", "UInt16",
                                         "Int32", "UInt32", "Int64", "UInt64"),
             "Boolean": ("Boolean",), "String": ("String",), "Enumeration": ("Enumeration",)}


def _parameters(path, zf, component, binding):
    """``(part, [(name, SSV type, value text)])`` of a ParameterBinding: inline (``part`` the
    system structure) or from the archive's SSV file its ``source`` names (``part`` that
    file), so that a problem names the member that holds the value."""
    source = binding.get("source")
    if source:
        if source not in zf.namelist():
            raise FileProblem(say(path, "SystemStructure.ssd", "component %s binds the "
                                  "parameter file %s, which the archive does not have"
                                  % (component, source), "the parameter files it binds"))
        try:
            pset = ElementTree.fromstring(read_member(path, zf, source))
        except ElementTree.ParseError as exc:
            raise FileProblem(say(path, source, "is not well-formed XML (%s)" % exc,
                                  "an SSV parameter set")) from None
        sets, part = [pset], source
    else:
        sets = [s for values in _children(binding, "ParameterValues")
                for s in _children(values, "ParameterSet")]
        part = "SystemStructure.ssd"
    found = []
    for pset in sets:
        for p in [p for ps in _children(pset, "Parameters") for p in _children(ps, "Parameter")]:
            typed = next((c for c in p if _local(c.tag) in SSV_TYPES), None)
            found.append((p.get("name") or "", _local(typed.tag) if typed is not None else None,
                          typed.get("value") if typed is not None else None))
    return part, found


def parameter_problem(model, variable, kind, value):
    """Why ``value`` (text, of SSV type ``kind``) cannot be the start value of ``variable`` (a
    :class:`Variable` of driftfmu's ``model`` or another FMU), as ``(what, expected)``; None
    when it can."""
    from driftfmu.models import parameters
    name = variable.name
    if variable.causality not in ("parameter", "input"):
        return ("%s is %s %s variable, which a parameter set cannot set" % (
            name, "an" if variable.causality[0] in "aeiou" else "a", variable.causality),
            "parameters and inputs")
    if kind not in SSV_TYPES or variable.type not in SSV_TYPES[kind]:
        return ("%s is given as %s; the FMU declares it %s" % (name, kind, variable.type),
                "the FMU's type")
    number = _number(value, variable.type)
    if variable.type in _INTEGERS + _REALS and number is None:
        return ("%s = %r is not %s" % (name, value, "an integer" if variable.type in _INTEGERS
                                      else "a number"), "a number of the FMU's type")
    if model is not None and table(model) is not None and name in parameters.PARAMETERS:
        problem = parameters.problem(name, number)
        if problem:
            return ("%s = %s is out of range" % (name, value), parameters.allowed(name))
    low, high = _number(variable.min, variable.type), _number(variable.max, variable.type)
    if number is not None and ((low is not None and number < low)
                               or (high is not None and number > high)):
        return ("%s = %s is outside its declared range" % (name, value), " and ".join(
            b for b in (None if low is None else "%s >= %s" % (name, variable.min),
                        None if high is None else "%s <= %s" % (name, variable.max)) if b))
    return None


def inspect_ssp(path, folder, machine="any", label=None):
    """What :func:`check_ssp` checks, without raising: ``(problems, checked, fmus)`` with
    ``fmus`` component -> (source member, the FMU extracted into ``folder``).  The system
    structure (at most :data:`MAX_READ`), each component's FMU (every check of
    :func:`inspect`), each parameter of each component's parameter bindings by component and
    name (a variable of that FMU that a parameter set may set, of its type, inside its declared
    range and, for driftfmu's models, its rule), each connection's two ends."""
    problems, checked, fmus = [], [], {}
    zf = open_archive(path, "SSP", label=label)
    path = path if label is None else label
    part = "SystemStructure.ssd"
    with zf:
        names = set(zf.namelist())
        if part not in names:
            problems.append(say(path, "", "it has no SystemStructure.ssd", "an SSP archive "
                                "(a zip archive with SystemStructure.ssd at its root)"))
            return problems, checked, fmus
        try:
            root = ElementTree.fromstring(read_member(path, zf, part))
        except ElementTree.ParseError as exc:
            problems.append(say(path, part, "is not well-formed XML (%s)" % exc,
                                "an SSP system structure"))
            return problems, checked, fmus
        system = _child(root, "System")
        if _local(root.tag) != "SystemStructureDescription" or system is None:
            problems.append(say(path, part, "it has no <System>", "an SSP system structure"))
            return problems, checked, fmus
        variables, models, count = {}, {}, 0
        for comp in _children(_child(system, "Elements"), "Component"):
            name, source = comp.get("name") or "", comp.get("source") or ""
            if source not in names:
                problems.append(say(path, part, "component %s has the source %r, which the "
                                    "archive does not have" % (name, source),
                                    "an FMU in the archive for each component"))
                continue
            fmu = Path(folder) / ("%d.fmu" % len(fmus))
            try:
                with open(fmu, "wb") as out:
                    for piece in stream(zf, source):
                        out.write(piece)
            except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError,
                    RuntimeError, ValueError) as exc:
                problems.append(say(path, source, "cannot be read from the archive (%s)" % exc,
                                    "an archive copied whole"))
                continue
            fmus[name] = (source, str(fmu))
            try:
                found = inspect(fmu, expected=expected_model(source), machine=machine,
                                label="%s: %s" % (path, source))
            except FileProblem as exc:
                problems.append(str(exc))
                continue
            problems += found.problems
            if found.desc is None:
                continue
            variables[name] = {v.name: v for v in found.desc.variables}
            models[name] = ours(found.desc)
            for binding in _children(_child(comp, "ParameterBindings"), "ParameterBinding"):
                try:
                    where, given = _parameters(path, zf, name, binding)
                except FileProblem as exc:
                    problems.append(str(exc))
                    continue
                for pname, kind, value in given:
                    count += 1
                    variable = variables[name].get(pname)
                    if variable is None:
                        settable = sorted(v for v, var in variables[name].items()
                                          if var.causality == "parameter")
                        problems.append(say(path, where, "component %s has no variable %r to "
                                            "set" % (name, pname), "one of its parameters: %s"
                                            % ", ".join(settable)))
                        continue
                    why = parameter_problem(ours(found.desc), variable, kind, value)
                    if why:
                        problems.append(say(path, where, "component %s: %s" % (name, why[0]),
                                            why[1]))
        checked.append("%s: system %r, %d components (%s), each FMU checked as driftfmu "
                       "checks an FMU; %d parameters, each a variable of its component of its "
                       "type and range" % (part, system.get("name"), len(fmus),
                                           ", ".join(fmus), count))
        connections = _children(_child(system, "Connections"), "Connection")
        for c in connections:
            for end, element, connector, kinds in (
                    ("start", c.get("startElement"), c.get("startConnector"), ("output",)),
                    ("end", c.get("endElement"), c.get("endConnector"), ("input",))):
                if element not in variables:
                    if element not in fmus:
                        problems.append(say(path, part, "a connection's %s is component %r, "
                                            "which the system does not have" % (end, element),
                                            "components of the system: %s"
                                            % ", ".join(fmus)))
                    continue
                v = variables[element].get(connector)
                if v is None or v.causality not in kinds:
                    problems.append(say(path, part, "a connection's %s is %s.%s, %s" % (
                        end, element, connector, "which that FMU does not have" if v is None
                        else "a %s variable" % v.causality), "%s variables of the component"
                        % " or ".join(kinds)))
        checked.append("%s: %d connections, each from an output to an input of the "
                       "components" % (part, len(connections)))
    return problems, checked, fmus


_SSP_CHECKED = set()


def check_ssp(path):
    """FileProblem with the first problem :func:`inspect_ssp` finds in the SSP at ``path``
    (its FMUs' binaries checked for this processor too); kept per process by the file's
    identity."""
    from driftfmu.simulations import folders
    key = _identity(path) if Path(path).is_file() else None
    if key is not None and key in _SSP_CHECKED:
        return
    with folders.temporary("driftfmu_ssp_") as folder:
        problems, _, _ = inspect_ssp(path, folder, machine=MACHINE)
    if problems:
        raise FileProblem(problems[0])
    if key is not None:
        _SSP_CHECKED.add(key)
