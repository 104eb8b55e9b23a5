"""Kinematics and constrained dynamics of the toggle mechanism, eqs. (17), (18) and (26).

Pure functions of numpy arrays and :class:`~toggle_cosim.parameters.MechanismParameters`.

Formulation (the same as the Modelica plant ``ToggleLSM.ToggleMechanism``)
-------------------------------------------------------------------------
q = (θ1, θ2, θ5), q̇ = (ω1, ω2, ω5). Bodies: lever 2 (J2 about O, centre of mass at O), link 3
(uniform rod A→B), slider B (mass mB, x only), link 5 (uniform rod D→C), slider C (mass mC,
x only). Points::

    A = r1 (cos θ1, sin θ1)             B = A + r3 (cos θ2, sin θ2)
    D = r4 (cos(θ1+φ), sin(θ1+φ))       C = D + r5 (cos θ5, sin θ5)

Constraints (loop closures)::

    Φ1 = r1 sin θ1 + r3 sin θ2 − f = 0          (slider B on its guide y = f)
    Φ2 = h − r4 sin(θ1+φ) − r5 sin θ5 = 0        (slider C on its guide y = h)

Eq. (18)::

    [ M(q)   Φ_qᵀ + Q_fᵀ ] [ q̈ ]   [ Q(q, q̇) ]
    [ Φ_q    0           ] [ λ  ] = [ γ(q, q̇) ]

with Q = −N(q, q̇) − ∂V/∂q + f_B ∂x_B/∂q + f_C ∂x_C/∂q, f_B = −F_E (external force on slider B
along +x; F_E ≥ 0 resists the forward stroke), f_C = −F_C (the PMLSM thrust acts on slider C
along −x), V = m3 g y_G3 + m5 g y_G5 (slider weights are carried by their guides; the lever's
centre of mass is at the pivot), and Q_fᵀ the friction matrix of eq. (17) in the coordinate
order (θ1, θ2, θ5)::

    row θ1: [−μ sgn(ω1) r1 sin θ1,  μ sgn(ω1) r4 sin(θ1+φ)]
    row θ2: [−μ sgn(ω2) r3 sin θ2,  0                     ]
    row θ5: [0,                      μ sgn(ω5) r5 sin θ5   ]

sgn(0) = 0. The friction multiplies λ, not |λ| (the paper's model), so its power can have
either sign.

M(q) and N(q, q̇) are written here in closed form from the kinetic energy
T = ½J2ω1² + ½m3|v_G3|² + ½J3ω2² + ½mB ẋ_B² + ½m5|v_G5|² + ½J5ω5² + ½mC ẋ_C², with N from the
Christoffel symbols of M, N_i = Σ_jk (∂M_ij/∂q_k − ½ ∂M_jk/∂q_i) q̇_j q̇_k.
``tests/reference_dynamics.py`` evaluates the same equations independently, from point
Jacobians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .parameters import MechanismParameters

__all__ = [
    "Points",
    "JointForces",
    "Energy",
    "Powers",
    "theta1_from_xB",
    "xB_from_theta1",
    "dependent_angles",
    "state_from_theta1",
    "initial_state",
    "state_from_slider",
    "theta1_state_from_slider",
    "positions",
    "constraint_residuals",
    "constraint_jacobian",
    "gamma",
    "friction_matrix",
    "friction_signs",
    "mass_matrix",
    "velocity_terms",
    "gravity_gradient",
    "generalized_forces",
    "dynamics",
    "velocity_ratios",
    "slider_B",
    "slider_C",
    "joint_forces",
    "energies",
    "powers",
    "nominal_fG",
    "nominal_fG_theta1",
]

FloatArray = NDArray[np.float64]


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


def theta1_state_from_slider(x_B: float, v_B: float, p: MechanismParameters) -> tuple[float, float]:
    """(θ1, ω1) from (x_B, v_B) with the kinematics of ``p`` (eq. (26) and the velocity constraint);
    scalar arithmetic, cheap enough for every controller sample."""
    return _theta1_omega1_from_slider(x_B, v_B, p)


@dataclass(frozen=True)
class Points:
    """Positions of the joints and centres of mass, each an array (x, y) [m]."""

    O: FloatArray
    A: FloatArray
    B: FloatArray
    D: FloatArray
    C: FloatArray
    G3: FloatArray
    G5: FloatArray

    @property
    def x_B(self) -> float:
        """Position of slider B [m]."""
        return float(self.B[0])

    @property
    def x_C(self) -> float:
        """Position of slider C (the PMLSM mover) [m]."""
        return float(self.C[0])


def positions(q: ArrayLike, p: MechanismParameters) -> Points:
    """Joint and centre-of-mass positions for q = (θ1, θ2, θ5) (the spec's point definitions)."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    A = p.r1 * np.array([math.cos(t1), math.sin(t1)])
    e2 = np.array([math.cos(t2), math.sin(t2)])
    D = p.r4 * np.array([math.cos(t1 + p.phi), math.sin(t1 + p.phi)])
    e5 = np.array([math.cos(t5), math.sin(t5)])
    return Points(
        O=np.zeros(2), A=A, B=A + p.r3 * e2, D=D, C=D + p.r5 * e5,
        G3=A + 0.5 * p.r3 * e2, G5=D + 0.5 * p.r5 * e5,
    )


def constraint_residuals(q: ArrayLike, p: MechanismParameters) -> FloatArray:
    """Φ(q) = (Φ1, Φ2) [m]."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    return np.array([
        p.r1 * math.sin(t1) + p.r3 * math.sin(t2) - p.f,
        p.h - p.r4 * math.sin(t1 + p.phi) - p.r5 * math.sin(t5),
    ])


def constraint_jacobian(q: ArrayLike, p: MechanismParameters) -> FloatArray:
    """Φ_q = [[r1 cos θ1, r3 cos θ2, 0], [−r4 cos(θ1+φ), 0, −r5 cos θ5]] (2×3)."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    return np.array([
        [p.r1 * math.cos(t1), p.r3 * math.cos(t2), 0.0],
        [-p.r4 * math.cos(t1 + p.phi), 0.0, -p.r5 * math.cos(t5)],
    ])


