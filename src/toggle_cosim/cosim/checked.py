"""A run checked before anything is loaded: `check_run` turns (run, plant, controller) into a
`CheckedRun`, everything the run's execution needs that can be known before instantiation.

One check, in the process that starts the run (`master.check`; under supervision the
parent, before the fork: `supervision`). It loads no FMU binary and runs no code of the
user's; the run's child inherits the result and only instantiates and steps it (`systems.execute`).
What it holds:

* the components, in the order a run lists them (`component_names`): the plant (its checked
  archive, the values the run sets on it: `plant_inputs.plant_settings`), the controller (a
  controller FMU as an FMU component; any other controller, the built-in law or one given,
  run natively; a user's controller.python still to be built: None), the parts (each FMU
  checked as any FMU the master runs, owned by the user, its values each a parameter or input
  of its type);
* the connections, checked (both ends exist, an output to an input, no input fed twice) with
  their unit conversions (`unit_conversion`: the same dimension, factor and offset from the
  FMUs' unit definitions; anything else refused), or the pair's wiring (`pair_connections`);
* the stepping order (`system.graph`: an algebraic loop is refused naming its cycle; the
  pair's own wiring steps the plant then the controller), the plan (`system.plan`), the signal
  table (`plant_inputs.input_samples`: the plant inputs no connection feeds, at every t_k; and
  for a controller FMU that tracks stroke.trajectory its x_ref, v_ref, a_ref, the sampled
  reference's rows, which the plan sets with its measurements);
* the trace's columns (`names`) and units, and run.json's static parts (its components).

The trace of the plain pair (`Wiring.is_pair`: no parts, connections or `record:` list) has
the pair's columns (`pair_ports`: time, the plant's recorded outputs, iq_ref, F_E, the
controller's diagnostics, the other inputs, by their plain names) and `CheckedRun.pair` says
so; any other system records every connector (`component.variable`: outputs, then fed inputs,
in stepping order) or its `record:` list, which may name any variable of an FMU component.

A controller.python factory is called in the run's child (user code never runs in the
process that supervises), so its check stops before the connections (`CheckedRun.complete`
False); `built(checked, controller)` finishes it there, from the built controller's
measured inputs and diagnostics, which only that instance can tell. Every refusal is one line:
`SystemError_` naming the key and the fix, `ControllerError` for the controller.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import COMMAND_COLUMNS, Controller, ControllerError, check_controller
from toggle_cosim.controller_fmu.variables import REFERENCE_INPUTS
from toggle_cosim.cosim.controllers import ControllerFmuPart, builds_in_child, check_user_controller, own_controller
from toggle_cosim.cosim.execution.fmi_pointers import RECORDED_TYPES
from toggle_cosim.cosim.execution.guard import FiniteGuard, controller_guard
from toggle_cosim.cosim.plant_inputs import input_samples, other_inputs, plant_settings
from toggle_cosim.cosim.user_code import check_owned
from toggle_cosim.plant.contract import ContractError, FmuArchive, PlantInterface, read_fmu
from toggle_cosim.runs.definition import Run
from toggle_cosim.system.graph import AlgebraicLoop, gauss_seidel_order
from toggle_cosim.system.interfaces import SettableError, check_settable, controller_interface, fmu_interface
from toggle_cosim.system.model import Connection, Interface, Part, Port, Value, Wiring
from toggle_cosim.system.plan import Plan, build_plan
from toggle_cosim.system.units import BASE, UnitDefinitionError, conversion, unit_meaning

__all__ = [
    "COMMAND",
    "CheckedRun",
    "FmuComponent",
    "NativeComponent",
    "SystemError_",
    "built",
    "check_run",
    "component_names",
    "pair_connections",
    "pair_ports",
    "unit_conversion",
]

COMMAND, LOAD = COMMAND_COLUMNS  # iq_ref (the controller's output), F_E (the plant's input)


class SystemError_(ValueError):  # noqa: N801 - `SystemError` is a builtin
    """A system that cannot run as written; str() is one line naming what and the fix."""


@dataclass(frozen=True)
class FmuComponent:
    """An FMU component to instantiate: the FMU as its check gave it (the plant's
    `PlantInterface`, a controller FMU's `ControllerFmu`, a part's `FmuArchive`: each with its
    path, model description and SHA-256), the values set before initialisation, in order, and
    its connectors (`fmu_interface`, with the variables the record reads)."""

    name: str
    fmu: Any
    values: tuple[tuple[str, Value], ...]
    interface: Interface


@dataclass(frozen=True)
class NativeComponent:
    """A controller of the protocol run natively (`slaves.ControllerSlave`): the built-in law, a
    controller given to `simulate`, or a user's built in the run's child; its diagnostics and
    its connectors in the plant's units (`system.interfaces.controller_interface`)."""

    name: str
    controller: Controller
    diagnostics: tuple[str, ...]
    interface: Interface


