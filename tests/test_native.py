"""The native (C) FMUs, FMI 2.0 and FMI 3.0: valid, the same interface as the Python FMUs, the
same bits in every master and host (fmpy, the fast master, a C host without Python, the Windows
binary under wine, a binary rebuilt from the FMU's own sources), and errors instead of crashes.

The behaviour tests shared with the Python FMUs (tests/test_lifecycle.py) run on both backends
through the ``backend_fmus`` fixture; here is what only the native FMUs have.
"""
import ctypes
import math
import random
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from driftfmu.fmu_src import native_build
from driftfmu.fmu_src.native_build import NAMES
from driftfmu.models import adxl203, excitation, harmonic
from driftfmu.simulations import gaussian, sinusoidal
from driftfmu.simulations.cosim import CoSimulationError, cosimulate
from driftfmu.simulations.fastcosim import FastInstance, cosimulate_fast

sys.path.insert(0, str(Path(__file__).parent / "hosts"))
import chain  # noqa: E402

pytestmark = pytest.mark.integration
VERSIONS = (2, 3)
MODELS = [(name, v) for v in VERSIONS for name in NAMES]
CHAIN = gaussian.FMU_NAMES  # Excitation -> Accelerometer -> DriftEstimator
ALL_OUTPUTS = None  # cosimulate's default: every output of every FMU


def chain_of(fmus):
    """The FMUs of the chain Excitation -> Accelerometer -> DriftEstimator among ``fmus``."""
    return {n: fmus[n] for n in CHAIN}


# -- the runs of the issue: start values, connections -------------------------------------------

def gaussian_run():
    """The letter's Gaussian run (Sec. III settings, 2000 samples)."""
    return gaussian.start_values(), gaussian.CONNECTIONS, 2000, 1e-3


def sinusoidal_harmonic_run(n=2000):
    """The sinusoidal run with the harmonic filter (run_sinusoidal's defaults)."""
    start = {
        "Excitation": dict(kind=excitation.SINUSOIDAL, X=1.0, f=150.0, phi=0.0, Xy=0.0,
                           phiy=0.0, Ts=1e-3, seed=1),
        "Accelerometer": dict(a0=0.0, a1=1.0, a2=0.01, R=1e-4, seed=1, Ts=1e-3, noise=1),
        "DriftEstimator": dict(a0=0.0, a1=1.0, a2=0.01, R=1e-4, process=harmonic.HARMONIC,
                               f=150.0, Qh=1e-8, A=0.0, Q=0.5, x0=0.0, P0=0.5, Ts=1e-3,
                               estimator=1),
    }
    return start, sinusoidal.CONNECTIONS, n, 1e-3


def adxl203_run(n=3000, Ts=1e-4):
    """``driftfmu run sinusoidal --preset adxl203`` (with transverse motion)."""
    sp = dict(adxl203.ADXL203, seed=3, Ts=Ts, noise=1)
    model = sinusoidal.nominal_model(sp, Ts)
    start = {
        "Excitation": dict(kind=excitation.SINUSOIDAL, X=1.5, f=150.0, phi=0.3, Xy=0.075,
                           phiy=0.5, Ts=Ts, seed=3),
        "Accelerometer": sp,
        "DriftEstimator": dict(model, process=harmonic.HARMONIC, f=150.0, Qh=1e-8, A=0.0,
                               Q=1.125, x0=0.0, P0=1.125, Ts=Ts, estimator=1),
    }
    return start, sinusoidal.CONNECTIONS, n, Ts


RUNS = {"gaussian": gaussian_run, "sinusoidal-harmonic": sinusoidal_harmonic_run,
        "adxl203": adxl203_run}


@pytest.fixture(scope="module")
def python_chain(built_fmus):
    """The Python FMUs of the chain Excitation -> Accelerometer -> DriftEstimator."""
    return {n: built_fmus[n] for n in CHAIN}


@pytest.fixture(scope="module")
def python_results(python_chain):
    """Every output of every run through the Python FMUs (fmpy master)."""
    out = {}
    for name, make in RUNS.items():
        start, connections, n, Ts = make()
        out[name] = cosimulate(python_chain, connections, n, Ts, start_values=start)
    return out


# -- validity and interface -------------------------------------------------------------------

@pytest.mark.parametrize("name,version", MODELS)
def test_native_fmu_validates_with_fmpy(native_fmus, name, version):
    assert validate_fmu(str(native_fmus[version][name])) == []


def test_fmpy_validate_command_prints_no_problem(native_fmus):
    for version in VERSIONS:
        for path in native_fmus[version].values():
            result = subprocess.run([sys.executable, "-m", "fmpy.cli", "validate",
                                     str(path)], capture_output=True, text=True)
            assert result.returncode == 0, result.stdout + result.stderr
            assert result.stdout.strip() == "No problems found.", result.stdout + result.stderr


def _interface(md):
    kinds = {"Real": "Real", "Float64": "Real", "Integer": "Integer", "Int32": "Integer"}
    rows = {}
    for v in md.modelVariables:
        if v.causality == "independent":
            continue
        rows[v.name] = (v.valueReference, kinds[v.type], v.causality, v.variability,
                        None if v.start is None else float(v.start), v.unit or None,
                        None if v.min is None else float(v.min),
                        None if v.max is None else float(v.max), v.description)
    outputs = {u.variable.name: sorted(d.name for d in (u.dependencies or []))
               for u in md.outputs}
    return rows, outputs


