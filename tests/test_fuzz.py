"""Fuzzing the FMUs from a C host (tests/fuzz): no crash, no hang, no fmi2OK with a non-finite
value, and a rejected call changes nothing; and the differential fuzz (tests/fuzz/differential.py):
the Python FMU, the native FMI 2.0 FMU and the native FMI 3.0 FMU of each model agree call by
call, with extreme parameters too, and no OK carries a negative variance.

Every script runs in its own process with a time limit.  This is the fixed-seed portion CI
runs; ``python3 -m tests.fuzz.run --seconds 600`` runs random scripts for ten minutes and
``python3 -m tests.fuzz.differential --seconds 1200`` the differential fuzz for twenty.
"""
import os
import shutil
import subprocess
import sys
import zlib
from pathlib import Path

import pytest

import fuzz
from fuzz import cases
from fuzz import differential
from driftfmu.models import chain
from driftfmu.simulations.gaussian import CONNECTIONS, FMU_NAMES

pytestmark = pytest.mark.integration
SEEDS = range(4)


def portions(count, loop):
    """``range(count)`` in two parameters: the first ``loop`` in the everyday loop, the rest in
    the qualification (the same cases, the same seeds: the loop is a prefix of the whole)."""
    return [pytest.param(range(0, loop), id="loop"),
            pytest.param(range(loop, count), id="rest", marks=pytest.mark.qualification)]
VALGRIND = ["-q", "--undef-value-errors=no", "--error-exitcode=99"]


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    exe = fuzz.compile_host(tmp_path_factory.mktemp("fuzz_host"))
    if exe is None:
        pytest.skip("no C compiler to build the fuzz host")
    return exe


