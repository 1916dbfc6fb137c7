"""Cost of one step of the Accelerometer FMU with the sensor's slow errors (issue 42) off and
on, against the Accelerometer of the code before them, in the same run.

Three Accelerometers, each alone in the C host tests/hosts/chain_host.c (no Python in the
process for the native FMU; the loader shim's Python for the Python FMU), stepping one sample
per step with its inputs held (x = 0.5 g; with the errors, theta = 0.1 rad and T = 300 K) and
its output z read at every step:

1. before: built from the commit before the slow errors (``--before``, default
   :data:`BEFORE`, exported with ``git archive`` and built in a child process);
2. off: this tree, every new parameter at its default (the letter's sensor);
3. on: this tree, every slow error on (turn-on bias, random walk, Gauss-Markov bias, a flicker
   bias over 0.1 .. 100 s (four components), exposure drift, tilt, temperature bias and scale,
   range, a 16-bit ADC over the range).

Goals: off costs no more than before (within the scatter of alternating runs: at most 1.05
times), on at most 2 times before.  Each figure is the median of ``--repeats`` runs, the three
alternating run by run, for the Python FMU and the native FMI 2.0 FMU.  Where valgrind is
installed, the instructions per step of both FMUs are counted too (callgrind, the difference
of two run lengths: the host's start, the FMU's loading and NumPy's import cancel): a count does
not depend on what else runs on the machine, as a wall time does.

The Python runs are long enough that what a run pays once does not hide the step: the FMU
imports NumPy after its first samples (about 0.07 s), which over 40,000 steps added about 1.7 µs
to every step of all three and brought the ratios towards 1; over 200,000 it adds about 0.3 µs.

``--each`` also counts what each term adds to the native step with every one on (that step
less the same step with the term off; callgrind, so valgrind is needed): a count, exact from run
to run, where the difference of two wall times of a few percent each would be the machine's
scatter.

Steps of several samples (``--held``, default 10 samples a step): the cost of a sample when the
master steps over ``--held`` samples at a time, the inputs held, before the slow errors, this
code with every slow error off and on, and with every one on the code of ``--held-before``
(default :data:`HELD_BEFORE`, where a held sample was computed in full in the native FMU and
advanced the error state through errors.advance in the Python FMU).  No goal is set on these:
before the slow errors a held sample without the output filter cost nothing (only the last
sample of a step was computed), and with a slow error on every sample's state must advance.

    python benchmarks/bench_errors.py [--steps 400000] [--python-steps 200000] [--repeats 5]
                                      [--each] [--held 10] [--held-before 1a4cf70]
"""
import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT / "tests" / "hosts"))

import chain  # noqa: E402

import figures  # noqa: E402

#: The commit the slow errors branched from: main before issue 42.
BEFORE = "9ff02a8"
#: The commit before the held samples of a step advanced only the error state and the filter.
HELD_BEFORE = "1a4cf70"
#: Every slow error on (models/errors.py), and the ADC over the range.
ALL_ON = dict(bias_on=0.05, random_walk=0.002, bias_gm=0.003, tau_gm=1.0, flicker=0.001,
              tau_min=0.1, tau_max=100.0, d_inf=0.04, E_tau=50.0, T0=298.15, kT_bias=0.002,
              kT_scale=-0.001, range=1.7, bits=16)
INPUTS_ON = dict(x=0.5, theta=0.1, T=300.0)
#: ``--each``: every term, as the start values that turn it off in the step with every one on.
TERMS = {
    "turn-on bias": dict(bias_on=0.0),
    "random walk": dict(random_walk=0.0),
    "Gauss-Markov bias": dict(bias_gm=0.0),
    "flicker bias (four components)": dict(flicker=0.0),
    "exposure drift": dict(d_inf=0.0),
    "tilt": dict(theta=0.0),
    "temperature bias and scale factor": dict(kT_bias=0.0, kT_scale=0.0),
    "range": dict(range=0.0),
    "16-bit ADC": dict(bits=0),
}
#: What the child process that builds the Accelerometer of a tree runs (PYTHONPATH: the tree).
BUILD = """
import sys
from driftfmu.fmu_src.builder import build_fmus
from driftfmu.fmu_src.native_build import build_native_fmus
out = sys.argv[1]
build_fmus(out, names=("Accelerometer",), log=lambda line: None)
build_native_fmus(out + "/native", names=("Accelerometer",), fmi_versions=(2,),
                  platforms=["x86_64-linux"], log=lambda line: None)
"""


