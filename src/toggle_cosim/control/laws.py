"""The control laws, defined once: one sample of the paper's two-phase VSC, eqs. (19)-(25),
and of its integral-compensated variant (docs/controllers.md, "An integral-compensated VSC").

`law_step` (and `law_start`, the first sample's start) is the single definition every loop runs:
`controller.VSCController` calls them in Python; the compiled loop and the controller FMU
(`controller_fmu`) run their C translation (`control.translate`), which evaluates the same
operations in the same order, so all give the same bits. Written in the translator's
subset: floats and `LawParameters`, local assignments, if/else, tuple returns, math.* calls,
abs, raise ValueError.
"""

from __future__ import annotations

import math

from toggle_cosim.control.nominal import nominal_reduced, theta1_omega1
from toggle_cosim.control.parameters import LawParameters

__all__ = ["error_terms", "hitting_time", "law_start", "law_step"]


def error_terms(q: float, qd: float, r: float, rd: float, p: LawParameters) -> tuple[float, float, float, float]:
    """(e, ė, f, G) for the objective, from its own measured coordinate q and rate qd and the
    reference r = q*(t), rd = q̇*(t) (`control.trajectory`; a constant target: r = p.target,
    rd = 0): e = q* − q, ė = q̇* − q̇ and the nominal plant q̈ = f + G u (u = i_q*; eq. (18) with
    μ = 0, F_E = 0 and F_C = K_f u).

    For x_B (q, qd = x_B, v_B): θ1, ω1 from (x_B, v_B) by eq. (26), valid for −180° < θ1 < 0,
    f = a_B(F_C = 0) = dx_B/dθ1 θ̈1(0) + b_B, G = K_f dx_B/dθ1 ∂θ̈1/∂F_C.
    For θ1 (q, qd = θ1, ω1, measured on the lever): f = θ̈1(0), G = K_f ∂θ̈1/∂F_C, at any θ1.
    """
    if p.objective == 0.0:
        t1, w1 = theta1_omega1(q, qd, p)
        acc0, dacc, dxB, bB = nominal_reduced(t1, w1, p)
        return r - q, rd - qd, dxB * acc0 + bB, p.K_f * dxB * dacc
    acc0, dacc, dxB, bB = nominal_reduced(q, qd, p)
    return r - q, rd - qd, acc0, p.K_f * dacc


def hitting_time(S0: float, P: float, Q: float) -> float:
    """Hitting time of the reaching law Ṡ = −Q sgn(S) − P S from S(t0) = S0, eq. (21):
    T_h = (1/P) ln(P |S0|/Q + 1) [s]."""
    return math.log(P * abs(S0) / Q + 1.0) / P


def law_start(q: float, qd: float, r: float, rd: float, p: LawParameters) -> tuple[float, float, float]:
    """The first sample's start of the law from the objective's measured coordinate and rate
    and the reference (r, rd) = (q*, q̇*) at t0: (S(t0), T_h, z0).

    Paper (p.law = 0): S0 = C e + ė, z0 = 0.
    Integral (p.law = 1): S = C_I e + ė + K_I z starts on the surface when K_I > 0, with
    z0 = −(C_I e0 + ė0)/K_I and S0 = 0 (eq. (21) then gives T_h = 0 and the error follows
    ë + C_I ė + K_I e = 0 from t0; docs/controllers.md, "An integral-compensated VSC").
    Hitting time, eq. (21): T_h = (1/P) ln(P |S0|/Q + 1).
    """
    e, edot, f, G = error_terms(q, qd, r, rd, p)
    z0 = 0.0
    if p.law == 0.0:
        S0 = p.C * e + edot
    else:
        S0 = p.C_I * e + edot
        if p.K_I > 0.0:
            z0 = -S0 / p.K_I
            S0 = 0.0  # on the surface by construction (up to rounding in the last bit)
    return S0, hitting_time(S0, p.P, p.Q), z0


def law_step(
    t: float, q: float, qd: float, z: float, r: float, rd: float, rdd: float, p: LawParameters
) -> tuple[float, float, float, float, float]:
    """One controller sample at time t from the objective's measured coordinate and rate (q, qd:
    x_B and v_B, or θ1 and ω1), the integrator state z and the reference at t: r = q*, rd = q̇*,
    rdd = q̈* (`control.trajectory`; a constant target: p.target, 0, 0).

    Tracking: with e = q* − q and ė = q̇* − q̇, ë = q̈* − q̈ = q̈* − f − G u on the nominal plant,
    so the surface's Ṡ = C ė + ë of eqs. (19)-(20) is Ṡ = C ė + q̈* − f − G u, and the
    equivalent control that imposes eq. (19) (or eq. (24)'s sliding law) gains q̈*/G: each u
    below is eqs. (23)-(25) with + q̈* inside the bracket (docs/controllers.md, "Tracking a
    trajectory"). With q̇* = q̈* = 0 the operations are today's (x + 0.0 = x).

    Paper (p.law = 0), with S = C e + ė:
        reaching (t − t0 < T_h), eq. (23): u = G⁻¹ (C ė + P S + Q sgn(S) − f + q̈*)
        sliding, eq. (24):                  u = G⁻¹ (C ė + β S/(|S| + δ) − f + q̈*)
    Integral (p.law = 1), with z = ∫e dt and S = C_I e + ė + K_I z:
        reaching: u = G⁻¹ (C_I ė + K_I e + P S + Q sgn(S) − f + q̈*)
        sliding:  u = G⁻¹ (C_I ė + K_I e + β S/(|S| + δ) − f + q̈*)
        then u is clipped to ±i_max, and z integrates e (z + T_s e) only while u is not clipped,
        or while e drives u back inside the limit (conditional integration, the anti-windup).

    Returns (u = i_q* [A], S, phase (0 reaching, 1 sliding), e, z at the next sample).
    """
    e, edot, f, G = error_terms(q, qd, r, rd, p)
    reaching = t - p.t0 < p.T_h
    if p.law == 0.0:
        S = p.C * e + edot
        if reaching:
            sg = 1.0 if S > 0.0 else (-1.0 if S < 0.0 else 0.0)
            u = (p.C * edot + p.P * S + p.Q * sg - f + rdd) / G
            return u, S, 0.0, e, z
        u = (p.C * edot + p.beta * S / (abs(S) + p.delta) - f + rdd) / G
        return u, S, 1.0, e, z
    S = p.C_I * e + edot + p.K_I * z
    if reaching:
        sg = 1.0 if S > 0.0 else (-1.0 if S < 0.0 else 0.0)
        u = (p.C_I * edot + p.K_I * e + p.P * S + p.Q * sg - f + rdd) / G
        phase = 0.0
    else:
        u = (p.C_I * edot + p.K_I * e + p.beta * S / (abs(S) + p.delta) - f + rdd) / G
        phase = 1.0
    z_next = z + p.T_s * e
    if u > p.i_max:
        u = p.i_max
        if e * G > 0.0:  # more error would push u further above the limit: hold the integrator
            z_next = z
    elif u < -p.i_max:
        u = -p.i_max
        if e * G < 0.0:
            z_next = z
    return u, S, phase, e, z_next
