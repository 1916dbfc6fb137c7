"""Internal (not a stable API; use the command driftfmu doctor instead).

``driftfmu doctor FMU``: will this FMU run on this host, and if not, why.

It reads the FMU (model description, the build record the driftfmu builder leaves in
``resources/driftfmu_build.json``, the binary for this platform, the bundled Python code) and
checks, in plain words: is there a binary for this platform; which libpython it needs and which
ones this host's loader can find; which Python version the bundled code was built with; which
modules that code imports, and whether each is in the standard library or bundled.  Finally it
loads and instantiates the FMU in a separate process, so a crash cannot take this one down.
"""
import ast
import json
import platform
import struct
import subprocess
import sys
import sysconfig
import zipfile
import zlib
from pathlib import Path

from driftfmu.simulations import lifetime

OK, WARN, FAIL = "ok", "warning", "problem"
#: The line of an FMU whose binary for this platform cannot load here (named by a problem
#: above): instantiating it would only repeat that, in the loader's words.
NOT_TRIED = (WARN, "not instantiated in a Python host: its binary for this platform cannot "
                   "be loaded here (see above)")


def _platform_dir(fmi_version="2.0"):
    if fmi_version.startswith("3"):  # FMI 3.0 platform tuples: x86_64-linux, aarch64-darwin
        machine = {"amd64": "x86_64", "arm64": "aarch64"}.get(platform.machine().lower(),
                                                              platform.machine().lower())
        return "%s-%s" % (machine, platform.system().lower())
    bits = "64" if sys.maxsize > 2 ** 32 else "32"
    return {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(
        platform.system(), "unknown") + bits


def _architecture(data, binary, fmi_version):
    """(status, line) on whether ``binary`` is built for this machine's processor: FMI 2.0's
    folders name no architecture (linux64 serves x86-64 and aarch64 alike, docs/platforms.md)."""
    from driftfmu.fmu_src import binaries
    machine = {"amd64": "x86_64", "arm64": "aarch64"}.get(platform.machine().lower(),
                                                          platform.machine().lower())
    try:
        archs = [lib.arch for lib in binaries.inspect(data)]
    except (binaries.BinaryFormatError, struct.error, ValueError, IndexError) as exc:
        return WARN, "it has %s, which could not be read (%s)" % (binary, exc)
    if machine in archs:
        return OK, "it has a binary for this platform (%s, %s)" % (binary, "/".join(archs))
    hint = (" (FMI 2.0 names no architecture: take the FMI 2.0 FMU built for %s; driftfmu's "
            "native FMUs: fmi2/ for x86-64, fmi2-aarch64/ for ARM)" % machine
            if fmi_version.startswith("2") else "")
    return FAIL, "%s is for %s, this machine is %s%s" % (binary, "/".join(archs), machine, hint)


def _stdlib_names():
    names = set(getattr(sys, "stdlib_module_names", ()))
    return names or set(sys.builtin_module_names)


def _imports(source):
    """Top-level modules imported by ``source``: ``(at import time, only inside functions)``."""
    eager, lazy = set(), set()

    def visit(node, inside_function):
        for child in ast.iter_child_nodes(node):
            names = ()
            if isinstance(child, ast.Import):
                names = [a.name.split(".")[0] for a in child.names]
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                names = [child.module.split(".")[0]]
            (lazy if inside_function else eager).update(names)
            visit(child, inside_function or isinstance(
                child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))
    visit(ast.parse(source), False)
    return eager, lazy - eager


def _loadable(soname):
    """True when the dynamic loader of this host finds and loads ``soname``."""
    code = "import ctypes,sys; ctypes.CDLL(sys.argv[1])"
    return lifetime.run([sys.executable, "-c", code, soname], capture_output=True,
                          timeout=30).returncode == 0


def _libpython_candidates(record):
    first = [record["libpython"]] if record.get("libpython") else []
    others = ["libpython3.%d.so.1.0" % m for m in range(14, 7, -1)] + ["libpython3.so"]
    return first + [s for s in others if s not in first]


def diagnose(fmu):
    """List of ``(level, message)`` about running ``fmu`` on this host."""
    fmu = Path(fmu)
    out = []
    if fmu.is_dir():
        return [(FAIL, "%s is a folder, not an FMU; allowed: the path of a .fmu file (the zip "
                       "archive, not the folder it was unzipped to)" % fmu)]
    if not fmu.is_file():
        return [(FAIL, "%s does not exist or is not a file" % fmu)]
    try:
        zf = zipfile.ZipFile(fmu)
    except zipfile.BadZipFile:
        return [(FAIL, "%s is not an FMU: not a zip archive" % fmu)]
    bad = None
    for info in zf.infolist():  # every entry read, its CRC checked: named here, not a crash
        try:
            zf.read(info)
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError) as exc:
            bad = "%s (%s)" % (info.filename, exc)
            break
    if bad is not None:
        return [(FAIL, "%s is damaged: %s cannot be read from the zip archive; rebuild it "
                       "(driftfmu build) or copy it again" % (fmu, bad))]
    names = set(zf.namelist())
    if "modelDescription.xml" not in names:
        return [(FAIL, "%s has no modelDescription.xml" % fmu)]
    from driftfmu.fmu_src.schemas import read_model_description
    try:
        md = read_model_description(str(fmu))
    except Exception as exc:  # an XML parser's or fmpy's validation message
        # (fmpy's ValidationError says only "Failed to validate modelDescription.xml:" and
        # keeps what failed in .problems)
        problems = [str(p).strip() for p in getattr(exc, "problems", None) or []]
        text = "; ".join(problems) or \
            (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        return [(FAIL, "its modelDescription.xml cannot be read (%s): the FMU is damaged, was "
                       "edited or does not follow the FMI standard; a host cannot even learn "
                       "its variables. If it is one of driftfmu's FMUs, rebuild it "
                       "(driftfmu build)" % text)]
    if md.coSimulation is None:
        return [(FAIL, "the FMU has no co-simulation interface")]
    ident = md.coSimulation.modelIdentifier
    out.append((OK, "FMI %s co-simulation FMU '%s' (%s)" % (md.fmiVersion, md.modelName,
                                                          md.generationTool)))
    plat = _platform_dir(md.fmiVersion)
    ext = {"Linux": ".so", "Darwin": ".dylib", "Windows": ".dll"}.get(platform.system(), ".so")
    binary = "binaries/%s/%s%s" % (plat, ident, ext)
    present = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and
                      n.count("/") >= 2})
    loadable = False  # a binary for this platform, whole, for this machine's architecture
    if binary in names:
        damaged = [(b, why) for b in sorted(n for n in names if n.startswith(
            "binaries/%s/" % plat) and n.endswith(ext)) for why in [
                _binary_problem(zf.read(b), zf.getinfo(b).file_size)] if why]
        if damaged:
            for b, why in damaged:
                out.append((FAIL, "its binary %s is damaged: %s; no host can load it. "
                                  "Rebuild the FMU (driftfmu build)" % (b, why)))
        else:
            out.append(_architecture(zf.read(binary), binary, md.fmiVersion))
            loadable = out[-1][0] != FAIL
    else:
        out.append((FAIL, "it has no binary for this platform (%s); it has: %s"
                    % (plat, ", ".join(present) or "none")))
    record = {}
    python_fmu = "pythonfmu" in (md.generationTool or "").lower() or any(
        n.endswith(("_pythonfmu.so", "_pythonfmu.dll", "_pythonfmu.dylib")) for n in names)
    if "resources/driftfmu_build.json" in names:
        try:
            record = json.loads(zf.read("resources/driftfmu_build.json"))
        except ValueError as exc:
            out.append((FAIL, "resources/driftfmu_build.json is not valid JSON (%s): the "
                              "loader cannot learn which libpython to load. Rebuild the FMU "
                              "(driftfmu build)" % exc))
        else:
            out.append((OK, "built by driftfmu with Python %s (%s loader)"
                        % (record.get("python_version", "?"), record.get("loader", "?"))))
    elif python_fmu:
        if not any(n.startswith("resources/") for n in names):
            out.append((FAIL, "it has no resources/ folder: a Python FMU's code "
                              "(resources/*.py, resources/slavemodule.txt) and its build record "
                              "(resources/driftfmu_build.json) are missing, so no host can "
                              "create the model. Rebuild the FMU (driftfmu build), or re-pack "
                              "it with its resources/ folder"))
        else:
            out.append((WARN, "resources/driftfmu_build.json is missing: the FMU was not built "
                              "by driftfmu or was re-packed; the libpython it needs is guessed"))
        if "resources/slavemodule.txt" not in names and any(
                n.startswith("resources/") for n in names):
            out.append((FAIL, "resources/slavemodule.txt is missing: pythonfmu reads the name "
                              "of the model's Python module from it, so no host can create the "
                              "model. Rebuild the FMU (driftfmu build)"))
    host_py = "%d.%d" % sys.version_info[:2]
    built_py = ".".join(str(record.get("python_version", "")).split(".")[:2])
    if built_py and built_py != host_py:
        out.append((OK, "this process runs Python %s; the FMU was built with %s — fine for "
                        "Python hosts, whose own interpreter runs the FMU's code"
                    % (host_py, built_py)))
    pyfiles = [n for n in names if n.startswith("resources/") and n.endswith(".py")]
    if not pyfiles and not record and not python_fmu:  # a native FMU: no Python inside
        if "sources/" in {n[:8] for n in names}:
            out.append((OK, "a native FMU (no Python inside): a host needs no libpython; it is "
                            "also a source FMU (sources/) for platforms without a binary"))
        out.append(_try_instantiate(fmu, md.fmiVersion) if loadable else NOT_TRIED)
        return out
    # libpython for hosts that are not Python
    found = [s for s in _libpython_candidates(record) if _loadable(s)]
    if found:
        out.append((OK, "a host that is not Python will load %s (the first of the libpython "
                        "versions the FMU tries that this host's loader finds)" % found[0]))
    else:
        libdir = sysconfig.get_config_var("LIBDIR")
        out.append((WARN, "no libpython is on this host's library path, so a host that is "
                          "not Python (C, Java, Rust) cannot run the FMU; add the folder of "
                          "libpython3.X.so.1.0 to LD_LIBRARY_PATH (here: %s) or set "
                          "DRIFTFMU_LIBPYTHON to its path. Python hosts are not affected."
                    % libdir))
    # the bundled Python code
    bundled = {n.split("/")[1].rsplit(".py", 1)[0] for n in pyfiles}
    eager, lazy = set(), set()
    for n in pyfiles:
        try:
            e, l = _imports(zf.read(n).decode("utf-8"))
        except SyntaxError as exc:
            out.append((FAIL, "%s does not parse on Python %s: %s" % (n, host_py, exc)))
            continue
        eager |= e
        lazy |= l
    stdlib = _stdlib_names() | {"__future__"}
    foreign = sorted(m for m in eager if m not in bundled and m not in stdlib)
    optional = sorted(m for m in lazy - eager if m not in bundled and m not in stdlib)
    if foreign:
        missing = [m for m in foreign if not _importable(m)]
        out.append((FAIL if missing else WARN,
                    "the FMU's code needs modules that are neither bundled nor in the standard "
                    "library: %s%s" % (", ".join(foreign), "; not installed here: "
                                       + ", ".join(missing) if missing else "")))
    elif bundled:
        out.append((OK, "the FMU's code needs only the standard library and its bundled "
                        "modules (%s): any host with a matching libpython runs it"
                    % ", ".join(sorted(bundled))))
    if optional:
        out.append((OK, "imported only inside functions that the FMU does not call: %s "
                        "(not needed)" % ", ".join(optional)))
    out.append(_try_instantiate(fmu) if loadable else NOT_TRIED)
    return out


