"""Discrete two-phase variable-structure controller, eqs. (19)-(25) of the paper.

Switching function S = C e + ė with e = x* − x (constant target, so ė = −ẋ; with a reference
trajectory (`reference`, `control.trajectory`) e = x*(t) − x, ė = ẋ*(t) − ẋ and ẍ*(t) enters the
equivalent control: `control.laws.law_step`). The nominal plant
ẍ = f + G u + d with u = i_q* is the controller's own model of the mechanism (μ = 0, F_E = 0,
nominal masses, ideal current loop, d = 0); it never sees the true plant's parameters.

* Reaching phase (r = 1 while t − t0 < T_h), eq. (23):
  u_r = G⁻¹ (C ė + P S + Q sgn(S) − f − d), which imposes Ṡ = −Q sgn(S) − P S, eq. (19).
* Sliding phase (r = 0 afterwards), eq. (24): u_s = G⁻¹ (C ė + β S/(|S| + δ) − f − d).
* Hitting time, eq. (21): T_h = (1/P) ln(P |S(t0)|/Q + 1), with S(t0) from the first sample.
* u = r u_r + (1 − r) u_s, eq. (25).

The controller is discrete and meets the controller protocol (`control.protocol`): the
co-simulation master calls :meth:`VSCController.start` at the first sample and
:meth:`VSCController.step` at each sample with the plant's outputs by name, and holds u until
the next sample. The law itself is `control.laws.law_step` (pure floats, the one definition
the compiled loop is generated from); this class validates the settings and keeps what the
law reads in a `LawParameters`. Its diagnostics, recorded in the trace, are S, phase
(0 reaching, 1 sliding) and e.

Law "integral" (``law="integral"``): the integral-compensated variant, S = C e + ė + K_I ∫e dt,
with the current clipped to ±i_max and conditional integration as anti-windup (docs/controllers.md).

Objectives: "x_B" (default; the paper's section 4: "regulate the position of slider B"), which
reads the plant's x_B and v_B, and "theta1" (the lever angle, as eq. (26) hints), which reads
the plant's theta1 and omega1 (an encoder on the lever): e = θ1* − θ1, with θ1* from the slider
target by eq. (26). In both cases ``target`` is the slider-B target position x_B* [m].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import ClassVar, Literal

from toggle_cosim.control import laws
from toggle_cosim.control.laws import error_terms, law_start, law_step
from toggle_cosim.control.parameters import (
    INTEGRAL,
    OBJECTIVE_THETA1,
    OBJECTIVE_XB,
    PAPER,
    LawParameters,
    mechanism_terms,
)
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.control.trajectory import SampledReference
from toggle_cosim.physics.mechanism import theta1_from_xB
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import ControllerGains, MechanismParameters, MotorParameters

__all__ = ["VSCController", "ControllerState", "ControlOutput", "MEASURED", "diagnostic_units", "hitting_time"]

Objective = Literal["x_B", "theta1"]
Law = Literal["paper", "integral"]
Phase = Literal["reaching", "sliding"]
MEASURED = {"x_B": ("x_B", "v_B"), "theta1": ("theta1", "omega1")}  # the plant outputs each objective reads


def diagnostic_units(objective: str, plant_units: Mapping[str, str]) -> dict[str, str]:
    """The units of the built-in law's diagnostics columns from the plant's units: e = target −
    measured (eqs. (19), (26)) in the unit of the variable the objective regulates, S = C e + ė in
    the unit of its rate (or the measured unit per second where the plant has no rate), and the
    phase r of eq. (25) a pure number, "1". A unit the plant does not give is left out."""
    measured, rate = MEASURED.get(objective, MEASURED["x_B"])
    units = {"phase": "1"}
    if measured in plant_units:
        units["e"] = plant_units[measured]
    if rate in plant_units:
        units["S"] = plant_units[rate]
    elif measured in plant_units:
        units["S"] = f"{plant_units[measured]}/s"
    return units


def hitting_time(S0: float, gains: ControllerGains) -> float:
    """Hitting time of the reaching law Ṡ = −Q sgn(S) − P S, eq. (21):
    T_h = (1/P) ln(P |S(t0)|/Q + 1) (`control.laws.hitting_time`)."""
    return laws.hitting_time(S0, gains.P, gains.Q)


@dataclass(frozen=True)
class ControllerState:
    """What the controller remembers from :meth:`VSCController.start`.

    Attributes:
        t0: time of the first sample [s].
        S0: S(t0), the switching function at the first sample (m/s or rad/s).
        T_h: hitting time of eq. (21), measured from t0 [s].
        law: what `control.laws.law_step` reads (the settings, t0 and T_h).
        z: the law's state at the sample the state is given to, ∫e dt of the integral law
            (0 for the paper's law).
    """

    t0: float
    S0: float
    T_h: float
    law: LawParameters | None = None
    z: float = 0.0

    def __deepcopy__(self, memo: dict) -> ControllerState:
        """Itself: a frozen value of floats and frozen parameters (a checkpoint keeps it as is)."""
        return self


@dataclass(frozen=True)
class ControlOutput(ControlStep):
    """One sample of the VSC: the protocol's command, diagnostics (S, phase, e) and next state,
    with what they were computed from.

    Attributes:
        command: control input u = i_q* [A], eq. (25).
        diagnostics: (S, phase, e): S = C e + ė (integral law: C_I e + ė + K_I z), phase 0
            reaching (r = 1, eq. (23)) or 1 sliding (r = 0, eq. (24)), e = q* − q (m, or rad for
            the θ1 objective).
        state: the controller's state at the next sample (z: ∫e dt of the integral law).
        q, qd: the sample's measured coordinate and rate (x_B, v_B or θ1, ω1).
        law: the law's parameters, from which edot, f and G are evaluated on demand (the
            master's loop never needs them).
        reference: the sample's (q*, q̇*, q̈*) when the law tracks a trajectory (None: the
            constant target, law.target).
    """

    q: float = 0.0
    qd: float = 0.0
    law: LawParameters | None = field(default=None, repr=False)
    reference: tuple[float, float, float] | None = field(default=None, repr=False)

    def _terms(self) -> tuple[float, float, float, float]:
        r, rd = (self.law.target, 0.0) if self.reference is None else self.reference[:2]
        return error_terms(self.q, self.qd, r, rd, self.law)

    @property
    def u(self) -> float:
        """i_q* [A]."""
        return self.command

    @property
    def S(self) -> float:
        """Switching function."""
        return self.diagnostics[0]

    @property
    def phase(self) -> Phase:
        """ "reaching" (r = 1, eq. (23)) or "sliding" (r = 0, eq. (24))."""
        return "reaching" if self.diagnostics[1] == 0.0 else "sliding"

    @property
    def e(self) -> float:
        """Tracking error e = q* − q."""
        return self.diagnostics[2]

    @property
    def z(self) -> float:
        """The law's state at the next sample."""
        return self.state.z

    @property
    def edot(self) -> float:
        """ė = q̇* − q̇."""
        return self._terms()[1]

    @property
    def f(self) -> float:
        """Drift of the nominal model (m/s² or rad/s²)."""
        return self._terms()[2]

    @property
    def G(self) -> float:
        """Input gain of the nominal model (m/s² per A or rad/s² per A)."""
        return self._terms()[3]


