"""Internal (not a stable API; use the driftfmu command or the functions of driftfmu instead).

The ``driftfmu`` command.

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
import os
import re
import signal
import sys
import time
import warnings
from pathlib import Path

from driftfmu.models import chain, parameters
from driftfmu.simulations import checks
from driftfmu.simulations.errors import (DataError, EXIT_FAILED, EXIT_INTERRUPTED,  # noqa: F401
                                         EXIT_USAGE, UsageError)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one readable line, and that takes every negative number
    as a value (``--a0 -1e-3``, ``--a0 -inf``), not as an option: argparse's own test knows only
    ``-1`` and ``-0.5``."""

    #: A negative number as Python's ``float`` reads it (no option of driftfmu looks like one).
    NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$",
                                 re.IGNORECASE)

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = self.NEGATIVE_NUMBER

    #: The parser (this one or a sub-command's) that parsed last: the one whose options an
    #: unrecognised option was meant for.
    _last = None

    def parse_known_args(self, args=None, namespace=None):
        _Parser._last = self  # a sub-command's parser is entered after its parents
        return super().parse_known_args(args, namespace)

    def error(self, message):
        choices = self.command_choices()
        if choices and message.startswith("the following arguments are required"):
            # a bare ``driftfmu`` or ``driftfmu run``: the usage and the list of commands
            self.print_help(sys.stderr)
            message = "%s needs one of: %s" % (self.prog, ", ".join(choices))
        self.exit(EXIT_USAGE, "%s: error: %s\n" % (self.prog.split()[0], _close(message)))

    def command_choices(self):
        """The names of this parser's sub-commands (empty when it has none)."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return list(action.choices)
        return []


def _close(message):
    """argparse's ``message`` with the name meant, as the API's keywords have it: ``invalid
    choice: 'gausian' (choose from ...)`` and ``unrecognized arguments: --a22 1`` get "(did
    you mean ...?)" where a choice or an option of the command is close."""
    import difflib
    m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)$", message)
    if m:
        offered = [c.strip().strip("'\"") for c in m.group(2).split(",")]
        close = difflib.get_close_matches(m.group(1), offered, n=1)
        return message + (" (did you mean %r?)" % close[0] if close else "")
    m = re.match(r"unrecognized arguments: (.*)$", message)
    if m and _Parser._last is not None:
        options = [o for a in _Parser._last._actions for o in a.option_strings]
        # compared without their dashes, which every option shares: with them '--engine' came
        # close to '--range' (0.67 for the names' 0.55)
        bare = {o.lstrip("-"): o for o in options}
        meant = []
        for word in m.group(1).split():
            name = word.split("=", 1)[0]
            close = difflib.get_close_matches(name.lstrip("-"), list(bare), n=1) \
                if name.startswith("-") and name.lstrip("-") else []
            if close:
                meant.append("%s for %s" % (bare[close[0]], name))
        if meant:
            return message + " (did you mean %s?)" % ", ".join(meant)
    return message


def param_type(name):
    """argparse type that parses a number and checks it against the parameter's range (the
    check of the API's keyword of the same name, :func:`checks.number_problem`)."""
    integer = isinstance(parameters.PARAMETERS[name].default, int)

    def parse(text):
        if integer:
            try:
                return int(text)
            except ValueError:
                pass  # 2.5 or 2.0: a number, not an integer (as the API's n=2.0 is not)
        return float(text)
    return checks.option(name, lambda v: checks.number_problem(name, v), parse)


#: What the command line accepts for a drive frequency (the FMU parameter allows f = 0, a
#: constant; a run needs a drive below the Nyquist rate).
FREQUENCY_ALLOWED = checks.FREQUENCY_ALLOWED

#: argparse type of a drive frequency: a finite number > 0 (the upper bound, the Nyquist rate,
#: depends on ``--Ts`` and is checked by the run before it starts).
frequency_type = checks.option("f", checks.frequency_problem, float)


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


