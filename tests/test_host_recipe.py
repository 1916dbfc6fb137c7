"""The recipe of docs/hosts.md for hosts that run one FMU at a time from input files: fmpy's
command line and ``fmpy.simulate_fmu``, run on Excitation, Accelerometer and DriftEstimator in
turn with the input files ``driftfmu inputs`` writes, give ``driftfmu.simulate``'s numbers bit
for bit, print nothing, and record every sample (simulations/hostinputs.py)."""
import os
import subprocess
import sys

import numpy as np
import pytest

import driftfmu
from driftfmu.simulations import hostinputs
from driftfmu.simulations.cli import main
from recipes import commands

pytestmark = pytest.mark.integration

TS = 1e-3
N = 30                    # samples: a short run, every step of the recipe
STOP = (N - 1) * TS
CHAIN = ("Excitation", "Accelerometer", "DriftEstimator")
#: The general sensor with the known input (a3, a4, B u): every input of the files matters.
GENERAL = {"a2": 0.05, "A": 0.6, "Q": 0.05, "R": 1e-3, "seed": 3, "a3": 0.02, "a4": 0.03,
           "B": 0.8, "drive": 1, "Qu": 0.3, "P0": 0.05}
START = {"Excitation": ("A", "Q", "seed", "B", "drive", "Qu"),
         "Accelerometer": ("a2", "R", "seed", "a3", "a4"),
         "DriftEstimator": ("a2", "A", "Q", "R", "a3", "a4", "B", "P0")}


def _recipe_holds():
    """FMU -> the inputs the page's fmpy recipe holds (``--hold NAME`` on its ``driftfmu
    inputs`` lines): the chain below runs what the page says."""
    import shlex
    holds = {}
    for line in commands("fmpy"):
        argv = shlex.split(line)
        if argv[:2] == ["driftfmu", "inputs"]:
            name = argv[2][:-len(".fmu")]
            holds[name] = [argv[i + 1] for i, a in enumerate(argv) if a == "--hold"]
    assert sorted(holds) == ["Accelerometer", "DriftEstimator"], holds
    return holds


#: the page's holds: the sensor's tilt and temperature, which no result of the chain gives
RECIPE_HOLDS = _recipe_holds()


def test_the_recipe_holds_the_tilt_and_temperature_no_result_gives():
    assert RECIPE_HOLDS == {"Accelerometer": ["theta", "T"], "DriftEstimator": ["theta", "T"]}


def _samples(result):
    """The rows of a host's result at the sample instants t_k (the others, at t_k + Ts/4 where
    an input file changes, hold the sample before)."""
    t = result["time"]
    at = np.abs(t / TS - np.rint(t / TS)) < 1e-6
    return result[at]


def _chain(run_one, fmus, tmp_path, start=None, hold=None):
    """Run the chain the recipe's way: each FMU by ``run_one(fmu, input file or None, output
    file, start values)``, its input file written by ``driftfmu inputs`` from the results
    upstream (``hold``: FMU -> the inputs no result gives, held at their start values by
    ``--hold``, besides the page's own holds).  Returns the three results (fmpy's structured
    arrays)."""
    from fmpy.util import read_csv
    start = start or {}
    out = {}
    for name in CHAIN:
        given = {k: start[k] for k in START[name] if k in start}
        inp = None
        if name != "Excitation":
            inp = tmp_path / ("%s_in.csv" % name)
            upstream = [tmp_path / ("%s.csv" % n) for n in CHAIN[:CHAIN.index(name)]][::-1]
            held = [x for h in RECIPE_HOLDS[name] + (hold or {}).get(name, [])
                    for x in ("--hold", h)]
            assert main(["inputs", str(fmus[name])] + [str(p) for p in upstream]
                        + ["--output-file", str(inp)] + held) == 0
        result = tmp_path / ("%s.csv" % name)
        run_one(fmus[name], inp, result, given)
        out[name] = read_csv(result)
    return out


def _assert_chain_equal(got, reference, what):
    """Every output of the three FMUs at every sample instant equals ``reference`` (the rows
    of ``driftfmu.simulate``) bit for bit."""
    compared = 0
    for name, result in got.items():
        rows = _samples(result)
        assert len(rows) == N, (what, name, len(rows))
        assert np.array_equal(rows["time"], reference["time"]), (what, name)
        for col in rows.dtype.names[1:]:
            if col in ("y", "z_y"):  # (second axis: off)
                continue
            assert np.array_equal(rows[col], reference[col]), (what, name, col)
            compared += 1
        # the rows between the instants hold the sample before
        held = result[~np.isin(np.arange(len(result)), np.flatnonzero(
            np.abs(result["time"] / TS - np.rint(result["time"] / TS)) < 1e-6))]
        for row in held:
            k = int(np.floor(row["time"] / TS))
            for col in result.dtype.names[1:]:
                assert row[col] == rows[col][k], (what, name, col, row["time"])
    return compared


