"""Internal (not a stable API; use driftfmu.allan instead).

``driftfmu allan``: the overlapping Allan deviation of one signal, from a co-simulation of the
chain or from a CSV file, as a table (``allan.csv``, printed) and a log-log figure
(``allan.png``) with the IEEE Std 952 reading of its white-noise ``N``, bias-instability ``B``
and random-walk ``K`` figures (``allan.json``).  The math is :mod:`driftfmu.models.allan`.

The signal is checked before anything is computed, each problem a :class:`UsageError` of one
line (exit status 2): a CSV without the column or the time column, a value that is not a
finite number, time that is not strictly increasing or not uniform (steps within 1e-6 of
their mean), fewer than two samples (two clusters of one), and a ``tau`` that is not a
multiple ``m Ts`` of the sample period with ``1 <= m <= n / 2``.
"""
import math

from driftfmu.models import allan as _allan
from driftfmu.simulations.errors import UsageError

#: What ``taus`` may be named.
TAU_KINDS = ("octave", "all")
#: What ``taus`` allows, in words.
TAUS_ALLOWED = ("'octave' (m = 1, 2, 4, ..), 'all' (every m), or a sequence of tau [s], each "
                "a multiple m Ts of the sample period with 1 <= m <= n / 2")
#: A tau is a multiple of the sample period when ``tau / Ts`` is within this of an integer
#: (relative).
MULTIPLE_RTOL = 1e-6
#: Relative step of the time column within which it counts as uniform (as ``identify``).
UNIFORM_RTOL = 1e-6
#: Default length [s] of a co-simulation to analyse (100,000 samples at Ts = 1 ms).
STOP_TIME = 100.0
#: The columns of ``allan.csv``.
CSV_COLUMNS = ("tau", "m", "adev", "low", "high", "terms", "edf")


def sample_period(t, name="time", where=""):
    """The sample period of the times ``t`` (a 1-D array, strictly increasing); a UsageError
    when they are not uniform: every step within :data:`UNIFORM_RTOL` of their mean."""
    import numpy as np
    d = np.diff(np.asarray(t, dtype=float))
    if d.size == 0:
        return None
    if not np.all(d > 0):
        raise UsageError("%s%s is not strictly increasing; allowed: uniformly sampled, "
                         "increasing time" % (where, name))
    Ts = float(d.mean())
    if np.max(np.abs(d - Ts)) > UNIFORM_RTOL * Ts:
        raise UsageError("%s%s is not uniformly sampled (steps from %.9g to %.9g s); allowed: "
                         "steps within %g of their mean" % (where, name, d.min(), d.max(),
                                                             UNIFORM_RTOL))
    return Ts


def from_csv(path, column="z", time="time"):
    """``(y, Ts)`` of ``column`` of the CSV file ``path`` (header row; ``time`` the time
    column); a UsageError naming the file and what is wrong."""
    from driftfmu.models import identify
    try:
        t, y = identify.read_csv(path, columns=(time, column), min_rows=1)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    return y, _checked(t, y, time, "%s: " % path)


def from_array(data, column="z", time="time"):
    """``(y, Ts)`` of ``column`` of a structured array with a ``time`` field (as
    ``driftfmu.simulate`` returns); a UsageError naming what is wrong."""
    import numpy as np
    fields = getattr(getattr(data, "dtype", None), "names", None) or ()
    for name, what in ((time, "time"), (column, "column")):
        if name not in fields:
            raise UsageError("the array has no field %r (%s = %r); allowed: one of %s" % (
                name, what, name, ", ".join(fields) or "none (not a structured array)"))
    t = np.asarray(data[time], dtype=float).ravel()
    y = np.asarray(data[column], dtype=float).ravel()
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        raise UsageError("%s[%d] = %r is not a finite number; allowed: finite numbers only"
                         % (column, bad[0], float(y[bad[0]])))
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise UsageError("%s[%d] = %r is not a finite number; allowed: finite numbers only"
                         % (time, bad[0], float(t[bad[0]])))
    return y, _checked(t, y, time, "")


def _checked(t, y, time, where):
    if len(y) < 2:
        raise UsageError("%s%d sample(s); allowed: at least 2 (two clusters of one sample)"
                         % (where, len(y)))
    return sample_period(t, time, where)