def _binary_problem(data, size):
    """Why a shared library cannot be loaded, in words, from its bytes alone (ELF, the
    format of Linux binaries; other formats are left to the loader); None when it looks
    whole."""
    import struct
    if platform.system() != "Linux":
        return None
    if size < 64 or data[:4] != b"\x7fELF":
        return ("not an ELF shared library (%d bytes, starting %r)" % (size, data[:4])
                if size else "an empty file")
    if data[4] != 2 or data[5] != 1:
        return ("a %s-bit %s-endian ELF file; this host runs 64-bit little-endian code"
                % ({1: "32", 2: "64"}.get(data[4], "?"), {1: "little", 2: "big"}.get(data[5],
                                                                                     "?")))
    phoff, shoff = struct.unpack_from("<QQ", data, 0x20)
    phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 0x36)
    need = max(phoff + phentsize * phnum, shoff + shentsize * shnum)
    if phoff + phentsize * phnum <= size:
        for i in range(phnum):
            p_type, _, p_offset = struct.unpack_from("<IIQ", data, phoff + i * phentsize)
            p_filesz = struct.unpack_from("<Q", data, phoff + i * phentsize + 0x20)[0]
            if p_type == 1:  # PT_LOAD: the loader maps these bytes of the file
                need = max(need, p_offset + p_filesz)
    if need > size:
        return ("truncated: the file has %d bytes, its ELF headers describe %d (a loader "
                "that maps it stops the host with SIGBUS)" % (size, need))
    return None


