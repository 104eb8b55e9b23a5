"""Plausibility flags: a run whose command exceeds the motor's rating, whose slider leaves the
linkage's working range or whose command chatters is flagged (run.json, summary table, console),
its status unchanged."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.cosim.plausibility import CHATTER_SIGN_CHANGES, CHATTER_TOTAL_VARIATION, plausibility_warnings
from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document
from toggle_cosim.physics.mechanism import working_range
from toggle_cosim.physics.parameters import MechanismParameters

ROOT = Path(__file__).resolve().parent.parent


def test_the_working_range_is_the_linkage_between_its_dead_points() -> None:
    """Folded at r3 − r1 = 0.17 m, toggle at r1 + r3 = 0.37 m (f = 0), 10 mm inside each."""
    assert working_range(MechanismParameters()) == pytest.approx((0.18, 0.36), abs=1e-12)


def test_each_limit_is_flagged_with_when_and_how_much() -> None:
    time = np.arange(6) * 0.1
    x_B = np.array([0.23, 0.20, 0.17, 0.175, 0.19, 0.2])
    iq = np.array([3.0, -12.0, 9.0, 11.0, 0.0, 1.0])
    rated, position = plausibility_warnings(time, x_B, iq, 10.0, (0.18, 0.36))
    assert rated.startswith("|i_q*| exceeds the rated current 10 A (plant.rated_current) from t = 0.1 s; peak 12 A")
    assert "working range 0.1800 m to 0.3600 m (plant.working_range) at t = 0.2 s" in position
    assert "x_B spans 0.17000 m to 0.23000 m" in position
    assert plausibility_warnings(time, x_B, iq, 12.0, (0.17, 0.36)) == []  # limits are inclusive


def test_a_70_hz_oscillation_of_the_command_is_flagged_as_chattering() -> None:
    """±3 A at 70 Hz gives about 840 A/s of total variation, over the 500 A/s limit; the same command
    without the oscillation (a decaying 3 A, a few A/s, as the shipped runs) is not flagged, nor
    is the oscillation's S outside the sliding phase; S changing sign at 140/s while sliding is."""
    time = np.arange(2001) * 0.0005  # 1 s at T_s
    x_B = np.full_like(time, 0.3)
    smooth = 3.0 * np.exp(-5.0 * time)
    oscillation = 3.0 * np.sin(2 * np.pi * 70.0 * time)
    (flag,) = plausibility_warnings(time, x_B, smooth + oscillation, 10.0, (0.18, 0.36))
    assert flag.startswith("the command chatters: i_q* varies by 83") and "A/s (limits 500 A/s" in flag
    assert CHATTER_TOTAL_VARIATION == 500.0 and CHATTER_SIGN_CHANGES == 100.0
    assert plausibility_warnings(time, x_B, smooth, 10.0, (0.18, 0.36)) == []
    S = 0.01 * np.sin(2 * np.pi * 70.0 * time)
    reaching, sliding = np.zeros_like(time), np.ones_like(time)
    assert plausibility_warnings(time, x_B, smooth, 10.0, (0.18, 0.36), S, reaching) == []
    (flag,) = plausibility_warnings(time, x_B, smooth, 10.0, (0.18, 0.36), S, sliding)
    assert re.search(r"S changes sign 1[34]\d times/s while sliding", flag), flag  # 2 x 70 Hz


class _Resonating:
    """A PD on x_B with ±3 A at 70 Hz added: a loop that resonates."""

    diagnostics = ("e",)

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return None

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        e = 0.3199 - measurement["x_B"]
        return ControlStep(12.0 * e - 2.5 * measurement["v_B"] + 3.0 * np.sin(2 * np.pi * 70.0 * t), (e,), state)


def test_a_resonating_run_stays_complete_and_is_flagged(plant_fmu: Path) -> None:
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.plant.contract import check_plant

    (run,) = runs_from_document({**_fig4(), "t_end": 0.5})
    outcome = check_and_simulate(run, check_plant(plant_fmu), controller=_Resonating())
    assert outcome.complete
    (flag,) = outcome.warnings
    assert flag.startswith("the command chatters: i_q* varies by ") and outcome.record["warnings"] == [flag]


def _fig4(**plant: object) -> dict:
    document = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    document.pop("variants")
    document["fmu"] = str(ROOT / "fmus" / "ToggleLSM.fmu")
    document["plant"].update(plant)
    return document


def test_the_scenario_keys_and_their_defaults() -> None:
    (run,) = runs_from_document(_fig4())
    assert run.plant.rated_current == 10.0 and run.plant.working_range == pytest.approx((0.18, 0.36))
    (run,) = runs_from_document(_fig4(rated_current=3.0, working_range=[0.2, 0.3]))
    assert run.plant.rated_current == 3.0 and run.plant.working_range == (0.2, 0.3)
    with pytest.raises(ScenarioError, match=r"key plant.working_range: \[0.3, 0.2\] is empty"):
        runs_from_document(_fig4(working_range=[0.3, 0.2]))


def test_a_flagged_run_stays_complete_and_says_so_everywhere(plant_fmu: Path, tmp_path: Path) -> None:
    """Fig. 4 (peak |i_q*| 3.17 A, x_B within 0.2329-0.3199 m) is plausible by default; with a
    3 A rating and a range that ends at 0.3 m it is flagged twice, and still complete."""
    from toggle_cosim.analysis.report import summary_table
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.plant.contract import check_plant

    plant = check_plant(plant_fmu)
    (plain,) = runs_from_document({**_fig4(), "t_end": 1.0})
    assert check_and_simulate(plain, plant).warnings == ()
    document = {**_fig4(rated_current=3.0, working_range=[0.2, 0.3]), "t_end": 1.0}
    scenario = tmp_path / "flagged.yaml"
    scenario.write_text(yaml.safe_dump(document))
    result = CliRunner().invoke(main, ["run", str(scenario), "--fmu", str(plant_fmu), "--out", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.output
    record = json.loads((tmp_path / "fig4_nominal" / "run" / "run.json").read_text())
    assert record["status"] == "complete"
    rated, position = record["warnings"]
    assert "exceeds the rated current 3 A" in rated and "peak 3.174 A at t = 0 s" in rated
    assert "leaves its working range 0.2000 m to 0.3000 m" in position
    lines = result.stdout.splitlines()
    assert "fig4_nominal: complete with 2 warnings;" in lines[0]
    assert lines[1:] == [f"[1/1] fig4_nominal: warning: {rated}", f"[1/1] fig4_nominal: warning: {position}"]
    (run,) = runs_from_document(document)
    table = summary_table([check_and_simulate(run, plant)])
    cell = f"{rated}; {position}".replace("|", "\\|")  # the table escapes the pipes of |i_q*|
    assert table.splitlines()[0].endswith("| warnings |") and f"| {cell} |" in table


def test_the_theta1_run_that_ends_past_the_fold_is_flagged(plant_fmu: Path) -> None:
    """friction_models/theta1_external_force_stick_slip: the load pushes slider B back through the
    folded position (x_B = 0.170 m), outside the working range: complete, and flagged."""
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.plant.contract import check_plant

    (run,) = [r for r in load_scenario(ROOT / "scenarios" / "friction_models.yaml") if r.variant.startswith("theta1")]
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert outcome.complete
    assert any("slider B leaves its working range 0.1800 m to 0.3600 m" in w for w in outcome.warnings)
    assert outcome.record["warnings"] == list(outcome.warnings)
