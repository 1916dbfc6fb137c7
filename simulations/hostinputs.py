"""Internal (not a stable API; use the driftfmu command ``driftfmu inputs`` instead).

Input files for hosts that run one FMU at a time from a CSV file (fmpy's ``simulate`` and
``simulate_fmu``, Reference-FMUs' fmusim, the FMU Compliance Checker), written so that such a
host gives the chain's numbers (``driftfmu.simulate``) bit for bit.

Why a host needs them.  These hosts set the inputs of ``t``, step from ``t``, and read (record)
the outputs at ``t + h`` *before* they set the inputs of ``t + h`` (fmpy
``simulation.simulateCS``, fmusim ``FMI2CSSimulate``, the Checker's ``fmi2_cs_simulate``).  Our
outputs that depend on inputs (``Accelerometer.z`` on ``x``, every DriftEstimator output on
``z``) are computed at a sample instant from the inputs set there, so a file that changes the
input at the sample instant ``t_k`` itself makes the host record at ``t_k`` the outputs of the
previous input (the one-row lag of issue 33), although the sample is then committed with the
right one.  The cure is in the file: the value of sample ``k`` is set a little *before* ``t_k``,
at ``t_{k-1} + Ts/4`` (:data:`LEAD`), and held until ``t_k + Ts/4``.  The host then has a
communication point inside each sample period at which it sets the next value; the outputs it
records at ``t_k`` follow the value of sample ``k``, and the step from ``t_k`` commits sample
``k`` with it.  fmpy and fmusim make a communication point at every change of an input file
(for any ``--output-interval``); the Checker steps at its fixed ``-h``, which must be at most
``Ts/2``.

The file, for samples ``1 .. m`` with values ``v_1 .. v_m`` of each input::

    time,<input>,...
    t_1,            v_1
    t_1 + Ts/4,     v_1       (the step from v_1 ...
    t_1 + Ts/4,     v_2        ... to v_2, at one instant: held, not a ramp)
    t_2 + Ts/4,     v_2
    t_2 + Ts/4,     v_3
    ...

The FMUs declare their inputs ``discrete`` (sampled, held between communication points), so fmpy,
fmusim and the Checker hold the file's values; a host that interpolated them as continuous
would still see constant pieces, the repeated time stamps making each change a step.

Where the values come from: the results (CSV files with a first column ``time``, as fmpy,
fmusim or the ``driftfmu`` masters write them) of the FMUs upstream.  An input takes the
column of its own name, else the column of the output wired to it (:data:`WIRING`, the
connections of ``driftfmu.simulate``: ``z_x`` from ``z``); the first file that has it wins.  An
input no file gives is refused, naming it and the columns the files have, unless it is held
(``--hold NAME``, ``hold=``): then it is written at its start value, so that the host does not
warn about a missing input (a column of the start value for a measurement nobody gave would
be a run on zeros).  Sample ``k``'s value is the first row of the file in the sample period
``[t_k, t_{k+1})``, a row counting as at ``t_k`` within the tolerance of
:mod:`driftfmu.simulations.times` (the FMUs' millionth of a period, and what a host's running
sum of times can have rounded): fed this way, an FMU's rows at ``t_k`` and at ``t_k + Ts/4``
both show sample ``k``; a file that has no row in a sample period (fmpy picks a 2 ms output
interval for a 2 s run) is refused, naming the sample and the ``--output-interval`` to use.

What a result file may hold, read row by row (memory bounded whatever its size: one row of
each file at a time, the input file written as it goes): UTF-8 text (a byte-order mark, as
spreadsheets write it, is skipped), lines ending in LF or CRLF of at most :data:`MAX_LINE`
characters, fields separated by commas (quoted or not), a header whose first column is
``time`` and whose names are unique, then rows of as many decimal numbers (``1``, ``-0.5``,
``2.5e-3``), finite as doubles, times that never decrease and do not start before the start
time; empty rows are skipped.  Anything else is refused in one line naming the file, the line
and the value, and what is allowed: ``nan``, ``inf``, ``1e400``, a time going backwards, a
row of another width, bytes that are not UTF-8, a line or field too long.  A result that gives
fewer than two samples is refused (a host needs two rows of an input file to hold a value).
"""
import csv
import math
import re
from pathlib import Path