#: Seconds between the plain progress lines written when standard error is not a terminal
#: (a CI log, a file); the environment variable ``DRIFTFMU_PROGRESS_EVERY`` overrides it.
PROGRESS_EVERY = 30.0
#: Seconds into a phase from which a long one writes its first line (not waiting for the
#: first interval): the first seconds of the run say that it runs and how long it will take.
FIRST_LINE = 3.0


class Progress:
    """What a run calls as it goes: ``update(done)`` with the units done so far in the
    current phase, ``update.phase(desc, total, unit)`` when a new phase starts (for example
    the validation after the runs), so that no long phase sits at 100 %, and
    ``update.work(at_once)`` (:func:`start_work`) when the phase's work starts after its
    set-up (FMUs built, workers started), ``at_once`` units at a time.

    On a terminal a tqdm bar; otherwise plain lines on standard error
    (``driftfmu: progress: <phase> 45 % (450/1000 runs), 12 s, about 15 s left at this pace``):
    the first at the first update from :data:`FIRST_LINE` seconds into a phase that looks long
    (more than ``every`` seconds to go at its pace), so that a long run shows within seconds
    that it runs and how long it will take, then one every ``every`` seconds; a short phase
    stays silent.  The time left (:meth:`left`) is an estimate from the work done so far: the
    pace since the work started, so what came before it (building the FMUs, starting
    workers) does not count as that work, and while fewer units are done than run at once,
    the first ones done count for all that run beside them.  Every line with work done and
    work left says it.
    """

    def __init__(self, total, desc, unit, bar=None, every=PROGRESS_EVERY, stream=None,
                 clock=time.monotonic):
        self.total, self.desc, self.unit, self.bar = total, desc, unit, bar
        self.every, self.stream, self.clock = every, stream or sys.stderr, clock
        self.done = 0
        self.started = self.phase_started = self.last = clock()
        self.work_started = self.phase_started  # the pace counts from here
        self.at_once = 1
        self.spoke = False  # a line of this phase written

    def __call__(self, done):
        self.done = done
        if self.bar is not None:
            self.bar.update(done - self.bar.n)
            return
        now = self.clock()
        if now - self.last >= self.every or self._early(now):
            self.last = now
            self.spoke = True
            self.write(now)

    def _early(self, now):
        """The phase's first line, before its first interval: from ``FIRST_LINE`` seconds on,
        when the rest of the phase looks longer than an interval."""
        if self.spoke or now - self.phase_started < min(FIRST_LINE, self.every):
            return False
        left = self.left(now)
        return left is not None and left > self.every

    def left(self, now):
        """Seconds left at the pace of the work done so far (an estimate); None before any
        unit is done, and once all are."""
        if not 0 < self.done < (self.total or 0):
            return None
        return (max(0.0, now - self.work_started) * (self.total - self.done)
                / max(self.done, min(self.at_once, self.total)))

    def work(self, at_once=1):
        """The current phase's work starts now (its set-up is over), ``at_once`` units at a
        time (the workers, or the runs of a chunk times the workers)."""
        self.work_started = self.clock()
        self.at_once = max(1, int(at_once))

    def phase(self, desc, total, unit=None):
        """Start a new phase of ``total`` units (``unit``: the last one's by default)."""
        self.desc, self.total, self.unit = desc, total, unit or self.unit
        self.done = 0
        self.phase_started = self.work_started = self.clock()
        self.at_once = 1
        self.spoke = False
        if self.bar is not None:
            self.bar.reset(total=total)
            self.bar.set_description(desc)
            self.bar.unit = " " + self.unit
        elif self.phase_started - self.started >= self.every:  # a long run: say so at once
            self.last = self.phase_started
            self.write(self.phase_started)

    def write(self, now):
        elapsed = now - self.phase_started
        line = "driftfmu: progress: %s" % self.desc
        if self.total:
            line += " %.0f %% (%d/%d %ss)" % (100.0 * self.done / self.total, self.done,
                                              self.total, self.unit)
        line += ", %s" % _seconds(elapsed)
        left = self.left(now)
        if left is not None:
            line += ", about %s left at this pace" % _seconds(left)
        self.stream.write(line + "\n")
        self.stream.flush()


