"""Internal (not a stable API; use driftfmu.build_fmus instead).

Build the native (C) twins of the three FMUs, FMI 2.0 and FMI 3.0, from the slaves' tables.

One source of truth: the slave classes' ``VARIABLES`` and ``DEPENDENCIES`` (fmu_src/<Name>.py),
the same tables pythonfmu registers for the Python FMUs.  For each model and FMI version this
module generates, at build time,

* ``config.h``: the struct ``ModelVariables`` (one field per row, in table order, ``double`` for
  Real and ``int`` for Integer), the value references ``vr_<name>`` (the table index, as in the
  Python FMU), the table ``MODEL_VARIABLES`` (name, type, causality, offset), the start values,
  the model name, version and instantiation token (the FMI 2 guid);
* ``modelDescription.xml``: FMI 2.0 through :func:`builder.complete_model_description` (units,
  min/max, ModelStructure exactly as for the Python FMU), FMI 3.0 written from the same table
  (valueReference the same numbers, Float64/Int32);
* FMI 3.0 ``sources/buildDescription.xml``; FMI 2.0 lists its sources in ``SourceFiles``.

Each FMU is also a source FMU: ``sources/`` holds every C file and header it is compiled from
(flat, so that ``cc -shared -fPIC -O2 -ffp-contract=off -Isources sources/*.c -lm`` builds it),
and prebuilt binaries for x86-64 and aarch64 Linux, Windows and macOS (:data:`PLATFORMS`):
gcc for x86-64 Linux, x86_64-w64-mingw32-gcc for x86-64 Windows (``-static-libgcc``: no DLLs
beyond the system's), zig (ziglang from PyPI) for the rest, all with ``-O2 -ffp-contract=off``
and no fast-math, so that IEEE 754 double arithmetic gives the bits of models/ (compilers for
ARM contract ``a*b+c`` into an FMA unless told not to).  A platform without a compiler here is
left out with one warning naming it.  ``documentation/binaries.txt`` lists every binary of the
FMU (and what built it), the FMI 3.0 ``sources/buildDescription.xml`` has one configuration per
prebuilt binary after the one for any compiler.  FMI 2.0 folder names: see
:data:`FMI2_FOLDERS` and docs/platforms.md.

Layout: ``<out>/fmi2/<Name>.fmu``, ``<out>/fmi2-aarch64/<Name>.fmu`` and
``<out>/fmi3/<Name>.fmu``; :data:`DEFAULT_OUT` is
``build/fmus/native``, beside the Python FMUs in ``build/fmus``.  Every FMU is validated with
fmpy before it is moved into place (atomically).
"""
import contextlib
import functools
import hashlib
import importlib
import os
import re
import shlex
import shutil
import stat
import subprocess
import sys
import time
import uuid
from pathlib import Path
from xml.etree import ElementTree as ET

from driftfmu import __version__
from driftfmu.fmu_src import builder, schemas
from driftfmu.simulations import folders, lifetime

NATIVE_DIR = Path(__file__).resolve().parent / "native"
MODELS_DIR = NATIVE_DIR / "models"
#: The models with a native twin: those of the builder with a C step logic
#: (fmu_src/native/models/<Name>_step.c), in the builder's order.
NAMES = tuple(n for n in builder.NAMES if (MODELS_DIR / ("%s_step.c" % n)).is_file())
DEFAULT_OUT = "build/fmus/native"
FMI_VERSIONS = (2, 3)
#: Flags of every compilation: no contraction into FMAs, no fast-math, C99.
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-fvisibility=hidden")
#: The platforms of the prebuilt binaries, by their FMI 3.0 name: (library suffix, the
#: compilers to try in order (the first installed builds it), the extra flags).  A compiler is
#: ("ENV", default command, extra flags): the environment variable overrides the command;
#: "zig" stands for the ziglang C cross-compiler (``python -m ziglang cc`` from PyPI, or ``zig``
#: on PATH) with the target triple of :data:`ZIG_TARGETS`.
PLATFORMS = {
    "x86_64-linux": (".so", (("CC", "cc", ("-shared", "-fPIC", "-s")), "zig")),
    "x86_64-windows": (".dll", (("MINGW_CC", "x86_64-w64-mingw32-gcc",
                                 ("-shared", "-s", "-static-libgcc",
                                  "-Wl,--no-insert-timestamp", "-Wl,--disable-auto-image-base",
                                  "-D__USE_MINGW_ANSI_STDIO=1")),
                                "zig")),
    "aarch64-linux": (".so", ("zig",)),
    "aarch64-windows": (".dll", ("zig",)),
    "x86_64-darwin": (".dylib", ("zig",)),
    "aarch64-darwin": (".dylib", ("zig",)),
}
#: zig's target triples: glibc 2.17 (the first glibc for aarch64, so any glibc-based aarch64
#: Linux has it), macOS 10.15 / 11.0 (11: the first Apple-silicon macOS), mingw-w64 (zig's
#: aarch64 Windows C library is the UCRT, part of Windows 10 and 11).
ZIG_TARGETS = {
    "x86_64-linux": "x86_64-linux-gnu.2.17", "aarch64-linux": "aarch64-linux-gnu.2.17",
    "x86_64-windows": "x86_64-windows-gnu", "aarch64-windows": "aarch64-windows-gnu",
    "x86_64-darwin": "x86_64-macos.10.15", "aarch64-darwin": "aarch64-macos.11.0",
}
#: zig's flags beyond CFLAGS: a shared library, stripped (no debug info in the FMU).
ZIG_FLAGS = ("-shared", "-s")
#: The FMI 2.0 folders.  FMI 2.0 names no architecture: fmpy (``fmpy.platform``) and FMI Library
#: (``fmi_platform`` in Config.cmake/fmiplatform.cmake) load ``binaries/linux64`` on every 64-bit
#: Linux, x86-64 or aarch64, ``win64`` on every 64-bit Windows and ``darwin64`` on every Mac.  So
#: the FMI 2.0 FMU holds the x86-64 Linux and Windows binaries and, in ``darwin64``, one
#: universal Mach-O library of both Mac architectures (the Mac loader picks its slice); its twin
#: for ARM (:data:`FMI2_ARM`, ``<out>/fmi2-aarch64``) holds the aarch64 Linux and Windows
#: binaries in ``linux64`` and ``win64``, where those importers look on an ARM machine.
FMI2_FOLDERS = {"x86_64-linux": "linux64", "x86_64-windows": "win64"}
FMI2_ARM_FOLDERS = {"aarch64-linux": "linux64", "aarch64-windows": "win64"}
FMI2_DARWIN = ("x86_64-darwin", "aarch64-darwin")
#: The folder (under the native FMUs' folder) of the FMI 2.0 FMUs for ARM Linux and Windows.
FMI2_ARM = "fmi2-aarch64"
#: The plain compiler call of the README, on the unpacked sources (Linux).
PLAIN_COMPILE = ("cc -shared -fPIC -std=c99 -O2 -ffp-contract=off -fno-fast-math "
                 "-Isources -o {identifier}.so sources/*.c -lm")