@pytest.mark.parametrize("name,version", MODELS)
def test_same_variables_and_value_references_as_the_python_fmu(built_fmus, native_fmus, name,
                                                               version):
    python = read_model_description(str(built_fmus[name]))
    native = read_model_description(str(native_fmus[version][name]))
    py_rows, py_outputs = _interface(python)
    na_rows, na_outputs = _interface(native)
    assert na_rows == py_rows
    assert na_outputs == py_outputs
    assert native.coSimulation.modelIdentifier == name
    assert native.coSimulation.canGetAndSetFMUstate and native.coSimulation.canSerializeFMUstate


@pytest.mark.parametrize("name,version", MODELS)
def test_source_fmu_declares_its_sources(native_fmus, name, version):
    with zipfile.ZipFile(native_fmus[version][name]) as archive:
        files = set(archive.namelist())
        md = read_model_description(str(native_fmus[version][name]))
    declared = md.buildConfigurations[0].sourceFileSets[0].sourceFiles
    assert declared and all("sources/" + f in files for f in declared)
    assert "sources/config.h" in files and "sources/model.h" in files
    # this machine's binary; every platform's: tests/test_platforms.py (qualification)
    platform = {2: "linux64", 3: "x86_64-linux"}[version]
    assert "binaries/%s/%s.so" % (platform, name) in files
    if version == 3:
        assert "sources/buildDescription.xml" in files


def _windows_compiler(fmi3_fmu):
    """The compiler's label that the FMI 3.0 FMU's build description gives its x86-64 Windows
    binary (both FMUs of a model hold the same library)."""
    import xml.etree.ElementTree as ET
    with zipfile.ZipFile(fmi3_fmu) as archive:
        root = ET.fromstring(archive.read("sources/buildDescription.xml"))
    (config,) = [c for c in root.iter("BuildConfiguration")
                 if c.get("platform") == "x86_64-windows"]
    return config.get("description").split(": ", 1)[1]


@pytest.mark.qualification  # the Windows binaries: built for the qualification only
def test_windows_binaries_need_only_system_dlls(native_fmus, tmp_path):
    """Each Windows binary imports only what every 64-bit Windows has: kernel32 and the C
    runtime its compiler links, msvcrt (mingw-w64) or the Universal CRT's api-ms-win-crt-*
    (zig; part of Windows 10 and 11), as its build description names the compiler."""
    objdump = shutil.which("x86_64-w64-mingw32-objdump")
    if not objdump:
        pytest.skip("x86_64-w64-mingw32-objdump is not installed")
    for version, folder in ((2, "win64"), (3, "x86_64-windows")):
        for name, path in native_fmus[version].items():
            if "binaries/%s/%s.dll" % (folder, name) not in zipfile.ZipFile(path).namelist():
                pytest.skip("no Windows binary was built here (no compiler for it)")
            label = _windows_compiler(native_fmus[3][name])
            dll = tmp_path / ("%s%d.dll" % (name, version))
            with zipfile.ZipFile(path) as archive:
                dll.write_bytes(archive.read("binaries/%s/%s.dll" % (folder, name)))
            dump = subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True,
                                  check=True).stdout
            dlls = {line.split(":")[1].strip().lower() for line in dump.splitlines()
                    if "DLL Name" in line}
            if label.startswith("zig"):
                crt = {d for d in dlls if d.startswith("api-ms-win-crt-")}
                assert crt and dlls - crt <= {"kernel32.dll"}, (name, version, label, dlls)
            else:
                assert "mingw32" in label, label
                assert dlls <= {"kernel32.dll", "msvcrt.dll"}, (name, version, label, dlls)


# -- the same bits as the Python FMUs -----------------------------------------------------------

@pytest.mark.parametrize("run", sorted(RUNS))
@pytest.mark.parametrize("version", VERSIONS)
def test_runs_equal_the_python_fmus_bit_for_bit(native_fmus, python_results, run, version):
    start, connections, n, Ts = RUNS[run]()
    fast = cosimulate_fast(chain_of(native_fmus[version]), connections, n, Ts, start_values=start)
    assert fast == python_results[run]
    if version == 2:  # fmpy's FMU2Slave master on the native FMUs
        assert cosimulate(chain_of(native_fmus[2]), connections, n, Ts, start_values=start) == fast


def test_fast_master_equals_fmpy_master_on_the_python_fmus(python_chain, python_results):
    start, connections, n, Ts = gaussian_run()
    assert cosimulate_fast(python_chain, connections, n, Ts, start_values=start) == \
        python_results["gaussian"]


def test_fast_master_without_a_c_compiler_falls_back_to_the_same_bits(native_fmus,
                                                                      python_results,
                                                                      monkeypatch):
    from driftfmu.simulations import fastcosim
    monkeypatch.setattr(fastcosim, "loop_library", lambda: None)
    start, connections, n, Ts = RUNS["adxl203"]()
    assert cosimulate_fast(chain_of(native_fmus[3]), connections, n, Ts, start_values=start) == \
        python_results["adxl203"]


