"""Internal (not a stable API; use the driftfmu command instead).

``python -m driftfmu``: the ``driftfmu`` command."""
import sys

from driftfmu.simulations.cli import main

if __name__ == "__main__":
    sys.exit(main())