def cluster_sizes(n, Ts, taus="octave", per_decade=None):
    """The cluster sizes ``m`` (``tau = m Ts``) of the table: ``taus`` ``"octave"``, ``"all"``
    or a sequence of ``tau`` [s]; ``per_decade``: about that many per decade instead of the
    octaves.  A UsageError for a ``tau`` outside the data."""
    if per_decade is not None:
        return _allan.decade_m(n, per_decade)
    if isinstance(taus, str):
        return _allan.octave_m(n) if taus == "octave" else _allan.all_m(n)
    ms = []
    top = n // 2
    for tau in taus:
        ratio = tau / Ts
        m = int(round(ratio))
        if abs(ratio - m) > MULTIPLE_RTOL * max(ratio, 1.0):
            raise UsageError("tau = %r s is not a multiple of the sample period Ts = %.9g s; "
                             "allowed: m Ts with 1 <= m <= %d (%.9g s to %.9g s)"
                             % (tau, Ts, top, Ts, top * Ts))
        if not 1 <= m <= top:
            raise UsageError("tau = %r s is outside the data (%d samples at Ts = %.9g s: at "
                             "least two clusters); allowed: m Ts with 1 <= m <= %d (%.9g s "
                             "to %.9g s)" % (tau, n, Ts, top, Ts, top * Ts))
        if m not in ms:
            ms.append(m)
    return sorted(ms)


def taus_problem(taus):
    """Why ``taus`` is not allowed (before the data are known), or None."""
    from driftfmu.simulations import checks
    if isinstance(taus, str):
        return None if taus in TAU_KINDS else (
            "taus = %r is not allowed; allowed: %s" % (taus, TAUS_ALLOWED))
    from collections.abc import Iterable
    if not isinstance(taus, Iterable) or isinstance(taus, (bytes, dict)):
        return "taus = %r is not allowed; allowed: %s" % (taus, TAUS_ALLOWED)
    taus = list(taus)
    if not taus:
        return "taus = [] is empty; allowed: %s" % TAUS_ALLOWED
    for tau in taus:
        if not checks.is_number(tau) or not (math.isfinite(tau) and tau > 0):
            return "taus has %r, which is not a number > 0; allowed: %s" % (tau, TAUS_ALLOWED)
    return None


