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
input no file gives is held at its start value, written into the file so that the host does
not warn about a missing input.  Sample ``k``'s value is the first row of the file in the
sample period ``[t_k, t_{k+1})``: fed this way, an FMU's rows at ``t_k`` and at ``t_k + Ts/4``
both show sample ``k``; a file that has no row in a sample period (fmpy picks a 2 ms output
interval for a 2 s run) is refused, naming the sample and the ``--output-interval`` to use.
"""
import csv
import math
from pathlib import Path

from driftfmu.simulations.errors import UsageError

#: Where in the previous sample period an input file changes to the next sample's value, in
#: sample periods after that period's instant (strictly inside it, away from the instants and
#: from the half-period points at which a fixed-step host with h = Ts/2 sets inputs).
LEAD = 0.25
#: A row is at sample instant t_k when within this many sample periods of it (the FMUs' own
#: tolerance, slave_base.INSTANT_TOLERANCE).
INSTANT_TOLERANCE = 1e-6
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
    model description (``Ts``: the start value of its parameter ``Ts``; start time: its default
    experiment's, else 0)."""
    from driftfmu.fmu_src.schemas import read_model_description
    path = Path(fmu)
    if not path.is_file():
        raise UsageError("FMU %s does not exist; allowed: the path of one of the FMUs' .fmu "
                         "files" % fmu)
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:
        raise UsageError("%s is not an FMU (%s); allowed: the path of one of the FMUs' .fmu "
                         "files" % (fmu, str(exc).splitlines()[0] if str(exc) else
                                    type(exc).__name__)) from None
    inputs = [(v.name, float(v.start) if v.start is not None else 0.0)
              for v in md.modelVariables if v.causality == "input"]
    ts = [v.start for v in md.modelVariables if v.name == "Ts"]
    Ts = float(ts[0]) if ts and ts[0] is not None else None
    experiment = md.defaultExperiment
    start = float(experiment.startTime) if experiment is not None and \
        experiment.startTime is not None else 0.0
    return md.modelName, inputs, Ts, start


