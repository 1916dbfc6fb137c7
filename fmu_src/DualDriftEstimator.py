"""Internal (not a stable API; use driftfmu.build_fmus instead).

DualDriftEstimator FMU: the EKF over both axes of a dual-axis sensor with a bilinear cross
term, and each axis's drift a2 E[x^2] + b E[x y] by EKF1, EKF2, EKF3 (:mod:`driftfmu.models.dualaxis`);
process model Gauss-Markov over (x, y) or two harmonic oscillators at a known frequency.

A new FMU rather than a mode of DriftEstimator: DriftEstimator's interface (its variables and
value references) stays exactly as it is, and this one has a measurement vector (z_x, z_y)."""


from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, SlaveBase, check_estimator_plain, var
from driftfmu.models import chain, covariance, drift, dualaxis, harmonic


_HIDDEN = "hidden state _state."
#: The filters' covariance entries as a refused sample names them (the outputs P_xx, P_xy, P_yy
#: where an entry is one), per process model in the shape of dualaxis.covariance_of; the same
#: in a state being restored (all hidden); and the matrix as a whole.
COVARIANCE_NAMES = {
    dualaxis.GAUSS_MARKOV: (("P_xx",), ("P_xy", "P_yy")),
    dualaxis.HARMONIC: (("P_xx",), (_HIDDEN + "P12", _HIDDEN + "P22"),
                        ("P_xy", _HIDDEN + "P23", "P_yy"),
                        (_HIDDEN + "P14", _HIDDEN + "P24", _HIDDEN + "P34", _HIDDEN + "P44"))}
STATE_COVARIANCE_NAMES = {p: tuple(tuple(_HIDDEN + n for n in row) for row in rows)
                          for p, rows in dualaxis.COVARIANCE_NAMES.items()}
COVARIANCE_LISTING = {p: "the covariance (%s) of hidden state _state"
                      % ", ".join(n for row in rows for n in row)
                      for p, rows in dualaxis.COVARIANCE_NAMES.items()}

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
    DESCRIPTION = ("EKF estimate of (x, y) from (z_x, z_y) of a dual-axis sensor with bilinear "
                   "cross terms, and each axis's drift a2 E[x^2] + b E[x y] (EKF1, EKF2, EKF3), "
                   "subtracted from z; process model Gauss-Markov over (x, y) or two harmonic "
                   "oscillators. The first sample instant of a step takes the (z_x, z_y) held "
                   "from its start as the measurement, further instants in the same step are "
                   "predict-only")
    #: The filter and drift-estimator state after the last sample (x0, y0, P0, P0y before the
    #: first).
    HIDDEN = ("_state",)
    OUTPUTS = OUTPUTS
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = super().check_parameters()
        if self.process == harmonic.HARMONIC:
            problems += self.nyquist_problems()
        return problems

    def prepare(self):
        self._axes = dualaxis.axes(self.parameter_values())
        self._model = dualaxis.model(self.process, A=self.A, Q=self.Q, Qy=self.Qy, rho=self.rho,
                                     f=self.f, Ts=self.Ts, Qh=self.Qh)

    def initial_hidden(self):
        return {"_state": dualaxis.estimator_init(self.process, self.x0, self.y0, self.P0,
                                                  self.P0y)}

    def _outputs(self, state):
        x_hat, y_hat, P_xx, P_xy, P_yy = dualaxis.moments(state)
        dx, dy = dualaxis.estimates(state.drift, *self._axes)
        dc_x, dc_y = drift.select(dx, self.estimator), drift.select(dy, self.estimator)
        return (x_hat, y_hat, P_xx, P_xy, P_yy, dx[0], dx[1], dx[2], dy[0], dy[1], dy[2],
                dc_x, dc_y, chain.compensate(self.z_x, dc_x), chain.compensate(self.z_y, dc_y))

    def show(self, outputs):
        (self.x_hat, self.y_hat, self.P_xx, self.P_xy, self.P_yy, self.dc_ekf1_x,
         self.dc_ekf2_x, self.dc_ekf3_x, self.dc_ekf1_y, self.dc_ekf2_y, self.dc_ekf3_y,
         self.dc_x, self.dc_y, self.z_comp_x, self.z_comp_y) = outputs

    def sample(self, hidden, k, first):
        state = hidden["_state"]
        if first:  # the measurement: (z_x, z_y) set at (or held from) the start of the step
            state = dualaxis.estimator_step(state, self.z_x, self.z_y, *self._axes, self._model)
        else:      # samples between communication points carry no measurement
            state = dualaxis.estimator_predict(state, self._model)
        return {"_state": state}, self._outputs(state)

    def hold(self, hidden, k0, n, first):
        hidden, outputs = self.sample(hidden, k0, first)
        if n > 1:
            state = hidden["_state"]
            k, end = k0, k0 + n - 1
            while k < end:  # the samples k0 + 1 .. k0 + n - 1, each from a valid covariance
                state, done = dualaxis.predict_run(state, self._model, end - k)
                k += done
                if k < end:  # the covariance after sample k is not valid
                    self._refuse_covariance(state, k)
                    state = dualaxis.estimator_predict(state, self._model)  # (not finite: on)
                    k += 1
            hidden, outputs = {"_state": state}, self._outputs(state)
        return hidden, outputs  # (the state after the last sample: the base class checks it)

    def _refuse_covariance(self, state, k):
        """Refuse sample ``k`` (not the last of a step) whose covariance is not valid, when its
        entries are finite (a non-finite one stays so, and the check of the last sample refuses
        it as an overflow)."""
        _, lower = dualaxis.covariance_of(state)
        if sum(0.0 * v for row in lower for v in row) == 0.0:
            self._fail(self.covariance_refusal({"_state": state}, k))

    def hidden_valid(self, hidden):
        # every number finite (the base class's test) and the covariance valid
        return SlaveBase.hidden_valid(self, hidden) and dualaxis.valid(hidden["_state"])

    def covariance_refusal(self, hidden, k):
        process, lower = dualaxis.covariance_of(hidden["_state"])
        if covariance.valid(lower):
            return None
        return covariance.refusal(COVARIANCE_NAMES[process], lower, k, self._sample_time(k),
                                  COVARIANCE_LISTING[process])

    def parse_hidden(self, name, value):
        if value is None:
            return None
        sizes = (len(dualaxis.DualState._fields), len(dualaxis.DualHarmonicState._fields))
        check_estimator_plain(value, sizes, len(dualaxis.DualDrift._fields),
                              "a dual estimator state [x, y, Pxx, Pxy, Pyy, drift] or "
                              "[x, dx, y, dy, P11 .. P24, drift]",
                              "a dual drift-estimator state [k, s1xx, .., dc3y]")
        return dualaxis.from_plain(value)

    def hidden_problems(self, hidden):
        state = hidden["_state"]
        harmonic_state = isinstance(state, dualaxis.DualHarmonicState)
        if harmonic_state != (self.process == harmonic.HARMONIC):
            return ["the estimator state does not belong to process = %r" % (self.process,)]
        process, lower = dualaxis.covariance_of(state)
        return covariance.state_problems(STATE_COVARIANCE_NAMES[process], lower,
                                         COVARIANCE_LISTING[process])