def gamma(q: ArrayLike, qd: ArrayLike, p: MechanismParameters) -> FloatArray:
    """γ = −(Φ_q q̇)_q q̇ = (r1 sin θ1 ω1² + r3 sin θ2 ω2², −r4 sin(θ1+φ) ω1² − r5 sin θ5 ω5²)."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    w1, w2, w5 = np.asarray(qd, dtype=float)
    return np.array([
        p.r1 * math.sin(t1) * w1 * w1 + p.r3 * math.sin(t2) * w2 * w2,
        -p.r4 * math.sin(t1 + p.phi) * w1 * w1 - p.r5 * math.sin(t5) * w5 * w5,
    ])


def friction_signs(qd: ArrayLike) -> FloatArray:
    """sgn(q̇) with sgn(0) = 0, the default friction signs of eq. (17)."""
    return np.sign(np.asarray(qd, dtype=float))


def friction_matrix(q: ArrayLike, sgn: ArrayLike, p: MechanismParameters) -> FloatArray:
    """Q_fᵀ of eq. (17), rows (θ1, θ2, θ5), columns (λ1, λ2) (3×2).

    ``sgn`` holds sgn(ω1), sgn(ω2), sgn(ω5) (possibly latched values).
    """
    t1, t2, t5 = np.asarray(q, dtype=float)
    g1, g2, g5 = np.asarray(sgn, dtype=float)
    mu = p.mu
    return np.array([
        [-mu * g1 * p.r1 * math.sin(t1), mu * g1 * p.r4 * math.sin(t1 + p.phi)],
        [-mu * g2 * p.r3 * math.sin(t2), 0.0],
        [0.0, mu * g5 * p.r5 * math.sin(t5)],
    ])


def _mass_terms(t1: float, t2: float, t5: float, p: MechanismParameters) -> tuple[float, ...]:
    """Closed-form entries of M(q) and their non-zero partial derivatives.

    Returns (M11, M12, M15, M22, M55, dM11/dθ1, dM12/dθ1, dM12/dθ2, dM15/dθ1, dM15/dθ5,
    dM22/dθ2, dM55/dθ5). M25 = 0 and M does not depend on any other coordinate.
    """
    a3 = 0.5 * p.r3
    a5 = 0.5 * p.r5
    s1, c1 = math.sin(t1), math.cos(t1)
    sp, cp = math.sin(t1 + p.phi), math.cos(t1 + p.phi)
    s2, c2 = math.sin(t2), math.cos(t2)
    s5, c5 = math.sin(t5), math.cos(t5)
    c12 = c1 * c2 + s1 * s2  # cos(θ1 − θ2)
    s12 = s1 * c2 - c1 * s2  # sin(θ1 − θ2)
    cp5 = cp * c5 + sp * s5  # cos(θ1 + φ − θ5)
    sp5 = sp * c5 - cp * s5  # sin(θ1 + φ − θ5)
    m3, m5, mB, mC, r1, r3, r4, r5 = p.m3, p.m5, p.mB, p.mC, p.r1, p.r3, p.r4, p.r5
    M11 = p.J2 + m3 * r1 * r1 + m5 * r4 * r4 + mB * r1 * r1 * s1 * s1 + mC * r4 * r4 * sp * sp
    M12 = m3 * r1 * a3 * c12 + mB * r1 * r3 * s1 * s2
    M15 = m5 * r4 * a5 * cp5 + mC * r4 * r5 * sp * s5
    M22 = p.J3 + m3 * a3 * a3 + mB * r3 * r3 * s2 * s2
    M55 = p.J5 + m5 * a5 * a5 + mC * r5 * r5 * s5 * s5
    d11_1 = 2.0 * (mB * r1 * r1 * s1 * c1 + mC * r4 * r4 * sp * cp)
    d12_1 = -m3 * r1 * a3 * s12 + mB * r1 * r3 * c1 * s2
    d12_2 = m3 * r1 * a3 * s12 + mB * r1 * r3 * s1 * c2
    d15_1 = -m5 * r4 * a5 * sp5 + mC * r4 * r5 * cp * s5
    d15_5 = m5 * r4 * a5 * sp5 + mC * r4 * r5 * sp * c5
    d22_2 = 2.0 * mB * r3 * r3 * s2 * c2
    d55_5 = 2.0 * mC * r5 * r5 * s5 * c5
    return M11, M12, M15, M22, M55, d11_1, d12_1, d12_2, d15_1, d15_5, d22_2, d55_5


def mass_matrix(q: ArrayLike, p: MechanismParameters) -> FloatArray:
    """Mass matrix M(q) of eq. (18) from the kinetic energy T of the five moving bodies::

        M11 = J2 + m3 r1² + m5 r4² + mB r1² sin²θ1 + mC r4² sin²(θ1+φ)
        M12 = m3 r1 (r3/2) cos(θ1−θ2) + mB r1 r3 sin θ1 sin θ2
        M15 = m5 r4 (r5/2) cos(θ1+φ−θ5) + mC r4 r5 sin(θ1+φ) sin θ5
        M22 = J3 + m3 r3²/4 + mB r3² sin²θ2,   M55 = J5 + m5 r5²/4 + mC r5² sin²θ5,   M25 = 0
    """
    t1, t2, t5 = np.asarray(q, dtype=float)
    M11, M12, M15, M22, M55 = _mass_terms(t1, t2, t5, p)[:5]
    return np.array([[M11, M12, M15], [M12, M22, 0.0], [M15, 0.0, M55]])


def velocity_terms(q: ArrayLike, qd: ArrayLike, p: MechanismParameters) -> FloatArray:
    """Velocity terms N(q, q̇) = Ṁ q̇ − ∂T/∂q of eq. (18), from the Christoffel symbols of M::

        N1 = ½ ∂M11/∂θ1 ω1² + ∂M12/∂θ2 ω2² + ∂M15/∂θ5 ω5²
        N2 = ∂M12/∂θ1 ω1² + ½ ∂M22/∂θ2 ω2²
        N5 = ∂M15/∂θ1 ω1² + ½ ∂M55/∂θ5 ω5²
    """
    t1, t2, t5 = np.asarray(q, dtype=float)
    w1, w2, w5 = np.asarray(qd, dtype=float)
    _, _, _, _, _, d11_1, d12_1, d12_2, d15_1, d15_5, d22_2, d55_5 = _mass_terms(t1, t2, t5, p)
    return np.array([
        0.5 * d11_1 * w1 * w1 + d12_2 * w2 * w2 + d15_5 * w5 * w5,
        d12_1 * w1 * w1 + 0.5 * d22_2 * w2 * w2,
        d15_1 * w1 * w1 + 0.5 * d55_5 * w5 * w5,
    ])


def gravity_gradient(q: ArrayLike, p: MechanismParameters) -> FloatArray:
    """∂V/∂q for V = m3 g y_G3 + m5 g y_G5."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    return p.g * np.array([
        p.m3 * p.r1 * math.cos(t1) + p.m5 * p.r4 * math.cos(t1 + p.phi),
        p.m3 * 0.5 * p.r3 * math.cos(t2),
        p.m5 * 0.5 * p.r5 * math.cos(t5),
    ])


