"""Kinematics, constrained dynamics (eq. 18), joint forces and energy of the toggle mechanism.

The dynamics are checked against ``reference_dynamics.py``, an independent evaluation of eq. (18)
built from generic point Jacobians and solved by the Schur complement, and by the energy balance
of long integrations.
"""

from __future__ import annotations

import math
import timeit

import numpy as np
import pytest
from mechanism_dynamics import (
    constraint_jacobian,
    constraint_residuals,
    dynamics,
    energies,
    friction_matrix,
    gamma,
    joint_forces,
    mass_matrix,
    nominal_fG,
    nominal_fG_theta1,
    positions,
    powers,
    slider_B,
    slider_C,
    theta1_state_from_slider,
    velocity_ratios,
)
from reference_dynamics import (
    reference_accelerations,
    reference_energy,
    reference_joint_forces,
    reference_powers,
)
from scipy.integrate import solve_ivp

from toggle_cosim.physics.mechanism import (
    dependent_angles,
    initial_state,
    state_from_slider,
    state_from_theta1,
    theta1_from_xB,
    xB_from_theta1,
)
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import MechanismParameters, MotorParameters

X_START, X_END = 0.2329, 0.3199
P0 = MechanismParameters()
K_F = thrust_constant(MotorParameters())


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.atleast_1d(a), np.atleast_1d(b)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _random_states(
    n: int, seed: int = 20010301
) -> list[tuple[np.ndarray, np.ndarray, float, float, MechanismParameters]]:
    """Random consistent states: θ1 in the stroke, ω1 ∈ [−10, 10] rad/s, ω2, ω5 from Φ_q q̇ = 0,
    F_C ∈ [−500, 500] N, F_E ∈ [0, 150] N, μ ∈ {0, 0.2}."""
    rng = np.random.default_rng(seed)
    lo, hi = theta1_from_xB(X_START, P0), theta1_from_xB(X_END, P0)
    out = []
    for i in range(n):
        q, qd = state_from_theta1(rng.uniform(lo, hi), rng.uniform(-10.0, 10.0), P0)
        p = MechanismParameters(mu=0.0 if i % 2 == 0 else 0.2)
        out.append((q, qd, float(rng.uniform(-500, 500)), float(rng.uniform(0, 150)), p))
    return out


STATES = _random_states(50)


# ---------------------------------------------------------------------------- kinematics


@pytest.mark.parametrize(("x_B", "deg"), [(X_START, -100.71), (X_END, -51.95)])
def test_eq26_stroke_angles(x_B: float, deg: float) -> None:
    """Eq. (26) gives the spec's lever angles (to 0.01°) and x_B computed back from the angles
    (B = A + r3 e(θ2) with θ2 from Φ1 = 0) is the input: the formula and branch are right."""
    theta1 = theta1_from_xB(x_B, P0)
    assert math.degrees(theta1) == pytest.approx(deg, abs=0.01)
    assert xB_from_theta1(theta1, P0) == pytest.approx(x_B, abs=1e-14)
    q, _ = initial_state(x_B, P0)
    assert positions(q, P0).x_B == pytest.approx(x_B, abs=1e-14)
    assert positions(q, P0).B[1] == pytest.approx(P0.f, abs=1e-14)


def test_eq26_literal_asin_form_for_positive_f() -> None:
    """For f > 0 the implementation (θ1' = atan2(x_B, f)) equals eq. (26) written with asin, and
    still closes the loop (|B − A| = r3, B on y = f)."""
    p = MechanismParameters(f=0.02)
    for x_B in (0.24, 0.28, 0.31):
        rho = math.hypot(x_B, p.f)
        literal = math.asin((x_B**2 + p.r1**2 + p.f**2 - p.r3**2) / (2 * p.r1 * rho)) - math.asin(x_B / rho)
        assert theta1_from_xB(x_B, p) == pytest.approx(literal, abs=1e-14)
        q, _ = initial_state(x_B, p)
        pts = positions(q, p)
        assert np.allclose(pts.B, [x_B, p.f], atol=1e-14)
        assert np.linalg.norm(pts.B - pts.A) == pytest.approx(p.r3, abs=1e-15)


