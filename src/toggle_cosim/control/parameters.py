"""The parameters of a control law as the law functions (and their C translation) read them:
one frozen dataclass of floats. Its fields are also the fields of the C struct `law_t` and of
its ctypes mirror, both generated from this class (`control.translate`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["LawParameters", "PAPER", "INTEGRAL", "OBJECTIVE_XB", "OBJECTIVE_THETA1"]

PAPER, INTEGRAL = 0.0, 1.0  # law codes
OBJECTIVE_XB, OBJECTIVE_THETA1 = 0.0, 1.0  # objective codes


@dataclass(frozen=True)
class LawParameters:
    """Everything a law step reads, as floats.

    Attributes:
        law: 0 the paper's two-phase VSC, eqs. (19)-(25); 1 its integral-compensated variant.
        objective: 0 slider position x_B, 1 lever angle θ1.
        target: x_B* [m] or θ1* [rad].
        C, Q, P, delta, beta: the gains of eqs. (19)-(24).
        C_I: slope of the integral law's surface [1/s].
        K_I: integral gain of the integral law [1/s²].
        i_max: current limit of the integral law [A] (its anti-windup acts there).
        T_s: sample time [s] (the integral law's integrator).
        K_f: the controller's thrust constant [N/A].
        t0, T_h: first sample time and hitting time of eq. (21) [s].
        r1 .. g: the nominal mechanism; J3 = m3 r3²/12 and J5 = m5 r5²/12 as the nominal model
            evaluates them.
    """

    law: float
    objective: float
    target: float
    C: float
    Q: float
    P: float
    delta: float
    beta: float
    C_I: float
    K_I: float
    i_max: float
    T_s: float
    K_f: float
    t0: float
    T_h: float
    r1: float
    r3: float
    r4: float
    r5: float
    f: float
    h: float
    phi: float
    m3: float
    m5: float
    mB: float
    mC: float
    J2: float
    J3: float
    J5: float
    g: float


MECHANISM_FIELDS = ("r1", "r3", "r4", "r5", "f", "h", "phi", "m3", "m5", "mB", "mC", "J2", "g")


def mechanism_terms(mechanism: object) -> dict[str, float]:
    """The nominal mechanism's fields of LawParameters, from a `physics.parameters.
    MechanismParameters` (read by name): its geometry and masses, and the rods' centroidal
    inertias J = m r²/12 (uniform links 3 and 5, eq. (18))."""
    terms = {name: getattr(mechanism, name) for name in MECHANISM_FIELDS}
    terms["J3"] = terms["m3"] * terms["r3"] * terms["r3"] / 12.0
    terms["J5"] = terms["m5"] * terms["r5"] * terms["r5"] / 12.0
    return terms
