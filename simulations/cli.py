"""The ``driftfmu`` command.

One convention for every sub-command: model parameters by their paper names (``--a2 0.01``,
``--R 1e-4``), ``--n`` samples, ``--runs`` Monte-Carlo runs, ``--seed``, ``--out DIR`` (created if
missing; results written whole or not at all).

Exit statuses, the same for every sub-command (:mod:`driftfmu.simulations.errors`): 0 done; 2 a usage
error (an option argparse refuses, or a setting the run cannot start with, such as a frequency
above the Nyquist rate), one line on standard error; 1 a failed run (the data cannot support the
result, an FMU or a file operation failed), one line; 130 interrupted (Ctrl-C or SIGTERM), one
line, worker processes stopped and temporary files removed.
"""
import argparse
import contextlib
import math
import os
import signal
import sys
import warnings
from pathlib import Path

from driftfmu.models import parameters
from driftfmu.simulations.errors import (DataError, EXIT_FAILED, EXIT_INTERRUPTED,  # noqa: F401
                                         EXIT_USAGE, UsageError)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one readable line."""

    def error(self, message):
        self.exit(EXIT_USAGE, "%s: error: %s\n" % (self.prog.split()[0], message))


def param_type(name):
    """argparse type that parses a number and checks it against the parameter's range."""
    integer = isinstance(parameters.PARAMETERS[name].default, int)

    def parse(text):
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                "%s = %r is not %s; allowed: %s" % (name, text, "an integer" if integer
                                                    else "a number", parameters.allowed(name)))
        msg = parameters.problem(name, value)
        if msg:
            raise argparse.ArgumentTypeError(msg)
        return value
    parse.__name__ = name
    return parse


#: What the command line accepts for a drive frequency (the FMU parameter allows f = 0, a
#: constant; a run needs a drive below the Nyquist rate).
FREQUENCY_ALLOWED = "0 < f < 1/(2 Ts), the Nyquist rate"


def frequency_type(text):
    """argparse type of a drive frequency: a finite number > 0 (the upper bound, the Nyquist
    rate, depends on ``--Ts`` and is checked by the run before it starts)."""
    try:
        value = float(text)
    except ValueError:
        value = None
    if value is None or not math.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError("f = %r is not allowed; allowed: %s"
                                         % (text, FREQUENCY_ALLOWED))
    return value


def add_params(parser, names, **defaults):
    """Add ``--<name>`` options for model parameters, with help from models.parameters."""
    for name in names:
        p = parameters.PARAMETERS[name]
        default = defaults.get(name, p.default)
        unit = "" if p.unit == "1" else " [%s]" % p.unit
        allowed = FREQUENCY_ALLOWED if name == "f" else parameters.allowed(name)
        parser.add_argument("--%s" % name, type=frequency_type if name == "f" else
                            param_type(name), default=default,
                            metavar=name.upper() if len(name) > 1 else name,
                            help="%s%s; allowed: %s (default: %s)"
                                 % (p.description, unit, allowed, default))


@contextlib.contextmanager
def progress(total, desc, unit, monitor=True):
    """A tqdm progress bar over ``total`` units (``unit``: ``"sample"``, ``"set"``, ``"run"``) as
    ``update(done)``; None when stderr is not a terminal.  ``monitor=False`` keeps tqdm from
    starting its monitor thread, so that the process stays single-threaded and worker processes
    can be forked."""
    if not sys.stderr.isatty():
        yield None
        return
    import tqdm
    if not monitor:
        tqdm.tqdm.monitor_interval = 0
    bar = tqdm.tqdm(total=total, desc=desc, unit=" " + unit, leave=False)
    try:
        yield lambda done: bar.update(done - bar.n)
    finally:
        bar.close()


