"""Excitation FMU: the true acceleration x, Gaussian (Gauss-Markov) or sinusoidal, and the
second-axis acceleration y (sinusoidal at the same frequency, amplitude Xy; 0 when Gaussian)."""

from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, SlaveBase, var
from driftfmu.models import excitation


class Excitation(SlaveBase):
    """True acceleration x_k: Gauss-Markov x_k = A x_{k-1} + w_k, w_k ~ N(0, Q), or X sin(2 pi f t + phi)."""

    VARIABLES = (
        var("kind", "parameter", start=excitation.GAUSSIAN, type="Integer", low=1, high=2,
            description="excitation: 1 Gaussian (Gauss-Markov), 2 sinusoidal"),
        var("A", "parameter"),
        var("Q", "parameter"),
        var("x0", "parameter"),
        var("X", "parameter"),
        var("f", "parameter"),
        var("phi", "parameter"),
        var("Xy", "parameter"),
        var("phiy", "parameter"),
        var("Ts", "parameter"),
        var("seed", "parameter", type="Integer"),
        var("x", "output", start=0.0, unit="g", description="true acceleration x_k"),
        var("y", "output", start=0.0, unit="g",
            description="second-axis acceleration y_k = Xy sin(2 pi f t_k + phiy) (0 if Gaussian)"),
    )
    DESCRIPTION = ("True acceleration x_k: Gauss-Markov x_k = A x_{k-1} + w_k, w_k ~ N(0, Q), "
                   "or X sin(2 pi f t + phi); second axis y_k = Xy sin(2 pi f t_k + phiy)")
    #: x_{k-1}, the excitation before the next sample (x0 before sample 1).
    HIDDEN = ("_x",)
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = super().check_parameters()
        if self.kind == excitation.SINUSOIDAL and self.f >= 0.5 / self.Ts:
            problems.append("f = %r Hz is at or above the Nyquist rate 1/(2 Ts) = %r Hz; "
                            "allowed: f < %r Hz" % (self.f, 0.5 / self.Ts, 0.5 / self.Ts))
        return problems

    def _sample(self, x_prev, k):
        if self.kind == excitation.GAUSSIAN:
            return excitation.gaussian_sample(x_prev, self.A, self.Q, self.seed, k)
        return excitation.sine(k, self.X, self.f, self.Ts, self.phi)

    def _sample_y(self, k):
        if self.kind == excitation.GAUSSIAN:
            return 0.0
        return excitation.sine(k, self.Xy, self.f, self.Ts, self.phiy)

    def initial_hidden(self):
        return {"_x": self.x0}

    def sample(self, hidden, k, first):
        x = self._sample(hidden["_x"], k)
        return {"_x": x}, {"x": x, "y": self._sample_y(k)}

    #: the hidden x is the output x, which the base class checks
    hidden_finite = None

    def hold(self, hidden, k0, n, first):
        x = hidden["_x"]
        if self.kind == excitation.GAUSSIAN:
            for k in range(k0, k0 + n):
                x = self._sample(x, k)
        else:  # the sinusoid needs no history
            x = self._sample(x, k0 + n - 1)
        return {"_x": x}, {"x": x, "y": self._sample_y(k0 + n - 1)}