def read_result(path):
    """``(names, rows)`` of a result CSV: the column names after ``time`` and the rows as
    tuples of floats (time first)."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            table = list(csv.reader(f))
    except OSError as exc:
        raise UsageError("%s: %s; allowed: a result CSV file" % (path, exc.strerror or exc)) \
            from None
    if not table or not table[0] or table[0][0].strip().strip('"') != "time":
        raise UsageError("%s has no header with a first column 'time'; allowed: a result CSV "
                         "as fmpy, fmusim or driftfmu write it" % path)
    names = [n.strip().strip('"') for n in table[0][1:]]
    rows = []
    for number, row in enumerate(table[1:], start=2):
        if not row:
            continue
        if len(row) != len(names) + 1:
            raise UsageError("%s line %d has %d columns, the header %d; allowed: one value per "
                             "column" % (path, number, len(row), len(names) + 1))
        try:
            rows.append(tuple(float(v) for v in row))
        except ValueError:
            raise UsageError("%s line %d holds a value that is not a number; allowed: numbers"
                             % (path, number)) from None
    if not rows:
        raise UsageError("%s has no rows; allowed: a result with at least one row" % path)
    return names, rows


def sample_values(path, rows, column, Ts, start):
    """The values of ``column`` (an index into the rows) at samples ``1, 2, ...``: for each
    sample period ``[t_k, t_{k+1})`` the first row in it, up to the period of the last row."""
    tol = INSTANT_TOLERANCE
    if abs((rows[0][0] - start) / Ts) > tol:
        raise UsageError("%s starts at t = %r s, not at the start time %r s (sample 1); "
                         "allowed: results from the start time on" % (path, rows[0][0], start))
    values = []
    for row in rows:
        position = (row[0] - start) / Ts  # sample periods after the start
        if not math.isfinite(position):
            raise UsageError("%s has the time %r; allowed: finite times" % (path, row[0]))
        k = math.floor(position + tol)    # the period [t_{k+1}, t_{k+2}) of sample k + 1
        if k < len(values):
            continue                      # a later row of a period already taken
        if k > len(values):
            missing = len(values) + 1     # 1-based sample number
            raise UsageError(
                "%s has no row for sample %d (t = %r s to %r s): every sample period needs "
                "one; record every sample (fmpy simulate --output-interval %r, the sample "
                "period Ts)" % (path, missing, start + (missing - 1) * Ts, start + missing * Ts,
                                Ts))
        values.append(row[column])
    return values


def host_input(fmu, results, Ts=None, start_time=None):
    """The input file of FMU ``fmu`` from the ``results`` upstream (see the module).

    Returns ``(header, rows, sources)``: the column names (``time`` first), the rows, and for
    each input the file it came from (None: held at its start value).
    """
    model, inputs, fmu_Ts, fmu_start = fmu_inputs(fmu)
    if not inputs:
        raise UsageError("%s (%s) has no inputs; allowed: an FMU with inputs (Accelerometer, "
                         "DriftEstimator, DualDriftEstimator; Excitation's u_in)" % (fmu, model))
    Ts = fmu_Ts if Ts is None else Ts
    start = fmu_start if start_time is None else start_time
    if Ts is None or not (math.isfinite(Ts) and Ts > 0.0):
        raise UsageError("Ts = %r; allowed: the sample period Ts > 0 the FMU runs with" % (Ts,))
    if not math.isfinite(start):
        raise UsageError("start time %r; allowed: a finite time" % (start,))
    tables = [(Path(p), *read_result(p)) for p in results]
    columns, sources = {}, {}
    for name, start_value in inputs:
        found = next(((path, rows, names.index(want) + 1) for want in _columns(model, name)
                      for path, names, rows in tables if want in names), None)
        if found is None:
            columns[name], sources[name] = start_value, None
        else:
            path, rows, index = found
            columns[name] = sample_values(path, rows, index, Ts, start)
            sources[name] = path
    lengths = [len(v) for v in columns.values() if isinstance(v, list)]
    if not lengths:
        raise UsageError("no file has a column for an input of %s (%s); allowed: result files "
                         "with a column %s" % (model, fmu, " or ".join(
                             sorted({c for n, _ in inputs for c in _columns(model, n)}))))
    m = min(lengths)
    series = {name: (v[:m] if isinstance(v, list) else [v] * m) for name, v in columns.items()}
    names = [name for name, _ in inputs]
    rows = [(start,) + tuple(series[n][0] for n in names)]
    for j in range(1, m):  # the value of sample j + 1 (at start + j Ts) from LEAD Ts after the
        change = start + (j - 1 + LEAD) * Ts  # instant before it
        rows.append((change,) + tuple(series[n][j - 1] for n in names))
        rows.append((change,) + tuple(series[n][j] for n in names))
    return ["time"] + names, rows, sources


def _columns(model, name):
    """The columns that may feed input ``name`` of ``model``, in order: its own name, then the
    output wired to it."""
    return [name] + ([WIRING[model, name]] if (model, name) in WIRING else [])


def write_input_file(fmu, results, out, Ts=None, start_time=None, force=False):
    """Write the input file of ``fmu`` (:func:`host_input`) to ``out``, whole or not at all;
    an existing ``out`` is kept unless ``force``.  Returns ``(samples, sources)``."""
    from driftfmu.simulations.output import Staging
    out = Path(out)
    if out.exists() and not force:
        raise UsageError("%s exists; allowed: a new file, or --force to replace it" % out)
    header, rows, sources = host_input(fmu, results, Ts, start_time)
    with Staging() as staging:  # (a kill at any instant: the next run completes the commit)
        with open(staging.path(out, folder=False), "w", newline="") as f:
            f.write(",".join(header) + "\n")
            for row in rows:  # repr: the shortest text that reads back as the same double
                f.write(",".join(repr(float(v)) for v in row) + "\n")
    return (len(rows) + 1) // 2, sources


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
    p.add_argument("--force", action="store_true", help="replace an existing --output-file FILE")
    p.set_defaults(func=_cli)


def _cli(args):
    samples, sources = write_input_file(args.fmu, args.results, args.output_file, args.Ts,
                                        args.start_time, args.force)
    print("wrote %s: %d samples of %s" % (args.output_file, samples, ", ".join(
        "%s from %s" % (name, path) if path is not None else "%s held at its start value" % name
        for name, path in sources.items())))
