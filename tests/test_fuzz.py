"""Fuzzing the FMUs from a C host (tests/fuzz): no crash, no hang, no fmi2OK with a non-finite
value, and a rejected call changes nothing.

Every script runs in its own process with a time limit.  This is the fixed-seed portion CI
runs; ``python3 -m tests.fuzz.run --seconds 600`` runs random scripts for ten minutes.
"""
import shutil
import zlib

import pytest

import fuzz
from fuzz import cases
from driftfmu.models import chain
from driftfmu.simulations.gaussian import CONNECTIONS, FMU_NAMES

pytestmark = pytest.mark.integration
SEEDS = range(4)
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

@pytest.mark.parametrize("seed", SEEDS)
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
    params = []
    for name in cases.CASES:
        for model in (FMU_NAMES if name in cases.ALL_MODELS else ("Accelerometer",)):
            marks = []
            if name in cases.PYTHON_SIDE:
                marks.append(pytest.mark.xfail(reason=cases.PYTHON_SIDE[name], strict=True))
            params.append(pytest.param(name, model, id="%s-%s" % (name, model), marks=marks))
    return params


@pytest.mark.parametrize("case, name", _invalid_params())
def test_invalid_calls_are_refused_and_change_nothing(host, models, case, name):
    result, problems, lines = cases.run_case(host, case, models[name], _other(models, name),
                                             _seed(case, name))
    assert problems == [], "\n".join(problems) + "\n" + result.output[-3000:]


@pytest.mark.parametrize("seed", range(6))
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
