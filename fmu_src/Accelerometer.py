"""Accelerometer FMU: the weakly nonlinear sensor z = a0 + a1 x + a2 x^2 + v, and the richer
dual-axis part (cubic term, cross-axis coupling, output low-pass, ratiometric output, ADC,
noise density) of :mod:`models.adxl203`, every extra off by default; or (``dual = 1``) the
dual-axis bilinear sensor of :mod:`models.dualaxis`, z = a0 + a1 x + a2 x^2 + bx x y + v_x and
z_y = a0y + a1y y + a2y y^2 + by x y + v_y."""

from driftfmu.fmu_src.slave_base import SlaveBase, default_experiment, var
from driftfmu.models import adxl203, dualaxis


class Accelerometer(SlaveBase):
    """Weakly nonlinear accelerometer z_k = a0 + a1 x_k + a2 x_k^2 + v_k, v_k ~ N(0, R); optional ADXL203-like extras."""

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
        var("a3", "parameter"),
        var("cross", "parameter"),
        var("fc", "parameter"),
        var("Vs", "parameter"),
        var("bits", "parameter", type="Integer"),
        var("density", "parameter"),
        var("axes", "parameter", type="Integer"),
        var("y", "input", start=0.0, unit="g", description="second-axis acceleration y_k"),
        var("z_y", "output", start=0.0, unit="V",
            description="second-axis output (axes = 2 or dual = 1; 0 otherwise)"),
        var("dual", "parameter", type="Integer"),
        var("bx", "parameter"),
        var("a0y", "parameter"),
        var("a1y", "parameter"),
        var("a2y", "parameter"),
        var("by", "parameter"),
        var("Ry", "parameter"),
    )
    DEPENDENCIES = {"z": ["x", "y"], "z_y": ["x", "y"]}
    #: Output filter states (None before the first sample): committed and pending, per axis.
    HIDDEN = ("_lp", "_lp_pending", "_lpy", "_lpy_pending")
    default_experiment = default_experiment(2000, 1e-3)

    def check_parameters(self):
        p = self.parameter_values()
        return super().check_parameters() + adxl203.problems(p) + dualaxis.sensor_problems(p)

    def start(self):
        self._cfg = adxl203.config(**self.parameter_values())
        self._axes = dualaxis.axes(self.parameter_values())
        self._lp = self._lp_pending = self._lpy = self._lpy_pending = None

    def _noise(self, k, axis):
        return adxl203.noise(self.seed, k, axis) if self.noise else 0.0

    def compute(self):
        if self.dual:
            self.z, self.z_y = dualaxis.measure(self.x, self.y, *self._axes,
                                                self._noise(self.k, 1), self._noise(self.k, 2))
            return
        self._lp_pending, self.z = adxl203.measure(self._lp, self.x, self.y,
                                                   self._noise(self.k, 1), self._cfg)
        if self.axes == 2:
            self._lpy_pending, self.z_y = adxl203.measure(self._lpy, self.y, self.x,
                                                          self._noise(self.k, 2), self._cfg)

    def advance(self, m):
        if self.dual:  # no output filter: nothing is held between communication points
            return
        args = (self.seed, self.k, m, self._cfg)
        self._lp = adxl203.hold(self._lp_pending, self.x, self.y, *args, axis=1,
                                noise_on=self.noise)
        if self.axes == 2:
            self._lpy = adxl203.hold(self._lpy_pending, self.y, self.x, *args, axis=2,
                                     noise_on=self.noise)

    def restore_hidden(self):
        self._cfg = adxl203.config(**self.parameter_values())
        self._axes = dualaxis.axes(self.parameter_values())
