"""Internal (not a stable API; use driftfmu.build_fmus instead).

Build the project's FMUs so that they validate clean and load in any host.

For each slave script ``fmu_src/<Name>.py`` :func:`build_fmus`

1. bundles the project code the slave imports, ``models/`` and ``fmu_src/slave_base.py``, as
   one package ``drift_<hash>`` and rewrites the slave's project imports to it; the slave module
   becomes ``<Name>_<hash>``.  pythonfmu runs all FMUs of a process in one interpreter with one
   ``sys.modules``, so unique names let FMUs of two different builds each run their own code;
2. builds the FMU with pythonfmu and completes its modelDescription.xml from the slave class's
   ``VARIABLES`` and ``DEPENDENCIES``: units (with SI base units), ``min``/``max``, the
   ModelStructure with Outputs and InitialUnknowns, and the co-simulation capabilities;
3. makes ``binaries/linux64/<Name>.so`` the loader shim compiled from ``loader/fmi2_shim.c``,
   which loads a libpython when the host is not a Python process and forwards every FMI call to
   pythonfmu's library, shipped beside it as ``<Name>_pythonfmu.so``.  Without a C compiler the
   builder falls back to adding libpython to pythonfmu's library as a DT_NEEDED entry;
4. validates the FMU with fmpy and moves it into place as ``<out_dir>/<Name>.fmu``.

``resources/driftfmu_build.json`` records the GUID (which the loader shim checks the host's
against), the Python version, libpython soname, code hash and loader kind of the build.  The
bundled package carries driftfmu's version, and the GUID is made from the module (with its code
hash), the class and that version (``slave_base.GUID_NAMESPACE``), so the model description and
every instance agree on it and FMU states can name their FMU.
"""
import ast
import contextlib
import hashlib
import importlib
import json
import os
import platform
import re
import shlex
import shutil
import sys
import sysconfig
import tempfile
import zipfile
from fractions import Fraction
from pathlib import Path
from xml.etree import ElementTree as ET

from driftfmu import __version__
from driftfmu.simulations import folders, lifetime
from driftfmu.fmu_src import schemas

SRC_DIR = Path(__file__).resolve().parent
NAMES = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")
LOADER_SOURCE = SRC_DIR / "loader" / "fmi2_shim.c"
BUILD_INFO = "resources/driftfmu_build.json"
HASH_LENGTH = 10

#: Units the unit definitions know: symbol -> (factor, SI base-unit exponents).  ``g`` is the
#: standard acceleration of gravity, 9.80665 m/s2.
UNIT_SYMBOLS = {
    "1": (1.0, {}),
    "kg": (1.0, {"kg": 1}),
    "m": (1.0, {"m": 1}),
    "s": (1.0, {"s": 1}),
    "A": (1.0, {"A": 1}),
    "K": (1.0, {"K": 1}),
    "mol": (1.0, {"mol": 1}),
    "cd": (1.0, {"cd": 1}),
    "rad": (1.0, {"rad": 1}),
    "Hz": (1.0, {"s": -1}),
    "N": (1.0, {"kg": 1, "m": 1, "s": -2}),
    "W": (1.0, {"kg": 1, "m": 2, "s": -3}),
    "V": (1.0, {"kg": 1, "m": 2, "s": -3, "A": -1}),
    "g": (9.80665, {"m": 1, "s": -2}),
}
_BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_UNIT_FACTOR = re.compile(r"^(sqrt\()?([A-Za-z]+|1)(-?\d+)?(?(1)\))$")


class BuildError(RuntimeError):
    """An FMU could not be built, or it was built but does not validate."""


def check_fmu_folder(fmu_dir, missing, native=False):
    """Before the FMUs ``missing`` (file names) are built into ``fmu_dir`` where a run looks for
    them: a UsageError when ``fmu_dir`` is an existing folder that holds anything but what a
    build writes there (``*.fmu``, ``native/``, hidden ``.driftfmu*`` staging and locks), so
    that a run given another folder (a project's, the working folder) does not fill it with
    FMUs unasked.  A new or empty folder, or one of FMUs, is built into.  ``native``: the
    missing FMUs are native ones (the command that builds them says so)."""
    from driftfmu.simulations.errors import UsageError
    folder = Path(fmu_dir)
    try:
        names = sorted(os.listdir(folder)) if folder.is_dir() else []
    except OSError:
        names = []
    other = [n for n in names if not (n.endswith(".fmu") or n == "native"
                                      or n.startswith(".driftfmu"))]
    if other:
        shown = ", ".join(other[:3]) + (", ..." if len(other) > 3 else "")
        raise UsageError("fmu_dir %s has no %s and holds other files (%s): driftfmu builds "
                         "missing FMUs only into a folder of its own; allowed: a folder of "
                         "driftfmu's FMUs, a new or an empty one, or build them there first "
                         "(driftfmu build%s --out %s)" % (fmu_dir, ", ".join(missing), shown,
                                                          " --native" if native else "",
                                                          fmu_dir))


