"""The unit of every column of a run's trace, read from where it is defined, never typed twice.

* time: s;
* the plant's outputs and the inputs it was sent (iq_ref, F_E): the plant FMU's
  modelDescription.xml (the variable's unit, else its declared type's unit);
* the built-in controller's diagnostics: e = target − measured (eqs. (19), (26)) carries the
  unit of the measured variable the objective regulates (x_B, or theta1), S = C e + ė the unit
  of its rate (v_B, or omega1 where the plant has it, else the angle's unit per second), and the
  phase r of eq. (25) (0 reaching, 1 sliding) is a pure number, "1".

A column whose unit nothing defines (a plant variable without a unit) is left out of the mapping.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from toggle_cosim.control.controller import MEASURED, diagnostic_units
from toggle_cosim.plant.contract import INPUTS, PlantInterface

__all__ = ["OBJECTIVE_VARIABLES", "declared_unit", "trace_units"]

# the plant outputs the built-in law regulates for each objective: (measured variable, its rate)
OBJECTIVE_VARIABLES = MEASURED


def declared_unit(variable: Any) -> str | None:
    """A modelDescription variable's unit: its own, else its declared type's; None if neither."""
    if variable.unit is not None:
        return str(variable.unit)
    declared = variable.declaredType
    return str(declared.unit) if declared is not None and declared.unit is not None else None


def trace_units(
    names: Sequence[str], plant: PlantInterface, objective: str, extra: Mapping[str, str] | None = None
) -> dict[str, str]:
    """{column: unit} for the trace columns `names` of a run of `plant` with the built-in law's
    `objective` ("x_B" or "theta1"); `extra` gives units of further columns (a controller's own)."""
    described = {}
    for variable in plant.model_description.modelVariables:
        unit = declared_unit(variable)
        if unit is not None:
            described[variable.name] = unit
    known = {"time": "s"}
    known.update((name, described[name]) for name in (*plant.recorded_outputs, *INPUTS) if name in described)
    known.update(diagnostic_units(objective, described))
    known.update(extra or {})
    return {name: known[name] for name in names if name in known}