def test_eq26_out_of_reach_raises() -> None:
    """Beyond the toggle (x_B > r1 + r3) eq. (26) has no solution."""
    with pytest.raises(ValueError, match="x_B"):
        theta1_from_xB(0.40, P0)


@pytest.mark.parametrize("x_B", [X_START, 0.27, X_END])
def test_initial_state_satisfies_constraints(x_B: float) -> None:
    """The initial state is at rest and on both guides: |Φ1|, |Φ2| < 1e-12 m."""
    q, qd = initial_state(x_B, P0)
    assert np.max(np.abs(constraint_residuals(q, P0))) < 1e-12
    assert np.all(qd == 0.0)
    pts = positions(q, P0)
    assert pts.C[1] == pytest.approx(P0.h, abs=1e-14)
    assert np.linalg.norm(pts.C - pts.D) == pytest.approx(P0.r5, abs=1e-15)


def test_state_from_slider_round_trip() -> None:
    """(x_B, v_B) → (q, q̇) satisfies Φ = 0, Φ_q q̇ = 0 and ẋ_B = v_B; the velocity ratios agree
    with central finite differences of the positions along the constraint manifold."""
    for x_B, v_B in [(0.24, 0.3), (0.29, -0.2), (0.315, 0.05)]:
        q, qd = state_from_slider(x_B, v_B, P0)
        assert np.max(np.abs(constraint_residuals(q, P0))) < 1e-12
        assert np.max(np.abs(constraint_jacobian(q, P0) @ qd)) < 1e-13
        x, v, _ = slider_B(q, qd, np.zeros(3), P0)
        assert (x, v) == pytest.approx((x_B, v_B), abs=1e-13)
        assert theta1_state_from_slider(x_B, v_B, P0) == pytest.approx((q[0], qd[0]), abs=1e-13)
        rho2, rho5, dxB, dxC = velocity_ratios(q, P0)
        h = 1e-6
        qp, _ = state_from_theta1(q[0] + h, 0.0, P0)
        qm, _ = state_from_theta1(q[0] - h, 0.0, P0)
        assert (qp[1] - qm[1]) / (2 * h) == pytest.approx(rho2, rel=1e-7)
        assert (qp[2] - qm[2]) / (2 * h) == pytest.approx(rho5, rel=1e-7)
        assert (positions(qp, P0).x_B - positions(qm, P0).x_B) / (2 * h) == pytest.approx(dxB, rel=1e-7)
        assert (positions(qp, P0).x_C - positions(qm, P0).x_C) / (2 * h) == pytest.approx(dxC, rel=1e-7)


def test_gamma_is_second_derivative_of_constraints() -> None:
    """γ = −(Φ_q q̇)_q q̇: along a constraint-consistent path θ1(t) = θ1_0 + ω t, Φ_q q̈ = γ where q̈
    is the finite-difference second derivative of the dependent angles."""
    t1, w = -1.3, 4.0
    h = 1e-4
    qs = [state_from_theta1(t1 + k * w * h, w, P0)[0] for k in (-1, 0, 1)]
    _, qd = state_from_theta1(t1, w, P0)
    qdd = (qs[2] - 2 * qs[1] + qs[0]) / h**2
    assert constraint_jacobian(qs[1], P0) @ qdd == pytest.approx(gamma(qs[1], qd, P0), rel=1e-6, abs=1e-6)


