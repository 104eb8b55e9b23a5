"""The controllers a system's compiled loop (`cosim.execution.system_loop`) runs natively in C, beside its
FMUs: the built-in law (`VSCController`, either law, tracking its sampled reference or its
constant target) and a python-control system (`control.lti.DiscreteSystemController`).

`native_controller(slave, ...)` says whether a `ControllerSlave`'s controller is one of them
(`compiled_law`, `compiled_controller`: its start and step are the built-in ones, with their
diagnostics and state), and takes over what the slave holds (`SampleState`): the C then samples
it as the slave does (system_skeleton.c), from the generated law (`control.law_c`) and the sums
(`lti_sums`) in Python's order, so the trace has the slave's bits. `NativeController.given_back` turns the C's memory back into a
`SampleState`, for the Python execution to take a sample the C handed back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from toggle_cosim.control.controller import ControllerState, VSCController
from toggle_cosim.control.lti import DiscreteSystemController, LtiMatrices, LtiState
from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.cosim.execution.slaves import ControllerSlave, SampleState

__all__ = [
    "NATIVE_LAW",
    "NATIVE_LTI",
    "NativeController",
    "compiled_controller",
    "compiled_law",
    "native_controller",
]

NATIVE_LAW, NATIVE_LTI = 1, 2  # native_t's kinds (system_skeleton.c)


def _name(function: object) -> str:
    return getattr(function, "__qualname__", repr(function))


def _replaced(controller: object, reference: type, method: str) -> bool:
    """Whether the controller's `method` is not `reference`'s own (overridden by its class, absent,
    or set on the object)."""
    own = getattr(type(controller), method, None)
    return own is not getattr(reference, method) or method in getattr(controller, "__dict__", {})


def compiled_law(controller: object, state: object) -> LawParameters | str:
    """The law the compiled loop may run in place of `controller`, or why it may not.

    The C is the translation of `VSCController.step`, so it runs only a controller whose start
    and step *are* those functions (a subclass that overrides either, or an object of another
    class with the same methods, runs in Python at every sample), with the built-in diagnostics
    and a state `VSCController.start` made."""
    only = "the compiled loop runs only the built-in law and controller FMUs"
    for method in ("step", "start"):
        if _replaced(controller, VSCController, method):
            own = getattr(type(controller), method, None)
            return (
                f"the controller's {method} is {_name(own)}, not the built-in law's {_name(getattr(VSCController, method))}: "
                + only
            )
    if getattr(controller, "diagnostics", None) != VSCController.diagnostics:
        return f"the controller's diagnostics are not the built-in law's: {only}"
    if not isinstance(state, ControllerState) or state.law is None:
        return f"the controller's state is not the built-in law's: {only}"
    return state.law


def compiled_controller(controller: object, state: object) -> LawParameters | DiscreteSystemController | str:
    """What the compiled loop may run in place of `controller`: the built-in law (`compiled_law`),
    a python-control system's adapter whose start and step are `DiscreteSystemController`'s (with
    its diagnostics and a state its start made), or why neither."""
    if not isinstance(controller, DiscreteSystemController):
        return compiled_law(controller, state)
    for method in ("step", "start"):
        if _replaced(controller, DiscreteSystemController, method):
            own = getattr(type(controller), method, None)
            return (
                f"the controller's {method} is {_name(own)}, not {_name(getattr(DiscreteSystemController, method))}: "
                "the compiled loop runs only the latter's sums"
            )
    if controller.diagnostics != DiscreteSystemController.diagnostics:
        return "the controller's diagnostics are not DiscreteSystemController's: the compiled loop records only e"
    if not (isinstance(state, LtiState) and len(state.x) == controller.matrices.n):
        return "the controller's state is not an LtiState of its system's states"
    return controller


@dataclass(frozen=True)
class NativeController:
    """A controller the system loop runs in C: the built-in law (`law`: its parameters with its
    start's t0 and T_h) or an LTI system (`lti`: its matrices, `target` its constant reference,
    `origin` its y0); the positions among its fed inputs of what it reads (`reads`: the law's q
    and qd, the system's y); its reference per sample ((n + 1, 3): q*, q̇*, q̈*; None: the constant
    target); and what the slave held at the first sample the loop runs (`start`)."""

    slave: ControllerSlave
    kind: int
    reads: tuple[int, ...]
    start: SampleState
    reference: np.ndarray | None = None
    law: LawParameters | None = None
    lti: LtiMatrices | None = None
    target: float = 0.0
    origin: float = 0.0

    @property
    def n_state(self) -> int:
        """The size of the state in C: the law's z, or the system's x."""
        return 1 if self.lti is None else self.lti.n

    def state_values(self, state: object) -> tuple[float, ...]:
        """A state of the controller as the C holds it."""
        if isinstance(state, LtiState):
            return state.x
        assert isinstance(state, ControllerState)
        return (state.z,)

    def _state(self, values: Sequence[float]) -> object:
        if self.lti is not None:
            return LtiState(tuple(values), self.origin)
        first = self.start.state
        return first if values[0] == first.z else replace(first, z=float(values[0]))

    def given_back(self, state: Sequence[float], saved: Sequence[float]) -> SampleState:
        """What the slave holds again: the committed `state` and the C's memory `saved` (dirty,
        held, row, next; system_skeleton.c's native_t)."""
        n_held, n_in = len(self.start.held), len(self.start.row)
        values = [float(v) for v in saved]  # Python floats, whatever sequence of numbers `saved` is
        held = tuple(values[1 : 1 + n_held])
        row = tuple(values[1 + n_held : 1 + n_held + n_in])
        following = values[1 + n_held + n_in : 1 + n_held + n_in + self.n_state]
        return SampleState(self._state(state), self._state(following), held, row, saved[0] != 0.0, True)


