"""TEMPLATE plant to copy: slider B as a mass on a guide, driven by a thrust constant times
iq_ref, with Coulomb friction on the guide, written with PythonFMU (FMI 2.0 Co-Simulation).

It has only what the plant contract requires (src/toggle_cosim/plant/contract.yaml: inputs
iq_ref, F_E; outputs x_B, v_B; parameters m_B, mu) and the optional parameter x_B0, which the
run sets to the scenario's stroke.x_start. PythonFMU writes no units; the contract check warns
about that and accepts the FMU. Build it with

    pythonfmu build -f examples/pythonfmu_plant/guided_mass.py -d fmus
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

G = 9.81  # m/s²
K_F = 56.96  # N/A, thrust constant of the drive


class GuidedMass(Fmi2Slave):
    author = "toggle-cosim template"
    description = "Slider B as a mass on a guide with Coulomb friction (template plant)"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.iq_ref, self.F_E = 0.0, 0.0
        self.m_B, self.mu, self.x_B0 = 4.43, 0.2, 0.2329
        self.x_B, self.v_B = self.x_B0, 0.0
        for name in ("iq_ref", "F_E"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("m_B", "mu", "x_B0"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        for name in ("x_B", "v_B"):
            self.register_variable(Real(name, causality=Fmi2Causality.output))

    def exit_initialization_mode(self) -> None:
        self.x_B, self.v_B = self.x_B0, 0.0

    def do_step(self, current_time: float, step_size: float) -> bool:
        """Exact motion under the constant drive over the step, in pieces split where v_B
        reaches zero (there the slider sticks while the drive is within the static friction)."""
        drive = K_F * self.iq_ref - self.F_E
        friction = self.mu * self.m_B * G
        left = step_size
        while left > 0.0:
            if self.v_B == 0.0 and abs(drive) <= friction:
                break  # stuck for the rest of the step
            direction = self.v_B if self.v_B != 0.0 else drive
            a = (drive - (friction if direction > 0.0 else -friction)) / self.m_B
            h = left
            if self.v_B * a < 0.0:  # decelerating: v_B reaches zero within the step?
                h = min(h, -self.v_B / a)
            self.x_B += self.v_B * h + 0.5 * a * h * h
            self.v_B = 0.0 if h < left else self.v_B + a * h
            left -= h
        return True
