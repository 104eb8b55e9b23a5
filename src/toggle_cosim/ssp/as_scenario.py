"""The values an SSP variant sets, read as the scenario document they amount to, so that the
scenario's rules apply to them (`experiments.scenario`: the schema's ranges, the stroke inside the
linkage, whole samples) and the run's record (stroke, friction model, gains) says what ran.

Plant values map to the scenario keys of `experiments.scenario.OWN_KEYS` (frictionModel through
`plant.friction.FRICTION_MODELS`, idealCurrentLoop to current_loop), F_E to plant.F_E, any other
to plant.parameters; the controller's to controller keys where the built-in law's parameters have
one (C, Q, P, delta, beta to gains; mB to nominal_m_B; law, objective, C_I, K_I, i_max); its target
is the stroke's x_target (the theta1 objective's through eq. (26)), the plant's x_B0 the stroke's
x_start. A value a component does not bind is its FMU's start value. What the master sets is
still exactly the bound values (`runs.definition.PlantSettings.fmu_values`); this document only
checks and describes them.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from toggle_cosim.experiments.scenario import OWN_KEYS, ScenarioError, runs_from_document
from toggle_cosim.physics.mechanism import xB_from_theta1
from toggle_cosim.physics.parameters import MechanismParameters
from toggle_cosim.plant.friction import FRICTION_MODELS
from toggle_cosim.runs.definition import Run
from toggle_cosim.ssp import layout

__all__ = ["CONTROLLER_NAMES", "PLANT_NAMES", "run_of_values"]

Value = float | int | bool
GAINS = ("C", "Q", "P", "delta", "beta")
CONTROLLER_KEYS = {"mB": "nominal_m_B", "C_I": "C_I", "K_I": "K_I", "i_max": "i_max"}
LAWS, OBJECTIVES = ("paper", "integral"), ("x_B", "theta1")
# the values this document reads: what a component does not bind is taken from its FMU's start
PLANT_NAMES = (*OWN_KEYS, layout.EXTERNAL_FORCE)
CONTROLLER_NAMES = (*GAINS, *CONTROLLER_KEYS, "law", "objective", "target")


def _choice(value: Value, choices: tuple[str, ...], name: str) -> str:
    if isinstance(value, bool) or float(value) not in range(len(choices)):
        numbers = ", ".join(f"{number} ({choice})" for number, choice in enumerate(choices))
        raise ScenarioError(f"{name} = {value!r} is not one of {numbers}")
    return choices[int(value)]


def _plant(values: Mapping[str, Value], document: dict[str, Any]) -> None:
    plant: dict[str, Any] = {}
    stroke = document.setdefault("stroke", {})
    models = {number: name for name, number in FRICTION_MODELS.items()}
    for name, value in values.items():
        key = OWN_KEYS.get(name)
        if name == layout.EXTERNAL_FORCE:
            plant["F_E"] = value
        elif key == "stroke.x_start":
            stroke["x_start"] = value
        elif key == "plant.current_loop":
            plant["current_loop"] = "ideal" if value else "first_order"
        elif key == "plant.friction_model":
            if isinstance(value, bool) or value not in models:
                numbers = ", ".join(f"{number} ({model})" for number, model in sorted(models.items()))
                raise ScenarioError(f"frictionModel = {value!r} is not one of {numbers}")
            plant["friction_model"] = models[value]
        elif key is not None:
            plant[key.removeprefix("plant.")] = value
        else:
            plant.setdefault("parameters", {})[name] = value
    document["plant"] = plant


def _controller(values: Mapping[str, Value], document: dict[str, Any]) -> None:
    controller: dict[str, Any] = {}
    gains = {name: values[name] for name in GAINS if name in values}
    if gains:
        controller["gains"] = gains
    for name, key in CONTROLLER_KEYS.items():
        if name in values:
            controller[key] = values[name]
    if "law" in values:
        controller["law"] = _choice(values["law"], LAWS, "law")
    objective = _choice(values.get("objective", 0), OBJECTIVES, "objective")
    controller["objective"] = objective
    if "target" in values:
        target = float(values["target"])
        nominal = MechanismParameters(mB=float(values.get("mB", MechanismParameters().mB)), mu=0.0)
        document["stroke"]["x_target"] = target if objective == "x_B" else xB_from_theta1(target, nominal)
    document["controller"] = controller


def run_of_values(
    name: str,
    description: str,
    t_end: float,
    T_s: float,
    plant: Mapping[str, Value],
    controller: Mapping[str, Value],
) -> Run:
    """The run the values amount to (scenario `name`, no variant); ScenarioError with the scenario's
    one-line message for a value outside its rules (a key the values leave out: its message)."""
    document: dict[str, Any] = {"name": name, "t_end": t_end, "T_s": T_s}
    if description:
        document["description"] = description
    _plant(plant, document)
    _controller(controller, document)
    (run,) = runs_from_document(document)
    return run
