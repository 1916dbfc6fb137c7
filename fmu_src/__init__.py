"""Internal (not a stable API; use driftfmu.build_fmus instead).

pythonfmu slave classes (one per file) and the FMU builder.

Each slave is a thin adapter over :mod:`driftfmu.models`: it reads inputs, calls one models/ function and
stores outputs.  The FMI plumbing they share lives once in :mod:`driftfmu.fmu_src.slave_base`.
"""