@pytest.fixture(scope="module")
def models(built_fmus, tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz_models")
    return {name: fuzz.unzip(fmu, root / name) for name, fmu in built_fmus.items()}


def _other(models, name):
    return models["DriftEstimator" if name != "DriftEstimator" else "Accelerometer"]


def _seed(*words):
    """A fixed seed per test case (the same in every run)."""
    return zlib.crc32(" ".join(words).encode())


# -- valid sequences: replays agree ------------------------------------------------------------

@pytest.mark.parametrize("seed", [s if s == 0 else pytest.param(s, marks=pytest.mark.qualification)
                                  for s in SEEDS])
@pytest.mark.parametrize("name", FMU_NAMES)
def test_valid_sequences_replay_identically(host, models, name, seed):
    lines, pairs = fuzz.valid_sequence(models[name], seed, n_calls=60)
    result = fuzz.run_script(host, lines)
    assert result.problems() == [], result.output[-3000:]
    refused = {n: s for n, s in result.statuses().items() if s > fuzz.WARNING}
    assert not refused, (refused, result.output[-3000:])
    for first, second in pairs:
        a, b = fuzz.reads(result, first), fuzz.reads(result, second)
        assert len(a) > 3 and a == b


def test_chain_in_the_c_host_equals_models(host, models, report):
    """The three FMUs wired in one C process, as the master wires them, equal models/."""
    n = 100
    slot = {name: i for i, name in enumerate(FMU_NAMES)}
    outs = {"Excitation": ["x"], "Accelerometer": ["z"],
            "DriftEstimator": ["x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp"]}
    lines = []
    for name, i in slot.items():
        lines += fuzz.header(models[name], slot=i, lib=i, name=name)
        lines += fuzz.initialise(models[name], i)
    reads, t = [], 0.0
    for k in range(n):
        if k:
            lines += ["step %d %r 0.001" % (i, t) for i in range(3)]
            t += 0.001
        for src, out, dst, inp in CONNECTIONS:
            lines.append("copy %d %d %d %d" % (slot[src], models[src].vr[out], slot[dst],
                                               models[dst].vr[inp]))
        row = []
        for name in FMU_NAMES:
            vrs = [models[name].vr[o] for o in outs[name]]
            lines.append("getr %d %d %s" % (slot[name], len(vrs), " ".join(map(str, vrs))))
            row.append(len(lines))
        reads.append(row)
    result = fuzz.run_script(host, lines)
    assert result.problems() == [], result.output[-3000:]
    printed = result.values()
    rows = [tuple(float(v) for line in row for v in printed[line]) for row in reads]
    ref = chain.simulate(n, 1)
    expected = [tuple(ref[c][k] for c in ["x", "z", "x_hat", "P", "dc_ekf1", "dc_ekf2",
                                           "dc_ekf3", "z_comp"]) for k in range(n)]
    report("FUZZ chain in the C host: %d communication points, equal to models/ bit for bit: %s"
           % (n, rows == expected))
    assert rows == expected


# -- invalid calls -----------------------------------------------------------------------------

def _invalid_params():
    """Every case on every model it applies to; the everyday loop runs each case once, on the
    models in turn (every model about as often), the qualification the rest."""
    params = []
    for i, name in enumerate(cases.CASES):
        models = FMU_NAMES if name in cases.ALL_MODELS else ("Accelerometer",)
        for model in models:
            marks = []
            if name in cases.PYTHON_SIDE:
                marks.append(pytest.mark.xfail(reason=cases.PYTHON_SIDE[name], strict=True))
            if model != models[i % len(models)]:
                marks.append(pytest.mark.qualification)
            params.append(pytest.param(name, model, id="%s-%s" % (name, model), marks=marks))
    return params


@pytest.mark.parametrize("case, name", _invalid_params())
def test_invalid_calls_are_refused_and_change_nothing(host, models, case, name):
    result, problems, lines = cases.run_case(host, case, models[name], _other(models, name),
                                             _seed(case, name))
    assert problems == [], "\n".join(problems) + "\n" + result.output[-3000:]


@pytest.mark.parametrize("seed", [s if s < 2 else pytest.param(s, marks=pytest.mark.qualification)
                                  for s in range(6)])
def test_random_mixes_of_invalid_calls(host, models, seed):
    rng = __import__("random").Random(seed)
    name = rng.choice(FMU_NAMES)
    pool = [c for c in cases.CASES if c not in cases.PYTHON_SIDE
            and (c in cases.ALL_MODELS or name == "Accelerometer")]
    chosen = rng.sample(pool, 4)
    result, problems, lines = cases.run_case(host, chosen, models[name], _other(models, name),
                                             seed)
    assert problems == [], (chosen, problems, result.output[-3000:])


def test_a_crash_a_hang_and_a_change_are_seen(host, models, tmp_path):
    """The judge itself: a host killed by a signal, one that hangs, and a reported change."""
    crash = tmp_path / "crash.sh"
    crash.write_text("#!/bin/sh\nkill -SEGV $$\n")
    crash.chmod(0o755)
    assert fuzz.run_script(str(crash), []).crashed
    assert "SIGSEGV" in fuzz.run_script(str(crash), []).problems()[0]
    hang = tmp_path / "hang.sh"
    hang.write_text("#!/bin/sh\nsleep 30\n")
    hang.chmod(0o755)
    assert fuzz.run_script(str(hang), [], time_limit=0.5).problems()[0].startswith("hang")
    changed = fuzz.Result(0, "S 3 setr 3\nCHANGED 3 setr\nEND\n")
    assert any("changed" in p for p in changed.problems())


# -- under valgrind ----------------------------------------------------------------------------

@pytest.mark.qualification
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.parametrize("name", ["Accelerometer", "DriftEstimator"])
def test_under_valgrind_no_invalid_memory_access(host, models, name, report):
    """Most invalid cases in one script each, under valgrind: no invalid read, write or free
    (Python's uninitialised-value reports are not counted)."""
    chosen = [c for c in cases.CASES if c not in cases.PYTHON_SIDE
              and (c in cases.ALL_MODELS or name == "Accelerometer")
              and not c.startswith("step_size_huge")]
    result, problems, lines = cases.run_case(host, chosen, models[name], _other(models, name),
                                             _seed("valgrind", name), valgrind=VALGRIND,
                                             time_limit=600)
    report("FUZZ valgrind %s: %d cases, %d calls, exit code %d" % (
        name, len(chosen), len(lines), result.returncode))
    assert result.returncode != 99, result.output[-5000:]
    assert problems == [], (problems, result.output[-3000:])


# -- the differential fuzz: Python FMU, native FMI 2.0, native FMI 3.0, call by call -----------

#: Scripts per model in the fixed-seed portion (about a minute for the four models), and those
#: of them in the everyday loop.
DIFFERENTIAL_SCRIPTS = 80
DIFFERENTIAL_SCRIPTS_LOOP = 25


@pytest.fixture(scope="module")
def twins(python_fmus, native_fmus, tmp_path_factory):
    """{model: {backend: unzipped folder}} of the three implementations of each model."""
    return differential.unzip_all(python_fmus, native_fmus,
                                  tmp_path_factory.mktemp("differential"))


@pytest.mark.parametrize("portion", portions(DIFFERENTIAL_SCRIPTS, DIFFERENTIAL_SCRIPTS_LOOP))
@pytest.mark.parametrize("name", differential.MODELS)
def test_python_and_native_twins_agree_call_by_call(twins, name, portion, report):
    seeds = [_seed("differential", name, str(i)) for i in portion]
    problems = differential.run(twins[name], seeds)
    report("FUZZ differential %s: %d scripts of about 100 calls on the Python FMU, the native "
           "FMI 2.0 and FMI 3.0 FMUs: %d disagreements" % (name, len(seeds), len(problems)))
    assert problems == [], "\n".join(problems[:10])


def test_a_state_got_while_sample_1_overflows_restores_in_every_twin(twins):
    """Found by the differential fuzz (seed 3302): after an exit whose sample 1 overflows
    (B = -1e308), the native Excitation had already written x = inf into its outputs, so a state
    got then was refused when set again ("x = inf is not finite"); the Python FMU, which
    computes sample 1 only when it is read, restored it.  Now every twin restores it, and
    still refuses to read the sample."""
    script = [["setup", -2.0], ["enter"], ["setr", ["u_in"], [-1.826915875]],
              ["setr", ["B"], [-1e308]], ["exit"], ["getr", ["x", "y", "u"]], ["gst", 0],
              ["reset"], ["setup", 1.5], ["enter"], ["exit"], ["getr", ["x", "y", "u"]],
              ["sst", 0], ["getr", ["x", "y", "u"]]]
    info = differential.model_info(twins["Excitation"]["native-fmi2"])
    results = {}
    for name, fmi in (("python", 2), ("native-fmi2", 2), ("native-fmi3", 3)):
        driver = differential.Driver(twins["Excitation"][name], fmi)
        driver.reset()
        try:
            results[name] = differential.run_script(driver, script, info["reals"])
        finally:
            driver.free()
    assert differential.compare(script, results) == []
    for name, rows in results.items():
        assert [row[0] for row in rows] == [0, 0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 3], name


#: Scripts per model with extreme parameters at every initialisation (issue 31), in the loop
#: and in the release qualification.
EXTREME_SCRIPTS = 12
EXTREME_SCRIPTS_QUALIFICATION = 600


@pytest.mark.parametrize("name", differential.MODELS)
def test_extreme_parameters_agree_and_no_ok_carries_a_negative_variance(twins, name, report):
    """Extreme parameters (near overflow, P0 = 1e154, x0 = 3e8, R = 5e-324, ...) and the harmonic
    filter at every initialisation: the three twins agree call by call, and no call answered OK
    reads a negative variance or gives a state whose filter covariance is not valid."""
    seeds = [_seed("extreme", name, str(i)) for i in range(EXTREME_SCRIPTS)]
    problems = differential.run(twins[name], seeds, extreme=True)
    report("FUZZ differential %s, extreme parameters: %d scripts, %d problems"
           % (name, len(seeds), len(problems)))
    assert problems == [], "\n".join(problems[:10])


@pytest.mark.qualification
@pytest.mark.parametrize("name", differential.MODELS)
def test_extreme_parameters_long_run(twins, name, report):
    seeds = [_seed("extreme-long", name, str(i)) for i in range(EXTREME_SCRIPTS_QUALIFICATION)]
    problems = differential.run(twins[name], seeds, extreme=True, time_limit=3000)
    report("FUZZ differential %s, extreme parameters, qualification: %d scripts, %d problems"
           % (name, len(seeds), len(problems)))
    assert problems == [], "\n".join(problems[:10])


class _Crafted:
    """A driver whose serialised state is ``data`` (the judge's test below)."""

    def __init__(self, driver, data):
        self.md, self.dir, self.fmi, self._data = driver.md, driver.dir, driver.fmi, data

    def ser(self, slot):
        return differential.OK, self._data


@pytest.mark.parametrize("backend", differential.BACKENDS)
def test_the_fuzz_sees_a_negative_variance_answered_ok(twins, backend):
    """The judge can fail: a variance output read as -1 with OK, and a state got with OK whose
    hidden P22 is negative (crafted into the serialised bytes of a real state), are reported."""
    import json
    from fuzz import native_state as ns
    drv = differential.Driver(twins["DriftEstimator"][backend], 3 if backend.endswith("3") else 2)
    try:
        for call in (["setup", 0.0], ["enter"], ["seti", ["process"], [2]], ["exit"],
                     ["step", 0.0, 1e-3], ["gst", 0]):
            assert getattr(drv, call[0])(*call[1:])[0] == differential.OK
        assert differential.variance_problems(drv, ["gst", 0], differential.OK, None) == []
        assert differential.variance_problems(drv, ["getr", ["x_hat", "P"]], differential.OK,
                                              [(0.5).hex(), (-1.0).hex()]) == \
            ["P = -1.0 is a negative variance"]
        data = drv.ser(0)[1]
        if backend == "python":
            state = json.loads(data)
            state["_state"][4] = -1.0
            data = json.dumps(state).encode()
        else:
            data = ns.crafted(ns.snapshot_type(drv.dir), data, "h.state.P22", -1.0)
        found = differential.variance_problems(_Crafted(drv, data), ["gst", 0],
                                               differential.OK, None)
        assert len(found) == 1 and "covariance" in found[0], found
    finally:
        drv.free()


#: Scripts per model with every instance compared around every call, and those of them in the
#: everyday loop.
CHECKED_SCRIPTS = 20
CHECKED_SCRIPTS_LOOP = 8


@pytest.mark.parametrize("portion", portions(CHECKED_SCRIPTS, CHECKED_SCRIPTS_LOOP))
@pytest.mark.parametrize("name", differential.MODELS)
def test_a_refused_call_changes_no_twin(twins, name, portion, report):
    """Every call that one of the three refuses (an error or worse) leaves that instance as it
    was: the statuses and values of every Real, and its serialised state, compared before and
    after the call (the case fuzz checks this in its FMI 2.0 host; this reaches the FMI 3.0
    twin too)."""
    seeds = [_seed("checked", name, str(i)) for i in portion]
    problems = differential.run(twins[name], seeds, check=True)
    report("FUZZ differential %s, every refused call checked: %d scripts on the three "
           "backends: %d problems" % (name, len(seeds), len(problems)))
    assert problems == [], "\n".join(problems[:10])


def test_the_differential_child_imports_the_driftfmu_of_its_parent(monkeypatch, tmp_path):
    """``python -m tests.fuzz.differential`` in a checkout that is not installed: the child runs
    as a script from tests/fuzz, so it finds driftfmu only because its PYTHONPATH starts with
    the folder of the parent's driftfmu (the host's own PYTHONPATH entries kept after it)."""
    import driftfmu
    root = str(Path(driftfmu.__file__).resolve().parent.parent)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), root]))
    monkeypatch.delenv("PYTHONMALLOC", raising=False)
    env = differential.child_environment()
    assert env["PYTHONPATH"].split(os.pathsep) == [root, str(tmp_path)]
    assert "PYTHONMALLOC" not in env
    assert differential.child_environment(valgrind=True)["PYTHONMALLOC"] == "malloc"
    done = subprocess.run([sys.executable, "-c", "import driftfmu; print(driftfmu.__file__)"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == driftfmu.__file__


@pytest.mark.qualification  # rebuilds a native twin with the defect planted
def test_the_differential_fuzz_reports_a_planted_difference(twins, tmp_path):
    """The judge can fail: the defect of issue 20 (a refused exit of initialisation that moves
    the instance to step mode anyway) planted into a rebuilt copy of the native FMI 2.0 twin is
    reported, as is a value changed in the FMI 3.0 twin's answers."""
    seeds = [_seed("planted", str(i)) for i in range(12)]
    planted = dict(twins["DriftEstimator"])
    planted["native-fmi2"] = differential.plant_defect(planted["native-fmi2"],
                                                       tmp_path / "planted")
    problems = differential.run(planted, seeds)
    assert problems and all("python vs native-fmi2" in p for p in problems), problems
    assert any('["getr"' in p and "status 3 vs 0" in p for p in problems), problems
    assert differential.run(twins["DriftEstimator"], seeds) == []  # the unplanted twin agrees
    problems = differential.run(twins["Excitation"], seeds[:2], plant="native-fmi3")
    assert len(problems) == 2 and all("python vs native-fmi3: values" in p for p in problems)
    # and with every refused call checked, the planted twin is caught changing its instance
    problems = differential.run(planted, seeds[:4], check=True)
    assert any("a refused call changed the native-fmi2 instance" in p for p in problems), \
        problems


@pytest.mark.qualification  # (a native build a class: about 6 s each)
@pytest.mark.parametrize("defect", sorted(differential.PLANTED_31))
def test_the_differential_fuzz_sees_the_issue_31_classes_planted_back(twins, tmp_path, defect):
    """The scripts reach each class of issue 31's plumbing: with its fix planted out of a
    rebuilt copy of the native FMI 2.0 twin, the fuzz reports it (a state kept across
    fmi2FreeInstance taken by the next instance, a step past the stop time taken, a count no
    array can have read: the child crashes)."""
    planted = dict(twins["DriftEstimator"])
    planted["native-fmi2"] = differential.plant_defect(
        planted["native-fmi2"], tmp_path / defect, differential.PLANTED_31[defect])
    seeds = [_seed("planted-31", str(i)) for i in range(40)]
    problems = differential.run(planted, seeds)
    assert problems, defect
    if defect != "counts":
        assert all("python vs native-fmi2" in p for p in problems), problems
    else:
        assert any("the child exited with -11" in p for p in problems), problems  # SIGSEGV


#: Scripts per model of the long run (qualification): with each instance compared around every
#: call, about five minutes on this machine for the four models.
LONG_SCRIPTS = 1500


@pytest.mark.qualification
@pytest.mark.parametrize("name", differential.MODELS)
def test_python_and_native_twins_agree_over_many_scripts(twins, name, report):
    """The long run of the differential fuzz, every refused call checked to change nothing:
    stop times, states kept across FreeInstance, impossible counts among the rest."""
    seeds = [_seed("long", name, str(i)) for i in range(LONG_SCRIPTS)]
    problems = []
    for at in range(0, len(seeds), 100):
        problems += differential.run(twins[name], seeds[at:at + 100], check=True,
                                     time_limit=1800)
    report("FUZZ differential %s, long: %d scripts on the three backends, every refused call "
           "checked: %d problems" % (name, len(seeds), len(problems)))
    assert problems == [], "\n".join(problems[:10])


# -- the case fuzz on the native FMI 2.0 twins, and under valgrind -----------------------------

#: Cases whose expectation holds for the Python FMUs only, and why.
NATIVE_DIFFERS = {name: "the native FMUs need no resources: fmi2Instantiate takes any "
                  "fmuResourceLocation, NULL included (the standard lets an FMU without "
                  "resources ignore it)" for name in cases.CASES if name.startswith("uri_")}


@pytest.fixture(scope="module")
def native_models(native_fmus, tmp_path_factory):
    root = tmp_path_factory.mktemp("fuzz_native_models")
    return {name: fuzz.unzip(fmu, root / name) for name, fmu in native_fmus[2].items()}


def _native_params():
    return [pytest.param(name, model, id="%s-%s" % (name, model))
            for name in cases.CASES if name not in NATIVE_DIFFERS
            for model in (differential.MODELS if name in cases.ALL_MODELS
                          else ("Accelerometer",))]


@pytest.mark.parametrize("case, name", _native_params())
def test_native_twins_refuse_invalid_calls_and_change_nothing(host, native_models, case, name):
    result, problems, lines = cases.run_case(host, case, native_models[name],
                                             _other(native_models, name), _seed(case, name))
    assert problems == [], "\n".join(problems) + "\n" + result.output[-3000:]


@pytest.mark.qualification
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.parametrize("name", differential.MODELS)
def test_native_twins_under_valgrind_no_invalid_memory_access(host, native_models, name,
                                                              report):
    """Every invalid case that applies, in one script per model, the native FMI 2.0 twin under
    valgrind: no invalid read, write or free."""
    chosen = [c for c in cases.CASES if c not in NATIVE_DIFFERS
              and (c in cases.ALL_MODELS or name == "Accelerometer")]
    result, problems, lines = cases.run_case(host, chosen, native_models[name],
                                             _other(native_models, name),
                                             _seed("valgrind-native", name), valgrind=VALGRIND,
                                             time_limit=600)
    report("FUZZ valgrind native %s: %d cases, %d calls, exit code %d" % (
        name, len(chosen), len(lines), result.returncode))
    assert result.returncode != 99, result.output[-5000:]
    assert problems == [], (problems, result.output[-3000:])


@pytest.mark.qualification
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_differential_fuzz_under_valgrind(twins, report):
    """A few differential scripts with the whole child process under valgrind: the shim, the
    Python FMU and both native twins, no invalid memory access."""
    seeds = [_seed("differential-valgrind", "0")]  # CPython under valgrind: minutes a script
    problems = differential.run(twins["DriftEstimator"], seeds, n_calls=40, valgrind=True,
                                time_limit=1500)
    report("FUZZ differential under valgrind: %d scripts, %d problems" % (len(seeds),
                                                                           len(problems)))
    assert problems == [], "\n".join(problems)[-5000:]
