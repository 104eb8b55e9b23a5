"""modelDescription.xml for a compiled model, FMI 2.0 and FMI 3.0, Co-Simulation, Model
Exchange or both.

Written from `GeneratedModel`: every variable with its causality, variability, initial,
unit, description and, where the standard allows one, start value; the unit definitions;
and the model structure with the dependencies structure.py reads off the flat model. After
the model's variables come the shell's own (value references as `shell/instance.h` numbers
them): the solver settings (tunable parameters), `time` (FMI 3.0), the integrator
statistics (`solver.steps`, `solver.rejectedSteps`, `solver.events`: Integer / Int64,
local, discrete), der(x) of every state, and (FMI 3.0 Model Exchange) the event indicators.
"""

from __future__ import annotations

import datetime
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass

from toggle_cosim.fmu_export.compile import GeneratedModel, ModelVariable
from toggle_cosim.fmu_export.interfaces import CO_SIMULATION, MODEL_EXCHANGE, Interfaces
from toggle_cosim.fmu_export.shell_settings import (
    FMI2_LOG_CATEGORIES,
    FMI3_LOG_CATEGORIES,
    SHELL_SETTINGS,
    SHELL_STATISTICS,
    ShellSetting,
    ShellStatistic,
)
from toggle_cosim.fmu_export.units import base_exponents


@dataclass(frozen=True)
class ShellReferences:
    """The value references of the shell's variables for `model` (shell/instance.h MD_VR_*)."""

    settings: int
    time: int
    statistics: int
    derivatives: int
    indicators: int

    @classmethod
    def of(cls, model: GeneratedModel) -> ShellReferences:
        settings = len(model.variables)
        time = settings + len(SHELL_SETTINGS)
        statistics = time + 1
        derivatives = statistics + len(SHELL_STATISTICS)
        return cls(settings, time, statistics, derivatives, derivatives + len(model.states))


def _shell_variables(references: ShellReferences) -> list[tuple[str, dict[str, str], dict[str, str]]]:
    """The shell's own variables in value-reference order, for either version's writer: the
    solver settings (tunable Real parameters) and the integrator statistics (discrete Integer
    locals), each as (type "Real" or "Integer", the variable's attributes, the type's attributes)."""

    def attributes(
        entry: ShellSetting | ShellStatistic, reference: int, causality: str, variability: str
    ) -> dict[str, str]:
        return {
            "name": entry.name,
            "valueReference": str(reference),
            "description": entry.description,
            "causality": causality,
            "variability": variability,
        }

    found: list[tuple[str, dict[str, str], dict[str, str]]] = []
    for offset, setting in enumerate(SHELL_SETTINGS):
        tunable = {**attributes(setting, references.settings + offset, "parameter", "tunable"), "initial": "exact"}
        found.append(("Real", tunable, {"unit": setting.unit, "start": _number(setting.start)}))
    for offset, statistic in enumerate(SHELL_STATISTICS):
        found.append(("Integer", attributes(statistic, references.statistics + offset, "local", "discrete"), {}))
    return found


def default_experiment(model: GeneratedModel) -> dict[str, str]:
    """<DefaultExperiment> from the model's `experiment` annotation; the tolerance defaults to
    the shell's relative tolerance."""
    return model.experiment.attributes(default_tolerance=SHELL_SETTINGS[0].start)


def _continuous_dependencies(model: GeneratedModel, name: str) -> frozenset[str] | None:
    return model.dependencies.continuous.get(name) if model.dependencies.continuous else None


def _initial_dependencies(model: GeneratedModel, name: str) -> frozenset[str] | None:
    return model.dependencies.initial.get(name) if model.dependencies.initial else None


def _dependency_list(found: frozenset[str] | None, key: dict[str, int]) -> str | None:
    """The dependencies attribute: the keys (indices / value references) of the named
    knowns, ascending; None (attribute left out: depends on everything) if unknown."""
    if found is None:
        return None
    return " ".join(str(k) for k in sorted(key[name] for name in found if name in key))


def _unknown(parent: ET.Element, tag: str, key_attribute: str, key: int, dependencies: str | None) -> None:
    element = ET.SubElement(parent, tag, {key_attribute: str(key)})
    if dependencies is not None:
        element.set("dependencies", dependencies)


def _initial_unknowns(*groups: Iterable[tuple[int, str]]) -> list[tuple[int, str]]:
    """The InitialUnknowns as (key, name), ascending by key, each once: an output that is
    also a state (a filter whose output is its state) is one unknown, not two."""
    return sorted(dict(item for group in groups for item in group).items())


def _state_variables(model: GeneratedModel) -> list[ModelVariable]:
    return [model.variable(name) for name in model.states]


def _number(value: float) -> str:
    return repr(float(value))


