"""Internal (not a stable API; use driftfmu.build_fmus instead).

Accelerometer FMU: the weakly nonlinear sensor z = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 + v
(a3 = a4 = 0: the letter's specific case), and the richer
dual-axis part (cubic term, cross-axis coupling, output low-pass, ratiometric output, ADC,
noise density) of :mod:`driftfmu.models.adxl203`, every extra off by default; or (``dual = 1``) the
dual-axis bilinear sensor of :mod:`driftfmu.models.dualaxis`, z = a0 + a1 x + a2 x^2 + bx x y + v_x and
z_y = a0y + a1y y + a2y y^2 + by x y + v_y.

The first axis also has the slow errors of :mod:`driftfmu.models.errors` (the letter's drift
classes 2 to 4: turn-on bias, random walk, Gauss-Markov and flicker bias, exposure drift, the
tilt and temperature inputs ``theta`` and ``T``, and the range), every one off by default; their
state is the hidden ``_err``."""

import math

from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, Blocks, SlaveBase, var, _is_number
from driftfmu.models import adxl203, dualaxis, errors
from driftfmu.models.noise import ziggurat

#: The parameters that switch a slow error on (:mod:`driftfmu.models.errors`; 0: off).
ERROR_SWITCHES = ("bias_on", "random_walk", "bias_gm", "flicker", "d_inf", "kT_bias",
                  "kT_scale", "range")


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
        var("fc", "parameter", high=adxl203.MAX_BANDWIDTH),
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
        var("a4", "parameter"),
        # the slow errors of models.errors (the letter's drift classes 2 to 4) and the range
        var("bias_on", "parameter"),
        var("random_walk", "parameter"),
        var("bias_gm", "parameter"),
        var("tau_gm", "parameter"),
        var("flicker", "parameter"),
        var("tau_min", "parameter"),
        var("tau_max", "parameter"),
        var("d_inf", "parameter"),
        var("E_tau", "parameter"),
        var("T0", "parameter"),
        var("kT_bias", "parameter"),
        var("kT_scale", "parameter"),
        var("range", "parameter"),
        var("theta", "input"),
        var("T", "input"),
    )
    DEPENDENCIES = {"z": ["x", "y", "theta", "T"], "z_y": ["x", "y"]}
    DESCRIPTION = ("Weakly nonlinear accelerometer z_k = a0 + a1 x_k + a2 x_k^2 + a3 x_k^3 "
                   "+ a4 x_k^4 + v_k, "
                   "v_k ~ N(0, R); optional ADXL203-like extras (cross-axis, output "
                   "low-pass, ratiometric supply, ADC, noise density, second axis); or (dual = 1) the "
                   "dual-axis bilinear sensor z_x = a0 + a1 x + a2 x^2 + bx x y + v_x, "
                   "z_y = a0y + a1y y + a2y y^2 + by x y + v_y; slow errors of the first axis "
                   "(the letter's drift classes 2-4: turn-on bias, random walk, Gauss-Markov and "
                   "flicker bias, exposure drift, tilt theta and temperature T inputs) and a "
                   "measurement range, off by default")
    #: Output filter states after the last sample (None before the first), per axis, and the
    #: slow errors' state (:class:`driftfmu.models.errors.ErrorState`; None while all are off).
    HIDDEN = ("_lp", "_lpy", "_err")
    #: (z alone while the second axis is off: z_y keeps its value)
    OUTPUTS = ("z", "z_y")
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = (super().check_parameters() + adxl203.problems(self.parameter_values())
                    + dualaxis.sensor_problems(self.parameter_values()))
        if self.dual and self.a4 != 0.0:
            problems.append("dual = 1 is not allowed with a4 = %r; allowed: dual = 1 with a4 = 0 "
                            "(the bilinear sensor is of 2nd order)" % (self.a4,))
        problems += errors.problems(self.parameter_values())
        on = [name for name in ERROR_SWITCHES if getattr(self, name) != 0.0]
        if self.dual and on:
            problems.append("dual = 1 is not allowed with %s; allowed: dual = 1 with %s = 0 (the "
                            "slow errors and the range act on the single-axis sensor)"
                            % (", ".join("%s = %r" % (n, getattr(self, n)) for n in on),
                               ", ".join(ERROR_SWITCHES)))
        if not problems:
            cfg = adxl203.config(**self.parameter_values())
            for name in ("a0", "a1", "a2", "a3", "sigma", "a4"):
                value = getattr(cfg, name)
                if not math.isfinite(value):
                    problems.append(
                        "the parameters give the effective %s = %r (a1, a2, a3, a4 and the noise "
                        "are scaled by S(Vs)/S(5 V) and density by sqrt(1/(2 Ts))); allowed: "
                        "parameters whose effective values are finite" % (name, value))
            for name in ("lo", "lsb"):
                value = getattr(cfg, name)
                if not math.isfinite(value):
                    problems.append(
                        "the ADC over a0 +- |a1| range gives %s = %r; allowed: a0, a1 and range "
                        "whose span is finite" % (name, value))
            ecfg = errors.config(**self.parameter_values())
            for name in ("b_on", "rw", "gm_c", "fl_sigma"):
                value = getattr(ecfg, name)
                if not math.isfinite(value):
                    problems.append(
                        "the parameters give the slow errors' %s = %r (b_on = bias_on n_0, rw = "
                        "random_walk sqrt(Ts), gm_c = bias_gm sqrt(1 - exp(-2 Ts/tau_gm)), "
                        "fl_sigma = flicker over the Allan deviation of the unit components); "
                        "allowed: parameters whose effective values are finite" % (name, value))
        return problems

    def prepare(self):
        values = self.parameter_values()
        self._cfg = adxl203.config(**values)
        self._axes = dualaxis.axes(values)
        seed = self.seed  # the noise draws of both axes, a pure function of k: in blocks
        self._v = (None, self.blocks("v1", seed, lambda k: adxl203.noise(seed, k, 1)),
                   self.blocks("v2", seed, lambda k: adxl203.noise(seed, k, 2)))
        ecfg = self._ecfg = errors.config(**values)
        # the slow errors' draws (errors.draws), each stream in blocks (their warm-up shared:
        # the streams' samples one by one cost, together, what the measurement noise's do); an
        # error state to check
        streams = (ecfg.rw != 0.0) + (ecfg.gm_sigma != 0.0) + ecfg.fl_n
        warm_up = Blocks.WARM_UP // (1 + streams)
        self._n_rw = self._stream("rw", 0, seed, warm_up) if ecfg.rw != 0.0 else None
        self._n_gm = self._stream("gm", 0, seed, warm_up) if ecfg.gm_sigma != 0.0 else None
        self._n_fl = tuple(self._stream("fl", i, seed, warm_up) for i in range(ecfg.fl_n))
        self._rows_k0, self._rows = 0, ()  # the draws of a block of samples, as _draws gives them
        # the input-independent processes in runs of samples (errors.run, _row)
        self._runs = ecfg.rw != 0.0 or ecfg.gm_sigma != 0.0 or ecfg.fl_n != 0
        self._run, self._run_k0, self._run_from, self._run_size = (), 0, None, RUN_FIRST
        self._last_in = self._last = None  # the error state given and made by the last sample
        self._chain = 0  # samples that followed one another since the last that did not
        self.hidden_valid = self._errors_valid if ecfg.on else None

    def _stream(self, name, i, seed, warm_up):
        stream = errors.stream_of(name, i)
        return self.blocks("%s%d" % (name, i), seed, lambda k: ziggurat(seed, stream, k), warm_up)

    def _row(self, err, k):
        """errors.run's row of sample ``k`` from ``err``, the error state after sample ``k -
        1``: from the run in store where ``err`` holds the very numbers that run left at ``k -
        1`` (the same objects, so the same values); else None, and the sample is computed on its
        own (errors.advance).  A new run starts from ``err`` once :data:`RUN_AFTER` samples in a
        row have each started from the state the one before made (a master that restores states
        often never pays for a run it does not use), with :data:`RUN_FIRST` samples, and the
        next one, where a run was used to its end, with twice as many (at most Blocks.SIZE), over
        the draws the blocks hold from ``k`` (None while they run sample by sample)."""
        run, i = self._run, k - self._run_k0
        if 0 <= i <= len(run):
            prev = run[i - 1] if i else self._run_from
            if err[3] is prev[2] and err[0] is prev[0] and err[1] is prev[1]:  # (fl, rw, gm)
                if i < len(run):
                    return run[i]
                return self._new_run(err, k, min(2 * self._run_size, Blocks.SIZE))
        if err is self._last:
            self._chain += 1
        elif err is not self._last_in:  # (the same sample again, other inputs: no break)
            self._chain = 0
        if self._chain >= RUN_AFTER:
            return self._new_run(err, k, RUN_FIRST)
        return None

    def _new_run(self, err, k, size):
        """A run of errors.run from ``err`` at sample ``k`` (at most ``size`` samples, to the end
        of the blocks of draws); its first row, or None where the blocks run sample by
        sample."""
        streams = (self._n_rw, self._n_gm) + self._n_fl
        draws = [None if b is None else b.run(k) for b in streams]
        if any(b is not None and d is None for b, d in zip(streams, draws)):
            self._chain = 0  # (the warm-up: a run once RUN_AFTER more samples followed)
            return None
        n = min(size, min(len(d) for d in draws if d is not None))
        draws = [None if d is None else d[:n] for d in draws]
        self._run = errors.run(err, (draws[0], draws[1], tuple(draws[2:])), self._ecfg)
        self._run_k0, self._run_from, self._run_size = k, (err.rw, err.gm, err.fl), size
        return self._run[0]

    def _draws(self, k):
        """errors.draws(seed, k, ecfg), from the blocks: the tuples of a run of samples from
        them at once where they hold arrays of draws (Blocks.run), one by one otherwise."""
        i = k - self._rows_k0
        rows = self._rows
        if 0 <= i < len(rows):
            return rows[i]
        streams = [b for b in (self._n_rw, self._n_gm) + self._n_fl if b is not None]
        runs = [b.run(k) for b in streams]
        if not runs or None in runs:
            n_rw, n_gm = self._n_rw, self._n_gm
            return (0.0 if n_rw is None else n_rw(k), 0.0 if n_gm is None else n_gm(k),
                    tuple([f(k) for f in self._n_fl]))
        n = min(map(len, runs))
        runs = [r[:n] for r in runs]
        zeros = [0.0] * n
        rw = runs.pop(0) if self._n_rw is not None else zeros
        gm = runs.pop(0) if self._n_gm is not None else zeros
        self._rows_k0, self._rows = k, list(zip(rw, gm, zip(*runs) if runs else [()] * n))
        return self._rows[0]

    def _hold_errors(self, err, k, m):
        """errors.hold's state after the ``m`` samples from ``k`` with the input held: over the
        runs of draws the blocks hold (errors.hold_run), sample by sample (errors.advance_state)
        where they hold none (no NumPy, the warm-up)."""
        ecfg, x, end = self._ecfg, self.x, k + m
        streams = [b for b in (self._n_rw, self._n_gm) + self._n_fl if b is not None]
        while k < end:
            runs = [b.run(k, end - k) for b in streams]
            if None in runs:
                err = errors.advance_state(err, x, *self._draws(k), ecfg)
                k += 1
                continue
            n = min([end - k] + [len(r) for r in runs])
            runs = iter([r if len(r) == n else r[:n] for r in runs])
            n_rw = next(runs) if self._n_rw is not None else None
            n_gm = next(runs) if self._n_gm is not None else None
            err = errors.hold_run(err, x, n, (n_rw, n_gm, tuple(runs)), ecfg)
            k += n
        return err

    def initial_hidden(self):
        ecfg = self._ecfg
        return {"_lp": None, "_lpy": None,
                "_err": errors.initial_state(self.seed, ecfg) if ecfg.on else None}

    def _axis(self, prev, own, other, k, axis, output):
        v = self._v[axis](k) if self.noise else 0.0  # (adxl203.noise)
        try:
            return adxl203.measure(prev, own, other, v, self._cfg)
        except (OverflowError, ValueError):  # the ADC cannot quantise a non-finite voltage
            cfg = self._cfg
            e = adxl203.lowpass(prev, adxl203.sense(own, other, v, cfg), cfg.alpha)
            self._not_finite(output, cfg.a0 + e, k)

    def _axis_errors(self, prev, err, k):
        """The first axis with the slow errors (adxl203.measure_errors): (lp, err, z)."""
        v = self._v[1](k) if self.noise else 0.0  # (adxl203.noise)
        ecfg = self._ecfg
        if self._runs:  # (the walk, the Gauss-Markov or the flicker bias on: err is a state)
            row = self._row(err, k)
            self._last_in = err
            if row is not None:
                lp, err, z = adxl203.measure_errors_run(prev, err, row, self.x, self.y, v,
                                                        self.theta, self.T, self._cfg, ecfg)
            else:
                lp, err, z = adxl203.measure_errors(prev, err, self.x, self.y, v,
                                                    self._draws(k), self.theta, self.T,
                                                    self._cfg, ecfg)
            self._last = err
            return lp, err, z
        lp, err, z = adxl203.measure_errors(prev, err or OFF_STATE, self.x, self.y, v,
                                            self._draws(k), self.theta, self.T, self._cfg, ecfg)
        return lp, err if ecfg.on else None, z

    def _dual(self, k):
        v = (self._v[1](k), self._v[2](k)) if self.noise else (0.0, 0.0)  # (adxl203.noise)
        z, z_y = dualaxis.measure(self.x, self.y, *self._axes, *v)
        return {"_lp": None, "_lpy": None, "_err": None}, (z, z_y)

    def sample(self, hidden, k, first):
        if self.dual:
            return self._dual(k)
        if self._ecfg.on or self.theta != 0.0:
            lp, err, z = self._axis_errors(hidden["_lp"], hidden["_err"], k)
        else:
            lp, z = self._axis(hidden["_lp"], self.x, self.y, k, 1, "z")
            err = None
        if self.axes != 2:
            return {"_lp": lp, "_lpy": None, "_err": err}, (z,)
        lpy, z_y = self._axis(hidden["_lpy"], self.y, self.x, k, 2, "z_y")
        return {"_lp": lp, "_lpy": lpy, "_err": err}, (z, z_y)

    def show(self, outputs):
        if len(outputs) == 1:
            self.z = outputs[0]
        else:
            self.z, self.z_y = outputs

    #: the filter state e of an axis reaches its output z = Q(a0 + e): a non-finite e makes z
    #: non-finite, or the ADC raises, both refused by the base class.  With a slow error on,
    #: prepare sets the instance's check of the error state (_errors_valid): the walk, the
    #: Gauss-Markov and flicker biases reach z as they are (a non-finite one makes z
    #: non-finite), but an exposure E can overflow while the drift it gives stays finite.
    hidden_valid = None

    @staticmethod
    def _errors_valid(hidden):
        err = hidden["_err"]
        return err is None or err.E - err.E == 0.0

    def hold(self, hidden, k0, n, first):
        if n > 1:  # the samples before the last change only the filter and error states:
            lp, lpy, err, cfg = hidden["_lp"], hidden["_lpy"], hidden["_err"], self._cfg
            if err is not None:  # (adxl203.hold, errors.hold: the same bits, faster)
                err = self._hold_errors(err, k0, n - 1)
            if cfg.alpha is not None:
                own = self.x
                if self._ecfg.on or self.theta != 0.0:
                    own = errors.sensed(own, self.theta, self.T, self._ecfg)
                lp = adxl203.hold(lp, own, self.y, self.seed, k0 - 1, n, cfg, axis=1,
                                  noise_on=self.noise)
                if self.axes == 2:
                    lpy = adxl203.hold(lpy, self.y, self.x, self.seed, k0 - 1, n, cfg, axis=2,
                                       noise_on=self.noise)
            hidden, k0 = {"_lp": lp, "_lpy": lpy, "_err": err}, k0 + n - 1
        return self.sample(hidden, k0, first)

    # -- the error state in an FMU state ------------------------------------------------------
    def parse_hidden(self, name, value):
        if name != "_err":
            return super().parse_hidden(name, value)
        if value is None:
            return None
        if not (isinstance(value, list) and len(value) == 4 and isinstance(value[3], list)):
            raise ValueError("not [rw, gm, E, [flicker components]]")
        for v in value[:3] + value[3]:
            if not (_is_number(v) and math.isfinite(v)):
                raise ValueError("%r is not a finite number" % (v,))
        return errors.ErrorState(float(value[0]), float(value[1]), float(value[2]),
                                 tuple(float(v) for v in value[3]))

    def hidden_problems(self, hidden):
        err = hidden["_err"]
        if err is None:
            return []
        if not self._ecfg.on:
            return ["the hidden state _err is set although every slow error is off (%s = 0); "
                    "allowed: null" % ", ".join(ERROR_SWITCHES)]
        return ["hidden state _err: %s" % p for p in errors.state_problems(err, self._ecfg)]


#: A run of the input-independent processes (Accelerometer._row) starts once this many samples in
#: a row each started from the state the one before made, with RUN_FIRST samples.
RUN_AFTER = 64
RUN_FIRST = 64

#: The error state of a sensor whose errors are off but whose tilt is not 0 (nothing to keep).
OFF_STATE = errors.ErrorState(0.0, 0.0, 0.0, ())