from driftfmu.simulations import times
from driftfmu.simulations.errors import FileProblem, UsageError

#: Where in the previous sample period an input file changes to the next sample's value, in
#: sample periods after that period's instant (strictly inside it, away from the instants and
#: from the half-period points at which a fixed-step host with h = Ts/2 sets inputs).
LEAD = 0.25
#: A row is at sample instant t_k when within this many sample periods of it (the FMUs' own
#: tolerance, slave_base.INSTANT_TOLERANCE), plus a host's rounding (simulations/times.py).
INSTANT_TOLERANCE = times.INSTANT_TOLERANCE
#: The longest line of a result file read, in characters (a row of a thousand numbers of 25
#: characters each fits 40 times over).
MAX_LINE = 1 << 20
#: A number as a result file may write it: ASCII decimal digits, optionally with an exponent
#: (Python's float() also reads '1_000', 'nan' and other scripts' digits; fmpy does not).
NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: (model, input) -> the output wired to it, as ``driftfmu.simulate`` wires the chain.
WIRING = {
    ("Accelerometer", "x"): "x",
    ("Accelerometer", "y"): "y",
    ("DriftEstimator", "z"): "z",
    ("DriftEstimator", "u"): "u",
    ("DualDriftEstimator", "z_x"): "z",
    ("DualDriftEstimator", "z_y"): "z_y",
}


def fmu_inputs(fmu):
    """``(model name, [(input, start value)], Ts, start time)`` of the FMU file ``fmu``, from its
    model description, once the FMU holds what driftfmu relies on
    (:func:`driftfmu.simulations.fmucheck.check_fmu`) (``Ts``: the start value of its
    parameter ``Ts``; start time: its default experiment's, else 0)."""
    from driftfmu.simulations import fmucheck
    path = Path(fmu)
    # check_fmu refuses a missing path and a folder first, each as what it is
    md = fmucheck.check_fmu(str(path), expected=fmucheck.expected_model(path), validate=False)
    inputs = [(v.name, float(v.start) if v.start is not None else 0.0)
              for v in md.modelVariables if v.causality == "input"]
    ts = [v.start for v in md.modelVariables if v.name == "Ts"]
    Ts = float(ts[0]) if ts and ts[0] is not None else None
    experiment = md.defaultExperiment
    start = float(experiment.startTime) if experiment is not None and \
        experiment.startTime is not None else 0.0
    return md.modelName, inputs, Ts, start