def source_files(name, src_dir=SRC_DIR):
    """The project files bundled into FMU ``name``, in the order they are hashed.

    Parameters
    ----------
    name : str
        Slave name; the script is ``<src_dir>/<name>.py``.
    src_dir : path-like
        The ``fmu_src`` directory; ``models/`` is its sibling.

    Returns
    -------
    list of pathlib.Path
        ``models/**/*.py`` sorted by path, then ``slave_base.py``, then the slave script.
    """
    src_dir = Path(src_dir)
    models = sorted(p for p in (src_dir.parent / "models").rglob("*.py")
                    if "__pycache__" not in p.parts)
    return models + [src_dir / "slave_base.py", src_dir / ("%s.py" % name)]


def source_hash(name, src_dir=SRC_DIR):
    """First ``HASH_LENGTH`` hex digits of the SHA-256 of the code bundled into FMU ``name``.

    The digest runs over each file of :func:`source_files` in turn: its path relative to the
    project root, a NUL byte, its bytes, a NUL byte.  An FMU whose recorded hash differs from
    this value was built from other code.
    """
    src_dir = Path(src_dir)
    root = src_dir.parent
    digest = hashlib.sha256()
    for path in source_files(name, src_dir):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()[:HASH_LENGTH]


def build_fmus(out_dir="build/fmus", names=NAMES, src_dir=SRC_DIR, log=print):
    """Build, complete and validate one FMU per slave script.

    Parameters
    ----------
    out_dir : path-like
        Directory of the FMUs; created if missing.  Each ``<Name>.fmu`` is written under a
        temporary name and moved into place only once it validates.
    names : sequence of str
        Slave names; ``<src_dir>/<Name>.py`` holds the slave class.
    src_dir : path-like
        The ``fmu_src`` directory (``slave_base.py`` and the slave scripts); ``models/`` is its
        sibling.
    log : callable
        Receives one progress or warning line (str) at a time.

    Returns
    -------
    list of pathlib.Path
        The FMUs, in the order of ``names``.

    Raises
    ------
    BuildError
        If a slave cannot be bundled or an FMU does not validate.
    """
    generated = generation_time()  # a bad SOURCE_DATE_EPOCH fails before anything is built
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    src_dir = Path(src_dir).resolve()
    with folders.temporary("driftfmu_loader_") as work:
        loader = _make_loader(Path(work), log)
        return [_build_one(name, out_dir, src_dir, loader, log, generated) for name in names]


def generation_time():
    """The ``generationDateAndTime`` of the model descriptions: ``SOURCE_DATE_EPOCH`` (seconds
    since 1970-01-01 UTC, https://reproducible-builds.org/specs/source-date-epoch/) as
    ``YYYY-MM-DDThh:mm:ssZ`` when it is set, so that the same sources build the same bytes;
    None (pythonfmu's time of the build) when it is not."""
    value = os.environ.get("SOURCE_DATE_EPOCH")
    if value is None or value == "":
        return None
    import datetime
    try:
        seconds = int(value.strip())
        if seconds < 0:
            raise ValueError
        stamp = datetime.datetime.fromtimestamp(seconds, datetime.timezone.utc)
    except (ValueError, OverflowError, OSError):
        raise BuildError("SOURCE_DATE_EPOCH=%r is not a time; allowed: a whole number of "
                         "seconds since 1970-01-01 00:00 UTC, e.g. $(git log -1 --format=%%ct)"
                         % value) from None
    return stamp.strftime("%Y-%m-%dT%H:%M:%SZ")


def libpython_soname():
    """Soname of the libpython of the running interpreter, e.g. ``libpython3.11.so.1.0``."""
    soname = sysconfig.get_config_var("INSTSONAME") or ""
    if ".so" not in soname:  # a statically linked interpreter names its archive here
        soname = "libpython%d.%d%s.so.1.0" % (sys.version_info[0], sys.version_info[1],
                                             sys.abiflags)
    return soname


