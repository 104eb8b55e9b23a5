"""Two-phase VSC, eqs. (19)-(25), in a discrete loop on the nominal plant.

The plant here is eq. (18) solved by ``mechanism.dynamics`` (5×5 solve) with μ = 0, F_E = 0 and
an ideal current loop (F_C = K_f i_q*), integrated by solve_ivp between samples (zero-order hold,
T_s = 0.5 ms). The controller computes its model from its own closed-form reduction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
from mechanism_dynamics import dynamics, slider_B
from scipy.integrate import solve_ivp

from toggle_cosim.control.controller import ControllerState, VSCController, hitting_time
from toggle_cosim.physics.mechanism import initial_state, state_from_theta1, theta1_from_xB
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import ControllerGains, MechanismParameters, MotorParameters

X_START, X_END = 0.2329, 0.3199
TS = 0.5e-3
K_F = thrust_constant(MotorParameters())
NOMINAL = MechanismParameters(mu=0.0)
GAINS = ControllerGains()


def at(x_B: float, v_B: float = 0.0) -> dict[str, float]:
    """A measurement of the slider alone (what the x_B objective reads)."""
    return {"x_B": x_B, "v_B": v_B}


@dataclass
class Run:
    state: ControllerState
    t: np.ndarray
    x_B: np.ndarray
    v_B: np.ndarray
    a_B: np.ndarray
    u: np.ndarray
    S: np.ndarray
    reaching: np.ndarray


def simulate(ctrl: VSCController, plant: MechanismParameters, T: float, F_E: float = 0.0) -> Run:
    """Discrete loop: sample (x_B, v_B, θ1, ω1) at t_k = k T_s, u_k = controller, hold u_k on [t_k, t_k+1)
    while solve_ivp integrates the plant's reduced state (θ1, ω1) (θ2, θ5 and their rates from the
    constraints, θ̈1 from the full eq. (18))."""

    def rhs(_t: float, y: np.ndarray, F_C: float) -> list[float]:
        q, qd = state_from_theta1(y[0], y[1], plant)
        qdd, _ = dynamics(q, qd, F_C, F_E, plant)
        return [qd[0], qdd[0]]

    q0, _ = initial_state(X_START, plant)
    y = np.array([q0[0], 0.0])
    n = round(T / TS)
    rows = []
    state: ControllerState | None = None
    for k in range(n + 1):
        t = k * TS
        q, qd = state_from_theta1(y[0], y[1], plant)
        x_B, v_B, _ = slider_B(q, qd, np.zeros(3), plant)
        measured = {"x_B": x_B, "v_B": v_B, "theta1": y[0], "omega1": y[1]}
        if state is None:
            state = ctrl.start(t, measured)
        out = ctrl.step(state, t, measured)
        u = out.command
        qdd, _ = dynamics(q, qd, K_F * u, F_E, plant)
        a_B = slider_B(q, qd, qdd, plant)[2]
        rows.append((t, x_B, v_B, a_B, u, out.S, out.phase == "reaching"))
        if k == n:
            break
        sol = solve_ivp(rhs, (t, t + TS), y, args=(K_F * u,), rtol=1e-10, atol=1e-12)
        y = sol.y[:, -1]
    arr = np.array(rows)
    assert state is not None
    return Run(state, arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5], arr[:, 6].astype(bool))


@pytest.fixture(scope="module")
def nominal_run() -> Run:
    return simulate(VSCController(gains=GAINS, nominal=NOMINAL, K_f=K_F, target=X_END), NOMINAL, T=1.5)


def analytic_S(t: np.ndarray, S0: float) -> np.ndarray:
    """Solution of eq. (19) for S > 0: S(t) = (S0 + Q/P) e^{−P t} − Q/P."""
    return (S0 + GAINS.Q / GAINS.P) * np.exp(-GAINS.P * t) - GAINS.Q / GAINS.P


def reaching_tolerance(S0: float, max_abs_aB: float) -> float:
    """Bound on |S(t_k) − S_analytic(t_k)| in the reaching phase from the zero-order hold.

    At each sample the control imposes Ṡ(t_k⁺) = −P S_k − Q exactly (nominal plant), but u is then
    held, so over a step S_{k+1} = S_k − T_s (P S_k + Q) + ½ T_s² S̈_hold, whereas the analytic
    solution has S̈ = P (P S + Q). The error ε_k therefore obeys
    ε_{k+1} = (1 − P T_s) ε_k + ½ T_s² D_k with |D_k| ≤ P (P |S0| + Q) + |S̈_hold|, so
    |ε_k| ≤ ½ T_s² D_max / (P T_s) = T_s D_max / (2P). With S = C e + ė, S̈_hold = −C a_B − ȧ_B;
    |C a_B| ≤ C max|a_B| and the jerk under a held input is small (the slider starts at rest);
    a 25 % margin covers it. With the paper's gains: about 8.9e-3 m/s ≈ 2 % of S0.
    """
    D_max = GAINS.P * (GAINS.P * abs(S0) + GAINS.Q) + GAINS.C * max_abs_aB
    return 1.25 * TS * D_max / (2 * GAINS.P)


def test_initial_switching_function_and_hitting_time() -> None:
    """S(t0) = C (x* − x_B0) = 5 × 0.087 = 0.435 m/s and T_h = ln(P S0/Q + 1)/P = 0.0373 s, eq. (21)."""
    ctrl = VSCController(gains=GAINS, nominal=NOMINAL, K_f=K_F, target=X_END)
    st = ctrl.start(0.0, at(X_START))
    assert st.S0 == pytest.approx(0.435, abs=1e-12)
    assert st.T_h == pytest.approx(0.0373, abs=1e-4)
    assert st.T_h == pytest.approx(math.log(50 * 0.435 / 4 + 1) / 50, rel=1e-14)
    # T_h is measured from t0
    assert ctrl.start(2.0, at(X_START)).T_h == st.T_h
    assert ctrl.phase(ctrl.start(2.0, at(X_START)), 2.0 + 0.037) == "reaching"
    assert ctrl.phase(ctrl.start(2.0, at(X_START)), 2.0 + 0.0373) == "sliding"
    assert hitting_time(-st.S0, GAINS) == st.T_h  # |S(t0)|


def test_control_laws_eq23_eq24() -> None:
    """u_r and u_s are eqs. (23) and (24) with d = 0 and the nominal f, G."""
    ctrl = VSCController(gains=GAINS, nominal=NOMINAL, K_f=K_F, target=X_END)
    st = ctrl.start(0.0, at(X_START))
    x_B, v_B = 0.25, 0.2
    o_r = ctrl.step(st, 0.01, at(x_B, v_B))
    o_s = ctrl.step(st, 0.05, at(x_B, v_B))
    u_r, u_s = o_r.command, o_s.command
    e, ed = X_END - x_B, -v_B
    S = 5 * e + ed
    assert (o_r.phase, o_s.phase) == ("reaching", "sliding")
    assert o_r.S == pytest.approx(S, rel=1e-15)
    assert u_r == pytest.approx((5 * ed + 50 * S + 4 * np.sign(S) - o_r.f) / o_r.G, rel=1e-14)
    assert u_s == pytest.approx((5 * ed + 65 * S / (abs(S) + 0.25) - o_s.f) / o_s.G, rel=1e-14)


def test_controller_ignores_nominal_friction() -> None:
    """The nominal model has no friction: the controller's output does not depend on nominal.mu."""
    a = VSCController(nominal=MechanismParameters(mu=0.0), K_f=K_F)
    b = VSCController(nominal=MechanismParameters(mu=0.2), K_f=K_F)
    st = a.start(0.0, at(X_START))
    assert a.step(st, 0.1, at(0.27, 0.3)).command == b.step(st, 0.1, at(0.27, 0.3)).command


