"""modelDescription.xml of the controller FMU, FMI 2.0 and FMI 3.0 Co-Simulation, from its
variables (`variables`): units in <UnitDefinitions>, the inputs, outputs and parameters with
their units and descriptions, the sample time as the default step size, and the structure:
every output depends directly on the inputs (a sample's command is the law at that sample's
inputs: direct feedthrough), at initialisation too."""

from __future__ import annotations

import datetime
import xml.etree.ElementTree as ET

from toggle_cosim.controller_fmu.variables import VR_TIME, FmuVariable, inputs, outputs, parameters
from toggle_cosim.fmu_export.units import base_exponents

__all__ = ["DESCRIPTION", "LOG_CATEGORIES", "fmi2_model_description", "fmi3_model_description"]

DESCRIPTION = (
    "Two-phase VSC of Fung, Wu and Chen (2001), eqs. (19)-(25), and its integral-compensated variant: "
    "a sampled controller (sample and hold every T_s) generated from toggle-cosim's control law"
)
LOG_CATEGORIES = (
    ("logEvents", "samples taken"),
    ("logStatusWarning", "warnings"),
    ("logStatusError", "errors (always reported)"),
    ("logAll", "everything"),
)


def _number(value: float) -> str:
    return repr(float(value))


def _root(version: str, token_attribute: str, token: str, tool: str, model_identifier: str) -> ET.Element:
    return ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": version,
            "modelName": model_identifier,
            token_attribute: token,
            "description": DESCRIPTION,
            "generationTool": tool,
            "generationDateAndTime": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "variableNamingConvention": "flat",
        },
    )


def _common(root: ET.Element, all_variables: tuple[FmuVariable, ...]) -> None:
    """<UnitDefinitions>, <LogCategories>, <DefaultExperiment> (the same in both standards)."""
    definitions = ET.SubElement(root, "UnitDefinitions")
    for unit in sorted({v.unit for v in all_variables if v.unit}):
        element = ET.SubElement(definitions, "Unit", name=unit)
        ET.SubElement(element, "BaseUnit", {k: str(v) for k, v in base_exponents(unit).items()})
    categories = ET.SubElement(root, "LogCategories")
    for name, description in LOG_CATEGORIES:
        ET.SubElement(categories, "Category", name=name, description=description)
    T_s = next(v.start for v in all_variables if v.name == "T_s")
    ET.SubElement(root, "DefaultExperiment", startTime="0.0", stepSize=_number(T_s))


def _value_attributes(variable: FmuVariable) -> dict[str, str]:
    found = {}
    if variable.unit:
        found["unit"] = variable.unit
    if variable.minimum is not None:
        found["min"] = _number(variable.minimum)
    if variable.maximum is not None:
        found["max"] = _number(variable.maximum)
    if variable.start is not None:
        found["start"] = _number(variable.start)
    return found


def _kind(variable: FmuVariable) -> dict[str, str]:
    if variable.causality == "input":
        return {"causality": "input", "variability": "continuous"}
    if variable.causality == "output":
        return {"causality": "output", "variability": "discrete", "initial": "calculated"}
    return {"causality": "parameter", "variability": "fixed", "initial": "exact"}


def _text(root: ET.Element) -> str:
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def fmi2_model_description(token: str, model_identifier: str, tool: str, sources: tuple[str, ...]) -> str:
    """FMI 2.0 Co-Simulation modelDescription.xml (GUID `token`), listing `sources`."""
    ins, outs, pars = inputs(), outputs(), parameters()
    every = (*ins, *outs, *pars)
    root = _root("2.0", "guid", token, tool, model_identifier)
    root.set("numberOfEventIndicators", "0")
    cs = ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": model_identifier,
            "needsExecutionTool": "false",
            "canHandleVariableCommunicationStepSize": "false",
            "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0",
            "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canNotUseMemoryManagementFunctions": "true",
            "canGetAndSetFMUstate": "true",
            "canSerializeFMUstate": "true",
            "providesDirectionalDerivative": "false",
        },
    )
    files = ET.SubElement(cs, "SourceFiles")
    for name in sources:
        ET.SubElement(files, "File", name=name)
    _common(root, every)
    model_variables = ET.SubElement(root, "ModelVariables")
    index = {}
    for position, variable in enumerate(every, start=1):
        index[variable.name] = position
        element = ET.SubElement(
            model_variables,
            "ScalarVariable",
            {
                "name": variable.name,
                "valueReference": str(variable.value_reference),
                "description": variable.description,
                **_kind(variable),
            },
        )
        ET.SubElement(element, "Real", _value_attributes(variable))
    structure = ET.SubElement(root, "ModelStructure")
    depends = " ".join(str(index[v.name]) for v in ins)
    for tag in ("Outputs", "InitialUnknowns"):
        group = ET.SubElement(structure, tag)
        for variable in outs:
            ET.SubElement(group, "Unknown", index=str(index[variable.name]), dependencies=depends)
    return _text(root)


def fmi3_model_description(token: str, model_identifier: str, tool: str) -> str:
    """FMI 3.0 Co-Simulation modelDescription.xml (instantiationToken `token`); the sources are
    listed in sources/buildDescription.xml."""
    ins, outs, pars = inputs(), outputs(), parameters()
    every = (*ins, *outs, *pars)
    root = _root("3.0", "instantiationToken", token, tool, model_identifier)
    ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": model_identifier,
            "needsExecutionTool": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canGetAndSetFMUState": "true",
            "canSerializeFMUState": "true",
            "providesDirectionalDerivatives": "false",
            "providesAdjointDerivatives": "false",
            "providesPerElementDependencies": "false",
            "canHandleVariableCommunicationStepSize": "false",
            "maxOutputDerivativeOrder": "0",
            "providesIntermediateUpdate": "false",
            "canReturnEarlyAfterIntermediateUpdate": "false",
            "hasEventMode": "false",
            "providesEvaluateDiscreteStates": "false",
        },
    )
    _common(root, every)
    model_variables = ET.SubElement(root, "ModelVariables")
    ET.SubElement(
        model_variables,
        "Float64",
        name="time",
        valueReference=str(VR_TIME),
        description="simulation time",
        causality="independent",
        variability="continuous",
    )
    for variable in every:
        ET.SubElement(
            model_variables,
            "Float64",
            {
                "name": variable.name,
                "valueReference": str(variable.value_reference),
                "description": variable.description,
                **_kind(variable),
                **_value_attributes(variable),
            },
        )
    structure = ET.SubElement(root, "ModelStructure")
    depends = " ".join(str(v.value_reference) for v in ins)
    for tag in ("Output", "InitialUnknown"):
        for variable in outs:
            ET.SubElement(structure, tag, valueReference=str(variable.value_reference), dependencies=depends)
    return _text(root)
