"""Parameters of the PMLSM, the toggle mechanism and the two-phase VSC.

Source: R.-F. Fung, J.-W. Wu, D.-S. Chen, "A variable structure control toggle mechanism
driven by a linear synchronous motor with joint Coulomb friction", J. Sound Vib. (2001),
referred to below as "the paper", and ``docs/model.md`` for the values the paper
does not give (its mechanism parameters come from its reference [8], which we do not have).

Every value marked **assumed** is our choice, not the paper's.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

__all__ = ["MotorParameters", "MechanismParameters", "ControllerGains"]


def _require(condition: bool, name: str, message: str) -> None:
    if not condition:
        raise ValueError(f"{name}: {message}")


def _check_finite(obj: object) -> None:
    for fld in fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, fld.name)
        if isinstance(value, (int, float)) and not math.isfinite(value):
            raise ValueError(f"{fld.name}: must be finite, got {value!r}")


@dataclass(frozen=True)
class MotorParameters:
    """Flat single-sided PMLSM of the paper's section 2.1 and section 4.

    All values except ``K`` are the paper's (section 4). The thrust constant
    ``K_f = F_C / i_q`` follows from eqs. (2), (13)-(16); see :func:`toggle_cosim.physics.motor.thrust_constant`.

    Attributes:
        tau: pole pitch τ [m].
        P_m: number of permanent-magnet poles P_m [-], eq. (12).
        B_r: remanent flux density of the magnets B_r [T], eq. (15).
        L_m: height of the PM poles L_m [m], eqs. (2), (14).
        alpha: pole width over pole pitch α = τ_p/τ [-], eq. (13); 0 < α ≤ 1.
        K_C: Carter's coefficient K_C [-], eq. (2).
        G: air gap between the PM poles and the stator G [m], eqs. (2), (14).
        L_A: width of the poles along z, L_A [m], eq. (12).
        K_w1: total winding factor K_w1 [-], eq. (2).
        gamma0: current load angle γ0 [rad], eq. (12).
        W: series turns per phase W [-], eq. (2).
        p: number of poles of the stator winding p [-], eq. (2).
        K: **assumed** meaning of the paper's undefined gain "K = 350": the bandwidth [rad/s] of
            the drive's current loop, di_q/dt = K (i_q* − i_q).
    """

    tau: float = 0.1143
    P_m: float = 2.0
    B_r: float = 0.86
    L_m: float = 0.00635
    alpha: float = 0.67
    K_C: float = 1.0
    G: float = 0.002
    L_A: float = 0.1016
    K_w1: float = 0.955
    gamma0: float = math.pi / 2
    W: float = 96.0
    p: float = 1.0
    K: float = 350.0

    def __post_init__(self) -> None:
        _check_finite(self)
        for name in ("tau", "P_m", "B_r", "L_m", "K_C", "G", "L_A", "K_w1", "W", "p", "K"):
            _require(getattr(self, name) > 0, name, f"must be positive, got {getattr(self, name)!r}")
        _require(0 < self.alpha <= 1, "alpha", f"must lie in (0, 1], got {self.alpha!r}")

    def as_dict(self) -> dict[str, float]:
        """The parameters as a plain dict (field name → value)."""
        return asdict(self)


@dataclass(frozen=True)
class MechanismParameters:
    """Geometry and inertia of the toggle mechanism (``docs/model.md``), eqs. (17), (18), (26).

    Geometry and inertia are **assumed** (the paper takes them from its reference [8], which is
    not available); ``mB`` (4.43 kg nominal, 8.86 kg in the paper's variation case) and ``mu``
    (0.2, the paper's upper bound for the joint Coulomb friction) are the paper's.

    Attributes:
        r1: lever arm O-A [m] (assumed 0.10).
        r3: length of link A-B [m] (assumed 0.27).
        r4: lever arm O-D [m] (assumed 0.10).
        r5: length of link D-C [m] (assumed 0.27).
        f: height of the guide of slider B [m] (assumed 0.0), eqs. (26) and Φ1.
        h: height of the guide of slider C [m] (assumed 0.10), Φ2.
        phi: angle between the lever arms O-A and O-D [rad] (assumed 166°).
        m2: lever mass [kg] (assumed 0.8; centre of mass at the pivot O, so no gravity torque).
        J2: lever moment of inertia about O [kg m²] (assumed 0.003).
        m3: mass of link A-B, a uniform rod [kg] (assumed 0.3).
        m5: mass of link D-C, a uniform rod [kg] (assumed 0.3).
        mB: mass of slider B [kg] (paper: 4.43 nominal).
        mC: mass of slider C, the PMLSM mover [kg] (assumed 1.5).
        g: gravitational acceleration along −y [m/s²].
        mu: joint dry-friction coefficient of eq. (17) [-] (paper: 0.2; 0 = no friction).
    """

    r1: float = 0.10
    r3: float = 0.27
    r4: float = 0.10
    r5: float = 0.27
    f: float = 0.0
    h: float = 0.10
    phi: float = math.radians(166.0)
    m2: float = 0.8
    J2: float = 0.003
    m3: float = 0.3
    m5: float = 0.3
    mB: float = 4.43
    mC: float = 1.5
    g: float = 9.81
    mu: float = 0.2

    def __post_init__(self) -> None:
        _check_finite(self)
        for name in ("r1", "r3", "r4", "r5"):
            _require(getattr(self, name) > 0, name, f"length must be positive, got {getattr(self, name)!r}")
        for name in ("m2", "m3", "m5", "mB", "mC"):
            _require(getattr(self, name) > 0, name, f"mass must be positive, got {getattr(self, name)!r}")
        _require(self.J2 > 0, "J2", f"moment of inertia must be positive, got {self.J2!r}")
        _require(self.g >= 0, "g", f"must be non-negative, got {self.g!r}")
        _require(self.mu >= 0, "mu", f"friction coefficient must be non-negative, got {self.mu!r}")

    @property
    def J3(self) -> float:
        """Moment of inertia of link A-B about its centre, m3 r3²/12 (uniform rod)."""
        return self.m3 * self.r3**2 / 12.0

    @property
    def J5(self) -> float:
        """Moment of inertia of link D-C about its centre, m5 r5²/12 (uniform rod)."""
        return self.m5 * self.r5**2 / 12.0

    def as_dict(self) -> dict[str, float]:
        """Plain dict with keys r1 r3 r4 r5 f h phi m2 J2 m3 m5 mB mC g mu (the API of
        ``tests/reference_dynamics.py``)."""
        return asdict(self)


@dataclass(frozen=True)
class ControllerGains:
    """Gains of the two-phase VSC, eqs. (19)-(25); values from the paper's section 4.

    Attributes:
        C: slope of the switching function S = C e + ė [1/s].
        Q: constant-rate reaching gain of eq. (19), Ṡ = −Q sgn(S) − P S.
        P: proportional reaching gain of eq. (19) [1/s].
        delta: boundary-layer width δ of the smoothing function of eq. (24).
        beta: gain β of the smoothing function β S/(|S| + δ) of eq. (24).
    """

    C: float = 5.0
    Q: float = 4.0
    P: float = 50.0
    delta: float = 0.25
    beta: float = 65.0

    def __post_init__(self) -> None:
        _check_finite(self)
        for name in ("C", "Q", "P", "delta", "beta"):
            _require(getattr(self, name) > 0, name, f"gain must be positive, got {getattr(self, name)!r}")

    def as_dict(self) -> dict[str, float]:
        """The gains as a plain dict."""
        return asdict(self)
