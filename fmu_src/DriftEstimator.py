"""DriftEstimator FMU: EKF with the letter's EKF1/EKF2/EKF3 drift estimators; process model
Gauss-Markov (the letter's scalar filter) or a harmonic oscillator at a known frequency."""

from driftfmu.fmu_src.slave_base import SlaveBase, default_experiment, var
from driftfmu.models import chain, drift, harmonic


class DriftEstimator(SlaveBase):
    """EKF estimate of x from z and the state-dependent drift a2 E[x^2] (EKF1, EKF2, EKF3), subtracted from z."""

    VARIABLES = (
        var("a0", "parameter"),
        var("a1", "parameter"),
        var("a2", "parameter"),
        var("A", "parameter"),
        var("Q", "parameter"),
        var("R", "parameter"),
        var("x0", "parameter"),
        var("P0", "parameter"),
        var("Ts", "parameter"),
        var("estimator", "parameter", start=1, type="Integer", low=1, high=3,
            description="drift estimator that feeds z_comp: 1 EKF1, 2 EKF2, 3 EKF3"),
        var("z", "input", start=0.0, unit="V", description="sensor output z_k"),
        var("process", "parameter", type="Integer"),
        var("f", "parameter", description="frequency f of the harmonic process model"),
        var("Qh", "parameter"),
        var("x_hat", "output", start=0.0, unit="g", description="a-posteriori estimate x+_k"),
        var("P", "output", start=0.0, unit="g2", description="a-posteriori error variance P+_k"),
        var("dc_ekf1", "output", start=0.0, unit="V", description="drift estimate of EKF1"),
        var("dc_ekf2", "output", start=0.0, unit="V", description="drift estimate of EKF2"),
        var("dc_ekf3", "output", start=0.0, unit="V", description="drift estimate of EKF3"),
        var("dc", "output", start=0.0, unit="V",
            description="drift estimate of the selected estimator"),
        var("z_comp", "output", start=0.0, unit="V",
            description="drift-compensated sensor output z_k - dc_k"),
    )
    DEPENDENCIES = {name: ["z"] for name in
                    ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp")}
    HIDDEN = ("_state", "_pending")
    default_experiment = default_experiment(2000, 1e-3)

    def check_parameters(self):
        problems = super().check_parameters()
        if self.process == harmonic.HARMONIC and self.f >= 0.5 / self.Ts:
            problems.append("f = %r Hz is at or above the Nyquist rate 1/(2 Ts) = %r Hz; "
                            "allowed: f < %r Hz" % (self.f, 0.5 / self.Ts, 0.5 / self.Ts))
        return problems

    def _set_model(self):
        C, S = harmonic.rotation(self.f, self.Ts)
        self._model = dict(process=self.process, A=self.A, Q=self.Q, C=C, S=S, Qh=self.Qh)

    def start(self):
        self._set_model()
        self._state = harmonic.estimator_init(self.process, self.x0, self.P0)
        self._pending = self._state

    def compute(self):
        self._pending = harmonic.estimator_step(self._state, self.z, self.a0, self.a1, self.a2,
                                                self.R, **self._model)
        self.x_hat, self.P = self._pending.x, self._pending.P
        dcs = drift.estimates(self._pending.drift, self.a2)
        self.dc_ekf1, self.dc_ekf2, self.dc_ekf3 = dcs
        self.dc = drift.select(dcs, self.estimator)
        self.z_comp = chain.compensate(self.z, self.dc)

    def advance(self, m):
        state = self._pending
        for _ in range(m - 1):  # samples between communication points carry no measurement
            state = harmonic.estimator_predict(state, **self._model)
        self._state = state

    def restore_hidden(self):
        self._set_model()
        for name in self.HIDDEN:
            setattr(self, name, harmonic.from_plain(getattr(self, name)))
