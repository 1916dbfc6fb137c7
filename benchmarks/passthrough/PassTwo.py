"""Floor of the ADXL203 benchmark: a pythonfmu FMU with the dual-axis Accelerometer's inputs
and outputs, copying one to the other."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class PassTwo(Fmi2Slave):
    """Pass-through: z = x, z_y = y."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.x = self.y = self.z = self.z_y = 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.input))
        self.register_variable(Real("z", causality=Fmi2Causality.output))
        self.register_variable(Real("z_y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.z = self.x
        self.z_y = self.y
        return True
