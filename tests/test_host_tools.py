"""The command-line hosts of docs/hosts.md, their recipes run as the page writes them: fmusim
(Reference-FMUs; ``--output-file``, 16 printed digits) and fmi-sim (Rust; an output interval of
at most Ts/2).  Each FMU runs from ``driftfmu inputs``' files; the rows at the sample instants are
compared with ``driftfmu.simulate``'s: bit for bit where the host writes every double whole, to
its printed digits where it does not.

Neither host is a Python package: ``DRIFTFMU_FMUSIM`` and ``DRIFTFMU_FMI_SIM`` name the
executables (else ``fmusim`` and ``fmi-sim`` on PATH); without one its tests skip and say how to
get it."""
import csv
import os
import shlex
import shutil
import subprocess

import numpy as np
import pytest

import driftfmu
from driftfmu.simulations.cli import main
from recipes import commands

pytestmark = pytest.mark.integration

TS = 1e-3
CHAIN = ("Excitation", "Accelerometer", "DriftEstimator")
#: The start values of the recipes (docs/hosts.md): a2 = 0.02, seed = 7.
USER = {"a2": 0.02, "seed": 7}


def _tool(env, name, how):
    path = os.environ.get(env) or shutil.which(name)
    if not path or not os.access(path, os.X_OK):
        pytest.skip("%s not found (%s); %s" % (
            name, "%s=%s is not an executable" % (env, path) if path
            else "not on PATH and %s not set" % env, how))
    return path


def _fmusim():
    return _tool("DRIFTFMU_FMUSIM", "fmusim",
                 "build it from Reference-FMUs' sources (github.com/modelica/Reference-FMUs, "
                 "fmusim/, release v0.0.39) or take the fmusim binary of a release, and put "
                 "it on PATH or set DRIFTFMU_FMUSIM to it")


def _fmi_sim():
    return _tool("DRIFTFMU_FMI_SIM", "fmi-sim",
                 "cargo install fmi-sim (crates.io), and put ~/.cargo/bin on PATH or set "
                 "DRIFTFMU_FMI_SIM to it")


def _fmus(kind, python_fmus, native_fmus):
    return python_fmus if kind == "python" else native_fmus[int(kind[-1])]


def _reference(kind, fmus_in_build_layout, stop):
    backend, version = ("python", 2) if kind == "python" else ("native", int(kind[-1]))
    return driftfmu.simulate(stop_time=stop, start_values=USER, backend=backend,
                             fmi_version=version, fmu_dir=fmus_in_build_layout)


def _run_recipe(name, exe, fmus, cwd):
    """The recipe's lines in ``cwd`` (the FMUs copied there under their names): the host's
    with ``exe`` in place of its name, ``driftfmu inputs`` through the command's main."""
    for n in CHAIN:
        shutil.copy(fmus[n], cwd / ("%s.fmu" % n))
    lines = commands(name)
    assert len(lines) == 5, lines
    for line in lines:
        argv = shlex.split(line)
        if argv[0] == "driftfmu":
            here = os.getcwd()
            os.chdir(cwd)
            try:
                assert main(argv[1:]) == 0, line
            finally:
                os.chdir(here)
        else:
            done = subprocess.run([exe] + argv[1:], cwd=cwd, capture_output=True, text=True,
                                  timeout=600)
            assert done.returncode == 0, (line, done.stdout, done.stderr)
    return lines


def _read(path):
    from fmpy.util import read_csv
    return read_csv(str(path))


def _at_instants(result):
    """The first row at each sample instant t_k (an input file's change is a repeated time
    stamp a quarter period after the instant, not at it)."""
    t = result["time"]
    k = np.rint(t / TS)
    at = np.flatnonzero(np.abs(t / TS - k) < 1e-6)
    _, first = np.unique(k[at], return_index=True)
    return result[at[first]]


def _printed(values):
    """``values`` as a host prints them with ``%.16g`` and reads them back."""
    return np.array([float("%.16g" % v) for v in values])


