"""Internal (not a stable API; use the out= of the functions of driftfmu instead).

Writing results whole or not at all, and the plots.

Files are written into a hidden staging folder beside the destination and moved into place only
when every file of the set has been written (:class:`Staging`, :func:`staged`); on any error or
Ctrl-C, also during the moves, the destination is left as it was.
"""
import contextlib
import json
import os
import shutil
from pathlib import Path

from driftfmu.simulations import folders
from driftfmu.simulations.errors import UsageError

#: The prefix of the hidden staging folders.
STAGE = ".driftfmu-stage-"


def nearest_existing(path):
    """``path`` if it exists, else its nearest parent that does (a folder, or a file in the
    way of the folders to make)."""
    path = Path(path)
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _holds_replaced(stage):
    """True when the staging folder ``stage`` holds files that were in place before (its
    process was killed while it moved its files in): they are not removed with it."""
    return any(name.startswith(".replaced-") for name in os.listdir(stage))


class Staging:
    """All the outputs of one job, or none of them (``driftfmu build``: FMUs, native FMUs,
    cross-check folders, the SSP archive; a master's result folder, through :func:`staged`).

    :meth:`path` hands out a staged stand-in for each destination, a hidden folder
    ``.driftfmu-stage-*`` in the destination's nearest existing folder (the same file system,
    so the move is a rename); the job writes there.  Leaving the ``with`` block normally moves
    every staged file into place, a file that was there kept aside until all have moved; an
    exception or interrupt in the block or during the moves removes the staged files, puts
    back what was replaced and removes the folders made for the destinations.  Either way the
    hidden folders go.  Those of a process killed outright (SIGKILL) stay until the next
    staging in the same folder removes them (:func:`driftfmu.simulations.folders.sweep`), unless
    they hold a file that was in place before.
    """

    def __init__(self):
        self._pairs = []  # (hidden folder, staged path, destination)
        self._shown = []  # (staged path, destination as given): for the log's lines
        self._held = []   # (log, line) of the lines about written files, until the commit

    def path(self, target, folder=True):
        """The staged stand-in for ``target`` (a folder, or with ``folder=False`` a file)."""
        shown = Path(target)
        target = shown.absolute()
        anchor = target if folder else target.parent
        while not anchor.is_dir() and anchor != anchor.parent:
            anchor = anchor.parent
        folders.sweep((STAGE,), dir=anchor, keep=_holds_replaced)
        stage = Path(folders.make(STAGE, dir=anchor))
        staged = stage / target.name
        self._pairs.append((stage, staged, target))
        self._shown.append((staged, shown))
        return staged

    def log(self, log):
        """``log`` with the staged paths in its lines named by their destinations; a line
        naming a staged path (what was written: "built ...") is held back until every output
        is in place, so a job that fails names no file it leaves behind."""
        def staged_log(line):
            held = False
            for staged, shown in self._shown:
                held = held or str(staged) in line
                line = line.replace(str(staged), str(shown))
            if held:
                self._held.append((log, line))
            else:
                log(line)
        return staged_log

    def __enter__(self):
        return self

    def __exit__(self, kind, value, tb):
        try:
            if kind is None:
                self._commit()
        finally:
            for stage, _, _ in self._pairs:
                folders.remove(stage)
        if kind is None:  # (and the commit did not raise): every output is in place
            for log, line in self._held:
                log(line)
        return False

    def _commit(self):
        placed, kept, made = [], [], []
        try:
            for stage, staged, target in self._pairs:
                if staged.is_dir():
                    files = sorted(p for p in staged.rglob("*") if not p.is_dir())
                else:
                    files = [staged] if staged.exists() else []
                for f in files:
                    dest = target / f.relative_to(staged) if f != staged else target
                    top = dest.parent
                    while not top.parent.exists():
                        top = top.parent
                    if not top.exists():
                        made.append(top)
                        dest.parent.mkdir(parents=True)
                    if dest.exists() or dest.is_symlink():
                        aside = stage / (".replaced-%d" % len(kept))
                        os.replace(dest, aside)
                        kept.append((aside, dest))
                    os.replace(f, dest)
                    placed.append(dest)
        except BaseException:
            for dest in reversed(placed):
                with contextlib.suppress(OSError):
                    dest.unlink()
            for aside, dest in reversed(kept):
                with contextlib.suppress(OSError):
                    os.replace(aside, dest)
            for d in reversed(made):
                shutil.rmtree(d, ignore_errors=True)
            raise