def cmd_build(args):
    from driftfmu.fmu_src.builder import build_fmus
    from driftfmu.simulations.output import removing_new_folders
    with removing_new_folders(args.out):  # no empty folder left by a failed or stopped build
        paths = build_fmus(args.out)  # logs one line per FMU
    fmus = {p.stem: p for p in map(Path, paths)}
    native = None
    if args.native or args.backend == "native":
        from driftfmu.fmu_src.native_build import build_native_fmus
        native = build_native_fmus(Path(args.out) / "native")  # one line per FMU
    if args.cross_check:
        from driftfmu.fmu_src.crosscheck import write_cross_check
        with removing_new_folders(args.cross_check):
            sets = ([(2, fmus, "python")] if native is None
                    else [(v, native[v], "native") for v in sorted(native)])
            for fmi_version, chosen, backend in sets:
                for d in write_cross_check(chosen, args.cross_check, fmi_version=fmi_version,
                                           backend=backend):
                    print("%s/ (cross-check: fmu, _in.csv, _ref.csv, _ref.opt, ReadMe.txt)"
                          % d)
    if args.ssp:
        from driftfmu.fmu_src.ssp import build_ssp
        chosen = fmus if args.backend == "python" else native[2]
        with removing_new_folders(Path(args.ssp).parent):
            print("%s (SSP: the wired chain of the %s FMUs, start values of the letter's "
                  "Gaussian run)" % (build_ssp(chosen, args.ssp), args.backend))


def check_build_args(args):
    """Usage errors of ``driftfmu build`` found before anything is built."""
    if args.ssp:
        ssp = Path(args.ssp)
        if ssp.is_dir():
            raise UsageError("--ssp %s is a folder; allowed: the path of the .ssp file to write"
                             % ssp)
        if ssp.exists() and not args.force:
            raise UsageError("--ssp %s exists; add --force to replace it" % ssp)


def cmd_run_gaussian(args):
    from driftfmu.simulations.gaussian import run_gaussian
    with progress(args.n, "co-simulation", "sample") as update:
        res = run_gaussian(out=args.out, a0=args.a0, a1=args.a1, a2=args.a2, A=args.A,
                           Q=args.Q, R=args.R, n=args.n, seed=args.seed, Ts=args.Ts,
                           P0=args.P0, estimator=args.estimator, fmu_dir=args.fmu_dir,
                           progress=update, backend=args.backend)
    s = res["summary"]
    f = s["final"]
    print("wrote %s/results.csv, summary.json, drift.png" % args.out)
    print("final drift: EKF1 %.4g, EKF2 %.4g, EKF3 %.4g | realised %.4g, empirical %.4g, "
          "expected %.4g" % (f["dc_ekf1"], f["dc_ekf2"], f["dc_ekf3"], f["dc_realised"],
                             f["dc_empirical"], f["dc_expected"]))
    line = "EKF1-EKF2 gap %.4f dB" % s["ekf1_ekf2_gap_db"]
    if "ekf1_ekf2_gap_db_expected" in s:
        line += " (expected 10 log10(1 + R/(a1^2 Q)) = %.4f dB)" % s["ekf1_ekf2_gap_db_expected"]
    print(line)
    st = s["settled_from_sample"]
    print("within 10 %% of the realised drift from sample: EKF1 %s, EKF2 %s, EKF3 %s"
          % tuple(settled_text(st[e]) for e in ("ekf1", "ekf2", "ekf3")))
    print("validation: FMU outputs equal models/ (max |diff| %.3g, tolerance %g)"
          % (max(s["validation"]["max_abs_diff"].values()), s["validation"]["tolerance"]))


def settled_text(k, n=None):
    """A settling sample for people: ``"never"`` (None, or after the last sample ``n``)."""
    if k is None or (n is not None and k > n):
        return "never (not within the band at the last sample)"
    return "%d" % k


