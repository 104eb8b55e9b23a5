"""The controller protocol: what the co-simulation master asks of a controller, defined once.

Every T_s the master reads the plant's outputs, asks the controller for the current command
i_q* [A], records it with the controller's diagnostics, and holds it until the next sample::

    state = controller.start(t0, measurement)             # at the first sample
    result = controller.step(state, t, measurement)       # at every sample, the first included
    result.command                                        # i_q* [A], a finite float
    result.diagnostics                                    # floats, one per controller.diagnostics name
    state = result.state                                  # what the next sample's step gets

A controller is any object with these three members (structural typing: no base class):

* ``diagnostics``: a tuple of column names, known before the run, so that the trace's columns
  are (time, the plant's outputs, iq_ref, F_E, *diagnostics);
* ``start(t0, measurement)``: the controller's state at the first sample;
* ``step(state, t, measurement)``: a `ControlStep`.

Optionally ``close()``: what the controller holds outside Python (a library, a file, a process)
is released; the master calls it, if the
controller has it, on every exit path of a run (complete, failed, interrupted, refused).

The measurement is the plant's outputs at the sample, by name (`Measurement`, a read-only
mapping: ``measurement["x_B"]``, ``measurement["theta1"]``). The built-in two-phase VSC
(`control.controller.VSCController`) is one such controller; `control.lti` adapts a
python-control discrete-time system to the protocol.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

from toggle_cosim.messages import short_repr

__all__ = [
    "COMMAND_COLUMNS",
    "ControlStep",
    "Controller",
    "ControllerContext",
    "ControllerError",
    "Measurement",
    "check_controller",
    "checked_command",
    "command_not_finite",
]

COMMAND_COLUMNS = ("iq_ref", "F_E")  # the plant's inputs, recorded before the diagnostics
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\Z")


class ControllerError(Exception):
    """A controller that cannot be used, or that failed; str() is the one-line reason."""


@dataclass(frozen=True)
class ControlStep:
    """What a controller's step returns.

    Attributes:
        command: the current command i_q* [A], held until the next sample.
        diagnostics: one float per name of the controller's ``diagnostics``, in that order.
        state: the controller's state for the next sample's step.
    """

    command: float
    diagnostics: tuple[float, ...]
    state: Any


@runtime_checkable
class Controller(Protocol):
    """A discrete controller the master calls every T_s (module docstring)."""

    diagnostics: tuple[str, ...]

    def start(self, t0: float, measurement: Mapping[str, float]) -> Any:
        """The controller's state at the first sample t0 [s]."""
        ...

    def step(self, state: Any, t: float, measurement: Mapping[str, float]) -> ControlStep:
        """The command [A] and diagnostics for the sample at time t [s], and the next state."""
        ...


class Measurement(Mapping[str, float]):
    """The plant's outputs at one sample, by name: a read-only view of the trace row."""

    __slots__ = ("_index", "_row")

    def __init__(self, index: Mapping[str, int], row: Sequence[float]) -> None:
        self._index, self._row = index, row

    def __getitem__(self, name: str) -> float:
        return float(self._row[self._index[name]])

    def __iter__(self) -> Iterator[str]:
        return iter(self._index)

    def __len__(self) -> int:
        return len(self._index)

    def __repr__(self) -> str:
        return f"Measurement({dict(self)!r})"


@dataclass(frozen=True)
class ControllerContext:
    """What a controller factory is given besides its scenario parameters (`cosim.controllers`).

    Attributes:
        T_s: sample time [s]; the controller is called every T_s.
        t_end: end of the run [s].
        x_start, x_target: the stroke of slider B [m] (stroke.x_start, stroke.x_target).
        objective: the scenario's controller.objective ("x_B" or "theta1").
        label: the run, "scenario" or "scenario/variant".
        outputs: the names the measurement will hold (the plant's recorded outputs).
        builtin: the scenario's built-in controller (a `VSCController` with the scenario's
            gains, law and nominal model), to wrap, replace or subclass.
    """

    T_s: float
    t_end: float
    x_start: float
    x_target: float
    objective: str
    label: str
    outputs: tuple[str, ...] = ()
    builtin: Any = field(default=None, repr=False)

    def builtin_arguments(self) -> dict[str, Any]:
        """The built-in controller's settings as keyword arguments, e.g. for a subclass:
        ``MyVSC(**context.builtin_arguments())``."""
        return dict(vars(self.builtin)) if self.builtin is not None else {}


