"""The chain with a custom excitation from a NumPy array.

The Excitation FMU is left out: the true acceleration ``x`` comes from an array (here two
sinusoids and a slow ramp), is held between its rows, drives the Accelerometer FMU, and the
DriftEstimator FMU estimates the state-dependent drift ``a2 E[x^2]``.
"""
import numpy as np

import driftfmu


def simulate_custom_input(show_plot=True, fmu_dir="build/fmus", backend="python"):
    """Co-simulate Accelerometer -> DriftEstimator on an acceleration given as an array.

    Returns the structured result array of :func:`driftfmu.simulate` (``time`` first).
    """
    Ts = 1e-3
    t = np.arange(4000) * Ts
    x = 0.6 * np.sin(2 * np.pi * 7.0 * t) + 0.3 * np.sin(2 * np.pi * 31.0 * t) + 0.05 * t
    signal = np.zeros(t.size, dtype=[("time", np.float64), ("x", np.float64)])
    signal["time"], signal["x"] = t, x

    # the filter's process model: a Gauss-Markov state of the signal's variance
    Q = float(np.var(x))
    result = driftfmu.simulate(["Accelerometer", "DriftEstimator"], stop_time=t[-1],
                               step_size=Ts, input=signal,
                               start_values={"a2": 0.02, "R": 1e-4, "seed": 4, "Q": Q,
                                             "P0": Q, "Ts": Ts},
                               output=["z", "x_hat", "dc_ekf1", "z_comp"],
                               fmu_dir=fmu_dir, backend=backend)

    if show_plot:
        import matplotlib.pyplot as plt
        realised = 0.02 * np.cumsum(x ** 2) / np.arange(1, x.size + 1)
        fig, ax = plt.subplots(2, 1, sharex=True)
        ax[0].plot(result["time"], result["z"], label="z")
        ax[0].plot(t, x, label="x (input)")
        ax[0].legend()
        ax[1].plot(result["time"], result["dc_ekf1"], label="EKF1 drift")
        ax[1].plot(t, realised, "--", label="a2 mean(x^2)")
        ax[1].set_xlabel("time [s]")
        ax[1].legend()
        plt.show()
    return result


if __name__ == "__main__":
    simulate_custom_input()
