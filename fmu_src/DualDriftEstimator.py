"""DualDriftEstimator FMU: the EKF over both axes of a dual-axis sensor with a bilinear cross
term, and each axis's drift a2 E[x^2] + b E[x y] by EKF1, EKF2, EKF3 (:mod:`models.dualaxis`);
process model Gauss-Markov over (x, y) or two harmonic oscillators at a known frequency.

A new FMU rather than a mode of DriftEstimator: DriftEstimator's interface (its variables and
value references) stays exactly as it is, and this one has a measurement vector (z_x, z_y)."""

from driftfmu.fmu_src.slave_base import SlaveBase, default_experiment, var
from driftfmu.models import chain, drift, dualaxis, harmonic

#: Outputs, each depending on both inputs.
OUTPUTS = ("x_hat", "y_hat", "P_xx", "P_xy", "P_yy", "dc_ekf1_x", "dc_ekf2_x", "dc_ekf3_x",
           "dc_ekf1_y", "dc_ekf2_y", "dc_ekf3_y", "dc_x", "dc_y", "z_comp_x", "z_comp_y")


class DualDriftEstimator(SlaveBase):
    """EKF estimate of (x, y) from (z_x, z_y) and each axis's drift a2 E[x^2] + b E[x y] (EKF1, EKF2, EKF3), subtracted from z."""

    VARIABLES = (
        var("a0", "parameter"),
        var("a1", "parameter"),
        var("a2", "parameter"),
        var("bx", "parameter"),
        var("R", "parameter"),
        var("a0y", "parameter"),
        var("a1y", "parameter"),
        var("a2y", "parameter"),
        var("by", "parameter"),
        var("Ry", "parameter"),
        var("A", "parameter"),
        var("Q", "parameter"),
        var("Qy", "parameter", start=0.01),
        var("rho", "parameter"),
        var("x0", "parameter"),
        var("y0", "parameter"),
        var("P0", "parameter"),
        var("P0y", "parameter"),
        var("Ts", "parameter"),
        var("estimator", "parameter", start=1, type="Integer", low=1, high=3,
            description="drift estimator that feeds z_comp_x, z_comp_y: 1 EKF1, 2 EKF2, 3 EKF3"),
        var("process", "parameter", type="Integer"),
        var("f", "parameter", description="frequency f of the harmonic process model"),
        var("Qh", "parameter"),
        var("z_x", "input", start=0.0, unit="V", description="first-axis sensor output z_x,k"),
        var("z_y", "input", start=0.0, unit="V", description="second-axis sensor output z_y,k"),
        var("x_hat", "output", start=0.0, unit="g", description="a-posteriori estimate x+_k"),
        var("y_hat", "output", start=0.0, unit="g", description="a-posteriori estimate y+_k"),
        var("P_xx", "output", start=0.0, unit="g2", description="a-posteriori variance of x"),
        var("P_xy", "output", start=0.0, unit="g2",
            description="a-posteriori covariance of x and y"),
        var("P_yy", "output", start=0.0, unit="g2", description="a-posteriori variance of y"),
        var("dc_ekf1_x", "output", start=0.0, unit="V", description="x-axis drift, EKF1"),
        var("dc_ekf2_x", "output", start=0.0, unit="V", description="x-axis drift, EKF2"),
        var("dc_ekf3_x", "output", start=0.0, unit="V", description="x-axis drift, EKF3"),
        var("dc_ekf1_y", "output", start=0.0, unit="V", description="y-axis drift, EKF1"),
        var("dc_ekf2_y", "output", start=0.0, unit="V", description="y-axis drift, EKF2"),
        var("dc_ekf3_y", "output", start=0.0, unit="V", description="y-axis drift, EKF3"),
        var("dc_x", "output", start=0.0, unit="V",
            description="x-axis drift of the selected estimator"),
        var("dc_y", "output", start=0.0, unit="V",
            description="y-axis drift of the selected estimator"),
        var("z_comp_x", "output", start=0.0, unit="V",
            description="drift-compensated output z_x,k - dc_x,k"),
        var("z_comp_y", "output", start=0.0, unit="V",
            description="drift-compensated output z_y,k - dc_y,k"),
    )
    DEPENDENCIES = {name: ["z_x", "z_y"] for name in OUTPUTS}
    HIDDEN = ("_state", "_pending")
    default_experiment = default_experiment(2000, 1e-3)

    def check_parameters(self):
        problems = super().check_parameters()
        if self.process == harmonic.HARMONIC and self.f >= 0.5 / self.Ts:
            problems.append("f = %r Hz is at or above the Nyquist rate 1/(2 Ts) = %r Hz; "
                            "allowed: f < %r Hz" % (self.f, 0.5 / self.Ts, 0.5 / self.Ts))
        return problems

    def _set_model(self):
        p = self.parameter_values()
        self._axes = dualaxis.axes(p)
        self._model = dualaxis.model(self.process, A=self.A, Q=self.Q, Qy=self.Qy, rho=self.rho,
                                     f=self.f, Ts=self.Ts, Qh=self.Qh)

    def start(self):
        self._set_model()
        self._state = dualaxis.estimator_init(self.process, self.x0, self.y0, self.P0, self.P0y)
        self._pending = self._state

    def compute(self):
        self._pending = dualaxis.estimator_step(self._state, self.z_x, self.z_y, *self._axes,
                                                self._model)
        self.x_hat, self.y_hat, self.P_xx, self.P_xy, self.P_yy = dualaxis.moments(self._pending)
        dx, dy = dualaxis.estimates(self._pending.drift, *self._axes)
        self.dc_ekf1_x, self.dc_ekf2_x, self.dc_ekf3_x = dx
        self.dc_ekf1_y, self.dc_ekf2_y, self.dc_ekf3_y = dy
        self.dc_x = drift.select(dx, self.estimator)
        self.dc_y = drift.select(dy, self.estimator)
        self.z_comp_x = chain.compensate(self.z_x, self.dc_x)
        self.z_comp_y = chain.compensate(self.z_y, self.dc_y)

    def advance(self, m):
        state = self._pending
        for _ in range(m - 1):  # samples between communication points carry no measurement
            state = dualaxis.estimator_predict(state, self._model)
        self._state = state

    def restore_hidden(self):
        self._set_model()
        for name in self.HIDDEN:
            setattr(self, name, dualaxis.from_plain(getattr(self, name)))
