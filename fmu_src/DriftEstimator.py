"""Internal (not a stable API; use driftfmu.build_fmus instead).

DriftEstimator FMU: EKF with the letter's EKF1/EKF2/EKF3 drift estimators; process model
Gauss-Markov (the letter's scalar filter, with the known input B u of eq. 1) or a harmonic
oscillator at a known frequency; the sensor's characteristic up to 4th order (a3, a4); a bias
state b beside x (bias = 1, Gauss-Markov process model) and the class-2 offset of the tilt and
temperature inputs removed from z before filtering."""


import math

from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, SlaveBase, check_estimator_plain, var
from driftfmu.models import bias, chain, covariance, drift, errors, harmonic, parameters

#: The covariance of the harmonic filter as the refusals name it: the output P and the hidden
#: P12, P22 (rows of the lower triangle), and the matrix as a whole.
COVARIANCE_NAMES = (("P",), ("hidden state _state.P12", "hidden state _state.P22"))
COVARIANCE_LISTING = "the covariance (P, P12, P22) of hidden state _state"
#: The same in a state being restored, where all are hidden.
STATE_COVARIANCE_NAMES = (("hidden state _state.P",),
                          ("hidden state _state.P12", "hidden state _state.P22"))
#: The covariance of the bias filter ([x, b]) in a state being restored (in a step its entries
#: are the outputs P, P_xb, P_bb: models.bias.COVARIANCE_NAMES).
BIAS_STATE_COVARIANCE_NAMES = (("hidden state _state.P",),
                               ("hidden state _bias.Pxb", "hidden state _bias.Pbb"))