def _describe(controller: object) -> str:
    kind = type(controller)
    return f"{kind.__module__}.{kind.__qualname__}"


def check_controller(controller: object, reserved: Sequence[str] = ()) -> tuple[str, ...]:
    """The controller's diagnostic names, after checking that it meets the protocol: callable
    start and step, and diagnostics a tuple of distinct names (letters, digits, _) that are not
    among `reserved` (the trace's other columns). Raises ControllerError naming the problem."""
    what = _describe(controller)
    for method in ("start", "step"):
        if not callable(getattr(controller, method, None)):
            raise ControllerError(
                f"the controller {what} has no {method}() method (the protocol needs diagnostics, start and step)"
            )
    names = getattr(controller, "diagnostics", None)
    if names is None:
        raise ControllerError(
            f"the controller {what} has no diagnostics attribute (a tuple of column names; () for none)"
        )
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise ControllerError(
            f"the controller {what}: diagnostics must be a tuple of column names, not {short_repr(names)}"
        )
    names = tuple(names)
    for name in names:
        if not (isinstance(name, str) and _NAME.match(name)):
            raise ControllerError(
                f"the controller {what}: diagnostic name {short_repr(name)} is not a column name (letters, digits and _)"
            )
    if len(set(names)) != len(names):
        raise ControllerError(f"the controller {what}: diagnostics {short_repr(names)} name a column twice")
    clash = [name for name in names if name in ("time", *COMMAND_COLUMNS, *reserved)]
    if clash:
        raise ControllerError(
            f"the controller {what}: diagnostic {clash[0]!r} is already a column of the trace (rename it)"
        )
    return names


def command_not_finite(u: object, t: float) -> ControllerError:
    """The error of a command `u` at t that is not a finite float (a step's result, or what a
    controller FMU gave: `cosim.execution.guard`)."""
    return ControllerError(
        f"the controller's command at t = {t:.6g} s is {short_repr(u)}, not a finite float (i_q* in A)"
    )


def checked_command(result: object, diagnostics: int, t: float) -> tuple[float, tuple[float, ...], Any]:
    """(command, diagnostics, state) of a step's result, or ControllerError saying what is wrong
    with it: not a ControlStep, a command that is not a finite float, the wrong number of
    diagnostics. A ControlStep with a finite float command and a tuple of floats passes by the
    first test, which the loop meets at every sample; anything else gets the full check."""
    if result.__class__ is ControlStep:
        u, values = result.command, result.diagnostics
        if u.__class__ is float and u - u == 0.0 and values.__class__ is tuple and len(values) == diagnostics:
            for value in values:
                if value.__class__ is not float:
                    break
            else:
                return u, values, result.state
    if not isinstance(result, ControlStep):
        raise ControllerError(
            f"the controller's step returned {type(result).__name__} at t = {t:.6g} s, not a ControlStep"
            " (return ControlStep(command, diagnostics, state))"
        )
    u = result.command
    if type(u) is not float and (isinstance(u, bool) or not isinstance(u, numbers.Real)) or not math.isfinite(u):
        raise command_not_finite(u, t)
    values = result.diagnostics
    try:
        values = tuple(map(float, values))
    except (TypeError, ValueError):
        raise ControllerError(
            f"the controller's diagnostics at t = {t:.6g} s are {short_repr(values)}, not a tuple of floats"
        ) from None
    if len(values) != diagnostics:
        raise ControllerError(
            f"the controller's step returned {len(values)} diagnostics at t = {t:.6g} s, "
            f"its diagnostics attribute names {diagnostics}"
        )
    return float(u), values, result.state
