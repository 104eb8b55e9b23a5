"""Thrust constant of the PMLSM, eqs. (2), (9), (12)-(16) of Fung, Wu & Chen (2001)."""

from __future__ import annotations

import math

import pytest
from scipy.integrate import quad

from toggle_cosim.physics.motor import airgap_flux_density_per_ampere, mmf_per_ampere, thrust_constant
from toggle_cosim.physics.parameters import MotorParameters

MU0 = 1.25663706212e-6  # any value: it cancels between eqs. (14) and (16)


def _bx1(x: float, y: float, m: MotorParameters) -> float:
    """B_x1 of eq. (9) per ampere, with k = coth(π g0/τ), g0 = L_m + G (eqs. (2), (4))."""
    kk = math.pi / m.tau
    k = 1.0 / math.tanh(kk * (m.L_m + m.G))
    F1 = 6.0 * math.sqrt(2.0) / (m.K_C * math.pi) * m.K_w1 * m.W / m.p
    return -MU0 * kk * F1 * (math.cosh(kk * y) - k * math.sinh(kk * y)) * math.cos(kk * x)


def test_thrust_constant_value() -> None:
    """Eq. (16) with the paper's motor parameters gives K_f = 56.959 N/A (spec value, computed
    independently); 1e-4 relative would catch any wrong factor (2, π, √2, a sin/sinh mix-up)."""
    K_f = thrust_constant(MotorParameters())
    assert K_f == pytest.approx(56.959, rel=1e-4)


def test_eq14_is_amplitude_of_eq9_at_airgap() -> None:
    """Eq. (14), B_x = μ0 (π/τ) F_1 sinh(πL_m/τ)/sinh(π(G+L_m)/τ), is the amplitude of the field
    of eq. (9) at y = G (cosh a − coth(b) sinh a = sinh(b − a)/sinh b)."""
    m = MotorParameters()
    amp_eq9 = abs(_bx1(0.0, m.G, m))
    assert airgap_flux_density_per_ampere(m, mu0=MU0) == pytest.approx(amp_eq9, rel=1e-12)
    assert mmf_per_ampere(m) == pytest.approx(6 * math.sqrt(2) / math.pi * 0.955 * 96, rel=1e-15)


def test_closed_form_16_matches_quadrature_of_12() -> None:
    """Eq. (12) integrated numerically, F_C = P_m L_A σ_m ∫_{−ατ/2}^{ατ/2} B_x sin(πx/τ − γ0) dx with
    σ_m = B_r/μ0 (eq. 15) and B_x the air-gap amplitude of eq. (14) (eq. (9) at y = G, x = 0), per
    ampere, equals the closed form (16) in magnitude to 1e-9. (The integral is negative for
    γ0 = π/2; eq. (16) reports its magnitude, the thrust that drives the mover.)"""
    m = MotorParameters()
    sigma_m = m.B_r / MU0
    Bx = abs(_bx1(0.0, m.G, m))  # eq. (14) via eq. (9)
    half = m.alpha * m.tau / 2.0
    integral, _ = quad(lambda x: Bx * math.sin(math.pi * x / m.tau - m.gamma0), -half, half, epsabs=0, epsrel=1e-13)
    F_per_A = m.P_m * m.L_A * sigma_m * integral
    assert integral < 0
    assert abs(F_per_A) == pytest.approx(thrust_constant(m), rel=1e-9)


def test_x_dependent_field_would_give_a_different_constant() -> None:
    """Documents the reading of eq. (12): with the x-dependent field of eq. (9) under the integral
    (instead of its amplitude, eq. (14)) the result is (τ/π)(απ/2 + sin(απ)/2) sin γ0 in place of
    (2τ/π) sin(απ/2) sin γ0, about 15 % lower, so eq. (16) is not that reading. We follow eq. (16)."""
    m = MotorParameters()
    sigma_m = m.B_r / MU0
    half = m.alpha * m.tau / 2.0
    integral, _ = quad(
        lambda x: _bx1(x, m.G, m) * math.sin(math.pi * x / m.tau - m.gamma0), -half, half, epsabs=0, epsrel=1e-13
    )
    F_x_dep = m.P_m * m.L_A * sigma_m * integral
    ratio = (m.alpha * math.pi / 2 + math.sin(m.alpha * math.pi) / 2) / (2 * math.sin(m.alpha * math.pi / 2))
    assert F_x_dep == pytest.approx(ratio * thrust_constant(m), rel=1e-9)
    assert 0.84 < ratio < 0.87


def test_thrust_constant_scaling() -> None:
    """K_f is proportional to B_r, W, 1/K_C and sin γ0 (eqs. 2, 16); a wrong exponent on any of
    them would break these exact ratios."""
    base = thrust_constant(MotorParameters())
    assert thrust_constant(MotorParameters(B_r=1.72)) == pytest.approx(2 * base, rel=1e-14)
    assert thrust_constant(MotorParameters(W=48)) == pytest.approx(base / 2, rel=1e-14)
    assert thrust_constant(MotorParameters(K_C=2.0)) == pytest.approx(base / 2, rel=1e-14)
    assert thrust_constant(MotorParameters(gamma0=math.pi / 6)) == pytest.approx(base / 2, rel=1e-14)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("tau", 0.0),
        ("B_r", -1.0),
        ("L_m", 0.0),
        ("G", -0.001),
        ("alpha", 1.5),
        ("alpha", 0.0),
        ("K", 0.0),
        ("W", float("nan")),
    ],
)
def test_motor_parameter_validation(field: str, value: float) -> None:
    """Invalid motor parameters raise ValueError naming the field."""
    with pytest.raises(ValueError, match=field):
        MotorParameters(**{field: value})