def _fmi2_attributes(variable: ModelVariable) -> dict[str, str]:
    """causality / variability / initial for FMI 2.0, from the variable's kind."""
    if variable.kind == "parameter":
        return {"causality": "parameter", "variability": "fixed", "initial": "exact"}
    if variable.kind == "calculated":
        return {"causality": "calculatedParameter", "variability": "fixed", "initial": "calculated"}
    if variable.kind == "constant":
        return {"causality": "local", "variability": "constant", "initial": "exact"}
    if variable.kind == "input":
        return {"causality": "input", "variability": "continuous"}
    causality = "output" if variable.causality == "output" else "local"
    variability = "discrete" if variable.discrete else "continuous"
    return {"causality": causality, "variability": variability, "initial": "calculated"}


def _units(model: GeneratedModel) -> list[str]:
    found = {v.unit for v in model.variables if v.unit} | {s.unit for s in SHELL_SETTINGS}
    return sorted(found)


def _add_unit_definitions(root: ET.Element, units: list[str]) -> None:
    definitions = ET.SubElement(root, "UnitDefinitions")
    for unit in units:
        element = ET.SubElement(definitions, "Unit", name=unit)
        ET.SubElement(element, "BaseUnit", {k: str(v) for k, v in base_exponents(unit).items()})


def _description_root(model: GeneratedModel, tool: str, **version_specific: str) -> ET.Element:
    """<fmiModelDescription> with the attributes both standards share, then the version's own."""
    root = ET.Element(
        "fmiModelDescription",
        fmiVersion=version_specific.pop("fmiVersion"),
        modelName=model.name,
        **{k: version_specific.pop(k) for k in ("guid", "instantiationToken") if k in version_specific},
        description=model.description,
        generationTool=tool,
        generationDateAndTime=datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        variableNamingConvention="structured",
        **version_specific,
    )
    if not model.description:
        del root.attrib["description"]
    return root


def _fmi2_interface_elements(
    root: ET.Element, model_identifier: str, interfaces: Interfaces, sources: tuple[str, ...]
) -> None:
    """<ModelExchange> and / or <CoSimulation>, in the schema's order, with <SourceFiles>."""
    common = {
        "modelIdentifier": model_identifier,
        "needsExecutionTool": "false",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "false",
        "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true",
        "providesDirectionalDerivative": "false",
    }
    elements = []
    if MODEL_EXCHANGE in interfaces:
        # fmi2CompletedIntegratorStep counts the importer's steps (solver.steps): wanted
        elements.append(ET.SubElement(root, "ModelExchange", {**common, "completedIntegratorStepNotNeeded": "false"}))
    if CO_SIMULATION in interfaces:
        elements.append(
            ET.SubElement(
                root,
                "CoSimulation",
                {
                    **common,
                    "canHandleVariableCommunicationStepSize": "true",
                    "canInterpolateInputs": "false",
                    "maxOutputDerivativeOrder": "0",
                    "canRunAsynchronuously": "false",
                },
            )
        )
    for element in elements:
        if sources:
            files = ET.SubElement(element, "SourceFiles")
            for name in sources:
                ET.SubElement(files, "File", name=name)