def test_friction_matrix_matches_eq17() -> None:
    """Q_fᵀ of eq. (17) in (θ1, θ2, θ5) row order; column j equals μ sgn(q̇_i) times Φ_j,q with
    sin → cos and cos → −sin, the relation the spec states for the sign of Φ2."""
    q, _ = initial_state(0.27, P0)
    sgn = np.array([1.0, -1.0, 1.0])
    Qf = friction_matrix(q, sgn, P0)
    t1, t2, t5 = q
    mu, r1, r3, r4, r5, phi = P0.mu, P0.r1, P0.r3, P0.r4, P0.r5, P0.phi
    expected = np.array(
        [
            [-mu * r1 * math.sin(t1), mu * r4 * math.sin(t1 + phi)],
            [mu * r3 * math.sin(t2), 0.0],
            [0.0, mu * r5 * math.sin(t5)],
        ]
    )
    assert np.allclose(Qf, expected, rtol=0, atol=1e-16)
    # sgn(0) = 0: no friction in a joint whose rate is zero
    assert np.all(friction_matrix(q, np.zeros(3), P0) == 0.0)


# ---------------------------------------------------------------------------- dynamics


def test_dynamics_matches_independent_reference() -> None:
    """q̈ and λ of eq. (18) agree with reference_dynamics (point Jacobians, Schur complement) at 50
    random consistent states with friction (μ = 0.2) and without, to 1e-10 relative. Any wrong
    term of M, N, gravity, applied forces, γ or Q_f would show up far above round-off (1e-14)."""
    worst_a = worst_l = 0.0
    for q, qd, F_C, F_E, p in STATES:
        qdd, lam = dynamics(q, qd, F_C, F_E, p)
        qdd_r, lam_r = reference_accelerations(q, qd, F_C, F_E, p.as_dict(), np.sign(qd))
        worst_a = max(worst_a, _rel(qdd, qdd_r))
        worst_l = max(worst_l, _rel(lam, lam_r))
        assert np.max(np.abs(constraint_jacobian(q, p) @ qdd - gamma(q, qd, p))) < 1e-10
    assert worst_a < 1e-10, worst_a
    assert worst_l < 1e-10, worst_l


def test_latched_signs_are_used() -> None:
    """Passing sgn overrides np.sign(q̇): sgn = 0 reproduces μ = 0 exactly; flipped signs change
    the friction and agree with the reference given the same signs."""
    q, qd, F_C, F_E, _ = STATES[3]
    p = MechanismParameters(mu=0.2)
    a0, l0 = dynamics(q, qd, F_C, F_E, MechanismParameters(mu=0.0))
    a1, l1 = dynamics(q, qd, F_C, F_E, p, sgn=np.zeros(3))
    assert np.array_equal(a0, a1) and np.array_equal(l0, l1)
    flipped = -np.sign(qd)
    a2, l2 = dynamics(q, qd, F_C, F_E, p, sgn=flipped)
    a3, _ = dynamics(q, qd, F_C, F_E, p)
    assert _rel(a2, a3) > 1e-4
    a2r, l2r = reference_accelerations(q, qd, F_C, F_E, p.as_dict(), flipped)
    assert _rel(a2, a2r) < 1e-10 and _rel(l2, l2r) < 1e-10


def test_mass_matrix_and_kinetic_energy() -> None:
    """M(q) is symmetric positive definite and ½ q̇ᵀ M q̇ equals T computed body by body from the
    point velocities (energies()) and the reference's T, to 1e-12 relative."""
    for q, qd, _, _, p in STATES[:20]:
        M = mass_matrix(q, p)
        assert np.array_equal(M, M.T)
        assert np.all(np.linalg.eigvalsh(M) > 0)
        T = energies(q, qd, p).T
        assert 0.5 * qd @ M @ qd == pytest.approx(T, rel=1e-12)
        ref = reference_energy(q, qd, p.as_dict())
        assert T == pytest.approx(ref["T"], rel=1e-12)
        assert energies(q, qd, p).V == pytest.approx(ref["V"], rel=1e-12, abs=1e-15)


