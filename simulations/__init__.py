"""Internal (not a stable API; use the functions of driftfmu instead).

fmpy master scripts and experiments around the driftfmu FMUs.

Each experiment is a function that returns its results (and writes files only when given an
output folder), so tests import and check it; :mod:`driftfmu.simulations.cli` is the ``driftfmu`` command.
"""
