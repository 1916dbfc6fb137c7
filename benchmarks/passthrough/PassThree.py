"""Floor of the ADXL203 benchmark: a pythonfmu FMU with the DriftEstimator's input and the
three outputs the experiment records."""
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class PassThree(Fmi2Slave):
    """Pass-through: x_hat = z; P and dc_ekf1 held."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.z = self.x_hat = self.P = self.dc_ekf1 = 0.0
        self.register_variable(Real("z", causality=Fmi2Causality.input))
        for name in ("x_hat", "P", "dc_ekf1"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.x_hat = self.z
        return True
