"""Baseline for the step benchmark: a pythonfmu FMU whose output never changes."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class PassSource(Fmi2Slave):
    """Pass-through source: output x, held."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.5
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        return True
