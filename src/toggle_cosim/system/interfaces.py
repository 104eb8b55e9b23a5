"""An FMU's connectors as a system sees them (`fmu_interface`): read from its model description
(fmpy's), the one definition that the master's slaves (`cosim.execution.slaves`), the run's check
(`cosim.checked`) and the SSP reader (`ssp.fmus`) all use; and a natively run controller's
(`controller_interface`). Nothing is loaded."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from toggle_cosim.system.model import Interface

__all__ = [
    "FLOAT64_TYPES",
    "REAL_TYPES",
    "SettableError",
    "check_settable",
    "controller_interface",
    "fmu_interface",
    "settable_type",
    "variable_unit",
]

REAL_TYPES = ("Real", "Float64", "Float32")
FLOAT64_TYPES = ("Real", "Float64")  # read by getReal / getFloat64; any other type by its own getter
# the FMI types a value may be given for before initialisation, as the SSV element that sets them
SETTABLE_TYPES = {
    "Real": "Real",
    "Float64": "Real",
    "Float32": "Real",
    "Boolean": "Boolean",
    "Integer": "Integer",
    "Int32": "Integer",
}


_CAUSALITIES = {
    "output": "an output",
    "local": "a local variable (a state or an internal one)",
    "independent": "the independent variable (time)",
    "calculatedParameter": "a calculated parameter",
    "structuralParameter": "a structural parameter",
}


class SettableError(ValueError):
    """A value that cannot be set on an FMU before initialisation; str() says why, naming the
    variable (the caller adds the FMU and the key)."""


def settable_type(variable: Any, name: str, value: object) -> str:
    """The type (Real, Integer, Boolean) under which `value` is set on the FMU `variable`
    (named `name`; None: the FMU has none): a parameter or an input, of a type set here, the value
    of that type. Raises SettableError: the one check of a component's values, before any run,
    for an SSP's bindings and a scenario's `components.NAME.parameters` alike."""
    if variable is None or variable.causality not in ("parameter", "input"):
        if variable is None:
            raise SettableError(f"the FMU has no variable {name!r}")
        what = _CAUSALITIES.get(variable.causality, f"a {variable.causality} variable")
        raise SettableError(f"{name!r} is {what} of the FMU, not a parameter or input")
    kind = SETTABLE_TYPES.get(variable.type)
    if kind is None:
        raise SettableError(f"variable {name!r} is of type {variable.type}; values are set on Real, Integer, Boolean")
    if kind == "Boolean" and not isinstance(value, bool):
        raise SettableError(f"variable {name!r} is a Boolean, but its value is {value!r}")
    if kind == "Boolean":
        return kind
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        article = "an" if kind == "Integer" else "a"
        raise SettableError(f"variable {name!r} is {article} {kind}, but its value is {value!r} (give a finite number)")
    if kind == "Integer" and float(value) != int(value):
        raise SettableError(f"variable {name!r} is an Integer, but its value is {value!r}")
    return kind


def check_settable(description: Any, values: Sequence[tuple[str, object]]) -> None:
    """Every (name, value) of `values` can be set on the FMU of `description` (`settable_type`)."""
    variables = {v.name: v for v in description.modelVariables}
    for name, value in values:
        settable_type(variables.get(name), name, value)


def variable_unit(variable: Any) -> str | None:
    """A model variable's unit: its own, else its declared type's; None if neither."""
    if getattr(variable, "unit", None):
        return variable.unit
    declared = getattr(variable, "declaredType", None)
    return getattr(declared, "unit", None) or None


def fmu_interface(description: Any, observed: Sequence[str] = ()) -> Interface:
    """An FMU's Real inputs and outputs (then `observed`: other variables read as outputs, those
    it has), each output's direct dependencies on inputs from its ModelStructure (an output that
    declares none depends on every input), and the units. The outputs read by getReal /
    getFloat64 come first, then those of other types (`Interface.typed`: an observed Integer,
    Boolean, ...; FMI 3.0's Float32), which a system records but does not connect."""
    variables = {v.name: v for v in description.modelVariables}
    real = [v for v in description.modelVariables if v.type in REAL_TYPES]
    inputs = tuple(v.name for v in real if v.causality == "input")
    outputs = tuple(v.name for v in real if v.causality == "output")
    depends: dict[str, tuple[str, ...]] = {}
    declared = {unknown.variable.name: unknown for unknown in getattr(description, "outputs", None) or ()}
    for name in outputs:
        unknown = declared.get(name)
        if unknown is None or unknown.dependencies is None:
            depends[name] = inputs
        else:
            depends[name] = tuple(v.name for v in unknown.dependencies if v.name in inputs)
    extra = tuple(name for name in observed if name not in outputs and name not in inputs and name in variables)
    units = {name: variable_unit(variables[name]) for name in (*inputs, *outputs, *extra)}
    read = (*outputs, *extra)
    first = tuple(name for name in read if variables[name].type in FLOAT64_TYPES)
    typed = {name: variables[name].type for name in extra if variables[name].type not in REAL_TYPES}
    return Interface(inputs, (*first, *(name for name in read if name not in first)), depends, units, typed)


def controller_interface(
    measured: Sequence[str],
    diagnostics: Sequence[str],
    command: str = "iq_ref",
    units: Mapping[str, str | None] | None = None,
) -> Interface:
    """A controller's connectors when the master runs it natively: its inputs what it measures,
    its outputs the command and its diagnostics, each depending directly on every input; the
    units those of the plant variables of their names (`units`; None: none declared)."""
    measured, outputs = tuple(measured), (command, *diagnostics)
    units = {name: (units or {}).get(name) for name in (*measured, command)}
    return Interface(measured, outputs, {output: measured for output in outputs}, units)