class Result:
    """A result CSV file, read row by row: :attr:`names` (the columns after ``time``) and
    :meth:`rows`, each ``(line number, (time, values...))`` as floats.  Open it with ``with``;
    every departure from what the module says a result may hold is a FileProblem naming the
    file, the line and the value."""

    def __init__(self, path):
        self.path = Path(path)
        try:
            self._file = open(self.path, "rb")
        except OSError as exc:
            raise UsageError("%s: %s; allowed: a result CSV file" % (
                self.path, exc.strerror or exc)) from None
        self._line = 0
        try:
            self._reader = csv.reader(self._lines())
            header = self._next()
            if header is None or not header or header[0].strip().strip('"') != "time":
                found = "" if header is None else ",".join(header)[:60]
                hint = ("; its header uses ';' as the separator" if header and len(header) == 1
                        and ";" in header[0] else "")
                raise FileProblem("%s line 1: no header with a first column 'time' (found %r)%s; "
                                  "allowed: a result CSV as fmpy, fmusim or driftfmu write it, "
                                  "comma-separated" % (self.path, found, hint))
            self.names = [n.strip().strip('"') for n in header[1:]]
            twice = sorted({n for n in self.names if self.names.count(n) > 1})
            if twice or "time" in self.names:
                raise FileProblem("%s line 1: the header names %s twice; allowed: one column "
                                  "per name" % (self.path, (twice or ["time"])[0]))
        except BaseException:
            self._file.close()
            raise

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._file.close()

    def _fail(self, what, allowed, line=None):
        raise FileProblem("%s line %d: %s; allowed: %s" % (
            self.path, self._line if line is None else line, what, allowed))

    def _lines(self):
        """The file's lines as text, each at most MAX_LINE characters (a longer one is refused
        before it is read whole), decoded as UTF-8, the first without a byte-order mark."""
        while True:
            raw = self._file.readline(4 * MAX_LINE + 1)  # (UTF-8: up to 4 bytes a character)
            if not raw:
                return
            self._line += 1
            if self._line == 1:
                if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
                    self._fail("the file is UTF-16 text (it starts with a UTF-16 byte-order "
                               "mark)", "UTF-8 text (a spreadsheet's 'CSV UTF-8')")
                if raw.startswith(b"\xef\xbb\xbf"):
                    raw = raw[3:]
            if len(raw) > 4 * MAX_LINE:
                text = None
            else:
                try:
                    text = raw.decode("utf-8")
                except UnicodeDecodeError as exc:
                    self._fail("byte %d of the line (0x%02x) is not UTF-8" % (
                        exc.start + 1, raw[exc.start]), "UTF-8 text")
            if text is None or len(text) > MAX_LINE:
                self._fail("the line is longer than %d characters" % MAX_LINE,
                           "lines of at most %d characters" % MAX_LINE)
            yield text

    def _next(self):
        try:
            return next(self._reader)
        except StopIteration:
            return None
        except csv.Error as exc:
            self._fail("%s" % exc, "comma-separated values (a field of at most %d "
                       "characters)" % csv.field_size_limit())

    def rows(self):
        """Yield ``(line number, (time, values...))`` of every row that is not empty."""
        width = len(self.names) + 1
        previous = None
        while True:
            row = self._next()
            if row is None:
                return
            line = self._line
            if not row or not any(field.strip() for field in row):
                continue
            if len(row) != width:
                self._fail("%d columns, the header %d" % (len(row), width),
                           "one value per column")
            values = []
            for name, field in zip(["time"] + self.names, row):
                text = field.strip()
                if not NUMBER.fullmatch(text):
                    self._fail("%s = %r is not a number" % (name, field[:40]),
                               "decimal numbers such as 0.001, -2.5 or 1e-3 (finite)")
                value = float(text)
                if not math.isfinite(value):
                    self._fail("%s = %s is beyond the range of a double" % (name, text[:40]),
                               "finite numbers, at most 1.8e308 in magnitude")
                values.append(value)
            if previous is not None and values[0] < previous:
                self._fail("the time %r is before the time of the row above, %r" % (
                    values[0], previous), "times that never decrease")
            previous = values[0]
            yield line, tuple(values)


def samples(result, columns, Ts, start):
    """Yield, for samples ``1, 2, ...``, the values of ``columns`` (indices into the rows) of
    the ``Result`` ``result``: for each sample period ``[t_k, t_{k+1})`` the first row in it
    (:func:`driftfmu.simulations.times.period`), up to the period of the last row."""
    path = result.path
    expected = 0   # the 0-based period whose first row comes next
    for line, row in result.rows():
        t = row[0]
        if expected == 0:
            if times.before_start(t, start, Ts):
                raise FileProblem(
                    "%s line %d: the result starts at t = %r s, before the start time %r s; "
                    "allowed: results from the start time on (--start-time, or the FMU's "
                    "default experiment)" % (path, line, t, start))
        k = times.period(t, start, Ts)
        if k is None:
            raise FileProblem("%s line %d: the time %r s is not a sample instant that can be "
                              "told apart with Ts = %r s from the start time %r s; allowed: "
                              "times a finite number of sample periods after the start, "
                              "within %g periods" % (path, line, t, Ts, start,
                                                     times.MAX_TOLERANCE))
        if k < expected:
            continue                      # a later row of a period already taken
        if k > expected:
            missing = expected + 1        # 1-based sample number
            if expected == 0:
                raise FileProblem(
                    "%s line %d: the result starts at t = %r s, after the start time %r s "
                    "(sample 1); allowed: results from the start time on" % (path, line, t,
                                                                           start))
            raise FileProblem(
                "%s line %d: no row for sample %d (t = %r s to %r s): every sample period "
                "needs one; record every sample (fmpy simulate --output-interval %r, the "
                "sample period Ts)" % (path, line, missing, start + (missing - 1) * Ts,
                                       start + missing * Ts, Ts))
        expected += 1
        yield tuple(row[c] for c in columns)


