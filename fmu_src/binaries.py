"""Internal (not a stable API; use driftfmu.build_fmus instead).

Read what a shared library holds, for any platform, without the platform's tools.

The native FMUs carry binaries for six platforms (ELF for Linux, PE32+ for Windows, Mach-O for
macOS); only some of them can be run on the build machine.  The others are checked by reading
them: the architecture, the exported symbols (what a host's ``dlsym``/``GetProcAddress`` finds)
and the libraries they import.  Each reader follows the format's own specification (ELF's
System V ABI, Microsoft's PE/COFF, Apple's ``<mach-o/loader.h>``, ``<mach-o/fat.h>`` and the
export trie of ``dyld``); :func:`inspect` picks the reader from the file's magic number.

:func:`universal` writes a Mach-O universal ("fat") binary from thin slices, as Apple's ``lipo
-create`` does: the FMI 2.0 folder ``darwin64`` then serves both Intel and Apple-silicon Macs.
"""
import struct
from dataclasses import dataclass, field


class BinaryFormatError(ValueError):
    """The bytes are not a shared library this module can read."""


@dataclass
class Library:
    """What one shared library (one architecture slice) holds."""
    format: str                 # "ELF", "PE", "Mach-O"
    arch: str                   # "x86_64" or "aarch64" (or the raw machine number)
    kind: str                   # "shared library" when it is one, else what it is
    exports: set = field(default_factory=set)   # names a host looks up (macOS: no leading _)
    imports: list = field(default_factory=list)  # libraries it needs, in load order
    notes: dict = field(default_factory=dict)    # format specific (glibc versions, signature)


def inspect(data):
    """The :class:`Library` slices of ``data`` (bytes): one, or one per slice of a universal
    Mach-O binary.  Raises :class:`BinaryFormatError` for anything else."""
    if data[:4] == b"\x7fELF":
        return [_elf(data)]
    if data[:2] == b"MZ":
        return [_pe(data)]
    if data[:4] == b"\xcf\xfa\xed\xfe":
        return [_macho(data)]
    if data[:4] == b"\xca\xfe\xba\xbe":
        count, = struct.unpack_from(">I", data, 4)
        slices = []
        for i in range(count):
            _, _, offset, size, _ = struct.unpack_from(">iiIII", data, 8 + 20 * i)
            slices.append(_macho(data[offset:offset + size]))
        return slices
    raise BinaryFormatError("not an ELF, PE or Mach-O library (first bytes %r)" % data[:4])


# -- ELF (System V ABI, 64-bit little-endian) ---------------------------------------------------

_ELF_MACHINES = {62: "x86_64", 183: "aarch64"}


def _cstring(data, offset):
    end = data.index(b"\0", offset)
    return data[offset:end].decode("utf-8", "replace")


