"""Kinematics of the toggle mechanism, eq. (26) and the loop closures.

Pure functions of floats and :class:`~toggle_cosim.physics.parameters.MechanismParameters`.
q = (θ1, θ2, θ5): lever, link 3 (A→B), link 5 (D→C)::

    A = r1 (cos θ1, sin θ1)             B = A + r3 (cos θ2, sin θ2)
    D = r4 (cos(θ1+φ), sin(θ1+φ))       C = D + r5 (cos θ5, sin θ5)

Constraints (loop closures)::

    Φ1 = r1 sin θ1 + r3 sin θ2 − f = 0          (slider B on its guide y = f)
    Φ2 = h − r4 sin(θ1+φ) − r5 sin θ5 = 0        (slider C on its guide y = h)

The constrained dynamics of eq. (18) (used only by the tests) are in
``tests/mechanism_dynamics.py``; the controller's nominal model is ``control/nominal.py``."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from toggle_cosim.physics.parameters import MechanismParameters

__all__ = [
    "theta1_from_xB",
    "xB_from_theta1",
    "dependent_angles",
    "state_from_theta1",
    "initial_state",
    "state_from_slider",
    "toggle_limit",
    "folded_limit",
    "working_range",
    "SINGULARITY_MARGIN",
]

FloatArray = NDArray[np.float64]
SINGULARITY_MARGIN = 0.01  # m: the working range keeps this far from the toggle and the folded position


def toggle_limit(p: MechanismParameters) -> float:
    """x_B at the toggle position (links O-A and A-B aligned, θ1 = 0): the largest x_B."""
    return math.sqrt((p.r1 + p.r3) ** 2 - p.f**2)


def folded_limit(p: MechanismParameters) -> float:
    """x_B at the folded position (link A-B folded back over O-A, θ1 = −π): the smallest x_B."""
    return math.sqrt(max((p.r3 - p.r1) ** 2 - p.f**2, 0.0))


def working_range(p: MechanismParameters) -> tuple[float, float]:
    """The slider positions the toggle works in: SINGULARITY_MARGIN inside the folded and the
    toggle position, the two dead points where dx_B/dθ1 = 0 and eq. (26) has two branches
    (0.180 m to 0.360 m for the assumed geometry). A stroke must lie in it (scenario check); a
    run whose slider leaves it is flagged (`cosim.plausibility`)."""
    return folded_limit(p) + SINGULARITY_MARGIN, toggle_limit(p) - SINGULARITY_MARGIN


# --------------------------------------------------------------------------------------------
# Kinematics
# --------------------------------------------------------------------------------------------


def theta1_from_xB(x_B: float, p: MechanismParameters) -> float:
    """Lever angle θ1 for a slider-B position x_B, eq. (26).

    θ1 = asin[(x_B² + r1² + f² − r3²) / (2 r1 √(x_B² + f²))] − θ1',  θ1' = asin(x_B/√(x_B² + f²)).

    θ1' is evaluated as atan2(x_B, f), which equals eq. (26)'s asin for f ≥ 0 (and x_B > 0) and
    stays correct for f < 0. With f = 0, θ1' = π/2 and θ1 = −acos((x_B² + r1² − r3²)/(2 r1 x_B)),
    i.e. the branch with A below the guide (θ1 ∈ [−π, 0]), which is the one the spec uses
    (θ1 = −100.71° at x_B = 0.2329 m, −51.95° at x_B = 0.3199 m).

    Raises:
        ValueError: when x_B is out of the mechanism's reach (the asin argument leaves [−1, 1]).
    """
    rho = math.hypot(x_B, p.f)
    if rho == 0.0:
        raise ValueError("x_B: the guide passes through the pivot at x_B = 0; eq. (26) undefined")
    arg = (x_B * x_B + p.r1 * p.r1 + p.f * p.f - p.r3 * p.r3) / (2.0 * p.r1 * rho)
    if not -1.0 <= arg <= 1.0:
        raise ValueError(f"x_B: {x_B!r} m is out of reach of the mechanism (eq. (26) argument {arg:.6g})")
    return math.asin(arg) - math.atan2(x_B, p.f)


def dependent_angles(theta1: float, p: MechanismParameters) -> tuple[float, float]:
    """θ2 and θ5 from the constraints Φ1 = Φ2 = 0 (branch with cos θ2, cos θ5 > 0):

    θ2 = asin((f − r1 sin θ1)/r3),  θ5 = asin((h − r4 sin(θ1+φ))/r5).

    Raises:
        ValueError: when a constraint cannot be closed for this θ1.
    """
    s2 = (p.f - p.r1 * math.sin(theta1)) / p.r3
    s5 = (p.h - p.r4 * math.sin(theta1 + p.phi)) / p.r5
    if not -1.0 <= s2 <= 1.0:
        raise ValueError(f"theta1: {theta1!r} rad cannot close loop 1 (sin θ2 = {s2:.6g})")
    if not -1.0 <= s5 <= 1.0:
        raise ValueError(f"theta1: {theta1!r} rad cannot close loop 2 (sin θ5 = {s5:.6g})")
    return math.asin(s2), math.asin(s5)


def _dependent_rates(theta1: float, theta2: float, theta5: float, p: MechanismParameters) -> tuple[float, float]:
    """dθ2/dθ1 and dθ5/dθ1 from the velocity constraint Φ_q q̇ = 0."""
    rho2 = -p.r1 * math.cos(theta1) / (p.r3 * math.cos(theta2))
    rho5 = -p.r4 * math.cos(theta1 + p.phi) / (p.r5 * math.cos(theta5))
    return rho2, rho5


def state_from_theta1(theta1: float, omega1: float, p: MechanismParameters) -> tuple[FloatArray, FloatArray]:
    """Consistent (q, q̇) for a lever angle and rate: Φ(q) = 0 and Φ_q q̇ = 0."""
    theta2, theta5 = dependent_angles(theta1, p)
    rho2, rho5 = _dependent_rates(theta1, theta2, theta5, p)
    q = np.array([theta1, theta2, theta5])
    qd = np.array([omega1, rho2 * omega1, rho5 * omega1])
    return q, qd


def initial_state(x_B: float, p: MechanismParameters) -> tuple[FloatArray, FloatArray]:
    """Initial state at rest: θ1 from eq. (26), θ2 and θ5 from the constraints, q̇ = 0."""
    return state_from_theta1(theta1_from_xB(x_B, p), 0.0, p)


def xB_from_theta1(theta1: float, p: MechanismParameters) -> float:
    """Slider-B position x_B = r1 cos θ1 + r3 cos θ2 with θ2 from Φ1 = 0."""
    theta2, _ = dependent_angles(theta1, p)
    return p.r1 * math.cos(theta1) + p.r3 * math.cos(theta2)


def state_from_slider(x_B: float, v_B: float, p: MechanismParameters) -> tuple[FloatArray, FloatArray]:
    """The one-degree-of-freedom map back from the slider: (x_B, v_B) → (q, q̇).

    θ1 from eq. (26), θ2 and θ5 from the constraints, and q̇ from Φ_q q̇ = 0 together with
    ẋ_B = −r1 sin θ1 ω1 − r3 sin θ2 ω2 = v_B.
    """
    theta1 = theta1_from_xB(x_B, p)
    theta2, theta5 = dependent_angles(theta1, p)
    rho2, rho5 = _dependent_rates(theta1, theta2, theta5, p)
    dxB = -p.r1 * math.sin(theta1) - p.r3 * math.sin(theta2) * rho2
    omega1 = v_B / dxB
    return np.array([theta1, theta2, theta5]), np.array([omega1, rho2 * omega1, rho5 * omega1])
