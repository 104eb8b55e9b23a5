"""A scenario file -> an SSP archive (`toggle-cosim ssp`), SSP 1.0 (the default: what libcosim
and Ecos read) or SSP 2.0 (`--ssp-version 2.0`: Float64 connectors and values, Int32 integers, as
OMSimulator writes them, `versions.written_type`; the study's SRMD in each SSD's MetaData,
`study_record`): one root SSD per variant
(`SystemStructure.ssd` the first, `<variant>.ssd` the others: `layout`), each with the plant and
the controller FMU as components, the connections, one parameter binding per component (that
variant's .ssv), DefaultExperiment (0, t_end, with T_s as libcosim's fixed step) and our
annotation (the variant's scenario document, a description that no reader acts on).

Each set holds, for the plant, exactly what our master sets on it (`cosim.master.plant_settings`)
and F_E, its input; for the controller, every field of the built-in law's `LawParameters` but t0
and T_h (the controller FMU starts the law itself). Numbers are written with `repr`, so they read
back with the same bits. The archive is checked against the SSP schemas of its version before it is written,
and written whole or not at all (`files.outputs`).
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lxml import etree

from toggle_cosim.control.parameters import settable_values
from toggle_cosim.cosim.controllers import builtin_controller
from toggle_cosim.cosim.master import plant_settings
from toggle_cosim.cosim.outcome import installed_versions
from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
from toggle_cosim.experiments.shipped import DEFAULT_CONTROLLER
from toggle_cosim.files.outputs import SSP, replacing
from toggle_cosim.fmu_export.units import UnitError, base_exponents
from toggle_cosim.runs.definition import Run
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import DEFAULT_VERSION, VERSIONS, Element, SspError, schema_problem
from toggle_cosim.ssp.fmus import FmuVariables, describe
from toggle_cosim.ssp.study_record import metadata_element, study_record
from toggle_cosim.ssp.versions import written_type
from toggle_cosim.system.model import Connection, Port, Wiring

__all__ = ["ParameterSet", "controller_values", "default_controller", "parameter_sets", "write_ssp"]

# LawParameters fields the controller FMU computes itself at its first sample
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
Value = float | bool | int


@dataclass(frozen=True)
class ParameterSet:
    """One variant's values: for the plant (in the order the master sets them, then F_E) and for
    the controller, and the scenario document the run was built from."""

    name: str
    plant: tuple[tuple[str, Value], ...]
    controller: tuple[tuple[str, Value], ...]
    run: Run


def controller_values(run: Run) -> tuple[tuple[str, float], ...]:
    """The controller FMU's parameters for `run`: its built-in law's settable `law_parameters()`
    by field name (`control.parameters.settable_values`)."""
    return settable_values(builtin_controller(run).law_parameters())


def parameter_sets(runs: Sequence[Run], plant) -> list[ParameterSet]:  # noqa: ANN001 - a PlantInterface
    """One ParameterSet per run (variant), in order."""
    sets = []
    for run in runs:
        try:
            values = plant_settings(run, plant)
        except ValueError as error:
            raise SspError(f"{run.source}: {error}") from None
        sets.append(
            ParameterSet(
                layout.set_name(run.variant),
                (*values, (layout.EXTERNAL_FORCE, run.plant.F_E)),
                controller_values(run),
                run,
            )
        )
    return sets


def _q(namespace: str, tag: str) -> str:
    return f"{{{namespace}}}{tag}"


def _number(value: Value, kind: str) -> str:
    """The text of a value of SSV type `kind`: true/false, an integer, or repr of a float (read
    back with the same bits)."""
    if kind == "Boolean":
        return "true" if value else "false"
    if kind == "Integer":
        return str(int(value))
    return repr(float(value))


def _ssv(
    parameter_set: str, values: Sequence[tuple[str, Value]], variables: FmuVariables, version: str = DEFAULT_VERSION
) -> Element:
    """One component's values as an .ssv of SSP `version` (its types: `versions.written_type`)."""
    root = etree.Element(_q(layout.SSV_NS, "ParameterSet"), nsmap={"ssv": layout.SSV_NS}, version=version)
    root.set("name", parameter_set)
    parameters = etree.SubElement(root, _q(layout.SSV_NS, "Parameters"))
    for name, value in values:
        kind = variables.value_type(name, value)
        parameter = etree.SubElement(parameters, _q(layout.SSV_NS, "Parameter"), name=name)
        etree.SubElement(parameter, _q(layout.SSV_NS, written_type(kind, version)), value=_number(value, kind))
    return root


