"""Independent reference evaluation of eq. (18) of Fung, Wu & Chen (2001) for the toggle mechanism.

Self-contained (numpy only; does NOT import toggle_cosim) so that it can check both
``toggle_cosim.physics.mechanism`` and the Modelica/FMU plant.

It is built differently from ``toggle_cosim.physics.mechanism``:

* every material point (centres of mass of links 3 and 5, sliders B and C) is described as a
  generic sum of rotating vectors, p(q) = Σ_k L_k (cos ψ_k, sin ψ_k) with ψ_k = a_k·q + c_k;
  its Jacobian J_p = Σ_k L_k (−sin ψ_k, cos ψ_k) a_kᵀ and the velocity-product term
  J̇_p q̇ = −Σ_k L_k (cos ψ_k, sin ψ_k) (a_k·q̇)² follow mechanically;
* M = Σ m J_pᵀ W J_p + Σ J_body a aᵀ (W selects x only for the sliders),
  N = Σ m J_pᵀ W J̇_p q̇, generalized gravity and applied forces = Σ J_pᵀ F_p;
* the constraints are Φ1 = y_B − f, Φ2 = h − y_C, so Φ_q and γ come from the y-rows of the
  slider Jacobians, and the friction matrix of eq. (17) from their x-rows:
  Q_fᵀ = μ diag(sgn) [∂x_B/∂q, −∂x_C/∂q];
* eq. (18) is solved by the Schur complement on the multipliers, not as one 5×5 system;
* the pin forces solve all the bodies' Newton–Euler equations at once (11 equations, 10
  unknowns, moments about each body's centre of mass) by least squares, and report the
  residual of that over-determined system.

API (plain floats and a dict with keys r1 r3 r4 r5 f h phi m2 J2 m3 m5 mB mC g mu; J3 and J5 are
m3 r3²/12 and m5 r5²/12 unless the dict provides them):

    reference_accelerations(q, qd, F_C, F_E, params, sgn=None) -> (qdd, lam)
    reference_joint_forces(q, qd, F_C, F_E, params, sgn=None) -> dict
    reference_energy(q, qd, params) -> dict(T, V, E)
    reference_powers(q, qd, F_C, F_E, params, sgn=None) -> dict(P_in, P_load, P_fric)
    reference_friction_rows(q, lam, params) -> R (the rows of Q_fᵀλ/μ with sgn = 1)
    reference_breakaway_thrust(q, direction, F_E, params, bracket) -> F_C where a slip from rest
        in `direction` under friction μ sgn(q̇)|R| has θ̈1 = 0 (the stick-slip breakaway)
    reference_slip_accelerations(q, omega1, direction, F_C, F_E, params) -> (qdd, lam) of a
        slip in `direction` under friction μ sgn(q̇)|R| (model 2)
    reference_rest_holds(q, F_C, F_E, params) -> True where no slip from rest is consistent
    reference_rest_trajectory(theta1_0, segments, F_E, params, dt) -> samples of x_B and of the
        rest flag of the one-degree-of-freedom motion under model 2 with the Filippov rest rule
    reference_current_trajectory(theta1_0, iq_ref, T_s, K, K_f, F_E, params) -> the same motion
        driven through a first-order current loop by sampled commands (a closed loop replayed)

Friction at rest (Filippov): the linkage has one degree of freedom, q̇ = k(q) ω1 with k the null
vector of Φ_q scaled to k_1 = 1, so every joint rests when the lever does. At ω1 = 0 the
friction is set-valued; a slip in direction d (sgn ω1 = d) is consistent when its own
acceleration keeps that direction, d θ̈1(slip d) > 0. The mechanism leaves rest in the
consistent direction and stays at rest when neither direction is consistent.

Conventions: q = (θ1, θ2, θ5), qd = (ω1, ω2, ω5); F_C ≥ 0 is the thrust on slider C along −x,
F_E the external force on slider B along −x; sgn defaults to np.sign(qd) (sgn(0) = 0).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

Terms = list[tuple[float, np.ndarray, float]]

_E1 = np.array([1.0, 0.0, 0.0])
_E2 = np.array([0.0, 1.0, 0.0])
_E5 = np.array([0.0, 0.0, 1.0])


def _inertia(params: Mapping[str, float]) -> tuple[float, float]:
    J3 = params.get("J3", params["m3"] * params["r3"] ** 2 / 12.0)
    J5 = params.get("J5", params["m5"] * params["r5"] ** 2 / 12.0)
    return float(J3), float(J5)


def _points(params: Mapping[str, float]) -> dict[str, Terms]:
    r1, r3, r4, r5, phi = (params[k] for k in ("r1", "r3", "r4", "r5", "phi"))
    return {
        "A": [(r1, _E1, 0.0)],
        "D": [(r4, _E1, phi)],
        "G3": [(r1, _E1, 0.0), (0.5 * r3, _E2, 0.0)],
        "B": [(r1, _E1, 0.0), (r3, _E2, 0.0)],
        "G5": [(r4, _E1, phi), (0.5 * r5, _E5, 0.0)],
        "C": [(r4, _E1, phi), (r5, _E5, 0.0)],
    }


def _pos(terms: Terms, q: np.ndarray) -> np.ndarray:
    out = np.zeros(2)
    for L, a, c in terms:
        psi = a @ q + c
        out += L * np.array([np.cos(psi), np.sin(psi)])
    return out


def _jac(terms: Terms, q: np.ndarray) -> np.ndarray:
    out = np.zeros((2, 3))
    for L, a, c in terms:
        psi = a @ q + c
        out += L * np.outer([-np.sin(psi), np.cos(psi)], a)
    return out


def _jdot_qd(terms: Terms, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    out = np.zeros(2)
    for L, a, c in terms:
        psi = a @ q + c
        out -= L * np.array([np.cos(psi), np.sin(psi)]) * (a @ qd) ** 2
    return out


def _model(
    q: Sequence[float],
    qd: Sequence[float],
    F_C: float,
    F_E: float,
    params: Mapping[str, float],
    sgn: Sequence[float] | None,
) -> dict[str, Any]:
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    s = np.sign(qd) if sgn is None else np.asarray(sgn, dtype=float)
    pts = _points(params)
    J = {k: _jac(v, q) for k, v in pts.items()}
    Jdq = {k: _jdot_qd(v, q, qd) for k, v in pts.items()}
    J3, J5 = _inertia(params)
    Wx = np.diag([1.0, 0.0])
    I2 = np.eye(2)
    # (mass, point, weighting): links with full planar translation, sliders along x only
    translating = [(params["m3"], "G3", I2), (params["mB"], "B", Wx), (params["m5"], "G5", I2), (params["mC"], "C", Wx)]
    rotating = [(params["J2"], _E1), (J3, _E2), (J5, _E5)]
    M = np.zeros((3, 3))
    N = np.zeros(3)
    for m, k, W in translating:
        M += m * J[k].T @ W @ J[k]
        N += m * J[k].T @ W @ Jdq[k]
    for Jb, a in rotating:
        M += Jb * np.outer(a, a)
    g = params["g"]
    Q = -N
    Q += J["G3"].T @ np.array([0.0, -params["m3"] * g])
    Q += J["G5"].T @ np.array([0.0, -params["m5"] * g])
    Q += J["B"].T @ np.array([-F_E, 0.0])
    Q += J["C"].T @ np.array([-F_C, 0.0])
    Phi_q = np.vstack([J["B"][1], -J["C"][1]])
    gam = np.array([-Jdq["B"][1], Jdq["C"][1]])
    QfT = params["mu"] * (s[:, None] * np.column_stack([J["B"][0], -J["C"][0]]))
    return dict(q=q, qd=qd, s=s, pts=pts, J=J, Jdq=Jdq, M=M, Q=Q, Phi_q=Phi_q, gamma=gam, QfT=QfT, J3=J3, J5=J5)


def reference_accelerations(
    q: Sequence[float],
    qd: Sequence[float],
    F_C: float,
    F_E: float,
    params: Mapping[str, float],
    sgn: Sequence[float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(q̈, λ) of eq. (18): M q̈ + (Φ_qᵀ + Q_fᵀ) λ = Q, Φ_q q̈ = γ, by the Schur complement."""
    d = _model(q, qd, F_C, F_E, params, sgn)
    M, Q, Phi_q, gam = d["M"], d["Q"], d["Phi_q"], d["gamma"]
    AT = Phi_q.T + d["QfT"]
    Minv_AT = np.linalg.solve(M, AT)
    Minv_Q = np.linalg.solve(M, Q)
    lam = np.linalg.solve(Phi_q @ Minv_AT, Phi_q @ Minv_Q - gam)
    qdd = Minv_Q - Minv_AT @ lam
    return qdd, lam


