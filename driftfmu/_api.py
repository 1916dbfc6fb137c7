"""The public Python API of driftfmu (re-exported by ``driftfmu``).

Small and in the style of FMPy's ``simulate_fmu``: ``build_fmus`` builds the FMUs,
``simulate`` co-simulates any subset of them and returns a structured NumPy array whose
first field is ``time``, and one function per experiment of the letter returns its results.
Everything else in the package (``driftfmu.models``, ``driftfmu.simulations``,
``driftfmu.fmu_src``) is internal: it may change between versions.

Every function checks its arguments before anything is built, run or written, by the rules
and in the words of the ``driftfmu`` command's checks of the same options: a keyword it does
not take is a ``TypeError`` (also a ``ValueError``) naming the function and every keyword it
takes; a value of the wrong type (text and ``True``/``False`` are not numbers, a count is an
``int``), out of its range or not one of its choices, an ``out`` that is a file, and a run too
large for this machine's memory or disk (with the estimate and the largest size that fits) are
a ``ValueError`` of one line naming the value and what is allowed.

Heavy imports (NumPy, fmpy, the masters) happen inside the functions, so ``import driftfmu``
stays cheap.
"""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, Mapping, Optional, Sequence, Union

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

PathLike = Union[str, Path]

#: The four FMUs, in the order a Gauss-Seidel master steps them.
FMU_NAMES = ("Excitation", "Accelerometer", "DriftEstimator", "DualDriftEstimator")

#: The default wiring of the chain: (source FMU, output, destination FMU, input).  Of these,
#: ``simulate`` uses the connections whose two FMUs are both simulated.
CONNECTIONS = (
    ("Excitation", "x", "Accelerometer", "x"),
    ("Excitation", "y", "Accelerometer", "y"),
    ("Accelerometer", "z", "DriftEstimator", "z"),
    ("Accelerometer", "z", "DualDriftEstimator", "z_x"),
    ("Accelerometer", "z_y", "DualDriftEstimator", "z_y"),
    # the known input u (eq. 1) to the filter's prediction B u; with B = 0 the filter ignores it
    ("Excitation", "u", "DriftEstimator", "u"),
)

#: The FMU kinds: ``"python"`` (pythonfmu, FMI 2.0) and ``"native"`` (C, FMI 2.0 or 3.0).
BACKENDS = ("python", "native")


def _check_choice(name: str, value: Any, allowed: Sequence[Any]) -> None:
    from driftfmu.simulations import checks
    checks.refuse([checks.choice_problem(name, value, allowed)])


