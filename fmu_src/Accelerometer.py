"""Internal (not a stable API; use driftfmu.build_fmus instead).

Accelerometer FMU: the weakly nonlinear sensor z = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 + v
(a3 = a4 = 0: the letter's specific case), and the richer
dual-axis part (cubic term, cross-axis coupling, output low-pass, ratiometric output, ADC,
noise density) of :mod:`driftfmu.models.adxl203`, every extra off by default; or (``dual = 1``) the
dual-axis bilinear sensor of :mod:`driftfmu.models.dualaxis`, z = a0 + a1 x + a2 x^2 + bx x y + v_x and
z_y = a0y + a1y y + a2y y^2 + by x y + v_y."""

import math

from driftfmu.fmu_src.slave_base import DEFAULT_EXPERIMENT, SlaveBase, var
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
    )
    DEPENDENCIES = {"z": ["x", "y"], "z_y": ["x", "y"]}
    DESCRIPTION = ("Weakly nonlinear accelerometer z_k = a0 + a1 x_k + a2 x_k^2 + a3 x_k^3 "
                   "+ a4 x_k^4 + v_k, "
                   "v_k ~ N(0, R); optional ADXL203-like extras (cross-axis, output "
                   "low-pass, ratiometric supply, ADC, noise density, second axis); or (dual = 1) the "
                   "dual-axis bilinear sensor z_x = a0 + a1 x + a2 x^2 + bx x y + v_x, "
                   "z_y = a0y + a1y y + a2y y^2 + by x y + v_y")
    #: Output filter states after the last sample (None before the first), per axis.
    HIDDEN = ("_lp", "_lpy")
    #: (z alone while the second axis is off: z_y keeps its value)
    OUTPUTS = ("z", "z_y")
    default_experiment = DEFAULT_EXPERIMENT

    def check_parameters(self):
        problems = (super().check_parameters() + adxl203.problems(self.parameter_values())
                    + dualaxis.sensor_problems(self.parameter_values()))
        if self.dual and self.a4 != 0.0:
            problems.append("dual = 1 is not allowed with a4 = %r; allowed: dual = 1 with a4 = 0 "
                            "(the bilinear sensor is of 2nd order)" % (self.a4,))
        if not problems:
            cfg = adxl203.config(**self.parameter_values())
            for name in ("a0", "a1", "a2", "a3", "sigma", "a4"):
                value = getattr(cfg, name)
                if not math.isfinite(value):
                    problems.append(
                        "the parameters give the effective %s = %r (a1, a2, a3, a4 and the noise "
                        "are scaled by S(Vs)/S(5 V) and density by sqrt(1/(2 Ts))); allowed: "
                        "parameters whose effective values are finite" % (name, value))
        return problems

    def prepare(self):
        self._cfg = adxl203.config(**self.parameter_values())
        self._axes = dualaxis.axes(self.parameter_values())
        seed = self.seed  # the noise draws of both axes, a pure function of k: in blocks
        self._v = (None, self.blocks("v1", seed, lambda k: adxl203.noise(seed, k, 1)),
                   self.blocks("v2", seed, lambda k: adxl203.noise(seed, k, 2)))

    def initial_hidden(self):
        return {"_lp": None, "_lpy": None}

    def _axis(self, prev, own, other, k, axis, output):
        v = self._v[axis](k) if self.noise else 0.0  # (adxl203.noise)
        try:
            return adxl203.measure(prev, own, other, v, self._cfg)
        except (OverflowError, ValueError):  # the ADC cannot quantise a non-finite voltage
            cfg = self._cfg
            e = adxl203.lowpass(prev, adxl203.sense(own, other, v, cfg), cfg.alpha)
            self._not_finite(output, cfg.a0 + e, k)

    def _dual(self, k):
        v = (self._v[1](k), self._v[2](k)) if self.noise else (0.0, 0.0)  # (adxl203.noise)
        z, z_y = dualaxis.measure(self.x, self.y, *self._axes, *v)
        return {"_lp": None, "_lpy": None}, (z, z_y)

    def sample(self, hidden, k, first):
        if self.dual:
            return self._dual(k)
        lp, z = self._axis(hidden["_lp"], self.x, self.y, k, 1, "z")
        if self.axes != 2:
            return {"_lp": lp, "_lpy": None}, (z,)
        lpy, z_y = self._axis(hidden["_lpy"], self.y, self.x, k, 2, "z_y")
        return {"_lp": lp, "_lpy": lpy}, (z, z_y)

    def show(self, outputs):
        if len(outputs) == 1:
            self.z = outputs[0]
        else:
            self.z, self.z_y = outputs

    #: the filter state e of an axis reaches its output z = Q(a0 + e): a non-finite e makes z
    #: non-finite, or the ADC raises, both refused by the base class
    hidden_valid = None

    def hold(self, hidden, k0, n, first):
        if n > 1:  # the samples before the last change only the filter state: adxl203.hold
            lp, lpy, cfg = hidden["_lp"], hidden["_lpy"], self._cfg  # (the same bits, faster)
            if cfg.alpha is not None:
                lp = adxl203.hold(lp, self.x, self.y, self.seed, k0 - 1, n, cfg, axis=1,
                                  noise_on=self.noise)
                if self.axes == 2:
                    lpy = adxl203.hold(lpy, self.y, self.x, self.seed, k0 - 1, n, cfg, axis=2,
                                       noise_on=self.noise)
            hidden, k0 = {"_lp": lp, "_lpy": lpy}, k0 + n - 1
        return self.sample(hidden, k0, first)
