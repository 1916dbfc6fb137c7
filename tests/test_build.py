"""fmu_src/builder.py: the FMUs validate clean and run in C hosts and Python hosts of any version.

The hosts in tests/hosts print ``VALUE <x>`` after a few steps and ``LOG <status> <category>:
<message>`` for every message; exit code 2 means fmi2Instantiate returned NULL.
"""
import functools
import glob
import importlib
import json
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import textwrap
import time
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import fmpy
import pytest
from fmpy.validation import validate_fmu

from driftfmu.fmu_src import builder
from driftfmu.fmu_src.builder import (NAMES, BuildError, build_fmus, rewrite_imports, source_hash,
                             unit_definition)
from waiting import BOUND

HOSTS = Path(__file__).parent / "hosts"
LIBDIR = sysconfig.get_config_var("LIBDIR")
SONAME = builder.libpython_soname()
STEPS = 10

integration = pytest.mark.integration


# -- helpers -----------------------------------------------------------------------------------

def clean_env(**extra):
    """The environment without anything that would steer the loader or Python, plus ``extra``."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("LD_PRELOAD", "LD_LIBRARY_PATH", "DRIFTFMU_LIBPYTHON", "PYTHONHOME",
                        "PYTHONPATH")}
    env.update(extra)
    return env


def host_args(fmu, tmp_path):
    """Extract ``fmu``; the hosts' arguments reading its first output after STEPS steps."""
    unzipped = tmp_path / fmu.stem
    fmpy.extract(str(fmu), unzipdir=str(unzipped))
    md = fmpy.read_model_description(str(unzipped))
    output = next(v for v in md.modelVariables if v.causality == "output")
    return [str(unzipped), md.coSimulation.modelIdentifier, md.guid, str(output.valueReference),
            str(STEPS), repr(float(md.defaultExperiment.stepSize))]


def run(command, env):
    result = subprocess.run(command, env=env, capture_output=True, text=True, timeout=BOUND)
    return result.returncode, result.stdout + result.stderr


def value_of(output):
    """The VALUE a host printed; fails with the host's output if there is none."""
    lines = [line for line in output.splitlines() if line.startswith("VALUE ")]
    assert lines, output
    return float(lines[-1].split()[1])


def errors_in(output):
    return [line for line in output.splitlines()
            if line.startswith("LOG ") and int(line.split()[1]) >= 3]


@functools.lru_cache(maxsize=None)
def other_pythons():
    """Interpreters of other Python 3 versions (>= 3.8) on this machine: {(3, minor): path}."""
    pyenv_root = os.environ.get("PYENV_ROOT", os.path.expanduser("~/.pyenv"))
    candidates = sorted(glob.glob(os.path.join(pyenv_root, "versions", "*", "bin", "python3")))
    candidates += [shutil.which("python3.%d" % minor) for minor in range(8, 14)]
    found = {}
    for path in filter(None, candidates):
        result = subprocess.run([path, "-c", "import sys; print(*sys.version_info[:2])"],
                                capture_output=True, text=True, env=clean_env())
        if result.returncode != 0:
            continue
        version = tuple(map(int, result.stdout.split()))
        if version >= (3, 8) and version != sys.version_info[:2]:
            found.setdefault(version, path)
    return found


def libpython_of(python):
    """Full path of the shared libpython of interpreter ``python``, or None."""
    code = ("import sysconfig as s; print(s.get_config_var('LIBDIR'), "
            "s.get_config_var('INSTSONAME'))")
    libdir, soname = subprocess.run([python, "-c", code], capture_output=True, text=True,
                                    env=clean_env()).stdout.split()
    path = os.path.join(libdir, soname)
    return path if ".so" in soname and os.path.exists(path) else None


def on_default_loader_path(soname):
    ldconfig = shutil.which("ldconfig") or "/sbin/ldconfig"
    result = subprocess.run([ldconfig, "-p"], capture_output=True, text=True)
    return any(line.split()[0] == soname for line in result.stdout.splitlines()[1:] if line)


