"""Internal (not a stable API; use the command driftfmu doctor instead).

``driftfmu doctor FMU``: will this FMU (or SSP archive) run on this host, and if not, why.

It reads the FMU (the archive by its declared sizes, every member streamed and its CRC
checked; the model description, against driftfmu's table of the model when it is one of
driftfmu's, and every start value against its declared range; the build record the driftfmu
builder leaves in ``resources/driftfmu_build.json``; the binaries for this platform, each a
whole library of this platform's format; the bundled Python code) and checks, in plain words:
is there a binary for this platform; which libpython it needs and which ones this host's loader
can find; which Python version the bundled code was built with; which modules that code
imports, and whether each is in the standard library or bundled.  A line says what was
checked.  Finally it loads and instantiates the FMU in a separate process, so a crash cannot
take this one down.  An SSP archive gets the checks of driftfmu's SSP runner (its system
structure, each parameter by component and name, each connection) and each of its FMUs the
checks of an FMU.  Nothing is read whole beyond the bounds of
:mod:`driftfmu.simulations.fmucheck`, so a zip bomb is refused by what it declares.
"""
import ast
import functools
import json
import platform
import struct
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

from driftfmu.fmu_src import schemas
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


def _architecture(zf, binary, fmi_version):
    """(status, line) on whether ``binary`` (a member of the archive ``zf``) is built for this
    machine's processor: FMI 2.0's folders name no architecture (linux64 serves x86-64 and
    aarch64 alike, docs/platforms.md).  Read whole only within the bound of what is read
    whole (fmucheck.MAX_READ), else by its headers."""
    from driftfmu.fmu_src import binaries
    from driftfmu.simulations import fmucheck
    machine = fmucheck.MACHINE
    if zf.getinfo(binary).file_size > fmucheck.MAX_READ:
        why = fmucheck.member_binary_problem(zf, binary)
        if why is None:
            return OK, "it has a binary for this platform (%s, %s)" % (binary, machine)
        return FAIL, "%s is not for this machine: %s" % (binary, why)
    try:
        archs = [lib.arch for lib in binaries.inspect(zf.read(binary))]
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
    visit(schemas.parse_python(source), False)
    return eager, lazy - eager


@functools.lru_cache(maxsize=None)
def _loadable(soname):
    """True when the dynamic loader of this host finds and loads ``soname`` (asked once per
    process: an SSP's FMUs ask alike)."""
    code = "import ctypes,sys; ctypes.CDLL(sys.argv[1])"
    return lifetime.run([sys.executable, "-c", code, soname], capture_output=True,
                          timeout=30).returncode == 0


def _libpython_candidates(record):
    first = [record["libpython"]] if record.get("libpython") else []
    others = ["libpython3.%d.so.1.0" % m for m in range(14, 7, -1)] + ["libpython3.so"]
    return first + [s for s in others if s not in first]


def diagnose(fmu):
    """List of ``(level, message)`` about running ``fmu`` (an FMU, or an SSP archive) on this
    host; the last but one line says what was checked."""
    from driftfmu.simulations import fmucheck
    from driftfmu.simulations.errors import FileProblem
    fmu = Path(fmu)
    out = []
    if fmu.is_dir():
        return [(FAIL, "%s is a folder, not an FMU; allowed: the path of a .fmu file (the zip "
                       "archive, not the folder it was unzipped to)" % fmu)]
    if not fmu.is_file():
        return [(FAIL, "%s does not exist or is not a file" % fmu)]
    try:
        zf = zipfile.ZipFile(fmu)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError, OSError):
        return [(FAIL, "%s is not an FMU: not a zip archive" % fmu)]
    with zf:
        names = set(zf.namelist())
        # by the central directory first: a zip bomb is refused before a byte is inflated
        problem = fmucheck.archive_problem(fmu, zf)
        if problem:
            return [(FAIL, problem)]
        if "modelDescription.xml" not in names and "SystemStructure.ssd" in names:
            return diagnose_ssp(fmu)
        for info in zf.infolist():  # every entry read (streamed), its CRC checked
            error = fmucheck.member_error(zf, info.filename)
            if error:
                return [(FAIL, "%s is damaged: %s (%s) cannot be read from the zip archive; "
                               "rebuild it (driftfmu build) or copy it again"
                         % (fmu, info.filename, error))]
        if "modelDescription.xml" not in names:
            return [(FAIL, "%s has no modelDescription.xml" % fmu)]
        return _diagnose_fmu(fmu, zf, names, out)


