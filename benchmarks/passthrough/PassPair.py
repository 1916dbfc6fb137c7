"""Floor of the ADXL203 benchmark: a pythonfmu FMU with the Excitation's two outputs, held."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class PassPair(Fmi2Slave):
    """Pass-through source: outputs x and y, held."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = 0.5
        self.y = 0.25
        self.register_variable(Real("x", causality=Fmi2Causality.output))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        return True
