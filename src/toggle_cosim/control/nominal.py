"""The controller's nominal model of the toggle mechanism, in scalar floats: the one definition
of the mass-matrix terms of eq. (18) and of the one-d.o.f. reduction the VSC of eqs. (22)-(24)
uses. Written in the restricted subset `control.translate` turns into C (floats, a frozen
parameter dataclass, local assignments, if/else, tuple returns, math.* calls, raise ValueError),
so the compiled loop evaluates exactly these operations in the same order.
"""

from __future__ import annotations

import math

from toggle_cosim.control.parameters import LawParameters

__all__ = ["mass_terms", "theta1_omega1", "nominal_reduced"]


def mass_terms(
    s1: float,
    c1: float,
    sp: float,
    cp: float,
    s2: float,
    c2: float,
    s5: float,
    c5: float,
    J2: float,
    J3: float,
    J5: float,
    m3: float,
    m5: float,
    mB: float,
    mC: float,
    r1: float,
    r3: float,
    r4: float,
    r5: float,
) -> tuple[float, float, float, float, float, float, float, float, float, float, float, float]:
    """Closed-form entries of M(q) of eq. (18) and their non-zero partial derivatives, from the
    sines and cosines of θ1, θ1 + φ, θ2, θ5 (J3, J5 about the rods' centres)::

        M11 = J2 + m3 r1² + m5 r4² + mB r1² sin²θ1 + mC r4² sin²(θ1+φ)
        M12 = m3 r1 (r3/2) cos(θ1−θ2) + mB r1 r3 sin θ1 sin θ2
        M15 = m5 r4 (r5/2) cos(θ1+φ−θ5) + mC r4 r5 sin(θ1+φ) sin θ5
        M22 = J3 + m3 r3²/4 + mB r3² sin²θ2,   M55 = J5 + m5 r5²/4 + mC r5² sin²θ5,   M25 = 0

    Returns (M11, M12, M15, M22, M55, ∂M11/∂θ1, ∂M12/∂θ1, ∂M12/∂θ2, ∂M15/∂θ1, ∂M15/∂θ5,
    ∂M22/∂θ2, ∂M55/∂θ5).
    """
    a3 = 0.5 * r3
    a5 = 0.5 * r5
    c12 = c1 * c2 + s1 * s2  # cos(θ1 − θ2)
    s12 = s1 * c2 - c1 * s2  # sin(θ1 − θ2)
    cp5 = cp * c5 + sp * s5  # cos(θ1 + φ − θ5)
    sp5 = sp * c5 - cp * s5  # sin(θ1 + φ − θ5)
    M11 = J2 + m3 * r1 * r1 + m5 * r4 * r4 + mB * r1 * r1 * s1 * s1 + mC * r4 * r4 * sp * sp
    M12 = m3 * r1 * a3 * c12 + mB * r1 * r3 * s1 * s2
    M15 = m5 * r4 * a5 * cp5 + mC * r4 * r5 * sp * s5
    M22 = J3 + m3 * a3 * a3 + mB * r3 * r3 * s2 * s2
    M55 = J5 + m5 * a5 * a5 + mC * r5 * r5 * s5 * s5
    d11_1 = 2.0 * (mB * r1 * r1 * s1 * c1 + mC * r4 * r4 * sp * cp)
    d12_1 = -m3 * r1 * a3 * s12 + mB * r1 * r3 * c1 * s2
    d12_2 = m3 * r1 * a3 * s12 + mB * r1 * r3 * s1 * c2
    d15_1 = -m5 * r4 * a5 * sp5 + mC * r4 * r5 * cp * s5
    d15_5 = m5 * r4 * a5 * sp5 + mC * r4 * r5 * sp * c5
    d22_2 = 2.0 * mB * r3 * r3 * s2 * c2
    d55_5 = 2.0 * mC * r5 * r5 * s5 * c5
    return M11, M12, M15, M22, M55, d11_1, d12_1, d12_2, d15_1, d15_5, d22_2, d55_5