# -- bundling ----------------------------------------------------------------------------------

def rewrite_imports(source, package):
    """Point a slave script's project imports at the bundled package ``package``.

    ``driftfmu.models`` and ``driftfmu.models.*`` become ``<package>.models...``;
    ``driftfmu.fmu_src.slave_base`` becomes ``<package>.slave_base`` (``import
    driftfmu.models.x`` binds ``driftfmu`` to the bundle).  Other imports, relative ones included, stay as they are.

    Parameters
    ----------
    source : str
        The slave script.
    package : str
        Name of the bundled package, ``drift_<hash>``.

    Returns
    -------
    str
        The script with each project import statement replaced, indentation and trailing
        comments kept.

    Raises
    ------
    BuildError
        For a project import that cannot be bundled (another ``driftfmu`` module) or that
        shares its line with other code.
    """
    tree = schemas.parse_python(source)
    lines = source.splitlines(keepends=True)
    edits = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            statements = _rewritten(node, package)
            if statements is not None:
                edits.append((node, statements))
    for node, statements in sorted(edits, key=lambda e: e[0].lineno, reverse=True):
        first, last = node.lineno - 1, node.end_lineno - 1
        head = lines[first].encode()[:node.col_offset].decode()
        tail = lines[last].encode()[node.end_col_offset:].decode()
        if head.strip() or (tail.strip() and not tail.lstrip().startswith("#")):
            raise BuildError("line %d: a project import must be a statement on its own line"
                             % node.lineno)
        new = [head + s + "\n" for s in statements[:-1]] + [head + statements[-1] + tail]
        lines[first:last + 1] = new
    return "".join(lines)


def _bundled_name(module, package):
    """Name of project module ``module`` inside ``package``, or None if not a project module."""
    if module == "driftfmu.models" or module.startswith("driftfmu.models."):
        return "%s.%s" % (package, module[len("driftfmu."):])
    if module == "driftfmu.fmu_src.slave_base" or module.startswith("driftfmu.fmu_src.slave_base."):
        return package + module[len("driftfmu.fmu_src"):]
    if module == "driftfmu" or module.startswith("driftfmu."):
        raise BuildError("%s is not bundled into the FMU; a slave may import driftfmu.models and "
                         "driftfmu.fmu_src.slave_base only" % module)
    return None


def _alias(alias):
    return alias.name + (" as " + alias.asname if alias.asname else "")


def _rewritten(node, package):
    """Replacement statements for one import node, or None to keep it."""
    if isinstance(node, ast.ImportFrom):
        if node.level:
            return None
        names = ", ".join(_alias(a) for a in node.names)
        if node.module == "driftfmu.fmu_src":
            if any(a.name != "slave_base" for a in node.names):
                raise BuildError("line %d: only driftfmu.fmu_src.slave_base is bundled"
                                 % node.lineno)
            return ["from %s import %s" % (package, names)]
        if node.module == "driftfmu":
            if any(a.name != "models" for a in node.names):
                raise BuildError("line %d: only driftfmu.models is bundled" % node.lineno)
            return ["from %s import %s" % (package, names)]
        target = _bundled_name(node.module, package)
        return None if target is None else ["from %s import %s" % (target, names)]
    targets = [_bundled_name(a.name, package) for a in node.names]
    if not any(targets):
        return None
    statements = []
    for alias, target in zip(node.names, targets):
        if target is None:
            statements.append("import " + _alias(alias))
        elif alias.asname:
            statements.append("import %s as %s" % (target, alias.asname))
        elif alias.name.startswith("driftfmu.models"):
            statements.append("import " + target)
            statements.append("import %s as driftfmu" % package)
        else:
            raise BuildError("line %d: write `from driftfmu.fmu_src.slave_base import ...` "
                             "instead of `import %s`" % (node.lineno, alias.name))
    return statements