def _on_grid(reference: object, n: int, T_s: float) -> np.ndarray | None | str:
    if reference is None:
        return None
    values = getattr(reference, "values", None)
    if getattr(reference, "T_s", None) != T_s or not isinstance(values, np.ndarray) or values.shape != (n + 1, 3):
        return "its reference is not sampled on the run's grid (T_s, t_end)"
    return np.ascontiguousarray(values, dtype=np.float64)


def native_controller(slave: ControllerSlave, fed: Sequence[str], n: int, T_s: float) -> NativeController | str:
    """`slave` as a native controller of the system loop, or why it runs in Python. `fed`: its
    fed inputs in the plan's order; n, T_s: the run's last sample and sample time. The slave has
    started (the execution's initialisation computes every component once)."""
    held = slave.sample_state()
    if not held.started:
        return "it has not started"
    controller = slave.controller
    if isinstance(controller, DiscreteSystemController):
        checked = compiled_controller(controller, held.state)
        if isinstance(checked, str):
            return checked
        if not isinstance(held.next, LtiState) or controller.output not in fed:
            return f"its measurement {controller.output} is not connected"
        reference = _on_grid(controller.reference, n, T_s)
        if isinstance(reference, str):
            return reference
        return NativeController(
            slave,
            NATIVE_LTI,
            (fed.index(controller.output),),
            held,
            reference,
            lti=controller.matrices,
            target=controller.target,
            origin=held.state.origin,
        )
    law = compiled_law(controller, held.state)
    if isinstance(law, str):
        return law
    measured = tuple(getattr(controller, "measured", ()))
    if not isinstance(held.next, ControllerState) or any(name not in fed for name in measured):
        return f"its measurements {' and '.join(measured)} are not both connected"
    reference = _on_grid(getattr(controller, "reference", None), n, T_s)
    if isinstance(reference, str):
        return reference
    return NativeController(slave, NATIVE_LAW, tuple(fed.index(name) for name in measured), held, reference, law=law)