Component = FmuComponent | NativeComponent


@dataclass(frozen=True)
class CheckedRun:
    """A run checked (module docstring): `run` with the coupling it runs with, its plant, its
    controller (None: controller.python, built in the run's child: `built`), its components in
    `component_names` order (the controller's None until it is built), and once `complete` the
    checked connections, the stepping order, the plan, the signal table, the trace's columns
    (`names`) and units, run.json's components, the components' ids and the execution's
    finiteness guard."""

    run: Run
    plant: PlantInterface
    controller: Controller | None
    components: tuple[Component | None, ...]
    pair: bool  # the trace and run.json are the plain pair's (`pair_ports`)
    wiring: Wiring  # what the execution steps: the run's, with the pair's record list for the pair
    connections: tuple[Connection, ...] = ()
    order: tuple[str, ...] = ()
    plan: Plan | None = None
    signals: np.ndarray | None = None
    names: tuple[str, ...] = ()
    units: Mapping[str, str] = dataclasses.field(default_factory=dict)
    records: tuple[dict[str, Any], ...] = ()
    ids: tuple[int, ...] = ()  # each component's id (`component_names`), in stepping order
    guard: FiniteGuard | None = None  # a controller FMU's finiteness guard (`guard.controller_guard`)

    @property
    def complete(self) -> bool:
        """Whether everything is checked: False while a controller.python is still to be built."""
        return self.plan is not None

    @property
    def builds_controller(self) -> bool:
        """Whether the run's child builds the controller (controller.python, none given)."""
        return self.controller is None

    @property
    def runs_users_code(self) -> bool:
        """Whether the controller is the user's (controller.python, controller.fmu, or one given
        that is not the built-in law): a crash or a hang may be its own, not the plant's."""
        return self.controller is None or type(self.controller) is not VSCController

    @property
    def diagnostics(self) -> tuple[str, ...]:
        """The controller's diagnostics (its outputs besides the command), once known."""
        component = self.components[1]
        if isinstance(component, NativeComponent):
            return component.diagnostics
        return tuple(getattr(self.controller, "diagnostics", ()))


def unit_conversion(
    connection: Connection, start: tuple[str | None, Any], end: tuple[str | None, Any]
) -> tuple[float, float] | None:
    """The (factor, offset) that turns the start's unit into the end's (None: the same unit, or
    either has none: the value is passed as it is). `start`, `end`: (unit, the FMU's model
    description or None). SystemError_ for units of different dimensions or unknown units."""
    (unit_s, desc_s), (unit_e, desc_e) = start, end
    if not unit_s or not unit_e or unit_s == unit_e:
        return None
    try:
        m_s, m_e = unit_meaning(unit_s, desc_s), unit_meaning(unit_e, desc_e)
    except UnitDefinitionError as error:
        raise SystemError_(f"the connection {connection}: {error}") from None
    if m_s is None or m_e is None:
        unknown = unit_s if m_s is None else unit_e
        raise SystemError_(
            f"the connection {connection} joins the units {unit_s!r} and {unit_e!r}, and {unknown!r} is not defined "
            "(declare it in the FMU's UnitDefinitions or connect variables of the same unit)"
        )
    if m_s[: len(BASE)] != m_e[: len(BASE)]:
        raise SystemError_(
            f"the connection {connection} joins {unit_s!r} to {unit_e!r}, of different dimensions (connect "
            "variables of the same quantity)"
        )
    if m_s[-2:] == m_e[-2:]:
        return None
    return conversion(m_s, m_e)


def component_names(wiring: Wiring) -> tuple[str, ...]:
    """A system's components as a run lists them: the plant, the controller, then the parts in
    the order written. A component's id while the master calls it is 1 + its place here
    (`systems.execute`'s `calling`)."""
    return (wiring.plant, wiring.controller, *(part.name for part in wiring.parts))