def _stage(name, src_dir, digest, stage):
    """Write the bundled package and the renamed slave script into ``stage``; return the script.

    Every bundled file goes through :func:`rewrite_imports`, so no bundled code can reach a
    ``driftfmu`` that happens to be importable where the FMU runs.
    """
    package = stage / ("drift_" + digest)
    root = src_dir.parent
    for source in source_files(name, src_dir)[:-1]:
        target = package / (source.name if source.parent == src_dir else source.relative_to(root))
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(rewrite_imports(source.read_text(), package.name))
    # the FMU's own copy of driftfmu's version: the slaves put it (and a GUID made from it)
    # into their FMU states, and the model description
    (package / "__init__.py").write_text('"""driftfmu code bundled by build %s."""\n'
                                         '__version__ = %r\n' % (digest, __version__))
    for folder in [package] + [p for p in package.rglob("*") if p.is_dir()]:
        init = folder / "__init__.py"
        if not init.exists():
            init.write_text('"""driftfmu code bundled by build %s."""\n' % digest)
    slave = src_dir / ("%s.py" % name)
    (package / slave.name).write_text(rewrite_imports(slave.read_text(), package.name))
    script = stage / ("%s_%s.py" % (name, digest))
    script.write_text(ENTRY_MODULE.format(name=name, package=package.name))
    return script


#: The module pythonfmu loads.  pythonfmu 0.7.0 re-executes it on every fmi2Instantiate (module
#: globals, fresh locals), takes the Fmi2Slave class it finds among the locals, and then releases
#: one reference to the module's globals that it never took.  A slave class defined here would be
#: created anew, and leaked, on every instantiation (16 KiB each); an import creates it once per
#: process, and each execution hands back the reference to the globals that pythonfmu will drop
#: (a list slot, 8 bytes).
ENTRY_MODULE = '''"""Entry module of the {name} FMU, generated by the driftfmu builder."""
_g = globals()
_g.setdefault("_references_released_by_pythonfmu", []).append(_g)
from {package}.{name} import {name}  # noqa: E402,F401
'''


@contextlib.contextmanager
def _importable(directory, *top_level):
    """Put ``directory`` first on sys.path; afterwards remove it and forget ``top_level``."""
    entry = str(directory)
    sys.path.insert(0, entry)
    try:
        yield
    finally:
        sys.path[:] = [p for p in sys.path if p != entry]
        for module in list(sys.modules):
            if module.split(".")[0] in top_level:
                del sys.modules[module]
        importlib.invalidate_caches()


# -- the model description ---------------------------------------------------------------------

def unit_definition(unit):
    """Factor and SI base-unit exponents of a unit such as ``"V/g2"`` or ``"g/sqrt(Hz)"``.

    A unit is factors joined by ``.`` or ``*``, optionally divided (``/``) by more factors; a
    factor is a symbol of :data:`UNIT_SYMBOLS` with an optional integer exponent (``g2``,
    ``s-1``), or the square root of one (``sqrt(Hz)``).

    Returns
    -------
    tuple of (float, dict) or None
        ``(factor, {base: exponent})`` with :class:`fractions.Fraction` exponents, zero ones
        left out, or None for a symbol the table does not know.
    """
    factor, exponents = 1.0, {}
    for i, part in enumerate(unit.split("/")):
        sign = 1 if i == 0 else -1
        for token in re.split(r"[.*]", part):
            match = _UNIT_FACTOR.match(token.strip())
            if not match:
                return None
            root, symbol, power = match.group(1, 2, 3)
            if symbol not in UNIT_SYMBOLS:
                return None
            power = Fraction(sign * int(power or 1), 2 if root else 1)
            f, base = UNIT_SYMBOLS[symbol]
            factor *= f ** float(power)
            for b, e in base.items():
                exponents[b] = exponents.get(b, 0) + e * power
    return factor, {b: e for b, e in exponents.items() if e}


def _unit_element(unit, log):
    """A <Unit>; its <BaseUnit> is left out where FMI's integer exponents cannot express it."""
    element = ET.Element("Unit", name=unit)
    definition = unit_definition(unit)
    if definition is None:
        log("warning: unit %r is not in builder.UNIT_SYMBOLS; it is defined without base units"
            % unit)
        return element
    factor, exponents = definition
    if any(e.denominator != 1 for e in exponents.values()):
        return element
    attrib = {b: str(exponents[b]) for b in _BASE_UNITS if b in exponents}
    if factor != 1.0:
        attrib["factor"] = repr(factor)
    ET.SubElement(element, "BaseUnit", attrib)
    return element


def _number(value, kind):
    return str(int(value)) if kind == "Integer" else repr(float(value))


