"""Which continuous states of the plant FMU play which part (the shipped plant, ToggleLSM.Plant):
the lever's coordinate and rate (the one degree of freedom), the dependent link angles and rates
held by the two loop closures (the index-reduced DAE keeps them as states, with Baumgarte terms
pulling drift back to the constraint manifold), the current loop's state, and the energy
integrals (bookkeeping: nothing depends on them).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PlantStates", "SHIPPED"]


@dataclass(frozen=True)
class PlantStates:
    """The names of the plant's continuous states by role, and the outputs that define the constraints."""

    coordinate: str  # the independent coordinate θ1
    rate: str  # its rate ω1
    dependent: tuple[str, ...]  # θ2, θ5: fixed by the constraints for a given θ1
    dependent_rates: tuple[str, ...]  # ω2, ω5, in the same order
    current: str  # the current loop's state (i_q under the first-order loop)
    residuals: tuple[str, ...]  # outputs that vanish on the constraint manifold (Φ1, Φ2)

    @property
    def positions(self) -> tuple[str, ...]:
        return (self.coordinate, *self.dependent)

    @property
    def required(self) -> tuple[str, ...]:
        return (*self.positions, self.rate, *self.dependent_rates, self.current)


SHIPPED = PlantStates(
    coordinate="mechanism.theta1",
    rate="mechanism.omega1",
    dependent=("mechanism.theta2", "mechanism.theta5"),
    dependent_rates=("mechanism.omega2", "mechanism.omega5"),
    current="motor.i_lag",
    residuals=("Phi1", "Phi2"),
)
