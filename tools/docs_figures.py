"""Make the figures of docs/results.md (and the README's) with the commands the page names.

Each figure is written by its command into a temporary folder and copied into docs/; the runs
are deterministic, so the same sources give the same figures.  From the project root, after
``driftfmu build --native`` (or it builds what it needs):

    python tools/docs_figures.py                 # every figure (about 4 minutes on 2 cores)
    python tools/docs_figures.py fig4.png        # only these (and what their command writes)
    python tools/docs_figures.py --list          # the commands, one a line

``--fmu-dir DIR`` takes the FMUs from DIR (default build/fmus).
"""
import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"

#: (the command as the page names it, the figures it writes).  The ADXL203 experiment runs on
#: the native FMUs, which give the Python FMUs' results to the last bit, in seconds.
FIGURES = [
    ("driftfmu run gaussian", ("drift.png",)),
    ("driftfmu montecarlo gaussian", ("fig1.png",)),
    ("driftfmu montecarlo sinusoidal", ("sine.png",)),
    ("driftfmu sweep", ("fig2.png", "fig3.png")),
    ("driftfmu experiment adxl203 --backend native", ("fig4.png", "fig5.png")),
    ("driftfmu experiment dual-axis --engine batch", ("dual_axis.png",)),
    ("driftfmu experiment drift-classes", ("drift_classes.png",)),
]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("only", nargs="*", help="figures to make (file names), default all")
    ap.add_argument("--fmu-dir", default="build/fmus")
    ap.add_argument("--list", action="store_true", help="print the commands and stop")
    args = ap.parse_args(argv)
    known = {name for _, names in FIGURES for name in names}
    unknown = set(args.only) - known
    if unknown:
        ap.error("unknown figure(s) %s; allowed: %s" % (", ".join(sorted(unknown)),
                                                          ", ".join(sorted(known))))
    for command, names in FIGURES:
        if args.only and not set(names) & set(args.only):
            continue
        if args.list:
            print("%s  ->  %s" % (command, ", ".join("docs/%s" % n for n in names)))
            continue
        with tempfile.TemporaryDirectory(prefix="docs_figures_") as tmp:
            argv = command.split()[1:] + ["--out", str(Path(tmp) / "out"),
                                          "--fmu-dir", str(Path(args.fmu_dir).absolute())]
            print("%s ..." % command, flush=True)
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "driftfmu"] + argv, check=True,
                           stdout=subprocess.DEVNULL)
            for name in names:
                shutil.copyfile(Path(tmp) / "out" / name, DOCS / name)
            print("  docs/%s (%.0f s)" % (", docs/".join(names), time.perf_counter() - t0),
                  flush=True)


if __name__ == "__main__":
    main()
