"""Writing results whole or not at all, and the plots.

Files are written into a staging folder beside the destination and moved into place only when
every file of the set has been written; on any error or Ctrl-C the destination is left as it
was, and folders created for it are removed again when they are still empty.
"""
import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path

from driftfmu.simulations.errors import UsageError


@contextlib.contextmanager
def removing_new_folders(path):
    """Run the block; when it fails (or is interrupted), remove the folders of ``path`` and its
    parents that did not exist before and are empty after."""
    path = Path(path)
    new = []
    p = path
    while not p.exists() and p != p.parent:
        new.append(p)
        p = p.parent
    try:
        yield
    except BaseException:
        for d in new:  # deepest first
            with contextlib.suppress(OSError):
                d.rmdir()  # only when empty
        raise


@contextlib.contextmanager
def staged(out_dir):
    """Yield a staging folder; on success move its files into ``out_dir`` (created if missing).

    ``out_dir`` naming an existing file is a ValueError (one line, nothing written)."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise UsageError("%s is an existing file; allowed: a folder (created if missing)" % out)
    with removing_new_folders(out):
        out.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=".staging-", dir=out))
        try:
            yield stage
            for f in sorted(stage.iterdir()):
                os.replace(f, out / f.name)
        finally:
            shutil.rmtree(stage, ignore_errors=True)


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


def plot_drift(path, cols, title):
    """The letter's Fig. 1, done right: EKF1-3 against the realised and expected drift (top) and
    against the empirical drift ``z̄ - a0``, whose linear term ``a1 x̄`` dwarfs the drift for a
    Gaussian state (bottom)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    k = np.arange(1, len(cols["dc_ekf1"]) + 1)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 7), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 2]})
    for ax in (top, bottom):
        ax.plot(k, cols["dc_ekf1"], color="C0", lw=1.2, label="EKF1")
        ax.plot(k, cols["dc_ekf2"], color="C1", lw=1.0, ls="--", label="EKF2")
        ax.plot(k, cols["dc_ekf3"], color="C2", lw=1.2, label="EKF3")
        ax.grid(True, alpha=0.3)
        ax.set_ylabel("drift [V]")
    top.plot(k, cols["dc_realised"], color="k", lw=1.4, label="realised  a2 mean(x²)")
    top.plot(k, cols["dc_expected"], color="k", lw=1.0, ls=":", label="expected  a2 var(x)")
    bottom.plot(k, cols["dc_empirical"], color="0.5", lw=0.8, label="empirical  z̄ - a0")
    ref = float(np.asarray(cols["dc_expected"])[-1])
    if ref > 0:
        top.set_ylim(0.0, 2.5 * ref)
    top.set_xlim(1, k[-1])
    top.set_title(title)
    top.legend(loc="upper right", fontsize=8, ncol=2)
    bottom.legend(loc="upper right", fontsize=8, ncol=2)
    bottom.set_xlabel("sample k")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
