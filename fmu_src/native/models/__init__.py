"""Internal (not a stable API; use driftfmu.build_fmus instead).

The C port of models/ and of the slaves' per-sample logic (see ../README.md)."""