def without_system_libpython(command):
    """``command`` run where every libpython3 the loader could find is /dev/null, or None.

    Uses a private mount namespace (``unshare``); None where that is not allowed.
    """
    unshare = shutil.which("unshare")
    if not unshare:
        return None
    flags = ["-m"] if os.geteuid() == 0 else ["-r", "-m"]
    if subprocess.run([unshare, *flags, "true"], capture_output=True).returncode != 0:
        return None
    folders = ["/lib", "/lib64", "/usr/lib", "/usr/lib64", "/usr/local/lib",
               "/lib/x86_64-linux-gnu", "/usr/lib/x86_64-linux-gnu"]
    files = {f for d in folders for f in glob.glob(os.path.join(d, "libpython3*.so*"))}
    ldconfig = shutil.which("ldconfig") or "/sbin/ldconfig"
    listing = subprocess.run([ldconfig, "-p"], capture_output=True, text=True).stdout
    files |= {line.split(" => ")[-1] for line in listing.splitlines() if "libpython3" in line}
    script = "set -e; %s exec %s" % (
        "".join("mount --bind /dev/null %s; " % shlex.quote(f) for f in sorted(files)),
        " ".join(map(shlex.quote, command)))
    return [unshare, *flags, "sh", "-c", script]


# -- a toy project following the slave contract ------------------------------------------------

TOY_SLAVE_BASE = '''\
"""Toy slave base: registers a slave's VARIABLES with pythonfmu."""
from pythonfmu import Fmi2Causality, Fmi2Variability, Integer, Real

from driftfmu.models.helpers import gained

TYPES = {"Real": Real, "Integer": Integer}


def register_all(slave):
    for spec in slave.VARIABLES:
        setattr(slave, spec["name"], spec["start"])
        slave.register_variable(TYPES[spec["type"]](
            spec["name"], causality=getattr(Fmi2Causality, spec["causality"]),
            variability=getattr(Fmi2Variability, spec["variability"]),
            description=spec["description"]))


def output(u, offset):
    return gained(u) + offset
'''

TOY_SLAVE = '''\
"""Toy FMU: y = GAIN u + offset; mode 1 logs an error and refuses to step, mode 2 raises."""
from pythonfmu import Fmi2Slave
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Status

from driftfmu.fmu_src.slave_base import output, register_all
from driftfmu.models import constants


def _var(name, type, causality, variability, start, unit=None, low=None, high=None):
    return {"name": name, "type": type, "causality": causality, "variability": variability,
            "start": start, "unit": unit, "min": low, "max": high, "description": name}


class Toy(Fmi2Slave):
    """y = GAIN u + offset"""

    VARIABLES = [
        _var("offset", "Real", "parameter", "fixed", constants.OFFSET, "V", -10.0, 10.0),
        _var("mode", "Integer", "parameter", "fixed", 0, None, 0, 2),
        _var("u", "Real", "input", "continuous", 0.0, "m/s2"),
        _var("y", "Real", "output", "continuous", 0.0, "V"),
    ]
    DEPENDENCIES = %(dependencies)s
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=1.0, step_size=0.1)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        register_all(self)

    def do_step(self, current_time, step_size):
        if self.mode == 1:
            self.log("toy: mode 1 refuses to step", Fmi2Status.error)
            return False
        if self.mode == 2:
            raise ValueError("toy: mode 2 raises")
        self.y = output(self.u, self.offset)
        return True
'''


