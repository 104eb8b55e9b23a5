"""A stand-in for the controller FMU ToggleVSC (PythonFMU, FMI 2.0 CS), for the SSP tests: the
same variables (inputs x_B, v_B, theta1, omega1; outputs iq_ref, S, phase, e, z; the parameters of
LawParameters but t0 and T_h; not the reference inputs x_ref, v_ref, a_ref, which an SSP leaves
unconnected), with a proportional law in place of the VSC."""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

PARAMETERS = (
    "law objective target C Q P delta beta C_I K_I i_max T_s K_f r1 r3 r4 r5 f h phi m3 m5 mB mC J2 J3 J5 g tracking"
).split()


class ToggleVSC(Fmi2Slave):
    author = "toggle-cosim tests"
    description = "Stand-in for ToggleVSC: the same variables, a proportional law"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        for name in PARAMETERS:
            setattr(self, name, 1.0)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        for name in ("x_B", "v_B", "theta1", "omega1"):
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("iq_ref", "S", "phase", "e", "z"):
            setattr(self, name, 0.0)
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def do_step(self, current_time: float, step_size: float) -> bool:
        self.e = self.target - self.x_B
        self.iq_ref = self.C * self.e
        return True