def _elf(data):
    if data[4] != 2 or data[5] != 1:
        raise BinaryFormatError("only 64-bit little-endian ELF is read")
    e_type, e_machine = struct.unpack_from("<HH", data, 16)
    e_shoff, = struct.unpack_from("<Q", data, 40)
    e_shentsize, e_shnum = struct.unpack_from("<HH", data, 58)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, e_shoff + i * e_shentsize)
                for i in range(e_shnum)]
    # (name, type, flags, addr, offset, size, link, info, addralign, entsize)
    lib = Library("ELF", _ELF_MACHINES.get(e_machine, str(e_machine)),
                  "shared library" if e_type == 3 else "ELF type %d" % e_type)
    versions = set()
    for sh in sections:
        kind, offset, size, link = sh[1], sh[4], sh[5], sh[6]
        strtab = sections[link][4] if link < len(sections) else 0
        if kind == 11:  # SHT_DYNSYM
            for i in range(size // 24):
                st_name, st_info, st_other, st_shndx = struct.unpack_from(
                    "<IBBH", data, offset + 24 * i)
                bind, visibility = st_info >> 4, st_other & 3
                if st_shndx != 0 and bind in (1, 2) and visibility == 0 and st_name:
                    lib.exports.add(_cstring(data, strtab + st_name))
        elif kind == 6:  # SHT_DYNAMIC
            for i in range(size // 16):
                tag, value = struct.unpack_from("<qQ", data, offset + 16 * i)
                if tag == 1:  # DT_NEEDED
                    lib.imports.append(_cstring(data, strtab + value))
        elif kind == 0x6ffffffe:  # SHT_GNU_verneed: the symbol versions it requires
            at = offset
            while True:
                _, count, _, aux, next_ = struct.unpack_from("<HHIII", data, at)
                a = at + aux
                for _ in range(count):
                    _, _, _, name, next_aux = struct.unpack_from("<IHHII", data, a)
                    versions.add(_cstring(data, strtab + name))
                    if not next_aux:
                        break
                    a += next_aux
                if not next_:
                    break
                at += next_
    lib.notes["symbol_versions"] = sorted(versions)
    return lib


def glibc_version(lib):
    """The newest ``GLIBC_x.y`` an ELF library requires, as a tuple (``(0,)`` for none)."""
    found = [tuple(int(p) for p in v[6:].split(".")) for v in lib.notes.get("symbol_versions", ())
             if v.startswith("GLIBC_") and v[6:].replace(".", "").isdigit()]
    return max(found, default=(0,))


# -- PE/COFF (PE32+) ----------------------------------------------------------------------------

_PE_MACHINES = {0x8664: "x86_64", 0xAA64: "aarch64"}


def _pe(data):
    pe, = struct.unpack_from("<I", data, 0x3C)
    if data[pe:pe + 4] != b"PE\0\0":
        raise BinaryFormatError("no PE signature")
    machine, n_sections, _, _, _, opt_size, characteristics = struct.unpack_from(
        "<HHIIIHH", data, pe + 4)
    opt = pe + 24
    if struct.unpack_from("<H", data, opt)[0] != 0x20B:
        raise BinaryFormatError("only PE32+ (64-bit) is read")
    n_dirs, = struct.unpack_from("<I", data, opt + 108)
    dirs = [struct.unpack_from("<II", data, opt + 112 + 8 * i) for i in range(n_dirs)]
    sections = [struct.unpack_from("<8sIIII", data, opt + opt_size + 40 * i)
                for i in range(n_sections)]

    def at(rva):
        for _, vsize, vaddr, raw_size, raw in sections:
            if vaddr <= rva < vaddr + max(vsize, raw_size):
                return raw + rva - vaddr
        raise BinaryFormatError("RVA 0x%x is in no section" % rva)

    lib = Library("PE", _PE_MACHINES.get(machine, hex(machine)),
                  "shared library" if characteristics & 0x2000 else "PE image (not a DLL)")
    if n_dirs > 0 and dirs[0][0]:
        e = at(dirs[0][0])
        n_names, = struct.unpack_from("<I", data, e + 24)
        names, = struct.unpack_from("<I", data, e + 32)
        for i in range(n_names):
            name_rva, = struct.unpack_from("<I", data, at(names) + 4 * i)
            lib.exports.add(_cstring(data, at(name_rva)))
    for index, size in ((1, 20), (13, 32)):  # imports, delay-load imports
        if n_dirs > index and dirs[index][0]:
            d = at(dirs[index][0])
            name_field = 12 if index == 1 else 4
            while any(data[d:d + size]):
                lib.imports.append(_cstring(data, at(struct.unpack_from(
                    "<I", data, d + name_field)[0])))
                d += size
    return lib


# -- Mach-O (64-bit), its export trie, universal binaries -------------------------------------

_MACHO_CPUS = {0x01000007: "x86_64", 0x0100000C: "aarch64"}
_LOAD_DYLIB = {0xC, 0x80000018, 0x8000001F, 0x80000023}  # load, weak, re-export, upward


def _uleb(data, at):
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def _export_trie(data, start, size):
    """The names in dyld's export trie (what ``dlsym`` finds), leading ``_`` kept."""
    names, stack = set(), [(0, b"")]
    while stack:
        node, prefix = stack.pop()
        at = start + node
        terminal, at = _uleb(data, at)
        if terminal:
            names.add(prefix.decode("utf-8", "replace"))
        at += terminal
        count, at = data[at], at + 1
        for _ in range(count):
            end = data.index(b"\0", at)
            label, (child, at) = data[at:end], _uleb(data, end + 1)
            if child >= size:
                raise BinaryFormatError("export trie node 0x%x is outside the trie" % child)
            stack.append((child, prefix + label))
    return names


def _macho(data):
    if data[:4] != b"\xcf\xfa\xed\xfe":
        raise BinaryFormatError("not a 64-bit little-endian Mach-O slice")
    cpu, _, filetype, ncmds, _, _ = struct.unpack_from("<iiIIII", data, 4)
    lib = Library("Mach-O", _MACHO_CPUS.get(cpu, hex(cpu)),
                  "shared library" if filetype == 6 else "Mach-O file type %d" % filetype)
    at, trie, symtab = 32, None, set()
    lib.notes["code_signature"] = False
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, at)
        if cmd in _LOAD_DYLIB:
            lib.imports.append(_cstring(data, at + struct.unpack_from("<I", data, at + 8)[0]))
        elif cmd == 0xD:  # LC_ID_DYLIB: the name a program linked against it records
            lib.notes["install_name"] = _cstring(
                data, at + struct.unpack_from("<I", data, at + 8)[0])
        elif cmd == 0x1D:  # LC_CODE_SIGNATURE
            lib.notes["code_signature"] = True
        elif cmd == 0x32:  # LC_BUILD_VERSION
            platform, minos = struct.unpack_from("<II", data, at + 8)
            lib.notes["platform"] = platform  # 1 = macOS
            lib.notes["minos"] = (minos >> 16, (minos >> 8) & 0xFF, minos & 0xFF)
        elif cmd == 0x80000033:  # LC_DYLD_EXPORTS_TRIE
            trie = struct.unpack_from("<II", data, at + 8)
        elif cmd in (0x22, 0x80000022):  # LC_DYLD_INFO(_ONLY): export_off, export_size
            off, sz = struct.unpack_from("<II", data, at + 40)
            trie = trie or ((off, sz) if sz else None)
        elif cmd == 0x2:  # LC_SYMTAB
            symoff, nsyms, stroff, _ = struct.unpack_from("<IIII", data, at + 8)
            for i in range(nsyms):
                strx, n_type, _, _ = struct.unpack_from("<IBBH", data, symoff + 16 * i)
                if n_type & 0xE0 == 0 and n_type & 0x01 and n_type & 0x0E == 0x0E:
                    symtab.add(_cstring(data, stroff + strx))
        at += size
    names = _export_trie(data, *trie) if trie else symtab
    # C symbols carry a leading underscore; dlsym("fmi2DoStep") finds "_fmi2DoStep"
    lib.exports = {n[1:] for n in names if n.startswith("_")}
    lib.notes["symtab_exports"] = {n[1:] for n in symtab if n.startswith("_")}
    return lib


def universal(slices):
    """A Mach-O universal binary of the thin 64-bit ``slices`` (bytes each), like ``lipo
    -create``: each slice aligned to 2^14 bytes (the arm64 page size)."""
    align = 14
    header = struct.pack(">II", 0xCAFEBABE, len(slices))
    offset = (8 + 20 * len(slices) + (1 << align) - 1) >> align << align
    table, body = b"", b""
    for i, data in enumerate(slices):
        if data[:4] != b"\xcf\xfa\xed\xfe":
            raise BinaryFormatError("a universal binary is made of thin 64-bit Mach-O slices")
        cpu, subtype = struct.unpack_from("<ii", data, 4)
        table += struct.pack(">iiIII", cpu, subtype & 0x00FFFFFF, offset + len(body), len(data),
                             align)
        body += data
        if i < len(slices) - 1:
            body += b"\0" * (-len(body) % (1 << align))
    return (header + table).ljust(offset, b"\0") + body