def _seconds(s):
    return "%.0f s" % s if s < 120 else "%.1f min" % (s / 60.0)


@contextlib.contextmanager
def progress(total, desc, unit, monitor=True):
    """A :class:`Progress` over ``total`` units (``unit``: ``"sample"``, ``"set"``, ``"run"``):
    a tqdm bar when stderr is a terminal, periodic plain lines otherwise.  ``monitor=False``
    keeps tqdm from starting its monitor thread, so that the process stays single-threaded
    and worker processes can be forked."""
    if not sys.stderr.isatty():
        every = os.environ.get("DRIFTFMU_PROGRESS_EVERY")
        try:
            every = PROGRESS_EVERY if every is None else float(every)
        except ValueError:
            every = PROGRESS_EVERY
        yield Progress(total, desc, unit, every=every)
        return
    import tqdm
    if not monitor:
        tqdm.tqdm.monitor_interval = 0
    bar = tqdm.tqdm(total=total, desc=desc, unit=" " + unit, leave=False)
    try:
        yield Progress(total, desc, unit, bar=bar)
    finally:
        bar.close()


def start_phase(progress, desc, total, unit=None):
    """Tell ``progress`` (a :class:`Progress`, any callable, or None) that a new phase of
    ``total`` units starts."""
    phase = getattr(progress, "phase", None)
    if phase is not None:
        phase(desc, total, unit)


def start_work(progress, at_once=1):
    """Tell ``progress`` (a :class:`Progress`, any callable, or None) that the current phase's
    work starts now, ``at_once`` units at a time: its estimate of the time left counts from
    here (:meth:`Progress.left`)."""
    work = getattr(progress, "work", None)
    if work is not None:
        work(at_once)


def cmd_build(args):
    """``driftfmu build``: :func:`driftfmu.build_fmus` for the Python FMUs, then (``--native``)
    for the native FMUs of both FMI versions.  The cross-check folders hold the native FMUs when
    they are built, else the Python ones; the SSP archive holds the ``--backend`` ones."""
    import driftfmu
    from driftfmu.fmu_src import native_build
    from driftfmu.simulations.output import Staging
    start = start_values(args.start_values)
    if not (args.native or args.backend == "native"):  # one call, all or nothing by itself
        driftfmu.build_fmus(args.out, log=build_log,  # logs one line per FMU
                            cross_check=args.cross_check, ssp=args.ssp, start_values=start)
        return
    # two calls, all the outputs of both or none: they write to staged stand-ins, moved into
    # place only once both have succeeded (with --backend python the first call writes the
    # SSP: a failing native build must not leave it behind)
    with Staging() as staging:
        out = staging.path(args.out)
        cross_check = args.cross_check and staging.path(args.cross_check)
        ssp = args.ssp and staging.path(args.ssp, folder=False)
        log = staging.log(build_log)
        python_ssp = args.backend == "python"
        driftfmu.build_fmus(out, log=log, cross_check=None,
                            ssp=ssp if python_ssp else None,
                            start_values=start if python_ssp else None)
        driftfmu.build_fmus(out, backend="native", fmi_version=(2, 3), log=log,
                            cross_check=cross_check,
                            ssp=ssp if not python_ssp else None,
                            start_values=start if not python_ssp else None,
                            cache=None if args.no_cache else native_build.user_cache())