def test_run_gaussian_and_sinusoidal_take_the_backend(native_fmus):
    fmu_dir = native_fmus[2]["Excitation"].parent.parent.parent
    g = gaussian.run_gaussian(fmu_dir=fmu_dir, backend="native", n=300, plot=False)
    assert g["summary"]["validation"]["passed"]
    s = sinusoidal.run_sinusoidal(fmu_dir=fmu_dir, backend="native", n=300, preset="adxl203",
                                  Ts=1e-4, plot=False)
    assert s["summary"]["validation"]["passed"]
    with pytest.raises(ValueError, match="backend = 'c' is not allowed"):
        gaussian.run_gaussian(fmu_dir=fmu_dir, backend="c", n=10)


# -- random parameters, multi-sample steps, a state saved and restored --------------------------

def random_case(rng):
    """Start values of a random chain and a random schedule of whole-sample steps."""
    Ts = rng.choice((1e-3, 2.5e-4, 1e-4))
    kind = rng.choice((excitation.GAUSSIAN, excitation.SINUSOIDAL))
    seed = rng.randrange(0, 2 ** 31 - 1)
    f = rng.uniform(10.0, 0.3 / Ts)
    a = dict(a0=rng.uniform(-0.5, 0.5), a1=rng.choice((-1, 1)) * rng.uniform(0.5, 2.0),
             a2=rng.uniform(0.0, 0.05), R=10 ** rng.uniform(-5, -2))
    A, Q = rng.uniform(-0.9, 0.9), 10 ** rng.uniform(-3, -1)
    sensor = dict(a, seed=seed, Ts=Ts, noise=rng.choice((0, 1)))
    if rng.random() < 0.5:
        sensor.update(a3=rng.uniform(-0.01, 0.01), cross=rng.uniform(-0.05, 0.05),
                      fc=rng.choice((0.0, rng.uniform(50.0, min(2500.0, 0.4 / Ts)))),
                      Vs=rng.choice((0.0, rng.uniform(3.0, 6.0))), bits=rng.choice((0, 8, 12)),
                      density=rng.choice((0.0, 1e-4)), axes=rng.choice((1, 2)))
    start = {
        "Excitation": dict(kind=kind, A=A, Q=Q, x0=rng.uniform(-1, 1), X=rng.uniform(0.1, 2),
                           f=f, phi=rng.uniform(-3, 3), Xy=rng.uniform(0, 0.2),
                           phiy=rng.uniform(-3, 3), Ts=Ts, seed=seed),
        "Accelerometer": sensor,
        "DriftEstimator": dict(a, A=A, Q=Q, x0=0.0, P0=rng.uniform(0.01, 1.0), Ts=Ts,
                               estimator=rng.choice((1, 2, 3)),
                               process=rng.choice((harmonic.GAUSS_MARKOV, harmonic.HARMONIC)),
                               f=f, Qh=10 ** rng.uniform(-9, -6)),
    }
    steps = [rng.choice((1, 1, 1, 2, 3, 7)) * Ts for _ in range(rng.randrange(60, 160))]
    return start, steps


OUTS = {"Excitation": ["x", "y"], "Accelerometer": ["z", "z_y"],
        "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp"]}


class Stepper:
    """The three FMUs (either FMI version) stepped with a schedule of step sizes."""

    def __init__(self, fmus, start):
        self.inst = {n: FastInstance(n, fmus[n]) for n in CHAIN}
        for n, inst in self.inst.items():
            inst.initialise(start.get(n, {}), 0.0)
        self.t = 0.0

    def _get(self, inst, names):
        fmu = inst.fmu
        vrs = [inst.vrs[v] for v in names]
        return list(fmu.getReal(vrs) if inst.fmi == 2 else fmu.getFloat64(vrs))

    def _set(self, inst, name, value):
        fmu = inst.fmu
        (fmu.setReal if inst.fmi == 2 else fmu.setFloat64)([inst.vrs[name]], [value])

    def point(self):
        e, a, d = (self.inst[n] for n in CHAIN)
        x, y = self._get(e, ["x", "y"])
        self._set(a, "x", x)
        self._set(a, "y", y)
        self._set(d, "z", self._get(a, ["z"])[0])
        return tuple(v for n in CHAIN for v in self._get(self.inst[n], OUTS[n]))

    def step(self, h):
        for inst in self.inst.values():
            if inst.fmi == 2:
                inst.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
            else:
                inst.fmu.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t += h
        return self.point()

    def save(self):
        return {n: (i.fmu.getFMUstate() if i.fmi == 2 else i.fmu.getFMUState())
                for n, i in self.inst.items()}

    def restore(self, states):
        for n, i in self.inst.items():
            (i.fmu.setFMUstate if i.fmi == 2 else i.fmu.setFMUState)(states[n])

    def free(self):
        for i in self.inst.values():
            i.free()


def schedule(fmus, start, steps, restore_at):
    """Rows at every point of ``steps``; the state is saved at point ``restore_at`` and, after
    the run, restored and the rest re-run: returns (rows, rows of the re-run from there)."""
    s = Stepper(fmus, start)
    try:
        rows = [s.point()]
        saved = None
        for i, h in enumerate(steps):
            if i == restore_at:
                saved, t = s.save(), s.t
            rows.append(s.step(h))
        s.restore(saved)
        s.t = t
        again = [s.step(h) for h in steps[restore_at:]]
        return rows, again
    finally:
        s.free()


