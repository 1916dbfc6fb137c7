"""Internal (not a stable API; use driftfmu.build_fmus instead).

DriftEstimator FMU: EKF with the letter's EKF1/EKF2/EKF3 drift estimators; process model
Gauss-Markov (the letter's scalar filter, with the known input B u of eq. 1) or a harmonic
oscillator at a known frequency; the sensor's characteristic up to 4th order (a3, a4)."""


from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, SlaveBase, check_estimator_plain, var
from driftfmu.models import chain, covariance, drift, harmonic

#: The covariance of the harmonic filter as the refusals name it: the output P and the hidden
#: P12, P22 (rows of the lower triangle), and the matrix as a whole.
COVARIANCE_NAMES = (("P",), ("hidden state _state.P12", "hidden state _state.P22"))
COVARIANCE_LISTING = "the covariance (P, P12, P22) of hidden state _state"
#: The same in a state being restored, where all are hidden.
STATE_COVARIANCE_NAMES = (("hidden state _state.P",),
                          ("hidden state _state.P12", "hidden state _state.P22"))


class DriftEstimator(SlaveBase):
    """EKF estimate of x from z and the state-dependent drift a2 E[x^2] + a3 E[x^3] + a4 E[x^4] (EKF1, EKF2, EKF3), subtracted from z."""

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
        var("a3", "parameter"),
        var("a4", "parameter"),
        var("B", "parameter", description="input gain B of the filter's prediction "
            "x-_k = A x+_{k-1} + B u_k (Gauss-Markov process model; 0: no known input)"),
        var("u", "input", start=0.0, unit="g",
            description="known input u_k of the process model (used when B != 0)"),
    )
    DEPENDENCIES = {name: ["z", "u"] for name in
                    ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp")}
    DESCRIPTION = ("EKF estimate of x from z and the state-dependent drift a2 E[x^2] + a3 E[x^3] "
                   "+ a4 E[x^4] (EKF1, EKF2, EKF3), subtracted from z; process model Gauss-Markov "
                   "(with the known input B u) or harmonic. The first "
                   "sample instant of a step takes the z held from its start as the "
                   "measurement, further instants in the same step are predict-only")
    #: The filter and drift-estimator state after the last sample (x0, P0 before the first).
    HIDDEN = ("_state",)
    OUTPUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp")
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = super().check_parameters()
        if self.process == harmonic.HARMONIC:
            problems += self.nyquist_problems()
        return problems

    def prepare(self):
        C, S = harmonic.rotation(self.f, self.Ts)
        self._model = dict(process=self.process, A=self.A, Q=self.Q, C=C, S=S, Qh=self.Qh,
                           B=self.B)
        # the same calls with the arguments laid out once (positional: no keyword matching on
        # every sample); the parameters are fixed after initialisation, and prepare runs again
        # whenever they may have changed (initialisation, Initialization Mode, a state restore)
        m = self._model
        self._step_args = (self.a0, self.a1, self.a2, self.R, m["process"], m["A"], m["Q"],
                           m["C"], m["S"], m["Qh"], self.a3, self.a4, m["B"])
        self._predict_args = (m["process"], m["A"], m["Q"], m["C"], m["S"], m["Qh"], m["B"])
        # the check after each sample (see hidden_valid): the class's for the harmonic model;
        # none for the Gauss-Markov one, whose numbers all reach the outputs and whose scalar P
        # stays >= 0 (it would answer True); the state's kind follows process wherever a
        # sample is computed
        if self.process == harmonic.HARMONIC:
            self.__dict__.pop("hidden_valid", None)
        else:
            self.hidden_valid = None

    def initial_hidden(self):
        return {"_state": harmonic.estimator_init(self.process, self.x0, self.P0)}

    def _outputs(self, state):
        dcs = drift.estimates(state.drift, self.a2, self.a3, self.a4)
        dc = drift.select(dcs, self.estimator)
        return state.x, state.P, dcs[0], dcs[1], dcs[2], dc, chain.compensate(self.z, dc)

    def show(self, outputs):
        (self.x_hat, self.P, self.dc_ekf1, self.dc_ekf2, self.dc_ekf3, self.dc,
         self.z_comp) = outputs

    def sample(self, hidden, k, first):
        state = hidden["_state"]
        if first:  # the measurement: the z set at (or held from) the start of the step
            state = harmonic.estimator_step(state, self.z, *self._step_args, self.u)
        else:      # samples between communication points carry no measurement (u held)
            state = harmonic.estimator_predict(state, *self._predict_args, self.u)
        return {"_state": state}, self._outputs(state)

    def hold(self, hidden, k0, n, first):
        hidden, outputs = self.sample(hidden, k0, first)
        if n > 1:
            state = hidden["_state"]
            args, u = self._predict_args, self.u
            check = type(state) is harmonic.HarmonicState  # (the scalar P stays >= 0)
            for k in range(k0, k0 + n - 1):
                if check and not covariance.valid2(state.P, state.P12, state.P22):
                    self._refuse_covariance(state, k)
                state = harmonic.estimator_predict(state, *args, u)
            hidden, outputs = {"_state": state}, self._outputs(state)
        return hidden, outputs  # (the state after the last sample: the base class checks it)

    def _refuse_covariance(self, state, k):
        """Refuse sample ``k`` (not the last of a step) whose harmonic state's covariance is not
        valid, when its entries are finite (a non-finite one stays so, and the check of the
        last sample refuses it as an overflow)."""
        zero = 0.0 * state.P + 0.0 * state.P12 + 0.0 * state.P22
        if zero == 0.0:
            self._fail(self.covariance_refusal({"_state": state}, k))

    def hidden_valid(self, hidden):
        # x, P and the drift sums reach the outputs (x_hat, P, dc_ekf1 = a2 s1, dc_ekf2 = dc2,
        # dc_ekf3 from a2 s3 and dc3), so a non-finite one makes an output non-finite, which the
        # base class refuses first; the harmonic model's d, P12 and P22 do not reach them, and
        # its covariance (P, P12, P22) must be valid (models/covariance.py)
        state = hidden["_state"]
        if type(state) is harmonic.HarmonicState:
            zero = 0.0 * state.d + 0.0 * state.P12 + 0.0 * state.P22  # 0, or nan if any is not
            return zero == 0.0 and covariance.valid2(state.P, state.P12, state.P22)
        return True

    def covariance_refusal(self, hidden, k):
        lower = harmonic.covariance_of(hidden["_state"])
        if lower is None or covariance.valid(lower):
            return None
        return covariance.refusal(COVARIANCE_NAMES, lower, k, self._sample_time(k),
                                  COVARIANCE_LISTING)

    def parse_hidden(self, name, value):
        if value is None:
            return None
        check_estimator_plain(value, (3, 6), (5, len(drift.DriftState._fields)),
                              "an estimator state [x, P, drift] or [x, d, P, P12, P22, drift]",
                              "a drift-estimator state [k, s1, dc2, s3, dc3]")
        return harmonic.from_plain(value)

    def hidden_problems(self, hidden):
        state = hidden["_state"]
        harmonic_state = isinstance(state, harmonic.HarmonicState)
        if harmonic_state != (self.process == harmonic.HARMONIC):
            return ["the estimator state does not belong to process = %r" % (self.process,)]
        lower = harmonic.covariance_of(state) or ((state.P,),)
        names = STATE_COVARIANCE_NAMES[:len(lower)]
        return covariance.state_problems(names, lower, COVARIANCE_LISTING)