def test_invalid_controller_configuration() -> None:
    with pytest.raises(ValueError, match="objective"):
        VSCController(objective="x_C")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="K_f"):
        VSCController(K_f=0.0)
    with pytest.raises(ValueError, match="x_B"):
        VSCController(target=0.5)


def test_reaching_phase_follows_eq19(nominal_run: Run) -> None:
    """On the nominal plant the sampled S(t_k) follows the analytic solution of eq. (19),
    S(t) = (S0 + Q/P) e^{−P t} − Q/P, for t_k < T_h, within the zero-order-hold bound of
    :func:`reaching_tolerance` (≈ 2 % of S0)."""
    r = nominal_run
    m = r.reaching
    dev = np.max(np.abs(r.S[m] - analytic_S(r.t[m], r.state.S0)))
    tol = reaching_tolerance(r.state.S0, float(np.max(np.abs(r.a_B[m]))))
    assert tol < 0.021 * r.state.S0
    assert dev < tol, (dev, tol)


def test_reaching_tolerance_detects_model_error() -> None:
    """The tolerance is tight enough to fail a wrong model: with the controller's K_f 10 % too high
    the reaching phase leaves the bound (0.04 s simulated)."""
    wrong = VSCController(gains=GAINS, nominal=NOMINAL, K_f=1.1 * K_F, target=X_END)
    r = simulate(wrong, NOMINAL, T=0.04)
    m = r.reaching
    dev = np.max(np.abs(r.S[m] - analytic_S(r.t[m], r.state.S0)))
    assert dev > reaching_tolerance(r.state.S0, float(np.max(np.abs(r.a_B[m]))))


