"""The three joint-friction models of the plant FMU (README, "Friction models").

Physics checked: under the dissipative and stick-slip models the friction power is never
negative, so E_fric never decreases, on forward and backward strokes (the paper's eq. (17)
does decrease it on the backward stroke, which shows the check can fail); under stick-slip a
constant thrust below breakaway holds slider B at rest to 1e-9 m for 1 s, and one above it
moves the slider; a plant without the parameter refuses a non-default model in one line.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from test_plant_fmu import Plant

from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document
from toggle_cosim.plant.friction import FRICTION_MODELS, friction_settings

F_E = 100.0  # N, the load of Fig. 5


def _stroke(
    fmu: Path, model: str, iq: float, seconds: float, load: float = F_E, **extra: float | bool
) -> dict[str, np.ndarray]:
    """Open loop: constant i_q* and F_E from t = 0 (set before initialisation), sampled every ms."""
    plant = Plant(fmu, frictionModel=FRICTION_MODELS[model], mu=0.2, mu_s=0.2, iq_ref=iq, F_E=load, **extra)
    names = ("x_B", "v_B", "E_fric", "mechanism.stuck", "mechanism.T_st", "mechanism.T_s", "E_in", "E_mech", "E_load")
    rows = [plant.get(*names)]
    for _ in range(int(round(seconds / 1e-3))):
        plant.step(1e-3)
        rows.append(plant.get(*names))
    plant.close()
    data = np.array(rows)
    return {name: data[:, i] for i, name in enumerate(names)}


@pytest.mark.parametrize("model", ["dissipative", "stick_slip"])
@pytest.mark.parametrize(
    "iq, load, direction", [(3.0, 100.0, +1.0), (0.5, 100.0, -1.0), (0.3, 0.0, +1.0), (-0.3, 0.0, -1.0)]
)
def test_friction_energy_never_decreases(plant_fmu: Path, model: str, iq: float, load: float, direction: float) -> None:
    """Friction power mu sum_i |omega_i| |R_i| >= 0: E_fric is non-decreasing sample to sample
    (to 1e-12 J, rounding) on forward and backward strokes, with and without the 100 N load
    (backward: the load pushes back against 0.5 A, or the thrust is reversed), and it grows by
    more than 1 mJ: friction does take energy."""
    run = _stroke(plant_fmu, model, iq, 0.1, load)
    moved = run["x_B"][-1] - run["x_B"][0]
    assert direction * moved > 5e-3, f"the stroke went the wrong way or not far: {moved:+.4g} m"
    steps = np.diff(run["E_fric"])
    assert steps.min() >= -1e-12, f"E_fric fell by {-steps.min():.3g} J in one sample"
    assert run["E_fric"][-1] > 1e-3
    # and the energy the friction takes is the energy that goes missing: E_in = dE_mech + E_fric + E_load
    residual = run["E_in"] - (run["E_mech"] - run["E_mech"][0]) - run["E_fric"] - run["E_load"]
    assert np.abs(residual).max() < 1e-7


def test_paper_friction_hands_energy_back_on_the_backward_stroke(plant_fmu: Path) -> None:
    """Eq. (17) multiplies the signed lambda: on the backward stroke driven by a reversed thrust
    (-0.3 A, no load) E_fric falls, and ends negative (the defect the dissipative model removes),
    so the check above discriminates."""
    run = _stroke(plant_fmu, "paper", -0.3, 0.1, 0.0)
    assert np.diff(run["E_fric"]).min() < -1e-5
    assert run["E_fric"][-1] < -1e-3


def test_stick_slip_holds_below_breakaway_and_moves_above(plant_fmu: Path) -> None:
    """Ideal current loop, F_E = 100 N. At 1.9 A the holding torque on theta1 stays below the
    static capacity mu_s sum |k_i| |R_i|: slider B stays within 1e-9 m of x_B0 for 1 s and the
    mechanism stays stuck; at 2.6 A the torque exceeds it, the mechanism breaks away and moves
    forward by more than 1 mm within 0.1 s."""
    held = _stroke(plant_fmu, "stick_slip", 1.9, 1.0, idealCurrentLoop=True)
    assert np.abs(held["x_B"] - held["x_B"][0]).max() <= 1e-9
    assert held["mechanism.stuck"].min() == 1.0
    assert np.all(np.abs(held["mechanism.T_st"]) < held["mechanism.T_s"])
    moved = _stroke(plant_fmu, "stick_slip", 2.6, 0.1, idealCurrentLoop=True)
    assert abs(moved["mechanism.T_st"][0]) > moved["mechanism.T_s"][0]
    assert moved["x_B"][-1] - moved["x_B"][0] > 1e-3
    assert moved["mechanism.stuck"][-1] == 0.0


def test_a_plant_without_frictionModel_runs_the_paper_model_only(tmp_path: Path) -> None:
    """A foreign plant FMU without the parameter: the default needs nothing; any other model is
    refused in one line naming the key."""
    fmu = tmp_path / "foreign.fmu"
    assert friction_settings("paper", 0.2, None, {"m_B", "mu"}, fmu) == []
    with pytest.raises(ValueError) as error:
        friction_settings("stick_slip", 0.2, 0.3, {"m_B", "mu"}, fmu)
    assert "plant.friction_model: stick_slip" in str(error.value) and "\n" not in str(error.value)
    assert friction_settings("stick_slip", 0.2, None, {"frictionModel", "mu_s"}, fmu) == [
        ("frictionModel", 3.0),
        ("mu_s", 0.2),
    ]


def test_scenario_keys_friction_model_and_mu_s() -> None:
    """plant.friction_model defaults to paper; unknown models and negative mu_s are refused."""
    base = {"name": "s", "t_end": 0.01, "T_s": 0.0005, "stroke": {"x_start": 0.2329, "x_target": 0.3199}}
    run = runs_from_document(base)[0]
    assert run.plant.friction_model == "paper" and run.plant.mu_s is None
    run = runs_from_document({**base, "plant": {"friction_model": "stick_slip", "mu_s": 0.3}})[0]
    assert run.plant.friction_model == "stick_slip" and run.plant.mu_s == 0.3
    with pytest.raises(ScenarioError, match="plant.friction_model"):
        runs_from_document({**base, "plant": {"friction_model": "karnopp"}})
    with pytest.raises(ScenarioError, match="plant.mu_s"):
        runs_from_document({**base, "plant": {"mu_s": -0.1}})


def test_a_foreign_plant_refuses_stick_slip_before_running(plant_fmu: Path, tmp_path: Path) -> None:
    """Through the CLI, a plant FMU without `frictionModel` (here: ours with the parameter renamed):
    friction_model: paper runs; stick_slip is refused with one line, exit 2, nothing written."""
    from click.testing import CliRunner
    from test_bad_plant_files import _rewrite

    from toggle_cosim.cli import main

    foreign = _rewrite(
        plant_fmu, tmp_path / "foreign.fmu", lambda xml: xml.replace('name="frictionModel"', 'name="frictionLaw"')
    )
    scenario = tmp_path / "s.yaml"
    text = (
        "name: s\nt_end: 0.01\nT_s: 0.0005\nstroke: {x_start: 0.2329, x_target: 0.3199}\nplant: {friction_model: %s}\n"
    )
    runner = CliRunner()
    scenario.write_text(text % "paper")
    result = runner.invoke(main, ["run", str(scenario), "--fmu", str(foreign), "--out", str(tmp_path / "ok")])
    assert result.exit_code == 0, result.output
    scenario.write_text(text % "stick_slip")
    out = tmp_path / "refused"
    result = runner.invoke(main, ["run", str(scenario), "--fmu", str(foreign), "--out", str(out)])
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "plant.friction_model: stick_slip" in lines[0] and "frictionModel" in lines[0]
    assert not out.exists()


def _push_then_hold(fmu: Path, model: str, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Ideal current loop, F_E = 100 N: 2.6 A for 50 ms (the mechanism breaks away forward), then
    1.9 A, below what moves it: it decelerates and comes to rest. x_B and `stuck` every ms."""
    plant = Plant(
        fmu, frictionModel=FRICTION_MODELS[model], mu=0.2, mu_s=0.2, idealCurrentLoop=True, iq_ref=2.6, F_E=F_E
    )
    rows = []
    try:
        for k in range(int(round(seconds / 1e-3))):
            if k == 50:
                plant.set("iq_ref", 1.9)
            plant.step(1e-3)
            rows.append(plant.get("x_B", "mechanism.stuck"))
    finally:
        plant.fmu.freeInstance()
        shutil.rmtree(plant.dir, ignore_errors=True)
    data = np.array(rows)
    return data[:, 0], data[:, 1]


@pytest.mark.parametrize("model", ["stick_slip", "dissipative", "paper"])
def test_a_mechanism_that_comes_to_rest_stays_at_rest(plant_fmu: Path, model: str) -> None:
    """Where the motion would reverse under a load that static friction holds, every model sticks
    once and stays (x_B constant to 1e-9 m from then on, one stick, no chattering); before the
    stuck mode of the paper's and the dissipative model, those two chattered there and the FMU
    stopped with its Zeno error."""
    x_B, stuck = _push_then_hold(plant_fmu, model, 0.8)
    assert stuck[:100].max() == 0.0, "it moved first"
    k = int(np.argmax(stuck > 0))
    assert 100 < k < 700 and np.all(stuck[k:] == 1.0)
    assert np.ptp(x_B[k:]) <= 1e-9
    assert x_B[k] - x_B[0] > 1e-3