def write_toy(root, gain, dependencies='{"y": ["u"]}'):
    """A project at ``root`` (models/, fmu_src/) whose Toy FMU computes y = gain u + 0.5."""
    (root / "models").mkdir(parents=True)
    (root / "fmu_src").mkdir()
    (root / "models" / "constants.py").write_text("GAIN = %r\nOFFSET = 0.5\n" % gain)
    (root / "models" / "helpers.py").write_text(
        "from .constants import GAIN\n\n\ndef gained(u):\n    return GAIN * u\n")
    (root / "fmu_src" / "slave_base.py").write_text(TOY_SLAVE_BASE)
    (root / "fmu_src" / "Toy.py").write_text(TOY_SLAVE % {"dependencies": dependencies})
    return root / "fmu_src"


@pytest.fixture(scope="module")
def toy_fmus(tmp_path_factory):
    """Two builds of Toy that differ only in models/constants.py: GAIN 2 and GAIN 3."""
    fmus = []
    for gain in (2.0, 3.0):
        root = tmp_path_factory.mktemp("toy")
        src = write_toy(root, gain)
        fmus += build_fmus(root / "out", names=("Toy",), src_dir=src, log=lambda line: None)
    return fmus


@pytest.fixture(scope="module")
def c_host(tmp_path_factory):
    """The compiled tests/hosts/c_host.c."""
    cc = shutil.which(os.environ.get("CC", "cc"))
    if not cc:
        pytest.skip("no C compiler to build the C host")
    exe = tmp_path_factory.mktemp("c_host") / "c_host"
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([cc, "-o", str(exe), str(HOSTS / "c_host.c"), "-I%s" % headers, "-ldl"],
                   check=True)
    return str(exe)


# -- the model description ---------------------------------------------------------------------

@integration
@pytest.mark.parametrize("name", NAMES)
def test_real_fmus_validate_clean(built_fmus, name):
    path = str(built_fmus[name])
    assert validate_fmu(path) == []
    code, output = run([sys.executable, "-m", "fmpy", "validate", path], os.environ)
    assert code == 0 and "No problems found" in output, output


@integration
@pytest.mark.parametrize("name", NAMES)
def test_model_description_follows_the_slave_tables(built_fmus, name):
    slave = getattr(importlib.import_module("driftfmu.fmu_src." + name), name)
    md = fmpy.read_model_description(str(built_fmus[name]))
    assert md.coSimulation.modelIdentifier == name
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert (md.coSimulation.canHandleVariableCommunicationStepSize
            == getattr(slave, "CAN_HANDLE_VARIABLE_STEP", True))
    units = {u.name for u in md.unitDefinitions}
    specs = {spec["name"]: spec for spec in slave.VARIABLES}
    for v in md.modelVariables:
        spec = specs[v.name]
        if v.type == "Real":
            assert v.unit == spec["unit"] and (v.unit is None or v.unit in units)
        for key in ("min", "max"):
            if spec[key] is not None:
                assert float(getattr(v, key)) == spec[key]
    for unknown in md.outputs:
        direct = {d.name for d in unknown.dependencies}
        assert direct == set(slave.DEPENDENCIES.get(unknown.variable.name, ()))
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    assert {u.variable.name for u in md.initialUnknowns} == outputs


@integration
@pytest.mark.parametrize("name", NAMES)
def test_build_record_and_unique_names(built_fmus, name):
    with zipfile.ZipFile(built_fmus[name]) as fmu:
        info = json.loads(fmu.read(builder.BUILD_INFO))
        module = fmu.read("resources/slavemodule.txt").decode().strip()
        files = set(fmu.namelist())
    digest = source_hash(name)
    assert info["hash"] == digest and info["loader"] == "shim" and info["libpython"] == SONAME
    assert module == info["module"] == "%s_%s" % (name, digest)
    assert "resources/%s.py" % module in files
    assert "resources/drift_%s/models/__init__.py" % digest in files
    assert {"binaries/linux64/%s.so" % name, "binaries/linux64/%s_pythonfmu.so" % name} <= files


