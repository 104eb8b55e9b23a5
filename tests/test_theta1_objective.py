"""The θ1 objective measures θ1: the law reads the plant's `theta1` and `omega1` (an encoder on the
lever), also past the folded position θ1 = −180°, where eq. (26) inverted on x_B gives the mirror
angle. Checked on `friction_models/theta1_external_force_stick_slip` (F_E = 100 N, stick-slip
friction), the run that goes past the fold:

* the recorded command is, at every sample, the two-phase VSC of eqs. (19)-(25) evaluated here
  independently from the plant's measured (θ1, ω1, θ2, θ5): f and G of θ̈1 = f + G u from
  `reference_dynamics` (point Jacobians, Schur complement; μ = 0, F_E = 0, the nominal masses),
  S0, T_h of eq. (21), the reaching law (23) and the sliding law (24), coded again below;
* the lever reaches θ1 = −204.28°, sticks at t = 1.0909 s and ends at x_B = 0.17040 m (the
  numbers an independent implementation of plant and controller gave; before the fix the law
  read the mirror angle, and the run stuck at t = 0.76 s at x_B = 0.195 m);
* a plant without `omega1` is refused for the θ1 objective before any run, in one line.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from reference_dynamics import reference_accelerations

from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.physics.mechanism import theta1_from_xB
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import MechanismParameters, MotorParameters
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.plant.settings import SettingError, check_settings

ROOT = Path(__file__).resolve().parent.parent
VARIANT = "theta1_external_force_stick_slip"


@pytest.fixture(scope="module")
def theta1_run(plant_fmu: Path):
    run = next(r for r in load_scenario(ROOT / "scenarios" / "friction_models.yaml") if r.variant == VARIANT)
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert outcome.complete, outcome.reason
    return run, outcome


def _independent_commands(run, trace) -> np.ndarray:
    """The θ1 VSC's command at every sample, from the plant's measured θ1, ω1, θ2, θ5."""
    nominal = MechanismParameters(mB=run.controller.nominal_m_B, mu=0.0)
    p, gains, K_f = nominal.as_dict(), run.controller.gains, thrust_constant(MotorParameters())
    target = theta1_from_xB(run.x_target, nominal)  # θ1* by eq. (26): the target is on the stroke's side
    commands = []
    T_h = None
    for row in zip(*(trace.column(n) for n in ("time", "theta1", "omega1", "theta2", "theta5")), strict=True):
        t, th1, w1, th2, th5 = (float(v) for v in row)
        # ω2, ω5 from the velocity constraints Φ̇1 = r1 cos θ1 ω1 + r3 cos θ2 ω2 = 0,
        # Φ̇2 = −r4 cos(θ1+φ) ω1 − r5 cos θ5 ω5 = 0
        w2 = -p["r1"] * math.cos(th1) * w1 / (p["r3"] * math.cos(th2))
        w5 = -p["r4"] * math.cos(th1 + p["phi"]) * w1 / (p["r5"] * math.cos(th5))
        q, qd = (th1, th2, th5), (w1, w2, w5)
        f = reference_accelerations(q, qd, 0.0, 0.0, p)[0][0]
        G = reference_accelerations(q, qd, K_f, 0.0, p)[0][0] - f  # θ̈1 per A
        e, edot = target - th1, -w1
        S = gains.C * e + edot
        if T_h is None:
            T_h = math.log(gains.P * abs(S) / gains.Q + 1.0) / gains.P  # eq. (21), from the first sample
        if t < T_h:  # eq. (23)
            u = (gains.C * edot + gains.P * S + gains.Q * np.sign(S) - f) / G
        else:  # eq. (24)
            u = (gains.C * edot + gains.beta * S / (abs(S) + gains.delta) - f) / G
        commands.append(u)
    return np.array(commands)


def test_the_command_is_the_law_on_the_measured_lever_angle(theta1_run) -> None:
    """At every one of the 3001 samples, before and past the fold, the recorded i_q* equals the
    independent evaluation to 1e-6 A (3.3e-8 A here; the recorded currents reach 131 A, and the
    law on the mirror angle differs by 1.3 A); at the samples past the
    fold the eq. (26) inversion of x_B is off by degrees, so a law reading it would differ there."""
    run, outcome = theta1_run
    trace = outcome.trace
    expected = _independent_commands(run, trace)
    got = trace.column("iq_ref")
    assert np.max(np.abs(got)) > 100.0
    assert np.max(np.abs(got - expected)) < 1e-6, np.max(np.abs(got - expected))  # 3.3e-8 A here
    theta1, x_B = trace.column("theta1"), trace.column("x_B")
    past = theta1 < -math.pi
    assert past.sum() > 400  # the lever is past the folded position for 467 samples (0.23 s) between 0.277 and 0.658 s
    nominal = MechanismParameters(mB=run.controller.nominal_m_B, mu=0.0)
    from_xB = np.array([theta1_from_xB(x, nominal) for x in x_B[past]])
    assert np.max(np.abs(from_xB - theta1[past])) > math.radians(40.0)  # the mirror angle


def test_the_lever_passes_the_fold_sticks_at_1_0909_s_and_ends_at_0_17040_m(theta1_run) -> None:
    run, outcome = theta1_run
    trace = outcome.trace
    t, x_B, v_B, theta1 = trace.time, trace.column("x_B"), trace.column("v_B"), trace.column("theta1")
    assert math.degrees(theta1.min()) == pytest.approx(-204.28, abs=0.01)
    held = np.flatnonzero(x_B != x_B[-1])[-1] + 1  # the first sample from which x_B stays put
    assert t[held] == pytest.approx(1.091, abs=1e-9)  # stuck by the sample at 1.091 s ...
    assert abs(v_B[held - 1]) > 1e-6  # ... still moving at 1.0905 s: it sticks in between (1.0909 s)
    assert np.all(np.abs(v_B[held:]) < 1e-12)
    assert x_B[-1] == pytest.approx(0.17040, abs=5e-6)
    assert math.degrees(theta1[-1]) == pytest.approx(-173.58, abs=0.01)


def test_a_plant_without_omega1_is_refused_for_the_theta1_objective(plant_fmu: Path) -> None:
    """The θ1 objective reads theta1 and omega1: a plant without omega1 is refused before the
    run, naming the key and the output; the x_B objective runs on it."""
    plant = check_plant(plant_fmu)
    without = dataclasses.replace(
        plant,
        references={k: v for k, v in plant.references.items() if k != "omega1"},
        absent=(*plant.absent, "omega1"),
    )
    run = next(r for r in load_scenario(ROOT / "scenarios" / "friction_models.yaml") if r.variant == VARIANT)
    with pytest.raises(
        SettingError,
        match=r"key controller\.objective: theta1 needs the plant outputs theta1 and omega1; .* lacks 'omega1'",
    ):
        check_settings(run, without)
    x_B = dataclasses.replace(run, controller=dataclasses.replace(run.controller, objective="x_B"))
    check_settings(x_B, without)
