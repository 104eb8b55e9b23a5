"""What a run sets on its plant, checked against the plant's variables before any run starts.

`plant.parameters` names must be variables of the FMU that can be set before initialisation
(causality parameter, variability fixed or tunable), with a value of their type (a number for a
Real/Float64, true/false for a Boolean); `current_loop: ideal` needs the parameter
idealCurrentLoop; the built-in controller's objective needs the optional outputs the contract
names for it (theta1: theta1 and omega1); `plant.inputs` names must be Real inputs of the FMU, and
an input table's unit (its CSV header's) must be the input's unit in the FMU. Each failure is
one `SettingError` line naming the key and the variable.
"""

from __future__ import annotations

from toggle_cosim.plant.contract import CONTRACT, PlantInterface, declared_unit, objective_requirements
from toggle_cosim.plant.friction import friction_settings
from toggle_cosim.runs.definition import Run


class SettingError(Exception):
    """A setting the plant cannot take; str() is the one-line reason."""


def input_unit(plant: PlantInterface, name: str) -> str | None:
    """The unit of the plant input `name`: the FMU's declared one, else the contract's."""
    variable = next((v for v in plant.model_description.modelVariables if v.name == name), None)
    unit = declared_unit(variable) if variable is not None else None
    return unit or next((v.unit for v in CONTRACT if v.name == name), None)


def check_inputs(run: Run, plant: PlantInterface) -> None:
    """Each of plant.inputs must be a Real input of the FMU; a table's unit (its CSV header's) must
    be the input's unit in the FMU (an FMU input without a unit takes the table's values as they are)."""
    variant = f" (variant {run.variant})" if run.variant else ""
    variables = {v.name: v for v in plant.model_description.modelVariables}
    given = [("F_E", "plant.F_E", run.plant.F_E)]
    given += [(name, f"plant.inputs.{name}", value) for name, value in run.plant.inputs.items()]
    for name, key, _ in given[1:]:
        variable = variables.get(name)
        if variable is None:
            inputs = [v.name for v in plant.model_description.modelVariables if v.causality == "input"]
            raise SettingError(
                f"key {key}{variant}: the plant FMU {plant.path} has no variable {name!r} (its inputs: {', '.join(inputs)})"
            )
        if variable.causality != "input" or variable.type not in ("Real", "Float64"):
            raise SettingError(
                f"key {key}{variant}: {name!r} is a {variable.type} {variable.causality} of the plant FMU, not a Real input"
            )
    for name, key, value in given:
        source = getattr(value, "source", None)
        if source is None or source.unit is None:
            continue
        unit = input_unit(plant, name)
        if unit is not None and source.unit != unit:
            raise SettingError(
                f"key {key}{variant}: {source.path} gives column {source.column} in {source.unit!r}, the plant FMU's "
                f"{name} is in {unit!r} (convert the table to {unit}, or write its header as '{source.column} [{unit}]')"
            )


def check_settings(run: Run, plant: PlantInterface) -> None:
    variables = {v.name: v for v in plant.model_description.modelVariables}
    check_inputs(run, plant)
    try:  # a friction model the plant cannot run
        friction_settings(run.plant.friction_model, run.plant.mu, run.plant.mu_s, plant.references, plant.path)
    except ValueError as error:
        raise SettingError(str(error)) from None
    objective = run.controller.objective
    lacking = [name for name in objective_requirements(objective) if name in plant.absent]
    if run.controller.python is None and lacking:
        raise SettingError(
            f"key controller.objective: {objective} needs the plant outputs "
            f"{' and '.join(objective_requirements(objective))}; the plant FMU {plant.path} lacks "
            f"{', '.join(repr(name) for name in lacking)} (use objective x_B, or add the outputs to the plant)"
        )
    if run.plant.current_loop == "ideal" and "idealCurrentLoop" not in variables:
        raise SettingError(
            f"key plant.current_loop: the plant FMU {plant.path} has no parameter idealCurrentLoop, "
            "so 'ideal' cannot be set (use first_order)"
        )
    for name, value in run.plant.parameters.items():
        where = f"key plant.parameters.{name}" + (f" (variant {run.variant})" if run.variant else "")
        variable = variables.get(name)
        if variable is None:
            raise SettingError(f"{where}: the plant FMU {plant.path} has no variable {name!r} (check the name)")
        if variable.causality != "parameter" or variable.variability not in ("fixed", "tunable"):
            raise SettingError(
                f"{where}: {name!r} is a {variable.variability} {variable.causality}, not a parameter "
                "that can be set before a run"
            )
        if variable.type == "Boolean" and not isinstance(value, bool):
            raise SettingError(f"{where}: {name!r} is a Boolean; write true or false, not {value!r}")
        if variable.type in ("Real", "Float64") and isinstance(value, bool):
            raise SettingError(f"{where}: {name!r} is a {variable.type}; write a number, not {value!r}")
        if variable.type not in ("Real", "Float64", "Boolean"):
            raise SettingError(
                f"{where}: {name!r} is of type {variable.type}; only Real/Float64 and Boolean can be set"
            )
