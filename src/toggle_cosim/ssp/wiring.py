"""An SSD's connections as the system's `Connection`s (`read_connections`), each checked as the
SSP standard reads it (1.0, and 2.0's Float64/Float32 connectors), and whether they are the plain
plant + controller loop (`is_pair_loop`).

Each connection is checked, one SspError line naming the SSD and the connection:

* both ends exist (components and connectors of the SSD, variables of the FMUs), no system-level
  connector, and a connector's kind is its FMU variable's causality;
* it runs from an output to an input (section 5, Connections), both Real (the FMU variables, and
  the connectors' types where given: Real, or SSP 2.0's Float64 and Float32, `versions.family`);
  no connector is an array or a clock (SSP 2.0: `versions.refuse_array`, `versions.refuse_clocks`);
* no input is driven by two connections;
* units: the value leaves the start FMU in its unit and reaches the end FMU in its own
  (a connector's unit, an SSD Unit or the FMU's, has to mean the same dimension as its FMU
  variable's). Two units of one dimension are a conversion: with base-unit factor f and offset
  o (base = f·value + o), end = (f_s/f_e)·start + (o_s − o_e)/f_e. Different dimensions are
  refused. A unit the FMU leaves out is the connector's;
* a LinearTransformation (factor a, offset b) applies after the unit conversion (the schema's
  text: "the value of source is already converted to the target unit"), so the connection is
  end = a·(converted start) + b; with suppressUnitConversion="true" it applies instead of it.
  Other transformations (Boolean or Integer mappings) are refused;
* the `Connection`'s factor and offset are what the master applies on top of its own conversion
  between the two FMUs' declared units (`cosim.systems.unit_conversion`, after the Connection's):
  where both FMUs declare units, a pure unit conversion is the identity Connection; where one
  declares none, the Connection holds the whole conversion (`_beyond_master`);
* no algebraic loop: a cycle through connections and the FMUs' declared direct dependencies
  (ModelStructure; an output that declares none depends on every input), found by
  `system.graph.algebraic_loop`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from lxml import etree

from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import Element, SspError
from toggle_cosim.ssp.fmus import FmuVariables
from toggle_cosim.ssp.versions import family, refuse_array, refuse_clocks, type_element
from toggle_cosim.system.graph import algebraic_loop
from toggle_cosim.system.model import Connection, Port, Wiring
from toggle_cosim.system.units import BASE, Meaning, UnitDefinitionError, conversion, meaning, unit_meaning

__all__ = ["Connector", "connectors_of", "conversion", "is_pair_loop", "meaning_of", "read_connections"]

NS = layout.NAMESPACES


@dataclass(frozen=True)
class Connector:
    """A component's connector as the SSD declares it: its kind, unit and type element (Real,
    Float64, ...; None: none given)."""

    kind: str
    unit: str | None
    type: str | None = None


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
        what = f"component {name!r}'s connector {label!r}"
        refuse_clocks(connector, what, where)
        refuse_array(connector, what, where)
        typed = type_element(connector)
        if typed is None:
            found[label] = Connector(kind, None)
        else:
            found[label] = Connector(kind, typed.get("unit"), etree.QName(typed).localname)
    return found


def ssd_units(ssd: Element) -> dict[str, Meaning]:
    """The SSD's own Units by name (`system.units.meaning`: UnitDefinitionError for a factor of 0
    or a number that is not finite)."""
    units = {}
    for unit in ssd.iterfind("ssd:Units/ssc:Unit", NS):
        base = unit.find("ssc:BaseUnit", NS)
        attributes = dict(base.attrib) if base is not None else {}
        units[unit.get("name")] = meaning(
            unit.get("name"),
            [attributes.get(key, 0) for key in BASE],
            attributes.get("factor", 1),
            attributes.get("offset", 0),
        )
    return units


def meaning_of(unit: str, fmu: FmuVariables) -> Meaning | None:
    """What `unit` means in the FMU (`system.units.unit_meaning`)."""
    return unit_meaning(unit, fmu.model_description)


def _show(meaning: Meaning | None, name: str | None) -> str:
    if meaning is None:
        return repr(name)
    powers = " ".join(f"{key}^{int(p)}" if p != 1 else key for key, p in zip(BASE, meaning, strict=False) if p)
    factor, offset = meaning[-2:]
    return f"{name!r} (= {factor:g} {powers or '1'}{f' + {offset:g}' if offset else ''})"


def _end_unit(
    port: Port, connection: str, connector: Connector, fmu: FmuVariables, units: Mapping[str, Meaning], where: str
) -> tuple[str | None, Meaning | None]:
    """The unit a port's value has (its FMU's; the connector's where the FMU gives none) and what
    it means; SspError if the connector's unit means another dimension than the FMU's."""
    own = fmu.unit(port.variable)
    given = connector.unit
    given_meaning = (units.get(given) or meaning_of(given, fmu)) if given else None
    own_meaning = meaning_of(own, fmu) if own else None
    if given and own and given != own:
        if given_meaning is None or own_meaning is None or given_meaning[:-2] != own_meaning[:-2]:
            what = "another dimension" if given_meaning and own_meaning else "and what one means is not defined"
            raise SspError(
                f"{where}: the connection {connection} gives {port} the unit {_show(given_meaning, given)}, but its "
                f"FMU's unit is {_show(own_meaning, own)}, {what} (give the connector the FMU's unit)"
            )
    if own:
        return own, own_meaning
    return given, given_meaning


def _transformation(element: Element, connection: str, where: str) -> tuple[float, float]:
    """The connection's LinearTransformation (factor, offset); (1, 0) without one."""
    found = (1.0, 0.0)
    for child in element:
        kind = etree.QName(child).localname
        if kind in ("Annotations", "ConnectionGeometry"):
            continue
        if kind != "LinearTransformation":
            raise SspError(
                f"{where}: the connection {connection} has a {kind} (only a LinearTransformation is supported; "
                "remove it)"
            )
        found = (float(child.get("factor", 1)), float(child.get("offset", 0)))
    return found