def _initial(variable):
    """The ``initial`` of a ScalarVariable, explicit or the FMI 2.0 default."""
    if variable.get("initial"):
        return variable.get("initial")
    causality = variable.get("causality", "local")
    if variable.get("variability") == "constant" or causality == "parameter":
        return "exact"
    if causality in ("calculatedParameter", "output", "local"):
        return "calculated"
    return None


def complete_model_description(xml, slave, log=print):
    """Complete pythonfmu's modelDescription.xml from the slave class's tables.

    Parameters
    ----------
    xml : bytes
        modelDescription.xml as pythonfmu wrote it.
    slave : type
        The slave class: ``VARIABLES`` (dicts with name, type, causality, variability, start,
        unit, min, max, description), ``DEPENDENCIES`` (output name -> names of the inputs it
        depends on directly) and optionally ``CAN_HANDLE_VARIABLE_STEP`` (default True).
    log : callable
        Receives warnings.

    Returns
    -------
    bytes
        The model description with

        - ``unit`` (Real only; FMI 2.0 Integers have none), ``min`` and ``max`` on each
          variable's type element and a ``UnitDefinitions`` entry per unit used;
        - ``ModelStructure/Outputs`` with each output's direct input dependencies;
        - ``ModelStructure/InitialUnknowns``: every output with initial approx or calculated and
          every calculatedParameter, depending on its inputs from ``DEPENDENCIES`` and on all
          parameters with initial exact (a conservative superset);
        - ``canGetAndSetFMUstate`` and ``canSerializeFMUstate`` true,
          ``canHandleVariableCommunicationStepSize`` from the class and ``needsExecutionTool``
          false: the FMU needs a Python installation (a shared library and its standard
          library), not a running tool.

        The guid, date and DefaultExperiment stay as built.

    Raises
    ------
    BuildError
        If the tables do not match the variables pythonfmu registered.
    """
    root = ET.fromstring(xml)
    specs = {spec["name"]: spec for spec in slave.VARIABLES}
    variables = root.find("ModelVariables").findall("ScalarVariable")
    registered = [v.get("name") for v in variables]
    if sorted(registered) != sorted(specs):
        raise BuildError("%s.VARIABLES %s does not match the registered variables %s"
                         % (slave.__name__, sorted(specs), registered))
    index = {name: i + 1 for i, name in enumerate(registered)}

    cosim = root.find("CoSimulation")
    cosim.set("needsExecutionTool", "false")
    cosim.set("canHandleVariableCommunicationStepSize",
              str(bool(getattr(slave, "CAN_HANDLE_VARIABLE_STEP", True))).lower())
    cosim.set("canGetAndSetFMUstate", "true")
    cosim.set("canSerializeFMUstate", "true")

    units = set()
    for variable in variables:
        spec = specs[variable.get("name")]
        element = variable[0]
        if element.tag != spec["type"]:
            raise BuildError("%s is registered as %s but VARIABLES says %s"
                             % (spec["name"], element.tag, spec["type"]))
        attrib = {}
        if spec.get("unit") and element.tag == "Real":
            attrib["unit"] = spec["unit"]
            units.add(spec["unit"])
        for key in ("min", "max"):
            if spec.get(key) is not None and element.tag in ("Real", "Integer"):
                attrib[key] = _number(spec[key], element.tag)
        attrib.update(element.attrib)
        element.attrib.clear()
        element.attrib.update(attrib)
    if units:
        definitions = ET.Element("UnitDefinitions")
        definitions.extend(_unit_element(u, log) for u in sorted(units))
        root.insert(list(root).index(cosim) + 1, definitions)

    causality = {v.get("name"): v.get("causality", "local") for v in variables}
    dependencies = getattr(slave, "DEPENDENCIES", {})
    for output, inputs in dependencies.items():
        if causality.get(output) != "output":
            raise BuildError("DEPENDENCIES: %r is not an output" % output)
        wrong = [name for name in inputs if causality.get(name) != "input"]
        if wrong:
            raise BuildError("DEPENDENCIES[%r]: %s are not inputs" % (output, wrong))
    exact_parameters = [index[v.get("name")] for v in variables
                        if causality[v.get("name")] == "parameter" and _initial(v) == "exact"]

    structure = root.find("ModelStructure")
    structure.clear()
    outputs = ET.SubElement(structure, "Outputs")
    initial_unknowns = ET.SubElement(structure, "InitialUnknowns")
    for variable in variables:
        name = variable.get("name")
        direct = sorted(index[i] for i in dependencies.get(name, ()))
        if causality[name] == "output":
            ET.SubElement(outputs, "Unknown", index=str(index[name]),
                          dependencies=" ".join(map(str, direct)))
        if ((causality[name] == "output" and _initial(variable) in ("approx", "calculated"))
                or causality[name] == "calculatedParameter"):
            known = sorted(set(direct + exact_parameters) - {index[name]})
            ET.SubElement(initial_unknowns, "Unknown", index=str(index[name]),
                          dependencies=" ".join(map(str, known)))
    for section in (outputs, initial_unknowns):
        if not len(section):
            structure.remove(section)

    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8",
                                                                     xml_declaration=False)


