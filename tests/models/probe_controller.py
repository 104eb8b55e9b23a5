"""A stand-in controller FMU (PythonFMU, FMI 2.0 Co-Simulation) that reveals a master's call order.

It has the interface of the project's controller FMU ToggleVSC (inputs x_B, v_B, theta1, omega1;
output iq_ref first, then diagnostics) and its sampling semantics (docs/other-masters.md): the
output at a communication point is the law evaluated at (t_k, the current inputs); setting an
input marks it stale and a get re-evaluates a stale output; doStep evaluates a stale sample,
then advances to t_{k+1} = start + (k+1) T_s and HOLDS the sample just taken until an input is
set. The law is a PD law simple enough to recompute anywhere:

    iq_ref = K (x_star - x_B) - D v_B

The diagnostics record what the controller saw: t_s (the time of the sample that produced
iq_ref), x_seen and v_seen (the inputs at that sample), x_first (x_B at the first sample,
re-taken at every evaluation until the first doStep returns, like ToggleVSC's law start) and
n_eval (how many times the law has been evaluated); t_do is the communication point the master
passed to the last doStep (0 before the first). A doStep whose step is not T_s is refused, and so is
an evaluation with x_B < x_min (as ToggleVSC refuses an x_B out of the mechanism's reach):
the exception becomes an error status.
Build: pythonfmu build -f tests/models/probe_controller.py -d DIR
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real

INPUTS = ("x_B", "v_B", "theta1", "omega1")
OUTPUTS = ("iq_ref", "t_s", "x_seen", "v_seen", "x_first", "n_eval", "t_do")
PARAMETERS = {"K": 400.0, "D": 40.0, "x_star": 0.2, "T_s": 5e-4, "x_min": 0.05}


class ProbeController(Fmi2Slave):
    author = "toggle-cosim tests"
    description = "PD stand-in controller that records the call order of a co-simulation master"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.x_B, self.v_B, self.theta1, self.omega1 = 0.2329, 0.0, 0.0, 0.0
        self.K, self.D, self.x_star, self.T_s, self.x_min = PARAMETERS.values()
        self._start, self._k, self._stale, self._stepped = 0.0, 0, True, False
        self._out = dict.fromkeys(OUTPUTS, 0.0)
        for name in INPUTS:
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.input,
                    getter=lambda n=name: getattr(self, n),
                    setter=self._setter(name),
                )
            )
        for name in PARAMETERS:
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        for name in OUTPUTS:
            self.register_variable(
                Real(
                    name,
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.discrete,
                    getter=self._getter(name),
                )
            )

    def _setter(self, name: str):
        def set_input(value: float) -> None:
            setattr(self, name, value)
            self._stale = True

        return set_input

    def _getter(self, name: str):
        def get_output() -> float:
            if self._stale:
                self._evaluate()
            return self._out[name]

        return get_output

    def _evaluate(self) -> None:
        if not self.x_B >= self.x_min:  # like ToggleVSC refusing an x_B out of the mechanism's reach
            raise ValueError(f"x_B = {self.x_B} m is out of reach (below x_min = {self.x_min} m) at t = {self._k} T_s")
        out = self._out
        out["iq_ref"] = self.K * (self.x_star - self.x_B) - self.D * self.v_B
        out["t_s"] = self._start + self._k * self.T_s
        out["x_seen"], out["v_seen"] = self.x_B, self.v_B
        if not self._stepped:
            out["x_first"] = self.x_B
        out["n_eval"] += 1.0
        self._stale = False

    def setup_experiment(self, start_time, stop_time, tolerance) -> None:
        self._start = start_time

    def do_step(self, current_time: float, step_size: float) -> bool:
        if abs(step_size - self.T_s) > 1e-9 * self.T_s:
            return False
        if self._stale:
            self._evaluate()
        self._out["t_do"] = current_time
        self._k += 1
        self._stepped = True
        return True