def pair_connections(wiring: Wiring, controller_inputs: Sequence[str]) -> tuple[Connection, ...]:
    """The pair's wiring: each controller input from the plant output of its name, the command to the plant."""
    p, c = wiring.plant, wiring.controller
    return (
        *(Connection(Port(p, name), Port(c, name)) for name in controller_inputs),
        Connection(Port(c, COMMAND), Port(p, COMMAND)),
    )


def pair_ports(
    wiring: Wiring, plant: PlantInterface, diagnostics: tuple[str, ...], inputs: tuple[str, ...]
) -> tuple[Port, ...]:
    """The ports whose values are the pair's trace columns after time, in its order."""
    p, c = wiring.plant, wiring.controller
    return (
        *(Port(p, name) for name in plant.recorded_outputs),
        Port(c, COMMAND),
        Port(p, LOAD),
        *(Port(c, name) for name in diagnostics),
        *(Port(p, name) for name in inputs),
    )


def _check_connections(connections: Sequence[Connection], interfaces: Mapping[str, Interface], where: str) -> None:
    fed: dict[Port, Connection] = {}
    for connection in connections:
        for side, port in (("start", connection.start), ("end", connection.end)):
            interface = interfaces.get(port.component)
            if interface is None:
                raise SystemError_(
                    f"{where}: the connection {connection} names the component {port.component!r}, which the system "
                    f"does not have (its components: {', '.join(interfaces)})"
                )
            wanted = (
                tuple(v for v in interface.outputs if v not in interface.typed) if side == "start" else interface.inputs
            )
            if port.variable not in wanted:
                kind = "output" if side == "start" else "input"
                known = ", ".join(wanted) or "none"
                raise SystemError_(
                    f"{where}: the connection {connection} {'starts' if side == 'start' else 'ends'} at {port}, which "
                    f"is not a Real {kind} of {port.component!r} (its {kind}s: {known}); a connection runs from an "
                    "output to an input"
                )
        if connection.end in fed:
            raise SystemError_(
                f"{where}: the connections {fed[connection.end]} and {connection} both drive {connection.end} "
                "(an input takes one connection; remove one)"
            )
        fed[connection.end] = connection


@functools.lru_cache(maxsize=64)
def _read_part(path: Path, size: int, mtime_ns: int, missing: str) -> FmuArchive:
    """`read_fmu` of a part's file, kept while the file is unchanged (its size and time): the runs
    of one command (a scenario's variants, a sweep's cases) each check the parts they share."""
    return read_fmu(path, missing=missing)


def _checked_part(part: Part, source: Path | None) -> FmuArchive:
    """A part's FMU checked as any FMU the master runs (a zip archive, safe, FMI 2.0 or 3.0,
    Co-Simulation, a binary for this platform: `plant.contract.read_fmu`) and, being code this
    command runs, owned by the user (`user_code.check_owned`), its values each a parameter or
    input of the FMU, of its type (`system.interfaces.check_settable`): the checked archive (path,
    model description, SHA-256), or SystemError_ naming the key and the fix."""
    ssp = source is not None and Path(source).suffix.lower() == ".ssp"
    key = f"component {part.name!r}" if ssp else f"key components.{part.name}.fmu"
    try:
        missing = f"build it, or fix {key}"
        try:
            status = part.fmu.stat()
        except OSError:
            archive = read_fmu(part.fmu, missing=missing)  # its own message for a missing file
        else:
            archive = _read_part(part.fmu.resolve(), status.st_size, status.st_mtime_ns, missing)
            check_owned(part.fmu, key)
    except ContractError as error:
        raise SystemError_(f"{key}: {error}") from None
    except ControllerError as error:
        raise SystemError_(str(error)) from None
    try:  # the one check of a component's values (the SSP reader's too), before any run
        check_settable(archive.model_description, part.values)
    except SettableError as error:
        where = f"component {part.name!r}" if ssp else f"key components.{part.name}.parameters"
        raise SystemError_(
            f"{where}: {error} ({part.fmu.name}; give a parameter or input of its FMU, or fix the name or the value)"
        ) from None
    return archive


def _controller_component(
    wiring: Wiring, controller: Controller, outputs: tuple[str, ...], units: Mapping[str, str | None]
) -> Component:
    """The controller as a component: a controller FMU as an FMU (its settings its values), any
    other natively, its connectors in the units of the plant variables of their names."""
    name = wiring.controller
    if isinstance(controller, ControllerFmuPart):
        fmu = controller.fmu
        return FmuComponent(name, fmu, tuple(controller.settings), fmu_interface(fmu.model_description))
    diagnostics = tuple(check_controller(controller, outputs))
    measured = tuple(
        getattr(controller, "measured", None) or outputs
    )  # what it declares it reads, else the plant's outputs
    interface = controller_interface(measured, diagnostics, COMMAND, units)
    return NativeComponent(name, controller, diagnostics, interface)


