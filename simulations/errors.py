"""Internal (not a stable API; use the ValueError that driftfmu's functions raise instead).

The exceptions the ``driftfmu`` command maps to its exit statuses.

- :class:`UsageError`: a setting the command cannot run with (an option out of range, a drive
  frequency at or above the Nyquist rate, more held-out sets than sets); exit status 2, like an
  option argparse refuses.  Raised before any work starts.
  :class:`UnknownKeywordError`, a keyword a function does not take, is one too.
  :class:`FileProblem`, a file someone else could have made (an FMU, an SSP, a result CSV)
  that is not what driftfmu relies on, is one too: the message names the file, the part and
  what is expected.
- :class:`DataError`: input data that cannot support the result asked for (a recording too short
  for the fit, a drive frequency the recording contradicts); exit status 1, a failed run.
- Any other exception is a failed run (exit status 1); Ctrl-C is exit status 130.

Both are ``ValueError`` subclasses, so code that catches ValueError keeps working.
"""


class UsageError(ValueError):
    """A setting is not allowed (exit status 2); the message names it and what is allowed."""


class UnknownKeywordError(UsageError, TypeError):
    """A keyword argument a function of driftfmu does not take; the message names the function
    as it was called and every keyword it takes.  A ``TypeError`` as Python's own for an
    unexpected keyword, and a ``ValueError`` (a :class:`UsageError`) as driftfmu's other
    refused settings."""


class FileProblem(UsageError):
    """A file that is not what driftfmu relies on (exit status 2), found before driftfmu relies
    on it: the message names the file, the part of it and what is expected."""


class DataError(ValueError):
    """The data cannot support the fit or reference asked for (exit status 1)."""


#: Exit statuses of the ``driftfmu`` command.
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
