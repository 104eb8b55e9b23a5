"""A current drive for the SSP system tests (PythonFMU, FMI 2.0 CS): its output i follows its
input iq_ref at once, and a Boolean output says whether |iq_ref| exceeds i_max (an input named
iq_ref like the plant's, so the reader must tell the plant from it by the plant contract)."""

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Drive(Fmi2Slave):
    author = "toggle-cosim tests"
    description = "A current drive: i = iq_ref"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.i_max = 10.0
        self.iq_ref = 0.0
        self.register_variable(Real("i_max", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("iq_ref", causality=Fmi2Causality.input))
        self.register_variable(Real("i", causality=Fmi2Causality.output, getter=lambda: self.iq_ref))
        self.register_variable(
            Boolean("saturated", causality=Fmi2Causality.output, getter=lambda: abs(self.iq_ref) > self.i_max)
        )

    def do_step(self, current_time: float, step_size: float) -> bool:
        return True