def _unit_element(units: Element, name: str, variables: Sequence[FmuVariables]) -> None:
    exponents = next((found for v in variables if (found := v.base_unit(name)) is not None), None)
    if exponents is None:
        try:
            exponents = {**base_exponents(name), "factor": 1.0, "offset": 0.0}
        except UnitError:
            return
    unit = etree.SubElement(units, _q(layout.SSC_NS, "Unit"), name=name)
    attributes = {key: str(int(exponents[key])) for key in BASE_UNITS if exponents.get(key, 0)}
    for key, default in (("factor", 1.0), ("offset", 0.0)):
        if float(exponents.get(key, default)) != default:
            attributes[key] = repr(float(exponents[key]))
    etree.SubElement(unit, _q(layout.SSC_NS, "BaseUnit"), attributes)


def _connectors(component: Element, names: Sequence[str], variables: FmuVariables, version: str) -> set[str]:
    """The component's connectors (each a Real: ssc:Real in SSP 1.0, ssc:Float64 in 2.0, with its
    FMU variable's unit); the units they use."""
    connectors = etree.SubElement(component, _q(layout.SSD_NS, "Connectors"))
    units = set()
    for name in names:
        variable = variables.variable(name)
        connector = etree.SubElement(connectors, _q(layout.SSD_NS, "Connector"), name=name, kind=variable.causality)
        unit = variables.unit(name)
        real = etree.SubElement(connector, _q(layout.SSC_NS, written_type("Real", version)))
        if unit:
            real.set("unit", unit)
            units.add(unit)
    return units


def _system_components(
    wiring: Wiring, plant: FmuVariables, controller: FmuVariables, parts: Mapping[str, FmuVariables]
) -> tuple[list[tuple[str, FmuVariables, list[str]]], list[Connection]]:
    """The components of a system (plant, controller, parts in order) with the connectors each
    gets (every connected variable; the plant's F_E too, which its parameter set gives), and the
    connections (the pair's wiring when the system gives none)."""
    variables = {wiring.plant: plant, wiring.controller: controller, **{p.name: parts[p.name] for p in wiring.parts}}
    if wiring.connections is None:
        inputs = controller.inputs()
        connections = [Connection(Port(wiring.plant, s), Port(wiring.controller, s)) for s in inputs]
        connections.append(Connection(Port(wiring.controller, layout.COMMAND), Port(wiring.plant, layout.COMMAND)))
    else:
        connections = list(wiring.connections)
    connectors: dict[str, list[str]] = {name: [] for name in variables}
    for connection in connections:
        for port in (connection.start, connection.end):
            if port.component not in variables:
                raise SspError(
                    f"the connection {connection} names the component {port.component!r}, which the system does not "
                    f"have (its components: {', '.join(variables)})"
                )
            variables[port.component].variable(port.variable)
            if port.variable not in connectors[port.component]:
                connectors[port.component].append(port.variable)
    if layout.EXTERNAL_FORCE not in connectors[wiring.plant] and layout.EXTERNAL_FORCE in plant.variables:
        connectors[wiring.plant].append(layout.EXTERNAL_FORCE)
    return [(name, variables[name], connectors[name]) for name in variables], connections


def _transformation(wire: Element, connection: Connection, variables: Mapping[str, FmuVariables]) -> None:
    """The SSD form of a connection's factor and offset. Our master converts between the two
    FMUs' units itself, after the connection's factor and offset (`cosim.systems.unit_conversion`):
    where it would, the SSD says the whole conversion as a LinearTransformation with
    suppressUnitConversion="true" (so a master that ignores units, libcosim, runs it alike); else
    a non-identity connection is a LinearTransformation (the reader reads either back)."""
    from toggle_cosim.cosim.systems import SystemError_, unit_conversion

    start, end = variables[connection.start.component], variables[connection.end.component]
    try:
        master = unit_conversion(
            connection,
            (start.unit(connection.start.variable), start.model_description),
            (end.unit(connection.end.variable), end.model_description),
        )
    except SystemError_ as error:
        raise SspError(str(error)) from None
    if master is None:
        factor, offset = connection.factor, connection.offset
    else:
        f, o = master
        factor, offset = f * connection.factor, f * connection.offset + o
        wire.set("suppressUnitConversion", "true")
    if (factor, offset) != (1.0, 0.0):
        attributes = {}
        if factor != 1.0:
            attributes["factor"] = repr(float(factor))
        if offset != 0.0:
            attributes["offset"] = repr(float(offset))
        etree.SubElement(wire, _q(layout.SSC_NS, "LinearTransformation"), attributes)