# -- fmusim -------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["python", "native-fmi2", "native-fmi3"])
def test_fmusim_runs_the_recipe_as_written_to_its_printed_digits(
        kind, python_fmus, native_fmus, fmus_in_build_layout, tmp_path, report):
    """The page's five lines: the Excitation's file is ``driftfmu.simulate``'s values printed
    with %.16g; downstream, fed those 16-digit files, every output is within a few units of the
    16th significant digit (of the column's largest value), not further."""
    exe = _fmusim()
    _run_recipe("fmusim", exe, _fmus(kind, python_fmus, native_fmus), tmp_path)
    results = {n: _at_instants(_read(tmp_path / f)) for n, f in
               zip(CHAIN, ("exc.csv", "acc.csv", "de.csv"))}
    want = _reference(kind, fmus_in_build_layout, 2.0)  # fmusim's default: the 2 s experiment
    worst = 0.0
    for name, rows in results.items():
        assert len(rows) == len(want), (name, len(rows))
        for col in rows.dtype.names[1:]:
            got, ref = rows[col], want[col]
            if name == "Excitation":
                assert np.array_equal(got, _printed(ref)), col
                continue
            scale = np.max(np.abs(ref))
            digit16 = 10.0 ** (np.floor(np.log10(scale)) - 15) if scale else 0.0
            diff = np.max(np.abs(got - ref))
            assert diff <= 10 * digit16, (name, col, diff, digit16)
            worst = max(worst, diff / digit16 if digit16 else 0.0)
    report("fmusim (%s FMUs), the page's recipe: the Excitation is driftfmu.simulate printed "
           "with %%.16g; downstream within %.2g units of the 16th digit" % (kind, worst))


