"""What a system is: components (FMUs, the controller, signal sources), their connections, and
the variables a run records. A scenario file (`experiments.scenario`) and an SSD (`ssp.reader`)
are two ways to write one; the master (`cosim.execution.algorithm`) steps it.

These are plain data: nothing here opens an FMU. What a component's connectors are (their
causality, unit and direct dependencies) is read when the system is built for a run
(`Interface`, `cosim.execution.slaves`); the order the master steps the components in follows from the
connections and those dependencies (`system.graph`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

Value = float | int | bool

__all__ = ["Connection", "Interface", "Part", "Port", "PortError", "Value", "Wiring"]


class PortError(ValueError):
    """A port written as something other than `component.variable`."""


@dataclass(frozen=True, order=True)
class Port:
    """A variable of a component: `component.variable` (the variable's name may hold dots)."""

    component: str
    variable: str

    @classmethod
    def parse(cls, text: object) -> Port:
        """`"sensor.x_m"` -> Port("sensor", "x_m"); PortError unless both parts are there."""
        if not isinstance(text, str) or "." not in text.strip(". "):
            raise PortError(f"{text!r} is not a port: write component.variable (e.g. plant.x_B)")
        component, variable = text.strip().split(".", 1)
        if not component or not variable:
            raise PortError(f"{text!r} is not a port: write component.variable (e.g. plant.x_B)")
        return cls(component, variable)

    def __str__(self) -> str:
        return f"{self.component}.{self.variable}"


@dataclass(frozen=True)
class Connection:
    """A connection start -> end: the end input takes factor·start + offset (a unit conversion;
    the identity copies the value's bits)."""

    start: Port
    end: Port
    factor: float = 1.0
    offset: float = 0.0

    @property
    def identity(self) -> bool:
        return self.factor == 1.0 and self.offset == 0.0

    def __str__(self) -> str:
        return f"{self.start} -> {self.end}"


@dataclass(frozen=True)
class Part:
    """An FMU component besides the plant and the controller: a sensor, a drive, a load.
    `values` are set before initialisation, in order; `source` is how its file names it."""

    name: str
    fmu: Path
    values: tuple[tuple[str, Value], ...] = ()
    source: str = ""


@dataclass(frozen=True)
class Wiring:
    """What a run adds to the plant + controller pair to make it a system: more components,
    the connections (None: the pair's own wiring, each controller input from the plant output
    of its name and the command to the plant's iq_ref), and the ports to record (None: every
    connector of every component). A scenario names its plant and controller `plant` and `controller`."""

    parts: tuple[Part, ...] = ()
    connections: tuple[Connection, ...] | None = None
    record: tuple[Port, ...] | None = None
    plant: str = "plant"  # the plant's and the controller's component names (an SSD's own)
    controller: str = "controller"

    @property
    def is_pair(self) -> bool:
        """Whether this is the plain pair (the master's fixed plant + controller loop runs it)."""
        return not self.parts and self.connections is None and self.record is None


@dataclass(frozen=True)
class Interface:
    """A component's connectors as the master sees them: its inputs and outputs (Real; then the
    other variables it records, `typed` giving the type of those that are not Real), each
    output's direct dependencies on inputs (an FMU's ModelStructure; a controller's outputs
    depend on every input), and units (None: none declared)."""

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    depends: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    units: Mapping[str, str | None] = field(default_factory=dict)
    typed: Mapping[str, str] = field(default_factory=dict)  # outputs of other types than Real: recorded, not connected

    def feedthrough(self, variable: str) -> bool:
        """Whether some output depends directly on the input `variable`."""
        return any(variable in inputs for inputs in self.depends.values())
