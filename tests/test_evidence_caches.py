"""Blocks and caches keyed on everything they depend on (issue 32): each dependency changed
alone, and what is served afterwards is what a fresh computation gives.

- the Python FMUs' precomputed blocks (``fmu_src/slave_base.py``'s ``Blocks``: the draws, the
  sinusoids, the known input): an instance whose blocks are made takes, by an FMU state
  restored (``fmi2SetFMUstate``) or in Initialization Mode, any one parameter changed; its
  outputs from then on equal a fresh instance's with that parameter, bit for bit, for every
  parameter of every slave;
- the native build's library cache: the platform, the compiler command, its version, its
  extra flags, the common flags, the C files' order, a staged source's name and its bytes;
- fastcosim's unpack cache: an FMU rewritten in place, with the same size and modification
  time;
- the compiled batch kernel and the fast master's C loop in the temporary folder: the
  compiler, and the flags they are compiled with.
"""
import math
import os
import struct
import zipfile

import pytest
from pythonfmu.enums import Fmi2Causality

from driftfmu.fmu_src.Accelerometer import Accelerometer
from driftfmu.fmu_src.DriftEstimator import DriftEstimator
from driftfmu.fmu_src.Excitation import Excitation
from driftfmu.models import parameters

from test_hardening import put, ready, vr








def _outputs(slave, steps, t0=0.0, Ts=1e-3):
    """The bits of every Real output over ``steps`` steps of 1, 3 and 1/2 samples (inputs set
    from the sample number, the same in every run)."""
    outs = [v.value_reference for v in slave.vars.values()
            if type(v).__name__ == "Real" and v.causality == Fmi2Causality.output]
    assert outs
    inputs = [s["name"] for s in type(slave).VARIABLES if s["causality"] == "input"]
    rows, t = [], t0
    for i in range(steps):
        for j, name in enumerate(inputs):
            put(slave, name, 0.3 * math.sin(0.7 * i + j) + 0.1 * j)
        rows.append(struct.pack("<%dd" % len(outs), *slave.get_real(outs)))
        h = Ts * (3 if i % 5 == 2 else 0.5 if i % 7 == 4 else 1)
        assert slave.do_step(t, h), [m.msg for m in slave.log_queue]
        t += h
    return rows


#: Slaves whose samples read blocks, each kind of block in use (and every other parameter).
CONFIGS = {
    "Excitation Gaussian, Gaussian input": (Excitation, dict(A=0.6, Q=0.05, B=0.8, drive=1,
                                                             Qu=0.3, Ts=1e-3, seed=11)),
    "Excitation Gaussian, second axis, sinusoidal input": (Excitation, dict(
        A=-0.4, Q=0.05, Qy=0.02, rho=0.3, B=-0.5, drive=2, Xu=0.9, fu=40.0, Ts=1e-3,
        seed=12)),
    "Excitation sinusoidal, sinusoidal input": (Excitation, dict(
        kind=2, X=1.2, f=30.0, phi=0.4, Xy=0.5, phiy=1.1, drive=2, Xu=0.7, fu=45.0, B=0.3,
        Ts=1e-3, seed=13)),
    "Accelerometer, two axes": (Accelerometer, dict(a0=0.1, a2=0.05, a3=0.02, a4=-0.01,
                                                    R=1e-3, axes=2, cross=0.02, Ts=1e-3,
                                                    seed=14)),
    "DriftEstimator": (DriftEstimator, dict(a2=0.05, a3=0.02, a4=0.01, A=0.5, B=0.7, Ts=1e-3)),
}

#: A changed value for parameters whose general rule (below) would not be valid or telling.
CHANGED = {"kind": None, "process": None, "dual": None, "axes": None, "noise": 0, "drive": None,
           "estimator": 2, "bits": 10, "seed": None, "Ts": 1.25e-3, "Vs": 4.0, "fc": 300.0,
           "cross": 0.1, "rho": -0.2, "A": 0.3}


def _changed(name, value):
    """A valid value of parameter ``name`` other than ``value`` (None: the parameter switches a
    mode, tested as its own configuration above)."""
    if name in CHANGED:
        if name == "seed":
            return value + 1
        if name == "drive" and value == 2:
            return 1
        return CHANGED[name]
    new = value * 1.25 + 0.05 if value >= 0 else value * 0.8
    return new if parameters.problem(name, new) is None else None


