"""A python-control discrete-time system as a controller (`control.protocol`).

The system (a `control.StateSpace` or `control.TransferFunction` with sample time dt = T_s,
one input and one output) acts on the error of one plant output, e = target − measurement[output],
and its output is the command i_q* [A]::

    x[0] = 0,    u[k] = C x[k] + D e[k],    x[k+1] = A x[k] + B e[k]

on the matrices of the system's state-space form (a transfer function is converted by
`control.ss`, the realisation python-control gives). The products are evaluated by `lti_step`
as explicit sums in a fixed order (row by row, column 0 first, the D or B term last) rather than
by numpy's matmul, whose BLAS may sum in another order: the compiled loop
(`cosim.compiled_loop`) runs the same sums in C, so both loops give the same bits. The
command is not clipped or saturated. The diagnostic recorded in the trace is e; the state is
a tuple of floats. python-control is imported by whoever built the system; this module only
uses it then.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from toggle_cosim.control.protocol import ControlStep

__all__ = ["DiscreteSystemController", "LtiMatrices", "lti_step"]


@dataclass(frozen=True)
class LtiMatrices:
    """A SISO discrete-time realisation as Python floats: A row by row (n × n), B, C (n each), D."""

    A: tuple[tuple[float, ...], ...]
    B: tuple[float, ...]
    C: tuple[float, ...]
    D: float

    @property
    def n(self) -> int:
        """The number of states."""
        return len(self.B)


def lti_step(m: LtiMatrices, x: tuple[float, ...], e: float) -> tuple[float, tuple[float, ...]]:
    """(u, x_next): u = C x + D e, x_next = A x + B e, each sum from 0.0, column 0 first, the input
    term last (the order loop_skeleton.c's lti_control sums in)."""
    u = 0.0
    for c, xj in zip(m.C, x, strict=True):
        u += c * xj
    u += m.D * e
    following = []
    for row, b in zip(m.A, m.B, strict=True):
        acc = 0.0
        for a, xj in zip(row, x, strict=True):
            acc += a * xj
        following.append(acc + b * e)
    return u, tuple(following)


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
        self.measured = (output,)  # the plant output the error is formed from
        s = self.system
        self.matrices = LtiMatrices(
            tuple(tuple(float(a) for a in row) for row in s.A),
            tuple(float(b) for b in s.B[:, 0]),
            tuple(float(c) for c in s.C[0, :]),
            float(s.D[0, 0]),
        )

    def start(self, t0: float, measurement: Mapping[str, float]) -> tuple[float, ...]:
        """The system's state at rest, x = 0."""
        return (0.0,) * self.matrices.n

    def step(self, state: tuple[float, ...], t: float, measurement: Mapping[str, float]) -> ControlStep:
        """u = C x + D e and x ← A x + B e, for e = target − measurement[output] (`lti_step`)."""
        e = self.target - measurement[self.output]
        u, following = lti_step(self.matrices, state, e)
        return ControlStep(u, (e,), following)
