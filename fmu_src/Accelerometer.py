"""Accelerometer FMU: the weakly nonlinear sensor z = a0 + a1 x + a2 x^2 + v."""
from pythonfmu import Fmi2Slave  # noqa: F401  (pythonfmu's builder looks for Fmi2Slave here)

from fmu_src.slave_base import SlaveBase, default_experiment, var
from models import sensor


class Accelerometer(SlaveBase):
    """Weakly nonlinear accelerometer z_k = a0 + a1 x_k + a2 x_k^2 + v_k, v_k ~ N(0, R)."""

    VARIABLES = (
        var("a0", "parameter"),
        var("a1", "parameter"),
        var("a2", "parameter"),
        var("R", "parameter"),
        var("noise", "parameter", start=1, type="Integer", low=0, high=1,
            description="measurement noise v_k: 1 on, 0 off"),
        var("seed", "parameter", type="Integer"),
        var("Ts", "parameter"),
        var("x", "input", start=0.0, unit="g", description="true acceleration x_k"),
        var("z", "output", start=0.0, unit="V", description="sensor output z_k"),
    )
    DEPENDENCIES = {"z": ["x"]}
    default_experiment = default_experiment(2000, 1e-3)

    def compute(self):
        v = sensor.measurement_noise(self.seed, self.k) if self.noise else 0.0
        self.z = sensor.measure(self.x, self.a0, self.a1, self.a2, self.R, v)