@pytest.mark.parametrize("case", range(12))
def test_random_parameters_and_steps_equal_the_python_fmus(built_fmus, native_fmus, case):
    rng = random.Random(20061 + case)
    start, steps = random_case(rng)
    middle = len(steps) // 2
    ref, ref_again = schedule(built_fmus, start, steps, middle)
    assert ref_again == ref[middle + 1:]   # the Python FMUs' own save/restore
    for version in VERSIONS:
        rows, again = schedule(native_fmus[version], start, steps, middle)
        assert rows == ref, (case, version)
        assert again == ref[middle + 1:], (case, version)


def test_non_whole_steps_fmi2_equals_fmi3_and_samples_stay_on_the_grid(native_fmus, built_fmus):
    """Steps that are not whole sample periods (the step rule of slave_base): both FMI versions agree bit for
    bit; at points on the sample grid the excitation and the plain sensor (no filter) give the
    values of the whole-step run; where the Python FMUs accept such steps they agree too."""
    start, _, _, Ts = gaussian_run()
    steps = [1.5 * Ts, 0.5 * Ts, 0.25 * Ts, 2.75 * Ts, Ts, 0.3 * Ts, 0.7 * Ts, 3 * Ts] * 5
    rows = {}
    for version in VERSIONS:
        rows[version], _ = schedule(native_fmus[version], start, steps, 3)
    assert rows[2] == rows[3]
    whole, _ = schedule(native_fmus[2], start, [Ts] * int(round(sum(steps) / Ts)), 1)
    t, on_grid = 0.0, 0
    for h, row in zip(steps, rows[2][1:]):
        t += h
        k = round(t / Ts)
        if abs(t / Ts - k) <= 1e-6:
            on_grid += 1
            assert row[:3] == whole[k][:3], k  # x, y, z at sample k + 1
    assert on_grid >= 10
    try:
        python, _ = schedule(built_fmus, start, steps, 3)
    except Exception as exc:
        assert "whole number of sample periods" in str(exc) or "status 3" in str(exc)
    else:
        assert python == rows[2]


@pytest.mark.parametrize("case", range(6))
def test_random_parameters_and_non_whole_steps(built_fmus, native_fmus, case):
    """Random parameter sets with steps of fractions and non-whole multiples of Ts and a state
    restore in the middle: FMI 2.0 and 3.0 agree bit for bit, the restored run repeats the
    first, and so do the Python FMUs wherever they accept such steps (the step rule of slave_base)."""
    rng = random.Random(777 + case)
    start, _ = random_case(rng)
    Ts = start["Excitation"]["Ts"]
    steps = [rng.choice((0.25, 0.3, 1 / 3, 0.5, 1.5, 2.5, 1.0, 4.75)) * Ts for _ in range(80)]
    runs = {v: schedule(native_fmus[v], start, steps, 40) for v in VERSIONS}
    assert runs[2] == runs[3]
    rows, again = runs[2]
    assert again == rows[41:]
    try:
        python = schedule(built_fmus, start, steps, 40)
    except Exception as exc:
        assert "status 3" in str(exc) or "whole number of sample periods" in str(exc)
    else:
        assert python == runs[2]


# -- hosts without Python: the C host, wine, the rebuilt source FMU -----------------------------

class _Hosts(dict):
    """The C host for "linux", "windows" (mingw-w64, run under wine) and "aarch64" (zig, run
    under qemu-user), each compiled when a test first asks for it (None without its tools)."""

    def __init__(self, folder):
        super().__init__()
        self.folder = folder

    def __missing__(self, kind):
        if kind == "linux":
            host = chain.compile_host(self.folder / "chain_host")
        elif kind == "windows":
            host = chain.compile_host(self.folder / "chain_host.exe", windows=True) \
                if chain.have_windows_tools() else None
        else:
            host = chain.compile_host(self.folder / "chain_host_aarch64", aarch64=True) \
                if chain.have_aarch64_tools() else None
        self[kind] = host
        return host


@pytest.fixture(scope="module")
def hosts(tmp_path_factory):
    return _Hosts(tmp_path_factory.mktemp("hosts"))


def host_run(host, fmus, run, folder, windows=False, record=None, aarch64=False):
    start, connections, n, Ts = RUNS[run]()
    version = int(read_model_description(str(next(iter(fmus.values())))).fmiVersion[0])
    unpacked = {name: chain.unpack(path, Path(folder) / name) for name, path in fmus.items()}
    record = record or {name: OUTS[name] for name in fmus}
    text, keys = chain.script(version, unpacked, start, connections, record, n, Ts,
                              relative_to=folder if windows else None)
    cols, _, _ = chain.run(host, text, keys, folder, windows=windows, aarch64=aarch64)
    return cols


def every_output(fmus):
    """{instance: [every output of its model description]}."""
    return {name: [v.name for v in read_model_description(str(path)).modelVariables
                   if v.causality == "output"] for name, path in fmus.items()}