class NativeBuildError(RuntimeError):
    """A native FMU could not be generated, compiled or validated."""


def slave_class(name):
    """The slave class ``fmu_src/<name>.py`` (its VARIABLES and DEPENDENCIES)."""
    return getattr(importlib.import_module("driftfmu.fmu_src.%s" % name), name)


# -- config.h ---------------------------------------------------------------------------------

def _c_number(value, kind):
    if kind == "Integer":
        return str(int(value))
    text = repr(float(value))
    return text if any(c in text for c in ".en") else text + ".0"


def config_h(slave, token, fmi_version):
    """The generated header of one native FMU (see the module docstring)."""
    name = slave.__name__
    specs = slave.VARIABLES
    lines = [
        "/* config.h of the native %s FMU (FMI %d.0), generated by fmu_src/native_build.py from"
        % (name, fmi_version),
        " * %s.VARIABLES and .DEPENDENCIES: do not edit. */" % name,
        "#ifndef DRIFTFMU_CONFIG_H",
        "#define DRIFTFMU_CONFIG_H",
        "",
        "#include <stddef.h>",
        "",
        '#define MODEL_NAME "%s"' % name,
        "#define MODEL_IDENTIFIER %s" % name,
        '#define MODEL_VERSION "%s"' % __version__,
        '#define INSTANTIATION_TOKEN "%s"' % token,
        '#define MODEL_TOKEN_NAME "%s"' % ("guid" if fmi_version == 2 else "instantiationToken"),
        "#define FMI_VERSION %d" % fmi_version,
        "#define N_VARIABLES %d" % len(specs),
        "#define MODEL_HAS_FEEDTHROUGH %d" % (1 if slave.DEPENDENCIES else 0),
        '#define MODEL_LOGIC_HEADER "%s_step.h"' % name,
        "#include MODEL_LOGIC_HEADER",
        "",
        "typedef struct {",
    ]
    for spec in specs:
        ctype = "double" if spec["type"] == "Real" else "int"
        lines.append("    %s %s;  /* %s %s: %s */" % (ctype, spec["name"], spec["causality"],
                                                       spec["type"],
                                                       spec["description"].replace("*/", "")))
    lines += ["} ModelVariables;", "", "enum {"]
    lines += ["    vr_%s = %d," % (spec["name"], i) for i, spec in enumerate(specs)]
    lines += ["};", "", "static const VariableInfo MODEL_VARIABLES[N_VARIABLES] = {"]
    for spec in specs:
        lines.append('    {"%s", TYPE_%s, CAUSALITY_%s, offsetof(ModelVariables, %s)},'
                     % (spec["name"], spec["type"].upper(), spec["causality"].upper(),
                        spec["name"]))
    lines += ["};", "", "#define MODEL_START_VALUES { \\"]
    for spec in specs:
        start = spec["start"] if spec["start"] is not None else 0
        lines.append("    %s, /* %s */ \\" % (_c_number(start, spec["type"]), spec["name"]))
    lines += ["}", "", "#endif", ""]
    return "\n".join(lines)


# -- model descriptions -----------------------------------------------------------------------

#: The FMI 3.0 independent variable, after the table's variables (value reference
#: len(VARIABLES)).
TIME_VARIABLE = {"name": "time", "valueReference": None, "causality": "independent",
                 "variability": "continuous",
                 "description": "simulation time: start time plus the accepted steps [s]",
                 "unit": "s"}

LOG_CATEGORIES = (
    ("logStatusWarning", "Log messages with status warning."),
    ("logStatusDiscard", "Log messages with status discard."),
    ("logStatusError", "Log messages with status error (always sent to the host)."),
    ("logStatusFatal", "Log messages with status fatal."),
    ("logStatusOK", "Information messages (sent with debug logging on)."),
)


