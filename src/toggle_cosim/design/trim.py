"""Trim: the operating point that holds slider B at rest at a given position.

At rest (all rates zero) the mechanism's acceleration is affine in the current i_q, so the
holding command solves r(i) = 0 for r(i) = dω1/dt at the rest configuration with i_q = i_q* = i
(first-order loop: its state i_lag = i too, so it is also at rest): two evaluations of the
Model Exchange FMU and one Newton step, then the residual is checked. The configuration comes
from the FMU itself, initialised at rest with x_B0 = x_B (eq. (26) and the two loop closures).

The point is friction-free: the plant is evaluated with μ = 0 (at rest the paper's friction
has sgn(0) = 0 and holds nothing, and its sign switches make the model non-differentiable
there); a run with μ > 0 gets a warning saying so. F_E and m_B are the run's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toggle_cosim.cosim.master import plant_settings
from toggle_cosim.design.model_exchange import ModelExchangeError, ModelExchangePlant, state_info
from toggle_cosim.design.roles import SHIPPED, PlantStates
from toggle_cosim.physics.mechanism import folded_limit, toggle_limit, working_range
from toggle_cosim.physics.parameters import MechanismParameters
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run

__all__ = ["OperatingPoint", "TrimError", "check_plant_alone", "external_force", "open_at", "trim"]

INPUTS = ("iq_ref", "F_E")
TRIM_TOLERANCE = 1e-9  # rad/s²: |dω/dt| left at the trimmed point (measured: below 1e-12)


class TrimError(ValueError):
    """No operating point for this request; str() is the one-line reason."""


@dataclass(frozen=True)
class OperatingPoint:
    """Slider B held at rest at x_B: the FMU's states, the holding command and the run's load."""

    x_B: float  # m
    iq_ref: float  # A, the holding command i_q*
    F_E: float  # N, the run's external force
    m_B: float  # kg, the run's slider mass
    states: Mapping[str, float]  # every continuous state of the FMU, by name
    outputs: Mapping[str, float]  # the plant's recorded outputs at the point
    residual: float  # rad/s², max |dω/dt| left at the point
    fmu: Path
    run_label: str
    friction_free: bool = True  # always: see `warnings`
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def as_dict(self) -> dict[str, object]:
        """The point as plain values (the linearisation's files store it)."""
        return {
            "x_B": self.x_B,
            "iq_ref": self.iq_ref,
            "F_E": self.F_E,
            "m_B": self.m_B,
            "states": dict(self.states),
            "outputs": dict(self.outputs),
            "residual": self.residual,
            "fmu": str(self.fmu),
            "run": self.run_label,
            "friction_free": self.friction_free,
            "warnings": list(self.warnings),
        }


def external_force(run: Run) -> float:
    """The run's external force F_E [N] at the operating point (the one place trim reads it); a
    load that varies in time has no one value to hold against, and is refused."""
    if not isinstance(run.plant.F_E, (int, float)):
        raise TrimError(
            f"key plant.F_E: the load is a {run.plant.F_E.kind} in time; an operating point needs one value"
            " (give F_E a number in the scenario, e.g. a variant with the load you want to trim at)"
        )
    return float(run.plant.F_E)


def _check_position(run: Run, x_B: float) -> None:
    """x_B finite, in the working range, and strictly inside the linkage's reach (the folded and
    the toggle position: beyond them eq. (26) has no solution and the plant cannot be initialised;
    a plant.working_range may reach past them)."""
    if not np.isfinite(x_B):
        raise TrimError(f"x_B = {x_B!r}: give a finite position of slider B in metres")
    geometry = MechanismParameters()
    low, high = run.plant.working_range or working_range(geometry)
    if not low <= x_B <= high:
        raise TrimError(
            f"x_B = {x_B:g} m is outside the working range {low:.4g} to {high:.4g} m of {run.label} "
            "(the toggle's dead points lie beyond it; choose x_B inside, or set plant.working_range)"
        )
    folded, toggle = folded_limit(geometry), toggle_limit(geometry)
    if not folded < x_B < toggle:
        raise TrimError(
            f"x_B = {x_B:g} m is beyond the linkage's reach, {folded:.4g} m (folded) to {toggle:.4g} m (toggle), "
            f"although within {run.label}'s plant.working_range (slider B cannot be there; choose x_B inside the reach)"
        )


def _check_states(plant: PlantInterface, roles: PlantStates) -> None:
    names = state_info(plant).names
    missing = [name for name in roles.required if name not in names]
    if missing or any(name not in plant.references for name in ("x_B0", *roles.residuals)):
        raise ModelExchangeError(
            f"{plant.path}: trim and linearize know the shipped plant's states (ToggleLSM.Plant: "
            f"{', '.join(roles.required)}, the parameter x_B0 and the outputs {', '.join(roles.residuals)}); "
            f"this FMU's states are {', '.join(names)}"
        )


def check_plant_alone(run: Run) -> None:
    """TrimError (one line) for a run that is a system with parts or connections of its own:
    trim and linearize take the plant FMU alone with the run's settings, so they would drop its
    parts and wiring (a die's force on plant.F_E, a sensor) and answer for another plant. The
    pair with a `record:` list alone is the pair."""
    wiring = run.system
    if not wiring.parts and wiring.connections is None:
        return
    what = []
    if wiring.parts:
        what.append(f"components {', '.join(part.name for part in wiring.parts)}")
    fed = [str(c) for c in wiring.connections or () if c.end.component == wiring.plant and c.end.variable != INPUTS[0]]
    if fed:
        what.append(f"connections {', '.join(fed)}")
    elif wiring.connections is not None:
        what.append("connections of its own")
    raise TrimError(
        f"keys components:/connections: {run.label} is a system ({'; '.join(what)}); trim and linearize take its"
        " plant FMU alone, so they would drop them (linearise a scenario without components: and connections:,"
        " with the load you want as plant.F_E)"
    )


def open_at(run: Run, plant: PlantInterface, x_B: float) -> ModelExchangePlant:
    """The plant as a Model Exchange instance with the run's settings, friction off, initialised
    at rest with slider B at x_B; the run's plant alone (`check_plant_alone`)."""
    check_plant_alone(run)
    _check_states(plant, SHIPPED)
    settings = [(name, value) for name, value in plant_settings(run, plant) if name not in ("x_B0", "mu")]
    settings += [("mu", 0.0), ("x_B0", float(x_B))]
    return ModelExchangePlant(plant, settings, INPUTS)


def _friction_warning(run: Run) -> tuple[str, ...]:
    if run.plant.mu == 0:
        return ()
    return (
        f"the run's mu = {run.plant.mu:g}: the operating point and the linearisation are friction-free "
        "(mu = 0; joint friction is discontinuous at rest)",
    )


def trim(run: Run, x_B: float, plant: PlantInterface, roles: PlantStates = SHIPPED) -> OperatingPoint:
    """The operating point holding slider B at rest at x_B under the run's F_E and m_B (friction-free)."""
    _check_position(run, x_B)
    F_E = external_force(run)
    with open_at(run, plant, x_B) as me:
        names = me.states.names
        index = {name: k for k, name in enumerate(names)}
        rates = [index[name] for name in (roles.rate, *roles.dependent_rates)]
        x0 = me.initial_states.copy()
        x0[rates] = 0.0

        def acceleration(current: float) -> np.ndarray:
            x = x0.copy()
            x[index[roles.current]] = current
            derivatives, _ = me.evaluate(x, (current, F_E), ())
            return derivatives[rates]

        r0, r1 = acceleration(0.0)[0], acceleration(1.0)[0]
        if not np.isfinite(r0) or not np.isfinite(r1) or r1 == r0:
            raise TrimError(
                f"x_B = {x_B:g} m: the current does not move the lever there (dω1/dt = {r0:g} at 0 A, {r1:g} at 1 A)"
            )
        current = -r0 / (r1 - r0)
        current -= acceleration(current)[0] / (r1 - r0)  # one Newton step: removes the rounding of the first
        residual = float(np.max(np.abs(acceleration(current))))
        if not residual <= TRIM_TOLERANCE:
            raise TrimError(f"x_B = {x_B:g} m: no holding current found (|dω/dt| = {residual:g} rad/s² left)")
        x0[index[roles.current]] = current
        outputs = list(plant.recorded_outputs)
        _, values = me.evaluate(x0, (current, F_E), [plant.references[name] for name in outputs])
    return OperatingPoint(
        x_B=float(values[outputs.index("x_B")]),
        iq_ref=float(current),
        F_E=F_E,
        m_B=float(run.plant.m_B),
        states={name: float(value) for name, value in zip(names, x0, strict=True)},
        outputs={name: float(value) for name, value in zip(outputs, values, strict=True)},
        residual=residual,
        fmu=plant.path,
        run_label=run.label,
        warnings=_friction_warning(run),
    )
