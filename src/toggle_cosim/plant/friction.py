"""The plant's joint-friction models, as the scenario names them and the FMU numbers them.

The models live in the Modelica source (`ToggleMechanism`, parameter `frictionModel`); this
module is the one table from the scenario key `plant.friction_model` to that parameter, and
the settings the master writes for it. See docs/friction-models.md:

* ``paper``        eq. (17) as the paper writes it, tau_i = mu sgn(omega_i) R_i (the default)
* ``dissipative``  tau_i = mu sgn(omega_i) |R_i|: friction power is never negative
* ``stick_slip``   dissipative while the mechanism slips, a holding torque up to the static
                   capacity mu_s sum_i |domega_i/domega1| |R_i| while it sticks
"""

from __future__ import annotations

from collections.abc import Collection
from pathlib import Path

FRICTION_MODELS: dict[str, int] = {"paper": 1, "dissipative": 2, "stick_slip": 3}
DEFAULT_MODEL = "paper"


def friction_settings(
    model: str, mu: float, mu_s: float | None, available: Collection[str], fmu: Path
) -> list[tuple[str, float]]:
    """The FMU parameters for friction model `model`: `frictionModel` and `mu_s` (mu_s defaults
    to mu). A plant without `frictionModel` runs the paper's model only; asking it for another
    raises ValueError with the one-line reason."""
    if "frictionModel" not in available:
        if model != DEFAULT_MODEL:
            raise ValueError(
                f"{fmu}: the plant has no parameter frictionModel, so plant.friction_model: {model} cannot be set"
                f" (use friction_model: {DEFAULT_MODEL} or a plant built from this project's Modelica source)"
            )
        return []
    settings: list[tuple[str, float]] = [("frictionModel", float(FRICTION_MODELS[model]))]
    if "mu_s" in available:
        settings.append(("mu_s", mu if mu_s is None else mu_s))
    elif mu_s is not None:
        raise ValueError(f"{fmu}: the plant has no parameter mu_s, so plant.mu_s cannot be set")
    return settings