def _importable(module):
    import importlib.util
    return importlib.util.find_spec(module) is not None


def _try_instantiate(fmu, fmi_version="2.0"):
    # the child extracts the FMU into a folder this process made and removes when the child
    # has ended: also when the FMU crashed it or it was killed at the time limit
    if fmi_version.startswith("3"):
        code = ("import sys\nfrom fmpy import read_model_description, extract\n"
                "from fmpy.fmi3 import FMU3Slave\n"
                "md = read_model_description(sys.argv[1]); d = sys.argv[2]\n"
                "extract(sys.argv[1], unzipdir=d)\n"
                "s = FMU3Slave(guid=md.guid, unzipDirectory=d, "
                "modelIdentifier=md.coSimulation.modelIdentifier, instanceName='doctor')\n"
                "s.instantiate(); s.enterInitializationMode(startTime=0.0)\n"
                "s.exitInitializationMode(); s.terminate(); s.freeInstance()\n")
        return _run_instantiate(code, fmu)
    code = ("import sys\nfrom fmpy import read_model_description, extract\n"
            "from fmpy.fmi2 import FMU2Slave\n"
            "md = read_model_description(sys.argv[1]); d = sys.argv[2]\n"
            "extract(sys.argv[1], unzipdir=d)\n"
            "s = FMU2Slave(guid=md.guid, unzipDirectory=d, "
            "modelIdentifier=md.coSimulation.modelIdentifier, instanceName='doctor')\n"
            "s.instantiate(); s.setupExperiment(startTime=0.0)\n"
            "s.enterInitializationMode(); s.exitInitializationMode()\n"
            "s.terminate(); s.freeInstance()\n")
    return _run_instantiate(code, fmu)