def _cases():
    out = []
    for config, (cls, base) in CONFIGS.items():
        s = cls(instance_name="probe")
        values = dict(s.parameter_values(), **base)
        for name, value in sorted(values.items()):
            new = _changed(name, value)
            if new is not None and new != value:
                out.append(pytest.param(cls, base, name, new, id="%s: %s" % (config, name)))
    return out


CASES = _cases()


@pytest.mark.parametrize("cls, base, name, value", CASES)
def test_a_state_restore_with_any_one_parameter_changed_makes_its_blocks_anew(cls, base, name,
                                                                               value):
    """The instance made its blocks under ``base`` (20 steps); a state with ``name`` changed
    alone is restored into it: from there its outputs are those of a fresh instance with that
    parameter, bit for bit."""
    used = ready(cls, **base)
    _outputs(used, 20)
    fresh = ready(cls, **dict(base, **{name: value}))
    state = fresh._get_fmu_state()
    used._set_fmu_state(state)
    assert not used.log_queue, [m.msg for m in used.log_queue]
    assert _outputs(used, 30) == _outputs(fresh, 30)


def test_the_block_parameters_matter_where_they_are_tested():
    """Each parameter a block depends on changes the outputs of its configuration above, so a
    block that did not follow it would be seen."""
    keys = {Excitation: ("seed", "Ts", "Qu", "Xu", "fu", "drive", "X", "f", "phi", "Xy", "phiy"),
            Accelerometer: ("seed",)}
    seen = set()
    for config, (cls, base) in CONFIGS.items():
        if cls not in keys:
            continue
        before = _outputs(ready(cls, **base), 30)
        for name in keys[cls]:
            value = dict(ready(cls).parameter_values(), **base)[name]
            new = _changed(name, value)
            if new is None or new == value:
                continue
            if _outputs(ready(cls, **dict(base, **{name: new})), 30) != before:
                seen.add((cls.__name__, name))
    assert seen >= {("Excitation", n) for n in keys[Excitation]} | {("Accelerometer", "seed")}


@pytest.mark.parametrize("name, value", [("Ts", 2e-3), ("fu", 25.0), ("Xu", 0.4), ("seed", 5),
                                         ("Qu", 0.7), ("drive", 1)])
def test_a_parameter_set_again_in_initialization_mode_makes_its_blocks_anew(name, value):
    """Outputs read in Initialization Mode make the blocks; a parameter set after that, before
    Exit Initialization Mode, is the one the samples take."""
    base = dict(A=0.5, Q=0.05, B=0.8, drive=2, Qu=0.2, Xu=1.1, fu=40.0, Ts=1e-3, seed=3)
    s = Excitation(instance_name="e")
    s.setup_experiment(0.0)
    s.enter_initialization_mode()
    for k, v in base.items():
        put(s, k, v)
    s.get_real([vr(s, "x"), vr(s, "u")])  # sample 1, from the blocks of base
    put(s, name, value)
    s.exit_initialization_mode()
    assert not s.log_queue, [m.msg for m in s.log_queue]
    fresh = ready(Excitation, **dict(base, **{name: value}))
    assert _outputs(s, 1100) == _outputs(fresh, 1100)  # across the blocks' 1024 samples


# -- the native build's library cache --------------------------------------------------------

@pytest.fixture()
def staged(tmp_path):
    from driftfmu.fmu_src import native_build
    sources = tmp_path / "sources"
    c_files = native_build.stage_sources("Excitation", 3, sources)
    return native_build, sources, c_files


