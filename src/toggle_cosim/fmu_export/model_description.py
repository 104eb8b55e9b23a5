"""modelDescription.xml for a compiled model, FMI 2.0 and FMI 3.0 Co-Simulation.

Written from `GeneratedModel`: every variable with its causality, variability, initial,
unit, description and, where the standard allows one, start value; the unit definitions;
and the model structure. The shell's own solver settings are appended as parameters after
the model's variables (their value references follow the model's, as `shell/solver.h` says).
"""

from __future__ import annotations

import datetime
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from toggle_cosim.fmu_export.compile import GeneratedModel, ModelVariable
from toggle_cosim.fmu_export.units import base_exponents


@dataclass(frozen=True)
class ShellSetting:
    """A setting of the FMU's integrator, exposed as a tunable parameter."""

    name: str
    start: float
    unit: str
    description: str


SHELL_SETTINGS = (
    ShellSetting("solver.relTol", 1e-8, "1", "Relative tolerance of the FMU's Dormand-Prince 5(4) integrator"),
    ShellSetting("solver.absTol", 1e-10, "1", "Absolute tolerance of the FMU's integrator"),
    ShellSetting("solver.maxStep", 0.0, "s", "Largest internal step of the FMU's integrator; 0: no bound"),
)

DEFAULT_EXPERIMENT = {"startTime": "0.0", "stopTime": "1.5", "tolerance": "1e-08", "stepSize": "0.0005"}


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


def fmi2_model_description(model: GeneratedModel, model_identifier: str, tool: str) -> str:
    """The FMI 2.0 Co-Simulation modelDescription.xml text."""
    root = _description_root(model, tool, fmiVersion="2.0", guid=model.guid,
                             numberOfEventIndicators=str(model.event_count))
    ET.SubElement(
        root,
        "CoSimulation",
        modelIdentifier=model_identifier,
        canHandleVariableCommunicationStepSize="true",
        canInterpolateInputs="false",
        maxOutputDerivativeOrder="0",
        canRunAsynchronuously="false",
        canBeInstantiatedOnlyOncePerProcess="false",
        canNotUseMemoryManagementFunctions="false",
        canGetAndSetFMUstate="true",
        canSerializeFMUstate="true",
        providesDirectionalDerivative="false",
    )
    _add_unit_definitions(root, _units(model))
    ET.SubElement(root, "DefaultExperiment", DEFAULT_EXPERIMENT)
    variables = ET.SubElement(root, "ModelVariables")
    outputs: list[int] = []
    initial_unknowns: list[int] = []
    for index, variable in enumerate(model.variables, start=1):
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
            outputs.append(index)
            initial_unknowns.append(index)
        elif attributes["causality"] == "calculatedParameter":
            initial_unknowns.append(index)
    for offset, setting in enumerate(SHELL_SETTINGS):
        element = ET.SubElement(
            variables,
            "ScalarVariable",
            name=setting.name,
            valueReference=str(len(model.variables) + offset),
            description=setting.description,
            causality="parameter",
            variability="tunable",
            initial="exact",
        )
        ET.SubElement(element, "Real", unit=setting.unit, start=_number(setting.start))
    structure = ET.SubElement(root, "ModelStructure")
    if outputs:
        section = ET.SubElement(structure, "Outputs")
        for index in outputs:
            ET.SubElement(section, "Unknown", index=str(index))
    if initial_unknowns:
        section = ET.SubElement(structure, "InitialUnknowns")
        for index in initial_unknowns:
            ET.SubElement(section, "Unknown", index=str(index))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ---------------------------------------------------------------------------------------
# FMI 3.0
# ---------------------------------------------------------------------------------------

# The log categories of shell/fmi3.c, in its order (error statuses are logged regardless).
FMI3_LOG_CATEGORIES = (
    ("logEvents", "One line per state event: time, indicator and kind"),
    ("logStatusWarning", "Calls that return fmi3Warning, with the reason"),
    ("logStatusError", "Calls that return fmi3Error, with the reason (always reported)"),
    ("logAll", "Everything, including integrator statistics per communication step"),
)


def time_value_reference(model: GeneratedModel) -> int:
    """The value reference of FMI 3.0's independent variable `time`: after the model's
    variables and the shell settings (shell/fmi3.c: VR_TIME = nvars + MD_SHELL_NREAL)."""
    return len(model.variables) + len(SHELL_SETTINGS)


def _fmi3_attributes(variable: ModelVariable) -> dict[str, str]:
    """causality / variability / initial for FMI 3.0. The kinds map as in FMI 2.0 (the
    semantics of these combinations did not change); a Boolean cannot be continuous."""
    attributes = _fmi2_attributes(variable)
    if variable.base_type == "Boolean" and attributes["variability"] == "continuous":
        attributes["variability"] = "discrete"
    return attributes


def fmi3_model_description(model: GeneratedModel, model_identifier: str, tool: str) -> str:
    """The FMI 3.0 Co-Simulation modelDescription.xml text.

    Value references are those of FMI 2.0 (the model's variables, then the shell settings),
    plus `time` (causality independent) at `time_value_reference(model)`. The model
    structure lists outputs and initial unknowns by value reference.
    """
    root = _description_root(model, tool, fmiVersion="3.0", instantiationToken=model.guid)
    ET.SubElement(
        root,
        "CoSimulation",
        modelIdentifier=model_identifier,
        canBeInstantiatedOnlyOncePerProcess="false",
        canGetAndSetFMUState="true",
        canSerializeFMUState="true",
        providesDirectionalDerivatives="false",
        providesAdjointDerivatives="false",
        providesPerElementDependencies="false",
        canHandleVariableCommunicationStepSize="true",
        maxOutputDerivativeOrder="0",
        providesIntermediateUpdate="false",
        mightReturnEarlyFromDoStep="false",
        canReturnEarlyAfterIntermediateUpdate="false",
        hasEventMode="false",
        providesEvaluateDiscreteStates="false",
    )
    _add_unit_definitions(root, _units(model))
    categories = ET.SubElement(root, "LogCategories")
    for name, description in FMI3_LOG_CATEGORIES:
        ET.SubElement(categories, "Category", name=name, description=description)
    ET.SubElement(root, "DefaultExperiment", DEFAULT_EXPERIMENT)
    variables = ET.SubElement(root, "ModelVariables")
    ET.SubElement(
        variables,
        "Float64",
        name="time",
        valueReference=str(time_value_reference(model)),
        description="Simulation time",
        causality="independent",
        variability="continuous",
        unit="s",
    )
    outputs: list[int] = []
    initial_unknowns: list[int] = []
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
            outputs.append(variable.value_reference)
            initial_unknowns.append(variable.value_reference)
        elif attributes["causality"] == "calculatedParameter":
            initial_unknowns.append(variable.value_reference)
    for offset, setting in enumerate(SHELL_SETTINGS):
        ET.SubElement(
            variables,
            "Float64",
            name=setting.name,
            valueReference=str(len(model.variables) + offset),
            description=setting.description,
            causality="parameter",
            variability="tunable",
            initial="exact",
            unit=setting.unit,
            start=_number(setting.start),
        )
    structure = ET.SubElement(root, "ModelStructure")
    for reference in outputs:
        ET.SubElement(structure, "Output", valueReference=str(reference))
    for reference in initial_unknowns:
        ET.SubElement(structure, "InitialUnknown", valueReference=str(reference))
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
