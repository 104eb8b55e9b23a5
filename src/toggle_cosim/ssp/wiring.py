"""An SSD's connections checked against the wiring our master implements (`check_wiring`).

Until the master steps any system, an SSP runs only if its connections are exactly the plant +
controller loop the master wires: every input of the controller from the plant output of the
same name, and the controller's iq_ref to the plant's iq_ref. Before that comparison each
connection is checked as the SSP 1.0 standard reads it, so that the refusal names what is wrong:

* both ends exist (components and connectors of the SSD, variables of the FMUs), no system-level
  connector, and a connector's kind is its FMU variable's causality;
* it runs from an output to an input (section 5, Connections);
* its units: each end's unit means what its FMU's unit means (an SSD Unit that redefines `m` by
  a factor 0.001 is a conversion), and the two ends mean the same (a declared conversion between
  two names is accepted only when it is the identity: same SI exponents, factor 1, offset 0),
  and a LinearTransformation, if any, is the identity;
* no algebraic loop: a cycle through connections and the FMUs' declared direct dependencies
  (ModelStructure; an output that declares none depends on every input).

Each failure is one SspError line naming the SSD and the connection.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from lxml import etree

from toggle_cosim.fmu_export.units import UnitError, base_exponents
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import Element, SspError
from toggle_cosim.ssp.fmus import FmuVariables

__all__ = ["Connector", "Wire", "check_wiring", "connectors_of"]

NS = layout.NAMESPACES
BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
Meaning = tuple[float, ...]  # the SI exponents of BASE, then factor and offset


@dataclass(frozen=True)
class Connector:
    """A component's connector as the SSD declares it: its kind and unit (None: none given)."""

    kind: str
    unit: str | None


@dataclass(frozen=True)
class Wire:
    """One connection, start -> end."""

    start: str
    start_connector: str
    end: str
    end_connector: str

    def __str__(self) -> str:
        return f"{self.start}.{self.start_connector} -> {self.end}.{self.end_connector}"


def connectors_of(component: Element, fmu: FmuVariables, where: str) -> dict[str, Connector]:
    """A component's connectors, each a variable of its FMU with the FMU's causality as its kind."""
    found = {}
    name = component.get("name")
    for connector in component.iterfind("ssd:Connectors/ssd:Connector", NS):
        label = connector.get("name")
        variable = fmu.variables.get(label)
        if variable is None:
            raise SspError(
                f"{where}: component {name!r} declares the connector {label!r}, which its FMU "
                f"{fmu.label.rsplit('/', 1)[-1]} does not have (remove it or fix the name)"
            )
        kind = connector.get("kind")
        if kind != variable.causality:
            raise SspError(
                f"{where}: component {name!r} declares {label!r} as a connector of kind {kind}, but its FMU's variable "
                f"has causality {variable.causality} (give the connector kind {variable.causality!r})"
            )
        typed = next((child for child in connector if etree.QName(child).namespace == layout.SSC_NS), None)
        found[label] = Connector(kind, typed.get("unit") if typed is not None else None)
    return found


def _ssd_units(ssd: Element) -> dict[str, Meaning]:
    units = {}
    for unit in ssd.iterfind("ssd:Units/ssc:Unit", NS):
        base = unit.find("ssc:BaseUnit", NS)
        attributes = dict(base.attrib) if base is not None else {}
        units[unit.get("name")] = (
            *(float(attributes.get(key, 0)) for key in BASE),
            float(attributes.get("factor", 1)),
            float(attributes.get("offset", 0)),
        )
    return units


def _fmu_meaning(unit: str, fmu: FmuVariables) -> Meaning | None:
    found = fmu.base_unit(unit)
    if found is None:
        try:
            found = {**base_exponents(unit), "factor": 1.0, "offset": 0.0}
        except UnitError:
            return None
    return (
        *(float(found.get(key) or 0) for key in BASE),
        float(found.get("factor") if found.get("factor") is not None else 1),
        float(found.get("offset") or 0),
    )


def _show(meaning: Meaning | None, name: str | None) -> str:
    if meaning is None:
        return repr(name)
    powers = " ".join(f"{key}^{int(p)}" if p != 1 else key for key, p in zip(BASE, meaning, strict=False) if p)
    factor, offset = meaning[-2:]
    return f"{name!r} (= {factor:g} {powers or '1'}{f' + {offset:g}' if offset else ''})"


def _check_units(wire: Wire, connectors, fmus, ssd_units, where: str) -> None:  # noqa: ANN001
    meanings = []
    for component, name in ((wire.start, wire.start_connector), (wire.end, wire.end_connector)):
        fmu = fmus[component]
        own = fmu.unit(name)
        given = connectors[component][name].unit or own
        meaning = ssd_units.get(given) if given in ssd_units else (_fmu_meaning(given, fmu) if given else None)
        own_meaning = _fmu_meaning(own, fmu) if own else None
        if given and own and (meaning != own_meaning if meaning and own_meaning else given != own):
            raise SspError(
                f"{where}: the connection {wire} gives {component}.{name} the unit {_show(meaning, given)}, but its "
                f"FMU's unit is {_show(own_meaning, own)}; a unit conversion is not supported here (give the FMU's unit)"
            )
        meanings.append((given, meaning))
    (start, start_meaning), (end, end_meaning) = meanings
    same = start_meaning == end_meaning if start_meaning and end_meaning else start == end
    if start and end and not same:
        raise SspError(
            f"{where}: the connection {wire} joins {start} to {end}; only the identity is supported "
            "(give both connectors the same unit)"
        )


