"""The ``driftfmu`` command.

One convention for every sub-command: model parameters by their paper names (``--a2 0.01``,
``--R 1e-4``), ``--n`` samples, ``--runs`` Monte-Carlo runs, ``--seed``, ``--out DIR`` (created if
missing; results written whole or not at all).  A bad option is answered with one line on
standard error and exit status 2; a failed run with one line and exit status 1.
"""
import argparse
import contextlib
import sys
from pathlib import Path

from driftfmu.models import parameters

EXIT_FAILED = 1
EXIT_USAGE = 2


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


def add_params(parser, names, **defaults):
    """Add ``--<name>`` options for model parameters, with help from models.parameters."""
    for name in names:
        p = parameters.PARAMETERS[name]
        default = defaults.get(name, p.default)
        parser.add_argument("--%s" % name, type=param_type(name), default=default,
                            metavar=name.upper() if len(name) > 1 else name,
                            help="%s [%s]; allowed: %s (default: %s)"
                                 % (p.description, p.unit, parameters.allowed(name), default))


@contextlib.contextmanager
def progress(total, desc, monitor=True):
    """A tqdm progress bar over ``total`` units as ``update(done)``; None when stderr is not a
    terminal.  ``monitor=False`` keeps tqdm from starting its monitor thread, so that the process
    stays single-threaded and worker processes can be forked."""
    if not sys.stderr.isatty():
        yield None
        return
    import tqdm
    if not monitor:
        tqdm.tqdm.monitor_interval = 0
    bar = tqdm.tqdm(total=total, desc=desc, unit="step", leave=False)
    try:
        yield lambda done: bar.update(done - bar.n)
    finally:
        bar.close()


def cmd_build(args):
    from driftfmu.fmu_src.builder import build_fmus
    paths = build_fmus(args.out)  # logs one line per FMU
    fmus = {p.stem: p for p in map(Path, paths)}
    native = None
    if args.native or args.backend == "native":
        from driftfmu.fmu_src.native_build import build_native_fmus
        native = build_native_fmus(Path(args.out) / "native")  # one line per FMU
    if args.cross_check:
        from driftfmu.fmu_src.crosscheck import write_cross_check
        sets = ([(2, fmus, "python")] if native is None
                else [(v, native[v], "native") for v in sorted(native)])
        for fmi_version, chosen, backend in sets:
            for d in write_cross_check(chosen, args.cross_check, fmi_version=fmi_version,
                                       backend=backend):
                print("%s/ (cross-check: fmu, _in.csv, _ref.csv, _ref.opt, ReadMe.txt)" % d)
    if args.ssp:
        from driftfmu.fmu_src.ssp import build_ssp
        chosen = fmus if args.backend == "python" else native[2]
        print("%s (SSP: the wired chain of the %s FMUs, start values of the letter's Gaussian "
              "run)" % (build_ssp(chosen, args.ssp), args.backend))


def cmd_run_gaussian(args):
    from driftfmu.simulations.gaussian import run_gaussian
    with progress(args.n, "co-simulation") as update:
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
          % (st["ekf1"], st["ekf2"], st["ekf3"]))
    print("validation: FMU outputs equal models/ (max |diff| %.3g, tolerance %g)"
          % (max(s["validation"]["max_abs_diff"].values()), s["validation"]["tolerance"]))


#: Modules that add their own sub-commands: each has ``add_cli(groups)`` taking the dict
#: ``{"top": <sub-parsers of driftfmu>, "run": <sub-parsers of driftfmu run>}``.
PLUGINS = ("driftfmu.simulations.doctor", "driftfmu.simulations.sweep", "driftfmu.simulations.montecarlo",
           "driftfmu.simulations.sinusoidal", "driftfmu.simulations.adxl203")


def make_parser():
    parser = _Parser(prog="driftfmu", description=(
        "FMI 2.0 co-simulation FMUs of a weakly nonlinear accelerometer and an EKF drift "
        "compensator (Chorti et al., Sensor Letters 2006), and fmpy masters around them."))
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    p = sub.add_parser("build", help="build Excitation.fmu, Accelerometer.fmu and "
                       "DriftEstimator.fmu (validated with fmpy)")
    p.add_argument("--out", default="build/fmus", metavar="DIR",
                   help="output folder for the FMUs (default: build/fmus)")
    p.add_argument("--cross-check", nargs="?", const="build/cross-check", default=None,
                   metavar="DIR", help="also write FMI cross-check folders (FMU, input, "
                   "reference result, options, ReadMe) under DIR/fmus/2.0/cs/linux64/driftfmu/ "
                   "(DIR default: build/cross-check)")
    p.add_argument("--ssp", nargs="?", const="build/DriftChain.ssp", default=None,
                   metavar="FILE", help="also write the wired chain as an SSP archive "
                   "(default: build/DriftChain.ssp)")
    p.add_argument("--native", action="store_true",
                   help="also build the native (C) twins of the FMUs, FMI 2.0 and FMI 3.0 source "
                   "FMUs with x86-64 Linux and Windows binaries, as DIR/native/fmi2/<Name>.fmu "
                   "and DIR/native/fmi3/<Name>.fmu (validated with fmpy)")
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
    for name in PLUGINS:
        importlib.import_module(name).add_cli({"top": sub, "run": runs})
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


def main(argv=None):
    parser = make_parser()
    args = parser.parse_args(argv)
    try:
        args.func(args)
    except KeyboardInterrupt:
        sys.stderr.write("driftfmu: interrupted; nothing was written\n")
        return EXIT_FAILED
    except Exception as exc:  # one readable line, not a traceback
        sys.stderr.write("driftfmu: error: %s\n" % str(exc).strip().splitlines()[0])
        return EXIT_FAILED
    return 0


if __name__ == "__main__":
    sys.exit(main())
