"""The letter's Figs. 2-3 sweep on a Dask cluster (here a local one).

``driftfmu.sweep`` sends chunks of Monte-Carlo runs to the cluster's workers; with a real
cluster pass ``scheduler="tcp://host:8786"`` instead of a client.  Run ``r`` uses seed
``seed + r`` wherever it runs, so the result does not depend on the cluster.
"""
import numpy as np

import driftfmu


def dask_sweep(show_plot=True, runs=200, n=500, a2=(1e-3, 1e-2, 1e-1), R=(1e-6, 1e-4, 1e-2)):
    """Sweep EKF1's and EKF3's error over ``a2`` x ``R`` on a local Dask cluster.

    Returns the result of :func:`driftfmu.sweep` (``grid_dc1`` etc., shape
    ``(len(a2), len(R), runs)``).
    """
    import tempfile

    import dask
    from dask.distributed import Client, LocalCluster

    # the cluster's scratch folder goes with it (by default Dask keeps dask-scratch-space in
    # the temporary folder for good)
    with tempfile.TemporaryDirectory(prefix="dask-") as scratch, \
            dask.config.set({"temporary-directory": scratch}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                         dashboard_address=None) as cluster, Client(cluster) as client:
        result = driftfmu.sweep(a2=list(a2), R=list(R), runs=runs, n=n, client=client)

    # EKF1's mean error against the realised drift a2 mean(x^2), per grid point
    realised = result["grid_a2"][:, None, None] * result["grid_x2bar"]
    error = np.abs(result["grid_dc1"] - realised).mean(axis=2)
    if show_plot:
        import matplotlib.pyplot as plt
        for i, v in enumerate(result["grid_a2"]):
            plt.loglog(result["grid_R"], error[i], "o-", label="a2 = %g" % v)
        plt.xlabel("R [V^2]")
        plt.ylabel("mean |EKF1 - realised drift| [V]")
        plt.legend()
        plt.show()
    result["ekf1_error"] = error
    return result


if __name__ == "__main__":
    dask_sweep()
