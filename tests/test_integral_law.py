"""The integral-compensated VSC (controller.law: integral) on the plant FMU.

Physics checked:
* on the nominal plant (μ = 0, F_E = 0, m_B = 4.43 kg, ideal current loop), where the
  controller's model is exact, the slider follows the designed error dynamics
  ë + C_I ė + K_I e = 0 from e(t0) = e0, ė(t0) = 0: with C_I = 2λ, K_I = λ², λ = 8/s,
  e(t) = e0 (1 + λt) e^(−λt), to 0.1 mm (the law started anywhere else, or a wrong surface,
  is off by millimetres);
* over the map F_E 0–150 N × m_B 4.43–8.86 kg with μ = 0.2 (corners and centre here; the
  whole map in scenarios/sweep_law_FE_mB.yaml): final error < 0.1 mm at 1.5 s, settling (2 %)
  < 1.0 s, peak |i_q*| ≤ 10 A and below the default i_max (which therefore does not bind), and
  no chattering: the total variation of i_q* per second stays ≤ 10 A/s (a command switching
  by Q/G ≈ 0.5 A every sample would give ~1000 A/s);
* anti-windup: with i_max = 3 A at the heavy corner (150 N, 8.86 kg) the current is clipped
  for a quarter of a second, yet the slider arrives without overshoot (integrating through
  the clipping instead overshoots by more than half the stroke).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import ScenarioError, load_scenario, runs_from_document
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "integral_load.yaml"


def _run(variant: str = "friction", **plant):
    run = next(r for r in load_scenario(SCENARIO) if r.variant == variant)
    return dataclasses.replace(run, plant=dataclasses.replace(run.plant, **plant)) if plant else run


def _total_variation_per_second(outcome) -> float:
    u, t = outcome.trace.column("iq_ref"), outcome.trace.time
    return float(np.sum(np.abs(np.diff(u))) / (t[-1] - t[0]))


def test_on_the_nominal_plant_the_error_follows_the_designed_dynamics(plant_fmu: Path) -> None:
    run = _run("no_friction", F_E=0.0, current_loop="ideal")
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert outcome.complete
    lam = 8.0
    assert (run.controller.C_I, run.controller.K_I) == (2 * lam, lam * lam)
    t = outcome.trace.time
    e0 = run.x_target - run.x_start
    designed = run.x_target - e0 * (1.0 + lam * t) * np.exp(-lam * t)
    assert np.max(np.abs(outcome.trace.column("x_B") - designed)) < 1e-4
    assert outcome.summary.hitting_time_s == 0.0  # started on the surface: no reaching phase
    assert np.all(outcome.trace.column("phase") == 1.0)


@pytest.mark.parametrize(("F_E", "m_B"), [(0.0, 4.43), (0.0, 8.86), (150.0, 4.43), (150.0, 8.86), (80.0, 6.645)])
def test_targets_over_the_map_with_friction(plant_fmu: Path, F_E: float, m_B: float) -> None:
    run = _run("friction", F_E=F_E, m_B=m_B)
    assert run.plant.mu == 0.2 and run.controller.nominal_m_B == 4.43
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert outcome.complete, outcome.reason
    s = outcome.summary
    assert abs(s.final_error_m) < 1e-4
    assert s.settling_time_s is not None and s.settling_time_s < 1.0
    assert s.peak_iq_ref_A <= 10.0
    assert s.peak_iq_ref_A < run.controller.i_max  # the current limit does not bind here
    assert _total_variation_per_second(outcome) <= 10.0


def test_anti_windup_arrives_without_overshoot_when_the_current_limit_binds(plant_fmu: Path) -> None:
    run = _run("heavy_150N")
    run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, i_max=3.0))
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert outcome.complete
    u = outcome.trace.column("iq_ref")
    assert np.max(np.abs(u)) == 3.0
    assert np.count_nonzero(np.abs(u) == 3.0) * run.T_s > 0.1  # clipped for more than 0.1 s
    assert outcome.summary.overshoot_percent < 1.0
    assert abs(outcome.summary.final_error_m) < 1e-4


def test_the_paper_law_stays_the_default(plant_fmu: Path) -> None:
    run = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0]
    assert run.controller.law == "paper"


def test_bad_law_settings_are_rejected_with_the_key() -> None:
    document = {
        "name": "x",
        "t_end": 0.1,
        "T_s": 0.0005,
        "stroke": {"x_start": 0.2329, "x_target": 0.3199},
        "controller": {"law": "pid"},
    }
    with pytest.raises(ScenarioError, match="controller.law"):
        runs_from_document(document)
    document["controller"] = {"law": "integral", "i_max": 0}
    with pytest.raises(ScenarioError, match="controller.i_max"):
        runs_from_document(document)
