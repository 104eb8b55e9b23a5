"""Painlevé-type inconsistency of the coupled joint frictions (issue 33): where the slip equations
of eq. (18) with the friction of eq. (17) become singular, no consistent friction mode exists.

The slip equations at a point are linear in (q̈, λ) with the matrix
S(μ, s) = [[M, Φ_qᵀ + Q_fᵀ(μ, s)], [Φ_q, 0]], Q_fᵀ = μ diag(s) [∂x_B/∂q, −∂x_C/∂q], s_i = ±1 the
friction sign of joint i (sgn(q̇_i) under `paper`, sgn(q̇_i) sgn(R_i) under `dissipative` and a
slipping `stick_slip`). ρ = det S(μ, s) / det S(0) is 1 without friction. Raising μ from 0, the
slip equations keep one solution while ρ > 0; where ρ reaches 0 they become singular, and beyond
it the mode's acceleration answers its drive with the wrong sign (Painlevé's paradox: a slip
mode with no consistent solution, or two).
Evaluated with the independent `reference_dynamics` (numpy only), over the working range of
slider B (0.18 to 0.36 m, clear of the toggle's two dead points) for the nominal and the doubled
mass of slider B, and all eight sign patterns.
"""

from __future__ import annotations

import dataclasses
import itertools
import re
from pathlib import Path

import numpy as np
import pytest
from reference_dynamics import _closed_angles, _model

from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.physics.parameters import MechanismParameters
from toggle_cosim.plant.contract import check_plant

SIGNS = list(itertools.product((1.0, -1.0), repeat=3))


def _rho(theta1: float, mu: float, signs, params) -> float:
    """det S(μ, s) / det S(0) at θ1 on the loop closures."""
    params = dict(params, mu=mu)
    d = _model(_closed_angles(theta1, params), np.zeros(3), 0.0, 0.0, params, np.asarray(signs))
    M, Phi_q, QfT = d["M"], d["Phi_q"], d["QfT"]
    zero = np.zeros((2, 2))
    with_friction = np.block([[M, Phi_q.T + QfT], [Phi_q, zero]])
    without = np.block([[M, Phi_q.T], [Phi_q, zero]])
    return float(np.linalg.det(with_friction) / np.linalg.det(without))


def _worst(mu: float, m_B: float, points: int = 91) -> float:
    """The smallest ρ over the working range of x_B and the eight sign patterns."""
    params = MechanismParameters(mB=m_B, mu=mu).as_dict()
    r1, r3 = params["r1"], params["r3"]
    x_B = np.linspace(0.18, 0.36, points)
    theta1 = np.arcsin((x_B**2 + r1**2 - r3**2) / (2 * r1 * x_B)) - np.pi / 2  # eq. (26), f = 0
    return min(_rho(t, mu, s, params) for t in theta1 for s in SIGNS)


@pytest.mark.parametrize("m_B", [4.43, 8.86])
def test_up_to_mu_0_3_every_friction_mode_is_consistent_in_the_working_range(m_B: float) -> None:
    """μ ≤ 0.3 (the shipped range): ρ stays above 0.7 (0.76 at μ = 0.3, near x_B = 0.197 m), so
    no coupling of the joint frictions makes a slip mode singular: Painlevé cannot occur."""
    assert _worst(0.3, m_B) > 0.7


@pytest.mark.parametrize("m_B", [4.43, 8.86])
def test_at_mu_2_a_friction_mode_is_inconsistent(m_B: float) -> None:
    """The criterion is not vacuous: at μ = 2 (a constructed case, far outside the shipped range)
    some sign pattern makes ρ negative in the working range."""
    assert _worst(2.0, m_B, points=46) < 0.0


HOLD_MODULE = """
from toggle_cosim.control.protocol import ControlStep


class Hold:
    diagnostics = ()

    def __init__(self, command):
        self.command = command

    def start(self, t0, measurement):
        return None

    def step(self, state, t, measurement):
        return ControlStep(command=self.command, diagnostics=(), state=None)


def make_hold(context, command):
    return Hold(command)
"""


