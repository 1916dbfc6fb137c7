"""Baseline for the step benchmark: a pythonfmu FMU copying its input to its output."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class PassOne(Fmi2Slave):
    """Pass-through: z = x."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.0
        self.z = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Real("z", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.z = self.x
        return True
