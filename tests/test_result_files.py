"""Result files that someone else made, read by ``driftfmu inputs`` (issue 40), and times as
hosts and spreadsheets write them (issue 38): what fmpy cannot use is refused in one line
naming the file, the line and the value (exit 2, no file written); what spreadsheets write
(a byte-order mark, CRLF, quotes) is read; times written as decimals, running sums, ``%.16g``,
``%.17g`` or ``repr`` are applied at their samples (simulations/times.py), on both sides of
the tolerance; the memory stays bounded for any size (peak RSS of the process); an input no
result gives is refused unless held (issue 41)."""
import math
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from driftfmu.simulations import hostinputs, times
from driftfmu.simulations.cli import main

ROOT = Path(__file__).resolve().parent.parent
HEALTH = list(HealthCheck)


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    """FMUs on paper (tests/paperfmu.py): ``driftfmu inputs`` reads an FMU's model description
    and checks its binary, it never loads it."""
    import paperfmu
    folder = tmp_path_factory.mktemp("paper")
    return {m: paperfmu.paper_fmu(folder / ("%s.fmu" % m), m)
            for m in ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")}


@pytest.fixture(scope="module")
def acc(paper):
    return str(paper["Accelerometer"])


def _run(argv, capsys):
    rc = main(argv)
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


def _refused(rc, err, out_file, path, line=None):
    assert rc == 2, err
    lines = [x for x in err.strip().splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    if path is not None:
        assert str(path) in lines[0], lines[0]
    if line is not None:
        assert "%s line %d: " % (path, line) in lines[0], lines[0]
    assert not Path(out_file).exists()
    return lines[0]


def expected_file(values, start, Ts):
    """The input file of samples ``values`` (tuples of the inputs), as the module's rule
    writes it (every time by its own formula; repr)."""
    rows = [(start,) + values[0]]
    for j in range(1, len(values)):
        change = start + (j - 1 + hostinputs.LEAD) * Ts
        rows += [(change,) + values[j - 1], (change,) + values[j]]
    return "".join(",".join(repr(float(v)) for v in row) + "\n" for row in rows)


# -- the hostile files of the campaign ------------------------------------------------------------

#: the Accelerometer's tilt and temperature, which no result here gives: held at their start
#: values, so that each case reaches the check it is about
HOLD = ["--hold", "theta", "--hold", "T"]
HELD = (0.0, 298.15)
HEADER = "time,x,y,theta,T\n"


def held(values):
    """``values`` (x, y) with the held tilt and temperature after them, as written."""
    return [v + HELD for v in values]


GOOD = "time,x,y\n0.0,0.5,0.0\n0.001,0.25,0.0\n0.002,0.125,0.0\n"

#: (name, file bytes, extra arguments, the line named (None: none), words of the line)
HOSTILE = [
    ("nan", b"time,x,y\n0,1,0\n0.001,nan,0\n", [], 3, "x = 'nan' is not a number"),
    ("NaN", b"time,x,y\n0,1,0\n0.001,NaN,0\n", [], 3, "is not a number"),
    ("inf", b"time,x,y\n0,1,0\n0.001,inf,0\n", [], 3, "x = 'inf' is not a number"),
    ("-inf", b"time,x,y\n0,1,0\n0.001,-inf,0\n", [], 3, "is not a number"),
    ("1e400", b"time,x,y\n0,1,0\n0.001,1e400,0\n", [], 3,
     "x = 1e400 is beyond the range of a double"),
    ("-1e309", b"time,x,y\n0,1,0\n0.001,0,-1e309\n", [], 3, "beyond the range of a double"),
    ("empty field", b"time,x,y\n0,1,0\n0.001,,0\n", [], 3, "x = '' is not a number"),
    ("text", b"time,x,y\n0,1,0\n0.001,abc,0\n", [], 3, "x = 'abc' is not a number"),
    ("hex", b"time,x,y\n0,1,0\n0.001,0x1p3,0\n", [], 3, "is not a number"),
    ("underscore", b"time,x,y\n0,1,0\n0.001,1_000,0\n", [], 3, "is not a number"),
    ("other digits", "time,x,y\n0,1,0\n0.001,\uff11,0\n".encode(), [], 3, "is not a number"),
    ("decimal comma", b"time,x,y\n0,1,0\n0.001,0,5,0\n", [], 3, "4 columns, the header 3"),
    ("short row", b"time,x,y\n0,1,0\n0.001,2\n", [], 3, "2 columns, the header 3"),
    ("time nan", b"time,x,y\n0,1,0\nnan,2,0\n", [], 3, "time = 'nan' is not a number"),
    ("time inf", b"time,x,y\n0,1,0\ninf,2,0\n", [], 3, "time = 'inf' is not a number"),
    ("time backwards", b"time,x,y\n0,1,0\n0.001,2,0\n0.002,3,0\n0.0015,4,0\n", [], 5,
     "the time 0.0015 is before the time of the row above, 0.002"),
    ("before the start", b"time,x,y\n-0.001,1,0\n0.001,2,0\n", [], 2,
     "the result starts at t = -0.001 s, before the start time 0.0 s"),
    ("after the start", b"time,x,y\n0.001,1,0\n0.002,2,0\n", [], 2,
     "the result starts at t = 0.001 s, after the start time 0.0 s"),
    ("one row", b"time,x,y\n0,1,0\n", [], None, "gives one sample only"),
    ("no rows", b"time,x,y\n", [], None, "gives no sample"),
    ("empty", b"", [], 1, "no header with a first column 'time' (found '')"),
    ("no header", b"0,1,0\n0.001,2,0\n", [], 1, "no header with a first column 'time'"),
    ("header without time", b"t,x,y\n0,1,0\n", [], 1,
     "no header with a first column 'time' (found 't,x,y')"),
    ("semicolons", b"time;x;y\n0;1;0\n", [], 1, "uses ';' as the separator"),
    ("tabs", b"time\tx\ty\n0\t1\t0\n", [], 1, "no header with a first column 'time'"),
    ("a name twice", b"time,x,x\n0,1,0\n", [], 1, "the header names x twice"),
    ("UTF-16", "time,x,y\n0,1,0\n".encode("utf-16"), [], 1, "the file is UTF-16 text"),
    ("latin-1", b"time,x,y\n0,1,0\n0.001,2,0 \xb5\n", [], 3, "(0xb5) is not UTF-8"),
    ("NUL", b"time,x,y\n0,1,0\n0.001,2\x00,0\n", [], 3, "x = '2\\x00' is not a number"),
    ("huge field", b"time,x,y\n0,1,0\n0.001,2,\"" + b"9" * 200000 + b"\"\n", [], 3,
     "field larger than field limit"),
    ("huge line", b"time,x,y\n0,1,0\n0.001,2," + b"9" * (hostinputs.MAX_LINE + 10) + b"\n",
     [], 3, "the line is longer than %d characters" % hostinputs.MAX_LINE),
    ("a sample skipped", b"time,x,y\n0,1,0\n0.002,2,0\n", [], 3, "no row for sample 2"),
    ("milliseconds", b"time,x,y\n0,1,0\n1,2,0\n2,3,0\n", [], 3, "no row for sample 2"),
    ("--Ts 5e-324", GOOD.encode(), ["--Ts", "5e-324"], None,
     "Ts = 5e-324 is out of range; allowed: Ts >= 1e-09"),
    ("--Ts 1e300", GOOD.encode(), ["--Ts", "1e300"], None, "gives one sample only"),
    ("--Ts 0", GOOD.encode(), ["--Ts", "0"], None, "Ts = 0.0 is out of range"),
    ("--Ts -1", GOOD.encode(), ["--Ts", "-1"], None, "Ts = -1.0 is out of range"),
    ("--Ts nan", GOOD.encode(), ["--Ts", "nan"], None, "Ts = nan is not finite"),
    ("--start-time inf", GOOD.encode(), ["--start-time", "inf"], None,
     "start time inf; allowed: a finite time"),
    ("--hold of no input", GOOD.encode(), ["--hold", "z"], None,
     "--hold z: Accelerometer has no input z; allowed: its inputs x, y, theta, T"),
    ("--hold of a given input", GOOD.encode(), ["--hold", "x"], None,
     "upstream.csv has the column x for the input x, which --hold x holds; allowed: one of "
     "the two"),
    ("no column for an input", b"time,x\n0,1\n0.001,2\n", [], None,
     "Accelerometer's input y is in none of the results"),
]


@pytest.mark.parametrize("name, data, extra, line, words", HOSTILE,
                         ids=[h[0] for h in HOSTILE])
def test_a_hostile_result_is_one_line_naming_the_file_and_the_line(name, data, extra, line,
                                                                   words, acc, tmp_path,
                                                                   capsys):
    result = tmp_path / "upstream.csv"
    result.write_bytes(data)
    out = tmp_path / "acc_in.csv"
    rc, _, err = _run(["inputs", acc, str(result), "--output-file", str(out)] + HOLD + extra,
                      capsys)
    said = _refused(rc, err, out, result if not name.startswith("--") or
                    "one sample" in words else None, line)
    assert words in said, said


@pytest.mark.parametrize("name, text", [
    ("a byte-order mark", "\ufefftime,x,y\n0.0,0.5,0.0\n0.001,0.25,0.0\n0.002,0.125,0.0\n"),
    ("CRLF", GOOD.replace("\n", "\r\n")),
    ("a byte-order mark and CRLF", "\ufeff" + GOOD.replace("\n", "\r\n")),
    ("quotes", '"time","x","y"\n"0.0","0.5","0.0"\n"0.001","0.25","0.0"\n"0.002","0.125",'
               '"0.0"\n'),
    ("spaces", "time, x, y\n 0.0 , 0.5 , 0.0\n0.001, 0.25, 0.0\n0.002 ,0.125,0\n"),
    ("empty rows", GOOD + "\n,,\n\n"),
    ("no last newline", GOOD.rstrip("\n")),
    ("exponents", "time,x,y\n0e0,5e-1,0\n1e-3,2.5E-1,0\n2.0e-3,1.25e-1,0.\n"),
])
def test_what_spreadsheets_write_is_read(name, text, acc, tmp_path, capsys):
    result = tmp_path / "upstream.csv"
    result.write_bytes(text.encode("utf-8"))
    out = tmp_path / "acc_in.csv"
    rc, said, err = _run(["inputs", acc, str(result), "--output-file", str(out)] + HOLD,
                         capsys)
    assert rc == 0, err
    assert out.read_text() == HEADER + expected_file(
        held([(0.5, 0.0), (0.25, 0.0), (0.125, 0.0)]), 0.0, 1e-3)


# -- issue 41: no column of start values for an input nobody gave ---------------------------------

def test_the_estimator_without_the_accelerometers_result_is_refused(paper, tmp_path, capsys):
    """``driftfmu inputs DriftEstimator.fmu exc.csv`` wrote z = 0 for every sample and exited
    0; now it names the input and the columns the files have; with the Accelerometer's result
    it writes z from it; u, which no result here gives, is held only when asked."""
    exc = tmp_path / "exc.csv"
    exc.write_text("time,x,y\n0,0.5,0\n0.001,0.25,0\n")
    acc = tmp_path / "acc.csv"
    acc.write_text("time,z,z_y\n0,0.7,0\n0.001,0.8,0\n")
    out = tmp_path / "de_in.csv"
    fmu = str(paper["DriftEstimator"])
    rc, _, err = _run(["inputs", fmu, str(exc), "--output-file", str(out)], capsys)
    said = _refused(rc, err, out, None)
    assert said == ("driftfmu: error: DriftEstimator's inputs z, u, theta, T are in none of "
                    "the results (%s: x, y); allowed: results with the columns z; u; theta; T, "
                    "or --hold z --hold u --hold theta --hold T to write their start values "
                    "z = 0.0, u = 0.0, theta = 0.0, T = 298.15 for every sample" % exc), said
    rc, _, err = _run(["inputs", fmu, str(acc), str(exc), "--output-file", str(out)], capsys)
    assert "inputs u, theta, T are in none of the results" in _refused(rc, err, out, None)
    rc, _, err = _run(["inputs", fmu, str(acc), str(exc), "--output-file", str(out)] + HOLD,
                      capsys)
    assert _refused(rc, err, out, None) == (
        "driftfmu: error: DriftEstimator's input u is in none of the results (%s: z, z_y; %s: "
        "x, y); allowed: a result with a column u, or --hold u to write its start value 0.0 "
        "for every sample" % (acc, exc))
    rc, said, err = _run(["inputs", fmu, str(acc), str(exc), "--output-file", str(out),
                          "--hold", "u"] + HOLD, capsys)
    assert rc == 0 and "z from %s, u held at its start value (--hold u)" % acc in said, said
    assert out.read_text() == "time,z,u,theta,T\n" + expected_file(
        [(0.7, 0.0) + HELD, (0.8, 0.0) + HELD], 0.0, 1e-3)


@pytest.mark.parametrize("model", ["Accelerometer", "DriftEstimator", "DualDriftEstimator",
                                   "Excitation"])
def test_no_fmu_gets_a_column_of_start_values_for_an_input_no_result_gives(model, paper,
                                                                          tmp_path, capsys):
    """The class: for every FMU, each input that no result gives is refused by name, all of
    them in the one line, each with the ``--hold`` that would write it."""
    result = tmp_path / "r.csv"
    result.write_text("time,unrelated\n0,1\n0.001,2\n")
    out = tmp_path / "in.csv"
    rc, _, err = _run(["inputs", str(paper[model]), str(result), "--output-file", str(out)],
                      capsys)
    said = _refused(rc, err, out, None)
    names = [n for n, _ in hostinputs.fmu_inputs(str(paper[model]))[1]]
    assert names, model
    assert said.startswith("driftfmu: error: %s's input%s %s %s in none of the results" % (
        model, "s" if len(names) > 1 else "", ", ".join(names),
        "are" if len(names) > 1 else "is")), said
    for name in names:
        assert "--hold %s " % name in said, (name, said)


@pytest.mark.parametrize("model, hold", [
    ("Excitation", ["u_in"]), ("DriftEstimator", ["z", "u", "theta", "T"])])
def test_an_fmu_whose_every_input_is_held_is_refused(model, hold, paper, tmp_path, capsys,
                                                      monkeypatch):
    """With every input held no result's rows count the samples: the command wrote without
    end (an endless file); now one line (``_count`` is bounded here, so that the old fault
    ends and fails the test instead of filling the disk)."""
    monkeypatch.setattr(hostinputs, "_count", lambda: iter(range(1000)))
    result = tmp_path / "r.csv"
    result.write_text("time,unrelated\n0,1\n0.001,2\n")
    out = tmp_path / "in.csv"
    rc, _, err = _run(["inputs", str(paper[model]), str(result), "--output-file", str(out)] +
                      [a for name in hold for a in ("--hold", name)], capsys)
    assert _refused(rc, err, out, None) == (
        "driftfmu: error: %s's input%s %s %s held (%s), so no result gives the samples; "
        "allowed: at least one input from a result's column" % (
            model, "s" if len(hold) > 1 else "", ", ".join(hold),
            "are all" if len(hold) > 1 else "is", " ".join("--hold " + n for n in hold)))
    # one input from a result: written, the rest held
    result.write_text("time,z\n0,0.7\n0.001,0.8\n")
    if model == "DriftEstimator":
        rc, said, err = _run(["inputs", str(paper[model]), str(result), "--output-file",
                              str(out), "--hold", "u"] + HOLD, capsys)
        assert rc == 0 and out.exists(), err


def _foreign_fmu(path, md_variables, structure):
    """An FMU of a model that is not driftfmu's (``Gain``): FMI 2.0, the given variables, and
    a whole shared library of this machine as its binary (tests/paperfmu.py)."""
    import zipfile

    import paperfmu
    md = ('<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" '
          'modelName="Gain" guid="{gain}" variableNamingConvention="flat" '
          'numberOfEventIndicators="0">\n<CoSimulation modelIdentifier="Gain"/>\n'
          '<ModelVariables>\n%s</ModelVariables>\n<ModelStructure><Outputs>%s</Outputs>'
          '</ModelStructure>\n</fmiModelDescription>\n' % (md_variables, structure))
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", md)
        z.writestr("binaries/linux64/Gain.so", paperfmu.library())
    return path


def test_an_fmu_that_is_missing_or_a_folder_is_refused_as_what_it_is(tmp_path, capsys):
    """The FMU given to ``driftfmu inputs``: a path that does not exist is refused saying so, a
    folder (an unzipped FMU) saying it is a folder and that the archive is wanted."""
    result = tmp_path / "r.csv"
    result.write_text("time,x\n0,0.5\n0.001,0.25\n")
    out = tmp_path / "in.csv"
    missing = tmp_path / "Accelerometer.fmu"
    folder = tmp_path / "unzipped" / "Accelerometer.fmu"
    folder.mkdir(parents=True)
    for fmu, said in ((missing, "%s: does not exist; expected: an FMU file" % missing),
                      (folder, "%s: is a folder; expected: the FMU file itself (the zip "
                               "archive, not the folder it was unzipped to)" % folder)):
        rc, _, err = _run(["inputs", str(fmu), str(result), "--output-file", str(out)], capsys)
        assert _refused(rc, err, out, fmu) == "driftfmu: error: " + said


GAIN_U = ('<ScalarVariable name="u" valueReference="0" causality="input" '
          'variability="continuous"><Real/></ScalarVariable>\n'
          '<ScalarVariable name="y" valueReference="1" causality="output" '
          'variability="continuous"><Real/></ScalarVariable>\n')


def test_an_fmu_of_another_model_without_ts_or_start_values(tmp_path, capsys):
    """Its model description is all there is: an input without a start value (which FMI
    requires, and some tools omit) is held at 0; without a parameter Ts, --Ts is needed; with a
    Ts, its start value is the sample period."""
    fmu = _foreign_fmu(tmp_path / "Gain.fmu", GAIN_U, '<Unknown index="2"/>')
    assert hostinputs.fmu_inputs(str(fmu)) == ("Gain", [("u", 0.0)], None, 0.0)
    result = tmp_path / "r.csv"
    result.write_text("time,v\n0,0.5\n0.001,0.25\n")
    out = tmp_path / "in.csv"
    rc, _, err = _run(["inputs", str(fmu), str(result), "--output-file", str(out),
                       "--hold", "u"], capsys)
    assert _refused(rc, err, out, None).startswith(
        "driftfmu: error: Ts is not given and the FMU has none; allowed: --Ts, ")
    rc, _, err = _run(["inputs", str(fmu), str(result), "--output-file", str(out),
                       "--Ts", "0.001"], capsys)
    assert _refused(rc, err, out, None).endswith(
        "or --hold u to write its start value 0.0 for every sample")
    with_ts = _foreign_fmu(tmp_path / "GainTs.fmu", GAIN_U.replace(
        'continuous"><Real/>', 'continuous"><Real start="2.5"/>', 1) +
        '<ScalarVariable name="Ts" valueReference="2" causality="parameter" '
        'variability="fixed" initial="exact"><Real start="0.002"/></ScalarVariable>\n',
        '<Unknown index="2"/>')
    assert hostinputs.fmu_inputs(str(with_ts)) == ("Gain", [("u", 2.5)], 0.002, 0.0)
    # two inputs, both held: refused as the Excitation's one is (the plural from two on)
    two = _foreign_fmu(tmp_path / "Gain2.fmu", GAIN_U + GAIN_U.replace('"u"', '"v"').replace(
        '"y"', '"w"').replace('="0"', '="2"').replace('="1"', '="3"'),
        '<Unknown index="2"/><Unknown index="4"/>')
    result.write_text("time,x\n0,0.5\n0.001,0.25\n")
    rc, _, err = _run(["inputs", str(two), str(result), "--output-file", str(out), "--Ts",
                       "0.001", "--hold", "u", "--hold", "v"], capsys)
    assert _refused(rc, err, out, None) == (
        "driftfmu: error: Gain's inputs u, v are all held (--hold u --hold v), so no result "
        "gives the samples; allowed: at least one input from a result's column")


# -- times as hosts and spreadsheets write them ---------------------------------------------------

FORMATS = {
    "repr": repr,
    "%.16g": lambda t: "%.16g" % t,
    "%.17g": lambda t: "%.17g" % t,
    "%.15g": lambda t: "%.15g" % t,
}


def _times(kind, start, Ts, n):
    """The instants ``t_1 .. t_n`` as a host computes them: ``start + k Ts`` (``"product"``),
    a running sum (``"sum"``, FMI's communication points, a spreadsheet's filled-down
    ``=A2 + Ts``) or the exact decimals (``"decimal"``, text)."""
    if kind == "product":
        return [start + k * Ts for k in range(n)]
    if kind == "sum":
        out, t = [], start
        for _ in range(n):
            out.append(t)
            t += Ts
        return out
    d0, dT = Decimal(repr(start)), Decimal(repr(Ts))
    return [str(d0 + k * dT) for k in range(n)]


@settings(max_examples=60, deadline=None, suppress_health_check=HEALTH)
@given(Ts=st.sampled_from([1e-3, 2.5e-3, 1e-4, 0.02, 0.01 / 3]),
       start=st.sampled_from([0.0, 0.5, -1.25, 10.001, 1e3, 1e5]),
       n=st.integers(2, 300), kind=st.sampled_from(["product", "sum", "decimal"]),
       fmt=st.sampled_from(sorted(FORMATS)), between=st.lists(st.sampled_from([0.25, 0.5,
                                                                               0.75]),
                                                                max_size=2, unique=True),
       bom=st.booleans(), crlf=st.booleans(), seed=st.integers(0, 2 ** 32 - 1))
def test_times_as_hosts_write_them_are_applied_at_their_samples(
        acc, tmp_path_factory, Ts, start, n, kind, fmt, between, bom, crlf, seed):
    """Every sample's value is taken from the row at its instant, whatever arithmetic and
    text the host used for the time: not one step late, not refused."""
    rng = np.random.default_rng(seed)
    values = [(v, 0.0) for v in rng.normal(size=n).tolist()]
    instants = _times(kind, start, Ts, n)
    lines = ["time,x,y"]
    for k, t in enumerate(instants):
        text = t if kind == "decimal" else FORMATS[fmt](t)
        lines.append("%s,%r,0.0" % (text, values[k][0]))
        for f in sorted(between):  # rows between the instants hold the sample (fmpy's
            # event rows)
            lines.append("%s,%r,0.0" % (FORMATS[fmt](float(text) + f * Ts), values[k][0]))
    text = ("\r\n" if crlf else "\n").join(lines) + "\n"
    folder = tmp_path_factory.mktemp("times")
    result = folder / "upstream.csv"
    result.write_bytes(("\ufeff" if bom else "").encode() + text.encode())
    out = folder / "in.csv"
    hostinputs.write_input_file(acc, [result], out, Ts=Ts, start_time=start,
                                hold=("theta", "T"))
    assert out.read_text() == HEADER + expected_file(held(values), start, Ts)


@pytest.mark.qualification
@pytest.mark.parametrize("start", [0.0, 123.456])
def test_a_million_samples_summed_as_a_host_sums_them_are_each_at_their_instant(start):
    """A running sum of a million steps of 1 ms is off by up to 4e-5 periods (past the FMUs'
    millionth): each sum still counts as its own instant, and a time a quarter period after
    it as the period it starts."""
    Ts, t = 1e-3, start
    worst = 0.0
    for k in range(1000001):
        if k % 997 == 0 or k > 999000:
            assert times.period(t, start, Ts) == k, (k, t)
            assert times.period(t + 0.25 * Ts, start, Ts) == k, (k, t)
            worst = max(worst, abs((t - start) / Ts - k))
        t += Ts
    assert worst > times.INSTANT_TOLERANCE  # (the sum did drift past the FMUs' own)


def test_a_running_sum_of_many_samples_is_at_its_instants():
    """The everyday loop's share of the test above: 20,000 steps from a start of 1e4 s, where
    every addition rounds by a part in 1e-9 of a period."""
    Ts, start = 1e-3, 1e4
    t, drifted = start, 0
    for k in range(20001):
        assert times.period(t, start, Ts) == k, (k, t)
        assert times.period(t + 0.25 * Ts, start, Ts) == k
        drifted += abs((t - start) / Ts - k) > times.INSTANT_TOLERANCE
        t += Ts
    assert drifted  # (past the FMUs' own tolerance, where the rule of before failed)


@settings(max_examples=300, deadline=None)
@given(k=st.integers(1, 10 ** 6), start=st.floats(-1e4, 1e4),
       Ts=st.floats(1e-5, 10.0), side=st.sampled_from([0.25, 4.0]))
def test_both_sides_of_the_tolerance(k, start, Ts, side):
    """A time a quarter of the tolerance before an instant is the instant; four times the
    tolerance before it, the period before."""
    assume(abs(start) / Ts <= 1e8)
    t_k = start + k * Ts
    tol = times.tolerance(t_k, start, Ts)
    assume(tol <= times.MAX_TOLERANCE / 8)
    t = t_k - side * tol * Ts
    assert times.period(t, start, Ts) == (k if side < 1 else k - 1)
    assert times.period(t_k + side * tol * Ts, start, Ts) == k


def test_the_tolerance_has_a_ceiling_on_both_sides():
    """Past MAX_TOLERANCE of a period (about 9.5 million samples from 0) times cannot be told
    apart: refused (None), not guessed."""
    Ts = 1e-3
    k0 = int(0.9 * math.sqrt(times.MAX_TOLERANCE / times.ROUNDOFF))
    assert times.tolerance(k0 * Ts, 0.0, Ts) <= times.MAX_TOLERANCE
    k = next((k for k in range(k0, 2 * k0)  # (bounded: a tolerance that does not grow ends)
              if times.tolerance(k * Ts, 0.0, Ts) > times.MAX_TOLERANCE), None)
    assert k is not None, "the tolerance does not grow with the samples"
    assert times.period((k - 1) * Ts, 0.0, Ts) == k - 1
    assert times.period(k * Ts, 0.0, Ts) is None
    assert times.period(math.inf, 0.0, Ts) is None and times.period(math.nan, 0.0, Ts) is None


@pytest.mark.parametrize("side, accepted", [(0.25, True), (4.0, False)])
@pytest.mark.parametrize("start", [0.0, 1e4])
def test_a_result_starting_just_before_the_start_time(side, accepted, start, acc, tmp_path,
                                                      capsys):
    """Both sides of the tolerance at the start: a first row within it is sample 1, one
    before it is refused (results before the FMU's start time were accepted)."""
    Ts = 1e-3
    t0 = start - side * times.tolerance(start, start, Ts) * Ts
    assert t0 < start
    result = tmp_path / "r.csv"
    result.write_text("time,x,y\n%r,1,0\n%r,2,0\n" % (t0, start + Ts))
    out = tmp_path / "in.csv"
    rc, _, err = _run(["inputs", acc, str(result), "--output-file", str(out),
                       "--start-time", repr(start)] + HOLD, capsys)
    if accepted:
        assert rc == 0, err
        assert out.read_text() == HEADER + expected_file(held([(1.0, 0.0), (2.0, 0.0)]),
                                                         start, Ts)
    else:
        assert "before the start time" in _refused(rc, err, out, result, 2)


@pytest.mark.parametrize("side, accepted", [(0.25, True), (4.0, False)])
def test_a_row_just_before_an_instant(side, accepted, acc, tmp_path, capsys):
    """Both sides inside the file: a row a little before t_2 is sample 2 within the
    tolerance, and a later row of sample 1's period beyond it (so sample 2 has none)."""
    Ts = 1e-3
    t1 = Ts - side * times.tolerance(Ts, 0.0, Ts) * Ts
    result = tmp_path / "r.csv"
    result.write_text("time,x,y\n0.0,1,0\n%r,2,0\n0.002,3,0\n" % t1)
    out = tmp_path / "in.csv"
    rc, _, err = _run(["inputs", acc, str(result), "--output-file", str(out)] + HOLD, capsys)
    if accepted:
        assert rc == 0, err
        assert out.read_text() == HEADER + expected_file(held([(1.0, 0.0), (2.0, 0.0),
                                                               (3.0, 0.0)]), 0.0, Ts)
    else:
        assert "no row for sample 2" in _refused(rc, err, out, result, 4)


# -- simulate's input: the same rule ---------------------------------------------------------------

@pytest.mark.integration
def test_simulates_input_with_times_summed_by_a_host_is_applied_at_its_points(
        fmus_in_build_layout):
    """``simulate(input=...)`` with a time column summed as a spreadsheet fills it down, from
    a start of 1e4 s where each addition rounds by up to 7e-10 of a step: every value applies
    at its own communication point (the tolerance of 1e-9 steps of before took some a step
    late), the same numbers as the exact times."""
    import driftfmu
    start, Ts, n = 1e4, 1e-3, 400
    summed, t = [], start
    for _ in range(n):
        summed.append(t)
        t += Ts
    exact = [start + k * Ts for k in range(n)]
    late = sum((s - start) / Ts > k + 1e-9 for k, s in enumerate(summed))
    assert late, "the sums must pass the points by more than 1e-9 steps"
    x = np.random.default_rng(5).normal(size=n)
    results = []
    for column in (summed, exact):
        signal = np.array(list(zip(column, x, np.zeros(n))),
                          dtype=[("time", float), ("x", float), ("y", float)])
        results.append(driftfmu.simulate(fmus=["Accelerometer"], start_time=start,
                                         stop_time=start + (n - 1) * Ts, step_size=Ts,
                                         input=signal, fmu_dir=fmus_in_build_layout))
    assert np.array_equal(results[0]["z"], results[1]["z"])


# -- a property: corrupted files are refused at their line ---------------------------------------

CORRUPTIONS = {
    "nan": lambda row: row[:1] + ["nan"] + row[2:],
    "inf": lambda row: row[:1] + ["inf"] + row[2:],
    "1e400": lambda row: row[:1] + ["1e400"] + row[2:],
    "empty": lambda row: row[:1] + [""] + row[2:],
    "word": lambda row: row[:1] + ["x1"] + row[2:],
    "extra column": lambda row: row + ["1"],
    "missing column": lambda row: row[:-1],
    "time nan": lambda row: ["nan"] + row[1:],
}


@settings(max_examples=60, deadline=None, suppress_health_check=HEALTH)
@given(n=st.integers(3, 60), at=st.integers(0, 10 ** 6),
       corruption=st.sampled_from(sorted(CORRUPTIONS) + ["backwards", "latin-1"]),
       crlf=st.booleans(), bom=st.booleans())
def test_a_corrupted_row_is_refused_at_its_line(acc, tmp_path_factory, n, at, corruption,
                                                crlf, bom):
    rows = [["%r" % (k * 1e-3), "%r" % (0.1 * k), "0.0"] for k in range(n)]
    i = at % n
    line = i + 2
    if corruption == "backwards":
        i = max(i, 1)
        line = i + 2
        rows[i][0] = "%r" % ((i - 1.5) * 1e-3)
    elif corruption != "latin-1":
        rows[i] = CORRUPTIONS[corruption](rows[i])
    text = ("\r\n" if crlf else "\n").join(["time,x,y"] + [",".join(r) for r in rows]) + "\n"
    data = ("\ufeff" if bom else "").encode() + text.encode()
    if corruption == "latin-1":
        marker = (",".join(rows[i])).encode()
        data = data.replace(marker, marker + b"\xe9", 1)
    folder = tmp_path_factory.mktemp("corrupt")
    result = folder / "r.csv"
    result.write_bytes(data)
    out = folder / "in.csv"
    with pytest.raises(ValueError) as info:
        hostinputs.write_input_file(acc, [result], out, hold=("theta", "T"))
    said = str(info.value)
    assert "\n" not in said and said.startswith("%s line " % result), said
    number = int(said[len("%s line " % result):].split(":")[0])
    assert number == line, (said, line)
    assert not out.exists()


# -- memory: streamed, bounded for any size -------------------------------------------------------

def _peak_rss_of_inputs(fmu, result, out):
    import peakrss
    rc, _, err, peak = peakrss.run(["inputs", fmu, result, "--output-file", out] + HOLD)
    assert rc == 0, err
    return peak


def _big_result(path, megabytes):
    rng = np.random.default_rng(1)
    k = 0
    with open(path, "w") as f:
        f.write("time,x,y,u\n")
        while f.tell() < megabytes * 2 ** 20:
            block = rng.normal(size=(4096, 2)).tolist()
            f.write("".join("%r,%r,0.0,%r\n" % ((k + i) * 1e-3, a, b)
                            for i, (a, b) in enumerate(block)))
            k += 4096
    return k


def _memory(acc, tmp_path, megabytes, report):
    result = tmp_path / "big.csv"
    rows = _big_result(result, megabytes)
    out = tmp_path / "in.csv"
    peak = _peak_rss_of_inputs(acc, result, out)
    assert out.stat().st_size > result.stat().st_size  # (every sample written: two rows each)
    assert peak < 200 * 2 ** 20, peak
    report("driftfmu inputs on a %d MB result (%d rows): peak RSS %.0f MB"
           % (megabytes, rows, peak / 2 ** 20))
    return peak


def test_inputs_streams_a_result_in_bounded_memory(acc, tmp_path, report):
    """A 10 MB result (the loop's size; 1.5 GB was needed for 100 MB): the peak RSS of the
    process stays under 200 MB."""
    _memory(acc, tmp_path, 10, report)


@pytest.mark.qualification
def test_inputs_streams_a_100_mb_result_under_200_mb(acc, tmp_path, report):
    _memory(acc, tmp_path, 100, report)