def test_the_fmu_fails_in_one_line_where_no_friction_mode_is_consistent(plant_fmu: Path, tmp_path: Path) -> None:
    """A constructed Painlevé case: μ = 2 (outside the scenario's range, set on the run), the
    paper's model, slider B at 0.28 m driven backward (ρ = −0.185 for the signs of that slip).
    The run fails at its first motion with one line naming the case, the guard and the time,
    where it used to chatter (a Zeno failure that said nothing of why)."""
    tmp_path.chmod(0o700)
    (tmp_path / "hold.py").write_text(HOLD_MODULE)
    scenario = tmp_path / "painleve.yaml"
    scenario.write_text(
        "name: painleve\nt_end: 0.01\nT_s: 0.0005\nstroke: {x_start: 0.28, x_target: 0.3199}\n"
        "plant: {F_E: 0.0, m_B: 4.43, mu: 0.2, friction_model: paper, current_loop: ideal}\n"
        'controller: {python: "hold:make_hold", parameters: {command: -5.0}}\n'
    )
    (run,) = load_scenario(scenario)
    run = dataclasses.replace(run, plant=dataclasses.replace(run.plant, mu=2.0))
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert not outcome.complete
    assert "\n" not in outcome.reason
    assert "Painleve-type case" in outcome.reason and "joints theta1, theta2, theta5" in outcome.reason
    assert re.search(r"at t=[0-9.e-]+ s: mechanism\.guardSlip = -0\.18\d+ is not positive", outcome.reason)


def test_the_fmus_guard_is_the_determinant_ratio_of_the_independent_reference(plant_fmu: Path) -> None:
    """mechanism.guardSlip, read from the FMU while it slips backward at μ = 0.3 under the paper's
    model, equals ρ of `reference_dynamics` for the FMU's angle and friction signs to 1e-9."""
    from test_plant_fmu import Plant

    plant = Plant(plant_fmu, frictionModel=1, mu=0.3, idealCurrentLoop=True, iq_ref=-5.0, F_E=0.0, x_B0=0.28)
    try:
        for _ in range(20):
            plant.step(1e-3)
        theta1, s1, s2, s5, guard = plant.get(
            "theta1", "mechanism.sgn1", "mechanism.sgn2", "mechanism.sgn5", "mechanism.guardSlip"
        )
    finally:
        plant.close()
    params = MechanismParameters(mB=4.43, mu=0.3).as_dict()
    assert s1 == -1.0 and guard != 1.0
    assert abs(guard - _rho(theta1, 0.3, (s1, s2, s5), params)) < 1e-9


GUARD_DEMO = """model GuardDemo "A guard that a when clause turns negative at x = 0.5"
  Real x(start = 1.0, fixed = true);
  discrete Real mode(start = 1.0);
  Real guardMode "the demo's mode is inconsistent";
equation
  der(x) = -1.0;
  when x < 0.5 then
    mode = -1.0;
  end when;
  guardMode = mode;
end GuardDemo;
"""


def test_a_guard_of_any_model_fails_the_step_after_the_event_that_makes_it_negative(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shell's guard is generic: a model's variable named guard* (here of a one-state model,
    no mechanism) is checked after each event; the step in which x crosses 0.5 fails, logging
    the guard's description, the time of the event and the guard's value (fmpy prints the FMU's
    log), and the step before it passes."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from toggle_cosim.fmu_export import build_fmu

    source = tmp_path / "GuardDemo.mo"
    source.write_text(GUARD_DEMO)
    fmu = build_fmu(source, "GuardDemo", tmp_path / "GuardDemo.fmu", interfaces="cs").fmu.path
    description = read_model_description(str(fmu))
    slave = FMU2Slave(
        guid=description.guid,
        unzipDirectory=extract(str(fmu), unzipdir=str(tmp_path / "unzipped")),
        modelIdentifier=description.coSimulation.modelIdentifier,
        instanceName="demo",
    )
    slave.instantiate(loggingOn=False)
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.doStep(0.0, 0.25)  # no event
        with pytest.raises(Exception, match="status 3"):
            slave.doStep(0.25, 0.5)  # x crosses 0.5 at t = 0.5
    finally:
        slave.freeInstance()
    logged = capsys.readouterr().out
    assert re.search(
        r"the demo's mode is inconsistent at t=0\.5\d* s: guardMode = -1 is not positive after the events there",
        logged,
    ), logged