def _cross(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def reference_joint_forces(
    q: Sequence[float],
    qd: Sequence[float],
    F_C: float,
    F_E: float,
    params: Mapping[str, float],
    sgn: Sequence[float] | None = None,
) -> dict[str, Any]:
    """Pin forces from all Newton–Euler equations at once.

    Unknowns: F12 (ground on lever at O), F23 (lever on link 3 at A), F34 (link 3 on slider B),
    F25 (lever on link 5 at D), F56 (link 5 on slider C), each (x, y). Equations: lever force (2)
    and moment about O (1), link 3 force (2) and moment about G3 (1), slider B along x (1), link 5
    force (2) and moment about G5 (1), slider C along x (1). The rows of −Q_fᵀλ act as torques
    from ground on the lever, link 3 and link 5. Slider weights are carried by the guides.

    Returns a dict with keys "F12", "F23", "F34", "F25", "F56" (arrays), "normal" (dict of norms),
    "friction" (μ × norms), "qdd", "lam" and "residual" (max abs residual of the 11 equations, N or N m).
    """
    d = _model(q, qd, F_C, F_E, params, sgn)
    qdd, lam = reference_accelerations(q, qd, F_C, F_E, params, sgn)
    qv = d["q"]
    pts = {k: _pos(v, qv) for k, v in d["pts"].items()}
    acc = {k: d["J"][k] @ qdd + d["Jdq"][k] for k in d["pts"]}
    tau = -d["QfT"] @ lam
    g = params["g"]
    m2, m3, m5, mB, mC = (params[k] for k in ("m2", "m3", "m5", "mB", "mC"))
    idx = {"F12": 0, "F23": 2, "F34": 4, "F25": 6, "F56": 8}
    A = np.zeros((11, 10))
    b = np.zeros(11)

    def force(row: int, name: str, sign: float) -> None:
        A[row, idx[name]] += sign
        A[row + 1, idx[name] + 1] += sign

    def moment(row: int, r: np.ndarray, name: str, sign: float) -> None:
        # r × (sign F) = sign (r_x F_y − r_y F_x)
        A[row, idx[name]] += -sign * r[1]
        A[row, idx[name] + 1] += sign * r[0]

    O = np.zeros(2)
    # Lever: 0 = F12 − F23 − F25 − (0, m2 g);  J2 θ̈1 = A×(−F23) + D×(−F25) + τ1
    force(0, "F12", 1.0)
    force(0, "F23", -1.0)
    force(0, "F25", -1.0)
    b[0:2] = [0.0, m2 * g]
    moment(2, pts["A"] - O, "F23", -1.0)
    moment(2, pts["D"] - O, "F25", -1.0)
    b[2] = params["J2"] * qdd[0] - tau[0]
    # Link 3: m3 a_G3 = F23 − F34 − (0, m3 g);  J3 θ̈2 = (A−G3)×F23 + (B−G3)×(−F34) + τ2
    force(3, "F23", 1.0)
    force(3, "F34", -1.0)
    b[3:5] = m3 * acc["G3"] + np.array([0.0, m3 * g])
    moment(5, pts["A"] - pts["G3"], "F23", 1.0)
    moment(5, pts["B"] - pts["G3"], "F34", -1.0)
    b[5] = d["J3"] * qdd[1] - tau[1]
    # Slider B (x): mB a_Bx = F34x − F_E
    A[6, idx["F34"]] = 1.0
    b[6] = mB * acc["B"][0] + F_E
    # Link 5: m5 a_G5 = F25 − F56 − (0, m5 g);  J5 θ̈5 = (D−G5)×F25 + (C−G5)×(−F56) + τ5
    force(7, "F25", 1.0)
    force(7, "F56", -1.0)
    b[7:9] = m5 * acc["G5"] + np.array([0.0, m5 * g])
    moment(9, pts["D"] - pts["G5"], "F25", 1.0)
    moment(9, pts["C"] - pts["G5"], "F56", -1.0)
    b[9] = d["J5"] * qdd[2] - tau[2]
    # Slider C (x): mC a_Cx = F56x − F_C
    A[10, idx["F56"]] = 1.0
    b[10] = mC * acc["C"][0] + F_C

    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    residual = float(np.max(np.abs(A @ x - b)))
    out: dict[str, Any] = {name: x[i : i + 2].copy() for name, i in idx.items()}
    out["normal"] = {name[1:]: float(np.linalg.norm(out[name])) for name in idx}
    out["friction"] = {k: params["mu"] * v for k, v in out["normal"].items()}
    out["qdd"], out["lam"], out["residual"] = qdd, lam, residual
    return out


def reference_energy(q: Sequence[float], qd: Sequence[float], params: Mapping[str, float]) -> dict[str, float]:
    """T = ½ q̇ᵀ M q̇ (reference M), V = g (m3 y_G3 + m5 y_G5), E = T + V."""
    d = _model(q, qd, 0.0, 0.0, params, np.zeros(3))
    qdv = d["qd"]
    T = 0.5 * float(qdv @ d["M"] @ qdv)
    V = params["g"] * (params["m3"] * _pos(d["pts"]["G3"], d["q"])[1] + params["m5"] * _pos(d["pts"]["G5"], d["q"])[1])
    return {"T": T, "V": float(V), "E": T + float(V)}


def reference_powers(
    q: Sequence[float],
    qd: Sequence[float],
    F_C: float,
    F_E: float,
    params: Mapping[str, float],
    sgn: Sequence[float] | None = None,
) -> dict[str, float]:
    """P_in = −F_C ẋ_C (thrust power), P_load = F_E ẋ_B, P_fric = q̇ᵀ Q_fᵀ λ (signed)."""
    d = _model(q, qd, F_C, F_E, params, sgn)
    _, lam = reference_accelerations(q, qd, F_C, F_E, params, sgn)
    v_B = float(d["J"]["B"][0] @ d["qd"])
    v_C = float(d["J"]["C"][0] @ d["qd"])
    return {"P_in": -F_C * v_C, "P_load": F_E * v_B, "P_fric": float(d["qd"] @ d["QfT"] @ lam)}


def reference_friction_rows(q: Sequence[float], lam: Sequence[float], params: Mapping[str, float]) -> np.ndarray:
    """The rows R_i of Q_fᵀλ/μ with every sgn = 1: R = [∂x_B/∂q, −∂x_C/∂q] λ (the x-rows of the
    slider Jacobians), so that friction model 2 is Q_fᵀλ = μ sgn(q̇) |R|."""
    d = _model(q, np.zeros(3), 0.0, 0.0, params, np.ones(3))
    return np.column_stack([d["J"]["B"][0], -d["J"]["C"][0]]) @ np.asarray(lam, dtype=float)


def _admissible_direction(q: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
    """k with Φ_q k = 0 and k_1 = 1: q̇ = k ω1 for every motion of the closed loops."""
    d = _model(q, np.zeros(3), 0.0, 0.0, params, np.zeros(3))
    Phi_q = d["Phi_q"]
    # solve Phi_q[:, 1:] (k2, k5) = -Phi_q[:, 0]
    tail = np.linalg.solve(Phi_q[:, 1:], -Phi_q[:, 0])
    return np.r_[1.0, tail]


def reference_slip_accelerations(
    q: Sequence[float], omega1: float, direction: float, F_C: float, F_E: float, params: Mapping[str, float]
) -> tuple[np.ndarray, np.ndarray]:
    """(q̈, λ) of the mechanism at q with q̇ = k ω1, slipping in `direction` (the sign of ω1, given
    separately so that ω1 may be 0) under friction μ sgn(q̇_i) |R_i| (model 2). sgn(R_i) depends on
    λ, which depends on it: iterated to a fixed point."""
    q = np.asarray(q, dtype=float)
    k = _admissible_direction(q, params)
    qd = k * omega1
    base = direction * np.sign(k)  # sgn(q̇_i) for q̇ along k in `direction`
    sgn = base
    for _ in range(10):
        qdd, lam = reference_accelerations(q, qd, F_C, F_E, params, sgn)
        new = base * np.sign(reference_friction_rows(q, lam, params))
        if np.array_equal(new, sgn):
            break
        sgn = new
    return qdd, lam


def reference_rest_holds(q: Sequence[float], F_C: float, F_E: float, params: Mapping[str, float]) -> bool:
    """At rest at q: True when neither slip is consistent (d θ̈1(slip d) <= 0 for d = +1 and -1),
    so that the set-valued friction holds the mechanism."""
    return all(d * reference_slip_accelerations(q, 0.0, d, F_C, F_E, params)[0][0] <= 0.0 for d in (1.0, -1.0))


def _leaving_direction(q: np.ndarray, F_C: float, F_E: float, params: Mapping[str, float]) -> float:
    """The direction a slip from rest at q is consistent in, 0 where none is."""
    ways = [d for d in (1.0, -1.0) if d * reference_slip_accelerations(q, 0.0, d, F_C, F_E, params)[0][0] > 0.0]
    if len(ways) == 2:
        raise ValueError(f"both slips from rest are consistent at theta1 = {q[0]} (a Painlevé-type case)")
    return ways[0] if ways else 0.0


def _closed_angles(theta1: float, params: Mapping[str, float]) -> np.ndarray:
    """(θ1, θ2, θ5) on the loop closures Φ1 = Φ2 = 0, the branch of the assembled toggle."""
    r1, r3, r4, r5, f, h, phi = (params[k] for k in ("r1", "r3", "r4", "r5", "f", "h", "phi"))
    return np.array(
        [theta1, np.arcsin((f - r1 * np.sin(theta1)) / r3), np.arcsin((h - r4 * np.sin(theta1 + phi)) / r5)]
    )


def reference_rest_trajectory(
    theta1_0: float,
    segments: Sequence[tuple[float, float]],
    F_E: float,
    params: Mapping[str, float],
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The motion from rest at θ1 = theta1_0 under a piecewise constant thrust, segments =
    [(t_end, F_C), ...], friction model 2 with the Filippov rest rule: integrated in (θ1, ω1)
    on the loop closures (DOP853, rtol 1e-12), stopping at each zero of ω1 to decide between a
    slip through it and rest. Returns the sample times (every dt from dt on), x_B there and a
    flag that is 1 where the mechanism is at rest."""
    from scipy.integrate import solve_ivp

    pts = _points(params)
    times = np.arange(1, int(round(segments[-1][0] / dt)) + 1) * dt
    x_B = np.full(times.shape, np.nan)
    rest = np.zeros(times.shape)

    def record(t0: float, t1: float, theta1_of_t, at_rest: bool) -> None:
        sel = (times > t0 - 1e-12) & (times <= t1 + 1e-12)
        for i in np.flatnonzero(sel):
            x_B[i] = _pos(pts["B"], _closed_angles(float(theta1_of_t(times[i])), params))[0]
            rest[i] = 1.0 if at_rest else 0.0

    t, theta1, omega1, direction = 0.0, float(theta1_0), 0.0, 0.0
    for t_end, F_C in segments:
        while t < t_end - 1e-15:
            if direction == 0.0:  # at rest: leave only in the consistent direction
                direction = _leaving_direction(_closed_angles(theta1, params), F_C, F_E, params)
                if direction == 0.0:
                    held = theta1
                    record(t, t_end, lambda _t, held=held: held, True)
                    t = t_end
                    break

            def rhs(_t, y, direction=direction, F_C=F_C):
                q = _closed_angles(y[0], params)
                qdd, _ = reference_slip_accelerations(q, y[1], direction, F_C, F_E, params)
                return [y[1], qdd[0]]

            def reversal(_t, y, direction=direction):
                return direction * y[1]

            reversal.terminal, reversal.direction = True, -1
            sol = solve_ivp(
                rhs, (t, t_end), [theta1, omega1], method="DOP853", rtol=1e-12, atol=1e-15,
                dense_output=True, events=reversal,
            )  # fmt: skip
            record(t, sol.t[-1], lambda tt, sol=sol: sol.sol(tt)[0], False)
            t, theta1 = float(sol.t[-1]), float(sol.y[0, -1])
            if sol.status == 1:  # ω1 reached zero: slip through or rest, decided above
                omega1, direction = 0.0, 0.0
            else:
                omega1 = float(sol.y[1, -1])
    return times, x_B, rest


def reference_breakaway_thrust(
    q: Sequence[float], direction: float, F_E: float, params: Mapping[str, float], bracket: tuple[float, float]
) -> float:
    """The thrust F_C at which the mechanism at rest at q, slipping in `direction` (sgn(ω1)) under
    friction μ sgn(q̇_i) |R_i| (model 2, q̇ along the one admissible direction), has θ̈1 = 0: below
    it (direction +1) or above it (−1) the slip would decelerate at once, so a consistent
    stick-slip model holds the mechanism; found by bisection on `bracket`."""

    def alpha1(F_C: float) -> float:
        return float(reference_slip_accelerations(q, 0.0, direction, F_C, F_E, params)[0][0])

    lo, hi = bracket
    f_lo = alpha1(lo)
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if (alpha1(mid) > 0.0) == (f_lo > 0.0):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def reference_current_trajectory(
    theta1_0: float,
    iq_ref: Sequence[float],
    T_s: float,
    K: float,
    K_f: float,
    F_E: float,
    params: Mapping[str, float],
    rtol: float = 1e-11,
) -> tuple[np.ndarray, np.ndarray]:
    """The motion from rest at θ1 = theta1_0 with i_q(0) = 0 under friction model 2 and the
    Filippov rest rule, driven through the current loop di_q/dt = K (i_q* − i_q), F_C = K_f i_q,
    by the command iq_ref[k] held over [k T_s, (k + 1) T_s] (i_q solved exactly: an exponential
    per sample). Slipping in direction d, (θ1, ω1) is integrated (DOP853) to the sample's end or
    to ω1 = 0, where the consistent direction is chosen again; at rest, the mechanism leaves at
    the first instant a slip becomes consistent (d θ̈1(slip d) > 0, found by root finding on
    the exponential thrust). Returns x_B at every sample k = 0 .. len(iq_ref) and the rest flag."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    pts = _points(params)

    def x_B(theta1: float) -> float:
        return float(_pos(pts["B"], _closed_angles(theta1, params))[0])

    def alpha1(theta1: float, omega1: float, F_C: float, direction: float) -> float:
        q = _closed_angles(theta1, params)
        return float(reference_slip_accelerations(q, omega1, direction, F_C, F_E, params)[0][0])

    def leaving(theta1: float, F_C: float) -> float:
        ways = [d for d in (1.0, -1.0) if d * alpha1(theta1, 0.0, F_C, d) > 0.0]
        if len(ways) == 2:
            raise ValueError(f"both slips from rest are consistent at theta1 = {theta1} (a Painlevé-type case)")
        return ways[0] if ways else 0.0

    theta1, omega1, i_q, direction = float(theta1_0), 0.0, 0.0, 0.0
    xs, rest = [x_B(theta1)], [1.0]
    for k, command in enumerate(iq_ref):
        t_a, t_b = k * T_s, (k + 1) * T_s

        def thrust(t: float, i_a: float = i_q, t_a: float = t_a, u: float = float(command)) -> float:
            return K_f * (u + (i_a - u) * np.exp(-K * (t - t_a)))

        t = t_a
        while t < t_b - 1e-15:
            if direction == 0.0:
                direction = leaving(theta1, thrust(t))
                if direction == 0.0:

                    def cone(tt: float, held: float = theta1) -> float:
                        return max(d * alpha1(held, 0.0, thrust(tt), d) for d in (1.0, -1.0))

                    if cone(t_b) <= 0.0:
                        break  # held to the end of the sample
                    t = brentq(cone, t, t_b, xtol=1e-15, rtol=4e-16)
                    direction = 1.0 if alpha1(theta1, 0.0, thrust(t_b), 1.0) > 0.0 else -1.0

            def rhs(tt, y, d=direction):
                return [y[1], alpha1(y[0], y[1], thrust(tt), d)]

            def reversal(_t, y, d=direction):
                return d * y[1]

            reversal.terminal, reversal.direction = True, -1
            sol = solve_ivp(rhs, (t, t_b), [theta1, omega1], method="DOP853", rtol=rtol, atol=1e-14, events=reversal)
            t, theta1, omega1 = float(sol.t[-1]), float(sol.y[0, -1]), float(sol.y[1, -1])
            if sol.status == 1:  # ω1 reached zero: slip on or rest, decided above
                omega1, direction = 0.0, 0.0
        i_q = thrust(t_b) / K_f
        xs.append(x_B(theta1))
        rest.append(1.0 if direction == 0.0 else 0.0)
    return np.array(xs), np.array(rest)
