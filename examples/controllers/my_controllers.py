"""Three user controllers for toggle-cosim (docs/controllers.md), each named by a scenario's
controller.python key and built by its factory, factory(context, **controller.parameters):

* `make_pd`: a PD law on slider B written against the controller protocol;
* `make_pid`: a discrete PID as a python-control transfer function (dt = T_s), which
  toggle-cosim adapts (the scenario's controller.error names the error it acts on);
* `make_pid_2dof`: a 2-DOF PID as one python-control state-space system with two inputs, the
  reference and the measurement: the integral on the error, the proportional on a weighted
  reference, the filtered derivative on the measurement only, so the start gives no kick;
* `make_limited_vsc`: the paper's VSC with its command limited to the motor's rating, a
  subclass of the built-in controller that overrides step.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import ControllerContext, ControlStep


class PDController:
    """i_q* = Kp (x_B* − x_B) − Kd v_B [A]; records the error e [m]."""

    diagnostics = ("e",)

    def __init__(self, target: float, Kp: float, Kd: float) -> None:
        self.target, self.Kp, self.Kd = target, Kp, Kd

    def start(self, t0, measurement):  # noqa: ANN001, ANN201 - no state: the law is static
        return None

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        e = self.target - measurement["x_B"]
        return ControlStep(self.Kp * e - self.Kd * measurement["v_B"], (e,), state)


def make_pd(context: ControllerContext, Kp: float, Kd: float) -> PDController:
    return PDController(context.x_target, Kp, Kd)


def make_pid(context: ControllerContext, Kp: float, Ki: float, Kd: float, T_f: float):  # noqa: ANN201
    """C(z) = Kp + Ki T_s z/(z − 1) + Kd (1 − a)/T_s (z − 1)/(z − a), a = exp(−T_s/T_f): a PID
    whose derivative is filtered with time constant T_f, at the run's sample time T_s."""
    import math

    import control

    T_s = context.T_s
    a = math.exp(-T_s / T_f)
    z = control.tf([1.0, 0.0], [1.0], T_s)  # the shift operator
    return Kp + Ki * T_s * z / (z - 1) + Kd * (1 - a) / T_s * (z - 1) / (z - a)


def make_pid_2dof(  # noqa: PLR0913 - a PID's gains and weights
    context: ControllerContext, Kp: float, Ki: float, Kd: float, T_f: float, b: float = 1.0, c: float = 0.0
):  # noqa: ANN201
    """A 2-DOF PID at T_s with inputs [r, y] (reference and measured x_B, both from where x_B starts):

        i_q* = Kp (b r − y) + Ki T_s z/(z − 1) (r − y) + Kd (1 − a)/T_s (z − 1)/(z − a) (c r − y)

    a = exp(−T_s/T_f): the integral acts on the error, the proportional on the reference weighted
    by b, the derivative (filtered with time constant T_f) on c r − y; c = 0 puts it on the
    measurement alone, so a reference step does not kick the command. b = c = 1 is `make_pid`.
    Two states: x1 the integral's sum before this sample, x2 the derivative filter's."""
    import math

    import control

    T_s = context.T_s
    a = math.exp(-T_s / T_f)
    kd = Kd * (1 - a) / T_s  # the derivative's gain at high frequency
    A = [[1.0, 0.0], [0.0, a]]
    B = [[Ki * T_s, -Ki * T_s], [-c, 1.0]]  # x2 ← a x2 + (y − c r)
    C = [[1.0, kd * (1 - a)]]
    D = [[Kp * b + Ki * T_s + kd * c, -(Kp + Ki * T_s + kd)]]
    return control.ss(A, B, C, D, T_s, inputs=["r", "y"], outputs=["iq_ref"])


@dataclass(frozen=True)
class LimitedVSC(VSCController):
    """The built-in VSC, its command clipped to ±limit [A] (its diagnostics are the built-in's)."""

    limit: float = 3.0

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        result = super().step(state, t, measurement)
        return replace(result, command=max(-self.limit, min(self.limit, result.command)))


def make_limited_vsc(context: ControllerContext, limit: float) -> LimitedVSC:
    return LimitedVSC(**context.builtin_arguments(), limit=limit)
