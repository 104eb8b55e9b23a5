"""A python-control discrete-time system as a controller (`control.protocol`).

The system (a `control.StateSpace` or `control.TransferFunction` with sample time dt = T_s,
one input and one output) acts on the error of one plant output, e = target − measurement[output],
and its output is the command i_q* [A]::

    x[0] = 0,    u[k] = C x[k] + D e[k],    x[k+1] = A x[k] + B e[k]

evaluated by python-control itself (`output` and `dynamics` of the system's state-space form;
a transfer function is converted by `control.ss`). The diagnostic recorded in the trace is e.
python-control is imported by whoever built the system; this module only uses it then.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from toggle_cosim.control.protocol import ControlStep

__all__ = ["DiscreteSystemController"]


class DiscreteSystemController:
    """Adapts a SISO discrete-time python-control system to the controller protocol.

    Args:
        system: the python-control system (StateSpace or TransferFunction, dt = T_s).
        output: the plant output the error is formed from.
        target: its target value; e = target − output.
        T_s: the run's sample time [s]; the system's dt must equal it.

    Raises ValueError (one line, saying what is wrong with the system) for a system that is not
    discrete-time with dt = T_s, or not single-input single-output.
    """

    diagnostics: ClassVar[tuple[str, ...]] = ("e",)

    def __init__(self, system: Any, output: str, target: float, T_s: float) -> None:
        import control  # present: the system is one of its objects

        dt = system.dt
        if dt is None or dt is True:
            raise ValueError(f"a system without a sample time (dt = {dt}); give dt = T_s = {T_s:g} s")
        if dt is False or dt == 0:
            raise ValueError(
                "a continuous-time system (dt = 0); discretise it with sample time T_s (system.sample(T_s)) or give dt = T_s"
            )
        if not math.isclose(float(dt), T_s, rel_tol=1e-9, abs_tol=0.0):
            raise ValueError(f"a system with dt = {dt:g} s, not the run's T_s = {T_s:g} s (give dt = T_s)")
        if system.ninputs != 1 or system.noutputs != 1:
            raise ValueError(
                f"a system with {system.ninputs} inputs and {system.noutputs} outputs; the controller needs one of each"
                " (the error in, the command out)"
            )
        self.system = control.ss(system) if isinstance(system, control.TransferFunction) else system
        self.output, self.target = output, float(target)

    def start(self, t0: float, measurement: Mapping[str, float]) -> np.ndarray:
        """The system's state at rest, x = 0."""
        return np.zeros(self.system.nstates)

    def step(self, state: np.ndarray, t: float, measurement: Mapping[str, float]) -> ControlStep:
        """u = C x + D e and x ← A x + B e, for e = target − measurement[output]."""
        e = self.target - measurement[self.output]
        u = self.system.output(t, state, e)
        following = self.system.dynamics(t, state, e)
        return ControlStep(float(np.asarray(u).reshape(-1)[0]), (e,), following)
