"""The C port of models/ and of the slaves' per-sample logic (see ../README.md)."""