def theta1_omega1(x_B: float, v_B: float, p: LawParameters) -> tuple[float, float]:
    """(θ1, ω1) from the measured (x_B, v_B): eq. (26) and ω1 = v_B/(dx_B/dθ1). Eq. (26) has
    one solution in −180° < θ1 < 0 (the stroke's side of the folded position), which this is:
    the x_B objective's reduction. The θ1 objective reads θ1 and ω1 from the plant instead.

    √(x_B² + f²) is written with math.sqrt (the C library's hypot and CPython's may differ in
    the last bit; for the paper's f = 0 both give |x_B| exactly).
    """
    rho = math.sqrt(x_B * x_B + p.f * p.f)
    arg = (x_B * x_B + p.r1 * p.r1 + p.f * p.f - p.r3 * p.r3) / (2.0 * p.r1 * rho)
    if not -1.0 <= arg <= 1.0:
        raise ValueError("x_B: out of reach of the nominal mechanism (eq. (26))")
    t1 = math.asin(arg) - math.atan2(x_B, p.f)
    s1 = math.sin(t1)
    c1 = math.cos(t1)
    s2 = (p.f - p.r1 * s1) / p.r3
    c2 = math.sqrt(1.0 - s2 * s2)
    dxB = -p.r1 * s1 + p.r3 * s2 * p.r1 * c1 / (p.r3 * c2)
    return t1, v_B / dxB


def nominal_reduced(t1: float, w1: float, p: LawParameters) -> tuple[float, float, float, float]:
    """One-d.o.f. reduction of eq. (18) for μ = 0 and F_E = 0.

    With R = dq/dθ1 = (1, ρ2, ρ5) spanning the null space of Φ_q and s = (0, γ1/(r3 cos θ2),
    −γ2/(r5 cos θ5)) a particular solution of Φ_q q̈ = γ, q̈ = R θ̈1 + s and
    Rᵀ M R θ̈1 = Rᵀ(Q − M s) (the multipliers drop out since Rᵀ Φ_qᵀ = 0).

    Returns (θ̈1 at F_C = 0, ∂θ̈1/∂F_C, dx_B/dθ1, b_B) with a_B = dx_B/dθ1 θ̈1 + b_B.
    """
    r1 = p.r1
    r3 = p.r3
    r4 = p.r4
    r5 = p.r5
    s1 = math.sin(t1)
    c1 = math.cos(t1)
    sp = math.sin(t1 + p.phi)
    cp = math.cos(t1 + p.phi)
    s2 = (p.f - r1 * s1) / r3
    c2 = math.sqrt(1.0 - s2 * s2)
    s5 = (p.h - r4 * sp) / r5
    c5 = math.sqrt(1.0 - s5 * s5)
    rho2 = -r1 * c1 / (r3 * c2)
    rho5 = -r4 * cp / (r5 * c5)
    w2 = rho2 * w1
    w5 = rho5 * w1
    w1s = w1 * w1
    w2s = w2 * w2
    w5s = w5 * w5
    g1 = r1 * s1 * w1s + r3 * s2 * w2s
    g2 = -r4 * sp * w1s - r5 * s5 * w5s
    sv2 = g1 / (r3 * c2)
    sv5 = -g2 / (r5 * c5)
    M11, M12, M15, M22, M55, d11_1, d12_1, d12_2, d15_1, d15_5, d22_2, d55_5 = mass_terms(
        s1, c1, sp, cp, s2, c2, s5, c5, p.J2, p.J3, p.J5, p.m3, p.m5, p.mB, p.mC, r1, r3, r4, r5
    )
    N1 = 0.5 * d11_1 * w1s + d12_2 * w2s + d15_5 * w5s
    N2 = d12_1 * w1s + 0.5 * d22_2 * w2s
    N5 = d15_1 * w1s + 0.5 * d55_5 * w5s
    V1 = p.g * (p.m3 * r1 * c1 + p.m5 * r4 * cp)
    V2 = p.g * p.m3 * (0.5 * r3) * c2
    V5 = p.g * p.m5 * (0.5 * r5) * c5
    m_eff = M11 + 2.0 * (M12 * rho2 + M15 * rho5) + M22 * rho2 * rho2 + M55 * rho5 * rho5
    RMs = sv2 * (M12 + M22 * rho2) + sv5 * (M15 + M55 * rho5)
    RQ0 = -(N1 + V1) - rho2 * (N2 + V2) - rho5 * (N5 + V5)
    dxB = -r1 * s1 - r3 * s2 * rho2
    dxC = -r4 * sp - r5 * s5 * rho5
    acc0 = (RQ0 - RMs) / m_eff
    dacc = -dxC / m_eff  # the generalized force of F_C on θ1 is −F_C dx_C/dθ1
    bB = -r1 * c1 * w1s - r3 * (s2 * sv2 + c2 * w2s)
    return acc0, dacc, dxB, bB