def model_description_text(slave):
    """The model description's description, as the Python FMU's: ``DESCRIPTION`` and the step
    rule (slave_base.STEP_RULE) where the slave has them, else its docstring's first line."""
    from driftfmu.fmu_src import slave_base
    text = getattr(slave, "DESCRIPTION", "")
    rule = getattr(slave_base, "STEP_RULE", "")
    if text:
        return "%s. %s" % (text, rule) if rule else text
    return (slave.__doc__ or slave.__name__).strip().splitlines()[0]


def _header_attributes(slave, fmi_version, token):
    description = model_description_text(slave)
    attrib = {"fmiVersion": "%d.0" % fmi_version, "modelName": slave.__name__}
    attrib["guid" if fmi_version == 2 else "instantiationToken"] = token
    attrib.update({"description": description, "author": "driftfmu contributors",
                   "license": "MIT", "version": __version__,
                   "generationTool": "driftfmu %s (native C)" % __version__,
                   "variableNamingConvention": "structured"})
    return attrib


def _default_experiment(slave):
    d = slave.default_experiment
    return {"startTime": repr(float(d.start_time)), "stopTime": repr(float(d.stop_time)),
            "stepSize": repr(float(d.step_size))}


def fmi2_model_description(slave, token, source_files, log=print):
    """FMI 2.0 modelDescription.xml of the native FMU: the skeleton here, completed by
    :func:`builder.complete_model_description` exactly as the Python FMU's."""
    root = ET.Element("fmiModelDescription", _header_attributes(slave, 2, token))
    cosim = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": slave.__name__, "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true"})
    files = ET.SubElement(cosim, "SourceFiles")
    for f in source_files:
        ET.SubElement(files, "File", name=f)
    cats = ET.SubElement(root, "LogCategories")
    for n, d in LOG_CATEGORIES:
        ET.SubElement(cats, "Category", name=n, description=d)
    ET.SubElement(root, "DefaultExperiment", _default_experiment(slave))
    variables = ET.SubElement(root, "ModelVariables")
    for vr, spec in enumerate(slave.VARIABLES):
        sv = ET.SubElement(variables, "ScalarVariable", {
            "name": spec["name"], "valueReference": str(vr), "description": spec["description"],
            "causality": spec["causality"], "variability": spec["variability"]})
        element = ET.SubElement(sv, spec["type"])
        if spec["causality"] != "output" and spec["start"] is not None:
            element.set("start", builder._number(spec["start"], spec["type"]))
    ET.SubElement(root, "ModelStructure")
    xml = ET.tostring(root, encoding="utf-8")
    return builder.complete_model_description(xml, slave, log)