# -- the Linux binary --------------------------------------------------------------------------

def _fmi2_headers():
    import fmpy
    return Path(fmpy.__file__).resolve().parent / "c-code"


def _make_loader(work, log):
    """Compile the loader shim once per build; ``(kind, path)`` with kind shim/dt_needed/stock.

    Falls back to ``dt_needed`` (patchelf adds libpython to pythonfmu's library) when no C
    compiler works, and to ``stock`` (pythonfmu's library unchanged) when patchelf is missing
    too, each with a warning saying what is lost.
    """
    soname = libpython_soname()
    if not sys.platform.startswith("linux"):
        log("warning: not on Linux; binaries/linux64 is left as pythonfmu ships it, and loads "
            "in Python hosts only")
        return "stock", None
    compiler = shlex.split(os.environ.get("CC", "cc"))
    problem = "no C compiler (%s) found" % compiler[0]
    if shutil.which(compiler[0]):
        shim = work / "fmi2_shim.so"
        command = compiler + ["-shared", "-fPIC", "-O2", "-fvisibility=hidden",
                              "-I%s" % _fmi2_headers(), "-I%s" % (SRC_DIR / "native"),
                              '-DDRIFTFMU_BUILD_LIBPYTHON="%s"' % soname,
                              "-o", str(shim), str(LOADER_SOURCE), "-ldl", "-lpthread"]
        # the work folder's lock held by the compiler too (folders.held_fds)
        result = lifetime.run(command, capture_output=True, text=True, work=work,
                              pass_fds=folders.held_fds(work))
        if result.returncode == 0:
            return "shim", shim
        problem = "compiling %s failed:\n%s" % (LOADER_SOURCE, result.stderr.strip())
    lost = ("it loads only where %s is on the library path, a Python host of another version "
            "then gets a second libpython (crash risk), and model errors stay hidden unless "
            "debug logging is on" % soname)
    if shutil.which("patchelf"):
        log("warning: %s; linking pythonfmu's library to %s with patchelf instead: %s"
            % (problem, soname, lost))
        return "dt_needed", None
    log("warning: %s and patchelf is missing; binaries/linux64 is left as pythonfmu ships it "
        "and loads in Python hosts only" % problem)
    return "stock", None


def _linux_binaries(model_identifier, library, loader, work):
    """Archive entries (name -> bytes) that replace pythonfmu's linux64 library."""
    kind, shim = loader
    folder = "binaries/linux64/"
    if kind == "shim":
        return {folder + model_identifier + ".so": shim.read_bytes(),
                folder + model_identifier + "_pythonfmu.so": library}
    if kind == "dt_needed":
        path = work / (model_identifier + ".so")
        path.write_bytes(library)
        lifetime.run(["patchelf", "--add-needed", libpython_soname(), str(path)], check=True,
                     capture_output=True, pass_fds=folders.held_fds(work))
        return {folder + model_identifier + ".so": path.read_bytes()}
    return {folder + model_identifier + ".so": library}


# -- one FMU -----------------------------------------------------------------------------------

def _pythonfmu_home():
    """The installed pythonfmu's package folder.  pythonfmu's builder takes its binaries and
    the modules it copies into every FMU from beside its own ``__file__`` (``HERE``); when a
    Python FMU was simulated in this process before pythonfmu was imported here, the imported
    pythonfmu is that FMU's copy (its ``resources/pythonfmu``: no binaries, and removed with
    the instance)."""
    from importlib import metadata

    import pythonfmu.builder
    try:
        home = Path(metadata.distribution("pythonfmu").locate_file("pythonfmu"))
    except metadata.PackageNotFoundError:
        home = None
    if home is None or not (home / "resources" / "binaries").is_dir():
        return Path(pythonfmu.builder.__file__).parent
    return home