@dataclass(frozen=True)
class VSCController:
    """Two-phase VSC of eqs. (19)-(25) on a nominal model of the mechanism.

    Attributes:
        gains: C, Q, P, δ, β of eqs. (19)-(24).
        nominal: the controller's nominal mechanism (its ``mu`` is ignored: the nominal model has
            no friction); the plant may differ (m_B, F_E, μ): that is the robustness test.
        K_f: the controller's thrust constant [N/A], u = i_q* → F_C = K_f u (default: eq. (16)
            with the paper's motor parameters).
        target: slider-B target position x_B* [m] (also for the θ1 objective, via eq. (26)).
        objective: "x_B" (default) or "theta1".
        law: "paper" (default; eqs. (19)-(25)) or "integral" (docs/controllers.md, "An integral-compensated VSC").
        C_I: slope of the integral law's surface S = C_I e + ė + K_I ∫e dt [1/s].
        K_I: integral gain of the integral law [1/s²]; C_I = 2λ, K_I = λ² put a double pole at −λ.
        i_max: current limit of the integral law [A].
        T_s: sample time [s] (the integral law's integrator).
        reference: the trajectory the law tracks, sampled on the run's grid
            (`control.trajectory`; x_B objective only); None: the constant `target`.
    """

    diagnostics: ClassVar[tuple[str, ...]] = ("S", "phase", "e")

    gains: ControllerGains = field(default_factory=ControllerGains)
    nominal: MechanismParameters = field(default_factory=lambda: MechanismParameters(mu=0.0))
    K_f: float = field(default_factory=lambda: thrust_constant(MotorParameters()))
    target: float = 0.3199
    objective: Objective = "x_B"
    law: Law = "paper"
    C_I: float = 16.0
    K_I: float = 64.0
    i_max: float = 10.0
    T_s: float = 0.0005
    reference: SampledReference | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.objective not in ("x_B", "theta1"):
            raise ValueError(f"objective: must be 'x_B' or 'theta1', got {self.objective!r}")
        if self.law not in ("paper", "integral"):
            raise ValueError(f"law: must be 'paper' or 'integral', got {self.law!r}")
        if not (self.C_I > 0 and math.isfinite(self.C_I)):
            raise ValueError(f"C_I: must be positive and finite, got {self.C_I!r}")
        if not (self.K_I >= 0 and math.isfinite(self.K_I)):
            raise ValueError(f"K_I: must be non-negative and finite, got {self.K_I!r}")
        if not self.i_max > 0:
            raise ValueError(f"i_max: must be positive, got {self.i_max!r}")
        if not (self.K_f > 0 and math.isfinite(self.K_f)):
            raise ValueError(f"K_f: must be positive and finite, got {self.K_f!r}")
        theta1_from_xB(self.target, self.nominal)  # raises ValueError if out of reach
        if self.reference is not None and self.objective != "x_B":
            raise ValueError("reference: a trajectory is tracked by the x_B objective only (use objective x_B)")

    def reference_at(self, t: float, law: LawParameters) -> tuple[float, float, float]:
        """(q*, q̇*, q̈*) at t: the sampled trajectory's, or (target, 0, 0) for a constant target."""
        return (law.target, 0.0, 0.0) if self.reference is None else self.reference.at(t)

    @property
    def target_theta1(self) -> float:
        """θ1* from the slider target by eq. (26), with the nominal geometry [rad]."""
        return theta1_from_xB(self.target, self.nominal)

    def law_parameters(self, t0: float = 0.0, T_h: float = 0.0) -> LawParameters:
        """What `control.laws.law_step` reads, with the first sample's t0 and T_h."""
        p, gn = self.nominal, self.gains
        return LawParameters(
            law=PAPER if self.law == "paper" else INTEGRAL,
            objective=OBJECTIVE_XB if self.objective == "x_B" else OBJECTIVE_THETA1,
            target=self.target if self.objective == "x_B" else self.target_theta1,
            C=float(gn.C),
            Q=float(gn.Q),
            P=float(gn.P),
            delta=float(gn.delta),
            beta=float(gn.beta),
            C_I=float(self.C_I),
            K_I=float(self.K_I),
            i_max=float(self.i_max),
            T_s=float(self.T_s),
            K_f=float(self.K_f),
            t0=float(t0),
            T_h=float(T_h),
            **mechanism_terms(p),
            tracking=0.0 if self.reference is None else 1.0,
        )

    @property
    def measured(self) -> tuple[str, str]:
        """The plant outputs the law reads: (x_B, v_B), or (theta1, omega1) for the θ1 objective."""
        return MEASURED[self.objective]

    def switching_function(self, q: float, qd: float) -> float:
        """S = C e + ė for the measured coordinate and rate (with ∫e dt = 0, as at the first sample)."""
        law = self.law_parameters()
        r, rd, _ = self.reference_at(0.0, law)
        e, edot, _, _ = error_terms(q, qd, r, rd, law)
        return self.gains.C * e + edot

    def start(self, t0: float, measurement: Mapping[str, float]) -> ControllerState:
        """Initialise at the first sample: S(t0), the hitting time T_h of eq. (21) and the
        integral law's z(t0) (`control.laws.law_start`).

        Args:
            t0: time of the first sample [s].
            measurement: the plant's outputs at t0 by name; the law reads `measured`
                (x_B [m] and v_B [m/s], or theta1 [rad] and omega1 [rad/s]).
        """
        missing = [name for name in self.measured if name not in measurement]
        if missing:
            raise ValueError(
                f"the {self.objective} objective reads the plant outputs {' and '.join(self.measured)};"
                f" the measurement has no {missing[0]}"
            )
        q, qd = (float(measurement[name]) for name in self.measured)
        law = self.law_parameters()
        r, rd, _ = self.reference_at(float(t0), law)
        S0, T_h, z0 = law_start(q, qd, r, rd, law)
        return ControllerState(t0=float(t0), S0=S0, T_h=T_h, law=self.law_parameters(float(t0), T_h), z=z0)

    def phase(self, state: ControllerState, t: float) -> Phase:
        """r of eq. (25): "reaching" while t − t0 < T_h, "sliding" afterwards."""
        return "reaching" if t - state.t0 < state.T_h else "sliding"

    def step(self, state: ControllerState, t: float, measurement: Mapping[str, float]) -> ControlOutput:
        """Control input u = i_q* [A] for the sample at time t, eqs. (23)-(25) with d = 0
        (`control.laws.law_step`).

        Args:
            state: from :meth:`start`, or the previous step's ``state``.
            t: sample time [s].
            measurement: the plant's outputs at t by name (the law reads `measured`).

        Returns:
            the command, the diagnostics (S, phase, e) and the state at the next sample.
        """
        coordinate, rate = self.measured
        q, qd = float(measurement[coordinate]), float(measurement[rate])
        law = state.law if state.law is not None else self.law_parameters(state.t0, state.T_h)
        if self.reference is None:
            u, S, phase, e, z_next = law_step(t, q, qd, state.z, law.target, 0.0, 0.0, law)
            reference = None
        else:
            reference = self.reference.at(t)
            u, S, phase, e, z_next = law_step(t, q, qd, state.z, *reference, law)
        following = state if z_next == state.z else replace(state, z=z_next)
        return ControlOutput(
            command=u, diagnostics=(S, phase, e), state=following, q=q, qd=qd, law=law, reference=reference
        )