def _document(run: Run) -> dict[str, Any]:
    """The scenario document of one run: its resolved keys (the variant applied), without the
    scenario's own fmu (the SSP holds the plant)."""
    return {key: value for key, value in run.resolved.items() if key != "fmu"}


def system_structure(
    scenario: str,
    parameter_set: ParameterSet,
    plant: FmuVariables,
    controller: FmuVariables,
    fmus: Mapping[str, str],
    parts: Mapping[str, FmuVariables] | None = None,
    version: str = DEFAULT_VERSION,
    metadata: Sequence[Element] = (),
) -> Element:
    """The root SSD of one variant in SSP `version` ("1.0", "2.0"): `fmus` maps each component to
    its FMU's member name, `parts` each part of the run's system to its FMU's variables; each
    component binds that variant's .ssv, and nothing else. A run whose system has parts or
    connections of its own gets every component, connectors for each connected variable and its
    connections (`_transformation`). `metadata`: SSP 2.0 ssc:MetaData elements, placed after the
    DefaultExperiment (SSP 1.0 has no place for them)."""
    run = parameter_set.run
    root = etree.Element(
        _q(layout.SSD_NS, "SystemStructureDescription"),
        # osp declared here: libcosim reads an attribute of osp:Algorithm (xmlns:osp too) as an algorithm
        nsmap={"ssd": layout.SSD_NS, "ssc": layout.SSC_NS, "ssv": layout.SSV_NS, "osp": layout.OSP_NS},
        version=version,
        name=parameter_set.name,
        generationTool="toggle-cosim",
    )
    system = etree.SubElement(root, _q(layout.SSD_NS, "System"), name=scenario)
    if run.description:
        system.set("description", run.description)
    elements = etree.SubElement(system, _q(layout.SSD_NS, "Elements"))
    wiring = run.system
    if wiring.parts or wiring.connections is not None:
        components, connections = _system_components(wiring, plant, controller, parts or {})
    else:  # the plain pair
        inputs = controller.inputs()
        connections = [Connection(Port(layout.PLANT, signal), Port(layout.CONTROLLER, signal)) for signal in inputs]
        connections.append(Connection(Port(layout.CONTROLLER, layout.COMMAND), Port(layout.PLANT, layout.COMMAND)))
        components = [
            (layout.PLANT, plant, [*inputs, layout.COMMAND, layout.EXTERNAL_FORCE]),
            (layout.CONTROLLER, controller, [*inputs, layout.COMMAND]),
        ]
    variables_of = {component: variables for component, variables, _ in components}
    units: set[str] = set()
    for component, variables, connectors in components:
        element = etree.SubElement(
            elements,
            _q(layout.SSD_NS, "Component"),
            name=component,
            type=layout.FMU_TYPE,
            source=fmus[component],
        )
        units |= _connectors(element, connectors, variables, version)
        bindings = etree.SubElement(element, _q(layout.SSD_NS, "ParameterBindings"))
        etree.SubElement(
            bindings,
            _q(layout.SSD_NS, "ParameterBinding"),
            type="application/x-ssp-parameter-set",
            source=layout.ssv_member(parameter_set.name, component),
        )
    wires = etree.SubElement(system, _q(layout.SSD_NS, "Connections"))
    for connection in connections:
        wire = etree.SubElement(
            wires,
            _q(layout.SSD_NS, "Connection"),
            startElement=connection.start.component,
            startConnector=connection.start.variable,
            endElement=connection.end.component,
            endConnector=connection.end.variable,
        )
        _transformation(wire, connection, variables_of)
    if units:
        unit_list = etree.SubElement(root, _q(layout.SSD_NS, "Units"))
        for unit in sorted(units):
            _unit_element(unit_list, unit, tuple(variables_of.values()))
        if len(unit_list) == 0:
            root.remove(unit_list)
    default = etree.SubElement(root, _q(layout.SSD_NS, "DefaultExperiment"), startTime="0.0", stopTime=repr(run.t_end))
    osp = etree.SubElement(  # T_s as libcosim's fixed step
        etree.SubElement(default, _q(layout.SSD_NS, "Annotations")),
        _q(layout.SSC_NS, "Annotation"),
        type=layout.OSP_ANNOTATION_TYPE,
    )
    algorithm = etree.SubElement(osp, _q(layout.OSP_NS, "Algorithm"))
    etree.SubElement(algorithm, _q(layout.OSP_NS, "FixedStepAlgorithm"), baseStepSize=repr(run.T_s))
    if metadata and version == "1.0":
        raise ValueError("SSP 1.0 has no MetaData element: write SSP 2.0 to carry it")
    root.extend(metadata)
    annotations = etree.SubElement(root, _q(layout.SSD_NS, "Annotations"))
    annotation = etree.SubElement(annotations, _q(layout.SSC_NS, "Annotation"), type=layout.ANNOTATION_TYPE)
    described = etree.SubElement(annotation, _q(layout.TOGGLE_NS, "Scenario"), nsmap={"tc": layout.TOGGLE_NS})
    described.set("name", run.scenario)
    if run.variant is not None:
        described.set("variant", run.variant)
    described.text = json.dumps(_document(run), sort_keys=True)
    return root