def start_values(pairs, numbers=False):
    """``--start-values NAME VALUE ...`` as a dict (None when not given): a value that reads
    as an integer is one, else a float.  Text that is no number stays text, for the check that
    names it (with ``numbers``: refused here, in one line).  A name without a value is
    refused."""
    if pairs is None:
        return None
    if len(pairs) % 2:
        raise UsageError("--start-values %s: a name without a value; allowed: NAME VALUE "
                         "pairs, e.g. --start-values a2 0.02 seed 7" % " ".join(pairs))
    out = {}
    for name, text in zip(pairs[::2], pairs[1::2]):
        try:
            out[name] = int(text)
        except ValueError:
            try:
                out[name] = float(text)
            except ValueError:
                if numbers:
                    raise UsageError("--start-values %s %s: %r is not a number; allowed: "
                                     "NAME VALUE pairs of numbers" % (name, text, text)) from None
                out[name] = text
    return out


def build_log(line):
    """The builders' log: a line about a built FMU to standard output; a warning to standard
    error, one line, as the command's other warnings."""
    if line.startswith("warning: "):
        sys.stderr.write("driftfmu: %s\n" % first_line(line))
        sys.stderr.flush()
    else:
        print(line, flush=True)


def check_build_args(args):
    """Usage errors of ``driftfmu build`` found before anything is built."""
    from driftfmu.fmu_src.builder import BuildError, generation_time
    try:
        generation_time()  # SOURCE_DATE_EPOCH, when set, is a time
    except BuildError as exc:
        raise UsageError(str(exc)) from None
    if args.native or args.backend == "native":
        from driftfmu.fmu_src import native_build
        problem = native_build.compiler_problem("linux64")
        if problem:
            raise UsageError("build --native needs a C compiler: %s" % problem)
        if not args.no_cache:  # a cache another user could change is refused before the build
            native_build.open_cache(native_build.user_cache())
    if args.ssp:
        ssp = Path(args.ssp)
        if ssp.is_dir():
            raise UsageError("--ssp %s is a folder; allowed: the path of the .ssp file to write"
                             % ssp)
        if ssp.exists() and not args.force:
            raise UsageError("--ssp %s exists; add --force to replace it" % ssp)
    if args.start_values is not None:
        if not args.ssp:
            raise UsageError("--start-values sets the SSP archive's parameter values; allowed: "
                             "--start-values with --ssp")
        from driftfmu.fmu_src.ssp import parameter_values
        parameter_values(start_values(args.start_values))  # refused before anything is built


#: The sensor's slow errors, tilt, temperature, range and ADC (issue 42, docs/method.md
#: section 10; models.chain.SENSOR_ERRORS_OFF): off by default.
SENSOR_ERRORS = tuple(chain.SENSOR_ERRORS_OFF)
#: The general model's parameters (issue 16, docs/method.md section 9) and the sensor's slow
#: errors: off by default.
GENERAL = ("a3", "a4", "B", "drive", "Qu", "Xu", "fu") + SENSOR_ERRORS


def cmd_run_gaussian(args):
    """``driftfmu run gaussian``: :func:`driftfmu.run_gaussian`."""
    import driftfmu
    from driftfmu.simulations import budget
    budget.check_run("gaussian", args.n, args.out, args.backend)
    with progress(args.n, "co-simulation", "sample") as update:
        res = driftfmu.run_gaussian(out=args.out, a0=args.a0, a1=args.a1, a2=args.a2, A=args.A,
                           Q=args.Q, R=args.R, n=args.n, seed=args.seed, Ts=args.Ts,
                           P0=args.P0, estimator=args.estimator, fmu_dir=args.fmu_dir,
                           progress=update, backend=args.backend,
                           **{name: getattr(args, name) for name in GENERAL})
    s = res["summary"]
    f = s["final"]
    print("wrote %s/results.csv, summary.json, drift.png" % args.out)
    print("final drift [V]: EKF1 %.4g, EKF2 %.4g, EKF3 %.4g | realised %.4g, empirical %.4g, "
          "expected %.4g" % (f["dc_ekf1"], f["dc_ekf2"], f["dc_ekf3"], f["dc_realised"],
                             f["dc_empirical"], f["dc_expected"]))
    line = "EKF1-EKF2 gap %.4f dB" % s["ekf1_ekf2_gap_db"]
    if "ekf1_ekf2_gap_db_expected" in s:
        line += " (expected 10 log10(1 + R/(a1^2 Q)) = %.4f dB)" % s["ekf1_ekf2_gap_db_expected"]
    print(line)
    st = s["settled_from_sample"]
    print("within 10 %% of the realised drift from sample (and to the end): EKF1 %s, EKF2 %s, "
          "EKF3 %s"
          % tuple(settled_text(st[e]) for e in ("ekf1", "ekf2", "ekf3")))
    print("validation: FMU outputs equal models/ (max |diff| %.3g, tolerance %g)"
          % (max(s["validation"]["max_abs_diff"].values()), s["validation"]["tolerance"]))