def _diagnose_fmu(fmu, zf, names, out):
    from driftfmu.fmu_src.schemas import read_model_description
    from driftfmu.simulations import fmucheck
    from driftfmu.simulations.errors import FileProblem
    try:
        desc = fmucheck.parse_description(fmu, fmucheck.read_member(fmu, zf,
                                                                    "modelDescription.xml"))
        md = read_model_description(str(fmu))
    except Exception as exc:  # an XML parser's or fmpy's validation message
        # (fmpy's ValidationError says only "Failed to validate modelDescription.xml:" and
        # keeps what failed in .problems)
        problems = [str(p).strip() for p in getattr(exc, "problems", None) or []]
        text = "; ".join(problems) or \
            (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        if isinstance(exc, FileProblem):
            text = text.split(": modelDescription.xml: ", 1)[-1]
        return [(FAIL, "its modelDescription.xml cannot be read (%s): the FMU is damaged, was "
                       "edited or does not follow the FMI standard; a host cannot even learn "
                       "its variables. If it is one of driftfmu's FMUs, rebuild it "
                       "(driftfmu build)" % text)]
    if md.coSimulation is None:
        return [(FAIL, "the FMU has no co-simulation interface")]
    out.append((OK, "FMI %s co-simulation FMU '%s' (%s)" % (md.fmiVersion, md.modelName,
                                                          md.generationTool)))
    checked = ["the archive (%d members, their declared sizes within %s each and %s in all, "
               "every member read and its CRC checked)" % (
                   len(names), fmucheck.size_text(fmucheck.MAX_MEMBER),
                   fmucheck.size_text(fmucheck.MAX_ARCHIVE))]
    found = fmucheck.table_problems(desc)
    model = fmucheck.ours(desc)
    expected = fmucheck.expected_model(fmu)
    if model is None and expected is not None and desc.model != expected:
        out.append((FAIL, "it is an FMU of the model %r, not driftfmu's %s that its file's name "
                          "says; driftfmu's masters refuse it under this name" % (desc.model,
                                                                                 expected)))
    if model is not None:
        checked.append("the model description against driftfmu's %s table (%d variables: "
                       "names, value references, types, causality, variability, start "
                       "values, min and max; the modelName and modelIdentifier)"
                       % (model, len(fmucheck.table(model))))
        if found:
            what, want = found[0]
            out.append((FAIL, "its modelDescription.xml is not driftfmu's %s as its code "
                              "runs: %s; expected: %s%s. A host would be silently wrong; "
                              "rebuild the FMU (driftfmu build)" % (
                                  model, what, want, " (and %d more difference%s)" % (
                                      len(found) - 1, "s" * (len(found) > 2))
                                  if len(found) > 1 else "")))
        else:
            out.append((OK, "its model description is driftfmu's %s table: every variable's "
                            "name, value reference, type, causality and start value"
                        % model))
    checked.append("every start value against its declared min and max")
    for what, want in fmucheck.range_problems(desc)[:1]:
        out.append((FAIL, "its modelDescription.xml: %s; expected: %s. A host would start "
                          "the FMU outside what it declares" % (what, want)))
    plat = _platform_dir(md.fmiVersion)
    ext = {"Linux": ".so", "Darwin": ".dylib", "Windows": ".dll"}.get(platform.system(), ".so")
    binary = "binaries/%s/%s%s" % (plat, desc.identifier, ext)
    loadable = False  # a binary for this platform, whole, for this machine's architecture
    missing = fmucheck.binary_presence_problem(fmu, desc, names)
    if missing is None:
        libraries = sorted(n for n in names if n.startswith("binaries/%s/" % plat)
                           and n.endswith(ext))
        checked.append("%s (each a whole shared library of this platform's format: its "
                       "headers, segments and sections inside the file)"
                       % ", ".join(libraries))
        damaged = [(b, why) for b in libraries for why in [
            fmucheck.member_binary_problem(zf, b, machine="any")] if why]
        if damaged:
            for b, why in damaged:
                out.append((FAIL, "its binary %s is damaged: %s; no host can load it. "
                                  "Rebuild the FMU (driftfmu build)" % (b, why)))
        else:
            out.append(_architecture(zf, binary, md.fmiVersion))
            loadable = out[-1][0] != FAIL
    else:
        out.append((FAIL, "%s; expected: %s" % missing))
    out.extend(_python_findings(fmu, zf, names, md, checked))
    out.append((OK, "checked: " + "; ".join(checked)))
    out.append(_try_instantiate(fmu, md.fmiVersion) if loadable else NOT_TRIED)
    return out


def _python_findings(fmu, zf, names, md, checked):
    """The lines on what a Python FMU needs on a host (build record, libpython, its code's
    imports); a native FMU's one line."""
    from driftfmu.simulations import fmucheck
    out = []
    record = {}
    python_fmu = "pythonfmu" in (md.generationTool or "").lower() or any(
        n.endswith(("_pythonfmu.so", "_pythonfmu.dll", "_pythonfmu.dylib")) for n in names)
    if "resources/driftfmu_build.json" in names:
        try:
            record = json.loads(fmucheck.read_member(fmu, zf, "resources/driftfmu_build.json"))
            if not isinstance(record, dict):
                raise ValueError("not a JSON object")
        except ValueError as exc:
            record = {}
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
            e, l = _imports(fmucheck.read_member(fmu, zf, n).decode("utf-8"))
        except (SyntaxError, ValueError) as exc:
            out.append((FAIL, "%s does not parse on Python %s: %s" % (n, host_py, exc)))
            continue
        except fmucheck.FileProblem as exc:
            out.append((FAIL, str(exc)))
            continue
        eager |= e
        lazy |= l
    checked.append("the bundled code's imports (%d modules)" % len(pyfiles))
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
    return out


def diagnose_ssp(ssp):
    """List of ``(level, message)`` about running the SSP archive ``ssp`` on this host: the
    system structure, each parameter by component and name, each connection, and each
    component's FMU diagnosed as an FMU (its lines prefixed with its member's name)."""
    from driftfmu.simulations import fmucheck, folders
    from driftfmu.simulations.errors import FileProblem
    out = []
    with folders.temporary("driftfmu_doctor_") as folder:
        try:
            problems, checked, fmus = fmucheck.inspect_ssp(ssp, folder)
        except FileProblem as exc:
            return [(FAIL, str(exc))]
        out.append((OK, "an SSP archive with %d components: %s" % (
            len(fmus), ", ".join("%s (%s)" % (c, m) for c, (m, _) in fmus.items()))))
        # a component FMU's own problems are its diagnosis's below; every other one (the
        # system structure's, a parameter set's, a member that cannot be read) is listed here
        members = tuple("%s: %s: " % (ssp, m) for m, _ in fmus.values())
        for problem in problems:
            if not problem.startswith(members):
                out.append((FAIL, problem))
        for component, (member, path) in fmus.items():
            for level, message in diagnose(path):
                out.append((level, "%s: %s" % (member, message.replace(str(path), member))))
        out.append((OK, "checked: " + "; ".join(checked)))
    return out


def _binary_problem(data, size):
    """Why a shared library cannot be loaded, in words, from its bytes alone
    (:func:`driftfmu.simulations.fmucheck.binary_problem` on this platform, any processor);
    None when it looks whole."""
    from driftfmu.simulations import fmucheck
    return fmucheck.binary_problem(lambda offset, count: data[offset:offset + count], size,
                                   machine="any")


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
            # the work folder's lock held by the host too (folders.held_fds)
            r = lifetime.run([sys.executable, "-c", code, str(fmu), folder],
                             capture_output=True, text=True, timeout=timeout,
                             pass_fds=folders.held_fds(folder))
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
    kind = "SSP" if _is_ssp(fmu) else "FMU"
    print("driftfmu doctor: %s" % fmu)
    for level, msg in findings:
        print("[%s] %s" % (mark[level], msg))
    bad = [m for lvl, m in findings if lvl == FAIL]
    print("verdict: %s" % ("this %s will run on this host" % kind if not bad else
                           "this %s will NOT run on this host as it is: %s"
                           % (kind, "; ".join(_reason(m, str(fmu)) for m in bad))))
    return 1 if bad else 0


def _is_ssp(path):
    """Whether ``path`` is a zip archive with a SystemStructure.ssd and no model description
    (an SSP)."""
    try:
        with zipfile.ZipFile(path) as zf:
            names = set(zf.namelist())
    except (OSError, zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError):
        return False
    return "SystemStructure.ssd" in names and "modelDescription.xml" not in names


def _reason(message, path=""):
    """The first clause of a problem, for the verdict line (a message that starts with the
    FMU's path keeps it whole, whatever dots it holds)."""
    head = path if path and message.startswith(path) else ""
    rest = message[len(head):]
    if ": the FMU is damaged" in rest:  # what comes before it may quote a parser's sentences
        return head + rest.split(": the FMU is damaged")[0]
    return head + rest.split(". ")[0]


def add_cli(groups):
    p = groups["top"].add_parser("doctor", help="tell whether and why an FMU or SSP will run on "
                                 "this host (the archive, the model description against "
                                 "driftfmu's tables, the binaries, libpython, imports) and what "
                                 "was checked")
    p.add_argument("fmu", metavar="FMU", help="path of the .fmu (or .ssp) file")
    p.set_defaults(func=_cli)


def _cli(args):
    if not args.fmu.strip():
        from driftfmu.simulations.errors import UsageError
        raise UsageError("FMU %r is empty; allowed: the path of a .fmu file" % args.fmu)
    _exit(report(args.fmu))


def _exit(code):
    if code:
        raise SystemExit(code)