@contextlib.contextmanager
def staged(out_dir):
    """Yield a folder for the files of ``out_dir``; when the block succeeds they are moved into
    ``out_dir`` (created if missing), all of them or none (:class:`Staging`: on an error or an
    interrupt in the block or during the moves, ``out_dir`` is left as it was).

    ``out_dir`` naming an existing file, or a path under one, is a UsageError (one line, raised
    before the block runs, nothing written)."""
    out = Path(out_dir)
    existing = nearest_existing(out)
    if not existing.is_dir():
        raise UsageError("%s is an existing file; allowed: a folder (created if missing)"
                         % existing)
    with Staging() as staging:
        stage = staging.path(out)
        stage.mkdir()
        yield stage


def write_csv(path, columns, names):
    """Write ``columns[name]`` for ``name`` in ``names`` as CSV with a header, full precision."""
    import numpy as np
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")


def write_json(path, obj):
    """Write ``obj`` as indented JSON."""
    with open(path, "w") as fh:
        json.dump(obj, fh, indent=2, sort_keys=False)
        fh.write("\n")


def _limits(values, pad=0.08, include=()):
    """Axis limits around the finite ``values`` (and ``include``), padded; never empty."""
    import numpy as np
    v = np.concatenate([np.ravel(np.asarray(a, dtype=float)) for a in values]
                       + [np.asarray(include, dtype=float)])
    v = v[np.isfinite(v)]
    if not v.size:
        return -1.0, 1.0
    lo, hi = float(v.min()), float(v.max())
    span = hi - lo if hi > lo else max(abs(hi), 1e-12)
    return lo - pad * span, hi + pad * span


#: Units for people: the parameters' units as models.parameters writes them ("V/g2").
_UNIT_TEXT = {"V/g2": "V/g²", "V/g3": "V/g³", "V/g4": "V/g⁴", "g2": "g²", "V2": "V²"}


def value_text(name, value):
    """``"a4 = 0.05 V/g⁴"``: a parameter with its unit (none for a unit of 1)."""
    from driftfmu.models import parameters
    unit = parameters.PARAMETERS[name].unit
    return "%s = %g%s" % (name, value, "" if unit == "1" else " " + _UNIT_TEXT.get(unit, unit))


def general_text(general):
    """The general model's parameters that are not off (``a3, a4, B`` and the known input
    ``drive, Qu, Xu, fu``), for a title: ``"a4 = 0.05 V/g⁴, B = 1, known input u: sinusoidal,
    Xu = 1 g, fu = 5 Hz"``; ``""`` for the letter's sensor."""
    from driftfmu.models import excitation
    general = {k: v for k, v in (general or {}).items() if v}
    parts = [value_text(k, general[k]) for k in ("a3", "a4", "B") if k in general]
    drive = general.get("drive", excitation.DRIVE_OFF)
    if drive != excitation.DRIVE_OFF:
        parts.append("known input u: %s" % excitation.DRIVES.get(drive, drive))
        parts += [value_text(k, general[k]) for k in ("Qu", "Xu", "fu") if k in general]
    return ", ".join(parts)


def drift_labels(general=None):
    """(realised, expected): how the realised and the expected drift are computed, for labels:
    ``a2·mean(x²)`` and ``a2·E[x²]`` for the letter's sensor, ``mean(a2 x² + a4 x⁴)`` and
    ``E[a2 x² + a4 x⁴]`` with the general sensor's terms that are on."""
    general = general or {}
    terms = ["a2 x²"] + ["a%d x%s" % (i, "³⁴"[i - 3]) for i in (3, 4)
                         if general.get("a%d" % i)]
    if len(terms) == 1:
        return "a2·mean(x²)", "a2·E[x²]"
    return "mean(%s)" % " + ".join(terms), "E[%s]" % " + ".join(terms)