def test_nominal_fG_matches_full_dynamics() -> None:
    """The controller's closed-form reduction (ẍ_B = f + G u, θ̈1 = f + G u) equals the 5×5 solve
    of eq. (18) with μ = 0, F_E = 0 and F_C = K_f u, for u = 0 and u = 3 A (1e-11 relative; mu of
    the nominal parameters is ignored)."""
    pn = MechanismParameters(mu=0.2)  # mu must be ignored
    p0 = MechanismParameters(mu=0.0)
    for x_B, v_B in [(X_START, 0.0), (0.25, 0.4), (0.3, -0.3), (X_END, 0.01)]:
        q, qd = state_from_slider(x_B, v_B, p0)
        f, G = nominal_fG(x_B, v_B, pn, K_F)
        f1, G1 = nominal_fG_theta1(q[0], qd[0], pn, K_F)
        for u in (0.0, 3.0):
            qdd, _ = dynamics(q, qd, K_F * u, 0.0, p0)
            a_B = slider_B(q, qd, qdd, p0)[2]
            assert f + G * u == pytest.approx(a_B, rel=1e-11, abs=1e-12)
            assert f1 + G1 * u == pytest.approx(qdd[0], rel=1e-11, abs=1e-12)
        assert G > 0  # positive i_q drives slider B forward


def test_nominal_fG_is_cheap() -> None:
    """nominal_fG runs at every 0.5 ms sample: best-of-5 mean time per call below 30 µs."""
    per_call = min(timeit.repeat(lambda: nominal_fG(0.27, 0.2, P0, K_F), number=2000, repeat=5)) / 2000
    assert per_call < 30e-6, per_call


# ---------------------------------------------------------------------------- joint forces


def test_joint_forces_consistent_with_multipliers() -> None:
    """The Newton–Euler chain (sliders, links 3 and 5, lever) agrees with the multipliers of eq. (18),
    F34y = λ1 and F56y = −λ2, to 1e-9 relative, with and without friction; the lever's moment
    equation about O (not used to build the forces) balances; the pin forces equal the reference's
    simultaneous least-squares Newton–Euler solution (whose residual is ~0)."""
    for q, qd, F_C, F_E, p in STATES:
        qdd, lam = dynamics(q, qd, F_C, F_E, p)
        jf = joint_forces(q, qd, qdd, lam, F_C, F_E, p)
        scale = max(1.0, float(np.max(np.abs(lam))))
        assert abs(jf.F34[1] - lam[0]) <= 1e-9 * scale
        assert abs(jf.F56[1] + lam[1]) <= 1e-9 * scale
        pts = positions(q, p)
        tau1 = -(friction_matrix(q, np.sign(qd), p) @ lam)[0]
        cross = lambda r, F: r[0] * F[1] - r[1] * F[0]  # noqa: E731
        moment = cross(pts.A, -jf.F23) + cross(pts.D, -jf.F25) + tau1
        assert p.J2 * qdd[0] == pytest.approx(moment, rel=1e-9, abs=1e-9 * scale)
        ref = reference_joint_forces(q, qd, F_C, F_E, p.as_dict())
        assert ref["residual"] < 1e-9 * max(1.0, abs(F_C))
        for name in ("F12", "F23", "F34", "F25", "F56"):
            assert _rel(getattr(jf, name), ref[name]) < 1e-9, name
        n = jf.normal()
        assert n["34"] == pytest.approx(math.hypot(*jf.F34))
        assert jf.friction()["12"] == pytest.approx(p.mu * n["12"])


def test_slider_C_and_powers_match_reference() -> None:
    """Thrust, load and friction powers agree with the reference; P_in = −F_C ẋ_C."""
    for q, qd, F_C, F_E, p in STATES[:10]:
        _, lam = dynamics(q, qd, F_C, F_E, p)
        pw = powers(q, qd, lam, F_C, F_E, p)
        ref = reference_powers(q, qd, F_C, F_E, p.as_dict())
        assert (pw.P_in, pw.P_load, pw.P_fric) == pytest.approx(
            (ref["P_in"], ref["P_load"], ref["P_fric"]), rel=1e-10, abs=1e-12
        )
        assert pw.P_in == pytest.approx(-F_C * slider_C(q, qd, np.zeros(3), p)[1], rel=1e-14)