def test_unit_definitions():
    assert unit_definition("m/s2") == (1.0, {"m": 1, "s": -2})
    assert unit_definition("V/g2") == (1 / 9.80665 ** 2, {"kg": 1, "s": 1, "A": -1})
    assert unit_definition("1") == (1.0, {})
    assert unit_definition("g/sqrt(Hz)")[1] == {"m": 1, "s": -1.5}
    assert unit_definition("furlong") is None


# -- bundling ----------------------------------------------------------------------------------

def test_rewrite_imports_points_project_imports_at_the_bundle():
    source = textwrap.dedent("""\
        import os
        from driftfmu.models import sensor, ekf as filters  # noqa: F401
        from driftfmu.models.noise import (normal,
                                  STREAM)
        import driftfmu.models.chain
        import driftfmu.models.drift as drift, json
        from driftfmu.fmu_src.slave_base import SlaveBase
        from driftfmu.fmu_src import slave_base


        def f():
            from driftfmu.models import late
            import driftfmu.models.chain, json
            return late
        """)
    assert rewrite_imports(source, "drift_0123456789") == textwrap.dedent("""\
        import os
        from drift_0123456789.models import sensor, ekf as filters  # noqa: F401
        from drift_0123456789.models.noise import normal, STREAM
        import drift_0123456789.models.chain
        import drift_0123456789 as driftfmu
        import drift_0123456789.models.drift as drift
        import json
        from drift_0123456789.slave_base import SlaveBase
        from drift_0123456789 import slave_base


        def f():
            from drift_0123456789.models import late
            import drift_0123456789.models.chain
            import drift_0123456789 as driftfmu
            import json
            return late
        """)


@pytest.mark.parametrize("source", ["from driftfmu.fmu_src.builder import NAMES\n",
                                    "import driftfmu.fmu_src.slave_base\n",
                                    "from driftfmu import simulations\n",
                                    "import os; from driftfmu.models import sensor\n"])
def test_rewrite_imports_rejects_what_cannot_be_bundled(source):
    with pytest.raises(BuildError):
        rewrite_imports(source, "drift_0123456789")


def test_hash_follows_the_bundled_code(tmp_path):
    src = write_toy(tmp_path, 2.0)
    before = source_hash("Toy", src)
    (tmp_path / "models" / "constants.py").write_text("GAIN = 2.5\nOFFSET = 0.5\n")
    assert len(before) == builder.HASH_LENGTH and source_hash("Toy", src) != before


@integration
def test_same_model_from_two_builds_runs_its_own_code_in_one_process(toy_fmus):
    jobs = [{"fmu": str(fmu), "start": {"u": 1.0}, "steps": 1, "read": "y"} for fmu in toy_fmus]
    code, output = run([sys.executable, str(HOSTS / "fmpy_host.py"), json.dumps(jobs)],
                       clean_env())
    results = [json.loads(line[7:]) for line in output.splitlines() if line.startswith("RESULT")]
    assert code == 0 and [r["value"] for r in results] == [2.5, 3.5], output


@integration
def test_model_errors_reach_the_host_with_debug_logging_off(toy_fmus):
    jobs = [{"fmu": str(toy_fmus[0]), "start": {"mode": mode}, "steps": 1, "read": "y"}
            for mode in (1, 2, 0)]
    code, output = run([sys.executable, str(HOSTS / "fmpy_host.py"), json.dumps(jobs)],
                       clean_env())
    refused, raised, fine = [json.loads(line[7:]) for line in output.splitlines()
                             if line.startswith("RESULT")]
    assert "status 3" in refused["error"] and "mode 1 refuses to step" in output
    assert "status 4" in raised["error"] and "ValueError('toy: mode 2 raises')" in output
    assert fine == {"value": 0.5, "error": None}


@integration
def test_failed_build_keeps_the_previous_fmu(tmp_path):
    src = write_toy(tmp_path / "project", 2.0, dependencies='{"y": ["offset"]}')
    out = tmp_path / "out"
    out.mkdir()
    (out / "Toy.fmu").write_bytes(b"previous build")
    with pytest.raises(BuildError, match="not inputs"):
        build_fmus(out, names=("Toy",), src_dir=src, log=lambda line: None)
    assert [p.name for p in out.iterdir()] == ["Toy.fmu"]
    assert (out / "Toy.fmu").read_bytes() == b"previous build"