def plot_drift(path, cols, title, general=None, labels=None):
    """The letter's Fig. 1, done right (one run): EKF1-3 against the realised and the expected
    drift (top) and EKF1 against the empirical drift ``z̄ - a0``, the letter's reference, whose
    linear term ``a1 x̄`` dwarfs the drift for a Gaussian state (bottom).

    Drifts in mV over the sample number on a log axis (the start-up and the settled estimate
    both visible); the y range of the top panel is that of its curves after the first 1 % of
    the samples (at least 10), of the bottom one after the first 10 %, so a start-up transient
    does not flatten the rest; legends sit beside the axes, off the curves.  ``general``: the
    general model's parameters (``a3, a4``: the realised and expected drift's terms);
    ``labels``: (realised, expected), how the two are computed, instead.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    mv = {c: 1e3 * np.asarray(cols[c], dtype=float) for c in
          ("dc_ekf1", "dc_ekf2", "dc_ekf3", "dc_realised", "dc_expected", "dc_empirical")}
    n = len(mv["dc_ekf1"])
    k = np.arange(1, n + 1)
    start = min(n - 1, max(10, n // 100))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 7), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 2]})
    realised, expected = labels or drift_labels(general)
    top.plot(k, mv["dc_realised"], color="0.55", lw=3.2, alpha=0.6,
             label="realised  %s" % realised)
    top.plot(k, mv["dc_expected"], color="k", lw=1.0, ls=":", label="expected  %s" % expected)
    top.plot(k, mv["dc_ekf3"], color="C2", lw=1.3, label="EKF3")
    top.plot(k, mv["dc_ekf1"], color="C0", lw=2.0, label="EKF1")
    top.plot(k, mv["dc_ekf2"], color="C1", lw=1.1, ls=(0, (3, 3)),
             label="EKF2 (dashed, over EKF1)")
    top.set_ylim(*_limits([mv[c][start:] for c in ("dc_ekf1", "dc_ekf2", "dc_ekf3",
                                                   "dc_realised", "dc_expected")]))
    top.set_title("estimates against the realised and the expected drift", fontsize=10)
    bottom.plot(k, mv["dc_empirical"], color="C3", lw=0.9, label="empirical  z̄ − a0")
    bottom.plot(k, mv["dc_ekf1"], color="C0", lw=1.3, label="EKF1")
    bottom.axhline(0.0, color="k", lw=0.6)
    late = min(n - 1, max(10, n // 10))
    bottom.set_ylim(*_limits([mv["dc_empirical"][late:], mv["dc_ekf1"][late:]],
                             include=(0.0,)))
    bottom.set_title("EKF1 against the empirical drift z̄ − a0 (the letter's reference)",
                     fontsize=10)
    for ax in (top, bottom):
        log_sample_axis(ax)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_ylabel("drift [mV]")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
    bottom.set_xlim(1, max(n, 2))
    bottom.set_xlabel("sample k (log scale)")
    caption(fig, title)
    layout(fig)
    savefig(fig, path, dpi=120)
    plt.close(fig)


def mark_clipping(ax):
    """Mark every curve of ``ax`` that leaves the y range: small triangles on the frame where
    it is off the scale (pointing the way it went), and a note in the corner naming the curve,
    the samples and how far it went.  Nothing is clipped without a mark (issue 19: drift.png's
    bottom panel hid k = 1-99 of the empirical drift).  Log axes: values <= 0 are not drawable
    and not counted.  Returns the notes."""
    import numpy as np
    y0, y1 = sorted(ax.get_ylim())
    x0, x1 = sorted(ax.get_xlim())
    logy = ax.get_yscale() == "log"
    xname = "k" if any(a.get_xlabel().startswith("sample k")
                       for a in ax.get_shared_x_axes().get_siblings(ax)) else "x"
    ylabel = ax.get_ylabel()
    unit = (" " + ylabel[ylabel.rindex("[") + 1:ylabel.rindex("]")]
            if "[" in ylabel and ylabel.rstrip().endswith("]") else "")
    notes = []
    for line in list(ax.get_lines()):
        label = line.get_label()
        if label.startswith(("_child", "_nolegend_", "_clipped")):
            continue  # unnamed helpers (axhline, axvline) and the marks themselves
        label = label.lstrip("_")  # "_EKF1 5 %": named, kept out of the legend
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        if x.shape != y.shape or not x.size:
            continue
        ok = np.isfinite(x) & np.isfinite(y) & (x >= x0) & (x <= x1)
        if logy:
            ok &= y > 0
        for side, off, edge, marker in (("above", ok & (y > y1), y1, "^"),
                                        ("below", ok & (y < y0), y0, "v")):
            if not off.any():
                continue
            xs = x[off]
            pick = np.unique(np.linspace(0, xs.size - 1, min(xs.size, 12)).astype(int))
            ax.plot(xs[pick], np.full(pick.size, edge), ls="none", marker=marker, ms=5,
                    color=line.get_color(), clip_on=False, zorder=5,
                    label="_clipped %s" % label)
            far = float(np.max(y[off]) if side == "above" else np.min(y[off]))
            where = ("%g" % xs.min() if xs.min() == xs.max()
                     else "%g to %g" % (xs.min(), xs.max()))
            notes.append("%s off the scale %s at %s = %s (to %.3g%s)"
                         % (label.split("  ")[0].split(" (")[0], side, xname, where, far,
                            unit))
    title = ax.title
    if any(" above " in t for t in notes) and title.get_text():
        # the marks sit on the top edge: lift the axes' title clear of them
        ax.set_title(title.get_text(), fontsize=title.get_fontsize(), pad=11)
    if notes:
        ax.text(0.99, 0.02, "\n".join("%s %s" % ("▲" if " above " in t else "▼", t)
                                      for t in notes),
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7, color="0.25",
                bbox=dict(facecolor="white", edgecolor="0.7", alpha=0.85, lw=0.5))
    return notes


def mark_figure(fig):
    """:func:`mark_clipping` on every axes of ``fig`` not marked yet."""
    for ax in fig.axes:  # get_ylim() autoscales what is still stale
        if ax.get_visible() and ax.get_lines() and not getattr(ax, "_driftfmu_marked", False):
            mark_clipping(ax)
            ax._driftfmu_marked = True


def layout(fig, **kw):
    """``fig.tight_layout(**kw)`` after the curves that leave their axes are marked
    (:func:`mark_figure`), so that the layout makes room for what the marks move (a title
    lifted clear of the marks on the top edge)."""
    mark_figure(fig)
    fig.tight_layout(**kw)


def savefig(fig, path, dpi=120):
    """Save ``fig``: first every axes' curves that leave its y range are marked
    (:func:`mark_clipping`), where :func:`layout` has not done it."""
    mark_figure(fig)
    skip_layout_draw(fig)
    fig.savefig(path, dpi=dpi)


def fork_is_cheap():
    """More than one core, and a worker would be forked (this process is single-threaded)
    with matplotlib already imported, so that drawing a figure beside costs no start-up."""
    import os
    import sys
    import threading
    return ((os.cpu_count() or 1) > 1 and threading.active_count() == 1
            and "matplotlib.pyplot" in sys.modules and hasattr(os, "fork"))


def draw_beside(first, *others):
    """Call ``first()`` here and each of ``others`` (picklable: ``functools.partial`` of a
    module-level plotting function) in a forked worker at the same time, when forking is cheap
    (:func:`fork_is_cheap`); all in this process, in order, otherwise.  Returns when every one
    is done; an exception in a worker is raised here."""
    if not others or not fork_is_cheap():
        first()
        for other in others:
            other()
        return
    from driftfmu.simulations import batch
    with batch.process_pool(len(others), "driftfmu.simulations.output") as pool:
        later = [pool.submit(other) for other in others]
        first()
        for future in later:
            future.result()


def skip_layout_draw(fig):
    """After ``fig.tight_layout()`` the figure keeps a placeholder layout engine, and with any
    engine ``savefig`` first draws the whole figure without rendering it, only to lay it out
    (about 40 % of a figure's time): a placeholder lays out nothing, so it is dropped and the
    figure is drawn once, to the same pixels."""
    try:
        from matplotlib.layout_engine import PlaceHolderLayoutEngine
    except ImportError:  # matplotlib < 3.6: no layout engines, no extra draw
        return
    if isinstance(fig.get_layout_engine(), PlaceHolderLayoutEngine):
        fig.set_layout_engine(None)


def caption(fig, text, width=95):
    """A caption-like title over the whole figure, wrapped to ``width`` characters."""
    import textwrap
    text = text.replace(" = ", "\u00a0=\u00a0")  # "a1 = 1" stays on one line
    fig.suptitle("\n".join(textwrap.wrap(text, width)), fontsize=10.5)


#: Digits and minus as Unicode superscripts.
_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075"
                                            "\u2076\u2077\u2078\u2079")


def decade_label(value, pos=None):
    """A log axis' tick label: ``10⁻³`` at a power of ten (Unicode superscripts: the same
    look as matplotlib's default, without its mathtext, whose parsing was a quarter of a
    sweep figure's drawing time), ``%g`` elsewhere."""
    import math
    if value > 0.0:
        e = round(math.log10(value))
        if abs(math.log10(value) - e) < 1e-9:
            return "10" + str(int(e)).translate(_SUPERSCRIPT)
    return "%g" % value


def decade_labels(axis):
    """:func:`decade_label` for the major ticks of ``axis`` (``ax.xaxis`` or ``ax.yaxis``)."""
    from matplotlib.ticker import FuncFormatter
    axis.set_major_formatter(FuncFormatter(decade_label))


def log_sample_axis(ax):
    """A log x axis of sample numbers with plain tick labels (1, 10, 100, 1000)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(base=10))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: "%g" % v))
    ax.xaxis.set_minor_formatter(NullFormatter())