@pytest.mark.qualification
@pytest.mark.parametrize("version", VERSIONS)
def test_aarch64_linux_binaries_under_qemu_give_the_python_fmus_bits(native_fmus_all,
                                                                      python_results, hosts,
                                                                      version, tmp_path):
    """The C host cross-compiled for aarch64 (zig) runs the aarch64 Linux binaries under
    qemu-user: the Gaussian chain, the harmonic sinusoidal chain and the ADXL203 preset give
    every output of every FMU equal to the x86-64 Python FMUs' bit for bit.  FMI 2.0: the FMUs
    for ARM (``fmi2-aarch64``, the aarch64 library in ``binaries/linux64``, where fmpy and FMI
    Library look on an aarch64 Linux); FMI 3.0: ``binaries/aarch64-linux``."""
    import os
    if hosts["aarch64"] is None:
        why = "zig, qemu-user or libc6-arm64-cross is not installed (.ci/run installs them)"
        (pytest.fail if os.environ.get("DRIFTFMU_REQUIRE_PLATFORMS") else pytest.skip)(why)
    fmus = chain_of(native_fmus_all[version])  # with the cross-built binaries
    if version == 2:
        arm = fmus["Excitation"].parent.parent / native_build.FMI2_ARM
        fmus = {n: arm / p.name for n, p in fmus.items()}
    record = every_output(fmus)
    for run in sorted(RUNS):
        cols = host_run(hosts["aarch64"], fmus, run, tmp_path / run, record=record,
                        aarch64=True)
        ref = python_results[run]
        assert set(cols) == set(ref), run
        assert len(cols["time"]) == RUNS[run]()[2]
        for key in cols:
            assert cols[key] == ref[key], (run, key)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("run", ["gaussian", "adxl203"])
def test_c_host_without_python_gives_the_python_fmus_bits(native_fmus, python_results, hosts,
                                                          version, run, tmp_path):
    cols = host_run(hosts["linux"], chain_of(native_fmus[version]), run, tmp_path)
    ref = python_results[run]
    assert cols["time"] == ref["time"]
    for key in cols:
        if key != "time":
            assert cols[key] == ref[key], key