@pytest.mark.qualification  # builds every FMU twice
@integration
def test_source_date_epoch_makes_the_same_sources_build_the_same_bytes(tmp_path, monkeypatch):
    """With SOURCE_DATE_EPOCH set, the model description's generationDateAndTime is that time
    (not the build's), so two builds of the same sources, seconds apart, are equal byte for
    byte (the zip entries carry a fixed date already, the GUID is derived from the model and
    the version)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    first, = build_fmus(tmp_path / "a", names=("Excitation",), log=lambda line: None)
    with zipfile.ZipFile(first) as archive:
        md = ET.fromstring(archive.read("modelDescription.xml"))
    assert md.get("generationDateAndTime") == "2023-11-14T22:13:20Z"
    second_started = int(time.time())
    while int(time.time()) == second_started:  # the build's own clock shows another second
        time.sleep(0.05)
    second, = build_fmus(tmp_path / "b", names=("Excitation",), log=lambda line: None)
    assert first.read_bytes() == second.read_bytes()


@pytest.mark.parametrize("value", ["yesterday", "-1", "1.5", "99999999999999999999"])
def test_a_bad_source_date_epoch_is_refused_before_anything_is_built(value, tmp_path,
                                                                     monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", value)
    with pytest.raises(BuildError, match=r"SOURCE_DATE_EPOCH=.* is not a time; allowed: a "
                                         r"whole number of seconds since 1970"):
        build_fmus(tmp_path / "out", names=("Toy",), src_dir=tmp_path / "none",
                   log=lambda line: None)
    assert not (tmp_path / "out").exists()


@integration
def test_without_a_compiler_libpython_becomes_a_dt_needed_entry(tmp_path, monkeypatch):
    if not shutil.which("patchelf"):
        pytest.skip("patchelf is not installed")
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    src = write_toy(tmp_path / "project", 2.0)
    lines = []
    fmu, = build_fmus(tmp_path / "out", names=("Toy",), src_dir=src, log=lines.append)
    assert any("warning" in line and "patchelf" in line for line in lines)
    with zipfile.ZipFile(fmu) as archive:
        assert json.loads(archive.read(builder.BUILD_INFO))["loader"] == "dt_needed"
        (tmp_path / "Toy.so").write_bytes(archive.read("binaries/linux64/Toy.so"))
    needed = subprocess.run(["patchelf", "--print-needed", str(tmp_path / "Toy.so")],
                            capture_output=True, text=True, check=True).stdout.split()
    assert SONAME in needed


# -- hosts -------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def reference_values(built_fmus, tmp_path_factory):
    """Each FMU's first output after STEPS steps in a Python host of this version."""
    values = {}
    for name, fmu in built_fmus.items():
        args = host_args(fmu, tmp_path_factory.mktemp("reference"))
        code, output = run([sys.executable, str(HOSTS / "ctypes_host.py"), *args], clean_env())
        assert code == 0 and not errors_in(output), output
        values[name] = value_of(output)
    return values


@integration
@pytest.mark.parametrize("name", NAMES)
def test_c_host_runs_the_fmu_without_ld_preload(built_fmus, c_host, reference_values, name,
                                                tmp_path):
    args = host_args(built_fmus[name], tmp_path)
    code, output = run([c_host, *args], clean_env(LD_LIBRARY_PATH=LIBDIR))
    assert code == 0 and not errors_in(output), output
    assert value_of(output) == reference_values[name]
    if on_default_loader_path(SONAME):
        code, output = run([c_host, *args], clean_env())
        assert code == 0 and value_of(output) == reference_values[name], output