def check_run(
    run: Run, plant: PlantInterface, controller: Controller | None = None, coupling: str | None = None
) -> CheckedRun:
    """`run` on `plant` checked (module docstring); `controller`: one given (None: the run's own:
    the built-in law or controller.fmu, checked here; controller.python, built in the run's
    child and checked there, `built`); `coupling`: None for the run's own. Loads no FMU binary
    and runs no code of the user's. Raises SystemError_ or ControllerError (one line), ValueError
    for a plant setting the plant does not have (`plant_settings`)."""
    if coupling is not None and coupling != run.coupling:
        run = dataclasses.replace(run, coupling=coupling)
    wiring, outputs = run.system, tuple(plant.recorded_outputs)
    where = f"scenario {run.scenario}"
    observed: dict[str, list[str]] = {}
    for port in wiring.record or ():
        observed.setdefault(port.component, []).append(port.variable)
    plant_part = FmuComponent(
        wiring.plant,
        plant,
        tuple(plant_settings(run, plant)),
        fmu_interface(plant.model_description, observed.get(wiring.plant, ())),
    )
    if controller is None and not builds_in_child(run):
        controller = own_controller(run, outputs)  # the built-in law or controller.fmu: no code of the user's runs
    elif controller is None:
        check_user_controller(run, outputs)  # controller.python's module found and owned, not imported
    control = (
        None if controller is None else _controller_component(wiring, controller, outputs, plant_part.interface.units)
    )
    components: list[Component | None] = [plant_part, control]
    for part in wiring.parts:
        if part.name in (wiring.plant, wiring.controller, *(c.name for c in components[2:] if c is not None)):
            raise SystemError_(f"{where}: two components are named {part.name!r} (give each its own name)")
        archive = _checked_part(part, run.source)
        components.append(
            FmuComponent(
                part.name,
                archive,
                tuple(part.values),
                fmu_interface(archive.model_description, observed.get(part.name, ())),
            )
        )
    checked = CheckedRun(run, plant, controller, tuple(components), wiring.is_pair, wiring)
    return _wired(checked) if control is not None else checked


def built(checked: CheckedRun, controller: Controller) -> CheckedRun:
    """`checked`, whose controller.python was still to be built, finished with the `controller`
    the run's child built: its diagnostics checked against the protocol, then the connections,
    the order, the plan and the columns. Raises ControllerError or SystemError_."""
    plant = checked.components[0]
    assert isinstance(plant, FmuComponent)
    outputs = tuple(checked.plant.recorded_outputs)
    control = _controller_component(checked.run.system, controller, outputs, plant.interface.units)
    components = (plant, control, *checked.components[2:])
    return _wired(dataclasses.replace(checked, controller=controller, components=components))