def test_switch_at_first_sample_after_hitting_time(nominal_run: Run) -> None:
    """r of eq. (25) switches at the first sample with t_k − t0 ≥ T_h (t = 0.0375 s), once."""
    r = nominal_run
    first_sliding = int(np.argmax(~r.reaching))
    assert r.t[first_sliding] == pytest.approx(math.ceil(r.state.T_h / TS) * TS, abs=1e-12)
    assert np.all(r.reaching[:first_sliding]) and not np.any(r.reaching[first_sliding:])
    # S is near the surface at the switch (|S| ≪ S0)
    assert abs(r.S[first_sliding]) < 0.01 * r.state.S0


def test_nominal_positioning(nominal_run: Run) -> None:
    """Nominal case: x_B ends within 0.1 mm of x* = 0.3199 m after 1.5 s (on the surface the error
    decays as e^{−C t}, 0.087 e^{−5 × 1.46} ≈ 0.06 mm), with no overshoot beyond 0.1 mm, and the
    peak command is the first one, u0 = (P S0 + Q − f)/G ≈ 3.17 A."""
    r = nominal_run
    assert abs(r.x_B[-1] - X_END) < 1e-4
    assert np.max(r.x_B) < X_END + 1e-4
    assert int(np.argmax(np.abs(r.u))) == 0
    assert np.max(np.abs(r.u)) == pytest.approx(3.17, abs=0.01)


@pytest.mark.slow
def test_theta1_objective_reaches_target() -> None:
    """Option: regulating θ1 toward θ1* (eq. (26)) moves slider B to the same target on the
    nominal plant; S0 = C (θ1* − θ1_0) and T_h from eq. (21)."""
    ctrl = VSCController(gains=GAINS, nominal=NOMINAL, K_f=K_F, target=X_END, objective="theta1")
    r = simulate(ctrl, NOMINAL, T=1.5)
    d_theta = theta1_from_xB(X_END, NOMINAL) - theta1_from_xB(X_START, NOMINAL)
    assert r.state.S0 == pytest.approx(GAINS.C * d_theta, rel=1e-12)
    assert r.state.T_h == pytest.approx(math.log(GAINS.P * GAINS.C * d_theta / GAINS.Q + 1) / GAINS.P, rel=1e-12)
    assert abs(r.x_B[-1] - X_END) < 1e-4
