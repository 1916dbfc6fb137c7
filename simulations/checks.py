"""Internal (not a stable API; use the driftfmu command or the functions of driftfmu instead).

The checks of one setting that the command line and the Python API share, so that both refuse
the same value with the same line: a model parameter, a count, a choice, a drive frequency,
a flag, a path, a callback, a scheduler address, and the keywords a function takes.

Each ``*_problem`` function returns why a value is not allowed (one line: the value and the
whole set of what is allowed), or None.  The command line gives them the value it parsed from
its text (or the text itself when it does not parse); :func:`option` makes such a check an
argparse type.  :func:`refuse` raises the problems found as one :class:`UsageError`.
"""
import difflib
import math
import numbers
import os

from driftfmu.models import parameters
from driftfmu.simulations.errors import UnknownKeywordError, UsageError


def is_number(value):
    """True for an int or a float (NumPy's too); False for bool, text and everything else."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_integer(value):
    """True for an int (NumPy's too); False for bool, a float such as 2.0, and the rest."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def refuse(problems):
    """Raise the problems found (None entries are skipped) as one UsageError, one line."""
    problems = [p for p in problems if p]
    if problems:
        raise UsageError("; ".join(problems))


def number_problem(name, value):
    """:func:`driftfmu.models.parameters.problem`, with an integer parameter's value an integer:
    ``n=2.0`` is refused as ``--n 2.0`` is (and ``seed=True`` as ``--seed True``)."""
    p = parameters.PARAMETERS[name]
    if isinstance(p.default, int) and not isinstance(p.default, bool) and is_number(value) \
            and not is_integer(value):
        return "%s = %r is not an integer; allowed: %s" % (name, value, parameters.allowed(name))
    return parameters.problem(name, value)


def count_problem(name, value, low):
    """Why ``value`` is not an integer ``>= low``; a model parameter (``n``, ``runs``,
    ``seed``) by its own rule (:func:`number_problem`)."""
    if name in parameters.PARAMETERS:
        return number_problem(name, value)
    if not is_integer(value):
        return "%s = %r is not an integer; allowed: an integer %s >= %d" % (name, value, name,
                                                                           low)
    if value < low:
        return "%s = %r is out of range; allowed: an integer %s >= %d" % (name, value, name,
                                                                          low)
    return None


def choice_problem(name, value, allowed):
    """Why ``value`` is not one of ``allowed`` (of the same kind: ``True`` is not ``1``, ``2.0``
    is not ``2``), naming them all."""
    def same(a):
        if isinstance(a, str):
            return isinstance(value, str) and value == a
        return is_integer(value) and value == a
    if any(same(a) for a in allowed):
        return None
    words = [a for a in allowed if isinstance(a, str)]
    close = difflib.get_close_matches(value, words, n=1) if isinstance(value, str) else []
    return "%s = %r is not allowed%s; allowed: %s" % (
        name, value, " (did you mean %r?)" % close[0] if close else "",
        ", ".join(repr(a) for a in allowed))


#: What a drive frequency may be (the upper bound, the Nyquist rate, depends on the sample
#: period and is checked by the run before it starts).
FREQUENCY_ALLOWED = "0 < f < 1/(2 Ts), the Nyquist rate"


def frequency_problem(value, name="f"):
    """Why ``value`` is not a drive frequency: a finite number > 0 [Hz]."""
    if not is_number(value):
        return "%s = %r is not a number; allowed: %s" % (name, value, FREQUENCY_ALLOWED)
    if not (math.isfinite(value) and value > 0):
        return "%s = %r is out of range; allowed: %s" % (name, value, FREQUENCY_ALLOWED)
    return None


#: What ``freqs`` may be.
FREQS_ALLOWED = ("frequencies f [Hz] with %s, e.g. 100,125,150" % FREQUENCY_ALLOWED)


def freqs_problem(values):
    """Why ``values`` (a sequence) are not drive frequencies: empty, or the first that is not a
    number or not > 0."""
    if not len(values):
        return "freqs is empty; allowed: one or more %s" % FREQS_ALLOWED
    for v in values:
        if not is_number(v):
            return "freqs has %r, which is not a number; allowed: %s" % (v, FREQS_ALLOWED)
        if not (math.isfinite(v) and v > 0):
            return "freqs has %r, which is out of range; allowed: %s" % (v, FREQS_ALLOWED)
    return None


def flag_problem(name, value):
    """Why ``value`` is not ``True`` or ``False``."""
    import numpy as np
    if isinstance(value, (bool, np.bool_)):
        return None
    return "%s = %r is not allowed; allowed: True or False" % (name, value)


def callback_problem(name, value):
    """Why ``value`` is not a function to call (or None)."""
    if value is None or callable(value):
        return None
    return "%s = %r is not callable; allowed: a function, or None" % (name, value)


def path_problem(name, value, optional=True, example="results/run1"):
    """Why ``value`` is not a path (a str or os.PathLike, not empty), or None when it may be
    None and is."""
    if value is None and optional:
        return None
    if not isinstance(value, (str, os.PathLike)):
        return "%s = %r is not a path; allowed: a str or os.PathLike%s, e.g. %r" % (
            name, value, ", or None" if optional else "", example)
    if not str(os.fspath(value)).strip():
        return "%s = %r is empty; allowed: a folder path, e.g. %r" % (name, value, example)
    return None


#: What a scheduler address may be.
SCHEDULER_ALLOWED = ("the address of a Dask scheduler, [tcp:// | tls:// | ws:// | wss:// | "
                     "ucx://]HOST:PORT (e.g. tcp://127.0.0.1:8786) or inproc://NAME")
#: How to get what a scheduler needs.
DASK_EXTRA = "pip install 'driftfmu[dask]'"


def scheduler_problem(value):
    """Why ``value`` is not the address of a Dask scheduler, by its form first (the same line
    with or without Dask; whether something answers there is the run's to find out), then
    that Dask is installed."""
    import importlib.util
    import re
    if value is None:
        return None
    if not isinstance(value, str):
        return "scheduler = %r is not allowed; allowed: %s" % (value, SCHEDULER_ALLOWED)
    text = value.strip()
    m = re.fullmatch(r"(?:(tcp|tls|ws|wss|ucx)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):"
                     r"(\d{1,5})", text)
    inproc = text.startswith("inproc://") and len(text) > len("inproc://")
    if not inproc and (m is None or not 0 < int(m.group(3)) < 65536):
        return "scheduler = %r is not allowed; allowed: %s" % (value, SCHEDULER_ALLOWED)
    if importlib.util.find_spec("distributed") is None:
        return ("scheduler = %r needs Dask, which is not installed; install the extra: %s"
                % (value, DASK_EXTRA))
    return None


def check_keywords(call, given, allowed):
    """UnknownKeywordError unless every name of ``given`` is in ``allowed``; the line names the
    function as called (``call``, e.g. ``"run_gaussian()"``), the closest allowed name, and
    every allowed one."""
    unknown = [k for k in given if k not in allowed]
    if not unknown:
        return
    close = difflib.get_close_matches(unknown[0], list(allowed), n=1)
    raise UnknownKeywordError("%s got an unexpected keyword argument%s %s%s; allowed: %s" % (
        call, "s" if len(unknown) > 1 else "", ", ".join(repr(k) for k in unknown),
        " (did you mean %r?)" % close[0] if close else "", ", ".join(allowed)))


def keywords_of(function, extra=()):
    """The names ``function`` takes as keywords (not its ``**`` catch-all), then ``extra``:
    what it passes on from the catch-all."""
    import inspect
    names = [n for n, p in inspect.signature(function).parameters.items()
             if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    return tuple(names) + tuple(n for n in extra if n not in names)


def option(name, problem, parse=None):
    """An argparse type over a check: ``parse(text)`` (the text itself when it raises
    ValueError), then ``problem(value)``; its line is the option's error."""
    def convert(text):
        import argparse
        value = text
        if parse is not None:
            try:
                value = parse(text)
            except ValueError:
                value = text
        msg = problem(value)
        if msg:
            raise argparse.ArgumentTypeError(msg)
        return value
    convert.__name__ = name
    return convert


def count_option(name, low):
    """argparse type of a count: an integer ``>= low`` (:func:`count_problem`)."""
    return option(name, lambda v: count_problem(name, v, low), int)


def choice_option(name, allowed):
    """argparse type of a choice (:func:`choice_problem`; integers parsed as such)."""
    integers = all(is_integer(a) for a in allowed)
    return option(name, lambda v: choice_problem(name, v, allowed), int if integers else None)