#: Modules that add their own sub-commands: each has ``add_cli(groups)`` taking the dict
#: ``{"top": <sub-parsers of driftfmu>, "run": <sub-parsers of driftfmu run>}``; the module that
#: adds ``driftfmu experiment`` puts its sub-parsers there as ``"experiment"`` for the later ones.
PLUGINS = ("driftfmu.simulations.doctor", "driftfmu.simulations.sweep", "driftfmu.simulations.montecarlo",
           "driftfmu.simulations.sinusoidal", "driftfmu.simulations.adxl203",
           "driftfmu.simulations.dual_axis")


def make_parser():
    parser = _Parser(prog="driftfmu", description=(
        "FMI 2.0 co-simulation FMUs of a weakly nonlinear accelerometer and an EKF drift "
        "compensator (Chorti et al., Sensor Letters 2006), and fmpy masters around them."))
    from driftfmu import __version__
    parser.add_argument("--version", action="version", version="driftfmu %s" % __version__)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    p = sub.add_parser("build", help="build Excitation.fmu, Accelerometer.fmu, "
                       "DriftEstimator.fmu and DualDriftEstimator.fmu (validated with fmpy)")
    p.add_argument("--out", default="build/fmus", metavar="DIR",
                   help="output folder for the FMUs (default: build/fmus)")
    p.add_argument("--cross-check", nargs="?", const="build/cross-check", default=None,
                   metavar="DIR", help="also write FMI cross-check folders (FMU, input, "
                   "reference result, options, ReadMe) under DIR/fmus/2.0/cs/linux64/driftfmu/ "
                   "(DIR default: build/cross-check)")
    p.add_argument("--ssp", nargs="?", const="build/DriftChain.ssp", default=None,
                   metavar="FILE", help="also write the wired chain as an SSP archive "
                   "(default: build/DriftChain.ssp); an existing FILE is kept unless --force")
    p.add_argument("--force", action="store_true",
                   help="replace an existing --ssp FILE")
    p.add_argument("--native", action="store_true",
                   help="also build the native (C) twins of the FMUs, FMI 2.0 and FMI 3.0 source "
                   "FMUs with binaries for Linux, Windows and macOS on x86-64 and aarch64 (those "
                   "with a compiler here: gcc, mingw-w64, zig), as DIR/native/fmi2/<Name>.fmu, "
                   "DIR/native/fmi2-aarch64/<Name>.fmu (FMI 2.0 for ARM Linux and Windows) and "
                   "DIR/native/fmi3/<Name>.fmu (validated with fmpy); see docs/platforms.md")
    add_backend(p, what="the FMUs of the cross-check artifacts and the SSP export: python, or "
                "native (implies --native; the cross-check then has folders for FMI 2.0 and "
                "3.0 and for each platform)")
    p.set_defaults(func=cmd_build)

    run = sub.add_parser("run", help="co-simulate the FMUs with an fmpy master")
    runs = run.add_subparsers(dest="experiment", metavar="EXPERIMENT", parser_class=_Parser)
    runs.required = True
    g = runs.add_parser("gaussian", help="Gaussian excitation, the letter's Sec. III / Fig. 1")
    add_params(g, ("a0", "a1", "a2", "A", "Q", "R", "n", "seed", "Ts"))
    g.add_argument("--P0", type=param_type("P0"), default=None, metavar="P0",
                   help="initial error variance of the filter [g2] (default: Q / (1 - A^2))")
    g.add_argument("--estimator", type=int, choices=(1, 2, 3), default=1,
                   help="estimator whose drift is subtracted in z_comp (default: 1, EKF1)")
    add_out(g, "results/gaussian")
    add_fmu_dir(g)
    add_backend(g)
    g.set_defaults(func=cmd_run_gaussian)

    import importlib
    groups = {"top": sub, "run": runs}
    for name in PLUGINS:
        importlib.import_module(name).add_cli(groups)
    return parser


def add_out(parser, default):
    """The common ``--out DIR`` option."""
    parser.add_argument("--out", default=default, metavar="DIR",
                        help="output folder, created if missing; results are written whole "
                             "or not at all (default: %s)" % default)