@pytest.mark.qualification
@pytest.mark.parametrize("version", VERSIONS)
def test_valgrind_sees_no_invalid_access_in_the_c_host(native_fmus, hosts, version, tmp_path):
    if not shutil.which("valgrind"):
        pytest.skip("valgrind is not installed")
    start, connections, _, Ts = RUNS["adxl203"]()
    unpacked = {n: chain.unpack(p, tmp_path / n) for n, p in native_fmus[version].items()}
    text, keys = chain.script(version, unpacked, start, connections, OUTS, 200, Ts)
    (tmp_path / "script.txt").write_text(text)
    result = subprocess.run(["valgrind", "-q", "--error-exitcode=9", str(hosts["linux"]),
                             "script.txt"], cwd=tmp_path, capture_output=True, text=True,
                            timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stderr == "" and result.stdout.count("ROW") == 200


@pytest.mark.qualification
@pytest.mark.parametrize("version", VERSIONS)
def test_windows_binaries_under_wine_give_the_linux_bits(native_fmus, hosts, version, tmp_path):
    if hosts["windows"] is None:
        pytest.skip("mingw-w64 or wine64 is not installed (.ci/run installs both)")
    for run in ("gaussian", "adxl203"):
        linux = host_run(hosts["linux"], chain_of(native_fmus[version]), run, tmp_path / ("l" + run))
        windows = host_run(hosts["windows"], chain_of(native_fmus[version]), run, tmp_path / ("w" + run),
                           windows=True)
        assert len(windows["time"]) == RUNS[run]()[2]
        assert windows == linux, run


@pytest.mark.qualification
@pytest.mark.parametrize("version", VERSIONS)
def test_source_fmu_rebuilt_with_the_plain_compiler_call_gives_the_same_bits(
        native_fmus, hosts, version, tmp_path):
    rebuilt = {}
    for name, path in native_fmus[version].items():
        folder = tmp_path / "src" / name
        with zipfile.ZipFile(path) as archive:
            archive.extractall(folder)
        command = native_build.PLAIN_COMPILE.format(identifier=name)
        subprocess.run(command, shell=True, cwd=folder, check=True, capture_output=True)
        binary = "binaries/%s/%s.so" % ("linux64" if version == 2 else "x86_64-linux", name)
        assert (folder / (name + ".so")).read_bytes() != b""
        shutil.copyfile(folder / (name + ".so"), folder / binary)
        target = tmp_path / "fmus" / (name + ".fmu")
        target.parent.mkdir(exist_ok=True)
        with zipfile.ZipFile(path) as src, zipfile.ZipFile(target, "w") as dst:
            for item in src.infolist():
                data = (folder / binary).read_bytes() if item.filename == binary \
                    else src.read(item)
                dst.writestr(item, data)
        rebuilt[name] = target
    for run in ("gaussian", "sinusoidal-harmonic"):
        a = host_run(hosts["linux"], chain_of(native_fmus[version]), run, tmp_path / ("a" + run))
        b = host_run(hosts["linux"], chain_of(rebuilt), run, tmp_path / ("b" + run))
        assert a == b, run


@pytest.mark.qualification
@pytest.mark.parametrize("version", VERSIONS)
def test_fmpy_cmake_build_of_each_source_fmu_gives_the_same_bits(native_fmus, python_results,
                                                                 version, tmp_path):
    """fmpy's own source-FMU build (``fmpy.build.build_platform_binary``: its CMake project
    over the FMU's declared sources, the successor of ``fmpy.util.compile_platform_binary``)
    compiles every native FMU, binaries removed, on this machine; the rebuilt FMUs give the
    Python FMUs' bits in the three runs (the chain) and the prebuilt FMU's in fmpy's
    simulate_fmu (every FMU)."""
    import os
    if not shutil.which("cmake"):
        why = "cmake is not installed (.ci/run installs it from PyPI)"
        (pytest.fail if os.environ.get("DRIFTFMU_REQUIRE_PLATFORMS") else pytest.skip)(why)
    from fmpy.build import build_platform_binary
    rebuilt = {}
    for name, path in native_fmus[version].items():
        folder = (tmp_path / "src" / name).resolve()  # fmpy's CMake wants absolute paths
        with zipfile.ZipFile(path) as archive:
            archive.extractall(folder)
        shutil.rmtree(folder / "binaries")
        build_platform_binary(folder, build_dir=None)
        built = sorted(p.relative_to(folder).as_posix()
                       for p in (folder / "binaries").rglob("*") if p.is_file())
        assert built == ["binaries/%s/%s.so" % ("linux64" if version == 2 else "x86_64-linux",
                                                name)]
        target = tmp_path / "fmus" / (name + ".fmu")
        target.parent.mkdir(exist_ok=True)
        with zipfile.ZipFile(target, "w") as dst:
            for f in folder.rglob("*"):
                if f.is_file():
                    dst.write(f, f.relative_to(folder).as_posix())
        rebuilt[name] = target
    for run in sorted(RUNS):
        start, connections, n, Ts = RUNS[run]()
        assert cosimulate_fast(chain_of(rebuilt), connections, n, Ts, start_values=start) == \
            python_results[run], run
    opts = dict(stop_time=0.2, output_interval=1e-3)
    for name in native_fmus[version]:
        a = simulate_fmu(str(rebuilt[name]), **opts)
        b = simulate_fmu(str(native_fmus[version][name]), **opts)
        for column in b.dtype.names:
            assert a[column].tolist() == b[column].tolist(), (name, column)


@pytest.mark.parametrize("name,version", MODELS)
def test_simulate_fmu_runs_each_native_fmu_like_the_python_one(built_fmus, native_fmus, name,
                                                               version):
    opts = dict(stop_time=0.05, output_interval=1e-3)
    native = simulate_fmu(str(native_fmus[version][name]), **opts)
    python = simulate_fmu(str(built_fmus[name]), **opts)
    assert len(native) == len(python) == 51
    for column in python.dtype.names:
        assert native[column].tolist() == python[column].tolist(), column


# -- errors, not crashes ------------------------------------------------------------------------

def _library(native_fmus, version, name, tmp_path):
    folder, md = chain.unpack(native_fmus[version][name], tmp_path / ("%s%d" % (name, version)))
    sub = "linux64" if version == 2 else "x86_64-linux"
    return ctypes.CDLL(str(folder / "binaries" / sub / (name + ".so"))), md


def test_instantiate_refuses_null_arguments_and_a_foreign_guid(native_fmus, tmp_path):
    from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
    lib, md = _library(native_fmus, 2, "Excitation", tmp_path)
    lib.fmi2Instantiate.restype = ctypes.c_void_p
    lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                                    ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int,
                                    ctypes.c_int]
    messages = []
    logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg:
                                    messages.append(msg.decode()))
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = logger
    guid = md.guid.encode()
    assert not lib.fmi2Instantiate(b"e", 1, guid, b"", None, 0, 0)           # no callbacks
    assert not lib.fmi2Instantiate(None, 1, guid, b"", ctypes.byref(callbacks), 0, 0)
    assert "instanceName is NULL" in messages[-1]
    assert not lib.fmi2Instantiate(b"e", 1, None, b"", ctypes.byref(callbacks), 0, 0)
    assert not lib.fmi2Instantiate(b"e", 1, b"{not-this-one}", b"", ctypes.byref(callbacks),
                                   0, 0)
    assert "does not match" in messages[-1] and md.guid in messages[-1]
    assert not lib.fmi2Instantiate(b"e", 0, guid, b"", ctypes.byref(callbacks), 0, 0)
    assert "fmuType 0 is not supported" in messages[-1]
    for location in (None, b"", b"file:///nowhere", b"C:\\somewhere", b"relative/path"):
        c = lib.fmi2Instantiate(b"e", 1, guid, location, ctypes.byref(callbacks), 0, 0)
        assert c
        lib.fmi2FreeInstance.argtypes = [ctypes.c_void_p]
        lib.fmi2FreeInstance(c)


@pytest.mark.parametrize("version", VERSIONS)
def test_illegal_calls_are_refused_with_a_message_and_change_nothing(native_fmus, version):
    inst = FastInstance("sm", native_fmus[version]["DriftEstimator"])
    fmu = inst.fmu
    try:
        with pytest.raises(Exception):
            if version == 2:
                fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
            else:
                fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
        assert "not allowed in the instantiated mode" in inst.messages[-1]
        with pytest.raises(Exception):
            fmu.exitInitializationMode()
        assert "not allowed" in inst.messages[-1]
        inst.initialise({}, 0.0)
        with pytest.raises(Exception):
            fmu.enterInitializationMode()
        assert "not allowed in step mode" in inst.messages[-1]
        get = fmu.getReal if version == 2 else fmu.getFloat64
        before = get([inst.vrs[n] for n in OUTS["DriftEstimator"]])
        for h, text in ((math.nan, "h = nan s; allowed: a finite h > 0"),
                        (-1e-3, "h = -0.001 s; allowed: a finite h > 0"),
                        (0.0, "h = 0.0 s"), (math.inf, "h = inf s"),
                        (2.0e3, "spans more than 1000000 sample instants of Ts = 0.001 s")):
            with pytest.raises(Exception):
                fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=h)
            assert text in inst.messages[-1], inst.messages[-1]
        assert get([inst.vrs[n] for n in OUTS["DriftEstimator"]]) == before
        with pytest.raises(Exception):  # a mixed call with one bad value changes nothing
            (fmu.setReal if version == 2 else fmu.setFloat64)(
                [inst.vrs["z"], inst.vrs["x_hat"]], [0.5, 1.0])
        assert "x_hat is an output" in inst.messages[-1]
        assert get([inst.vrs["z"]]) == [0.0]
    finally:
        inst.free()