def settled_text(k, n=None):
    """A settling sample for people: ``"never"`` (None, or after the last sample ``n``)."""
    if k is None or (n is not None and k > n):
        return "never (not within the band for the last 10 % of the samples)"
    return "%d" % k


#: Modules that add their own sub-commands: each has ``add_cli(groups)`` taking the dict
#: ``{"top": <sub-parsers of driftfmu>, "run": <sub-parsers of driftfmu run>}``; the module that
#: adds ``driftfmu experiment`` puts its sub-parsers there as ``"experiment"`` for the later ones.
PLUGINS = ("driftfmu.simulations.doctor", "driftfmu.simulations.sweep", "driftfmu.simulations.montecarlo",
           "driftfmu.simulations.sinusoidal", "driftfmu.simulations.adxl203",
           "driftfmu.simulations.dual_axis", "driftfmu.simulations.drift_classes",
           "driftfmu.simulations.hostinputs",
           "driftfmu.simulations.allan")


def make_parser():
    parser = _Parser(prog="driftfmu", description=(
        "Co-simulation FMUs (FMI 2.0; their native C twins FMI 2.0 and 3.0) of a weakly "
        "nonlinear accelerometer and an EKF drift compensator (Chorti et al., Sensor Letters "
        "2006), and fmpy masters around them."))
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
    p.add_argument("--start-values", nargs="+", default=None, metavar="NAME VALUE",
                   help="with --ssp: the parameter values the archive carries as its parameter "
                   "sets (resources/<Component>.ssv), pairs of a name and a value, e.g. "
                   "--start-values a2 0.02 seed 7; a plain name sets the parameter in every "
                   "component that has it, Accelerometer.a2 in one (default: the FMUs' "
                   "defaults)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing --ssp FILE")
    p.add_argument("--native", action="store_true",
                   help="also build the native (C) twins of the FMUs, FMI 2.0 and FMI 3.0 source "
                   "FMUs with binaries for Linux, Windows and macOS on x86-64 and aarch64 (those "
                   "with a compiler here: gcc, mingw-w64, or zig for all of them, which the "
                   "extra driftfmu[native] installs), as DIR/native/fmi2/<Name>.fmu, "
                   "DIR/native/fmi2-aarch64/<Name>.fmu (FMI 2.0 for ARM Linux and Windows) and "
                   "DIR/native/fmi3/<Name>.fmu (validated with fmpy); see docs/platforms.md")
    add_backend(p, what="the FMUs of the cross-check artifacts and the SSP export: python, or "
                "native (implies --native; the cross-check then has folders for FMI 2.0 and "
                "3.0 and for each platform)")
    p.add_argument("--no-cache", action="store_true",
                   help="compile every native library; by default one compiled before from "
                   "the same sources by the same compiler is taken from the cache folder "
                   "DRIFTFMU_CACHE (default: ~/.cache/driftfmu/native-libraries; entries "
                   "unused for 30 days are removed)")
    p.set_defaults(func=cmd_build)

    run = sub.add_parser("run", help="co-simulate the FMUs with an fmpy master")
    runs = run.add_subparsers(dest="experiment", metavar="EXPERIMENT", parser_class=_Parser)
    runs.required = True
    g = runs.add_parser("gaussian", help="Gaussian excitation, the letter's Sec. III / Fig. 1")
    add_params(g, ("a0", "a1", "a2", "A", "Q", "R", "n", "seed", "Ts"))
    add_params(g, GENERAL)
    g.add_argument("--P0", type=param_type("P0"), default=None, metavar="P0",
                   help="initial error variance of the filter [g2] (default: Q / (1 - A^2))")
    g.add_argument("--estimator", type=checks.choice_option("estimator", (1, 2, 3)),
                   choices=(1, 2, 3), default=1,
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
                        help="folder of the FMUs, built there if missing when it holds no "
                             "other files (default: build/fmus)")