def variant_members(path: Path, sets: Sequence[ParameterSet]) -> list[str]:
    """The root SSD of each set, in order (`layout.ssd_member`); SspError if two would share a
    name, also on a file system that ignores case (a variant named SystemStructure, or two that
    differ in case only)."""
    members = [layout.ssd_member(index, parameter_set.name) for index, parameter_set in enumerate(sets)]
    seen: dict[str, str] = {}
    for member, parameter_set in zip(members, sets, strict=True):
        other = seen.setdefault(member.casefold(), parameter_set.name)
        if other != parameter_set.name:
            raise SspError(
                f"{parameter_set.run.source}: key variants: {other!r} and {parameter_set.name!r} would both be "
                f"written as {member} (names are compared ignoring case; rename one variant)"
            )
    return members


def _checked(root: Element, kind: str, member: str) -> bytes:
    problem = schema_problem(root, kind)
    if problem is not None:  # what we write is valid by construction: a failure here is our bug
        raise AssertionError(f"{member} written invalid ({problem})")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _refuse_sweep(path: Path) -> None:
    """SspError if `path` is a sweep file (which the scenario schema refuses as an unknown file)."""
    from toggle_cosim.files.yaml_loader import YamlError, load_yaml

    try:
        document = load_yaml(path, "scenario file")
    except YamlError:
        return
    if isinstance(document, Mapping) and ("axes" in document or "base" in document):
        raise SspError(
            f"{path}: a sweep file cannot be written as an SSP (an SSP holds one scenario and its variants); "
            "give the scenario file its base: names"
        )


def refuse_unwritable(path: Path, runs: Sequence[Run]) -> None:
    """SspError for a scenario an SSP cannot hold: a controller in Python, a load that varies in
    time, variants that differ in t_end or T_s (an SSP has one experiment)."""
    for run in runs:
        if run.controller.fmu is not None:
            raise SspError(
                f"{path}: key controller.fmu: the SSP's controller is the one given with --controller, with the built-in "
                "law's parameters; remove controller.fmu from the scenario and name that FMU with --controller"
            )
        if run.controller.python is not None:
            raise SspError(
                f"{path}: key controller.python: an SSP's controller is an FMU, so a Python controller cannot be "
                "written into it (use the built-in law, or run the scenario with toggle-cosim run)"
            )
        if run.plant.inputs:
            raise SspError(
                f"{path}: key plant.inputs: the SSP connects the plant's iq_ref and F_E only, so its other inputs "
                f"({', '.join(run.plant.inputs)}) cannot be written into it (run the scenario with toggle-cosim run)"
            )
        if run.trajectory is not None:
            raise SspError(
                f"{path}: key stroke.trajectory: an SSP's controller FMU regulates to the constant target (its"
                " reference inputs are left unconnected), so a trajectory cannot be written into it (remove"
                " stroke.trajectory, or run the scenario with toggle-cosim run)"
            )
        if not isinstance(run.plant.F_E, (int, float)):
            raise SspError(
                f"{path}: key plant.F_E: the load is a {run.plant.F_E.kind} in time, and an SSP's parameter set holds"
                " one value per input (give F_E a number, or run the scenario with toggle-cosim run)"
            )
    for key in ("t_end", "T_s"):
        values = {getattr(run, key) for run in runs}
        if len(values) > 1:
            raise SspError(
                f"{path}: key {key}: the variants use {', '.join(repr(v) for v in sorted(values))} s, and an SSP has one "
                "experiment for all its parameter sets (give every variant the same value, or split the scenario)"
            )


