"""The native FMUs in a C-style master loop through fmpy's low-level API.

No helper of driftfmu runs the FMUs here: fmpy's ``FMU2Slave`` wraps the FMI 2.0 C functions
one to one (``fmi2Instantiate``, ``fmi2SetReal``, ``fmi2DoStep``, ...), so this loop is what a C
host does.  The native FMUs need no Python inside; any FMI 2.0 host can run them.
"""
import shutil
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

import driftfmu


def run_c_style_loop(show_plot=True, fmu_dir="build/fmus", n=1000, seed=1):
    """Excitation -> Accelerometer -> DriftEstimator (native, FMI 2.0), ``n`` samples.

    Returns a structured array with the fields ``time``, ``x``, ``z``, ``dc_ekf1``.
    """
    names = ["Excitation", "Accelerometer", "DriftEstimator"]
    paths = {n: Path(fmu_dir) / "native" / "fmi2" / ("%s.fmu" % n) for n in names}
    if not all(p.is_file() for p in paths.values()):
        paths = driftfmu.build_fmus(fmu_dir, backend="native", fmi_version=2, names=names)
    Ts = 1e-3
    start = {"Excitation": {"seed": seed}, "Accelerometer": {"seed": seed},
             "DriftEstimator": {}}
    fmus, vrs, folders = {}, {}, []
    try:
        for name, path in paths.items():
            md = read_model_description(str(path))
            folders.append(extract(str(path)))
            vrs[name] = {v.name: v.valueReference for v in md.modelVariables}
            fmu = FMU2Slave(guid=md.guid, unzipDirectory=folders[-1],
                            modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
            fmu.instantiate()
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            for var, value in start[name].items():  # seed is an Integer
                fmu.setInteger([vrs[name][var]], [value])
            fmu.exitInitializationMode()
            fmus[name] = fmu

        exc, acc, est = fmus["Excitation"], fmus["Accelerometer"], fmus["DriftEstimator"]
        out = np.zeros(n, dtype=[("time", float), ("x", float), ("z", float),
                                 ("dc_ekf1", float)])
        t = 0.0
        for k in range(n):
            if k:  # step every FMU from t to t + Ts, then copy along the connections
                for fmu in fmus.values():
                    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=Ts)
                t = k * Ts
            x = exc.getReal([vrs["Excitation"]["x"]])[0]
            acc.setReal([vrs["Accelerometer"]["x"]], [x])
            z = acc.getReal([vrs["Accelerometer"]["z"]])[0]
            est.setReal([vrs["DriftEstimator"]["z"]], [z])
            out[k] = (t, x, z, est.getReal([vrs["DriftEstimator"]["dc_ekf1"]])[0])
    finally:
        for fmu in fmus.values():
            fmu.terminate()
            fmu.freeInstance()
        for folder in folders:
            shutil.rmtree(folder, ignore_errors=True)

    if show_plot:
        import matplotlib.pyplot as plt
        plt.plot(out["time"], out["dc_ekf1"], label="EKF1 drift (native FMU)")
        plt.xlabel("time [s]")
        plt.legend()
        plt.show()
    return out


if __name__ == "__main__":
    run_c_style_loop()
