"""The co-simulation master with the real plant FMU: the paper's runs end where they must,
the recorded trace obeys the controller's equations, and a plant fault ends a run cleanly."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim.control.controller import hitting_time
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.physics.parameters import ControllerGains
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
PAPER = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")


@pytest.fixture(scope="module")
def outcomes(plant_fmu: Path) -> dict[str, object]:
    plant = check_plant(plant_fmu)
    found = {}
    for name in PAPER:
        for run in load_scenario(ROOT / "scenarios" / f"{name}.yaml"):
            found[run.label] = check_and_simulate(run, plant)
    return found


def test_all_six_paper_runs_complete(outcomes: dict) -> None:
    assert len(outcomes) == 6
    for label, outcome in outcomes.items():
        assert outcome.complete, (label, outcome.reason)
        assert outcome.trace.data.shape[0] == 3001  # 1.5 s at T_s = 0.5 ms, both ends included
        assert np.all(np.isfinite(outcome.trace.data))


@pytest.mark.parametrize("variant", ["friction", "no_friction"])
def test_nominal_case_ends_within_a_tenth_of_a_millimetre(outcomes: dict, variant: str) -> None:
    """Fig. 4: x_B ends within 0.1 mm of x_B* = 0.3199 m after 1.5 s, with no overshoot."""
    trace = outcomes[f"fig4_nominal/{variant}"].trace
    assert abs(trace.column("x_B")[-1] - 0.3199) < 1e-4
    assert np.max(trace.column("x_B")) < 0.3199 + 1e-4


def test_hitting_time_and_phase_switch_in_the_recorded_trace(outcomes: dict) -> None:
    """Eq. (21) with S(t0) = C (x* - x0) = 0.435 m/s gives T_h = 0.0373 s; the recorded phase
    switches to sliding at the first sample at or after T_h."""
    outcome = outcomes["fig4_nominal/no_friction"]
    trace = outcome.trace
    S0 = trace.column("S")[0]
    assert S0 == pytest.approx(5 * (0.3199 - 0.2329), rel=1e-9)
    T_h = hitting_time(S0, ControllerGains())
    assert T_h == pytest.approx(0.0373, abs=1e-4)
    first_sliding = trace.time[np.argmax(trace.column("phase") == 1.0)]
    assert first_sliding >= T_h
    assert first_sliding - T_h < 0.0005 + 1e-12


def test_reaching_phase_follows_the_reaching_law_on_the_nominal_plant_fmu(plant_fmu: Path) -> None:
    """On the nominal plant (the FMU with mu = 0, F_E = 0, nominal m_B and an ideal current
    loop) S follows dS/dt = -P S - Q sgn(S) during reaching within the zero-order-hold error,
    T_s D_max / (2P) with a 25 % margin (the bound derived in tests/test_controller.py, about
    2 % of S0); with the 350 rad/s current loop the lag of the drive breaks that bound."""
    import yaml

    document = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    document.pop("variants")
    document["t_end"] = 0.1
    document["plant"].update(mu=0.0, F_E=0.0, current_loop="ideal")
    plant = check_plant(plant_fmu)
    P, Q, C, T_s = 50.0, 4.0, 5.0, 0.0005

    def deviation(doc: dict) -> tuple[float, float]:
        trace = check_and_simulate(runs_from_document(doc)[0], plant).trace
        S0 = trace.column("S")[0]
        reaching = trace.column("phase") == 0.0
        t = trace.time[reaching]
        analytic = (S0 + Q / P) * np.exp(-P * t) - Q / P
        D_max = P * (P * abs(S0) + Q) + C * np.max(np.abs(trace.column("a_B")[reaching]))
        return float(np.max(np.abs(trace.column("S")[reaching] - analytic))), 1.25 * T_s * D_max / (2 * P)

    ideal, bound = deviation(document)
    assert bound < 0.021 * 0.435
    assert ideal < bound
    document["plant"]["current_loop"] = "first_order"
    lagging, _ = deviation(document)
    assert lagging > bound


def test_friction_is_reported_with_its_sign_and_balances(outcomes: dict) -> None:
    """E_in = dE_mech + E_fric + E_load along every paper run (to 1e-4 of E_in)."""
    for label, outcome in outcomes.items():
        trace = outcome.trace
        balance = (
            trace.column("E_in")
            - (trace.column("E_mech") - trace.column("E_mech")[0])
            - trace.column("E_fric")
            - trace.column("E_load")
        )
        assert np.max(np.abs(balance)) < 1e-4 * np.max(np.abs(trace.column("E_in"))), label
        if label.endswith("no_friction"):
            assert np.all(trace.column("E_fric") == 0.0)


def test_run_record_names_the_fmu_and_versions(outcomes: dict, plant_fmu: Path) -> None:
    record = outcomes["fig4_nominal/friction"].record
    json.dumps(record, default=str)
    assert record["status"] == "complete"
    assert record["fmu"]["guid"] == check_plant(plant_fmu).guid
    assert len(record["fmu"]["sha256"]) == 64
    assert record["versions"]["fmpy"] != "not installed"
    assert math.isfinite(record["summary"]["final_error_m"])


@pytest.mark.parametrize("which", [1, 0], ids=["last-column", "first-diagnostic"])
def test_a_diagnostic_that_turns_nan_is_written_in_every_row_of_the_trace(
    plant_fmu: Path, tmp_path: Path, which: int
) -> None:
    """Issue 37, item 1: a Python controller whose diagnostic is NaN from t = 0.01 s, in the
    trace's last column or not. The run is complete (a diagnostic is a recorded value, not a
    measurement), trace.csv has every sample, run.json counts them, and the NaN read back."""
    from nan_values import FINITE, SAMPLES, nan_controller_scenario, run_scenario

    scenario = nan_controller_scenario(tmp_path, which)
    record, trace = run_scenario(scenario, plant_fmu, tmp_path / "out")
    assert record["status"] == "complete" and record["samples"] == trace.data.shape[0] == SAMPLES
    assert trace.names[-2:] == ("e", "flag")
    column = trace.column(("e", "flag")[which])
    assert np.all(np.isfinite(column[:FINITE])) and np.all(np.isnan(column[FINITE:]))
    assert np.all(np.isfinite(np.delete(trace.data, len(trace.names) - 2 + which, axis=1)))
    # the same run in this process: the same rows, NaN for NaN
    run = load_scenario(scenario)[0]
    in_process = check_and_simulate(run, check_plant(plant_fmu))
    assert in_process.complete and np.array_equal(in_process.trace.data, trace.data, equal_nan=True)


def test_a_run_ended_after_a_recorded_nan_keeps_every_sample_before_its_end(plant_fmu: Path, tmp_path: Path) -> None:
    """The supervising process counts the samples as the child records them: a controller that
    records NaN from t = 0.01 s and ends the run's process at t = 0.03 s leaves the 60 samples
    before, NaN included (not the 20 before the first NaN)."""
    from nan_values import FINITE, nan_controller_scenario

    from toggle_cosim.cosim.isolation.supervision import simulate_supervised

    run = load_scenario(nan_controller_scenario(tmp_path, 1, exit_at=0.03))[0]
    outcome = simulate_supervised(run, check_plant(plant_fmu))
    assert not outcome.complete and "ended the run's process" in outcome.reason, outcome.reason
    assert outcome.trace.data.shape[0] == outcome.record["samples"] == 60
    flag = outcome.trace.column("flag")
    assert np.all(flag[:FINITE] == 1.0) and np.all(np.isnan(flag[FINITE:]))
    assert outcome.trace.time[-1] == pytest.approx(0.0295, abs=1e-12)
