"""Internal (not a stable API; use the driftfmu command instead).

``python -m driftfmu``: the ``driftfmu`` command."""
from driftfmu.simulations.cli import run_program

if __name__ == "__main__":
    run_program()