def _cli_run(fmu, inp, out, start):
    cmd = [sys.executable, "-m", "fmpy", "simulate", str(fmu), "--stop-time", repr(STOP),
           "--output-interval", repr(TS), "--output-file", str(out)]
    if fmu.stem == "Excitation":  # as issue 33 ran it: x alone, so that the files of the
        cmd += ["--output-variables", "x"]  # others hold y and u (--hold) at their starts
    if inp is not None:
        cmd += ["--input-file", str(inp)]
    if start:
        cmd += ["--start-values"] + [str(x) for kv in start.items() for x in kv]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (cmd, done.stdout, done.stderr)
    # quiet: no "Warning: missing input for variable" (every input has its column), nothing
    assert done.stdout == "" and done.stderr == "", (fmu, done.stdout, done.stderr)


def test_fmpy_command_line_recipe_gives_the_chain_bit_for_bit(fmus_in_build_layout, tmp_path,
                                                              report):
    """``fmpy simulate Excitation.fmu --output-variables x``, then ``driftfmu inputs`` and
    ``fmpy simulate --input-file`` for the Accelerometer and the DriftEstimator: every output
    at every sample instant is ``driftfmu.simulate``'s, and no run prints a word (no
    ``Warning: missing input for variable "y"``: the files hold every input)."""
    fmus = {n: fmus_in_build_layout / ("%s.fmu" % n) for n in CHAIN}
    reference = driftfmu.simulate(stop_time=STOP, fmu_dir=fmus_in_build_layout)
    compared = _assert_chain_equal(_chain(_cli_run, fmus, tmp_path, hold={
        "Accelerometer": ["y"], "DriftEstimator": ["u"]}), reference, "fmpy CLI")
    report("host recipe: fmpy's command line, one FMU at a time with driftfmu inputs' files: "
           "%d samples, %d output columns equal to driftfmu.simulate bit for bit, no output "
           "printed" % (N, compared))


def _api_run(fmu, inp, out, start):
    from fmpy import simulate_fmu
    from fmpy.util import read_csv, write_csv
    result = simulate_fmu(str(fmu), stop_time=STOP, output_interval=TS, start_values=start,
                          input=read_csv(inp) if inp is not None else None)
    write_csv(out, result)


@pytest.mark.parametrize("backend", ["python", "native-fmi2", "native-fmi3"])
@pytest.mark.parametrize("settings", ["letter", "general"])
def test_simulate_fmu_recipe_gives_the_chain_bit_for_bit(backend, settings,
                                                         fmus_in_build_layout, tmp_path,
                                                         capfd):
    """``fmpy.simulate_fmu(input=read_csv(file))`` on each FMU in turn gives the chain's numbers,
    Python and native FMUs (FMI 2.0 and 3.0), at the letter's settings and with the general
    sensor's a3, a4 and the known input B u (whose u reaches the DriftEstimator through its
    input file)."""
    start = {} if settings == "letter" else GENERAL
    if backend == "python":
        fmus = {n: fmus_in_build_layout / ("%s.fmu" % n) for n in CHAIN}
        kind, version = "python", 2
    else:
        version = int(backend[-1])
        fmus = {n: fmus_in_build_layout / "native" / ("fmi%d" % version) / ("%s.fmu" % n)
                for n in CHAIN}
        kind = "native"
    reference = driftfmu.simulate(stop_time=STOP, fmu_dir=fmus_in_build_layout,
                                  start_values=start, backend=kind, fmi_version=version)
    got = _chain(_api_run, fmus, tmp_path, start)
    if start:
        assert np.any(got["Excitation"]["u"] != 0.0)
    _assert_chain_equal(got, reference, backend)
    printed = capfd.readouterr()
    assert "missing input" not in printed.out + printed.err, printed


def test_without_the_lead_the_host_records_the_previous_input(fmus_in_build_layout, tmp_path,
                                                             monkeypatch):
    """The lead is what makes the recipe work: a file that changes at the sample instants
    themselves (LEAD = 1, the naive file) makes fmpy record at t_k the outputs computed from the
    input of t_{k-1} (issue 33's acc.csv)."""
    monkeypatch.setattr(hostinputs, "LEAD", 1.0)
    fmus = {n: fmus_in_build_layout / ("%s.fmu" % n) for n in CHAIN}
    reference = driftfmu.simulate(stop_time=STOP, fmu_dir=fmus_in_build_layout)
    got = _chain(_api_run, fmus, tmp_path)
    z = _samples(got["Accelerometer"])["z"]
    assert z[0] == reference["z"][0] and not np.array_equal(z, reference["z"])