@pytest.mark.parametrize("version", VERSIONS)
def test_a_state_of_another_model_is_refused(native_fmus, version):
    a = FastInstance("a", native_fmus[version]["Accelerometer"])
    d = FastInstance("d", native_fmus[version]["DriftEstimator"])
    try:
        a.initialise({}, 0.0)
        d.initialise({}, 0.0)
        if version == 2:
            blob = a.fmu.serializeFMUstate(a.fmu.getFMUstate())
            with pytest.raises(Exception):
                d.fmu.setFMUstate(d.fmu.deSerializeFMUstate(blob))
        else:
            blob = a.fmu.serializeFMUState(a.fmu.getFMUState())
            with pytest.raises(Exception):
                d.fmu.setFMUState(d.fmu.deserializeFMUState(blob))
        assert "not an FMU state of DriftEstimator" in d.messages[-1]
        assert "a state of Accelerometer" in d.messages[-1]
    finally:
        a.free()
        d.free()


def test_fmi3_time_is_the_independent_variable(native_fmus):
    inst = FastInstance("t", native_fmus[3]["Excitation"])
    try:
        inst.initialise({}, 0.5)
        vr = inst.vrs["time"]
        assert vr == len(native_build.slave_class("Excitation").VARIABLES)
        inst.fmu.doStep(currentCommunicationPoint=0.5, communicationStepSize=2e-3)
        assert inst.fmu.getFloat64([vr]) == [0.502]
        with pytest.raises(Exception):
            inst.fmu.setFloat64([vr], [1.0])
        assert "independent variable" in inst.messages[-1]
    finally:
        inst.free()


def test_fast_master_reports_the_fmus_log(native_fmus):
    start = {"DriftEstimator": {"R": -1.0}}
    with pytest.raises(CoSimulationError, match="R = -1.0 is out of range; allowed: R > 0"):
        cosimulate_fast(chain_of(native_fmus[3]), gaussian.CONNECTIONS, 5, 1e-3, start_values=start)


# -- the SSP export, the cross-check artifacts, the command line ---------------------------------

def test_ssp_export_of_the_native_fmus_simulates_as_the_python_one(python_chain, native_fmus,
                                                                   tmp_path):
    from driftfmu.fmu_src import ssp
    python = ssp.simulate(ssp.build_ssp(python_chain, tmp_path / "py.ssp", n=100), 100)
    native = ssp.simulate(ssp.build_ssp(chain_of(native_fmus[2]), tmp_path / "c.ssp", n=100), 100)
    assert python.dtype.names == native.dtype.names
    for column in python.dtype.names:
        assert native[column].tolist() == python[column].tolist(), column


def test_cross_check_tree_has_a_folder_per_fmi_version_and_platform(native_fmus, tmp_path):
    from fmpy.cross_check.validate_vendor_repo import validate_test_fmu
    from driftfmu import __version__
    from driftfmu.fmu_src import crosscheck
    written = []
    for version in VERSIONS:   # each reference is checked against models/ as it is written
        written += crosscheck.write_cross_check(native_fmus[version], tmp_path, n=50,
                                                fmi_version=version, backend="native")
    # a folder for each platform whose binary the FMUs carry (Linux; in the qualification
    # Windows too)
    def carried(v):
        with zipfile.ZipFile(native_fmus[v]["Excitation"]) as archive:
            return {n.split("/")[1] for n in archive.namelist() if n.startswith("binaries/")}
    platforms = {v: carried(v) for v in VERSIONS}
    assert "linux64" in platforms[2] and "x86_64-linux" in platforms[3]
    expected = {tmp_path / "fmus" / ("%d.0" % v) / "cs" / p / "driftfmu" / __version__ / name
                for v in VERSIONS for p in platforms[v] for name in crosscheck.FMU_NAMES}
    assert set(written) == expected
    for d in written:
        name = d.name
        assert (d / (name + ".fmu")).is_file() and (d / (name + "_ref.csv")).is_file()
        assert "native C twin" in (d / "ReadMe.txt").read_text()
        if "/2.0/" in d.as_posix():
            assert validate_test_fmu(str(d)) == []


def test_command_line_takes_the_backend(native_fmus, tmp_path, capsys):
    from driftfmu.simulations.cli import main
    fmu_dir = native_fmus[2]["Excitation"].parent.parent.parent
    out = tmp_path / "g"
    assert main(["run", "gaussian", "--backend", "native", "--fmu-dir", str(fmu_dir), "--n",
                 "200", "--out", str(out)]) == 0
    assert (out / "results.csv").is_file()
    assert main(["run", "sinusoidal", "--backend", "native", "--fmu-dir", str(fmu_dir),
                 "--n", "200", "--out", str(tmp_path / "s")]) == 0
    with pytest.raises(SystemExit) as exc:
        main(["run", "gaussian", "--backend", "java"])
    assert exc.value.code == 2
    assert "backend = 'java' is not allowed; allowed: 'python', 'native'" in \
        capsys.readouterr().err