@contextlib.contextmanager
def _installed_pythonfmu():
    """pythonfmu's builder with ``HERE`` at :func:`_pythonfmu_home` for the block."""
    import pythonfmu.builder
    saved = pythonfmu.builder.HERE
    pythonfmu.builder.HERE = _pythonfmu_home()
    try:
        yield
    finally:
        pythonfmu.builder.HERE = saved


def _build_one(name, out_dir, src_dir, loader, log, generated=None):
    from pythonfmu import __version__ as pythonfmu_version
    from pythonfmu.builder import FmuBuilder, get_model_class

    digest = source_hash(name, src_dir)
    package = "drift_" + digest
    with folders.temporary("driftfmu_%s_" % name) as tmp:
        work = Path(tmp)
        stage = work / "stage"
        stage.mkdir()
        script = _stage(name, src_dir, digest, stage)
        with _importable(stage, script.stem, package):
            slave = get_model_class(script)
            slave.version = __version__  # into the model description
            with _installed_pythonfmu():
                built = FmuBuilder.build_FMU(script, dest=work / "pythonfmu",
                                             project_files=[stage / package])
        with zipfile.ZipFile(built) as archive:
            entries = {info.filename: archive.read(info) for info in archive.infolist()
                       if not info.is_dir()}
        xml = complete_model_description(entries["modelDescription.xml"], slave, log)
        if generated is not None:  # SOURCE_DATE_EPOCH: the same sources, the same bytes
            xml, count = re.subn(rb'generationDateAndTime="[^"]*"',
                                 b'generationDateAndTime="%s"' % generated.encode(), xml,
                                 count=1)
            if count != 1:
                raise BuildError("%s: pythonfmu's model description has no "
                                 "generationDateAndTime to set from SOURCE_DATE_EPOCH" % name)
        entries["modelDescription.xml"] = xml
        model_identifier = ET.fromstring(xml).find("CoSimulation").get("modelIdentifier")
        # pythonfmu's stock win64 (and any other) binary is not shipped: no test here loads
        # it, and the loader shim that repairs pythonfmu's defects is Linux-only (docs/platforms.md)
        entries = {k: v for k, v in entries.items()
                   if not k.startswith("binaries/") or k.startswith("binaries/linux64/")}
        library = entries.pop("binaries/linux64/%s.so" % model_identifier)
        entries.update(_linux_binaries(model_identifier, library, loader, work))
        entries[BUILD_INFO] = json.dumps({
            "model_identifier": model_identifier,
            "guid": ET.fromstring(xml).get("guid"),
            "hash": digest,
            "package": package,
            "module": script.stem,
            "python_version": platform.python_version(),
            "libpython": libpython_soname(),
            "loader": loader[0],
            "pythonfmu_version": pythonfmu_version,
            # a driftfmu slave (slave_base.SHIM_VR): the loader shim hands it the stop time and
            # has it check a deserialised state
            "shim_vr": getattr(slave, "SHIM_VR", None) == 0x7FFFFFFF,
        }, indent=2, sort_keys=True).encode() + b"\n"
        from driftfmu.fmu_src import documentation, icons
        entries.update(icons.entries(name, 2))
        entries.update(documentation.entries(name, "python", 2, entries, slave))
        target = out_dir / ("%s.fmu" % name)
        _write_atomically(target, entries)
    log("built %s (code %s, loader %s, %d kB)" % (target, package, loader[0],
                                                   (target.stat().st_size + 512) // 1024))
    return target


def _write_atomically(target, entries):
    """Zip ``entries`` next to ``target``, validate, then move into place."""
    fd, partial = tempfile.mkstemp(prefix=".%s." % target.stem, suffix=".part",
                                   dir=target.parent)
    os.close(fd)
    try:
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for filename in sorted(entries):
                info = zipfile.ZipInfo(filename, date_time=(1980, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16
                info.compress_type = zipfile.ZIP_DEFLATED
                archive.writestr(info, entries[filename])
        from driftfmu.fmu_src.schemas import validate_fmu
        problems = validate_fmu(partial)
        if problems:
            raise BuildError("%s does not validate:\n  %s" % (target.name, "\n  ".join(problems)))
        os.chmod(partial, 0o644)
        os.replace(partial, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(partial)
        raise