def _wired(checked: CheckedRun) -> CheckedRun:
    """The connections, units, order, plan, signal table and columns of `checked`, whose
    components are all known (module docstring)."""
    run, wiring = checked.run, checked.run.system
    where = f"scenario {run.scenario}"
    components = {c.name: c for c in checked.components if c is not None}
    if checked.pair:  # the pair's columns, by the plain names of their ports
        wiring = dataclasses.replace(
            wiring, record=pair_ports(wiring, checked.plant, checked.diagnostics, other_inputs(run))
        )
    interfaces = {name: component.interface for name, component in components.items()}
    plant_outputs = set(interfaces[wiring.plant].outputs)  # a controller FMU's reference inputs: not the plant's
    controller_inputs = [name for name in interfaces[wiring.controller].inputs if name in plant_outputs]
    connections = wiring.connections if wiring.connections is not None else pair_connections(wiring, controller_inputs)
    _check_connections(connections, interfaces, where)
    descriptions = {
        name: component.fmu.model_description if isinstance(component, FmuComponent) else None
        for name, component in components.items()
    }
    converted = []
    for connection in connections:
        start, end = connection.start, connection.end
        found = unit_conversion(
            connection,
            (interfaces[start.component].units.get(start.variable), descriptions[start.component]),
            (interfaces[end.component].units.get(end.variable), descriptions[end.component]),
        )
        if found is not None:
            factor, offset = found
            connection = Connection(start, end, factor * connection.factor, factor * connection.offset + offset)
        converted.append(connection)
    connections = tuple(converted)
    fed = {connection.end for connection in connections}
    signals = [("F_E", run.plant.F_E), *run.plant.inputs.items()]
    signal_ports, columns = [], []
    plant_inputs = interfaces[wiring.plant].inputs
    for index, (name, _) in enumerate(signals):
        port = Port(wiring.plant, name)
        if port in fed or name not in plant_inputs:
            continue
        signal_ports.append(port)
        columns.append(index)
    tracked = _reference_ports(checked.controller, wiring.controller, fed, where)
    signal_ports += tracked
    for port in wiring.record or ():
        interface = interfaces.get(port.component)
        if interface is None or (port.variable not in interface.outputs and port.variable not in interface.inputs):
            raise SystemError_(
                f"{where}: key record: {port} is not a variable of the system (its components: "
                f"{', '.join(interfaces)}; an FMU's variables by their names in its modelDescription.xml)"
            )
        kind = interface.typed.get(port.variable)
        if kind is not None and kind not in RECORDED_TYPES:
            raise SystemError_(
                f"{where}: key record: {port} is a {kind} variable; the trace holds numbers (record Real, Integer,"
                " Boolean or Enumeration variables)"
            )
        if port.variable in interface.inputs and port not in fed and port not in signal_ports:
            raise SystemError_(
                f"{where}: key record: {port} is an input nothing feeds (connect it, or record another variable)"
            )
    try:
        order = (
            (wiring.plant, wiring.controller)  # the pair's own wiring: the plant, then the controller
            if wiring.connections is None and not wiring.parts
            else tuple(gauss_seidel_order(list(components), connections, interfaces))
        )
    except AlgebraicLoop as error:
        raise SystemError_(f"{where}: {error}") from None
    plan = build_plan(order, interfaces, connections, signal_ports, wiring.record, run.coupling == "jacobi", tracked)
    samples = input_samples(run, run.steps)[:, columns].reshape(run.steps + 1, len(columns))
    if tracked:  # the very rows the built-in law reads at each sample: (q*, q̇*, q̈*)
        assert isinstance(checked.controller, ControllerFmuPart) and checked.controller.reference is not None
        samples = np.column_stack([samples, checked.controller.reference.values[:, : len(tracked)]])
    table = np.ascontiguousarray(samples, dtype=np.float64)
    units = {"time": "s"}
    for column in plan.names[1:]:
        port = Port.parse(column)
        unit = interfaces[port.component].units.get(port.variable)
        if unit:
            units[column] = unit
    names = ("time", *(port.variable for port in wiring.record)) if checked.pair else plan.names
    records = tuple(_component_record(component, order) for component in components.values())
    listed = component_names(checked.wiring)
    control = components[wiring.controller]
    return dataclasses.replace(
        checked,
        wiring=wiring,
        connections=connections,
        order=order,
        plan=plan,
        signals=table,
        names=tuple(names),
        units=units,
        records=records,
        ids=tuple(listed.index(name) + 1 for name in order),
        guard=controller_guard(plan, control.name, COMMAND) if isinstance(control, FmuComponent) else None,
    )


def _reference_ports(controller: Controller | None, name: str, fed: set[Port], where: str) -> list[Port]:
    """The inputs x_ref, v_ref, a_ref (`controllers.REFERENCE_INPUTS`) of a controller FMU that
    tracks the run's trajectory, fed by the signal table from its sampled reference; none when
    it regulates to its target. A connection that feeds one is refused: the reference is the run's."""
    if not isinstance(controller, ControllerFmuPart) or controller.reference is None:
        return []
    ports = [Port(name, variable) for variable in REFERENCE_INPUTS]
    for port in ports:
        if port in fed:
            raise SystemError_(
                f"{where}: a connection feeds {port}, which the controller FMU reads from stroke.trajectory (remove the"
                " connection, or remove stroke.trajectory)"
            )
    return ports


def _component_record(component: Component, order: Sequence[str]) -> dict[str, Any]:
    """What run.json says of a component: its name, place in the order, and its FMU (path,
    SHA-256, values) or what kind of native controller it is."""
    record: dict[str, Any] = {"name": component.name, "position": order.index(component.name)}
    if isinstance(component, FmuComponent):
        record.update(fmu=str(Path(component.fmu.path)), sha256=component.fmu.sha256, values=dict(component.values))
    else:
        record.update(kind="native controller", type=type(component.controller).__qualname__)
    return record