def test_inputs_are_declared_discrete_so_fmpy_holds_them(fmus_in_build_layout, tmp_path):
    """Every input of every FMU is declared discrete (sampled, held): fmpy applies the last
    value of an input file at a time between its rows instead of interpolating."""
    from fmpy import extract, instantiate_fmu
    from fmpy.simulation import Input
    from driftfmu.fmu_src.schemas import read_model_description
    paths = list(fmus_in_build_layout.glob("*.fmu")) + \
        list(fmus_in_build_layout.glob("native/fmi*/*.fmu"))
    assert len(paths) == 12
    for path in paths:
        md = read_model_description(path)
        inputs = [v for v in md.modelVariables if v.causality == "input"]
        assert inputs and {v.variability for v in inputs} == {"discrete"}, path
    path = fmus_in_build_layout / "Accelerometer.fmu"
    md = read_model_description(path)
    x = next(v for v in md.modelVariables if v.name == "x")
    signals = np.array([(0.0, 1.0, 0.0), (1.0, 2.0, 0.0)],
                       dtype=[("time", float), ("x", float), ("y", float)])
    fmu = instantiate_fmu(extract(str(path), unzipdir=str(tmp_path / "unzipped")), md)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        Input(fmu, md, signals).apply(0.75)
        assert fmu.getReal([x.valueReference]) == [1.0]  # held, not 1.75
    finally:
        fmu.freeInstance()


def test_inputs_command_refuses_a_result_that_skips_samples(fmus_in_build_layout, tmp_path,
                                                             capsys):
    """fmpy's own output interval for a 2 s run is 2 ms: half of the samples are not in the
    file. ``driftfmu inputs`` says so in one line (exit 2) instead of writing a file that
    loses them; an existing file is kept unless --force."""
    exc = tmp_path / "exc.csv"
    exc.write_text("time,x\n0.0,0.5\n0.002,0.25\n0.004,0.125\n")
    out = tmp_path / "acc_in.csv"
    fmu = str(fmus_in_build_layout / "Accelerometer.fmu")
    tilt = ["--hold", "theta", "--hold", "T"]  # (no result here gives them)
    assert main(["inputs", fmu, str(exc), "--output-file", str(out), "--hold", "y"] + tilt) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no row for sample 2" in err[0] and \
        "--output-interval 0.001" in err[0], err
    assert not out.exists()
    exc.write_text("time,x\n0.0,0.5\n0.001,0.25\n0.002,0.125\n")
    out.write_text("mine\n")
    assert main(["inputs", fmu, str(exc), "--output-file", str(out), "--hold", "y"] + tilt) == 2
    assert out.read_text() == "mine\n" and "--force" in capsys.readouterr().err
    # an input no result gives is refused in one line (issue 41: z = 0 without a word) ...
    assert main(["inputs", fmu, str(exc), "--output-file", str(out), "--force"] + tilt) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["driftfmu: error: Accelerometer's input y is in none of the results (%s: "
                   "x); allowed: a result with a column y, or --hold y to write its start "
                   "value 0.0 for every sample" % exc], err
    assert out.read_text() == "mine\n"
    # ... and held at its start value when asked
    assert main(["inputs", fmu, str(exc), "--output-file", str(out), "--force",
                 "--hold", "y"] + tilt) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "time,x,y,theta,T"  # every input, the held ones at their starts
    assert lines[1:] == [r + ",0.0,298.15" for r in (
        "0.0,0.5,0.0", "0.00025,0.5,0.0", "0.00025,0.25,0.0", "0.00125,0.25,0.0",
        "0.00125,0.125,0.0")]
    assert "y held at its start value (--hold y)" in capsys.readouterr().out


@pytest.mark.parametrize("kind", ["python", "native/fmi2", "native/fmi3"])
def test_a_refused_call_tells_its_reason_without_fmi_logging(kind, fmus_in_build_layout,
                                                             tmp_path):
    """fmpy's command line as a tool user runs it (no --fmi-logging, no --debug-logging): an
    input file with a non-finite value and a start value out of range stop the run, and the
    FMU's own reason is on the terminal (the FMUs log errors whatever ``loggingOn`` says)."""
    folder = fmus_in_build_layout if kind == "python" else fmus_in_build_layout / kind
    fmu = str(folder / "Accelerometer.fmu")
    bad = tmp_path / "bad_in.csv"
    bad.write_text("time,x,y\n0.0,0.5,0.0\n0.00025,0.5,0.0\n0.00025,inf,0.0\n")
    for extra, reason in ((["--input-file", str(bad)],
                           "x = inf is not finite; input accepts finite values only"),
                          (["--start-values", "R", "-1"], "R = -1.0 is out of range; allowed: "
                                                          "R > 0")):
        # fmpy leaves the FMU it extracted when a call fails: in this test's folder
        done = subprocess.run([sys.executable, "-m", "fmpy", "simulate", fmu, "--stop-time",
                               "0.002", "--output-interval", "0.001", "--output-file",
                               str(tmp_path / "out.csv")] + extra,
                              capture_output=True, text=True, timeout=300,
                              env=dict(os.environ, TMPDIR=str(tmp_path)))
        assert done.returncode != 0, (kind, extra)
        errors = [line for line in done.stdout.splitlines() if line.startswith("[ERROR]")]
        assert len(errors) == 1 and reason in errors[0], (kind, extra, done.stdout)