def _scaling(
    element: Element,
    start: Port,
    end: Port,
    connectors: Mapping[str, Mapping[str, Connector]],
    fmus: Mapping[str, FmuVariables],
    units: Mapping[str, Meaning],
    where: str,
) -> tuple[float, float]:
    """(factor, offset) of one connection: its unit conversion, then its LinearTransformation."""
    label = f"{start} -> {end}"
    ends = [
        _end_unit(port, label, connectors[port.component][port.variable], fmus[port.component], units, where)
        for port in (start, end)
    ]
    (start_unit, start_meaning), (end_unit, end_meaning) = ends
    factor, offset = 1.0, 0.0
    if start_unit and end_unit:
        if start_meaning is None or end_meaning is None:
            if start_unit != end_unit:
                raise SspError(
                    f"{where}: the connection {label} joins {start_unit} to {end_unit}, and what "
                    f"{start_unit if start_meaning is None else end_unit} means is not defined (define it in the "
                    "SSD's Units, or give both the same unit)"
                )
        elif start_meaning[:-2] != end_meaning[:-2]:
            raise SspError(
                f"{where}: the connection {label} joins {start_unit} to {end_unit}, units of different dimensions "
                f"({_show(start_meaning, start_unit)}, {_show(end_meaning, end_unit)}; connect a variable of the "
                "same dimension)"
            )
        else:
            factor, offset = conversion(start_meaning, end_meaning)
    a, b = _transformation(element, label, where)
    if element.get("suppressUnitConversion", "false") in ("true", "1"):
        total = (a, b)
    elif (a, b) == (1.0, 0.0):
        total = (factor, offset)
    else:
        total = (a * factor, a * offset + b)
    return _beyond_master(total, (factor, offset), start, end, fmus, label, where)


def _beyond_master(
    total: tuple[float, float],
    units: tuple[float, float],
    start: Port,
    end: Port,
    fmus: Mapping[str, FmuVariables],
    label: str,
    where: str,
) -> tuple[float, float]:
    """The Connection's factor and offset: what remains of the SSD's `total` once the master's own
    conversion between the two FMUs' units (`cosim.systems.unit_conversion`, applied after the
    Connection's) is taken out; `units` is the SSD's unit conversion (the master's, where both FMUs
    declare their units, and then a pure unit conversion leaves the identity)."""
    from toggle_cosim.cosim.systems import SystemError_, unit_conversion

    connection = Connection(start, end)
    try:
        master = unit_conversion(
            connection,
            (fmus[start.component].unit(start.variable), fmus[start.component].model_description),
            (fmus[end.component].unit(end.variable), fmus[end.component].model_description),
        )
    except SystemError_ as error:
        raise SspError(f"{where}: {error}") from None
    if master is None:
        return total
    f, o = master
    if total == units == master:
        return 1.0, 0.0
    return total[0] / f, (total[1] - o) / f