def _columns(model, name):
    """The columns that may feed input ``name`` of ``model``, in order: its own name, then the
    output wired to it."""
    wired = WIRING.get((model, name))
    return [name] + ([wired] if wired is not None and wired != name else [])


def plan(fmu, results, Ts=None, start_time=None, hold=()):
    """What :func:`write_input_file` writes, before a row is read: ``(model, inputs, Ts,
    start, sources)`` with ``inputs`` the FMU's ``[(input, start value)]`` and ``sources`` for
    each input the result file and column that feed it, or None when it is held (``hold``)."""
    from driftfmu.models import parameters
    model, inputs, fmu_Ts, fmu_start = fmu_inputs(fmu)
    if not inputs:
        raise UsageError("%s (%s) has no inputs; allowed: an FMU with inputs (Accelerometer, "
                         "DriftEstimator, DualDriftEstimator; Excitation's u_in)" % (fmu, model))
    Ts = fmu_Ts if Ts is None else Ts
    start = fmu_start if start_time is None else start_time
    problem = parameters.problem("Ts", Ts) if Ts is not None else \
        "Ts is not given and the FMU has none; allowed: --Ts, %s" % parameters.allowed("Ts")
    if problem:
        raise UsageError(problem)
    if not math.isfinite(start):
        raise UsageError("start time %r; allowed: a finite time" % (start,))
    names = [n for n, _ in inputs]
    unknown = [h for h in hold if h not in names]
    if unknown:
        raise UsageError("--hold %s: %s has no input %s; allowed: its inputs %s" % (
            unknown[0], model, unknown[0], ", ".join(names)))
    headers = []
    for p in results:
        with Result(p) as r:
            headers.append((Path(p), r.names))
    sources = {}
    missing = []
    for name, _ in inputs:
        found = next(((path, want) for want in _columns(model, name)
                      for path, names_ in headers if want in names_), None)
        if name in hold:
            if found is not None:
                raise UsageError("%s has the column %s for the input %s, which --hold %s "
                                 "holds; allowed: one of the two" % (found[0], found[1], name,
                                                                     name))
            sources[name] = None
        elif found is None:
            missing.append(name)
        else:
            sources[name] = found
    if missing:
        raise UsageError(_missing(model, missing, dict(inputs), headers))
    if all(sources[name] is None for name in names):
        # (a result's column sets how many samples the file has: without one it never ends)
        raise UsageError("%s's input%s %s %s held (%s), so no result gives the samples; "
                         "allowed: at least one input from a result's column" % (
                             model, "s" if len(names) > 1 else "", ", ".join(names),
                             "are all" if len(names) > 1 else "is",
                             " ".join("--hold %s" % n for n in names)))
    return model, inputs, Ts, start, sources


def _missing(model, missing, start_values, headers):
    """The one line that refuses the inputs ``missing`` no result gives: every one named,
    with the columns that would give it and the ``--hold`` that would write its start
    value."""
    files = "; ".join("%s: %s" % (path, ", ".join(n) or "no columns") for path, n in headers)
    if len(missing) == 1:
        name = missing[0]
        return ("%s's input %s is in none of the results (%s); allowed: a result with a "
                "column %s, or --hold %s to write its start value %r for every sample" % (
                    model, name, files, " or ".join(_columns(model, name)), name,
                    start_values[name]))
    return ("%s's inputs %s are in none of the results (%s); allowed: results with the "
            "columns %s, or %s to write their start values %s for every sample" % (
                model, ", ".join(missing), files,
                "; ".join(" or ".join(_columns(model, n)) for n in missing),
                " ".join("--hold %s" % n for n in missing),
                ", ".join("%s = %r" % (n, start_values[n]) for n in missing)))