def build(tree, out):
    """The Python and native FMI 2.0 Accelerometer FMUs of the source ``tree``:
    ``{"python": path, "native": path}``."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run([sys.executable, "-c", BUILD, str(out)], check=True, env=env, cwd=str(tree))
    return {"python": Path(out) / "Accelerometer.fmu",
            "native": Path(out) / "native" / "fmi2" / "Accelerometer.fmu"}


def export(ref, folder):
    """The tree of commit ``ref`` (``git archive``) in ``folder``."""
    folder.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return folder


def step_ns(host, fmu, start, steps, work, env=None, samples=1):
    """ns per step of the Accelerometer ``fmu`` alone in the C host, z read at every step, each
    step over ``samples`` samples (Ts = 1 ms)."""
    unpacked = {"Accelerometer": chain.unpack(fmu, work / "Accelerometer")}
    text, keys = chain.script(2, unpacked, {"Accelerometer": start}, (),
                              {"Accelerometer": ["z"]}, steps, 1e-3 * samples, quiet=True)
    _, ns, _ = chain.run(host, text, keys, work, env=env)
    return ns


def instructions(host, fmu, start, work, steps=(20000, 40000), env=None):
    """Instructions per step of the Accelerometer ``fmu`` alone in the C host (callgrind: the
    difference of the counts of two run lengths over the difference of the steps; ``env`` the
    host's environment, :func:`chain.python_fmu_env` for the Python FMU)."""
    counts = []
    for n in steps:
        folder = work / ("n%d" % n)
        folder.mkdir()
        unpacked = {"Accelerometer": chain.unpack(fmu, folder / "Accelerometer")}
        text, _ = chain.script(2, unpacked, {"Accelerometer": start}, (),
                               {"Accelerometer": ["z"]}, n, 1e-3, quiet=True)
        (folder / "script.txt").write_text(text)
        done = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                               str(host), "script.txt"], cwd=folder, capture_output=True,
                              text=True, env=env)
        counts.append(int(re.search(r"Collected : (\d+)", done.stderr).group(1)))
    return (counts[1] - counts[0]) / (steps[1] - steps[0])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=400000, help="steps of the native runs")
    ap.add_argument("--python-steps", type=int, default=200000,
                    help="steps of the runs with the Python FMU")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--before", default=BEFORE,
                    help="git commit of the Accelerometer before the slow errors (default: %s)"
                         % BEFORE)
    ap.add_argument("--each", action="store_true",
                    help="also count what each term adds to the native step with every one on "
                         "(valgrind)")
    ap.add_argument("--held", type=int, default=10,
                    help="samples a step in the figures of steps of several samples (0: none)")
    ap.add_argument("--held-before", default=HELD_BEFORE,
                    help="git commit of the Accelerometer whose held samples are compared "
                         "(default: %s)" % HELD_BEFORE)
    ap.add_argument("--no-record", action="store_true",
                    help="print the figures only (benchmarks/figures.json, docs/performance.md)")
    args = ap.parse_args(argv)
    load = figures.load()
    measured = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        fmus = {"before": build(export(args.before, tmp / "before"), tmp / "fmus_before"),
                "now": build(ROOT, tmp / "fmus_now")}
        if args.held > 1:
            fmus["held"] = build(export(args.held_before, tmp / "held"), tmp / "fmus_held")
        host = chain.compile_host(tmp / "chain_host")
        starts = {"before": dict(x=0.5), "off": dict(x=0.5), "on": dict(ALL_ON, **INPUTS_ON)}
        which = {"before": "before", "off": "now", "on": "now"}
        labels = ["before", "off", "on"]
        if args.each:
            for term, zeros in TERMS.items():
                starts[term] = dict(starts["on"], **zeros)
                which[term] = "now"
            labels += list(TERMS)
        for r in range(args.repeats):
            for backend in ("native", "python"):
                steps = args.steps if backend == "native" else args.python_steps
                env = chain.python_fmu_env() if backend == "python" else None
                for label in ("before", "off", "on"):
                    work = tmp / ("r%d_%s_%s" % (r, backend, label))
                    work.mkdir()
                    measured.setdefault((backend, label), []).append(step_ns(
                        host, fmus[which[label]][backend], starts[label], steps, work, env))
                    shutil.rmtree(work)
                if args.held > 1:  # (ns a sample; 10 times fewer steps of 10 samples)
                    for label, tree in (("before", "before"), ("off", "now"), ("on", "now"),
                                        ("held", "held")):
                        work = tmp / ("r%d_%s_held_%s" % (r, backend, label))
                        work.mkdir()
                        ns = step_ns(host, fmus[tree][backend],
                                     starts["on" if label == "held" else label],
                                     max(1, steps // args.held), work, env, args.held)
                        measured.setdefault((backend, "held " + label), []).append(
                            ns / args.held)
                        shutil.rmtree(work)
        counted, counted_python = {}, {}
        if shutil.which("valgrind"):
            for i, label in enumerate(labels):
                work = tmp / ("ir_%d" % i)
                work.mkdir()
                counted[label] = instructions(host, fmus[which[label]]["native"],
                                              starts[label], work)
            for label in ("before", "off", "on"):  # (the Python FMU: 10,000 vs 30,000 steps,
                work = tmp / ("ir_python_%s" % label)  # each past NumPy's import)
                work.mkdir()
                counted_python[label] = instructions(
                    host, fmus[which[label]]["python"], starts[label], work, (10000, 30000),
                    chain.python_fmu_env())
    median = {key: statistics.median(v) for key, v in measured.items()}
    print("machine: %s; load average %s"
          % (figures.machine(), " ".join("%.1f" % x for x in os.getloadavg())))
    print("one Accelerometer step in the C host, median of %d runs (%d native, %d Python "
          "steps); before = %s" % (args.repeats, args.steps, args.python_steps, args.before))
    rows = []
    met_all = True
    for backend, title in (("native", "native FMI 2.0"), ("python", "Python")):
        b, off, on = (median[(backend, k)] for k in ("before", "off", "on"))
        print("  %-15s before %8.1f ns, off %8.1f ns (%.3f), on %8.1f ns (%.3f); runs: %s"
              % (title, b, off, off / b, on, on / b, " | ".join(
                  "%s %s" % (k, " ".join("%.0f" % x for x in measured[(backend, k)]))
                  for k in ("before", "off", "on"))))
        against = "the %s Accelerometer before the slow errors (%s)" % (title, args.before)
        met_off, met_on = off / b <= 1.05, on / b <= 2.0
        met_all = met_all and met_off and met_on
        rows += [
            figures.row("one step of the %s Accelerometer before the slow errors" % title,
                        b / 1e3, "µs"),
            figures.row("the same, this code, every slow error off", off / 1e3, "µs", against,
                        off / b, "<= 1.05 (no more than before)", met_off),
            figures.row("the same, every slow error on", on / 1e3, "µs", against, on / b,
                        "<= 2", met_on),
        ]
    if args.held > 1:
        print("one sample of steps of %d samples (inputs held), median of %d runs:"
              % (args.held, args.repeats))
        for backend, title in (("native", "native FMI 2.0"), ("python", "Python")):
            b, off, on, old = (median[(backend, "held " + k)]
                               for k in ("before", "off", "on", "held"))
            print("  %-15s before %8.1f ns, off %8.1f ns, on %8.1f ns (%.2f x before); on at "
                  "%s %8.1f ns (this code %.3f of it)" % (title, b, off, on, on / b,
                                                         args.held_before, old, on / old))
            where = "in steps of %d samples" % args.held
            against = "the %s Accelerometer before the slow errors (%s), %s" % (
                title, args.before, where)
            rows += [
                figures.row("one sample of the %s Accelerometer before the slow errors, %s"
                            % (title, where), b / 1e3, "µs"),
                figures.row("the same, this code, every slow error off", off / 1e3, "µs",
                            against, off / b),
                figures.row("the same, every slow error on", on / 1e3, "µs", against, on / b),
                figures.row("the same, every slow error on, the code of %s (held samples "
                            "computed in full)" % args.held_before, old / 1e3, "µs"),
                figures.row("this code against %s, every slow error on, %s"
                            % (args.held_before, where), on / 1e3, "µs",
                            "the %s Accelerometer of %s, %s" % (title, args.held_before, where),
                            on / old),
            ]
    for count, title in ((counted, "native FMI 2.0"), (counted_python, "Python")):
        if not count:
            continue
        b, off, on = (count[k] for k in ("before", "off", "on"))
        print("  %s instructions per step (callgrind): before %.0f, off %.0f (%.3f), "
              "on %.0f (%.3f)" % (title, b, off, off / b, on, on / b))
        against = "the %s Accelerometer before the slow errors (%s)" % (title, args.before)
        rows += [
            figures.row("instructions of one step of the %s Accelerometer before the slow "
                        "errors (callgrind)" % title, b, "instructions"),
            figures.row("the same, this code, every slow error off", off, "instructions",
                        against, off / b, "<= 1.05 (no more than before)", off / b <= 1.05),
            figures.row("the same, every slow error on", on, "instructions", against, on / b,
                        "<= 2", on / b <= 2.0),
        ]
    if args.each and counted:
        print("what each term adds to the native step with every one on (that step less the "
              "step with the term off), callgrind:")
        for term in TERMS:
            ir = counted["on"] - counted[term]
            print("  %-34s %5.0f instructions (%.2f of the step before)"
                  % (term, ir, ir / counted["before"]))
            rows.append(figures.row("what the %s adds to the native step with every slow error "
                                    "on (callgrind; %.0f %% of the step before them)"
                                    % (term, 100.0 * ir / counted["before"]), ir,
                                    "instructions"))
    elif args.each:
        print("--each: valgrind is not installed, no count of each term")
    print("goals (off <= 1.05 x before, on <= 2 x before): %s" % ("met" if met_all
                                                                 else "NOT met"))
    figures.record(__file__, argv, rows, load,
                   "Median of %d alternating runs; %d steps of the native FMU, %d of the Python "
                   "FMU; one sample per step, z read at every step." % (
                       args.repeats, args.steps, args.python_steps))


if __name__ == "__main__":
    main()
