"""Internal (not a stable API; use driftfmu.build_fmus instead).

The native (C) twins of the FMUs: their sources, packed into every native FMU."""