def write_input_file(fmu, results, out, Ts=None, start_time=None, force=False, hold=()):
    """Write the input file of ``fmu`` (see the module) from ``results`` to ``out``, whole or
    not at all; an existing ``out`` is kept unless ``force``.  The files are read row by row
    and the input file written as they go (memory bounded for any size).  Returns
    ``(samples, sources)``, ``sources`` for each input the file it came from (None: held)."""
    from driftfmu.simulations.output import Staging
    out = Path(out)
    if out.exists() and not force:
        raise UsageError("%s exists; allowed: a new file, or --force to replace it" % out)
    model, inputs, Ts, start, sources = plan(fmu, results, Ts, start_time, hold)
    names = [n for n, _ in inputs]
    held = dict(inputs)
    files = []   # (path, [(input, column index)])
    for name in names:
        if sources[name] is not None:
            path, column = sources[name]
            entry = next((f for f in files if f[0] == path), None)
            if entry is None:
                entry = (path, [])
                files.append(entry)
            entry[1].append(name)
    m = 0
    with Staging() as staging:  # (a kill at any instant: the next run completes the commit)
        opened = []
        try:
            streams = []
            for path, fed in files:
                r = Result(path)
                opened.append(r)
                index = [r.names.index(sources[n][1]) + 1 for n in fed]
                streams.append((fed, samples(r, index, Ts, start)))
            with open(staging.path(out, folder=False), "w", newline="") as f:
                f.write(",".join(["time"] + names) + "\n")
                previous = None
                for j in _count():
                    value = dict((n, held[n]) for n in names if sources[n] is None)
                    ended = False
                    for fed, it in streams:
                        row = next(it, None)
                        if row is None:
                            ended = True
                            break
                        value.update(zip(fed, row))
                    if ended:
                        break
                    current = tuple(value[n] for n in names)
                    if j == 0:
                        _write(f, start, current)
                    else:  # sample j + 1's value from LEAD Ts after the instant before it
                        # (apart from both instants as a double: times.period told them apart
                        # within a hundredth of a period)
                        change = start + (j - 1 + LEAD) * Ts
                        _write(f, change, previous)
                        _write(f, change, current)
                    previous = current
                    m += 1
                for fed, it in streams:  # the rest of every file read and checked as well
                    for _ in it:
                        pass
            if m < 2:
                raise FileProblem(
                    "%s gives %s; allowed: results of at least 2 samples at Ts = %r s (a host "
                    "needs two rows of an input file to hold a value)" % (
                        ", ".join(str(p) for p, _ in files),
                        "no sample" if not m else "one sample only (t = %r s)" % start, Ts))
        finally:
            for r in opened:
                r.__exit__()
    return m, {name: (sources[name][0] if sources[name] is not None else None)
               for name in names}


def _count():
    j = 0
    while True:
        yield j
        j += 1


def _write(f, t, values):
    # repr: the shortest text that reads back as the same double
    f.write(",".join(repr(float(v)) for v in (t,) + tuple(values)) + "\n")


def add_cli(groups):
    p = groups["top"].add_parser(
        "inputs", help="write an FMU's input file for a host that runs one FMU at a time "
        "(fmpy simulate --input-file, fmusim, the FMU Compliance Checker) from the results "
        "of the FMUs upstream, timed so that the host gives the chain's numbers "
        "(docs/hosts.md)")
    p.add_argument("fmu", metavar="FMU", help="the .fmu whose input file to write")
    p.add_argument("results", metavar="RESULT", nargs="+",
                   help="result CSV files of the FMUs upstream (first column time), one row "
                   "per sample period at least: an input takes the column of its name, else "
                   "of the output wired to it")
    p.add_argument("--output-file", required=True, metavar="FILE",
                   help="the input CSV file to write")
    p.add_argument("--Ts", type=float, default=None, metavar="TS",
                   help="sample period [s] the FMU runs with (default: its Ts start value)")
    p.add_argument("--start-time", type=float, default=None, metavar="T",
                   help="start time [s] of the run (default: the FMU's default experiment's)")
    p.add_argument("--hold", action="append", default=[], metavar="NAME",
                   help="write the input NAME at its start value for every sample (an input "
                   "no result gives is refused otherwise); repeat for several")
    p.add_argument("--force", action="store_true", help="replace an existing --output-file FILE")
    p.set_defaults(func=_cli)


def _cli(args):
    samples_, sources = write_input_file(args.fmu, args.results, args.output_file, args.Ts,
                                         args.start_time, args.force, hold=args.hold)
    print("wrote %s: %d samples of %s" % (args.output_file, samples_, ", ".join(
        "%s from %s" % (name, path) if path is not None else
        "%s held at its start value (--hold %s)" % (name, name)
        for name, path in sources.items())))