def _chosen(path: Path, runs: list[Run], variants: Sequence[str]) -> list[Run]:
    """The runs of the variants named, in the order named (none named: every run)."""
    if not variants:
        return runs
    known = {layout.set_name(run.variant): run for run in runs}
    for name in variants:
        if name not in known:
            raise SspError(f"{path}: no variant {name!r} (choose one of {', '.join(known)} with --variant)")
    return [known[name] for name in dict.fromkeys(variants)]


def default_controller(plant_fmu: Path) -> Path:
    """The controller FMU an SSP takes when none is named: `ToggleVSC.fmu` beside the plant FMU,
    where `toggle-cosim build` writes both, so it is found by the rule that finds the plant
    (the scenario's fmu: key, relative to the scenario file) from any working folder."""
    return Path(plant_fmu).with_name(DEFAULT_CONTROLLER.name)


def write_ssp(
    scenario: Path,
    output: Path,
    plant_fmu: Path | None,
    controller_fmu: Path | None,
    variants: Sequence[str] = (),
    runs: Sequence[Run] | None = None,
    version: str = DEFAULT_VERSION,
) -> Path:
    """Write the SSP of `scenario` to `output` (whole or not at all) and return `output`.

    `plant_fmu`: the plant (None: the scenario's fmu: key, relative to the scenario file);
    `controller_fmu`: the controller (None: `default_controller`, beside the plant); `variants`: the variants to write, the
    first as SystemStructure.ssd (none: every variant in the scenario's order); `runs`: the
    scenario's runs as already loaded (None: loaded from `scenario`). A run's system (`Run.system`:
    parts, connections) is written as it is; its `record` list is no part of an SSD. `version`: the
    SSP version of every SSD and .ssv ("1.0", the default, which libcosim and Ecos read; or "2.0":
    Float64 connectors and values, Int32 integers, and the study's SRMD in each SSD's MetaData,
    `study_record`). Raises ScenarioError for a scenario
    that `run` refuses, SspError (one line) for anything else an SSP cannot be made from."""
    from toggle_cosim.plant.contract import ContractError, check_plant
    from toggle_cosim.plant.settings import SettingError, check_settings

    scenario = Path(scenario)
    if version not in VERSIONS:
        raise SspError(
            f"SSP version {version!r} (--ssp-version): toggle-cosim writes SSP {' or '.join(VERSIONS)} (give one of them)"
        )
    if runs is None:
        try:
            runs = load_scenario(scenario)
        except ScenarioError:
            _refuse_sweep(scenario)  # a sweep file is no scenario: say what it is
            raise
    runs = _chosen(scenario, list(runs), variants)
    refuse_unwritable(scenario, runs)
    chosen = plant_fmu if plant_fmu is not None else runs[0].fmu
    if chosen is None:
        raise SspError(f"{scenario}: no fmu: key and no --plant option (name the plant FMU)")
    try:
        plant = check_plant(Path(chosen))
    except ContractError as error:
        raise SspError(str(error)) from None
    for run in runs:
        try:
            check_settings(run, plant)
        except SettingError as error:
            raise SspError(f"{scenario}: {error}") from None
    plant_variables = FmuVariables.of(plant.path, plant.model_description)
    controller_fmu = Path(controller_fmu) if controller_fmu is not None else default_controller(plant.path)
    controller_variables = describe(controller_fmu)
    controller_variables.check_controller(plant_variables)
    sets = parameter_sets(runs, plant)
    for parameter_set in sets:
        for component, values, variables in (
            (layout.PLANT, parameter_set.plant, plant_variables),
            (layout.CONTROLLER, parameter_set.controller, controller_variables),
        ):
            variables.check_parameters(values, component, f"the {component}'s parameter set {parameter_set.name!r}")
    parts = _part_variables(scenario, runs)
    fmus = {layout.PLANT: plant.path, layout.CONTROLLER: Path(controller_fmu)}
    members = {component: layout.fmu_member(path.name) for component, path in fmus.items()}
    if members[layout.PLANT] == members[layout.CONTROLLER]:
        members[layout.CONTROLLER] = layout.fmu_member(f"{layout.CONTROLLER}_{fmus[layout.CONTROLLER].name}")
    part_members = _part_members(runs, members, fmus)
    texts = {}
    tools = installed_versions()
    for member, parameter_set in zip(variant_members(scenario, sets), sets, strict=True):
        wiring = parameter_set.run.system
        named = {
            wiring.plant: members[layout.PLANT],
            wiring.controller: members[layout.CONTROLLER],
            **{part.name: part_members[part.fmu] for part in wiring.parts},
        }
        ssvs = {}
        for component, values, variables in (
            (wiring.plant, parameter_set.plant, plant_variables),
            (wiring.controller, parameter_set.controller, controller_variables),
            *((part.name, part.values, parts[part.fmu]) for part in wiring.parts),
        ):
            ssv = layout.ssv_member(parameter_set.name, component)
            ssvs[component] = (ssv, _checked(_ssv(parameter_set.name, values, variables, version), "ssv", ssv))
        metadata = []
        if version != "1.0":  # SSP 2.0: the study's SRMD in the SSD's MetaData
            paths = {
                wiring.plant: fmus[layout.PLANT],
                wiring.controller: fmus[layout.CONTROLLER],
                **{part.name: Path(part.fmu) for part in wiring.parts},
            }
            used = {component: (named[component], paths[component]) for component in named}
            metadata.append(metadata_element(study_record(scenario, parameter_set.name, used, ssvs, tools)))
        try:
            ssd = system_structure(
                runs[0].scenario,
                parameter_set,
                plant_variables,
                controller_variables,
                named,
                {part.name: parts[part.fmu] for part in wiring.parts},
                version,
                metadata,
            )
        except SspError as error:
            raise SspError(f"{scenario}: variant {parameter_set.name}: {error}") from None
        texts[member] = _checked(ssd, "ssd", member)
        texts.update(dict(ssvs.values()))
    stored = {members[component]: path for component, path in fmus.items()}
    stored.update({member: path for path, member in part_members.items()})
    with replacing(output, "SSP (--out)", kind=SSP) as temporary:
        with zipfile.ZipFile(temporary, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            for member, text in texts.items():
                archive.writestr(member, text)
            for member, path in stored.items():  # an FMU is a zip already: stored as it is
                archive.write(path, member, compress_type=zipfile.ZIP_STORED)
    return Path(output)


def _part_variables(scenario: Path, runs: Sequence[Run]) -> dict[Path, FmuVariables]:
    """Each part FMU of the runs' systems, read once; every part's values checked against it."""
    found: dict[Path, FmuVariables] = {}
    for run in runs:
        names = {run.system.plant, run.system.controller}
        for part in run.system.parts:
            if part.name in names:
                raise SspError(f"{scenario}: two components are named {part.name!r} (give each its own name)")
            names.add(part.name)
            if part.fmu not in found:
                if not Path(part.fmu).is_file():
                    raise SspError(
                        f"{scenario}: key components.{part.name}.fmu: no FMU at {part.fmu} (build it, or fix the path)"
                    )
                found[part.fmu] = describe(Path(part.fmu), "part")
                if getattr(found[part.fmu].model_description, "coSimulation", None) is None:
                    raise SspError(
                        f"{scenario}: key components.{part.name}.fmu: {part.fmu} has no Co-Simulation interface "
                        "(an SSP's components run as Co-Simulation FMUs; export it for Co-Simulation)"
                    )
            found[part.fmu].check_parameters(part.values, f"part {part.name!r}", part.source or str(scenario))
    return found


def _part_members(runs: Sequence[Run], members: Mapping[str, str], fmus: Mapping[str, Path]) -> dict[Path, str]:
    """The archive member of each part FMU: resources/<its file name>, or <part>_<file name>
    where another FMU has that name (one member per file: parts of one FMU share it)."""
    taken = {member: path for member, path in zip(members.values(), fmus.values(), strict=True)}
    found: dict[Path, str] = {}
    for run in runs:
        for part in run.system.parts:
            if part.fmu in found:
                continue
            member = layout.fmu_member(Path(part.fmu).name)
            if taken.get(member, part.fmu) != part.fmu:
                member = layout.fmu_member(f"{part.name}_{Path(part.fmu).name}")
            taken[member] = part.fmu
            found[part.fmu] = member
    return found


def ssv_text(parameter_set: str, values: Sequence[tuple[str, Value]], variables: FmuVariables) -> bytes:
    """One component's parameter set as the text of a checked SSP 1.0 .ssv file (what `write_ssp`
    writes per component; an FMU carries its plant's sets this way too, `fmi_ls_ref.evidence`)."""
    return _checked(_ssv(parameter_set, values, variables), "ssv", parameter_set)
