"""Thrust constant of the flat single-sided PMLSM, eqs. (2) and (12)-(16) of the paper.

The thrust is F_C = K_f i_q. With F_1 = 6√2/(K_C π) (K_w1 W/p) I (eq. 2),

    B_x/I = μ0 (π/τ) (F_1/I) sinh(π L_m/τ) / sinh(π (G + L_m)/τ)        (eq. 14)
    σ_m   = B_r/μ0                                                        (eq. 15)
    K_f   = 2τ/(μ0 π) B_r P_m L_A sin(απ/2) sin γ0 · B_x/I                (eq. 16)

μ0 cancels between eqs. (14) and (16), so it does not appear below.

Note on eq. (12) → (16): eq. (16) is what eq. (12) gives when ``B_x`` under the integral is the
*amplitude* B_x1m of eq. (14) (the subscript "m"), a constant:
∫_{−ατ/2}^{ατ/2} sin(πx/τ − γ0) dx = −(2τ/π) sin(απ/2) sin γ0, whose magnitude is eq. (16).
Integrating the x-dependent field of eq. (9) instead would give (τ/π)(απ/2 + sin(απ)/2) sin γ0
in place of (2τ/π) sin(απ/2) sin γ0, about 15 % less. We follow eq. (16), as the paper does.
"""

from __future__ import annotations

import math

from toggle_cosim.physics.parameters import MotorParameters

__all__ = ["thrust_constant", "mmf_per_ampere", "airgap_flux_density_per_ampere"]


def mmf_per_ampere(m: MotorParameters) -> float:
    """Fundamental MMF per ampere F_1/I = 6√2/(K_C π) · K_w1 W/p, eq. (2)."""
    return 6.0 * math.sqrt(2.0) / (m.K_C * math.pi) * (m.K_w1 * m.W / m.p)


def airgap_flux_density_per_ampere(m: MotorParameters, mu0: float = 4e-7 * math.pi) -> float:
    """Amplitude of B_x at y = G per ampere, eq. (14) [T/A] (depends on μ0; K_f does not)."""
    k = math.pi / m.tau
    return mu0 * k * mmf_per_ampere(m) * math.sinh(k * m.L_m) / math.sinh(k * (m.G + m.L_m))


def thrust_constant(m: MotorParameters) -> float:
    """Thrust constant K_f = F_C/i_q [N/A] from eqs. (13)-(16) (μ0 cancels).

    K_f = 2τ/π · B_r P_m L_A sin(απ/2) sin γ0 · (π/τ) (F_1/I) sinh(π L_m/τ)/sinh(π(G+L_m)/τ).
    With the paper's motor parameters K_f ≈ 56.959 N/A.
    """
    k = math.pi / m.tau
    bx_over_mu0_i = k * mmf_per_ampere(m) * math.sinh(k * m.L_m) / math.sinh(k * (m.G + m.L_m))  # eq. (14) / μ0
    return (
        2.0
        * m.tau
        / math.pi
        * m.B_r
        * m.P_m
        * m.L_A
        * math.sin(m.alpha * math.pi / 2.0)
        * math.sin(m.gamma0)
        * bx_over_mu0_i
    )
