"""Internal (not a stable API; use driftfmu.build_fmus instead).

The FMUs' icons: a block a user recognises in a tool's diagram, drawn at build time with
matplotlib (a dependency) and packed into every FMU kind by the builders.

* FMI 2.0 (and, for tools that look there, FMI 3.0): ``model.png`` at the archive root;
* FMI 3.0: ``terminalsAndIcons/icon.png``.

Each icon is :data:`SIZE` pixels square: a rounded block with the model's name and a drawing of
what it does (the excitation's random signal, the sensor's bent characteristic
``z = a0 + a1 x + a2 x^2``, the estimator's drift estimate settling on the drift, two of those
for the dual-axis estimator).  The drawings are fixed curves, not data, so the same matplotlib
draws the same bytes (no time stamp or software name in the file): builds stay reproducible.
"""
import functools
import io
import math
import threading

#: Width and height of an icon [px].
SIZE = 160
_DPI = 100
#: matplotlib's text and path state is shared by the process: one icon at a time (the native
#: build makes FMUs in threads).
_LOCK = threading.Lock()

_TITLES = {"DriftEstimator": "Drift\nEstimator", "DualDriftEstimator": "Dual Drift\nEstimator"}


def _signal(n=40):
    """A fixed, noise-like signal (a sum of incommensurate sines): the excitation's glyph."""
    return [0.55 * math.sin(0.9 * i) + 0.3 * math.sin(2.3 * i + 1.0) + 0.15 * math.sin(5.1 * i)
            for i in range(n)]


def _draw(ax, name):
    """The model's glyph in the axes ``ax`` (data coordinates 0..1); none for a model it does
    not know (its block shows the name alone)."""
    if name == "Excitation":
        ys = _signal()
        ax.plot([0.1 + 0.8 * i / (len(ys) - 1) for i in range(len(ys))],
                [0.45 + 0.25 * y for y in ys], color="#1f77b4", lw=2)
        ax.text(0.5, 0.1, "x(t)", ha="center", va="center", fontsize=11)
    elif name == "Accelerometer":
        xs = [-1 + 2 * i / 40 for i in range(41)]
        ax.plot([0.5 + 0.38 * x for x in xs], [0.3 + 0.28 * (x + 0.5 * x * x) for x in xs],
                color="#d62728", lw=2)
        ax.plot([0.12, 0.88], [0.3, 0.3], color="0.4", lw=1)
        ax.plot([0.5, 0.5], [0.16, 0.72], color="0.4", lw=1)
        ax.text(0.5, 0.0, "z = h(x)", ha="center", va="bottom", fontsize=10)
    elif name.endswith("DriftEstimator"):
        axes = 2 if name.startswith("Dual") else 1
        for a in range(axes):
            base = 0.5 if axes == 1 else 0.62 - 0.3 * a
            ys = _signal(30)
            ax.plot([0.1 + 0.8 * i / 29 for i in range(30)],
                    [base + 0.09 * y for y in ys], color="0.6", lw=1)
            ax.plot([0.1 + 0.8 * i / 29 for i in range(30)],
                    [base - 0.15 + 0.12 * (1 - math.exp(-i / 6.0)) for i in range(30)],
                    color="#2ca02c", lw=2)
        ax.text(0.5, 0.05, "EKF dc", ha="center", va="center", fontsize=10)


@functools.lru_cache(maxsize=None)
def png(name):
    """The icon of model ``name`` as PNG bytes."""
    from matplotlib.figure import Figure
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.patches import FancyBboxPatch
    with _LOCK:
        fig = Figure(figsize=(SIZE / _DPI, SIZE / _DPI), dpi=_DPI)
        FigureCanvasAgg(fig)
        fig.patch.set_alpha(0.0)
        frame = fig.add_axes((0, 0, 1, 1))
        frame.set_axis_off()
        frame.set_xlim(0, 1)
        frame.set_ylim(0, 1)
        frame.add_patch(FancyBboxPatch((0.04, 0.04), 0.92, 0.92,
                                       boxstyle="round,pad=0,rounding_size=0.1",
                                       facecolor="white", edgecolor="#333333", lw=2.5))
        frame.text(0.5, 0.86, _TITLES.get(name, name), ha="center", va="top", fontsize=11,
                   fontweight="bold", linespacing=0.95)
        glyph = fig.add_axes((0.1, 0.08, 0.8, 0.5))
        glyph.set_axis_off()
        glyph.set_xlim(0, 1)
        glyph.set_ylim(0, 1)
        _draw(glyph, name)
        out = io.BytesIO()
        fig.savefig(out, format="png", dpi=_DPI, metadata={"Software": None})
        return out.getvalue()


def entries(name, fmi_version):
    """The icon files of an FMU: {archive name: bytes}."""
    data = png(name)
    out = {"model.png": data}
    if fmi_version == 3:
        out["terminalsAndIcons/icon.png"] = data
    return out