def generalized_forces(q: ArrayLike, qd: ArrayLike, F_C: float, F_E: float, p: MechanismParameters) -> FloatArray:
    """Right-hand side Q(q, q̇) of eq. (18): −N − ∂V/∂q + f_B ∂x_B/∂q + f_C ∂x_C/∂q,
    with f_B = −F_E and f_C = −F_C."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    dxB = np.array([-p.r1 * math.sin(t1), -p.r3 * math.sin(t2), 0.0])
    dxC = np.array([-p.r4 * math.sin(t1 + p.phi), 0.0, -p.r5 * math.sin(t5)])
    return -velocity_terms(q, qd, p) - gravity_gradient(q, p) - F_E * dxB - F_C * dxC


def _resolve_sgn(qd: ArrayLike, sgn: ArrayLike | None) -> FloatArray:
    if sgn is None:
        return friction_signs(qd)
    out = np.asarray(sgn, dtype=float)
    if out.shape != (3,):
        raise ValueError(f"sgn: expected three signs (ω1, ω2, ω5), got shape {out.shape}")
    return out


def dynamics(
    q: ArrayLike,
    qd: ArrayLike,
    F_C: float,
    F_E: float,
    p: MechanismParameters,
    sgn: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Solve the 5×5 linear system of eq. (18) for (q̈, λ).

    Args:
        q, qd: (θ1, θ2, θ5) and (ω1, ω2, ω5); consistent with the constraints.
        F_C: PMLSM thrust [N] (acts on slider C along −x).
        F_E: external force on slider B [N] (acts along −x; resists the forward stroke).
        p: mechanism parameters (``p.mu`` scales the friction of eq. (17)).
        sgn: friction signs (sgn ω1, sgn ω2, sgn ω5); default np.sign(qd) with sgn(0) = 0.
            Pass latched signs to integrate across zero crossings event by event.

    Returns:
        (q̈, λ) with q̈ = (θ̈1, θ̈2, θ̈5) [rad/s²] and λ = (λ1, λ2) [N].
    """
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    s = _resolve_sgn(qd, sgn)
    Phi_q = constraint_jacobian(q, p)
    A = np.zeros((5, 5))
    A[:3, :3] = mass_matrix(q, p)
    A[:3, 3:] = Phi_q.T + friction_matrix(q, s, p)
    A[3:, :3] = Phi_q
    b = np.empty(5)
    b[:3] = generalized_forces(q, qd, F_C, F_E, p)
    b[3:] = gamma(q, qd, p)
    x = np.linalg.solve(A, b)
    return x[:3], x[3:]