def fmi3_model_description(slave, token, log=print):
    """FMI 3.0 modelDescription.xml from the same table: Real -> Float64, Integer -> Int32,
    valueReference = table index, ModelStructure from DEPENDENCIES; plus the independent
    variable ``time`` (value reference ``len(VARIABLES)``, which the FMI 2.0 FMUs do not have)."""
    root = ET.Element("fmiModelDescription", _header_attributes(slave, 3, token))
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": slave.__name__, "needsExecutionTool": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
        "canHandleVariableCommunicationStepSize":
            str(bool(getattr(slave, "CAN_HANDLE_VARIABLE_STEP", True))).lower(),
        "hasEventMode": "false", "providesIntermediateUpdate": "false",
        "canReturnEarlyAfterIntermediateUpdate": "false"})
    units = sorted({s["unit"] for s in slave.VARIABLES if s["unit"] and s["type"] == "Real"}
                   | {"s"})
    if units:
        definitions = ET.SubElement(root, "UnitDefinitions")
        definitions.extend(builder._unit_element(u, log) for u in units)
    cats = ET.SubElement(root, "LogCategories")
    for n, d in LOG_CATEGORIES:
        ET.SubElement(cats, "Category", name=n, description=d)
    ET.SubElement(root, "DefaultExperiment", _default_experiment(slave))
    variables = ET.SubElement(root, "ModelVariables")
    index = {s["name"]: vr for vr, s in enumerate(slave.VARIABLES)}
    for vr, spec in enumerate(slave.VARIABLES):
        tag = "Float64" if spec["type"] == "Real" else "Int32"
        attrib = {"name": spec["name"], "valueReference": str(vr),
                  "description": spec["description"], "causality": spec["causality"],
                  "variability": spec["variability"]}
        if spec["unit"] and tag == "Float64":
            attrib["unit"] = spec["unit"]
        for key in ("min", "max"):
            if spec.get(key) is not None:
                attrib[key] = builder._number(spec[key], spec["type"])
        if spec["causality"] != "output" and spec["start"] is not None:
            attrib["start"] = builder._number(spec["start"], spec["type"])
        ET.SubElement(variables, tag, attrib)
    # FMI 3.0 wants exactly one independent variable; its value reference follows the table's
    ET.SubElement(variables, "Float64", dict(TIME_VARIABLE, name="time",
                                             valueReference=str(len(slave.VARIABLES))))
    structure = ET.SubElement(root, "ModelStructure")
    exact = [vr for vr, s in enumerate(slave.VARIABLES) if s["causality"] == "parameter"]
    outputs = [(vr, s) for vr, s in enumerate(slave.VARIABLES) if s["causality"] == "output"]
    for vr, s in outputs:
        deps = sorted(index[i] for i in slave.DEPENDENCIES.get(s["name"], ()))
        ET.SubElement(structure, "Output", valueReference=str(vr),
                      dependencies=" ".join(map(str, deps)))
    for vr, s in outputs:
        deps = sorted(set(index[i] for i in slave.DEPENDENCIES.get(s["name"], ())) | set(exact))
        ET.SubElement(structure, "InitialUnknown", valueReference=str(vr),
                      dependencies=" ".join(map(str, deps)))
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def build_description(name, source_files, built=None):
    """FMI 3.0 sources/buildDescription.xml: first the configuration for any C99 compiler (the
    flags of CFLAGS; an importer that builds the FMU takes the first), then one per prebuilt
    binary (``platform``), naming the compiler and the flags it was built with.

    ``built`` maps a platform of :data:`PLATFORMS` to its compiler's label."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    options = " ".join(f for f in CFLAGS if f != "-std=c99")
    configs = [(None, "any C99 compiler: no contraction into FMAs, no fast-math", options, True)]
    for platform, label in sorted((built or {}).items()):
        command = compiler_flags(platform, label)
        configs.append((platform, "the prebuilt binaries/%s/%s%s: %s %s"
                        % (platform, name, PLATFORMS[platform][0], label, command),
                        options, platform.endswith("-linux") or "mingw32" in label))
    for platform, description, opts, libm in configs:
        attrib = {"modelIdentifier": name, "description": description}
        if platform:
            attrib["platform"] = platform
        config = ET.SubElement(root, "BuildConfiguration", attrib)
        files = ET.SubElement(config, "SourceFileSet", language="C99", compilerOptions=opts)
        for f in source_files:
            ET.SubElement(files, "SourceFile", name=f)
        ET.SubElement(files, "IncludeDirectory", name=".")
        if libm:
            ET.SubElement(config, "Library", name="m", description="the C maths library (sqrt, "
                          "floor, frexp, ldexp: exact or correctly rounded)")
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def compiler_flags(platform, label):
    """The flags (beyond CFLAGS) the prebuilt binary of ``platform`` gets from the compiler
    ``label`` (for the build description)."""
    if label.startswith("zig"):
        return " ".join(CFLAGS + ZIG_FLAGS)
    for choice in PLATFORMS[platform][1]:
        if choice != "zig":
            return " ".join(CFLAGS + choice[2])
    return " ".join(CFLAGS)


# -- sources ----------------------------------------------------------------------------------

def fmi_headers(fmi_version):
    """The standard's headers (2-clause BSD, as fmpy ships them) for ``fmi_version``."""
    folder = builder._fmi2_headers()
    if fmi_version == 2:
        names = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
    else:
        names = ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")
    return [folder / n for n in names]


def _generate():
    """fmu_src/native/models/generate.py: the C units of each FMU and the generated parameter
    table of models.parameters."""
    return importlib.import_module("driftfmu.fmu_src.native.models.generate")


def model_sources(name, fmi_version):
    """The files (path) a native FMU is compiled from, the generated headers aside: the plumbing
    of its FMI version, the model's step logic and the models/ units it needs (with every
    models/ header), the FMI headers."""
    plumbing = [NATIVE_DIR / ("fmi%dFunctions.c" % fmi_version), NATIVE_DIR / "cosimulation.c",
                NATIVE_DIR / "cosimulation.h", NATIVE_DIR / "model.h",
                NATIVE_DIR / "state_handles.h"]
    units = [MODELS_DIR / u for u in _generate().UNITS[name]]
    headers = sorted(p for p in MODELS_DIR.glob("*.h")
                     if not (p.name.endswith("_step.h") and p.name != name + "_step.h"))
    return plumbing + units + headers + fmi_headers(fmi_version)


def generated_headers(name, fmi_version):
    """The headers generated at build time: name -> text."""
    return {"config.h": config_h(slave_class(name), token(name, fmi_version), fmi_version),
            "parameters_table.h": _generate().parameters_table()}


def source_hash(name, fmi_version):
    """SHA-256 over the sources and the table a native FMU is made from (its token derives
    from it, so a change of either makes another FMU)."""
    digest = hashlib.sha256()
    for path in model_sources(name, fmi_version):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update(_generate().parameters_table().encode())
    digest.update(repr(slave_class(name).VARIABLES).encode())
    digest.update(repr(sorted(slave_class(name).DEPENDENCIES.items())).encode())
    digest.update(("%s %d" % (__version__, fmi_version)).encode())
    return digest.hexdigest()


def token(name, fmi_version):
    """The FMU's guid / instantiationToken: a UUID derived from :func:`source_hash`."""
    return "{%s}" % uuid.uuid5(uuid.NAMESPACE_URL, "driftfmu:%s:%s"
                               % (name, source_hash(name, fmi_version)))


def stage_sources(name, fmi_version, folder):
    """Write the flat sources/ of a native FMU into ``folder``; return the .c file names."""
    folder.mkdir(parents=True, exist_ok=True)
    for path in model_sources(name, fmi_version):
        shutil.copyfile(path, folder / path.name)
    for filename, text in generated_headers(name, fmi_version).items():
        (folder / filename).write_text(text)
    return sorted(p.name for p in folder.iterdir() if p.suffix == ".c")