@integration
def test_driftfmu_libpython_names_the_library(built_fmus, c_host, reference_values, tmp_path):
    args = host_args(built_fmus["Accelerometer"], tmp_path)
    libraries = [os.path.join(LIBDIR, SONAME)]
    libraries += [lib for lib in map(libpython_of, other_pythons().values()) if lib][:1]
    for library in libraries:
        code, output = run([c_host, *args], clean_env(DRIFTFMU_LIBPYTHON=library))
        assert code == 0 and not errors_in(output), (library, output)
        assert value_of(output) == reference_values["Accelerometer"]


@integration
def test_without_any_libpython_instantiate_returns_null_with_a_message(built_fmus, c_host,
                                                                      tmp_path):
    bogus = str(tmp_path / "no" / "libpython3.99.so")
    command = without_system_libpython([c_host, *host_args(built_fmus["Excitation"], tmp_path)])
    if command is None:
        pytest.skip("cannot hide the system libpython (unshare with a mount namespace)")
    code, output = run(command, clean_env(DRIFTFMU_LIBPYTHON=bogus))
    assert code == 2 and "INSTANTIATE FAILED" in output, output
    message = errors_in(output)[0]
    assert "cannot start the FMU's Python" in message and bogus in output
    assert "DRIFTFMU_LIBPYTHON" in output and "LD_LIBRARY_PATH" in output


@pytest.mark.qualification
@integration
def test_python_hosts_of_other_versions(built_fmus, reference_values, tmp_path):
    if not other_pythons():
        pytest.skip("no Python 3 of another version (>= 3.8) on this machine")
    for version, python in sorted(other_pythons().items()):
        for name, fmu in built_fmus.items():
            args = host_args(fmu, tmp_path / ("py%d%d" % version))
            code, output = run([python, str(HOSTS / "ctypes_host.py"), *args], clean_env())
            assert code == 0 and not errors_in(output), (version, name, output)
            assert value_of(output) == reference_values[name], (version, name)


# -- building after simulating a Python FMU in the same process ----------------------------------

_SIMULATE_THEN_BUILD = """
import sys
import driftfmu
import fmpy
from pathlib import Path
from xml.etree import ElementTree as ET
fmu_dir, out = sys.argv[1:3]
# (fmpy's own master: driftfmu's masters check the FMU against driftfmu's tables first, which
# imports the installed pythonfmu)
fmpy.simulate_fmu(str(Path(fmu_dir) / "Excitation.fmu"), stop_time=0.01)
import pythonfmu
print("imported pythonfmu from", Path(pythonfmu.__file__).parent)
print(driftfmu.build_fmus(out, names=["Excitation"])["Excitation"])
"""


@integration
def test_a_build_after_simulating_a_python_fmu_uses_the_installed_pythonfmu(built_fmus,
                                                                          tmp_path):
    """A Python FMU simulated in this process before pythonfmu was imported here brings its own
    copy of pythonfmu (the FMU's resources/pythonfmu, without pythonfmu's binaries, removed with
    the instance); the build then uses the installed pythonfmu's binaries and modules all the
    same (it failed with KeyError 'binaries/linux64/Excitation.so')."""
    fmu_dir = tmp_path / "fmus"
    fmu_dir.mkdir()
    (fmu_dir / "Excitation.fmu").symlink_to(built_fmus["Excitation"])
    root = Path(__file__).resolve().parent.parent
    p = subprocess.run([sys.executable, "-c", _SIMULATE_THEN_BUILD, str(fmu_dir),
                        str(tmp_path / "out")], capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, PYTHONPATH=str(root)))
    assert p.returncode == 0, p.stderr
    assert "resources" in p.stdout.splitlines()[0]  # the FMU's copy was the one imported
    fmu = Path(p.stdout.splitlines()[-1])
    assert not validate_fmu(str(fmu))
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
    assert "binaries/linux64/Excitation.so" in names
    assert "resources/pythonfmu/fmi2slave.py" in names
