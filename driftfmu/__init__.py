"""driftfmu: EKF drift estimation for weakly nonlinear sensors, as FMI co-simulation FMUs.

Chorti, Karatzas, White and Harris, "Use of the EKF for State Dependent Drift Estimation in
Weakly Nonlinear Sensors", Sensor Letters 4(4):377-379, 2006.

Subpackages: ``driftfmu.models`` (the math, once), ``driftfmu.fmu_src`` (the pythonfmu
slaves and the FMU builder) and ``driftfmu.simulations`` (fmpy masters, experiments and the
``driftfmu`` command).  In the source tree they are the top-level folders ``models/``,
``fmu_src/`` and ``simulations/``; an installed distribution has them under ``driftfmu/``.
"""
import os as _os

#: The one place the version is written: pyproject.toml, the FMUs' model descriptions and the
#: cross-check folders read it from here.
__version__ = "0.1.0"

# Run from a source checkout that is not installed (or installed editable), the subpackages are
# the checkout's top-level folders beside this one: look for them there too.
_checkout = _os.path.dirname(_os.path.dirname(_os.path.abspath(__file__)))
if not _os.path.isdir(_os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "models")) \
        and _os.path.isfile(_os.path.join(_checkout, "models", "__init__.py")) \
        and _os.path.isfile(_os.path.join(_checkout, "pyproject.toml")):
    __path__.append(_checkout)  # noqa: F821 (a package's __path__)
del _os, _checkout

# The public API (FMPy-style): build the FMUs, co-simulate them, run the letter's experiments.
# Everything else in the package is internal.
from driftfmu._api import (  # noqa: E402
    allan, build_fmus, experiment_adxl203, experiment_drift_classes, experiment_dual_axis,
    identify, montecarlo, run_gaussian,
    run_sinusoidal, simulate, sweep)

__all__ = ["build_fmus", "simulate", "run_gaussian", "run_sinusoidal", "montecarlo", "sweep",
           "experiment_adxl203", "experiment_dual_axis",
           "experiment_drift_classes", "identify", "allan", "__version__"]