def _keywords_checked(function: Callable) -> Callable:
    """``function`` with a keyword it does not take refused in one line that names it and
    every keyword it takes (Python's own TypeError names neither the allowed ones nor a
    close match).  Its signature, name and docstring stay the function's."""
    import functools
    import inspect
    signature = inspect.signature(function)
    named = [n for n, p in signature.parameters.items()
             if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    takes_any = any(p.kind == p.VAR_KEYWORD for p in signature.parameters.values())

    @functools.wraps(function)
    def checked(*args: Any, **kwargs: Any) -> Any:
        if not takes_any:
            from driftfmu.simulations import checks
            checks.check_keywords("%s()" % function.__name__, kwargs, named)
        return function(*args, **kwargs)
    return checked


def _allowed(public: Callable, *inner: Callable, extra: Sequence[str] = (),
             internal: Sequence[str] = ("plot", "validate")) -> tuple:
    """Every keyword of a public function that passes ``**parameters`` on: its own named
    parameters, then those of the ``inner`` functions it passes them to (less their
    ``internal`` ones), then ``extra``."""
    import inspect
    names: list = []
    for fn in (public,) + inner:
        for n, p in inspect.signature(fn).parameters.items():
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and n not in names \
                    and n not in internal:
                names.append(n)
    return tuple(names) + tuple(n for n in extra if n not in names)


def _settings_problems(values: Mapping[str, Any], counts: Mapping[str, int] = {},
                       choices: Mapping[str, Sequence[Any]] = {},
                       flags: Sequence[str] = (), optional: Sequence[str] = ()) -> list:
    """Why the given settings are not allowed, by the rules the command line applies to the
    same options: ``counts`` (name -> least value), ``choices``, ``flags`` (True or False),
    the model parameters of :mod:`driftfmu.models.parameters` (an integer one an integer),
    ``f`` a drive frequency, ``scheduler`` an address, ``fmu_dir`` and ``out`` paths,
    ``progress`` and ``log`` callables; ``optional`` names may also be None."""
    from driftfmu.models import parameters
    from driftfmu.simulations import checks
    problems = []
    for name, value in values.items():
        if value is None and (name in optional or name in ("out", "progress", "log",
                                                             "scheduler", "workers")):
            continue
        if name in counts:
            problems.append(checks.count_problem(name, value, counts[name]))
        elif name in choices:
            problems.append(checks.choice_problem(name, value, choices[name]))
        elif name in flags:
            problems.append(checks.flag_problem(name, value))
        elif name == "f":
            problems.append(checks.frequency_problem(value))
        elif name == "scheduler":
            problems.append(checks.scheduler_problem(value))
        elif name in ("out", "fmu_dir"):
            problems.append(checks.path_problem(name, value, optional=name == "out",
                                                example="results/run1" if name == "out"
                                                else "build/fmus"))
        elif name in ("progress", "log"):
            problems.append(checks.callback_problem(name, value))
        elif name in parameters.PARAMETERS:
            problems.append(checks.number_problem(name, value))
    return [p for p in problems if p]


def _check_folders(out: Any, fmu_dir: Any = None) -> None:
    """The command line's checks of ``--out`` and ``--fmu-dir`` (before anything runs): an
    existing file where a folder is meant, a folder that cannot be created or written."""
    from driftfmu.simulations.cli import check_folder
    if out is not None:
        check_folder("out =", str(out))
    if fmu_dir is not None:
        check_folder("fmu_dir =", str(fmu_dir), writable=False)


def _quiet_log(line: str) -> None:
    """Build progress is dropped; a build warning becomes a Python warning."""
    if line.startswith("warning"):
        warnings.warn(line, stacklevel=3)


def _is_sequence(value: Any) -> bool:
    """True for a list, tuple, array or other iterable that is not text or a mapping."""
    from collections.abc import Iterable
    return isinstance(value, Iterable) and not isinstance(value, (str, bytes, Mapping))


@_keywords_checked
def build_fmus(out_dir: PathLike = "build/fmus", backend: str = "python",
               fmi_version: Union[int, Sequence[int]] = 2,
               names: Optional[Sequence[str]] = None,
               log: Optional[Callable[[str], None]] = None, *,
               cross_check: Optional[PathLike] = None,
               ssp: Optional[PathLike] = None,
               start_values: Optional[Mapping[str, float]] = None,
               cache: Optional[PathLike] = None) -> Dict[str, Path]:
    """Build and validate the FMUs.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Folder of the Python FMUs (``<out_dir>/<Name>.fmu``); the native FMUs go to
        ``<out_dir>/native/fmi<fmi_version>/<Name>.fmu``, where [`simulate`][driftfmu.simulate] looks for them
        (and, with an ARM compiler, the FMI 2.0 FMUs for ARM to ``native/fmi2-aarch64/``).
        Beside the Excitation, Accelerometer and DriftEstimator FMUs of each folder goes
        ``DriftChain.json``, the description from which the FMU Manipulation Toolbox's
        ``fmucontainer`` makes the chain one FMU (docs/hosts.md).
        Created if missing.  All or nothing: every output of the call (FMUs, ``cross_check``,
        ``ssp``) is built in a hidden staging folder and moved into place only once the whole
        build has succeeded; a failed or interrupted build leaves every path as it was.
    backend : {"python", "native"}
        ``"python"``: pythonfmu FMUs (FMI 2.0, Linux x86-64; the model runs in the host's
        CPython).  ``"native"``: the C twins, source FMUs with a binary for every platform
        whose compiler is installed (Linux, Windows, macOS; x86-64 and aarch64).
    fmi_version : {2, 3} or sequence of them
        FMI version of the native FMUs, or several (``(2, 3)``, as ``driftfmu build
        --native``); the Python FMUs are FMI 2.0 only.
    names : sequence of str, optional
        Which FMUs, of ``"Excitation"``, ``"Accelerometer"``, ``"DriftEstimator"`` and
        ``"DualDriftEstimator"`` (default: all four).
    log : callable, optional
        Receives one progress line per FMU (and per cross-check folder and SSP archive); by
        default progress is silent and build warnings (e.g. no C compiler for the loader
        shim) become Python warnings.
    cross_check : str or pathlib.Path, optional
        Also write the FMI cross-check folders of the built FMUs there (FMU, input, reference
        result, options, ReadMe; for native FMUs one folder per FMI version and platform), as
        ``driftfmu build --cross-check``.
    ssp : str or pathlib.Path, optional
        Also write the wired chain Excitation -> Accelerometer -> DriftEstimator of the built
        FMUs (FMI 2.0) as an SSP archive at this path (replaced if it exists), as ``driftfmu
        build --ssp``.
    start_values : dict of str to float, optional
        With ``ssp``: the parameter values the archive carries, as [`simulate`][driftfmu.simulate]
        takes them (``"a2"`` in every component that has it, ``"Accelerometer.a2"`` in one);
        the others keep the FMUs' defaults.  Each component's values are a parameter set of
        its own (``resources/<Component>.ssv``, referenced from the ``.ssd``), which
        OMSimulator applies, and fmpy's ``simulate_ssp`` when it is passed (docs/hosts.md).
        Checked before anything is built: a name that is no parameter or a value that is not
        allowed is refused in one line naming the component and the parameter.
    cache : str or pathlib.Path, optional
        Native FMUs only: a folder of compiled libraries kept from build to build; a library
        compiled before from the same sources by the same compiler (command, version, flags)
        is taken from there instead of compiled again, the same bytes.  Entries unused for 30
        days are removed.  ``driftfmu build`` uses the user's cache folder
        (``~/.cache/driftfmu/native-libraries``, or ``DRIFTFMU_CACHE``); default here: none,
        every library is compiled.

    Returns
    -------
    dict of str to pathlib.Path
        FMU name -> path of the built ``.fmu``; with several ``fmi_version``, the key is the
        FMU's path under ``native/``, e.g. ``"fmi3/Excitation"``.

    Raises
    ------
    ValueError
        ``backend``, ``fmi_version``, a name, a path or an export is not allowed (the message
        says what is).
    TypeError
        A keyword the function does not take (the message names every one it takes).
    RuntimeError
        An FMU could not be built or does not validate.

    Examples
    --------
    >>> import driftfmu
    >>> paths = driftfmu.build_fmus("build/fmus")
    >>> sorted(paths)
    ['Accelerometer', 'DriftEstimator', 'DualDriftEstimator', 'Excitation']
    >>> paths["Excitation"].as_posix()
    'build/fmus/Excitation.fmu'
    """
    from driftfmu.simulations import checks
    from driftfmu.simulations.errors import UsageError
    checks.refuse([checks.path_problem("out_dir", out_dir, optional=False,
                                       example="build/fmus")]
                  + [checks.path_problem(k, v) for k, v in (("cross_check", cross_check),
                                                            ("ssp", ssp), ("cache", cache))]
                  + [checks.callback_problem("log", log)])
    _check_choice("backend", backend, BACKENDS)
    several = not checks.is_integer(fmi_version)
    if several and (isinstance(fmi_version, (str, bytes)) or not _is_sequence(fmi_version)):
        raise UsageError("fmi_version = %r is not allowed; allowed: %s" % (
            fmi_version, "2" if backend == "python" else "2, 3 or a sequence of them"))
    versions = tuple(fmi_version) if several else (fmi_version,)
    if not versions:
        raise UsageError("fmi_version = () is not allowed; allowed: 2, 3 or a sequence of them")
    for v in versions:
        _check_choice("fmi_version", v, (2,) if backend == "python" else (2, 3))
    if names is not None and (isinstance(names, (str, bytes)) or not _is_sequence(names)):
        raise UsageError("names = %r is not allowed; allowed: a sequence of FMU names (one or "
                         "more of %s), e.g. [%r], or None (all)" % (names, ", ".join(FMU_NAMES),
                                                                    FMU_NAMES[0]))
    names = tuple(FMU_NAMES if names is None else names)
    for name in names:
        _check_choice("FMU name", name, FMU_NAMES)
    ssp_values = None
    if start_values is not None and ssp is None:
        raise UsageError("start_values are the SSP archive's parameter values; allowed: "
                         "start_values with ssp (the path of the archive to write)")
    if ssp is not None:
        from driftfmu.fmu_src.ssp import FMU_NAMES as chain
        from driftfmu.fmu_src.ssp import parameter_values
        if 2 not in versions or not set(chain) <= set(names):
            raise UsageError("ssp needs the FMI 2.0 FMUs %s; allowed: names with them and "
                             "fmi_version 2" % ", ".join(chain))
        ssp_values = parameter_values(start_values)  # refused before anything is built
    from driftfmu.simulations.output import Staging, nearest_existing
    for what, path, folder in (("out_dir", out_dir, True), ("cross_check", cross_check, True),
                               ("ssp", ssp, False)):
        if path is None:
            continue
        existing = nearest_existing(path if folder else Path(path).parent)
        if not existing.is_dir():  # before anything is built, not after
            raise UsageError("%s = %s: %s is an existing file; allowed: %s" % (
                what, path, existing, "a folder (created if missing)" if folder
                else "a file path in a folder"))
    log = _quiet_log if log is None else log
    # all the outputs or none: each is written to a staged stand-in and moved into place only
    # once the whole build has succeeded; a failed or stopped build leaves every path as it was
    with Staging() as staging:
        staged_out = staging.path(out_dir)
        staged_cross_check = None if cross_check is None else staging.path(cross_check)
        staged_ssp = None if ssp is None else staging.path(ssp, folder=False)
        log = staging.log(log)
        if backend == "python":
            from driftfmu.fmu_src import builder
            built = {2: {Path(p).stem: Path(p)
                         for p in builder.build_fmus(staged_out, names=names, log=log)}}
        else:
            from driftfmu.fmu_src import native_build
            built = native_build.build_native_fmus(staged_out / "native", names=names,
                                                   fmi_versions=versions, log=log, cache=cache)
            built = {v: {n: Path(p) for n, p in built[v].items()} for v in built}
        from driftfmu.fmu_src import container
        for v in sorted(built):  # the chain as one FMU: fmucontainer's description of it
            if set(container.NAMES) <= set(built[v]):
                container.write(built[v][container.NAMES[0]].parent)
        if staged_cross_check is not None:
            from driftfmu.fmu_src.crosscheck import write_cross_check
            for v in sorted(built):
                for d in write_cross_check(built[v], staged_cross_check, fmi_version=v,
                                           backend=backend):
                    log("%s/ (cross-check: fmu, _in.csv, _ref.csv, _ref.opt, ReadMe.txt)" % d)
        if staged_ssp is not None:
            from driftfmu.fmu_src.ssp import build_ssp
            log("%s (SSP: the wired chain of the %s FMUs, %s)" % (
                build_ssp(built[2], staged_ssp, start_values=ssp_values,
                          Ts=ssp_values["Excitation"]["Ts"]), backend,
                "the parameter values given" if start_values else
                "the start values of the letter's Gaussian run"))
    out = Path(out_dir)  # the paths the FMUs have now, as given
    built = {v: {n: out / p.relative_to(staged_out) for n, p in built[v].items()}
             for v in built}
    if not several:
        return built[versions[0]]
    return {"fmi%d/%s" % (v, n): p for v in sorted(built) for n, p in built[v].items()}


def _fmu_paths(names: Sequence[str], backend: str, fmi_version: int,
               fmu_dir: PathLike) -> Dict[str, Path]:
    """Paths of ``names``; the missing ones are built first."""
    from driftfmu.simulations.errors import UsageError
    from driftfmu.simulations.output import nearest_existing
    fmu_dir = Path(fmu_dir)
    existing = nearest_existing(fmu_dir)
    if not existing.is_dir():
        raise UsageError("fmu_dir %s: %s is a file; allowed: a folder of FMUs (built there if "
                         "missing)" % (fmu_dir, existing))
    if backend == "python":
        paths = {n: fmu_dir / ("%s.fmu" % n) for n in names}
    else:
        paths = {n: fmu_dir / "native" / ("fmi%d" % fmi_version) / ("%s.fmu" % n) for n in names}
    missing = [n for n, p in paths.items() if not p.is_file()]
    if missing:
        from driftfmu.fmu_src.builder import check_fmu_folder
        check_fmu_folder(fmu_dir, [paths[n].relative_to(fmu_dir).as_posix() for n in missing],
                         native=backend == "native")
        build_fmus(fmu_dir, backend=backend, fmi_version=fmi_version, names=missing)
    return paths


def _variables(path: Path) -> Dict[str, Any]:
    from driftfmu.simulations.cosim import checked_fmu
    # what the masters rely on, before fmpy (whose messages name neither the file nor a
    # remedy) and before any FMU runs (simulations/fmucheck.py)
    return {v.name: v for v in checked_fmu(str(path)).modelVariables}


def _start_value_problem(name: str, value: Any, variable: Any) -> Optional[str]:
    """Why ``value`` is not allowed as the start value of the FMU's parameter ``variable``
    (an fmpy model variable), or None: the rule of ``driftfmu.models.parameters`` where it
    has one (what the FMU checks too), else the declared type, min and max."""
    import math
    from driftfmu.models import parameters
    from driftfmu.simulations.checks import is_number
    integer = variable.type in ("Integer", "Int32")
    kind = "an integer" if integer else "a finite number"
    if not is_number(value):
        return "%s = %r is not a number; allowed: %s" % (name, value, kind)
    if name in parameters.PARAMETERS:
        return parameters.problem(name, value)
    low = None if variable.min is None else float(variable.min)
    high = None if variable.max is None else float(variable.max)
    if integer and math.isfinite(value) and value != int(value):
        return "%s = %r is not an integer; allowed: %s" % (name, value, kind)
    if not math.isfinite(value) or \
            (low is not None and value < low) or (high is not None and value > high):
        bounds = " and ".join(b for b in (
            None if variable.min is None else "%s >= %s" % (name, variable.min),
            None if variable.max is None else "%s <= %s" % (name, variable.max)) if b)
        return "%s = %r is not allowed; allowed: %s%s" % (name, value, kind,
                                                          ", " + bounds if bounds else "")
    return None


def _split_name(name: str, names: Sequence[str]) -> tuple:
    """``"FMU.var"`` -> (FMU, var) when FMU is simulated, else (None, name)."""
    fmu, dot, var = name.partition(".")
    if dot and fmu in names:
        return fmu, var
    return None, name


@_keywords_checked
def simulate(fmus: Sequence[str] = ("Excitation", "Accelerometer", "DriftEstimator"),
             stop_time: Optional[float] = None, step_size: Optional[float] = None,
             start_values: Optional[Mapping[str, float]] = None,
             input: Optional["np.ndarray"] = None, output: Optional[Sequence[str]] = None,
             backend: str = "python", fmi_version: int = 2, fmu_dir: PathLike = "build/fmus",
             start_time: float = 0.0) -> "np.ndarray":
    """Co-simulate the chain, or any subset of its FMUs, and return the results.

    The FMUs are stepped Gauss-Seidel in the order Excitation -> Accelerometer ->
    DriftEstimator -> DualDriftEstimator, wired Excitation ``x, y`` -> Accelerometer ``x, y``,
    Accelerometer ``z`` -> DriftEstimator ``z``, Accelerometer ``z, z_y`` -> DualDriftEstimator
    ``z_x, z_y`` and Excitation ``u`` -> DriftEstimator ``u`` (no lag: row ``k`` holds
    ``x_k``, its measurement ``z_k`` and the estimator's ``k``-th update; the Excitation's
    known input ``u`` reaches the DriftEstimator, which uses it when ``B != 0``).  Sample ``k`` of an
    FMU sits at ``start_time + (k - 1) Ts``; any ``step_size > 0`` is allowed (several samples
    per step, or several steps per sample, with the inputs held between sample instants).

    Parameters
    ----------
    fmus : sequence of str
        The FMUs to simulate, a subset of ``"Excitation"``, ``"Accelerometer"``,
        ``"DriftEstimator"`` and ``"DualDriftEstimator"`` (default: the letter's chain, the
        first three).
    stop_time : float, optional
        End of the simulation [s]; default 2.0 s, the FMUs' default experiment.
    step_size : float, optional
        Communication step [s]; default the sample period ``Ts`` from ``start_values``, else
        1 ms.
    start_values : dict of str to float, optional
        Parameter values by name.  A plain name (``"a2"``, ``"seed"``, ``"Ts"``) is set in
        every simulated FMU that has the variable; ``"Accelerometer.a2"`` sets it in one FMU.
        Unset parameters keep the FMUs' defaults (the letter's settings).  The general sensor
        (docs/method.md section 9) is set the same way: ``a3``, ``a4`` (Accelerometer and
        DriftEstimator), ``B`` (Excitation and DriftEstimator) and the Excitation's known
        input ``drive``, ``Qu``, ``Xu``, ``fu``; all off by default.
    input : numpy.ndarray, optional
        A structured array with a first field ``time`` and one field per input variable it
        drives (``"x"`` or ``"Accelerometer.x"``), like FMPy's ``input``.  At each
        communication point ``t`` the input takes the value of the last row with
        ``time <= t`` (zero-order hold; the first row before its time), a time within the
        FMUs' millionth of a step of ``t``, or within what a running sum of times can have
        rounded (``0.001 + 0.001 + ...``), counting as ``t`` (docs/hosts.md).  An input that an
        FMU of ``fmus`` already drives through a connection cannot also be given here.
    output : sequence of str, optional
        Variables to record (``"z"`` or ``"Accelerometer.z"``); a plain name is recorded from
        the FMUs that output it (else from any that has it).  Default: every output of the
        simulated FMUs.
    backend : {"python", "native"}
        Which FMUs: the pythonfmu FMUs or their native C twins (the same results bit for bit).
    fmi_version : {2, 3}
        FMI version of the native FMUs (the Python FMUs are FMI 2.0).
    fmu_dir : str or pathlib.Path
        Where the FMUs are (as [`build_fmus`][driftfmu.build_fmus] writes them); missing ones
        are built there when it is new, empty or holds only driftfmu's FMUs (a folder with
        other files is refused: nothing is written into it unasked).
    start_time : float
        Start of the simulation [s].

    Returns
    -------
    numpy.ndarray
        A structured array with one row per communication point
        ``start_time, start_time + step_size, ..., stop_time`` and the fields ``time`` first,
        then the recorded variables in the order of ``fmus``.  A field is named by the
        variable (``"z"``); when two simulated FMUs record a variable of the same name, both
        fields are named ``"<FMU>.<variable>"``.

    Raises
    ------
    ValueError
        An FMU, variable, backend, step, time, input value or start value is not allowed
        (one line naming it and what is allowed; a start value is checked against its
        parameter's rule and declared type and range before any FMU runs), or recording the
        outputs at every communication point would not fit the memory.  An FMU file that is
        not what driftfmu relies on (an edited model description, a cut binary, a zip bomb:
        docs/hosts.md, "Files someone else made") or that cannot be instantiated here is one
        line naming the file, the part and what is expected, before any FMU runs.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    RuntimeError
        An FMU call failed, e.g. a combination of parameters an FMU refuses (the first line
        says the FMU's reason; the lines after hold the rest of the FMUs' log).

    See Also
    --------
    run_gaussian : the letter's Gaussian run with its summary and reference checks.

    Examples
    --------
    >>> import driftfmu
    >>> result = driftfmu.simulate(stop_time=0.5, start_values={"a2": 0.02, "seed": 3})
    >>> result.dtype.names[:4]
    ('time', 'x', 'y', 'u')
    >>> len(result), float(result["time"][-1])
    (501, 0.5)
    >>> print("EKF1's drift estimate after 0.5 s: %.3g V" % result["dc_ekf1"][-1])
    EKF1's drift estimate after 0.5 s: 0.00021 V
    """
    import math

    import numpy as np

    from driftfmu.simulations.errors import UsageError

    from collections.abc import Iterable
    if isinstance(fmus, (str, bytes)) or not isinstance(fmus, Iterable):
        raise UsageError("fmus = %r is not allowed; allowed: a sequence of FMU names (one or "
                         "more of %s), e.g. [%r]" % (fmus, ", ".join(FMU_NAMES), FMU_NAMES[0]))
    from driftfmu.simulations import budget, checks
    checks.refuse([checks.path_problem("fmu_dir", fmu_dir, optional=False,
                                       example="build/fmus")])
    if output is not None and (isinstance(output, (str, bytes)) or not _is_sequence(output)):
        raise UsageError("output = %r is not allowed; allowed: a sequence of variable names, "
                         "e.g. ['z', 'dc_ekf1'], or None (every output)" % (output,))
    for label, value in (("stop_time", stop_time), ("step_size", step_size),
                         ("start_time", start_time)):
        if value is not None and not checks.is_number(value):
            raise UsageError("%s = %r is not a number; allowed: a finite number" % (label, value))
    names = list(fmus)
    if not names:
        raise UsageError("fmus = [] is not allowed; allowed: one or more of %s"
                         % ", ".join(FMU_NAMES))
    for name in names:
        _check_choice("FMU name", name, FMU_NAMES)
    if len(set(names)) != len(names):
        raise UsageError("fmus = %r names an FMU twice; allowed: each at most once" % (names,))
    names = [n for n in FMU_NAMES if n in names]  # the Gauss-Seidel order
    _check_choice("backend", backend, BACKENDS)
    _check_choice("fmi_version", fmi_version, (2,) if backend == "python" else (2, 3))
    if start_values is not None and not isinstance(start_values, Mapping):
        raise UsageError("start_values = %r is not a mapping; allowed: a dict of variable "
                         "names and values, e.g. {\"a2\": 0.02, \"seed\": 3}"
                         % (start_values,))
    start_values = dict(start_values or {})
    if step_size is None:
        ts = start_values.get("Ts")
        step_size = float(ts) if isinstance(ts, (int, float)) else 1e-3
    stop_time = 2.0 if stop_time is None else float(stop_time)
    start_time = float(start_time)
    if not (math.isfinite(step_size) and step_size > 0):
        raise UsageError("step_size = %r is not allowed; allowed: a finite number > 0"
                         % (step_size,))
    if not (math.isfinite(start_time) and math.isfinite(stop_time) and stop_time >= start_time):
        raise UsageError("start_time = %r, stop_time = %r are not allowed; allowed: finite, "
                         "stop_time >= start_time" % (start_time, stop_time))
    steps = (stop_time - start_time) / step_size
    if not math.isfinite(steps):  # (a step too small for the span to count its points)
        raise UsageError("stop_time = %r with step_size = %r makes more communication points "
                         "than can be counted; allowed: a longer step_size or an earlier "
                         "stop_time" % (stop_time, step_size))
    n_steps = int(round(steps)) + 1

    paths = _fmu_paths(names, backend, fmi_version, fmu_dir)
    variables = {n: _variables(paths[n]) for n in names}
    connections = [c for c in CONNECTIONS if c[0] in names and c[2] in names]
    connected = {(d, i) for _, _, d, i in connections}

    # start values: plain names go to every FMU that has the parameter
    per_fmu = {n: {} for n in names}
    for key, value in start_values.items():
        if not isinstance(key, str):
            raise UsageError("start value %r is not a parameter name; allowed: names such as "
                             "'a2' or 'Accelerometer.a2'" % (key,))
        fmu, var = _split_name(key, names)
        targets = [fmu] if fmu else [n for n in names if var in variables[n]]
        targets = [t for t in targets if var in variables[t]
                   and variables[t][var].causality == "parameter"]
        if not targets:
            raise UsageError("start value %r is not a parameter of %s; allowed: %s" % (
                key, " or ".join(names),
                ", ".join(sorted({v for n in names for v, mv in variables[n].items()
                                  if mv.causality == "parameter"}))))
        for t in targets:
            problem = _start_value_problem(var, value, variables[t][var])
            if problem:  # here, not as an FMU's log: fmpy would wrap an Integer out of range
                raise UsageError("start value %s" % problem)
            per_fmu[t][var] = value

    # external inputs, sampled with a zero-order hold at the communication points
    feeds = {}
    if input is not None:
        fields = getattr(getattr(input, "dtype", None), "names", None) or ()
        if not fields or fields[0] != "time":
            raise UsageError("input has fields %r; allowed: a structured array whose first "
                             "field is 'time'" % (fields,))
        times = np.asarray(input["time"], dtype=float)
        if times.ndim != 1 or times.size == 0 or not np.all(np.isfinite(times)) or \
                np.any(np.diff(times) < 0):
            raise UsageError("input['time'] must be a non-empty, non-decreasing 1-D array of "
                             "finite times")
        # a row at or before a communication point within the tolerance of
        # simulations/times.py (the FMUs' own, and what a running sum of times can round)
        from driftfmu.simulations import times as timing
        rows = timing.held_rows(times, start_time, step_size, n_steps)
        for key in fields[1:]:
            fmu, var = _split_name(key, names)
            targets = [fmu] if fmu else [n for n in names if var in variables[n]
                                         and variables[n][var].causality == "input"]
            targets = [t for t in targets if var in variables[t]
                       and variables[t][var].causality == "input"]
            if not targets:
                raise UsageError("input field %r is not an input of %s; allowed: %s" % (
                    key, " or ".join(names),
                    ", ".join(sorted({v for n in names for v, mv in variables[n].items()
                                      if mv.causality == "input"})) or "none"))
            values = np.asarray(input[key], dtype=float)[rows]
            if not np.all(np.isfinite(values)):
                raise UsageError("input field %r has values that are not finite (NaN or "
                                 "infinite) at the communication points; allowed: finite "
                                 "values" % (key,))
            for t in targets:
                if (t, var) in connected:
                    raise UsageError("input field %r drives %s.%s, which the connection from "
                                     "%s already drives; allowed: inputs of FMUs whose source "
                                     "is not simulated" % (key, t, var, " ".join(
                                         c[0] for c in connections if c[2:] == (t, var))))
                feeds.setdefault(t, {})[var] = values.tolist()

    # what to record
    if output is None:
        record = {n: [v for v, mv in variables[n].items() if mv.causality == "output"]
                  for n in names}
    else:
        record = {n: [] for n in names}
        for key in output:
            if not isinstance(key, str):
                raise UsageError("output %r is not a variable name; allowed: names such as "
                                 "'z' or 'Accelerometer.z'" % (key,))
            fmu, var = _split_name(key, names)
            if fmu:
                owners = [fmu] if var in variables[fmu] else []
            else:  # a plain name: the FMUs that output it, else any that has it
                owners = ([n for n in names if var in variables[n]
                           and variables[n][var].causality == "output"]
                          or [n for n in names if var in variables[n]])
            if not owners:
                raise UsageError("output %r is not a variable of %s; allowed: %s" % (
                    key, " or ".join(names), ", ".join(sorted({v for n in names
                                                               for v in variables[n]}))))
            for o in owners:
                if var not in record[o]:
                    record[o].append(var)
    record = {n: vs for n, vs in record.items() if vs}
    # before any FMU runs: a run that would fill the memory is refused, not left to fail
    budget.check_simulate(n_steps, 1 + sum(len(vs) for vs in record.values()), len(names),
                          stop_time, step_size, backend)

    from driftfmu.simulations.cosim import cosimulate
    if backend == "native" and not feeds:
        from driftfmu.simulations.fastcosim import cosimulate_fast
        raw = cosimulate_fast(paths, connections, n_steps, step_size, start_values=per_fmu,
                              record=record, start_time=start_time)
    else:
        raw = cosimulate(paths, connections, n_steps, step_size, start_values=per_fmu,
                         record=record, start_time=start_time, inputs=feeds)

    keys = [(n, v) for n, vs in record.items() for v in vs]
    counts: Dict[str, int] = {}
    for _, v in keys:
        counts[v] = counts.get(v, 0) + 1
    fields = ["time"] + [v if counts[v] == 1 else "%s.%s" % (n, v) for n, v in keys]
    result = np.empty(n_steps, dtype=[(f, np.float64) for f in fields])
    result["time"] = raw["time"]
    for field, (n, v) in zip(fields[1:], keys):
        result[field] = raw["%s.%s" % (n, v)]
    return result


def run_gaussian(out: Optional[PathLike] = None, *, n: int = 2000, backend: str = "python",
                 fmu_dir: PathLike = "build/fmus",
                 progress: Optional[Callable[[int], None]] = None,
                 **parameters: float) -> Dict[str, Any]:
    """The letter's Sec. III simulation (Fig. 1): one Gaussian co-simulation, checked.

    Excitation (Gauss-Markov ``x_k = A x_{k-1} + B u_k + w_k``) -> Accelerometer
    (``z = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 + v``) -> DriftEstimator, one row per sample;
    every FMU output is checked against ``driftfmu.models`` run directly on the same seed.
    With ``a3 = a4 = B = 0`` (the defaults) this is the letter's model and gives its bits.

    Parameters
    ----------
    out : str or pathlib.Path, optional
        If given, ``results.csv``, ``summary.json`` and ``drift.png`` are written there (all
        or none), as ``driftfmu run gaussian --out`` does.
    n : int
        Number of samples.
    backend : {"python", "native"}
        Which FMUs run (the same results bit for bit).
    fmu_dir : str or pathlib.Path
        Where the FMUs are; missing ones are built there when it is new, empty or holds only
        driftfmu's FMUs (a folder with other files is refused).
    progress : callable, optional
        Called as the run goes with the number of samples done so far (the ``driftfmu``
        command draws its progress bar with it).
    **parameters : float
        The letter's names: ``a0, a1, a2, A, Q, R, seed, Ts, x0, P0`` (defaults: the letter's
        settings ``a1 = 1, a2 = 0.01, Q = 0.01, R = 1e-4, A = 0``, seed 1, ``Ts = 1 ms``;
        ``P0 = Q / (1 - A^2)``) and ``estimator`` (1, 2 or 3: whose drift ``z_comp``
        subtracts).  The general sensor (docs/method.md section 9), off by default:
        ``a3, a4`` (the sensor's cubic and quartic terms, also in the filter's model), ``B``
        (the input gain, in the Excitation and the filter; with ``B != 0`` the Excitation's
        known input ``u`` is wired to the DriftEstimator) and the known input ``u_k`` itself:
        ``drive`` (0 none, 1 Gaussian white ``N(0, Qu)``, 2 the sinusoid
        ``Xu sin(2 pi fu t)``), ``Qu``, ``Xu``, ``fu``.  The Accelerometer's slow errors
        (docs/method.md section 10), off by default: ``bias_on, random_walk, bias_gm, tau_gm,
        flicker, tau_min, tau_max, d_inf, E_tau, T0, kT_bias, kT_scale, range, bits`` and the
        start values of its inputs ``theta``, ``T`` (the chain leaves them unconnected).

    Returns
    -------
    dict
        ``"columns"``: the results table, column name -> list (``time``, ``x``, ``z``,
        ``x_hat``, ``P``, ``dc_ekf1..3``, ``z_comp`` and the three drift references
        ``dc_empirical``, ``dc_realised``, ``dc_expected``, which count the ``a3``, ``a4``
        terms); ``"summary"``: final drifts, the EKF1-EKF2 gap and from which sample each
        estimator stays within 10 % of the realised drift.

    Raises
    ------
    ValueError
        A parameter is out of range or of the wrong type, or ``n`` samples would not fit the
        memory (the message names it and what is allowed).
    TypeError
        A keyword the function does not take (the message names every one it takes).
    RuntimeError
        An FMU output differs from the models/ reference, or an FMU call failed.
    """
    from driftfmu.simulations import budget, checks, gaussian
    checks.check_keywords("run_gaussian()", parameters,
                          _allowed(run_gaussian, gaussian.run_gaussian,
                                   extra=tuple(gaussian.GENERAL_OFF)))
    checks.refuse(_settings_problems(
        dict(parameters, n=n, backend=backend, fmu_dir=fmu_dir, out=out, progress=progress),
        choices={"backend": BACKENDS, "estimator": (1, 2, 3)}, optional=("P0",)))
    _check_folders(out, fmu_dir)
    budget.check_run("gaussian", n, out, backend, api=True, announce=False)
    return gaussian.run_gaussian(out=out, n=n, backend=backend, fmu_dir=fmu_dir,
                                 plot=out is not None, progress=progress, **parameters)


def run_sinusoidal(out: Optional[PathLike] = None, *, n: int = 2000, backend: str = "python",
                   fmu_dir: PathLike = "build/fmus",
                   progress: Optional[Callable[[int], None]] = None,
                   **parameters: Any) -> Dict[str, Any]:
    """One co-simulation under a sinusoidal drive ``x_k = X sin(2 pi f t_k + phi)``.

    Parameters
    ----------
    out : str or pathlib.Path, optional
        If given, ``results.csv``, ``summary.json`` and ``drift.png`` are written there.
    n : int
        Number of samples.
    backend : {"python", "native"}
        Which FMUs run.
    fmu_dir : str or pathlib.Path
        Where the FMUs are; missing ones are built there when it is new, empty or holds only
        driftfmu's FMUs (a folder with other files is refused).
    progress : callable, optional
        Called as the run goes with the number of samples done so far.
    **parameters
        ``X, f, phi, Ts, seed, a0, a1, a2, R``, the filter's ``process`` (1 Gauss-Markov,
        2 harmonic at ``f``, the default), ``Qh, A, Q, P0, x0, estimator``,
        ``preset="adxl203"`` for the ADXL203 stand-in, ``sensor`` (a dict of further
        accelerometer parameters: ``a3``, ``a4``, ``cross``,
        ``fc``, ``Vs``, ``bits``, ``density``, ``axes``, or ``a0``, ``a1``, ``a2``, ``R``
        unlike the filter's; the filter keeps its 2nd-order model), ``Xy, phiy`` for a second axis
        (defaults: ``X = 1 g``, ``f = 150 Hz``, the letter's sensor).  The known input ``u``
        of eq. 1, off by default: the Excitation's ``drive, Qu, Xu, fu`` make ``u_k`` (it
        does not move the sinusoid) and ``B != 0`` (Gauss-Markov filter only, ``process=1``)
        is the filter's input gain, ``x-_k = A x+_{k-1} + B u_k``, with the Excitation's
        ``u`` wired to the DriftEstimator's; e.g. a shaker's commanded motion ``drive=2,
        Xu=X, fu=f`` with ``A=0, B=1``.

    Returns
    -------
    dict
        ``"columns"`` (the results table) and ``"summary"``, as
        [`run_gaussian`][driftfmu.run_gaussian].

    Raises
    ------
    ValueError
        A parameter is out of range or of the wrong type, e.g. ``f`` at or above the Nyquist
        rate ``1/(2 Ts)``, or ``n`` samples would not fit the memory.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    RuntimeError
        An FMU output differs from the models/ reference, or an FMU call failed.
    """
    from driftfmu.models import adxl203
    from driftfmu.simulations import budget, checks, sinusoidal
    checks.check_keywords("run_sinusoidal()", parameters,
                          _allowed(run_sinusoidal, sinusoidal.run_sinusoidal,
                                   extra=tuple(sinusoidal.INPUT_OFF)))
    problems = _settings_problems(
        dict(parameters, n=n, backend=backend, fmu_dir=fmu_dir, out=out, progress=progress),
        choices={"backend": BACKENDS, "estimator": (1, 2, 3),
                 "preset": tuple(sorted(adxl203.PRESETS))},
        optional=("Q", "P0", "Qh", "preset"))
    sensor = parameters.get("sensor")
    if sensor is not None:
        if not isinstance(sensor, Mapping):
            problems.append("sensor = %r is not a mapping; allowed: a dict of accelerometer "
                            "parameters (%s), or None" % (sensor, ", ".join(SENSOR_PARAMETERS)))
        else:
            unknown = [k for k in sensor if k not in SENSOR_PARAMETERS]
            if unknown:
                problems.append("sensor has %s; allowed: %s" % (
                    ", ".join(repr(k) for k in unknown), ", ".join(SENSOR_PARAMETERS)))
            else:
                problems += _settings_problems(sensor)
    checks.refuse(problems)
    _check_folders(out, fmu_dir)
    budget.check_run("sinusoidal", n, out, backend, api=True, announce=False)
    return sinusoidal.run_sinusoidal(out=out, n=n, backend=backend, fmu_dir=fmu_dir,
                                     plot=out is not None, progress=progress, **parameters)


#: What :func:`run_sinusoidal`'s ``sensor`` may set: the Accelerometer's model (over the
#: quadratic one the filter runs with, or over the preset).
SENSOR_PARAMETERS = ("a0", "a1", "a2", "a3", "a4", "R", "cross", "fc", "Vs", "bits", "density",
                     "axes")


def montecarlo(kind: str = "gaussian", runs: int = 1000, n: int = 1000,
               out: Optional[PathLike] = None, *, engine: str = "batch",
               progress: Optional[Callable[[int], None]] = None,
               **parameters: Any) -> Dict[str, Any]:
    """Fig. 1 over a population: ``runs`` whole trajectories of ``n`` samples.

    Run ``r`` uses FMU seed ``seed + r``; the batch engine gives the FMUs' results bit for bit.

    Parameters
    ----------
    kind : {"gaussian", "sinusoidal"}
        Gauss-Markov state, or a sinusoid with a random phase per run.
    runs, n : int
        Number of runs and of samples per run.
    out : str or pathlib.Path, optional
        If given, ``montecarlo.npz``, ``summary.json`` and the figure (``fig1.png``, or
        ``sine.png`` for ``"sinusoidal"``) are written there.
    engine : {"batch", "fmu"}
        The batch engine (runs on the leading axis of NumPy arrays, or the compiled kernel)
        or the FMUs.
    progress : callable, optional
        Called as the runs go with the number of runs done so far.
    **parameters
        The letter's names ``a0, a1, a2, A, Q, R, seed, Ts`` (for ``"gaussian"`` also
        ``P0``; for ``"sinusoidal"`` also ``X, f``, with the filter's ``Q`` defaulting to
        ``X^2 / 2``), ``summary_only`` (keep per-run summaries and the figure's first runs,
        not every trajectory) and the engine's options (``workers``, ``scheduler`` (a Dask
        address), ``client``, ``backend``, ``fmu_dir``).  The general sensor (docs/method.md
        section 9), off by default: for ``"gaussian"`` ``a3, a4, B, drive, Qu, Xu, fu`` as in
        [`run_gaussian`][driftfmu.run_gaussian]; for ``"sinusoidal"`` ``a3, a4`` (batch
        engine only).  The
        realised and expected drifts then count the ``a3``, ``a4`` terms.  The sensor's slow
        errors (docs/method.md section 10), off by default, for both kinds (the sinusoidal
        one on the batch engine): ``bias_on, random_walk, bias_gm, tau_gm, flicker, tau_min,
        tau_max`` (class 4), ``d_inf, E_tau`` (class 3), ``theta, T, T0, kT_bias, kT_scale``
        (class 2; the tilt and temperature held over the runs), ``range`` and ``bits``;
        the filter keeps the letter's model, so they are what it does not know.

    Returns
    -------
    dict
        The arrays of ``montecarlo.npz`` (each ``(runs, n)``) and ``"summary"``: the
        fractions of runs settled by sample 250 against the realised and the empirical
        drift, and the EKF1-EKF2 gap.

    Raises
    ------
    ValueError
        ``kind`` or a parameter is not allowed, or ``runs`` trajectories of ``n`` samples
        would not fit the memory (the message names the largest ``runs`` that fits, and
        ``summary_only``).
    TypeError
        A keyword the function does not take (the message names every one it takes).
    """
    _check_choice("kind", kind, ("gaussian", "sinusoidal"))
    from driftfmu.simulations import budget, checks
    from driftfmu.simulations import montecarlo as _mc
    if kind == "gaussian":
        fn, general = _mc.montecarlo_gaussian, tuple(_mc.GENERAL_OFF)
    else:
        fn, general = _mc.montecarlo_sinusoidal, _mc.SINE_GENERAL
    checks.check_keywords("montecarlo(%r)" % kind, parameters,
                          _allowed(montecarlo, fn, extra=general))
    checks.refuse(_settings_problems(
        dict(parameters, runs=runs, n=n, out=out, engine=engine, progress=progress),
        choices={"engine": ("batch", "fmu"), "backend": BACKENDS}, flags=("summary_only",),
        counts={"workers": 1}, optional=("P0", "Q", "client")))
    _check_folders(out, parameters.get("fmu_dir"))
    budget.check_montecarlo(kind, runs, n, parameters.get("workers"), out,
                            summary_only=parameters.get("summary_only", False), api=True,
                            announce=False, engine=engine,
                            backend=parameters.get("backend", "python"))
    return fn(runs=runs, n=n, out=out, engine=engine, plot=out is not None, progress=progress,
              **parameters)


def sweep(a2: Optional[Sequence[float]] = None, R: Optional[Sequence[float]] = None,
          runs: int = 1000, n: int = 1000, out: Optional[PathLike] = None, *,
          progress: Optional[Callable[[int], None]] = None, **parameters: Any) -> Dict[str, Any]:
    """Figs. 2-3: EKF1's and EKF3's mean error over a grid of ``a2`` and ``R``.

    Parameters
    ----------
    a2, R : sequence of float, optional
        The grid; defaults ``logspace(-3, -0.5, 6)`` and ``logspace(-6, -2, 5)`` (in a sweep
        over ``a4``, ``a2`` is one value, default 0.01).
    runs, n : int
        Monte-Carlo runs per grid point and samples per run.
    out : str or pathlib.Path, optional
        If given, ``sweep.npz``, ``sweep.csv``, ``fig2.png`` and ``fig3.png`` are written.
    progress : callable, optional
        Called as the grid goes with the number of runs done so far (over all grid points).
    **parameters
        ``a0, a1, Q, A, seed, Ts``, the engine's options (``engine``, ``workers``,
        ``scheduler`` (a Dask address), ``client``, ``chunk``, ``fmu_dir``) and the general
        sensor, off by default: ``a4``, one value for every grid point or several, which make
        the grid ``(a4, R)`` at one ``a2`` (Fig. 2 over ``a4``), and ``a3, B, drive, Qu, Xu,
        fu`` as in [`run_gaussian`][driftfmu.run_gaussian], shared by every grid point; the
        sensor's slow errors likewise (``bias_on, random_walk, bias_gm, tau_gm, flicker,
        tau_min, tau_max, d_inf, E_tau, theta, T, T0, kT_bias, kT_scale, range, bits``,
        docs/method.md section 10).

    Returns
    -------
    dict
        ``grid_a2`` (``grid_a4`` in a sweep over ``a4``), ``grid_R`` and the final values of
        each run, ``grid_dc1``, ``grid_dc2``, ``grid_dc3`` (EKF1-3), ``grid_zbar`` and
        ``grid_x2bar`` (the running means of ``z`` and ``x^2``; with the general sensor also
        ``grid_dc_realised``), each of shape ``(len(a2), len(R), runs)``; ``axis`` (``"a2"``
        or ``"a4"``); ``table``, the columns of ``sweep.csv`` (mean errors per grid point
        against the realised, empirical and expected drift); ``seconds``, the wall time of
        the runs.

    Raises
    ------
    ValueError
        A grid value or parameter is not allowed, or the grid's runs would not fit the memory.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    """
    from driftfmu.simulations import checks
    from driftfmu.simulations import sweep as _sweep
    checks.check_keywords("sweep()", parameters,
                          _allowed(sweep, _sweep.sweep, extra=tuple(_sweep.GENERAL_OFF)))
    checks.refuse(_settings_problems(
        dict({k: v for k, v in parameters.items() if k != "a4"}, runs=runs, n=n, out=out,
             progress=progress),
        choices={"engine": ("batch", "fmu")}, counts={"workers": 1, "chunk": 1},
        optional=("client", "chunk")))
    _check_folders(out, parameters.get("fmu_dir"))
    if a2 is not None:
        parameters["a2"] = a2
    if R is not None:
        parameters["R"] = R
    return _sweep.sweep(runs=runs, n=n, out=out, plot=out is not None, progress=progress,
                        **parameters)


def experiment_adxl203(out: Optional[PathLike] = None, *,
                       progress: Optional[Callable[[int], None]] = None,
                       **settings: Any) -> Dict[str, Any]:
    """The letter's Sec. IV (Figs. 4-5) on the ADXL203 stand-in, through the FMUs.

    Per drive frequency, ``sets`` recordings are co-simulated; one model (2nd order, the
    letter's, or with ``order`` 3 or 4 also ``a3``, ``a4``) is fitted on all but the last
    ``held_out`` sets, and EKF1 runs with it on those.

    Parameters
    ----------
    out : str or pathlib.Path, optional
        If given, ``adxl203.csv``, ``.json``, ``.npz``, ``fig4.png`` and ``fig5.png``.
    progress : callable, optional
        Called as the experiment goes with the number of sets done so far (of
        ``len(freqs) * sets``).
    **settings
        ``freqs`` (Hz, default 100..200 by 25), ``sets`` (30), ``held_out`` (a sixth of
        ``sets``, rounded, at least 1),
        ``n`` (60,000 samples per set), ``Ts``, ``seed``, ``workers``, ``backend``,
        ``fmu_dir`` and ``order`` (2, 3 or 4: the order of the model fitted and run by the
        filter; the stand-in has a cubic term).  The full size takes minutes; ``sets=6,
        n=6000`` about ten seconds.

    Returns
    -------
    dict
        The summary: ``"per_frequency"`` holds each frequency's fitted model, drift, rms
        difference of EKF1 and the margin in dB; ``"settings"`` (with ``"order"``),
        ``"claim_holds"``, ``"timing"``, ``"wall_time_s"``.

    Raises
    ------
    ValueError
        A setting is not allowed (e.g. more held-out sets than the fit can spare), or the
        sets' samples would not fit the memory.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    """
    from driftfmu.simulations import adxl203, budget, checks
    checks.check_keywords("experiment_adxl203()", settings,
                          _allowed(experiment_adxl203, adxl203.run_adxl203))
    problems = _settings_problems(
        dict({k: v for k, v in settings.items() if k != "freqs"}, out=out, progress=progress),
        counts={"sets": 1, "held_out": 1, "workers": 1},
        choices={"backend": BACKENDS, "order": adxl203.ORDERS})
    freqs = settings.get("freqs", adxl203.FREQS)
    if checks.is_number(freqs):
        freqs = (freqs,)  # one frequency
    elif isinstance(freqs, (str, bytes)) or not _is_sequence(freqs):
        problems.append("freqs = %r is not allowed; allowed: a sequence of %s"
                        % (freqs, checks.FREQS_ALLOWED))
        freqs = None
    if freqs is not None:
        freqs = list(freqs)
        problems.append(checks.freqs_problem(freqs))
    checks.refuse(problems)
    settings = dict(settings, freqs=[float(f) for f in freqs])
    sets = settings.get("sets", adxl203.SETS)
    settings.setdefault("held_out", adxl203.default_held_out(sets))
    n, Ts = settings.get("n", adxl203.N), settings.get("Ts", adxl203.TS)
    adxl203.check_settings(settings["freqs"], sets, settings["held_out"], n, Ts,
                           settings.get("order", 2))
    _check_folders(out, settings.get("fmu_dir"))
    budget.check_adxl203(settings["freqs"], sets, n, settings.get("workers"), out,
                         settings.get("backend", "python"), api=True, announce=False)
    return adxl203.run_adxl203(out=out, plot=out is not None, progress=progress, **settings)


def experiment_dual_axis(out: Optional[PathLike] = None, *,
                         progress: Optional[Callable[[int], None]] = None,
                         **settings: Any) -> Dict[str, Any]:
    """Drift from axis cross-correlation (the letter's conclusion): dual- vs single-axis EKF1.

    Parameters
    ----------
    out : str or pathlib.Path, optional
        If given, ``dual_axis.csv``, ``dual_axis.json`` and ``dual_axis.png``.
    progress : callable, optional
        Called as the sweeps go with the number of runs done so far (of
        ``2 * points * runs``).
    **settings
        ``points`` per sweep, ``runs``, ``engine`` (``"fmu"`` or ``"batch"``), ``seed``,
        ``backend``, ``workers``, ``scheduler``, ``fmu_dir`` and the model's settings
        (``n, Ts, f, X, Xy, phi, A, Q, Qy``, the sensor's ``a0 a1 a2 bx R a0y a1y a2y by Ry``
        and ``Qh``).

    Returns
    -------
    dict
        The summary (the content of ``dual_axis.json``): per sweep point and axis the
        single- and dual-axis errors, the cross-term drift and the checks.

    Raises
    ------
    ValueError
        A setting is not allowed, or the sweeps' runs would not fit the memory.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    """
    from driftfmu.simulations import budget, checks, dual_axis
    checks.check_keywords("experiment_dual_axis()", settings,
                          _allowed(experiment_dual_axis, dual_axis.run_dual_axis,
                                   extra=tuple(dual_axis.DEFAULTS)))
    checks.refuse(_settings_problems(
        dict(settings, out=out, progress=progress),
        counts={"points": 2, "workers": 1},
        choices={"engine": tuple(dual_axis.RUNS), "backend": BACKENDS}, optional=("runs",)))
    engine = settings.get("engine", "fmu")
    runs = settings.get("runs")
    runs = dual_axis.RUNS[engine] if runs is None else runs
    points = settings.get("points", dual_axis.POINTS)
    s = dict(dual_axis.DEFAULTS, **{k: v for k, v in settings.items()
                                    if k in dual_axis.DEFAULTS})
    dual_axis.check_settings(s, points, runs, engine)
    _check_folders(out, settings.get("fmu_dir"))
    budget.check_dual_axis(points, runs, s["n"], engine, settings.get("workers"), out,
                           settings.get("backend", "python"), api=True, announce=False)
    return dual_axis.run_dual_axis(out=out, plot=out is not None, progress=progress,
                                   **settings)


def experiment_drift_classes(out: Optional[PathLike] = None, *,
                             progress: Optional[Callable[[int], None]] = None,
                             **settings: Any) -> Dict[str, Any]:
    """The letter's four drift classes, each alone and then all together, estimated and removed
    by the DriftEstimator, through the FMUs.

    Cases: class 1 (``a2 E[x^2]``, EKF1); class 2 (a tilt ``theta`` and a temperature ``T``,
    wired to the DriftEstimator with the sensor's coefficients; then with the coefficients off
    by ``wrong``, without and with the bias state); class 3 (the exposure drift, the bias
    state); class 4 (turn-on bias, random walk, Gauss-Markov and flicker biases, the bias state
    with ``Qb = K^2 Ts`` summed over the processes); all together.  Per case and run, over the
    settled window: the true drift ``z - a0 - a1 x - sqrt(R) v``, the estimate ``dc + b_hat +
    dc_class2`` and the residual drift of ``z_comp``, against a bound of four standard
    deviations derived from the settings (docs/method.md, section 12).

    Parameters
    ----------
    out : str or pathlib.Path, optional
        If given, ``drift_classes.csv``, ``drift_classes.json`` and ``drift_classes.png`` (all
        of them or none).
    progress : callable, optional
        Called as the experiment goes with the number of runs done so far (of
        ``7 * runs``), then of the cases validated.
    **settings
        ``n`` (samples per run, default 40,000), ``runs`` (3), ``seed`` (1), ``settle`` (the
        share of each run before the settled window, 0.5), ``wrong`` (the class-2
        coefficients' error, 0.10), ``block`` (the figure's block length, 1000 samples),
        ``workers``, ``backend``, ``fmu_dir`` and the letter's ``a0 a1 a2 A Q R Ts``.

    Returns
    -------
    dict
        The summary (the content of ``drift_classes.json``): per case the drift, estimate,
        residual, bound and fractions, per run the drifts and residuals; the claims and the
        validation against models/.

    Raises
    ------
    ValueError
        A setting is not allowed, or the runs would not fit the memory.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    """
    from driftfmu.simulations import budget, checks, drift_classes
    checks.check_keywords("experiment_drift_classes()", settings,
                          _allowed(experiment_drift_classes, drift_classes.run_drift_classes,
                                   extra=tuple(drift_classes.DEFAULTS)
                                   + tuple(drift_classes.LETTER)))
    checks.refuse(_settings_problems(
        dict({k: v for k, v in settings.items() if k not in ("settle", "wrong")}, out=out,
             progress=progress),
        counts={"runs": 1, "workers": 1, "block": 1}, choices={"backend": BACKENDS}))
    s = dict(drift_classes.LETTER, **drift_classes.DEFAULTS)
    s.update({k: v for k, v in settings.items() if k in s})
    drift_classes.check_settings(s)
    _check_folders(out, settings.get("fmu_dir"))
    budget.check_drift_classes(s["runs"], s["n"], settings.get("workers"), out,
                               settings.get("backend", "python"), api=True, announce=False)
    return drift_classes.run_drift_classes(out=out, plot=out is not None, progress=progress,
                                           **settings)


@_keywords_checked
def identify(files: Sequence[PathLike], f: float, held_out: int = 0,
             out: Optional[PathLike] = None, *, order: int = 2) -> Dict[str, Any]:
    """Fit the sensor ``a0, a1, ..., a_order`` and ``R`` from recordings driven by a sinusoid
    at ``f``.

    Harmonic analysis over whole periods of the known drive, not a sample-by-sample
    regression (an output filter's delay would count as noise): harmonics ``0..order`` of the
    output give the coefficients of ``z = a0 + a1 x + ... + a_order x^order + v``.  EKF1
    (harmonic process model at ``f``, with the fitted ``a3``, ``a4``) then runs on the last
    ``held_out`` recordings (their ``z`` only).

    Parameters
    ----------
    files : str, pathlib.Path or sequence of them
        CSV recordings with a header row and the columns ``time, x, z`` (``x`` the known
        drive [g], ``z`` the sensor output [V]), uniformly sampled; one path is one recording
        (enough for a fit; the spread of the coefficients needs two or more).
    f : float
        Drive frequency [Hz].
    held_out : int
        How many of the last files are not fitted but run EKF1.
    out : str or pathlib.Path, optional
        If given, ``identify.json`` (and with ``held_out``, ``identify.csv``).
    order : {2, 3, 4}
        Order of the characteristic to fit.  Harmonic ``order`` of ``f`` must lie below the
        Nyquist rate ``1/(2 Ts)``: a higher order would alias and is refused.

    Returns
    -------
    dict
        ``"model"``: the fitted ``a0, a1, a2, R`` (and ``a3``, ``a4`` up to ``order``, then
        also ``"order"``) averaged over the fitted files, with their spread
        ``sd_a0 .. sd_R`` (None for one file) and ``sets``; ``"fits"``: one fit per file
        (the coefficients, ``R``, the drive's ``X``, ``phi``, ``lag``, ``samples``,
        ``periods``, ``order`` and ``se``, the closed-form standard errors of the
        coefficients); ``"order"``; ``"warnings"``: doubts about the fit; with ``held_out``,
        ``"held_out"`` (EKF1's drift against the empirical drift per file) and
        ``"margin_db"``.

    Raises
    ------
    ValueError
        The data cannot support the fit (fewer than 2 whole periods, a drive that is not a
        sinusoid at ``f``), or a setting is not allowed (an ``order`` other than 2, 3, 4,
        checked before any file is read; an order that aliases at the recordings' sample
        period), or the recordings would not fit the memory.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    """
    import os
    from driftfmu.models import identify as _identify
    from driftfmu.simulations import budget, checks
    from driftfmu.simulations.adxl203 import run_identify
    from driftfmu.simulations.errors import UsageError
    if isinstance(files, (str, os.PathLike)):
        files = [files]  # one recording
    elif not _is_sequence(files):
        raise UsageError("files = %r is not allowed; allowed: the path of a recording (str or "
                         "os.PathLike) or a sequence of them" % (files,))
    files = list(files)
    problems = [checks.path_problem("files[%d]" % i, p, optional=False, example="run1.csv")
                for i, p in enumerate(files)]
    if not files:
        problems.append("files = [] is empty; allowed: one or more recordings (CSV paths)")
    problems += _settings_problems(dict(f=f, held_out=held_out, order=order, out=out),
                                   counts={"held_out": 0}, choices={"order": _identify.ORDERS})
    checks.refuse(problems)
    _check_folders(out)
    files = [os.fspath(p) for p in files]
    budget.check_identify(files, out, api=True, announce=False)
    import warnings
    with warnings.catch_warnings(record=True) as caught:  # said at the caller's line,
        warnings.simplefilter("always")                   # not at one of driftfmu's own
        summary = run_identify(files, f, held_out=held_out, out=out, order=order)
    for w in caught:
        warnings.warn(w.message, w.category, stacklevel=3)
    return summary


#: The FMUs that output each signal ``allan`` can co-simulate, and the chain up to them.
_ALLAN_CHAINS = (("Excitation",), ("Excitation", "Accelerometer"),
                 ("Excitation", "Accelerometer", "DriftEstimator"))


def _allan_chain(column: str) -> tuple:
    """The shortest chain of :data:`_ALLAN_CHAINS` whose last FMU outputs ``column``, and the
    output's unit; the whole chain (``simulate`` then names what it has) when none does."""
    from driftfmu.fmu_src import documentation
    for chain in _ALLAN_CHAINS:
        for spec in documentation.slave_class(chain[-1]).VARIABLES:
            if spec["name"] == column and spec["causality"] == "output":
                return chain, spec.get("unit")
    return _ALLAN_CHAINS[-1], None


@_keywords_checked
def allan(source: Union[None, PathLike, "np.ndarray"] = None, column: str = "z", *,
          time: str = "time", taus: Union[str, Sequence[float]] = "octave",
          per_decade: Optional[int] = None, out: Optional[PathLike] = None,
          unit: Optional[str] = None, stop_time: Optional[float] = None,
          start_values: Optional[Mapping[str, float]] = None, backend: str = "python",
          fmu_dir: PathLike = "build/fmus",
          progress: Optional[Callable[[int], None]] = None) -> Dict[str, Any]:
    r"""The overlapping Allan deviation of one signal, and its IEEE Std 952 reading.

    For ``n`` samples ``y_1 .. y_n`` at the sample period ``Ts``, the running sum ``S_0 = 0``,
    ``S_k = y_1 + .. + y_k``, and the averaging time ``tau = m Ts`` (``1 <= m <= n / 2``, at
    least two clusters of ``m`` samples):

    .. math::

        \sigma^2(\tau) = \frac{1}{2 m^2 (n - 2m + 1)}
            \sum_{i=0}^{n-2m} \left(S_{i+2m} - 2 S_{i+m} + S_i\right)^2

    (NIST SP 1065, eq. 11; equal to ``allantools.oadev`` to rounding).  Its confidence: the
    equivalent degrees of freedom ``nu`` (the smaller of NIST SP 1065's for white noise and
    for random walk; flicker noise's lies between) and the 68.3 % chi-square interval.  The
    reading, on the octave grid ``m = 1, 2, 4, ..`` (so the figures do not depend on
    ``taus``), from the ``tau`` whose estimate and neighbours have at least 100 EDF:

    - ``N`` (white noise, ``sigma = N / sqrt(tau)``): the line of slope -1/2 fitted on the
      first two or more consecutive octaves whose local slope is within 0.15 of -1/2, read
      at ``tau = 1 s``;
    - ``K`` (random walk, ``sigma = K sqrt(tau / 3)``): the line of slope +1/2 on the last
      such run near +1/2, read at ``tau = 3 s``;
    - ``B`` (bias instability): the flat line through the lowest point, when its local slope
      is within 0.15 of 0, divided by ``sqrt(2 ln 2 / pi) = 0.664``.

    A figure whose region the data do not show is not resolved: its ``value`` is None and
    its ``reason`` says why; no number is made up.

    Parameters
    ----------
    source : str, pathlib.Path, numpy.ndarray or None
        None: co-simulate the chain with ``driftfmu.simulate`` (Excitation -> Accelerometer,
        and the DriftEstimator for its outputs), ``start_values`` and ``stop_time``, one row
        per sample.  A path: a CSV file with a header row, the column ``time`` and the column
        ``column``.  A structured array with the fields ``time`` and ``column`` (as
        [`simulate`][driftfmu.simulate] returns).
    column : str
        The signal: an output of the chain (``"z"``, ``"z_comp"``, ``"x"``, ``"dc_ekf1"``,
        ...) or a column of the file or array.
    time : str
        The time column [s] of a file or array: strictly increasing, uniform (every step within
        1e-6 of their mean).
    taus : {"octave", "all"} or sequence of float
        The table's ``tau``: ``m = 1, 2, 4, ..`` (default), every ``m`` (``n / 2`` of them,
        each O(n)), or these ``tau`` [s], each a multiple ``m Ts`` with ``1 <= m <= n / 2``.
    per_decade : int, optional
        About this many ``tau`` per decade (``m = 10^(j / per_decade)`` rounded) instead of
        ``taus``.
    out : str or pathlib.Path, optional
        If given, ``allan.csv`` (the table), ``allan.json`` (the reading and the settings)
        and ``allan.png`` (the figure) are written there, all or none.
    unit : str, optional
        The signal's unit for the figures and labels (default: the FMU variable's unit, or
        ``"unit"`` for a file or array).
    stop_time : float, optional
        Length [s] of the co-simulation (default 100 s: 100,000 samples at ``Ts = 1 ms``).
    start_values : dict of str to float, optional
        The co-simulation's parameters, as [`simulate`][driftfmu.simulate] takes them (e.g.
        ``{"Q": 0.0, "R": 1e-6}``: the sensor at rest, its noise alone).
    backend : {"python", "native"}
        Which FMUs co-simulate (the same results bit for bit).
    fmu_dir : str or pathlib.Path
        Where the FMUs are; missing ones are built.
    progress : callable, optional
        Called as the table goes with the number of ``tau`` done.

    Returns
    -------
    dict
        The table, lists ``tau`` [s], ``m``, ``adev``, ``low``, ``high`` (the 68.3 %
        interval), ``terms`` (differences averaged, ``n - 2m + 1``), ``edf``; the figures
        ``N`` [unit sqrt(s), i.e. unit/sqrt(Hz)], ``B`` [unit] and ``K`` [unit/sqrt(s)], each
        a dict with ``value`` (None when not resolved), ``low``, ``high``, ``tau_from``,
        ``tau_to`` (the fitted region), ``points``, ``read_at`` (N, K) or ``floor`` (B) and
        ``reason``; ``reading`` (the octave grid it came from: ``tau``, ``adev``, ``edf``,
        ``slope``, ``read``); ``column``, ``unit``, ``Ts``, ``samples``, ``source``.

    Raises
    ------
    ValueError
        A setting is not allowed, or the signal cannot be analysed (one line naming what and
        what is allowed): a file without the column, a value that is not a finite number,
        time not strictly increasing or not uniform, fewer than two samples, a ``tau`` that
        is not a multiple of ``Ts`` within two clusters; ``start_values`` or ``stop_time``
        with a file or array.
    TypeError
        A keyword the function does not take (the message names every one it takes).
    RuntimeError
        An FMU call failed.

    Examples
    --------
    >>> import driftfmu
    >>> r = driftfmu.allan(column="z", stop_time=5.0, start_values={"Q": 0.0, "R": 1e-6})
    >>> print("N = %.3g V/sqrt(Hz)" % r["N"]["value"])  # sqrt(R Ts) = 3.16e-05
    N = ... V/sqrt(Hz)
    >>> print(r["K"]["value"], "-", r["K"]["reason"])
    None - no 2 consecutive tau with a local slope within 0.15 of +0.5 (and at least 100 EDF)
    """
    import math
    import os

    from driftfmu.simulations import allan as _allan
    from driftfmu.simulations import checks
    from driftfmu.simulations.cli import start_phase
    from driftfmu.simulations.errors import UsageError
    problems = []
    for name, value in (("column", column), ("time", time)):
        if not isinstance(value, str) or not value.strip():
            problems.append("%s = %r is not allowed; allowed: a column name, e.g. 'z'"
                            % (name, value))
    if unit is not None and not isinstance(unit, str):
        problems.append("unit = %r is not allowed; allowed: text, e.g. 'V', or None" % (unit,))
    problems.append(_allan.taus_problem(taus))
    if per_decade is not None:
        problems.append(checks.count_problem("per_decade", per_decade, 1))
        if taus != "octave":
            problems.append("per_decade = %r with taus = %r; allowed: one of them"
                            % (per_decade, taus))
    if stop_time is not None and not (checks.is_number(stop_time) and math.isfinite(stop_time)
                                      and stop_time > 0):
        problems.append("stop_time = %r is not allowed; allowed: a finite number > 0"
                        % (stop_time,))
    problems += _settings_problems(dict(out=out, progress=progress, fmu_dir=fmu_dir,
                                        backend=backend), choices={"backend": BACKENDS})
    simulation = source is None
    if not simulation and (start_values is not None or stop_time is not None):
        problems.append("start_values and stop_time are for a co-simulation (source = None); "
                        "allowed: neither with a file or an array")
    path = isinstance(source, (str, os.PathLike))
    if not (simulation or path or hasattr(source, "dtype")):
        problems.append("source = %r is not allowed; allowed: None (a co-simulation), the "
                        "path of a CSV file, or a structured array with a time field"
                        % (source,))
    if path:
        problems.append(checks.path_problem("source", source, optional=False,
                                            example="recording.csv"))
    checks.refuse(problems)
    _check_folders(out, fmu_dir if simulation else None)
    if simulation:
        chain, fmu_unit = _allan_chain(column)
        data = simulate(list(chain), stop_time=_allan.STOP_TIME if stop_time is None
                        else stop_time, start_values=start_values, output=[column],
                        backend=backend, fmu_dir=fmu_dir)
        y, Ts = _allan.from_array(data, column, "time")
        what = "a co-simulation of %s (%s FMUs, %s)" % (
            " -> ".join(chain), backend, ", ".join("%s = %r" % kv for kv in sorted(
                (start_values or {}).items())) or "default start values")
        unit = fmu_unit if unit is None else unit
    elif path:
        from driftfmu.simulations import budget
        budget.check_allan(source, out, api=True)
        y, Ts = _allan.from_csv(source, column, time)
        what = str(os.fspath(source))
    else:
        y, Ts = _allan.from_array(source, column, time)
        what = "an array"
    ms = _allan.cluster_sizes(len(y), Ts, taus, per_decade)
    start_phase(progress, "allan deviation", len(ms), "tau")
    result = _allan.analyse(y, Ts, ms, progress=progress)
    result.update(column=column, unit=unit, Ts=Ts, samples=len(y), source=what,
                  taus=taus if isinstance(taus, str) else [float(t) for t in taus],
                  per_decade=per_decade)
    if out is not None:
        _allan.write(out, result, "Allan deviation of %s: %d samples at Ts = %.6g s, from %s"
                     % (column, len(y), Ts, what))
    return result


__all__ = ["build_fmus", "simulate", "run_gaussian", "run_sinusoidal", "montecarlo", "sweep",
           "experiment_adxl203", "experiment_dual_axis", "identify", "allan"]
