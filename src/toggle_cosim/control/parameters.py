"""The parameters of a control law as the law functions (and their C translation) read them:
one frozen dataclass of floats. Its fields are also the fields of the C struct `law_t` and of
its ctypes mirror, both generated from this class (`control.translate`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "LawParameters",
    "PAPER",
    "INTEGRAL",
    "OBJECTIVE_XB",
    "OBJECTIVE_THETA1",
    "STARTED",
    "described",
    "settable",
    "settable_values",
]

PAPER, INTEGRAL = 0.0, 1.0  # law codes
OBJECTIVE_XB, OBJECTIVE_THETA1 = 0.0, 1.0  # objective codes


def described(
    unit: str, description: str, minimum: float | None = None, maximum: float | None = None
) -> dict[str, Any]:
    """A field's metadata: its unit (Modelica syntax; "" where it depends on the objective, m for
    x_B and rad for θ1, or where there is none), a one-line description and the bounds of its
    valid values. The one place these are written: the controller FMU's parameter list and its
    documentation are generated from them."""
    return {"unit": unit, "description": description, "min": minimum, "max": maximum}


@dataclass(frozen=True)
class LawParameters:
    """Everything a law step reads, as floats. Each field's unit, description and bounds are
    its metadata (`described`).

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
        tracking: 0 the law regulates to `target`; 1 it tracks a trajectory (q*, q̇*, q̈*) given
            per sample (the laws take it as arguments; the controller FMU reads it from its
            inputs x_ref, v_ref, a_ref when tracking is 1).
    """

    law: float = field(
        metadata=described(
            "", "0 the paper's two-phase VSC, eqs. (19)-(25); 1 its integral-compensated variant", 0.0, 1.0
        )
    )
    objective: float = field(
        metadata=described(
            "", "0 the slider position x_B (reads x_B, v_B); 1 the lever angle theta1 (reads theta1, omega1)", 0.0, 1.0
        )
    )
    target: float = field(
        metadata=described("", "target of the objective: x_B* [m], or theta1* [rad] for the theta1 objective")
    )
    C: float = field(metadata=described("1/s", "slope of the sliding surface S = C e + de/dt, eq. (19)"))
    Q: float = field(
        metadata=described("", "reaching gain Q of eq. (19) [m/s2, or rad/s2 for the theta1 objective]", 0.0)
    )
    P: float = field(metadata=described("1/s", "proportional reaching gain P of eq. (19)", 0.0))
    delta: float = field(
        metadata=described("", "boundary layer delta of the sliding law, eq. (24) [m/s, or rad/s]", 0.0)
    )
    beta: float = field(metadata=described("", "gain beta of the sliding law, eq. (24) [m/s2, or rad/s2]"))
    C_I: float = field(metadata=described("1/s", "slope of the integral law's surface S = C_I e + de/dt + K_I z", 0.0))
    K_I: float = field(metadata=described("1/s2", "integral gain of the integral law", 0.0))
    i_max: float = field(metadata=described("A", "current limit of the integral law (its anti-windup acts there)", 0.0))
    T_s: float = field(metadata=described("s", "sample time (the integral law's integrator; a controller's step)", 0.0))
    K_f: float = field(metadata=described("N/A", "the controller's thrust constant, F_C = K_f iq_ref, eq. (16)", 0.0))
    t0: float = field(metadata=described("s", "time of the first sample"))
    T_h: float = field(metadata=described("s", "hitting time of eq. (21), from t0"))
    r1: float = field(metadata=described("m", "nominal lever arm O-A"))
    r3: float = field(metadata=described("m", "nominal length of link A-B"))
    r4: float = field(metadata=described("m", "nominal lever arm O-D"))
    r5: float = field(metadata=described("m", "nominal length of link D-C"))
    f: float = field(metadata=described("m", "nominal height of the guide of slider B"))
    h: float = field(metadata=described("m", "nominal height of the guide of slider C"))
    phi: float = field(metadata=described("rad", "nominal angle between the lever arms O-A and O-D"))
    m3: float = field(metadata=described("kg", "nominal mass of link A-B"))
    m5: float = field(metadata=described("kg", "nominal mass of link D-C"))
    mB: float = field(metadata=described("kg", "nominal mass of slider B"))
    mC: float = field(metadata=described("kg", "nominal mass of slider C"))
    J2: float = field(metadata=described("kg.m2", "nominal lever moment of inertia about O"))
    J3: float = field(metadata=described("kg.m2", "nominal centroidal inertia of link A-B, m3 r3^2/12"))
    J5: float = field(metadata=described("kg.m2", "nominal centroidal inertia of link D-C, m5 r5^2/12"))
    g: float = field(metadata=described("m/s2", "gravitational acceleration"))
    tracking: float = field(
        default=0.0,
        metadata=described(
            "", "0 the constant target; 1 a trajectory: the controller FMU reads x_ref, v_ref, a_ref", 0.0, 1.0
        ),
    )

    def __deepcopy__(self, memo: dict) -> LawParameters:
        """Itself: a frozen value of floats (a checkpoint of a controller's state keeps it as is)."""
        return self


# The fields the law's start sets at its first sample (`laws.law_start`): t0 and T_h. A law that
# runs on its own (the controller FMU) computes them; every other field is a setting.
STARTED = ("t0", "T_h")


def settable() -> tuple[str, ...]:
    """The LawParameters fields a law is given as settings (all but STARTED), in field order:
    the controller FMU's parameters."""
    return tuple(f.name for f in dataclasses.fields(LawParameters) if f.name not in STARTED)


def settable_values(law: LawParameters) -> tuple[tuple[str, float], ...]:
    """(name, value) of `law`'s settable fields, in field order."""
    return tuple((name, getattr(law, name)) for name in settable())


MECHANISM_FIELDS = ("r1", "r3", "r4", "r5", "f", "h", "phi", "m3", "m5", "mB", "mC", "J2", "g")


def mechanism_terms(mechanism: object) -> dict[str, float]:
    """The nominal mechanism's fields of LawParameters, from a `physics.parameters.
    MechanismParameters` (read by name): its geometry and masses, and the rods' centroidal
    inertias J = m r²/12 (uniform links 3 and 5, eq. (18))."""
    terms = {name: getattr(mechanism, name) for name in MECHANISM_FIELDS}
    terms["J3"] = terms["m3"] * terms["r3"] * terms["r3"] / 12.0
    terms["J5"] = terms["m5"] * terms["r5"] * terms["r5"] / 12.0
    return terms
