"""A python-control discrete-time system as a controller (`control.protocol`).

The system (a `control.StateSpace` or `control.TransferFunction` with sample time dt = T_s and
one output, the command i_q* [A]) reads one plant output y (`output`, e.g. x_B in m) and its
reference r: the sampled `stroke.trajectory` x*(t_k) when the run has one, else the constant
`target`. It has one input or two:

* one input, the error e = r − y (a PID on the error, as the built-in laws' e);
* two inputs, u = [r − y0, y − y0] in that order (the reference, then the measurement, both in
  the output's unit and measured from y0, the output's value at the first sample, so the system
  at rest, x = 0, starts where the plant is): one system that treats them apart, e.g. a 2-DOF PID
  with its derivative on the measurement and a setpoint weight, which gives no kick at the start.

On the matrices of its state-space form (a transfer function is converted by `control.ss`, the
realisation python-control gives)::

    x[0] = 0,    i_q*[k] = C x[k] + D u[k],    x[k+1] = A x[k] + B u[k]

The products are evaluated by `lti_step` as explicit sums in a fixed order (row by row, column 0
first, then the input terms, input 0 first) rather than by numpy's matmul, whose BLAS may sum in
another order: the compiled system loop (`cosim.execution.system_loop`, lti_sums.c) runs the same sums in C,
so both forms give the same bits. The command is not clipped or saturated. The diagnostic recorded in the trace
is e = r − y for either form; the state is an `LtiState` (x and y0).

A continuous-time system is refused unless a discretisation method is named (`discretise`,
`DISCRETISE_METHODS`), which `control.sample_system` applies at T_s. python-control is imported
by whoever built the system; this module only uses it then.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.control.trajectory import SampledReference

__all__ = ["DISCRETISE_METHODS", "DiscreteSystemController", "LtiMatrices", "LtiState", "discrete_system", "lti_step"]

# control.sample_system's methods a scenario may name (controller.discretise)
DISCRETISE_METHODS = ("tustin", "zoh", "foh", "euler", "backward_diff", "matched")
INPUTS = {1: "e = r − y", 2: "[r − y0, y − y0]"}  # the two signal conventions, by the number of inputs


@dataclass(frozen=True)
class LtiMatrices:
    """A discrete-time realisation with one output as Python floats: A row by row (n × n), B row
    by row (n × m), C (n), D (m); m is the number of inputs (1: the error; 2: reference and
    measurement)."""

    A: tuple[tuple[float, ...], ...]
    B: tuple[tuple[float, ...], ...]
    C: tuple[float, ...]
    D: tuple[float, ...]

    @property
    def n(self) -> int:
        """The number of states."""
        return len(self.C)

    @property
    def m(self) -> int:
        """The number of inputs."""
        return len(self.D)


@dataclass(frozen=True)
class LtiState:
    """The adapter's state at a sample: the system's x, and y0, the measured output at the first
    sample (the origin of a two-input system's inputs)."""

    x: tuple[float, ...]
    origin: float


def lti_step(m: LtiMatrices, x: tuple[float, ...], u: tuple[float, ...]) -> tuple[float, tuple[float, ...]]:
    """(y, x_next): y = C x + D u, x_next = A x + B u, each sum from 0.0, column 0 first, the input
    terms last, input 0 first (the order lti_sums.c's lti_sums sums in)."""
    y = 0.0
    for c, xj in zip(m.C, x, strict=True):
        y += c * xj
    for d, v in zip(m.D, u, strict=True):
        y += d * v
    following = []
    for row, b_row in zip(m.A, m.B, strict=True):
        acc = 0.0
        for a, xj in zip(row, x, strict=True):
            acc += a * xj
        for b, v in zip(b_row, u, strict=True):
            acc += b * v
        following.append(acc)
    return y, tuple(following)


def discrete_system(system: Any, T_s: float, discretise: str | None = None) -> Any:
    """`system` as a discrete-time system at T_s: itself if it already is one (dt = T_s), or
    sampled by `control.sample_system` with the method `discretise` if it is continuous-time.
    Raises ValueError (one line, saying what is wrong and the fix) for a continuous system
    without a method, an unknown method, a method for a system that is already discrete, or a
    dt other than T_s."""
    import control  # present: the system is one of its objects

    dt = system.dt
    if discretise is not None and discretise not in DISCRETISE_METHODS:
        raise ValueError(f"controller.discretise: {discretise!r} is not one of {', '.join(DISCRETISE_METHODS)}")
    if dt is None or dt is True:
        raise ValueError(f"a system without a sample time (dt = {dt}); give dt = T_s = {T_s:g} s")
    if dt is False or dt == 0:
        if discretise is None:
            raise ValueError(
                f"a continuous-time system (dt = 0); sample it at T_s = {T_s:g} s (control.sample_system(sys, {T_s:g},"
                f" method='tustin')), or name the method in controller.discretise ({' | '.join(DISCRETISE_METHODS)})"
            )
        return control.sample_system(system, T_s, method=discretise)
    if discretise is not None:
        raise ValueError(
            f"a discrete-time system (dt = {dt:g} s) with controller.discretise: {discretise}; only a continuous-time"
            " system is discretised (remove controller.discretise)"
        )
    if not math.isclose(float(dt), T_s, rel_tol=1e-9, abs_tol=0.0):
        raise ValueError(f"a system with dt = {dt:g} s, not the run's T_s = {T_s:g} s (give dt = T_s)")
    return system


class DiscreteSystemController:
    """Adapts a python-control system with one output (the command) to the controller protocol.

    Args:
        system: the python-control system (StateSpace or TransferFunction): discrete-time with
            dt = T_s, or continuous-time with `discretise` naming the method.
        output: the plant output y it reads (its measurement).
        target: the constant reference r of y (used when there is no `reference`).
        T_s: the run's sample time [s].
        reference: the run's sampled trajectory (`SampledReference`), whose q*(t) is r; None:
            the constant `target`.
        discretise: a method of `DISCRETISE_METHODS` for a continuous-time system; None: the
            system must be discrete-time already.

    One input: the system acts on e = r − y; two inputs: on [r − y0, y − y0], y0 the output at the
    first sample. Raises ValueError (one line,
    saying what is wrong with the system and the fix) for a system that is not discrete-time with
    dt = T_s (nor discretised), or that has other than one output and one or two inputs.
    """

    diagnostics: ClassVar[tuple[str, ...]] = ("e",)

    def __init__(
        self,
        system: Any,
        output: str,
        target: float,
        T_s: float,
        *,
        reference: SampledReference | None = None,
        discretise: str | None = None,
    ) -> None:
        import control  # present: the system is one of its objects

        system = discrete_system(system, T_s, discretise)
        if system.ninputs not in INPUTS or system.noutputs != 1:
            raise ValueError(
                f"a system with {system.ninputs} inputs and {system.noutputs} outputs; the controller needs one output"
                " (the command i_q* in A) and one input (the error e = r − y) or two (the reference r, then the"
                " measurement y, both from y at the start)"
            )
        self.system = control.ss(system) if isinstance(system, control.TransferFunction) else system
        self.output, self.target, self.reference = output, float(target), reference
        self.measured = (output,)  # the plant output the controller reads
        s = self.system
        self.matrices = LtiMatrices(
            tuple(tuple(float(a) for a in row) for row in s.A),
            tuple(tuple(float(b) for b in row) for row in s.B),
            tuple(float(c) for c in s.C[0, :]),
            tuple(float(d) for d in s.D[0, :]),
        )

    def start(self, t0: float, measurement: Mapping[str, float]) -> LtiState:
        """The system at rest, x = 0, and y0 = the measured output at t0."""
        return LtiState((0.0,) * self.matrices.n, float(measurement[self.output]))

    def step(self, state: LtiState, t: float, measurement: Mapping[str, float]) -> ControlStep:
        """i_q* = C x + D u and x ← A x + B u (`lti_step`); u = (e,), e = r − y, or
        u = (r − y0, y − y0)."""
        r = self.target if self.reference is None else self.reference.at(t)[0]
        y = measurement[self.output]
        e = r - y
        u = (e,) if self.matrices.m == 1 else (r - state.origin, y - state.origin)
        command, following = lti_step(self.matrices, state.x, u)
        return ControlStep(command, (e,), LtiState(following, state.origin))
