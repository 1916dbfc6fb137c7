"""Baseline for the step benchmark: a pythonfmu FMU copying its input to six outputs."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real

OUTPUTS = ("x_hat", "P", "dc_ekf1", "dc_ekf2", "dc_ekf3", "z_comp")


class PassSix(Fmi2Slave):
    """Pass-through: six outputs equal to the input z."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.z = 0.0
        self.register_variable(Real("z", causality=Fmi2Causality.input))
        for name in OUTPUTS:
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        for name in OUTPUTS:
            setattr(self, name, self.z)
        return True