def fmi2_model_description(
    model: GeneratedModel,
    model_identifier: str,
    tool: str,
    interfaces: Interfaces = frozenset({CO_SIMULATION}),
    sources: tuple[str, ...] = (),
) -> str:
    """The FMI 2.0 modelDescription.xml text; `sources`: the C files of <SourceFiles>."""
    root = _description_root(
        model, tool, fmiVersion="2.0", guid=model.guid, numberOfEventIndicators=str(model.event_count)
    )
    _fmi2_interface_elements(root, model_identifier, interfaces, sources)
    _add_unit_definitions(root, _units(model))
    categories = ET.SubElement(root, "LogCategories")
    for category in FMI2_LOG_CATEGORIES:
        ET.SubElement(categories, "Category", name=category.name, description=category.description)
    ET.SubElement(root, "DefaultExperiment", default_experiment(model))
    variables = ET.SubElement(root, "ModelVariables")
    references = ShellReferences.of(model)
    index_of: dict[str, int] = {}  # variable name -> 1-based index in ModelVariables
    outputs: list[ModelVariable] = []
    calculated: list[ModelVariable] = []
    for index, variable in enumerate(model.variables, start=1):
        index_of[variable.name] = index
        attributes = _fmi2_attributes(variable)
        element = ET.SubElement(
            variables,
            "ScalarVariable",
            name=variable.name,
            valueReference=str(variable.value_reference),
            description=variable.description,
            **attributes,
        )
        if not variable.description:
            del element.attrib["description"]
        has_start = attributes.get("initial") == "exact" or attributes["causality"] == "input"
        if variable.kind == "state" and variable.start is not None:
            # A literal start of a state is reported, not settable: initial = calculated
            # forbids a start attribute, so it goes into the description instead.
            element.set("description", f"{variable.description} (starts at {variable.start:g})".strip())
        if variable.base_type == "Boolean":
            typed = ET.SubElement(element, "Boolean")
            if has_start:
                typed.set("start", "true" if variable.start else "false")
        else:
            typed = ET.SubElement(element, "Real")
            if variable.unit:
                typed.set("unit", variable.unit)
            if has_start:
                typed.set("start", _number(variable.start if variable.start is not None else 0.0))
        if attributes["causality"] == "output":
            outputs.append(variable)
        elif attributes["causality"] == "calculatedParameter":
            calculated.append(variable)
    next_index = len(model.variables) + 1
    for kind, attributes, value in _shell_variables(references):
        if kind == "Integer":  # FMI 2.0 spells out what 3.0 implies for a local
            attributes = {**attributes, "initial": "calculated"}
        element = ET.SubElement(variables, "ScalarVariable", attributes)
        ET.SubElement(element, kind, value)
        next_index += 1
    derivative_index: list[int] = []
    for offset, state in enumerate(_state_variables(model)):
        element = ET.SubElement(
            variables,
            "ScalarVariable",
            name=f"der({state.name})",
            valueReference=str(references.derivatives + offset),
            description=f"Time derivative of {state.name}",
            causality="local",
            variability="continuous",
            initial="calculated",
        )
        ET.SubElement(element, "Real", derivative=str(index_of[state.name]))
        derivative_index.append(next_index)
        next_index += 1

    knowns = {v.name: index_of[v.name] for v in model.variables if v.kind in ("state", "input")}
    start_knowns = {v.name: index_of[v.name] for v in model.variables if v.kind in ("parameter", "input")}
    structure = ET.SubElement(root, "ModelStructure")
    if outputs:
        section = ET.SubElement(structure, "Outputs")
        for variable in outputs:
            _unknown(
                section,
                "Unknown",
                "index",
                index_of[variable.name],
                _dependency_list(_continuous_dependencies(model, variable.name), knowns),
            )
    if model.states:
        section = ET.SubElement(structure, "Derivatives")
        for index, name in zip(derivative_index, model.derivatives, strict=True):
            _unknown(
                section, "Unknown", "index", index, _dependency_list(_continuous_dependencies(model, name), knowns)
            )
    initial = _initial_unknowns(
        [(index_of[v.name], v.name) for v in (*outputs, *calculated)],
        [(index_of[name], name) for name in model.states],
        zip(derivative_index, model.derivatives, strict=True),
    )
    if initial:
        section = ET.SubElement(structure, "InitialUnknowns")
        for index, name in initial:
            _unknown(
                section, "Unknown", "index", index, _dependency_list(_initial_dependencies(model, name), start_knowns)
            )
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ---------------------------------------------------------------------------------------
# FMI 3.0
# ---------------------------------------------------------------------------------------


def time_value_reference(model: GeneratedModel) -> int:
    """The value reference of FMI 3.0's independent variable `time`: after the model's
    variables and the shell settings (shell/instance.h: MD_VR_TIME = nvars + MD_SHELL_NREAL)."""
    return ShellReferences.of(model).time


def _fmi3_attributes(variable: ModelVariable) -> dict[str, str]:
    """causality / variability / initial for FMI 3.0. The kinds map as in FMI 2.0 (the
    semantics of these combinations did not change); a Boolean cannot be continuous."""
    attributes = _fmi2_attributes(variable)
    if variable.base_type == "Boolean" and attributes["variability"] == "continuous":
        attributes["variability"] = "discrete"
    return attributes


