"""Internal (not a stable API; use driftfmu.build_fmus instead).

Excitation FMU: the true acceleration x, Gaussian (Gauss-Markov) or sinusoidal, and the
second-axis acceleration y (sinusoidal at the same frequency, amplitude Xy; when Gaussian a
second Gauss-Markov axis of process noise Qy correlated rho with x's, 0 while Qy = 0); the
known input u_k (drive: Gaussian N(0, Qu) or Xu sin(2 pi fu t), or from the host through the
input u_in when drive = 0) that enters the Gaussian x as B u_k (eq. 1) and that the
DriftEstimator takes as its input u."""

from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, SlaveBase, var
from driftfmu.models import excitation, noise


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
            description="second-axis acceleration y_k = Xy sin(2 pi f t_k + phiy), or if "
                        "Gaussian y_k = A y_{k-1} + w_y,k (0 while Qy = 0)"),
        var("Qy", "parameter"),
        var("rho", "parameter"),
        var("B", "parameter"),
        var("drive", "parameter", type="Integer", description="known input u_k: 0 from the "
            "host (the input u_in; 0 unless set), 1 Gaussian white N(0, Qu), 2 sinusoid "
            "Xu sin(2 pi fu t)"),
        var("Qu", "parameter"),
        var("Xu", "parameter"),
        var("fu", "parameter"),
        var("u", "output", start=0.0, unit="g",
            description="known input u_k (drive), which drives x by B u_k when Gaussian; "
                        "connect it to the DriftEstimator's u"),
        var("u_in", "input", start=0.0, unit="g",
            description="known input u_k from the host (a shaker's drive, a commanded "
                        "motion), used when drive = 0; held between communication points"),
    )
    #: x (through B u_k) and u follow the host's u_in at the same communication point.
    DEPENDENCIES = {"x": ["u_in"], "u": ["u_in"]}
    DESCRIPTION = ("True acceleration x_k: Gauss-Markov x_k = A x_{k-1} + B u_k + w_k, "
                   "w_k ~ N(0, Q), with the known input u_k, "
                   "or X sin(2 pi f t + phi); second axis y_k = Xy sin(2 pi f t_k + phiy), or "
                   "Gauss-Markov y_k = A y_{k-1} + w_y,k with corr(w_x, w_y) = rho when Qy > 0")
    #: x_{k-1} and y_{k-1}, the excitation before the next sample (x0 and 0 before sample 1).
    HIDDEN = ("_x", "_y")
    OUTPUTS = ("x", "y", "u")
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = super().check_parameters()
        if self.kind == excitation.SINUSOIDAL:
            problems += self.nyquist_problems()
        if self.drive == excitation.SINUSOIDAL:
            problems += self.nyquist_problems("fu")
        return problems

    def prepare(self):
        # the Gaussian sample's arguments laid out once, and what depends on k alone (the
        # draws, the sinusoids, the drive) made blocks of samples; the parameters are fixed
        # after initialisation, and prepare runs again whenever they may have changed
        self._gaussian = self.kind == excitation.GAUSSIAN
        self._pair = (self.A, self.Q, self.Qy, self.rho)
        seed, Ts = self.seed, self.Ts
        if self._gaussian:
            self._w1 = self.blocks("w1", seed, lambda k: noise.normal(
                seed, noise.STREAM_PROCESS, k))
            self._w2 = self.blocks("w2", seed, lambda k: noise.normal(
                seed, noise.STREAM_SENSOR_Y, k))
        else:
            X, Xy, f, phi, phiy = self.X, self.Xy, self.f, self.phi, self.phiy
            self._sx = self.blocks("sx", (X, f, Ts, phi),
                                   lambda k: excitation.sine(k, X, f, Ts, phi))
            self._sy = self.blocks("sy", (Xy, f, Ts, phiy),
                                   lambda k: excitation.sine(k, Xy, f, Ts, phiy))
        drive, Qu, Xu, fu = self.drive, self.Qu, self.Xu, self.fu
        self._drive = None if drive == excitation.DRIVE_OFF else self.blocks(
            "u", (drive, seed, Qu, Xu, fu, Ts),
            lambda k: excitation.input_sample(drive, seed, k, Qu, Xu, fu, Ts))

    def _u(self, k):
        if self._drive is None:  # from the host (0 unless it sets u_in)
            return self.u_in
        return self._drive(k)

    def _sample(self, x_prev, y_prev, k, u):
        if self._gaussian:  # excitation.gaussian_pair, its draws from the blocks
            A, Q, Qy, rho = self._pair
            return excitation.correlated_pair(x_prev, y_prev, A, Q, Qy, rho, self._w1(k),
                                              self._w2(k) if Qy != 0.0 else 0.0, self.B, u)
        return self._sx(k), self._sy(k)  # excitation.sine of x and y

    def initial_hidden(self):
        return {"_x": self.x0, "_y": 0.0}

    def sample(self, hidden, k, first):
        u = self._u(k)  # (once: x takes it as B u_k, and it is the output u)
        x, y = self._sample(hidden["_x"], hidden["_y"], k, u)
        return {"_x": x, "_y": y}, (x, y, u)

    def show(self, outputs):
        self.x, self.y, self.u = outputs

    #: the hidden x is the output x, which the base class checks
    hidden_valid = None

    def hold(self, hidden, k0, n, first):
        x, y = hidden["_x"], hidden["_y"]
        if self._gaussian:
            for k in range(k0, k0 + n):
                u = self._u(k)
                x, y = self._sample(x, y, k, u)
        else:  # the sinusoid needs no history (nor the input)
            u = self._u(k0 + n - 1)
            x, y = self._sample(x, y, k0 + n - 1, u)
        return {"_x": x, "_y": y}, (x, y, u)