#: The FMUs a run can use (``--backend``).
BACKENDS = ("python", "native")


def add_backend(parser, what=None):
    """The common ``--backend python|native`` option."""
    parser.add_argument("--backend", type=checks.choice_option("backend", BACKENDS),
                        choices=BACKENDS, default="python",
                        help=(what or "the FMUs to run: python, the pythonfmu FMUs in FMU_DIR "
                              "(need a libpython), or native, their C twins in "
                              "FMU_DIR/native/fmi2 (need nothing; same bits); built there if "
                              "missing") + " (default: python)")


def check_out(args):
    """Usage errors of the output options (``--out``, and ``build``'s ``--cross-check`` and
    ``--ssp``), found before anything runs: an empty path, an existing file where a folder is
    meant, a folder that cannot be created or written."""
    for option, attr in (("--out", "out"), ("--cross-check", "cross_check")):
        value = getattr(args, attr, None)
        if value is not None:
            check_folder(option, value)
    if getattr(args, "fmu_dir", None) is not None:  # read, or written when the FMUs are missing
        check_folder("--fmu-dir", args.fmu_dir, writable=False)
    ssp = getattr(args, "ssp", None)
    if ssp is not None:
        if not ssp.strip():
            raise UsageError("--ssp '' is empty; allowed: the path of the .ssp file to write")
        check_folder("--ssp", str(Path(ssp).parent), what="the folder of")


def check_folder(option, value, what="", writable=True):
    """Usage error unless ``value`` names a folder that exists and can be written to, or that
    can be created: its nearest existing parent is a folder this process can write to (tried
    with a staging folder made and removed there, :func:`driftfmu.simulations.output.probe`,
    so it holds for root and for read-only file systems alike).  With
    ``writable=False`` only an empty path and a file where the folder or a parent should be."""
    if not value.strip():
        raise UsageError("%s %r is empty; allowed: a folder path, e.g. results/run1"
                         % (option, value))
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise UsageError("%s %s is an existing file; allowed: a folder (created if missing)"
                         % (option, value))
    from driftfmu.simulations.output import nearest_existing
    parent = nearest_existing(path)
    if not parent.is_dir():
        raise UsageError("%s %s cannot be created: %s is a file; allowed: a folder path"
                         % (option, value, parent))
    if not writable:
        return
    from driftfmu.simulations.output import probe
    try:
        probe(parent)  # (killed meanwhile: a staging folder, which the next run removes)
    except OSError as exc:
        raise UsageError("%s %s cannot be written: no folder can be made in %s%s (%s); "
                         "allowed: a folder you can write to" % (
                             option, value, what + " " if what else "", parent,
                             exc.strerror or exc)) from None


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
            status = _main(argv, previous)
    except KeyboardInterrupt:  # in the instant before _main's own handling
        sys.stderr.write("driftfmu: interrupted\n")
        status = EXIT_INTERRUPTED
    if status == EXIT_INTERRUPTED and argv is None:
        exit_watchdog(status)
    return status