def velocity_ratios(q: ArrayLike, p: MechanismParameters) -> tuple[float, float, float, float]:
    """Velocity ratios of the one-d.o.f. mechanism with respect to θ1:
    (dθ2/dθ1, dθ5/dθ1, dx_B/dθ1, dx_C/dθ1), from Φ_q q̇ = 0."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    rho2, rho5 = _dependent_rates(t1, t2, t5, p)
    dxB = -p.r1 * math.sin(t1) - p.r3 * math.sin(t2) * rho2
    dxC = -p.r4 * math.sin(t1 + p.phi) - p.r5 * math.sin(t5) * rho5
    return rho2, rho5, dxB, dxC


def slider_B(q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, p: MechanismParameters) -> tuple[float, float, float]:
    """(x_B, v_B, a_B) of slider B from (q, q̇, q̈)."""
    t1, t2, _ = np.asarray(q, dtype=float)
    w1, w2, _ = np.asarray(qd, dtype=float)
    a1, a2, _ = np.asarray(qdd, dtype=float)
    s1, c1, s2, c2 = math.sin(t1), math.cos(t1), math.sin(t2), math.cos(t2)
    x = p.r1 * c1 + p.r3 * c2
    v = -p.r1 * s1 * w1 - p.r3 * s2 * w2
    a = -p.r1 * (s1 * a1 + c1 * w1 * w1) - p.r3 * (s2 * a2 + c2 * w2 * w2)
    return x, v, a


def slider_C(q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, p: MechanismParameters) -> tuple[float, float, float]:
    """(x_C, v_C, a_C) of slider C (the PMLSM mover) from (q, q̇, q̈)."""
    t1, _, t5 = np.asarray(q, dtype=float)
    w1, _, w5 = np.asarray(qd, dtype=float)
    a1, _, a5 = np.asarray(qdd, dtype=float)
    sp, cp, s5, c5 = math.sin(t1 + p.phi), math.cos(t1 + p.phi), math.sin(t5), math.cos(t5)
    x = p.r4 * cp + p.r5 * c5
    v = -p.r4 * sp * w1 - p.r5 * s5 * w5
    a = -p.r4 * (sp * a1 + cp * w1 * w1) - p.r5 * (s5 * a5 + c5 * w5 * w5)
    return x, v, a


# --------------------------------------------------------------------------------------------
# Joint forces, energies, powers
# --------------------------------------------------------------------------------------------


def _cross(u: FloatArray, v: FloatArray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def _point_acc(length: float, theta: float, omega: float, alpha: float) -> FloatArray:
    """Acceleration of a point at distance ``length`` along a body at angle θ, relative to its
    base point: length (−sin θ α − cos θ ω², cos θ α − sin θ ω²)."""
    s, c = math.sin(theta), math.cos(theta)
    return length * np.array([-s * alpha - c * omega * omega, c * alpha - s * omega * omega])


@dataclass(frozen=True)
class JointForces:
    """Pin forces at the five revolute joints, each an array (x, y) [N].

    Definition (documented in the spec): the rows of −Q_fᵀλ of eq. (17) act as torques from
    ground on the lever (θ1), link 3 (θ2) and link 5 (θ5); the pin forces follow from the
    Newton–Euler equations of slider B (x), link 3 (moment about A), slider C (x), link 5
    (moment about D), links 3, 5 (force) and the lever (force) with the solved accelerations.
    The slider weights are carried by the guides and do not enter the pin forces (F34_y = λ1,
    F56_y = −λ2).

    Attributes:
        F12: ground on lever at O, joint (1,2).
        F23: lever on link 3 at A, joint (2,3).
        F34: link 3 on slider B at B, joint (3,4).
        F25: lever on link 5 at D, joint (2,5).
        F56: link 5 on slider C at C, joint (5,6).
        mu: the friction coefficient used for the friction forces.
    """

    F12: FloatArray
    F23: FloatArray
    F34: FloatArray
    F25: FloatArray
    F56: FloatArray
    mu: float

    def normal(self) -> dict[str, float]:
        """Normal force at each joint, the Euclidean norm of the pin force [N]."""
        return {
            "12": float(np.hypot(*self.F12)),
            "23": float(np.hypot(*self.F23)),
            "34": float(np.hypot(*self.F34)),
            "25": float(np.hypot(*self.F25)),
            "56": float(np.hypot(*self.F56)),
        }

    def friction(self) -> dict[str, float]:
        """Friction force at each joint, μ times the normal force [N]."""
        return {k: self.mu * v for k, v in self.normal().items()}


def _rod_and_slider_pins(length: float, m_rod: float, J_rod: float, theta: float, alpha: float,
                         a_centre: FloatArray, m_slider: float, a_slider: float, f_slider: float,
                         torque: float, g: float) -> tuple[FloatArray, FloatArray]:
    """Pin forces of a uniform rod (link 3 or 5) driving a slider (B or C) at its far end E.

    Slider: F_x = m_slider a_slider − f_slider (force of the rod on the slider). Rod moment about
    its near end P: J α + (G−P)×m a_G = (E−P)×(−F) + (G−P)×(0, −m g) + τ gives F_y. The rod's
    near-end pin force (of the lever on the rod) is m a_G + F + (0, m g).
    """
    e = np.array([math.cos(theta), math.sin(theta)])
    r_centre, r_end = 0.5 * length * e, length * e
    F_x = m_slider * a_slider - f_slider
    # (E−P)×(−F) = −(r_end_x F_y − r_end_y F_x)
    moment = J_rod * alpha + _cross(r_centre, m_rod * a_centre) - _cross(r_centre, np.array([0.0, -m_rod * g])) - torque
    F_end = np.array([F_x, (r_end[1] * F_x - moment) / r_end[0]])
    return F_end, m_rod * a_centre + F_end + np.array([0.0, m_rod * g])


def joint_forces(
    q: ArrayLike,
    qd: ArrayLike,
    qdd: ArrayLike,
    lam: ArrayLike,
    F_C: float,
    F_E: float,
    p: MechanismParameters,
    sgn: ArrayLike | None = None,
) -> JointForces:
    """Pin forces from the Newton–Euler equations with the solved accelerations (see
    :class:`JointForces` for the definition)::

        slider B:  F34x = mB a_Bx − f_B
        link 3:    J3 θ̈2 + (G3−A)×m3 a_G3 = (B−A)×(−F34) + (G3−A)×(0, −m3 g) + τ3 → F34y
                   F23 = m3 a_G3 + F34 + (0, m3 g)
        slider C:  F56x = mC a_Cx − f_C
        link 5:    J5 θ̈5 + (G5−D)×m5 a_G5 = (C−D)×(−F56) + (G5−D)×(0, −m5 g) + τ5 → F56y
                   F25 = m5 a_G5 + F56 + (0, m5 g)
        lever:     F12 = F23 + F25 + (0, m2 g)

    with τ_i = −(Q_fᵀ λ)_i, f_B = −F_E, f_C = −F_C.
    """
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    qdd = np.asarray(qdd, dtype=float)
    lam = np.asarray(lam, dtype=float)
    s = _resolve_sgn(qd, sgn)
    t1, t2, t5 = q
    w1, w2, w5 = qd
    a1, a2, a5 = qdd
    tau = -friction_matrix(q, s, p) @ lam
    f_B, f_C = -F_E, -F_C

    aA = _point_acc(p.r1, t1, w1, a1)
    aD = _point_acc(p.r4, t1 + p.phi, w1, a1)
    aG3 = aA + _point_acc(0.5 * p.r3, t2, w2, a2)
    aB = aA + _point_acc(p.r3, t2, w2, a2)
    aG5 = aD + _point_acc(0.5 * p.r5, t5, w5, a5)
    aC = aD + _point_acc(p.r5, t5, w5, a5)
    F34, F23 = _rod_and_slider_pins(p.r3, p.m3, p.J3, t2, a2, aG3, p.mB, aB[0], f_B, tau[1], p.g)
    F56, F25 = _rod_and_slider_pins(p.r5, p.m5, p.J5, t5, a5, aG5, p.mC, aC[0], f_C, tau[2], p.g)
    F12 = F23 + F25 + np.array([0.0, p.m2 * p.g])
    return JointForces(F12=F12, F23=F23, F34=F34, F25=F25, F56=F56, mu=p.mu)


@dataclass(frozen=True)
class Energy:
    """Mechanical energy: kinetic T, potential V (gravity on links 3 and 5), E_mech = T + V [J]."""

    T: float
    V: float

    @property
    def E(self) -> float:
        """E_mech = T + V [J]."""
        return self.T + self.V


def energies(q: ArrayLike, qd: ArrayLike, p: MechanismParameters) -> Energy:
    """Kinetic and potential energy, computed body by body from the point velocities (not from
    M(q)): T = ½J2ω1² + ½m3|v_G3|² + ½J3ω2² + ½mB ẋ_B² + ½m5|v_G5|² + ½J5ω5² + ½mC ẋ_C²,
    V = m3 g y_G3 + m5 g y_G5."""
    t1, t2, t5 = np.asarray(q, dtype=float)
    w1, w2, w5 = np.asarray(qd, dtype=float)
    vA = p.r1 * w1 * np.array([-math.sin(t1), math.cos(t1)])
    vD = p.r4 * w1 * np.array([-math.sin(t1 + p.phi), math.cos(t1 + p.phi)])
    e2p = np.array([-math.sin(t2), math.cos(t2)])
    e5p = np.array([-math.sin(t5), math.cos(t5)])
    vG3 = vA + 0.5 * p.r3 * w2 * e2p
    vB = vA + p.r3 * w2 * e2p
    vG5 = vD + 0.5 * p.r5 * w5 * e5p
    vC = vD + p.r5 * w5 * e5p
    T = 0.5 * (
        p.J2 * w1 * w1
        + p.m3 * float(vG3 @ vG3) + p.J3 * w2 * w2 + p.mB * vB[0] ** 2
        + p.m5 * float(vG5 @ vG5) + p.J5 * w5 * w5 + p.mC * vC[0] ** 2
    )
    pts = positions((t1, t2, t5), p)
    V = p.g * (p.m3 * pts.G3[1] + p.m5 * pts.G5[1])
    return Energy(T=float(T), V=float(V))


@dataclass(frozen=True)
class Powers:
    """Power flows [W]: P_in = f_C ẋ_C (thrust), P_load = F_E ẋ_B (into the load),
    P_fric = q̇ᵀ Q_fᵀ λ (taken by the friction of eq. (17); signed). dE_mech/dt = P_in − P_load − P_fric."""

    P_in: float
    P_load: float
    P_fric: float


def powers(
    q: ArrayLike,
    qd: ArrayLike,
    lam: ArrayLike,
    F_C: float,
    F_E: float,
    p: MechanismParameters,
    sgn: ArrayLike | None = None,
) -> Powers:
    """Thrust, load and friction power (see :class:`Powers`). P_fric is not made non-negative:
    with eq. (17) the friction multiplies λ, so it can feed energy in."""
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    s = _resolve_sgn(qd, sgn)
    t1, t2, t5 = q
    w1, w2, w5 = qd
    vB = -p.r1 * math.sin(t1) * w1 - p.r3 * math.sin(t2) * w2
    vC = -p.r4 * math.sin(t1 + p.phi) * w1 - p.r5 * math.sin(t5) * w5
    P_fric = float(qd @ (friction_matrix(q, s, p) @ np.asarray(lam, dtype=float)))
    return Powers(P_in=-F_C * vC, P_load=F_E * vB, P_fric=P_fric)


# --------------------------------------------------------------------------------------------
# Nominal model for the controller: x_B'' = f + G u (and theta1'' = f + G u)
# --------------------------------------------------------------------------------------------


def _nominal_reduced(t1: float, w1: float, p: MechanismParameters) -> tuple[float, float, float, float]:
    """One-d.o.f. reduction of eq. (18) for μ = 0 and F_E = 0, in scalar arithmetic.

    With R = dq/dθ1 = (1, ρ2, ρ5) spanning the null space of Φ_q and s = (0, γ1/(r3 cos θ2),
    −γ2/(r5 cos θ5)) a particular solution of Φ_q q̈ = γ, q̈ = R θ̈1 + s and
    Rᵀ M R θ̈1 = Rᵀ(Q − M s) (the multipliers drop out since Rᵀ Φ_qᵀ = 0).

    Returns (θ̈1 at F_C = 0, ∂θ̈1/∂F_C, dx_B/dθ1, b_B) with a_B = dx_B/dθ1 θ̈1 + b_B.
    """
    r1, r3, r4, r5 = p.r1, p.r3, p.r4, p.r5
    s1, c1 = math.sin(t1), math.cos(t1)
    sp, cp = math.sin(t1 + p.phi), math.cos(t1 + p.phi)
    s2 = (p.f - r1 * s1) / r3
    c2 = math.sqrt(1.0 - s2 * s2)
    s5 = (p.h - r4 * sp) / r5
    c5 = math.sqrt(1.0 - s5 * s5)
    rho2 = -r1 * c1 / (r3 * c2)
    rho5 = -r4 * cp / (r5 * c5)
    w2 = rho2 * w1
    w5 = rho5 * w1
    w1s, w2s, w5s = w1 * w1, w2 * w2, w5 * w5
    g1 = r1 * s1 * w1s + r3 * s2 * w2s
    g2 = -r4 * sp * w1s - r5 * s5 * w5s
    sv2 = g1 / (r3 * c2)
    sv5 = -g2 / (r5 * c5)

    a3, a5 = 0.5 * r3, 0.5 * r5
    m3, m5, mB, mC = p.m3, p.m5, p.mB, p.mC
    c12 = c1 * c2 + s1 * s2
    s12 = s1 * c2 - c1 * s2
    cp5 = cp * c5 + sp * s5
    sp5 = sp * c5 - cp * s5
    M11 = p.J2 + m3 * r1 * r1 + m5 * r4 * r4 + mB * r1 * r1 * s1 * s1 + mC * r4 * r4 * sp * sp
    M12 = m3 * r1 * a3 * c12 + mB * r1 * r3 * s1 * s2
    M15 = m5 * r4 * a5 * cp5 + mC * r4 * r5 * sp * s5
    M22 = m3 * r3 * r3 / 12.0 + m3 * a3 * a3 + mB * r3 * r3 * s2 * s2
    M55 = m5 * r5 * r5 / 12.0 + m5 * a5 * a5 + mC * r5 * r5 * s5 * s5
    d11_1 = 2.0 * (mB * r1 * r1 * s1 * c1 + mC * r4 * r4 * sp * cp)
    d12_1 = -m3 * r1 * a3 * s12 + mB * r1 * r3 * c1 * s2
    d12_2 = m3 * r1 * a3 * s12 + mB * r1 * r3 * s1 * c2
    d15_1 = -m5 * r4 * a5 * sp5 + mC * r4 * r5 * cp * s5
    d15_5 = m5 * r4 * a5 * sp5 + mC * r4 * r5 * sp * c5
    N1 = 0.5 * d11_1 * w1s + d12_2 * w2s + d15_5 * w5s
    N2 = d12_1 * w1s + mB * r3 * r3 * s2 * c2 * w2s
    N5 = d15_1 * w1s + mC * r5 * r5 * s5 * c5 * w5s
    g = p.g
    V1 = g * (m3 * r1 * c1 + m5 * r4 * cp)
    V2 = g * m3 * a3 * c2
    V5 = g * m5 * a5 * c5

    m_eff = M11 + 2.0 * (M12 * rho2 + M15 * rho5) + M22 * rho2 * rho2 + M55 * rho5 * rho5
    RMs = sv2 * (M12 + M22 * rho2) + sv5 * (M15 + M55 * rho5)
    RQ0 = -(N1 + V1) - rho2 * (N2 + V2) - rho5 * (N5 + V5)
    dxB = -r1 * s1 - r3 * s2 * rho2
    dxC = -r4 * sp - r5 * s5 * rho5
    acc0 = (RQ0 - RMs) / m_eff
    dacc = -dxC / m_eff  # generalized force of F_C on θ1 is −F_C dx_C/dθ1
    bB = -r1 * c1 * w1s - r3 * (s2 * sv2 + c2 * w2s)
    return acc0, dacc, dxB, bB


def _theta1_omega1_from_slider(x_B: float, v_B: float, p: MechanismParameters) -> tuple[float, float]:
    """Scalar (θ1, ω1) from (x_B, v_B): eq. (26) and ω1 = v_B/(dx_B/dθ1)."""
    rho = math.hypot(x_B, p.f)
    t1 = math.asin((x_B * x_B + p.r1 * p.r1 + p.f * p.f - p.r3 * p.r3) / (2.0 * p.r1 * rho)) - math.atan2(x_B, p.f)
    s1, c1 = math.sin(t1), math.cos(t1)
    s2 = (p.f - p.r1 * s1) / p.r3
    c2 = math.sqrt(1.0 - s2 * s2)
    dxB = -p.r1 * s1 + p.r3 * s2 * p.r1 * c1 / (p.r3 * c2)
    return t1, v_B / dxB


def nominal_fG(x_B: float, v_B: float, p_nominal: MechanismParameters, K_f: float) -> tuple[float, float]:
    """f and G of the nominal plant ẍ_B = f + G u (u = i_q*), the model of eqs. (22)-(24).

    The nominal plant is eq. (18) with μ = 0 (``p_nominal.mu`` is ignored), F_E = 0 and an ideal
    current loop, F_C = K_f u. The dynamics are linear in F_C, so f = a_B(F_C = 0) and
    G = K_f ∂a_B/∂F_C = K_f (dx_B/dθ1)(−dx_C/dθ1)/(Rᵀ M R). Scalar closed form (no numpy) since it
    runs at every controller sample.
    """
    t1, w1 = _theta1_omega1_from_slider(x_B, v_B, p_nominal)
    acc0, dacc, dxB, bB = _nominal_reduced(t1, w1, p_nominal)
    return dxB * acc0 + bB, K_f * dxB * dacc


def nominal_fG_theta1(theta1: float, omega1: float, p_nominal: MechanismParameters, K_f: float) -> tuple[float, float]:
    """f and G of the nominal plant for the θ1 objective: θ̈1 = f + G u (u = i_q*), with the same
    nominal model as :func:`nominal_fG` (μ = 0, F_E = 0, ideal current loop)."""
    acc0, dacc, _, _ = _nominal_reduced(theta1, omega1, p_nominal)
    return acc0, K_f * dacc