@pytest.mark.parametrize("kind", ["python", "native-fmi2", "native-fmi3"])
def test_fmusim_from_exact_files_gives_simulates_numbers_to_its_printed_digits(
        kind, python_fmus, native_fmus, fmus_in_build_layout, tmp_path):
    """Each FMU fed the chain's exact values (``driftfmu inputs`` on ``driftfmu.simulate``'s
    result, every double whole): fmusim's rows at every t_k are ``driftfmu.simulate``'s values
    printed with %.16g, every output of every FMU; fmusim prints no more digits than that."""
    exe = _fmusim()
    fmus = _fmus(kind, python_fmus, native_fmus)
    stop = 0.2
    want = _reference(kind, fmus_in_build_layout, stop)
    ref_csv = tmp_path / "ref.csv"
    with open(ref_csv, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(want.dtype.names)
        w.writerows([[repr(float(v)) for v in row] for row in want])
    compared = 0
    whole = 0
    for name in CHAIN:
        argv = [exe, "--output-interval", repr(TS), "--stop-time", repr(stop),
                "--output-file", str(tmp_path / ("%s.csv" % name))]
        argv += [x for k, v in USER.items() if _has(fmus[name], k) for x in
                 ("--start-value", k, str(v))]
        if name != "Excitation":
            inp = tmp_path / ("%s_in.csv" % name)
            assert main(["inputs", str(fmus[name]), str(ref_csv), "--output-file",
                         str(inp), "--hold", "theta", "--hold", "T"]) == 0
            argv += ["--input-file", str(inp)]
        done = subprocess.run(argv + [str(fmus[name])], capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, (name, done.stdout, done.stderr)
        rows = _at_instants(_read(tmp_path / ("%s.csv" % name)))
        assert len(rows) == len(want)
        for col in rows.dtype.names[1:]:
            assert np.array_equal(rows[col], _printed(want[col])), (kind, name, col)
            whole += int(np.array_equal(rows[col], want[col]))
            compared += 1
    assert compared >= 12
    assert whole < compared  # 16 digits do not give every double back


def _has(fmu, name):
    from driftfmu.fmu_src.schemas import read_model_description
    return any(v.name == name for v in read_model_description(str(fmu)).modelVariables)


def test_fmusim_without_an_output_file_writes_nothing(native_fmus, tmp_path):
    """Why the page's lines carry ``--output-file``: without it fmusim ends with status 0 and
    no result anywhere."""
    exe = _fmusim()
    shutil.copy(native_fmus[2]["Excitation"], tmp_path / "Excitation.fmu")
    done = subprocess.run([exe, "--output-interval", "0.001", "Excitation.fmu"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["Excitation.fmu"]
    assert done.stdout == ""  # nor on the terminal


# -- fmi-sim ------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["python", "native-fmi2"])
def test_fmi_sim_runs_the_recipe_as_written_bit_for_bit(kind, python_fmus, native_fmus,
                                                         fmus_in_build_layout, tmp_path, report):
    """The page's five lines (output interval Ts/2): every output of the three FMUs at every
    t_k is ``driftfmu.simulate``'s, bit for bit."""
    exe = _fmi_sim()
    _run_recipe("fmi-sim", exe, _fmus(kind, python_fmus, native_fmus), tmp_path)
    want = _reference(kind, fmus_in_build_layout, 2.0)
    compared = 0
    for name, f in zip(CHAIN, ("exc.csv", "acc.csv", "de.csv")):
        rows = _at_instants(_read(tmp_path / f))
        assert len(rows) == len(want), (name, len(rows))
        for col in rows.dtype.names[1:]:
            assert np.array_equal(rows[col], want[col]), (kind, name, col)
            compared += 1
    assert compared == len(want.dtype.names) - 1
    report("fmi-sim (%s FMUs), the page's recipe at an output interval of Ts/2: %d outputs x "
           "%d samples equal driftfmu.simulate bit for bit" % (kind, compared, len(want)))


def test_fmi_sim_at_an_interval_of_ts_records_the_previous_input(native_fmus,
                                                                 fmus_in_build_layout,
                                                                 tmp_path):
    """Why the page says Ts/2: at an output interval of Ts fmi-sim records at t_k the outputs
    of the input of t_(k-1); the Excitation, which has no input, is right either way."""
    exe = _fmi_sim()
    lines = commands("fmi-sim")
    assert all("--output-interval 0.0005" in line for line in lines if line.startswith("fmi-"))
    for n in CHAIN:
        shutil.copy(native_fmus[2][n], tmp_path / ("%s.fmu" % n))
    for line in lines[:3]:
        argv = shlex.split(line.replace("--output-interval 0.0005", "--output-interval 0.001"))
        if argv[0] == "driftfmu":
            here = os.getcwd()
            os.chdir(tmp_path)
            try:
                assert main(argv[1:]) == 0
            finally:
                os.chdir(here)
        else:
            done = subprocess.run([exe] + argv[1:], cwd=tmp_path, capture_output=True,
                                  text=True, timeout=600)
            assert done.returncode == 0, done.stderr
    want = _reference("native-fmi2", fmus_in_build_layout, 2.0)
    exc = _at_instants(_read(tmp_path / "exc.csv"))
    acc = _at_instants(_read(tmp_path / "acc.csv"))
    assert np.array_equal(exc["x"], want["x"])
    assert acc["z"][0] == want["z"][0] and np.max(np.abs(acc["z"] - want["z"])) > 0.1


def test_fmi_sim_does_not_read_the_fmi3_fmus(native_fmus, tmp_path):
    """As the page says: fmi-sim 0.7.0 stops at the FMI 3.0 model description's ``unit``."""
    exe = _fmi_sim()
    done = subprocess.run([exe, "--model", str(native_fmus[3]["Excitation"]), "-o",
                           str(tmp_path / "e.csv"), "co-simulation", "--output-interval",
                           "0.0005"], capture_output=True, text=True, timeout=600)
    assert done.returncode != 0 and 'unknown field "unit"' in done.stdout + done.stderr
