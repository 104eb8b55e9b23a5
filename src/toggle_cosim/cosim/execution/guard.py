"""The finiteness guard, an option of the execution: slots of a plan whose values must be finite.

A guarded input slot is checked as its value is set on its component (early or late, with the
component's set), a guarded output slot as its component's outputs are read; the first value in
that order that is not finite (NaN, an infinity) ends the run at that sample, before the call
that would pass it on. The Python execution (`algorithm.Execution`) and the compiled loop
(`system_loop.SystemLoop`, system_skeleton.c's `unguarded`) check the same slots at the same
points, and both raise `refusal`'s error, so a run ends at the same sample in the same words.

`controller_guard` is the guard a controller FMU runs with: what it measures (its inputs fed by
connections: in the pair, the plant's outputs) and its command, as a native controller guards
its own (`slaves.ControllerSlave`) and as the protocol checks a Python controller's command.
"""

from __future__ import annotations

from dataclasses import dataclass

from toggle_cosim.control.protocol import command_not_finite
from toggle_cosim.cosim.execution.slaves import SlaveError, measured_not_finite
from toggle_cosim.system.plan import SIGNAL, Plan

__all__ = ["FiniteGuard", "controller_guard", "refusal"]


@dataclass(frozen=True)
class FiniteGuard:
    """The guarded slots of a plan (module docstring): `slots`, its fed input slots and output
    slots; per component in stepping order, `inputs[c]` the guarded positions in plan.inputs[c]
    and `outputs[c]` those in plan.outputs[c]."""

    slots: frozenset[int]
    inputs: tuple[frozenset[int], ...]
    outputs: tuple[tuple[int, ...], ...]


def controller_guard(plan: Plan, controller: str, command: str) -> FiniteGuard:
    """The guard of a controller component run as an FMU: its inputs a connection feeds (what it
    measures; a signal, e.g. its reference, is the run's own) and its output `command`."""
    c = plan.order.index(controller)
    slots = {slot for slot in plan.inputs[c] if plan.feed_source[slot] > SIGNAL}
    if command in plan.output_names[c]:
        slots.add(plan.outputs[c][plan.output_names[c].index(command)])
    return FiniteGuard(
        frozenset(slots),
        tuple(frozenset(i for i, slot in enumerate(inputs) if slot in slots) for inputs in plan.inputs),
        tuple(tuple(j for j, slot in enumerate(outputs) if slot in slots) for outputs in plan.outputs),
    )


def refusal(plan: Plan, c: int, slot: int, value: float, t: float) -> SlaveError:
    """The error of component c's guarded `slot` holding `value` (not finite) at t: a measured
    input's names its source (`Plan.fed_by`; `not_finite`: the run's words say what it
    measures); the command's is the protocol's ("the controller's command at t = ... is nan, not
    a finite float")."""
    name = plan.order[c]
    if slot in plan.outputs[c]:
        return SlaveError(f"component {name!r}: {command_not_finite(value, t)}", name)
    return measured_not_finite(plan.fed_by[c][plan.inputs[c].index(slot)], value, t, name, "controller FMU")