# ---------------------------------------------------------------------------- energy


def _integrate_energy(p: MechanismParameters, F_C: float, F_E: float, T: float = 0.2):
    """Integrate the full state (q, q̇) of eq. (18) under constant F_C, F_E with the work integrals
    E_in = ∫P_in, E_fric = ∫P_fric, E_load = ∫P_load as extra states (rtol 1e-11)."""

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[:3], y[3:6]
        qdd, lam = dynamics(q, qd, F_C, F_E, p)
        pw = powers(q, qd, lam, F_C, F_E, p)
        return np.concatenate([qd, qdd, [pw.P_in, pw.P_fric, pw.P_load]])

    q0, qd0 = initial_state(X_START, p)
    sol = solve_ivp(rhs, (0.0, T), np.concatenate([q0, qd0, np.zeros(3)]), method="DOP853", rtol=1e-11, atol=1e-13)
    assert sol.success
    y = sol.y[:, -1]
    dE = energies(y[:3], y[3:6], p).E - energies(q0, qd0, p).E
    return y, dE


def test_energy_balance_without_friction() -> None:
    """μ = 0, F_E = 0, constant thrust F_C = 20 N for 0.2 s from rest at x_B = 0.2329: the work of
    the thrust equals the change of T + V (T from the point velocities, independent of M and N)
    to 1e-8 relative; the constraints stay satisfied (γ right) to 1e-9 m."""
    p = MechanismParameters(mu=0.0)
    y, dE = _integrate_energy(p, 20.0, 0.0)
    E_in, E_fric, E_load = y[6:]
    assert E_fric == 0.0 and E_load == 0.0
    assert positions(y[:3], p).x_B > X_START + 0.03  # the slider really moved
    assert abs(E_in - dE) <= 1e-8 * abs(E_in), (E_in, dE)
    assert np.max(np.abs(constraint_residuals(y[:3], p))) < 1e-9


def test_energy_balance_with_friction_and_load() -> None:
    """μ = 0.2, F_E = 30 N, F_C = 60 N: E_in = ΔE_mech + E_fric + E_load to 1e-8 relative, where
    E_fric = ∫ q̇ᵀ Q_fᵀ λ dt (signed, eq. (17)) and E_load = ∫ F_E ẋ_B dt."""
    p = MechanismParameters(mu=0.2)
    y, dE = _integrate_energy(p, 60.0, 30.0)
    E_in, E_fric, E_load = y[6:]
    assert E_load > 0 and E_fric != 0.0
    assert abs(E_in - (dE + E_fric + E_load)) <= 1e-8 * abs(E_in), (E_in, dE, E_fric, E_load)


# ---------------------------------------------------------------------------- parameters


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("r1", 0.0),
        ("r3", -0.27),
        ("r5", 0.0),
        ("mB", 0.0),
        ("mC", -1.0),
        ("m3", 0.0),
        ("J2", 0.0),
        ("mu", -0.1),
        ("g", -9.81),
        ("h", float("inf")),
    ],
)
def test_mechanism_parameter_validation(field: str, value: float) -> None:
    """Invalid mechanism parameters raise ValueError naming the field."""
    with pytest.raises(ValueError, match=field):
        MechanismParameters(**{field: value})


def test_rod_inertias_and_dict() -> None:
    """J3 = m3 r3²/12 and J5 = m5 r5²/12 (uniform rods); as_dict has the reference's keys."""
    assert P0.J3 == pytest.approx(0.3 * 0.27**2 / 12)
    assert P0.J5 == pytest.approx(0.3 * 0.27**2 / 12)
    assert set(P0.as_dict()) == set("r1 r3 r4 r5 f h phi m2 J2 m3 m5 mB mC g mu".split())
    assert dependent_angles(theta1_from_xB(X_START, P0), P0)[0] == pytest.approx(math.radians(21.3409345), abs=1e-8)