def test_the_native_library_cache_key_follows_each_input_alone(staged, monkeypatch):
    """The key (``native_build._cache_key``) changes when any one thing the library's bytes
    depend on changes, and not when nothing does."""
    native_build, sources, c_files = staged
    platform = "x86_64-linux"
    monkeypatch.setattr(native_build, "compiler_version", lambda command: "cc 12.2")
    command, extra, label = native_build.compiler(platform)
    base = native_build._cache_key(platform, sources, c_files)
    assert native_build._cache_key(platform, sources, list(c_files)) == base
    changes = {}
    changes["platform"] = native_build._cache_key("x86_64-windows", sources, c_files)
    monkeypatch.setattr(native_build, "compiler_version", lambda command: "cc 12.3")
    changes["compiler version"] = native_build._cache_key(platform, sources, c_files)
    monkeypatch.setattr(native_build, "compiler_version", lambda command: "cc 12.2")
    with monkeypatch.context() as m:
        m.setattr(native_build, "compiler", lambda p: (list(command) + ["-m64"], extra, label))
        changes["compiler command"] = native_build._cache_key(platform, sources, c_files)
    with monkeypatch.context() as m:
        m.setattr(native_build, "compiler", lambda p: (command, tuple(extra) + ("-g",), label))
        changes["extra flags"] = native_build._cache_key(platform, sources, c_files)
    with monkeypatch.context() as m:
        m.setattr(native_build, "CFLAGS", tuple(native_build.CFLAGS) + ("-DNDEBUG",))
        changes["common flags"] = native_build._cache_key(platform, sources, c_files)
    changes["C files' order"] = native_build._cache_key(platform, sources, c_files[::-1])
    first = sources / c_files[0]
    data = first.read_bytes()
    first.rename(sources / ("renamed_" + c_files[0]))
    changes["a source's name"] = native_build._cache_key(platform, sources, c_files)
    (sources / ("renamed_" + c_files[0])).rename(first)
    assert native_build._cache_key(platform, sources, c_files) == base
    first.write_bytes(data.replace(b";", b"; ", 1))
    changes["a source's bytes"] = native_build._cache_key(platform, sources, c_files)
    same = [what for what, key in changes.items() if key == base]
    assert not same, same


# -- fastcosim's unpack cache -----------------------------------------------------------------

def _fmu(path, text):
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("modelDescription.xml", text)
        archive.writestr("resources/data.txt", text)


def test_an_fmu_rewritten_in_place_with_the_same_size_and_time_is_unpacked_anew(tmp_path,
                                                                                 monkeypatch):
    """A build that writes an FMU again at the same path (same size; a file system with coarse
    times, or a copy that keeps the time) must not get the folder of the one before."""
    from driftfmu.simulations import fastcosim
    monkeypatch.setattr(fastcosim, "_UNPACKED", {})
    monkeypatch.setattr(fastcosim, "checked_fmu", lambda path, validate: None)
    monkeypatch.setattr(fastcosim.fmucheck, "check_binaries", lambda path, folder, md: None)
    monkeypatch.setattr(fastcosim.schemas, "read_model_description",
                        lambda folder, validate: open(os.path.join(folder,
                                                                   "modelDescription.xml")).read())
    path = tmp_path / "A.fmu"
    _fmu(path, "<first/>")
    folder, md = fastcosim.unpacked(str(path))
    assert md == "<first/>" and fastcosim.unpacked(str(path))[0] == folder  # kept
    stat = os.stat(path)
    _fmu(path, "<other/>")  # same length
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert os.stat(path).st_size == stat.st_size and os.stat(path).st_mtime_ns == stat.st_mtime_ns
    folder2, md2 = fastcosim.unpacked(str(path))
    assert md2 == "<other/>" and folder2 != folder
    with open(os.path.join(folder2, "resources", "data.txt")) as fh:
        assert fh.read() == "<other/>"


# -- the compiled kernel and the C loop in the temporary folder -------------------------------

def test_the_kernel_and_the_loop_are_named_by_their_compiler_and_flags(monkeypatch):
    """The libraries compiled into the temporary folder are named by what their bytes depend
    on: another compiler (``CC``, or the same command answering another ``--version``) or
    other flags is another file, not the one compiled before."""
    from driftfmu.simulations import fastcosim, kernel
    monkeypatch.setenv("CC", "cc")
    monkeypatch.setattr(kernel, "compiler_identity", lambda command: "cc 12.2 " + " ".join(command))
    names = {"kernel": [kernel.target()], "loop": [fastcosim.loop_target()]}
    assert kernel.target() == names["kernel"][0] and fastcosim.loop_target() == names["loop"][0]
    monkeypatch.setenv("CC", "gcc-13")
    names["kernel"].append(kernel.target())
    names["loop"].append(fastcosim.loop_target())
    monkeypatch.setenv("CC", "cc")
    monkeypatch.setattr(kernel, "compiler_identity", lambda command: "cc 12.3 " + " ".join(command))
    names["kernel"].append(kernel.target())
    names["loop"].append(fastcosim.loop_target())
    monkeypatch.setattr(kernel, "MACHINE_FLAGS", ("-march=x86-64",))
    names["kernel"].append(kernel.target())
    monkeypatch.setattr(fastcosim, "LOOP_FLAGS", ("-O1",) + fastcosim.LOOP_FLAGS[1:])
    names["loop"].append(fastcosim.loop_target())
    for what, targets in names.items():
        assert len(set(targets)) == len(targets), (what, targets)