def add_fmu_dir(parser):
    """The common ``--fmu-dir DIR`` option."""
    parser.add_argument("--fmu-dir", default="build/fmus", metavar="DIR",
                        help="folder of the FMUs, built there if missing (default: build/fmus)")


def add_backend(parser, what=None):
    """The common ``--backend python|native`` option."""
    parser.add_argument("--backend", choices=("python", "native"), default="python",
                        help=(what or "the FMUs to run: python, the pythonfmu FMUs in FMU_DIR "
                              "(need a libpython), or native, their C twins in "
                              "FMU_DIR/native/fmi2 (need nothing; same bits); built there if "
                              "missing") + " (default: python)")


def check_out(args):
    """Usage error when ``--out`` names something that is not a folder."""
    out = getattr(args, "out", None)
    if out is not None and os.path.exists(out) and not os.path.isdir(out):
        raise UsageError("--out %s is an existing file; allowed: a folder (created if missing)"
                         % out)


#: Set by the first SIGINT/SIGTERM: whatever exception the interrupted code then raises (an
#: import stopped half-way raises ImportError, not KeyboardInterrupt), the run was interrupted.
_interrupted = []


def _interrupt(signum, frame):
    """SIGINT (and SIGTERM): stop the command (KeyboardInterrupt) once; further signals must not
    break the clean-up that the first one started."""
    _interrupted.append(signum)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise KeyboardInterrupt


def _hold(signum, frame):
    """SIGINT/SIGTERM while the sub-commands' modules are imported: noted, acted on right after
    (an exception raised inside an extension module's import is not reliably re-raised)."""
    _interrupted.append(signum)


def _main_interrupted():
    sys.stderr.write("driftfmu: interrupted; worker processes stopped, no partial result files "
                     "left\n")
    return EXIT_INTERRUPTED


def first_line(exc):
    """One readable line for an exception (``OSError``: the file and the reason)."""
    if isinstance(exc, OSError) and exc.strerror:
        name = exc.filename if exc.filename is not None else ""
        return "%s%s%s" % (name, ": " if name else "", exc.strerror)
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def main(argv=None):
    """The ``driftfmu`` command; returns the exit status (0, 1, 2 or 130, see the module)."""
    del _interrupted[:]
    previous = {}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, _hold)  # first thing
    if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:  # kill, timeout: clean up the same way
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, _hold)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("always", UserWarning)  # every doubt, each on its own line
            warnings.showwarning = _show_warning
            return _main(argv, previous)
    except KeyboardInterrupt:  # in the instant before _main's own handling
        sys.stderr.write("driftfmu: interrupted\n")
        return EXIT_INTERRUPTED


def _show_warning(message, category, filename, lineno, file=None, line=None):
    sys.stderr.write("driftfmu: warning: %s\n" % first_line(message))


def _main(argv, previous):
    try:
        parser = make_parser()  # imports NumPy, matplotlib's helpers, the plugins
        for signum in previous:
            signal.signal(signum, _interrupt)
        if _interrupted:
            raise KeyboardInterrupt
        args = parser.parse_args(argv)
        try:
            check_out(args)
            if args.func is cmd_build:
                check_build_args(args)
        except UsageError as exc:
            parser.error(first_line(exc))
        args.func(args)
    except KeyboardInterrupt:
        return _main_interrupted()
    except Exception as exc:  # one readable line, not a traceback
        if _interrupted:  # whatever the interrupted code raised on its way out
            return _main_interrupted()
        sys.stderr.write("driftfmu: error: %s\n" % first_line(exc))
        return EXIT_USAGE if isinstance(exc, UsageError) else EXIT_FAILED
    finally:
        for signum, handler in previous.items():
            # called with arguments (a test, a script): give the caller its handler back; as
            # the program: a Ctrl-C while the interpreter shuts down has nothing left to stop
            signal.signal(signum, handler if argv is not None else signal.SIG_IGN)
    return 0


if __name__ == "__main__":
    sys.exit(main())