def _check_transformation(connection: Element, wire: Wire, where: str) -> None:
    for child in connection:
        kind = etree.QName(child).localname
        if kind in ("Annotations", "ConnectionGeometry"):
            continue
        identity = kind == "LinearTransformation" and (
            float(child.get("factor", 1)) == 1.0 and float(child.get("offset", 0)) == 0.0
        )
        if not identity:
            raise SspError(
                f"{where}: the connection {wire} has a {kind} that is not the identity (not supported; remove it)"
            )


def _wires(ssd: Element, connectors, where: str) -> list[Wire]:  # noqa: ANN001
    wires = []
    for connection in ssd.iterfind("ssd:System/ssd:Connections/ssd:Connection", NS):
        ends = []
        for side in ("start", "end"):
            element, connector = connection.get(f"{side}Element"), connection.get(f"{side}Connector")
            if element is None:
                raise SspError(
                    f"{where}: a connection to the system's own connector {connector!r} (system-level connectors "
                    "are not supported; connect the components directly)"
                )
            if element not in connectors:
                raise SspError(
                    f"{where}: a connection names the component {element!r}, which does not exist "
                    f"(choose one of {', '.join(connectors)})"
                )
            if connector not in connectors[element]:
                raise SspError(
                    f"{where}: a connection names the connector {element}.{connector}, which the component does "
                    "not declare (declare it in its Connectors or fix the name)"
                )
            ends.append((element, connector))
        wire = Wire(*ends[0], *ends[1])
        kinds = (connectors[wire.start][wire.start_connector].kind, connectors[wire.end][wire.end_connector].kind)
        if kinds != ("output", "input"):
            raise SspError(
                f"{where}: the connection {wire} runs from a connector of kind {kinds[0]} to one of kind {kinds[1]} "
                "(a connection runs from an output to an input)"
            )
        _check_transformation(connection, wire, where)
        wires.append(wire)
    return wires


def _loop(wires: list[Wire], fmus: Mapping[str, FmuVariables]) -> list[str] | None:
    """A cycle through the connections and the FMUs' direct dependencies, as names, or None."""
    edges: dict[str, list[str]] = {}
    for wire in wires:
        edges.setdefault(f"{wire.start}.{wire.start_connector}", []).append(f"{wire.end}.{wire.end_connector}")
    for component, fmu in fmus.items():
        inputs = fmu.inputs()
        for unknown in getattr(fmu.model_description, "outputs", None) or ():
            depends = inputs if unknown.dependencies is None else [v.name for v in unknown.dependencies]
            for name in depends:
                if name in inputs:
                    edges.setdefault(f"{component}.{name}", []).append(f"{component}.{unknown.variable.name}")
    state: dict[str, int] = {}  # 1: on the path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for following in edges.get(node, ()):
            if state.get(following) == 1:
                return [*path[path.index(following) :], following]
            if following not in state:
                found = visit(following)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in list(edges):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def check_wiring(
    ssd: Element,
    where: str,
    plant: str,
    controller: str,
    fmus: Mapping[str, FmuVariables],
    connectors: Mapping[str, Mapping[str, Connector]],
) -> None:
    """SspError unless the SSD's connections are exactly the loop our master runs (module doc)."""
    wires = _wires(ssd, connectors, where)
    loop = _loop(wires, fmus)
    if loop is not None:
        raise SspError(
            f"{where}: an algebraic loop {' -> '.join(loop)} (through the connections and the FMUs' direct "
            "dependencies; break it)"
        )
    units = _ssd_units(ssd)
    for wire in wires:
        _check_units(wire, connectors, fmus, units, where)
    expected = [Wire(plant, name, controller, name) for name in fmus[controller].inputs()]
    expected.append(Wire(controller, layout.COMMAND, plant, layout.COMMAND))
    ends: dict[tuple[str, str], Wire] = {}
    for wire in wires:
        twice = ends.setdefault((wire.end, wire.end_connector), wire)
        if twice != wire:
            raise SspError(f"{where}: the connections {twice} and {wire} both drive {wire.end}.{wire.end_connector}")
        if wire not in expected:
            raise SspError(
                f"{where}: the connection {wire} is not a wiring our master runs (it connects each controller "
                f"input to the plant output of that name and {controller}.{layout.COMMAND} to "
                f"{plant}.{layout.COMMAND}; remove or fix it)"
            )
    missing = [wire for wire in expected if wire not in wires]
    if missing:
        raise SspError(
            f"{where}: no connection {missing[0]} (our master runs the plant and controller only as the loop "
            f"these connections make; add {'it' if len(missing) == 1 else f'the {len(missing)} missing'})"
        )