def test_montecarlo_fmu_engine_and_adxl203_experiment_on_the_native_fmus(native_fmus,
                                                                        built_fmus):
    from driftfmu.simulations import adxl203 as experiment
    from driftfmu.simulations.montecarlo import montecarlo_gaussian
    fmu_dir = native_fmus[2]["Excitation"].parent.parent.parent
    kw = dict(runs=3, n=150, engine="fmu", workers=1, plot=False)
    native = montecarlo_gaussian(fmu_dir=fmu_dir, backend="native", **kw)
    python = montecarlo_gaussian(fmu_dir=built_fmus["Excitation"].parent, **kw)
    for key in ("fig1_dc1", "fig1_dc2", "fig1_x", "fig1_z"):
        assert native[key].tolist() == python[key].tolist(), key
    small = dict(freqs=(150.0,), sets=4, held_out=1, n=1500, workers=1, plot=False)
    a = experiment.run_adxl203(fmu_dir=fmu_dir, backend="native", **small)
    b = experiment.run_adxl203(fmu_dir=built_fmus["Excitation"].parent, **small)
    assert a["per_frequency"][0]["dc_ekf1"] == b["per_frequency"][0]["dc_ekf1"]
    assert a["per_frequency"][0]["margin_db"] == b["per_frequency"][0]["margin_db"]
    assert a["backend"] == "native" and b["backend"] == "python"


@pytest.mark.parametrize("version", VERSIONS)
def test_doctor_says_a_native_fmu_needs_no_python(native_fmus, version, capsys):
    from driftfmu.simulations.cli import main
    assert main(["doctor", str(native_fmus[version]["DriftEstimator"])]) == 0
    out = capsys.readouterr().out
    assert "a native FMU (no Python inside)" in out and "PROBLEM" not in out
    assert ("linux64" if version == 2 else "x86_64-linux") in out



# -- the dual-axis chain (issue 11): the native twins gain the same, bit for bit -----------------

def _dual_chain_start(sweep, value, seed):
    from driftfmu.models import dualaxis
    from driftfmu.simulations import dual_axis
    ex, sp, es = dual_axis.start_values(sweep, value, dual_axis.DEFAULTS)
    full = dualaxis.estimator_values(**es)
    return {"Excitation": dict(ex, seed=seed), "Accelerometer": dict(sp, seed=seed),
            "DualDriftEstimator": es, "SingleX": dualaxis.single_values(full, 1),
            "SingleY": dualaxis.single_values(full, 2)}


DUAL_INSTANCES = {"Excitation": "Excitation", "Accelerometer": "Accelerometer",
                  "DualDriftEstimator": "DualDriftEstimator", "SingleX": "DriftEstimator",
                  "SingleY": "DriftEstimator"}


@pytest.fixture(scope="module")
def dual_python_results(built_fmus):
    from driftfmu.simulations import dual_axis
    paths = {i: built_fmus[f] for i, f in DUAL_INSTANCES.items()}
    return {(sweep, value): cosimulate(paths, dual_axis.CONNECTIONS, 400, 1e-3,
                                       start_values=_dual_chain_start(sweep, value, 3))
            for sweep, value in DUAL_POINTS}


DUAL_POINTS = (("dphi", 0.0), ("dphi", 2.0), ("rho", -0.9), ("rho", 0.5))


@pytest.mark.parametrize("sweep,value", DUAL_POINTS)
@pytest.mark.parametrize("version", VERSIONS)
def test_dual_chain_equals_the_python_fmus_bit_for_bit(native_fmus, dual_python_results,
                                                       version, sweep, value):
    """Excitation (Qy, rho; the second sinusoid) -> Accelerometer (dual = 1) ->
    DualDriftEstimator (both process models) and the two single-axis estimators."""
    from driftfmu.simulations import dual_axis
    paths = {i: native_fmus[version][f] for i, f in DUAL_INSTANCES.items()}
    start = _dual_chain_start(sweep, value, 3)
    fast = cosimulate_fast(paths, dual_axis.CONNECTIONS, 400, 1e-3, start_values=start)
    ref = dual_python_results[(sweep, value)]
    assert fast == ref
    assert any(v != 0.0 for v in ref["Excitation.y"]) and any(
        v != 0.0 for v in ref["DualDriftEstimator.dc_ekf1_y"])
    if version == 2:  # fmpy's FMU2Slave master on the native FMUs
        assert cosimulate(paths, dual_axis.CONNECTIONS, 400, 1e-3, start_values=start) == fast


@pytest.mark.parametrize("version", VERSIONS)
def test_native_dual_sensor_refuses_the_adxl203_extras_in_the_python_words(native_fmus,
                                                                           version):
    inst = FastInstance("dual", native_fmus[version]["Accelerometer"])
    try:
        with pytest.raises(Exception):  # fmi2Error / fmi3Error at the end of initialisation
            inst.initialise({"dual": 1, "fc": 100.0, "bits": 12}, 0.0)
        assert any("dual = 1 is not allowed with fc = 100.0, bits = 12; allowed: dual = 1 "
                   "with a3 = cross = fc = Vs = bits = density = 0" in m
                   for m in inst.messages), inst.messages
    finally:
        inst.free()