def fmi3_model_description(
    model: GeneratedModel,
    model_identifier: str,
    tool: str,
    interfaces: Interfaces = frozenset({CO_SIMULATION}),
    sources: tuple[str, ...] = (),
) -> str:
    """The FMI 3.0 modelDescription.xml text (the sources are listed in buildDescription.xml).

    Value references are those of FMI 2.0 (the model's variables, then the shell's), plus
    `time` (causality independent) and, for Model Exchange, the event indicators. The model
    structure lists outputs, state derivatives, initial unknowns and event indicators by
    value reference.
    """
    del sources  # FMI 3.0 lists them in sources/buildDescription.xml
    root = _description_root(model, tool, fmiVersion="3.0", instantiationToken=model.guid)
    common = {
        "modelIdentifier": model_identifier,
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canGetAndSetFMUState": "true",
        "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "false",
        "providesAdjointDerivatives": "false",
        "providesPerElementDependencies": "false",
    }
    if MODEL_EXCHANGE in interfaces:
        ET.SubElement(
            root,
            "ModelExchange",
            {
                **common,
                "needsCompletedIntegratorStep": "true",  # it counts solver.steps
                "providesEvaluateDiscreteStates": "false",
            },
        )
    if CO_SIMULATION in interfaces:
        ET.SubElement(
            root,
            "CoSimulation",
            {
                **common,
                "canHandleVariableCommunicationStepSize": "true",
                "maxOutputDerivativeOrder": "0",
                "providesIntermediateUpdate": "false",
                "mightReturnEarlyFromDoStep": "false",
                "canReturnEarlyAfterIntermediateUpdate": "false",
                "hasEventMode": "false",
                "providesEvaluateDiscreteStates": "false",
            },
        )
    _add_unit_definitions(root, _units(model))
    categories = ET.SubElement(root, "LogCategories")
    for category in FMI3_LOG_CATEGORIES:
        ET.SubElement(categories, "Category", name=category.name, description=category.description)
    ET.SubElement(root, "DefaultExperiment", default_experiment(model))
    variables = ET.SubElement(root, "ModelVariables")
    references = ShellReferences.of(model)
    ET.SubElement(
        variables,
        "Float64",
        name="time",
        valueReference=str(references.time),
        description="Simulation time",
        causality="independent",
        variability="continuous",
        unit="s",
    )
    outputs: list[ModelVariable] = []
    calculated: list[ModelVariable] = []
    for variable in model.variables:
        attributes = _fmi3_attributes(variable)
        element = ET.SubElement(
            variables,
            "Boolean" if variable.base_type == "Boolean" else "Float64",
            name=variable.name,
            valueReference=str(variable.value_reference),
            description=variable.description,
            **attributes,
        )
        if not variable.description:
            del element.attrib["description"]
        if variable.kind == "state" and variable.start is not None:
            # initial = calculated forbids a start attribute: report the literal start instead
            element.set("description", f"{variable.description} (starts at {variable.start:g})".strip())
        if variable.base_type != "Boolean" and variable.unit:
            element.set("unit", variable.unit)
        if attributes.get("initial") == "exact" or attributes["causality"] == "input":
            start = variable.start if variable.start is not None else 0.0
            element.set("start", ("true" if start else "false") if variable.base_type == "Boolean" else _number(start))
        if attributes["causality"] == "output":
            outputs.append(variable)
        elif attributes["causality"] == "calculatedParameter":
            calculated.append(variable)
    for kind, attributes, value in _shell_variables(references):
        ET.SubElement(variables, {"Real": "Float64", "Integer": "Int64"}[kind], {**attributes, **value})
    derivative_vr: list[int] = []
    for offset, state in enumerate(_state_variables(model)):
        element = ET.SubElement(
            variables,
            "Float64",
            name=f"der({state.name})",
            valueReference=str(references.derivatives + offset),
            description=f"Time derivative of {state.name}",
            causality="local",
            variability="continuous",
            derivative=str(state.value_reference),
        )
        derivative_vr.append(references.derivatives + offset)
    indicator_vr: list[int] = []
    if MODEL_EXCHANGE in interfaces:
        for k in range(model.event_count):
            ET.SubElement(
                variables,
                "Float64",
                name=f"eventIndicator{k + 1}",
                valueReference=str(references.indicators + k),
                description=f"Event indicator {k + 1} of the model (zero crossings are events)",
                causality="local",
                variability="continuous",
            )
            indicator_vr.append(references.indicators + k)

    knowns = {v.name: v.value_reference for v in model.variables if v.kind in ("state", "input")}
    start_knowns = {v.name: v.value_reference for v in model.variables if v.kind in ("parameter", "input")}
    structure = ET.SubElement(root, "ModelStructure")
    for variable in outputs:
        _unknown(
            structure,
            "Output",
            "valueReference",
            variable.value_reference,
            _dependency_list(_continuous_dependencies(model, variable.name), knowns),
        )
    for reference, name in zip(derivative_vr, model.derivatives, strict=True):
        _unknown(
            structure,
            "ContinuousStateDerivative",
            "valueReference",
            reference,
            _dependency_list(_continuous_dependencies(model, name), knowns),
        )
    initial = _initial_unknowns(
        [(v.value_reference, v.name) for v in (*outputs, *calculated)],
        [(model.variable(name).value_reference, name) for name in model.states],
        zip(derivative_vr, model.derivatives, strict=True),
    )
    for reference, name in initial:
        _unknown(
            structure,
            "InitialUnknown",
            "valueReference",
            reference,
            _dependency_list(_initial_dependencies(model, name), start_knowns),
        )
    for reference in indicator_vr:
        ET.SubElement(structure, "EventIndicator", valueReference=str(reference))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