#: Seconds the interpreter may take to exit after an interrupt before :func:`exit_watchdog`
#: ends the process.
EXIT_GRACE = 10.0


def exit_watchdog(status, seconds=EXIT_GRACE):
    """End this process with ``status`` if it is still alive ``seconds`` from now: after an
    interrupt, nothing (a library's thread joined at the interpreter's exit, a worker that
    never answers) may keep the command waiting for ever.  A daemon thread, so a clean exit
    does not wait for it."""
    import threading

    def end():
        time.sleep(seconds)
        with contextlib.suppress(Exception):
            sys.stderr.flush()
        os._exit(status)
    threading.Thread(target=end, name="driftfmu-exit-watchdog", daemon=True).start()


def _show_warning(message, category, filename, lineno, file=None, line=None):
    sys.stderr.write("driftfmu: warning: %s\n" % first_line(message))


class ReportLost(Exception):
    """Writing to standard output failed (the OSError is the cause)."""


class _Report:
    """Standard output while a command runs: an error writing to it is a :class:`ReportLost`,
    told apart from an error writing the results."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        try:
            return self._stream.write(text)
        except OSError as exc:
            raise ReportLost(exc) from exc

    def flush(self):
        try:
            return self._stream.flush()
        except OSError as exc:
            raise ReportLost(exc) from exc

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _main(argv, previous):
    from driftfmu.simulations import output
    commits = output.COMMITS[0]
    stdout = sys.stdout
    sys.stdout = _Report(stdout)
    try:
        return _command(argv, previous)
    except ReportLost as exc:
        # the report of the run is lost; the exit status says what happened to the results
        reason = first_line(exc.__cause__)
        if output.COMMITS[0] > commits:
            sys.stderr.write("driftfmu: warning: standard output: %s; the results are in place "
                             "(this report of them is lost)\n" % reason)
            return 0
        sys.stderr.write("driftfmu: error: standard output: %s\n" % reason)
        return EXIT_FAILED
    finally:
        sys.stdout = stdout


def _command(argv, previous):
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
        sys.stdout.flush()  # the report's last lines: an error writing them is told here
    except KeyboardInterrupt:
        return _main_interrupted()
    except ReportLost:
        raise
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


def run_program():
    """``driftfmu`` as a program (``python -m driftfmu``): run :func:`main` and end the process
    with its status.

    Every command ends here with :func:`end_process` (``os._exit`` after the exit handlers).
    Through ``sys.exit`` an interrupted one could end killed by SIGINT instead of with status
    130: when Ctrl-C lands in code that runs from a string (``exec``/``eval``, as
    ``dataclasses`` and ``namedtuple`` do while a module is imported), CPython notes the
    KeyboardInterrupt as unhandled even though it was caught, and ``python -m`` then re-raises
    SIGINT at its exit whatever status is given.
    """
    status = main()
    end_process(status, join_threads=status != EXIT_INTERRUPTED)


def end_process(status, join_threads=True):
    """End this process with ``status`` as the interpreter's exit would, but without tearing
    down every module and object (0.1 s after a command that drew figures): non-daemon threads
    joined (not after an interrupt: :func:`exit_watchdog` bounds that exit instead), the exit
    handlers run, the standard streams flushed, then ``os._exit``."""
    import atexit
    import threading
    shutdown = getattr(threading, "_shutdown", None)  # noqa: SLF001 (the interpreter's join)
    if join_threads:
        # an interpreter without the join, or a profiler or debugger that reports after the
        # program (python -m cProfile -m driftfmu ...): the interpreter's own exit
        if shutdown is None or sys.getprofile() is not None or sys.gettrace() is not None:
            sys.exit(status)
        shutdown()
    atexit._run_exitfuncs()  # noqa: SLF001 (what the interpreter's exit would run)
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


if __name__ == "__main__":
    run_program()