# -- compiling --------------------------------------------------------------------------------

def zig_command():
    """The zig C compiler (list), or None: ``DRIFTFMU_ZIG`` if set, else ziglang from PyPI
    (``python -m ziglang cc``), else ``zig cc`` from PATH."""
    import importlib.util
    if os.environ.get("DRIFTFMU_ZIG"):
        command = shlex.split(os.environ["DRIFTFMU_ZIG"])
        return command if shutil.which(command[0]) else None
    if importlib.util.find_spec("ziglang") is not None:
        return [sys.executable, "-m", "ziglang", "cc"]
    return ["zig", "cc"] if shutil.which("zig") else None


def compiler(platform):
    """``(command, extra flags, label)`` of the first installed compiler of ``platform``, or
    None when none is."""
    for choice in PLATFORMS[platform][1]:
        if choice == "zig":
            command = zig_command()
            if command is not None:
                return (command + ["-target", ZIG_TARGETS[platform]], ZIG_FLAGS,
                        "zig cc -target %s" % ZIG_TARGETS[platform])
            continue
        env, default, extra = choice
        command = shlex.split(os.environ.get(env, default))
        if command and shutil.which(command[0]):
            return command, extra, os.path.basename(command[0])
        if os.environ.get(env) is not None:  # a compiler named but not installed: no fallback
            return None
    return None


def _libraries(platform, command):
    """``-lm`` where the C maths library is a library of its own (Linux; mingw-w64 as before)."""
    return ["-lm"] if platform.endswith("-linux") or "mingw32" in " ".join(command) else []


def compiler_problem(platform):
    """Why ``platform`` (FMI 3.0 name; ``linux64``/``win64`` accepted) has no compiler, naming
    what was looked for (``$CC`` or ``$MINGW_CC`` when set, zig) and how to get one; None when
    it has one."""
    platform = {"linux64": "x86_64-linux", "win64": "x86_64-windows"}.get(platform, platform)
    if compiler(platform) is not None:
        return None
    looked, envs = [], []
    for choice in PLATFORMS[platform][1]:
        if choice == "zig":
            looked.append("zig is not installed")
            continue
        env, default, _ = choice
        envs.append(env)
        given = os.environ.get(env)
        looked.append("%s=%r is not an installed program" % (env, given) if given is not None
                      else "%s is not installed" % default)
    allowed = ("%s naming an installed C compiler, or %s" % (envs[0], _install_hint(platform))
               if envs else _install_hint(platform))
    return "no %s compiler: %s; allowed: %s" % (platform, ", ".join(looked), allowed)


def compile_library(platform, sources_dir, c_files, target):
    """Compile ``c_files`` of ``sources_dir`` into the shared library ``target``; return
    ``(target, label of the compiler)``."""
    chosen = compiler(platform)
    if chosen is None:
        raise NativeBuildError(compiler_problem(platform))
    command, extra, label = chosen
    target.parent.mkdir(parents=True, exist_ok=True)
    if platform.endswith("-darwin"):  # the library's own name, not the build folder's path
        extra = tuple(extra) + ("-Wl,-install_name,@rpath/%s" % target.name,)
    args = (command + list(CFLAGS) + list(extra) + ["-I%s" % sources_dir, "-o", str(target)]
            + [str(sources_dir / f) for f in c_files] + _libraries(platform, command))
    # the work folder's lock held by the compiler too (folders.held_fds); the compiler's
    # temporary files beside its output, in the build's work folder
    result = lifetime.run(args, capture_output=True, text=True, cwd=target.parent,
                          work=target.parent, pass_fds=folders.held_fds(target.parent))
    if result.returncode != 0:  # the first line says who failed and why (the command's one line)
        lines = [line.strip() for line in result.stderr.splitlines() if line.strip()]
        why = next((line for line in lines if "error" in line.lower()),
                   lines[0] if lines else "no message")
        raise NativeBuildError("compiling %s for %s failed: %s exited with status %d: %s\n%s\n%s"
                               % (target.name, platform, label, result.returncode, why,
                                  " ".join(args), result.stderr.strip()))
    return target, label


#: How to get zig, the compiler of every platform: the extra that installs ziglang.
ZIG_EXTRA = ('the extra driftfmu[native] (pip install "driftfmu[native]": ziglang, a C '
             'compiler for every platform)')


def _install_hint(platform):
    if platform == "x86_64-linux":
        return "Debian: apt-get install gcc, or %s" % ZIG_EXTRA
    if platform == "x86_64-windows":
        return "Debian: apt-get install gcc-mingw-w64-x86-64, or %s" % ZIG_EXTRA
    return ZIG_EXTRA


# -- one FMU ----------------------------------------------------------------------------------