BIAS_STATE_LISTING = "the covariance (P, Pxb, Pbb) of hidden states _state and _bias"
#: The refusal of a bias state with the harmonic process model (C twin: DriftEstimator_step.c).
BIAS_WITH_HARMONIC = ("bias = %r is not allowed with process = %r; allowed: bias = 1 with "
                      "process = 1 (the harmonic filter has no bias state), or bias = 0")


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
        var("bias", "parameter", type="Integer"),
        var("Qb", "parameter"),
        var("tau_b", "parameter"),
        var("b0", "parameter"),
        var("Pb0", "parameter"),
        var("theta", "input", start=0.0, unit="rad", description="tilt theta of the sensor: "
            "it senses x + sin(theta) (the letter's class-2 g-offset; 0: none)"),
        var("T", "input", start=parameters.PARAMETERS["T0"].default, unit="K",
            description="temperature T of the sensor (class 2, with kT_bias and kT_scale)"),
        var("T0", "parameter"),
        var("kT_bias", "parameter"),
        var("kT_scale", "parameter"),
        var("b_hat", "output", start=0.0, unit="V",
            description="a-posteriori bias estimate b+_k (0 with bias = 0)"),
        var("P_bb", "output", start=0.0, unit="V2",
            description="a-posteriori error variance of the bias estimate (0 with bias = 0)"),
        var("P_xb", "output", start=0.0, unit="g.V",
            description="a-posteriori cross-covariance of x and b (0 with bias = 0)"),
        var("dc_class2", "output", start=0.0, unit="V",
            description="class-2 offset removed from z before filtering: kT_bias (T - T0) + "
            "h(g) - a0, g = (1 + kT_scale (T - T0)) sin theta"),
    )
    OUTPUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "dc", "z_comp", "b_hat", "P_bb",
               "P_xb", "dc_class2")
    DEPENDENCIES = {name: ["z", "u", "theta", "T"] for name in OUTPUTS}
    DESCRIPTION = ("EKF estimate of x from z and the state-dependent drift a2 E[x^2] + a3 E[x^3] "
                   "+ a4 E[x^4] (EKF1, EKF2, EKF3), subtracted from z; process model Gauss-Markov "
                   "(with the known input B u) or harmonic; optionally a bias state b beside x "
                   "(z = h(x) + b + v; z_comp = z - dc - b_hat) and the class-2 offset of the "
                   "tilt and temperature inputs removed from z before filtering. The first "
                   "sample instant of a step takes the z held from its start as the "
                   "measurement, further instants in the same step are predict-only")
    #: The filter and drift-estimator state after the last sample (x0, P0 before the first),
    #: and the bias part [b, Pxb, Pbb] of the filter (None with bias = 0).
    HIDDEN = ("_state", "_bias")
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = super().check_parameters()
        if self.process == harmonic.HARMONIC:
            problems += self.nyquist_problems()
        if self.bias == 1 and self.process == harmonic.HARMONIC:
            problems.append(BIAS_WITH_HARMONIC % (self.bias, self.process))
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
        # the bias filter's (models.bias.estimator_step / estimator_predict)
        self._bias = self.bias == 1
        Fb = bias.factor(self.tau_b, self.Ts)
        self._bias_step_args = (self.a0, self.a1, self.a2, self.A, self.Q, self.R, Fb, self.Qb,
                                self.a3, self.a4, self.B)
        self._bias_predict_args = (self.A, self.Q, Fb, self.Qb, self.B)
        # the class-2 offset's coefficients (the tilt is an input: checked per sample)
        self._class2_args = (self.a1, self.a2, self.T0, self.kT_bias, self.kT_scale, self.a3,
                             self.a4)
        self._kT = self.kT_bias != 0.0 or self.kT_scale != 0.0
        self._general = self._bias or self._kT
        # the check after each sample (see hidden_valid): the class's for the harmonic model
        # and the bias state; none for the letter's Gauss-Markov one, whose numbers all reach
        # the outputs and whose scalar P stays >= 0 (it would answer True); the state's kind
        # follows process and bias wherever a sample is computed
        if self.process == harmonic.HARMONIC or self._bias:
            self.__dict__.pop("hidden_valid", None)
        else:
            self.hidden_valid = None

    def initial_hidden(self):
        return {"_state": harmonic.estimator_init(self.process, self.x0, self.P0),
                "_bias": bias.init(self.b0, self.Pb0) if self.bias == 1 else None}

    def _outputs(self, state):
        dcs = drift.estimates(state.drift, self.a2, self.a3, self.a4)
        dc = drift.select(dcs, self.estimator)
        return (state.x, state.P, dcs[0], dcs[1], dcs[2], dc, chain.compensate(self.z, dc),
                0.0, 0.0, 0.0, 0.0)

    def _general_outputs(self, state, b, z, offset):
        """The outputs of a sample of the bias filter or with a class-2 offset: all of OUTPUTS
        (z the measurement after the offset is removed)."""
        dcs = drift.estimates(state.drift, self.a2, self.a3, self.a4)
        dc = drift.select(dcs, self.estimator)
        if b is None:
            return (state.x, state.P, dcs[0], dcs[1], dcs[2], dc, chain.compensate(z, dc),
                    0.0, 0.0, 0.0, offset)
        return (state.x, state.P, dcs[0], dcs[1], dcs[2], dc, bias.compensate(z, dc, b.b),
                b.b, b.Pbb, b.Pxb, offset)

    def show(self, outputs):
        (self.x_hat, self.P, self.dc_ekf1, self.dc_ekf2, self.dc_ekf3, self.dc, self.z_comp,
         self.b_hat, self.P_bb, self.P_xb, self.dc_class2) = outputs

    def sample(self, hidden, k, first):
        if self._general or self.theta != 0.0:  # (the bias state, a class-2 offset)
            return self._general_sample(hidden, first)
        state = hidden["_state"]
        if first:  # the measurement: the z set at (or held from) the start of the step
            state = harmonic.estimator_step(state, self.z, *self._step_args, self.u)
        else:      # samples between communication points carry no measurement (u held)
            state = harmonic.estimator_predict(state, *self._predict_args, self.u)
        return {"_state": state, "_bias": None}, self._outputs(state)

    def _general_sample(self, hidden, first):
        """A sample with the bias state or the class-2 offset: the offset (models.errors.class2_offset)
        is removed from z, and the bias filter (models.bias) or the letter's runs on the rest."""
        state, b, u = hidden["_state"], hidden["_bias"], self.u
        offset = errors.class2_offset(self.theta, self.T, *self._class2_args) \
            if self.theta != 0.0 or self._kT else 0.0
        z = self.z - offset
        if b is None:  # the letter's filter on z (either process model)
            state = harmonic.estimator_step(state, z, *self._step_args, u) if first else \
                harmonic.estimator_predict(state, *self._predict_args, u)
        elif first:
            state, b = bias.estimator_step(state, b, z, *self._bias_step_args, u)
        else:
            state, b = bias.estimator_predict(state, b, *self._bias_predict_args, u)
        return {"_state": state, "_bias": b}, self._general_outputs(state, b, z, offset)

    def hold(self, hidden, k0, n, first):
        hidden, outputs = self.sample(hidden, k0, first)
        if n > 1:
            if self._general or self.theta != 0.0:
                return self._general_hold(hidden, k0, n)
            state = hidden["_state"]
            args, u = self._predict_args, self.u
            check = type(state) is harmonic.HarmonicState  # (the scalar P stays >= 0)
            for k in range(k0, k0 + n - 1):
                if check and not covariance.valid2(state.P, state.P12, state.P22):
                    self._refuse_covariance(state, k)
                state = harmonic.estimator_predict(state, *args, u)
            hidden, outputs = {"_state": state, "_bias": None}, self._outputs(state)
        return hidden, outputs  # (the state after the last sample: the base class checks it)

    def _general_hold(self, hidden, k0, n):
        """The predict-only samples ``k0 + 1 .. k0 + n - 1`` after sample ``k0`` (computed), each
        covariance checked before the next sample is computed from it."""
        outputs = None
        for k in range(k0, k0 + n - 1):
            state, b = hidden["_state"], hidden["_bias"]
            if type(state) is harmonic.HarmonicState:
                if not covariance.valid2(state.P, state.P12, state.P22):
                    self._refuse_covariance(state, k)
            elif b is not None and not covariance.valid2(state.P, b.Pxb, b.Pbb):
                self._refuse_bias_covariance(state, b, k)
            hidden, outputs = self._general_sample(hidden, False)
        return hidden, outputs

    def _refuse_covariance(self, state, k):
        """Refuse sample ``k`` (not the last of a step) whose harmonic state's covariance is not
        valid, when its entries are finite (a non-finite one stays so, and the check of the
        last sample refuses it as an overflow)."""
        zero = 0.0 * state.P + 0.0 * state.P12 + 0.0 * state.P22
        if zero == 0.0:
            self._fail(self.covariance_refusal({"_state": state, "_bias": None}, k))

    def _refuse_bias_covariance(self, state, b, k):
        """The same for the bias filter's covariance (P, P_xb, P_bb)."""
        zero = 0.0 * state.P + 0.0 * b.Pxb + 0.0 * b.Pbb
        if zero == 0.0:
            self._fail(self.covariance_refusal({"_state": state, "_bias": b}, k))

    def hidden_valid(self, hidden):
        # x, P and the drift sums reach the outputs (x_hat, P, dc_ekf1 = a2 s1, dc_ekf2 = dc2,
        # dc_ekf3 from a2 s3 and dc3), so a non-finite one makes an output non-finite, which the
        # base class refuses first; the harmonic model's d, P12 and P22 do not reach them, and
        # its covariance (P, P12, P22) must be valid (models/covariance.py); the bias part's
        # b, Pxb, Pbb reach b_hat, P_xb, P_bb, and the covariance (P, Pxb, Pbb) must be valid
        state = hidden["_state"]
        if type(state) is harmonic.HarmonicState:
            zero = 0.0 * state.d + 0.0 * state.P12 + 0.0 * state.P22  # 0, or nan if any is not
            return zero == 0.0 and covariance.valid2(state.P, state.P12, state.P22)
        b = hidden.get("_bias")
        if b is not None:
            return covariance.valid2(state.P, b.Pxb, b.Pbb)
        return True

    def covariance_refusal(self, hidden, k):
        b = hidden.get("_bias")
        if b is not None:
            lower = bias.covariance_of(hidden["_state"], b)
            if covariance.valid(lower):
                return None
            return covariance.refusal(bias.COVARIANCE_NAMES, lower, k, self._sample_time(k))
        lower = harmonic.covariance_of(hidden["_state"])
        if lower is None or covariance.valid(lower):
            return None
        return covariance.refusal(COVARIANCE_NAMES, lower, k, self._sample_time(k),
                                  COVARIANCE_LISTING)

    def parse_hidden(self, name, value):
        if value is None:
            return None
        if name == "_bias":
            if not (isinstance(value, list) and len(value) == len(bias.Bias._fields)):
                raise ValueError("not a bias state [b, Pxb, Pbb]")
            for v in value:
                if not (isinstance(v, (int, float)) and not isinstance(v, bool)
                        and math.isfinite(v)):
                    raise ValueError("%r is not a finite number" % (v,))
            return bias.Bias(*value)
        check_estimator_plain(value, (3, 6), (5, len(drift.DriftState._fields)),
                              "an estimator state [x, P, drift] or [x, d, P, P12, P22, drift]",
                              "a drift-estimator state [k, s1, dc2, s3, dc3]")
        return harmonic.from_plain(value)

    def hidden_problems(self, hidden):
        state, b = hidden["_state"], hidden["_bias"]
        harmonic_state = isinstance(state, harmonic.HarmonicState)
        if harmonic_state != (self.process == harmonic.HARMONIC):
            return ["the estimator state does not belong to process = %r" % (self.process,)]
        if (b is not None) != (self.bias == 1):
            return ["the hidden state _bias = %s does not belong to bias = %r; allowed: %s"
                    % ("null" if b is None else list(b), self.bias,
                       "[b, Pxb, Pbb] with bias = 1" if b is None else "null with bias = 0")]
        if b is not None:
            return covariance.state_problems(BIAS_STATE_COVARIANCE_NAMES,
                                             bias.covariance_of(state, b), BIAS_STATE_LISTING)
        lower = harmonic.covariance_of(state) or ((state.P,),)
        names = STATE_COVARIANCE_NAMES[:len(lower)]
        return covariance.state_problems(names, lower, COVARIANCE_LISTING)