def _run_instantiate(code, fmu, timeout=120):
    from driftfmu.simulations import folders
    with folders.temporary("driftfmu_doctor_") as folder:
        try:
            r = lifetime.run([sys.executable, "-c", code, str(fmu), folder],
                               capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return (FAIL, "instantiating the FMU in a Python host did not finish in %g s"
                    % timeout)
    if r.returncode == 0:
        return (OK, "it instantiates and initialises in a Python host (fmpy) on this machine")
    if r.returncode < 0:
        import signal
        try:
            name = signal.Signals(-r.returncode).name
        except ValueError:
            name = "signal %d" % -r.returncode
        return (FAIL, "instantiating it in a Python host (fmpy) crashed that host (%s): a "
                      "binary of the FMU is damaged or does not fit this machine" % name)
    last = (r.stderr.strip().splitlines() or ["exit status %d" % r.returncode])[-1]
    return (FAIL, "instantiating it in a Python host (fmpy) failed: %s" % last)


def report(fmu):
    """Print the diagnosis; return 0 when nothing is a problem, 1 otherwise."""
    findings = diagnose(fmu)
    mark = {OK: "  ok  ", WARN: " warn ", FAIL: "PROBLEM"}
    print("driftfmu doctor: %s" % fmu)
    for level, msg in findings:
        print("[%s] %s" % (mark[level], msg))
    bad = [m for lvl, m in findings if lvl == FAIL]
    print("verdict: %s" % ("this FMU will run on this host" if not bad else
                           "this FMU will NOT run on this host as it is: %s"
                           % "; ".join(_reason(m, str(fmu)) for m in bad)))
    return 1 if bad else 0


def _reason(message, path=""):
    """The first clause of a problem, for the verdict line (a message that starts with the
    FMU's path keeps it whole, whatever dots it holds)."""
    head = path if path and message.startswith(path) else ""
    rest = message[len(head):]
    if ": the FMU is damaged" in rest:  # what comes before it may quote a parser's sentences
        return head + rest.split(": the FMU is damaged")[0]
    return head + rest.split(". ")[0]


def add_cli(groups):
    p = groups["top"].add_parser("doctor", help="tell whether and why an FMU will run on this "
                                 "host (libpython, Python version, imports)")
    p.add_argument("fmu", metavar="FMU", help="path of the .fmu file")
    p.set_defaults(func=_cli)


def _cli(args):
    if not args.fmu.strip():
        from driftfmu.simulations.errors import UsageError
        raise UsageError("FMU %r is empty; allowed: the path of a .fmu file" % args.fmu)
    _exit(report(args.fmu))


def _exit(code):
    if code:
        raise SystemExit(code)