def _compile_all(name, fmi_version, sources, c_files, work, platforms, cache=None):
    """{platform: (library bytes, compiler label)} of ``platforms``, compiled side by side;
    with ``cache`` (a folder), a library compiled before from the same sources by the same
    compiler command is taken from there (see :func:`build_native_fmus`)."""
    def one(platform):
        target = work / platform / (name + PLATFORMS[platform][0])
        key = _cache_key(platform, sources, c_files) if cache is not None else None
        hit = Path(cache) / key if key else None
        data = _read_cache_entry(hit) if hit is not None else None
        if data is not None:
            with contextlib.suppress(OSError):
                os.utime(hit, follow_symlinks=False)  # recently used (pruned by age)
            return platform, (data, compiler(platform)[2])
        path, label = compile_library(platform, sources, c_files, target)
        data = path.read_bytes()
        if hit is not None:  # a cache that cannot be written (read-only, full) is skipped
            part = hit.with_name("%s.%d.part" % (key, os.getpid()))
            try:
                fd = os.open(part, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
                with os.fdopen(fd, "wb") as fh:
                    fh.write(cache_entry(data))
                os.replace(part, hit)  # whole or absent, also for a build running beside
            except OSError:
                with contextlib.suppress(OSError):
                    part.unlink()
        return platform, (data, label)

    from concurrent.futures import ThreadPoolExecutor
    with ThreadPoolExecutor(max_workers=max(1, min(len(platforms), os.cpu_count() or 1))) \
            as pool:
        return dict(pool.map(one, platforms))


def _layouts(name, fmi_version, built):
    """The FMUs made of the compiled libraries ``built``: [(variant, {archive path: (bytes,
    what it is)})], variant ``""`` for the FMU of ``fmi<v>/`` and :data:`FMI2_ARM` for the FMI
    2.0 FMU for ARM Linux and Windows."""
    def entry(platform):
        data, label = built[platform]
        return data, "%s, %s" % (platform, label)

    if fmi_version == 3:
        return [("", {"binaries/%s/%s%s" % (p, name, PLATFORMS[p][0]): entry(p)
                      for p in built})]
    darwin = [p for p in FMI2_DARWIN if p in built]
    common = {}
    if darwin:
        from driftfmu.fmu_src import binaries
        data = binaries.universal([built[p][0] for p in darwin])
        common["binaries/darwin64/%s.dylib" % name] = (
            data, "universal Mach-O: %s" % "; ".join(entry(p)[1] for p in darwin))
    layouts = []
    for variant, by_platform in (("", FMI2_FOLDERS), (FMI2_ARM, FMI2_ARM_FOLDERS)):
        files = {"binaries/%s/%s%s" % (folder, name, PLATFORMS[p][0]): entry(p)
                 for p, folder in by_platform.items() if p in built}
        if files:
            files.update(common)
            layouts.append((variant, files))
    return layouts


def binaries_text(name, fmi_version, files, missing):
    """documentation/binaries.txt: every binary of the FMU, where it runs, what built it."""
    lines = ["%s (driftfmu %s, native C, FMI %d.0): the prebuilt binaries in this FMU"
             % (name, __version__, fmi_version), ""]
    for path in sorted(files):
        data, what = files[path]
        lines.append("%s  (%d bytes, sha256 %s)" % (path, len(data),
                                                    hashlib.sha256(data).hexdigest()[:16]))
        lines.append("    %s" % what)
    lines += ["", "Every binary: C99, %s (IEEE 754 double arithmetic without FMA contraction "
              "gives the bits of driftfmu's models/)." % " ".join(CFLAGS[1:4])]
    if missing:
        lines.append("Not built on this machine (no compiler for them): %s." % ", ".join(missing))
    # (only the FMI 3.0 FMUs carry sources/buildDescription.xml; FMI 2.0 lists its sources in
    # the model description)
    lines += ["For any other platform, compile sources/ (see %s)." % (
        "sources/buildDescription.xml" if fmi_version == 3
        else "the SourceFiles of modelDescription.xml"), ""]
    return "\n".join(lines)


#: Days an entry of a library cache (:func:`user_cache`) is kept unused before
#: :func:`prune_cache` removes it.
CACHE_DAYS = 30


def user_cache():
    """The folder of compiled libraries that ``driftfmu build`` keeps from build to build:
    ``DRIFTFMU_CACHE`` if set, else ``driftfmu/native-libraries`` in the user's cache folder
    (``$XDG_CACHE_HOME`` or ``~/.cache``; ``~/Library/Caches`` on macOS; ``%LOCALAPPDATA%`` on
    Windows)."""
    if os.environ.get("DRIFTFMU_CACHE"):
        return Path(os.environ["DRIFTFMU_CACHE"])
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or os.path.expanduser("~/AppData/Local")
    elif sys.platform == "darwin":
        base = os.path.expanduser("~/Library/Caches")
    else:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")
    return Path(base) / "driftfmu" / "native-libraries"


def open_cache(folder):
    """The library cache ``folder`` (a path) once checked, or None when it cannot be made (a
    cache that cannot be written is skipped).  The folders of its path that are missing are
    made with mode 0700; one that another user could change (owned by another user, writable
    by others, reached through a folder or a symbolic link they control:
    :func:`driftfmu.simulations.trust.path_problem`) is refused in one line (UsageError): what
    it holds goes into FMUs that run on this machine and elsewhere."""
    from driftfmu.simulations import trust
    from driftfmu.simulations.errors import UsageError
    folder = Path(os.path.abspath(folder))
    missing = []
    top = folder
    while not os.path.lexists(top) and top != top.parent:
        missing.append(top)
        top = top.parent
    try:
        for path in reversed(missing):
            with contextlib.suppress(FileExistsError):
                os.mkdir(path, 0o700)
    except OSError:
        return None
    problem = trust.path_problem(folder)
    if problem:
        raise UsageError("the library cache %s cannot be trusted: %s; allowed: a folder that "
                         "no other user can change (DRIFTFMU_CACHE names another; driftfmu "
                         "build --no-cache uses none)" % (folder, problem))
    return folder


def prune_cache(folder, days=CACHE_DAYS):
    """Remove the entries of the library cache ``folder`` not used (read or written) for
    ``days`` days, and parts of writes that were cut short an hour ago or more.  Only files
    named as the cache names them (``<platform>-<sha256>``, ``<that>.<pid>.part``) are
    touched: a cache folder set to one that holds other files loses none of them."""
    entry_name = re.compile(r"(%s)-[0-9a-f]{64}(\.[0-9]+\.part)?\Z"
                            % "|".join(map(re.escape, PLATFORMS)))
    now = time.time()
    for entry in Path(folder).glob("*"):
        match = entry_name.match(entry.name)
        if match is None:
            continue
        with contextlib.suppress(OSError):
            age = now - entry.stat().st_mtime
            if age > days * 86400 or (match.group(2) and age > 3600):
                entry.unlink()


#: First line of a library cache entry; the second is the SHA-256 of the library that follows.
CACHE_MAGIC = b"driftfmu native-library cache 1\n"


def cache_entry(data):
    """The bytes of a library cache entry holding the library ``data``: :data:`CACHE_MAGIC`,
    the library's SHA-256 in hex on a line, the library."""
    return CACHE_MAGIC + hashlib.sha256(data).hexdigest().encode() + b"\n" + data


def _read_cache_entry(path):
    """The library in the cache entry ``path``, or None when there is none, when it is not a
    regular file of this user's (or root's) that no one else can write
    (:func:`driftfmu.simulations.trust.others_can_write`; not a symbolic link), or when it is
    not whole (a file damaged on disk, cut short, or of another format): then it is compiled
    again and the entry replaced, never shipped in an FMU."""
    from driftfmu.simulations import trust
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:  # not there (or removed meanwhile), or a symbolic link
        return None
    st = os.fstat(fd)  # (before fdopen, which raises IsADirectoryError for a folder)
    if not stat.S_ISREG(st.st_mode) or trust.others_can_write(st):
        os.close(fd)
        return None
    with os.fdopen(fd, "rb") as fh:
        try:
            raw = fh.read()
        except OSError:
            return None
    if not raw.startswith(CACHE_MAGIC):
        return None
    digest, newline, data = raw[len(CACHE_MAGIC):].partition(b"\n")
    return data if newline and hashlib.sha256(data).hexdigest().encode() == digest else None


def _cache_key(platform, sources, c_files):
    """Hash of what a library's bytes depend on: the platform, the compiler command, its
    version and flags, the C files in order and every staged source's name and bytes (the
    build's folders are not in the library, tests/test_platforms.py).  Where the compiler is
    installed is not in it (:func:`_command_identity`, :func:`_version_identity`)."""
    command, extra, _ = compiler(platform)
    h = hashlib.sha256(repr((platform, _command_identity(command),
                             _version_identity(compiler_version(tuple(command))), tuple(extra),
                             CFLAGS, list(c_files))).encode())
    for p in sorted(Path(sources).iterdir()):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    return "%s-%s" % (platform, h.hexdigest())


def _command_identity(command):
    """The compiler command as the cache key names it: ziglang run by this Python (``python -m
    ziglang``) is named by ziglang's version instead of the interpreter's path, so environments
    with the same ziglang (a new virtual environment) share the cache."""
    if list(command[:3]) == [sys.executable, "-m", "ziglang"]:
        from importlib.metadata import PackageNotFoundError, version
        try:
            return ["ziglang==%s" % version("ziglang")] + list(command[3:])
        except PackageNotFoundError:  # ziglang without its metadata: the path, as given
            pass
    return list(command)


def _version_identity(text):
    """What ``--version`` printed, without clang's ``InstalledDir:`` line (where the compiler
    is installed, not which compiler it is: it names the virtual environment of ziglang)."""
    return "\n".join(line for line in text.splitlines() if not line.startswith("InstalledDir:"))


@functools.lru_cache(maxsize=None)
def compiler_version(command):
    """What ``command --version`` prints (its output; empty if it fails), once per command: a
    library cache kept from run to run must not serve what an older compiler made."""
    try:  # in a folder of its own: zig cc -target ... --version leaves an empty a.o behind
        with folders.temporary("driftfmu_cc_") as work:
            done = lifetime.run(list(command) + ["--version"], capture_output=True, text=True,
                                timeout=60, cwd=work, pass_fds=folders.held_fds(work))
    except (OSError, subprocess.SubprocessError):
        return ""
    return done.stdout if done.returncode == 0 else ""


def _build_one(name, fmi_version, out_dir, platforms, missing, log, cache=None):
    slave = slave_class(name)
    tok = token(name, fmi_version)
    targets = []
    with folders.temporary("driftfmu_native_%s_" % name) as tmp:
        work = Path(tmp)
        sources = work / "sources"
        c_files = stage_sources(name, fmi_version, sources)
        base = {"sources/" + p.name: p.read_bytes() for p in sorted(sources.iterdir())}
        log("compiling %s (native C, FMI %d.0) for %s ..."
            % (name, fmi_version, ", ".join(platforms)))
        built = _compile_all(name, fmi_version, sources, c_files, work, platforms, cache)
        if fmi_version == 2:
            base["modelDescription.xml"] = fmi2_model_description(slave, tok, c_files, log)
        else:
            base["modelDescription.xml"] = fmi3_model_description(slave, tok, log)
            base["sources/buildDescription.xml"] = build_description(
                name, c_files, {p: label for p, (_, label) in built.items()})
        for variant, files in _layouts(name, fmi_version, built):
            entries = dict(base)
            entries.update({path: data for path, (data, _) in files.items()})
            entries["documentation/binaries.txt"] = binaries_text(
                name, fmi_version, files, missing).encode()
            from driftfmu.fmu_src import documentation, icons
            entries.update(icons.entries(name, fmi_version))
            entries.update(documentation.entries(name, "native", fmi_version, entries, slave))
            folder = out_dir / (variant or "fmi%d" % fmi_version)
            folder.mkdir(parents=True, exist_ok=True)
            target = folder / ("%s.fmu" % name)
            builder._write_atomically(target, entries)
            shipped = sorted({p.split("/")[1] for p in files})
            log("built %s (native C, FMI %d.0, %d kB: %s)"
                % (target, fmi_version, (target.stat().st_size + 512) // 1024,
                   ", ".join(shipped)))
            targets.append(target)
    return targets


def available_platforms(log=print):
    """The platforms with an installed compiler (x86-64 Linux required); one warning names
    the missing ones and how to get them."""
    out = [p for p in PLATFORMS if compiler(p) is not None]
    if "x86_64-linux" not in out:
        raise NativeBuildError(compiler_problem("x86_64-linux"))
    missing = [p for p in PLATFORMS if p not in out]
    if missing:
        how = {}
        for p in missing:
            how.setdefault(_install_hint(p), []).append(p)
        log("warning: no compiler for %s here, so the native FMUs carry no binary for %s; to "
            "build %s: %s" % (", ".join(missing), "them" if len(missing) > 1 else "it",
                              "them" if len(missing) > 1 else "it",
                              "; ".join("%s: %s" % (", ".join(ps), hint)
                                        for hint, ps in how.items())))
    return out


def build_native_fmus(out_dir=DEFAULT_OUT, names=NAMES, fmi_versions=FMI_VERSIONS,
                      platforms=None, log=print, cache=None):
    """Build, validate and move into place ``<out_dir>/fmi<v>/<Name>.fmu`` (and, with the
    aarch64 Linux or Windows binary, the FMI 2.0 FMUs for ARM ``<out_dir>/fmi2-aarch64/``).

    Parameters
    ----------
    out_dir : path-like
        Folder of the native FMUs (default ``build/fmus/native``).
    names : sequence of str
        Models (slave names).
    fmi_versions : sequence of int
        2 and/or 3.
    platforms : sequence of str, optional
        Keys of :data:`PLATFORMS`; default every platform whose compiler is installed.
    log : callable
        Receives one line per FMU (with its size) and warnings.
    cache : path-like, optional
        A folder of compiled libraries: one compiled before from the same staged sources with
        the same compiler command is reused instead of compiled again (the test suite builds
        the FMUs for its hosts first and then, reusing those, every platform's); its entries
        unused for :data:`CACHE_DAYS` days are removed first (:func:`prune_cache`).  Each
        entry carries its library's SHA-256: one that does not match (damaged on disk, cut
        short) is compiled again and replaced, never shipped; so is one that is not this
        user's (or root's), or that others can write.  A folder that another user could
        change is refused (UsageError, :func:`open_cache`).  Default: none.

    Returns
    -------
    dict
        ``{fmi_version: {name: path}}`` (the FMUs of ``fmi<v>/``).
    """
    out_dir = Path(out_dir)
    if platforms is None:
        platforms = available_platforms(log)
    unknown = [p for p in platforms if p not in PLATFORMS]
    if unknown:
        raise NativeBuildError("platforms %s are not known; allowed: %s"
                               % (", ".join(unknown), ", ".join(PLATFORMS)))
    missing = [p for p in PLATFORMS if p not in platforms]
    if cache is not None:
        cache = open_cache(cache)
    if cache is not None:
        prune_cache(cache)
    from concurrent.futures import ThreadPoolExecutor
    schemas.prime()  # before the threads that validate (fmu_src/schemas.py)
    jobs = [(n, v) for v in fmi_versions for n in names]
    # two FMUs at a time (each compiles its platforms side by side): compilers are processes
    with ThreadPoolExecutor(max_workers=2) as pool:
        paths = list(pool.map(lambda job: _build_one(job[0], job[1], out_dir, platforms,
                                                      missing, log, cache), jobs))
    result = {v: {} for v in fmi_versions}
    for (n, v), targets in zip(jobs, paths):
        result[v][n] = targets[0]
    return result


def native_fmu_paths(fmu_dir, fmi_version=2):
    """Paths of the three native FMUs of ``fmi_version`` under ``<fmu_dir>/native``; built
    first when any is missing, from the libraries ``driftfmu build --native`` keeps
    (:func:`user_cache`) where they were compiled before."""
    folder = Path(fmu_dir) / "native"
    paths = {n: folder / ("fmi%d" % fmi_version) / ("%s.fmu" % n) for n in NAMES}
    if not all(p.exists() for p in paths.values()):
        builder.check_fmu_folder(fmu_dir, [p.relative_to(fmu_dir).as_posix()
                                           for p in paths.values() if not p.exists()],
                                 native=True)
        build_native_fmus(folder, fmi_versions=(fmi_version,), cache=user_cache())
    return paths
