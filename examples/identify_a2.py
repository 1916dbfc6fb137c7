"""Estimate the sensor's a2 (and a0, a1, R) from recordings with ``driftfmu.identify``.

Three recordings of a sinusoidally driven sensor are made with the FMUs (in practice they
come from a shaker and a reference accelerometer), written as CSV files with the columns
``time, x, z``, and fitted by harmonic analysis; EKF1 then runs on a held-out recording.
"""
import csv
import tempfile
from pathlib import Path

import driftfmu

#: The sensor the recordings are made with: what the fit should find.
TRUE = {"a0": 0.02, "a1": 0.98, "a2": 0.015, "R": 1e-4}


def record(path, seed, fmu_dir="build/fmus", f=150.0, stop_time=2.0):
    """One recording: the Excitation (sinusoid at ``f``) -> Accelerometer chain, as CSV."""
    result = driftfmu.simulate(["Excitation", "Accelerometer"], stop_time=stop_time,
                               start_values=dict(TRUE, kind=2, X=1.0, f=f, phi=0.3 * seed,
                                                 seed=seed),
                               output=["x", "z"], fmu_dir=fmu_dir)
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["time", "x", "z"])
        writer.writerows((repr(float(r["time"])), repr(float(r["x"])), repr(float(r["z"])))
                        for r in result)
    return path


def identify_a2(show_plot=True, fmu_dir="build/fmus", folder=None):
    """Record three sets, fit on two, run EKF1 on the third; return the identify summary."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(folder or tmp)
        files = [record(folder / ("rec%d.csv" % s), s, fmu_dir) for s in (1, 2, 3)]
        summary = driftfmu.identify(files, f=150.0, held_out=1)
    model = summary["model"]
    print("a2 = %.5f (true %.5f), a1 = %.4f, a0 = %.4f, R = %.2e; EKF1 margin %.1f dB"
          % (model["a2"], TRUE["a2"], model["a1"], model["a0"], model["R"],
             summary["margin_db"]))
    if show_plot:
        import matplotlib.pyplot as plt
        plt.bar(["fit %d" % (i + 1) for i in range(len(summary["fits"]))],
                [fi["a2"] for fi in summary["fits"]])
        plt.axhline(TRUE["a2"], color="k", linestyle="--", label="true a2")
        plt.legend()
        plt.show()
    return summary


if __name__ == "__main__":
    identify_a2()