def _port(element: Element, side: str, connectors, fmus, where: str) -> Port:  # noqa: ANN001
    component, connector = element.get(f"{side}Element"), element.get(f"{side}Connector")
    if component is None:
        raise SspError(
            f"{where}: a connection to the system's own connector {connector!r} (system-level connectors "
            "are not supported; connect the components directly)"
        )
    if component not in connectors:
        raise SspError(
            f"{where}: a connection names the component {component!r}, which does not exist "
            f"(choose one of {', '.join(connectors)})"
        )
    if connector not in connectors[component]:
        raise SspError(
            f"{where}: a connection names the connector {component}.{connector}, which the component does "
            "not declare (declare it in its Connectors or fix the name)"
        )
    return Port(component, connector)


def read_connections(
    ssd: Element,
    where: str,
    fmus: Mapping[str, FmuVariables],
    connectors: Mapping[str, Mapping[str, Connector]],
) -> tuple[Connection, ...]:
    """Every connection of the SSD in document order, checked (module docstring), with the factor
    and offset of its unit conversion and LinearTransformation."""
    ends: list[tuple[Element, Port, Port]] = []
    for element in ssd.iterfind("ssd:System/ssd:Connections/ssd:Connection", NS):
        start = _port(element, "start", connectors, fmus, where)
        end = _port(element, "end", connectors, fmus, where)
        label = f"{start} -> {end}"
        kinds = (connectors[start.component][start.variable].kind, connectors[end.component][end.variable].kind)
        if kinds != ("output", "input"):
            raise SspError(
                f"{where}: the connection {label} runs from a connector of kind {kinds[0]} to one of kind "
                f"{kinds[1]} (a connection runs from an output to an input)"
            )
        for port in (start, end):
            kind = fmus[port.component].variable(port.variable).type
            declared = connectors[port.component][port.variable].type
            for what, name in (("variable", kind), ("connector", declared)):
                if name is not None and family(name) != "Real":
                    raise SspError(
                        f"{where}: the connection {label} joins {port}, a {name} {what} (connections here join "
                        "Real inputs and outputs: Real, Float64, Float32; remove it)"
                    )
        ends.append((element, start, end))
    plain = [Connection(start, end) for _, start, end in ends]
    loop = algebraic_loop(plain, {name: fmu.interface() for name, fmu in fmus.items()})
    if loop is not None:
        raise SspError(
            f"{where}: an algebraic loop {' -> '.join(loop)} (through the connections and the FMUs' direct "
            "dependencies; break it)"
        )
    driven: dict[Port, str] = {}
    for _, start, end in ends:
        if end in driven:
            raise SspError(f"{where}: the connections {driven[end]} and {start} -> {end} both drive {end}")
        driven[end] = f"{start} -> {end}"
    found = []
    try:
        units = ssd_units(ssd)
        for element, start, end in ends:
            factor, offset = _scaling(element, start, end, connectors, fmus, units, where)
            found.append(Connection(start, end, factor, offset))
    except UnitDefinitionError as error:
        raise SspError(f"{where}: {error}") from None
    return tuple(found)


def is_pair_loop(
    connections: Sequence[Connection], plant: str, controller: str, fmus: Mapping[str, FmuVariables]
) -> bool:
    """Whether the connections are exactly the loop our master runs for a plant and a controller,
    in any order and each the identity: every controller input (`FmuVariables.inputs`) from the
    plant output of its name, and the controller's iq_ref to the plant's iq_ref."""
    from toggle_cosim.cosim.systems import pair_connections  # the master's own definition of the pair

    expected = set(pair_connections(Wiring(plant=plant, controller=controller), fmus[controller].inputs()))
    return len(connections) == len(expected) and set(connections) == expected
