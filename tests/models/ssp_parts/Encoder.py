"""A position sensor for the SSP system tests (PythonFMU, FMI 2.0 CS): y = gain·x, read at once
(y follows x without a step: a direct dependency, as PythonFMU declares for every output)."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Encoder(Fmi2Slave):
    author = "toggle-cosim tests"
    description = "A position sensor: y = gain * x"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.gain = 1000.0
        self.x = 0.0
        self.register_variable(Real("gain", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=lambda: self.gain * self.x))

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True