def analyse(y, Ts, ms, progress=None):
    """The table at cluster sizes ``ms`` and the reading (:func:`driftfmu.models.allan.read`)
    of ``y`` sampled at ``Ts``: a dict of lists ``tau, m, adev, low, high, terms, edf`` and
    ``N, B, K, reading``."""
    n = len(y)
    table = {c: [] for c in CSV_COLUMNS}
    chunk = max(1, len(ms) // 100)
    for start in range(0, len(ms), chunk):
        part = ms[start:start + chunk]
        adevs, terms = _allan.oadev(y, part)
        for m, a, k in zip(part, adevs, terms):
            nu = _allan.edf(n, m)
            low, high = _allan.interval(float(a), nu)
            for c, v in zip(CSV_COLUMNS, (m * Ts, m, float(a), low, high, int(k), nu)):
                table[c].append(v)
        if progress is not None:
            progress(start + len(part))
    reading = _allan.read(y, Ts)
    out = dict(table)
    out.update({k: reading[k] for k in ("N", "B", "K")})
    out["reading"] = reading["grid"]
    return out


#: How the figures are printed, with their units (the signal's unit ``u``).
FIGURES = (("N", "white noise", "%s/√Hz"), ("B", "bias instability", "%s"),
           ("K", "random walk", "%s/√s"))


def figure_unit(name, unit):
    return dict((f[0], f[2]) for f in FIGURES)[name] % (unit or "unit")


def figure_text(name, fig, unit):
    """One figure for people: ``N = 0.001 V/√Hz (0.000998 to 0.001002; slope -1/2 over tau
    0.002 to 0.512 s, read at tau = 1 s)`` or ``K: not resolved (why)``."""
    if fig["value"] is None:
        return "%s: not resolved (%s)" % (name, fig["reason"])
    u = figure_unit(name, unit)
    if name == "B":
        how = "floor %.4g %s over tau %.4g to %.4g s, divided by 0.664" % (
            fig["floor"], unit or "unit", fig["tau_from"], fig["tau_to"])
    else:
        how = "slope %s over tau %.4g to %.4g s, read at tau = %g s" % (
            "-1/2" if name == "N" else "+1/2", fig["tau_from"], fig["tau_to"], fig["read_at"])
    return "%s = %.4g %s (68 %%: %.4g to %.4g; %s)" % (name, fig["value"], u, fig["low"],
                                                       fig["high"], how)


def table_lines(result):
    """The table as printed: a header and one line per tau."""
    lines = ["%12s %9s %12s %12s %12s %9s %10s" % ("tau [s]", "m", "adev", "low", "high",
                                                   "terms", "edf")]
    for i in range(len(result["tau"])):
        lines.append("%12.6g %9d %12.6g %12.6g %12.6g %9d %10.4g" % tuple(
            result[c][i] for c in CSV_COLUMNS))
    return lines


def write(out, result, title):
    """``allan.csv``, ``allan.json`` and ``allan.png`` into ``out``, all or none."""
    from driftfmu.simulations import output
    with output.staged(out) as stage:
        output.write_csv(stage / "allan.csv", result, CSV_COLUMNS)
        output.write_json(stage / "allan.json", {k: v for k, v in result.items()
                                                 if k not in CSV_COLUMNS})
        plot(stage / "allan.png", result, title)


def plot(path, result, title):
    """The log-log figure, 9 x 6 in (1080 x 720 pixels at 120 dpi): the estimates as dots with
    their 68 % intervals, each fitted line dashed over the figure's range, thick over the tau
    it was fitted on and with a diamond (larger than the dots) where it is read, all in its own
    colour, with its value in the legend; where a figure is not resolved, a legend line that
    says so (nothing drawn beside it)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from driftfmu.simulations import output
    unit = result.get("unit") or "unit"
    tau = np.asarray(result["tau"])
    adev = np.asarray(result["adev"])
    low = np.asarray(result["low"])
    high = np.asarray(result["high"])
    fig, ax = plt.subplots(figsize=(9, 6))
    ax.set_xscale("log")
    ax.set_yscale("log")
    positive = adev > 0
    ax.errorbar(tau[positive], adev[positive],
                yerr=[adev[positive] - low[positive], high[positive] - adev[positive]],
                fmt="o", ms=3.5, color="C0", ecolor="0.55", elinewidth=1.0, capsize=2,
                label="overlapping Allan deviation of %s (68 %% intervals)"
                      % result.get("column", "the signal"))
    x_lo, x_hi = tau.min() / 1.6, tau.max() * 1.6
    for name, read_at in (("N", _allan.N_TAU), ("K", _allan.K_TAU)):
        if result[name]["value"] is not None:
            x_lo, x_hi = min(x_lo, read_at / 1.6), max(x_hi, read_at * 1.6)
    shown = np.concatenate([low[positive & (low > 0)], high[positive]])
    y_lo = shown.min() / 2.0 if shown.size else 1e-12
    y_hi = shown.max() * 2.0 if shown.size else 1.0
    for name, kind, _ in FIGURES:
        fig_ = result[name]
        value = fig_["value"]
        label = figure_text(name, fig_, unit).split(" (68")[0]
        if value is None:
            ax.plot([], [], " ", label=label)  # a legend line, nothing drawn
            continue
        if name == "N":
            line, color, read_at = (lambda t, v=value: v / np.sqrt(t)), "C1", _allan.N_TAU
            label += "  (%s, slope -1/2, at τ = 1 s)" % kind
        elif name == "K":
            line, color, read_at = (lambda t, v=value: v * np.sqrt(t / 3.0)), "C3", _allan.K_TAU
            label += "  (%s, slope +1/2, at τ = 3 s)" % kind
        else:
            line = (lambda t, v=fig_["floor"]: np.full_like(t, v))
            color, read_at = "C2", None
            label += "  (%s: floor / 0.664)" % kind
        y_lo = min(y_lo, line(np.array([read_at or tau.min()]))[0] / 1.5)
        y_hi = max(y_hi, line(np.array([read_at or tau.min()]))[0] * 1.5)
        t = np.geomspace(x_lo, x_hi, 200)
        v = line(t)
        inside = (v >= y_lo) & (v <= y_hi)  # drawn where it is on the scale, never clipped
        ax.plot(t[inside], v[inside], ls="--", lw=1.2, color=color, label=label)
        t = np.geomspace(fig_["tau_from"], fig_["tau_to"], 50)
        ax.plot(t, line(t), ls="-", lw=3.0, color=color, alpha=0.45, label="_nolegend_")
        at = read_at if read_at is not None else math.sqrt(fig_["tau_from"] * fig_["tau_to"])
        ax.plot([at], line(np.array([at])), marker="D", ms=6, color=color, label="_nolegend_")
    ax.set_xlim(x_lo, x_hi)
    ax.set_ylim(y_lo, y_hi)
    ax.set_xlabel("averaging time τ [s]")
    ax.set_ylabel("Allan deviation σ(τ) [%s]" % unit)
    ax.grid(True, which="major", alpha=0.35)
    ax.grid(True, which="minor", alpha=0.12)
    output.decade_labels(ax.xaxis)
    output.decade_labels(ax.yaxis)
    handles, labels = ax.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda i: not labels[i].startswith("overlapping"))
    ax.legend([handles[i] for i in order], [labels[i] for i in order], loc="upper center",
              bbox_to_anchor=(0.5, -0.12), fontsize=8.5, frameon=False)
    output.caption(fig, title)
    output.layout(fig)
    output.savefig(fig, path, dpi=120)
    plt.close(fig)


# -- command line -------------------------------------------------------------------------------

def _taus_option(text):
    """argparse type of ``--taus``: octave, all, or T1,T2,... [s]."""
    import argparse
    text = text.strip()
    if text in TAU_KINDS:
        return text

    def number(item):
        try:
            return float(item)
        except ValueError:
            return item.strip()
    taus = [number(v) for v in text.split(",") if v.strip()]
    problem = taus_problem(taus)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return taus


def add_cli(groups):
    """``driftfmu allan``."""
    from driftfmu.simulations import checks, cli
    p = groups["top"].add_parser(
        "allan", help="the overlapping Allan deviation of an output of the chain or of a CSV "
        "column: table, figure and the IEEE 952 reading of N, B, K")
    p.add_argument("csv", nargs="?", default=None, metavar="CSV",
                   help="a recording (header row, a time column and the column to analyse); "
                   "without it the chain is co-simulated (driftfmu.simulate)")
    p.add_argument("--column", default="z", metavar="NAME",
                   help="the signal: an output of the chain (z, z_comp, x, dc_ekf1, ...) or a "
                   "column of CSV (default: z)")
    p.add_argument("--time", default="time", metavar="NAME",
                   help="CSV's time column [s], uniformly sampled (default: time)")
    p.add_argument("--taus", type=_taus_option, default="octave", metavar="octave|all|T1,T2,..",
                   help="the table's tau: octave (m = 1, 2, 4, ..), all (every m; n/2 of them, "
                   "each O(n)), or a list [s] of multiples of the sample period within two "
                   "clusters (default: octave)")
    p.add_argument("--per-decade", type=checks.count_option("per_decade", 1), default=None,
                   metavar="K", help="about K tau per decade instead of --taus")
    p.add_argument("--stop-time", type=float, default=None, metavar="T",
                   help="length [s] of the co-simulation (default: %g s)" % STOP_TIME)
    p.add_argument("--start-values", nargs="+", default=None, metavar="NAME VALUE",
                   help="start values of the co-simulation as NAME VALUE pairs (any "
                   "parameter of the FMUs, e.g. --start-values Q 0 R 1e-6 seed 3: Q 0 "
                   "leaves the sensor at rest)")
    p.add_argument("--unit", default=None, metavar="U",
                   help="the signal's unit for the figures (default: the FMU variable's, or "
                   "'unit' for a CSV)")
    cli.add_out(p, "results/allan")
    cli.add_fmu_dir(p)
    cli.add_backend(p)
    p.set_defaults(func=_cmd_allan)


def _cmd_allan(args):
    """``driftfmu allan``: :func:`driftfmu.allan`."""
    import driftfmu
    from driftfmu.simulations import cli
    if args.csv is not None and (args.start_values is not None or args.stop_time is not None):
        raise UsageError("--start-values and --stop-time are for a co-simulation; allowed: "
                         "neither with a CSV file")
    if args.per_decade is not None and args.taus != "octave":
        raise UsageError("--per-decade with --taus %s; allowed: one of them"
                         % (args.taus if isinstance(args.taus, str)
                            else ",".join("%g" % t for t in args.taus)))
    kwargs = dict(column=args.column, taus=args.taus, per_decade=args.per_decade,
                  out=args.out, unit=args.unit)
    if args.csv is not None:
        kwargs["time"] = args.time
    else:
        kwargs.update(start_values=cli.start_values(args.start_values, numbers=True) or {},
                      stop_time=args.stop_time, backend=args.backend, fmu_dir=args.fmu_dir)
    with cli.progress(None, "allan deviation", "tau") as update:
        r = driftfmu.allan(args.csv, progress=update, **kwargs)
    print("wrote %s/allan.csv, allan.json, allan.png" % args.out)
    print("%s: %d samples at Ts = %.6g s, from %s" % (r["column"], r["samples"], r["Ts"],
                                                      r["source"]))
    for line in table_lines(r):
        print(line)
    for name, _, _ in FIGURES:
        print(figure_text(name, r[name], r["unit"]))
