"""Work budgets: a run limited by the simulated work its plant does (solver events or steps,
counted by the plant FMU) ends at the same sample on any machine, failed with a reason that
says so; `tune` gives every case a budget by default, so its trials do not depend on how busy
the machine is."""

from __future__ import annotations

import copy
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

import toggle_cosim as tc
from toggle_cosim.cosim import master
from toggle_cosim.cosim.execution.budget import DEFAULT_EVENTS_PER_SAMPLE
from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document
from toggle_cosim.experiments.tune_spec import TuneError, load_tuning
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent


def _document(**keys: object) -> dict:
    document = yaml.safe_load((ROOT / "scenarios" / "friction_models.yaml").read_text())
    document["variants"] = {"only": document["variants"]["nominal_stick_slip"]}
    document["t_end"] = 0.5
    return {**document, **keys}


def test_a_run_past_its_budget_ends_where_the_count_passed_it_and_within_it_is_unchanged(plant_fmu: Path) -> None:
    """Budget 3 events: the count is read every 200 samples, so the run ends at the first such
    sample past 3 events, failed, with the samples the unbudgeted run has there, bit for bit; a
    budget the run stays within changes nothing."""
    plant = check_plant(plant_fmu)
    (free,) = runs_from_document(_document())
    (tight,) = runs_from_document(_document(budget={"events": 3}))
    (loose,) = runs_from_document(_document(budget={"events": 10_000, "steps": 100_000}))
    whole = master.check_and_simulate(free, plant)
    assert whole.complete and whole.record["solver_statistics"]["solver.events"] > 3
    limited = master.check_and_simulate(tight, plant)
    found = re.fullmatch(r"budget exceeded \((\d+) events > 3, budget\.events\) by t = ([\d.]+) s", limited.reason)
    assert found and int(found[1]) > 3 and not limited.complete and limited.record["status"] == "failed"
    rows = limited.record["samples"]
    assert (rows - 1) % 200 == 0 and float(found[2]) == pytest.approx((rows - 1) * free.T_s)
    assert (whole.trace.data[:rows] == limited.trace.data).all()
    again = master.check_and_simulate(tight, plant)
    assert again.reason == limited.reason and again.record["samples"] == rows
    within = master.check_and_simulate(loose, plant)
    assert within.complete and (within.trace.data == whole.trace.data).all()


@pytest.mark.parametrize(
    ("budget", "expected"),
    [({"seconds": 3}, "budget"), ({"events": 0}, "budget.events"), ({}, "budget")],
)
def test_a_bad_budget_is_one_line_naming_the_key(budget: dict, expected: str) -> None:
    with pytest.raises(ScenarioError, match=re.escape(expected)):
        runs_from_document(_document(budget=budget))


def test_a_budget_on_a_system_holds_for_its_plant(plant_fmu: Path) -> None:
    """A system (here the pair with a `record:` list) counts its plant component's work after every
    stretch of 200 samples, from sample 0: a tight budget ends it failed at t = 0.0995 s, its
    trace kept to there; a loose one changes nothing."""
    plant = check_plant(plant_fmu)
    record = ["plant.x_B", "controller.iq_ref"]
    (tight,) = runs_from_document(_document(budget={"events": 3}, record=record))
    (loose,) = runs_from_document(_document(budget={"events": 10_000}, record=record))
    limited = master.check_and_simulate(tight, plant)
    assert not limited.complete and limited.record["status"] == "failed", limited.reason
    assert re.fullmatch(r"budget exceeded \(\d+ events > 3, budget\.events\) by t = 0\.0995 s", limited.reason)
    assert limited.record["samples"] == 200 and len(limited.trace.time) == 200
    within = master.check_and_simulate(loose, plant)
    assert within.complete and (within.trace.data[:200] == limited.trace.data).all()


def test_tune_gives_every_case_a_budget_unless_its_file_says_otherwise(tmp_path: Path) -> None:
    """By default every case gets budget.events_per_sample 4, as a fixed key (so the sweep files a
    tuning writes run the same cases); case_budget sets other keys, none sets none."""
    from test_tune import write_tuning

    tuning = load_tuning(write_tuning(tmp_path / "default"))
    assert [c.document["budget"] for c in tuning.cases] == [{"events_per_sample": DEFAULT_EVENTS_PER_SAMPLE}] * 4
    assert tuning.fixed["budget.events_per_sample"] == DEFAULT_EVENTS_PER_SAMPLE
    given = load_tuning(write_tuning(tmp_path / "given", case_budget={"steps": 5000})).cases
    assert [c.document["budget"] for c in given] == [{"steps": 5000}] * 4
    assert len({c.case_id for c in given} | {c.case_id for c in tuning.cases}) == 8
    none = load_tuning(write_tuning(tmp_path / "none", case_budget="none")).cases
    assert all("budget" not in c.document for c in none)
    with pytest.raises(TuneError, match="case_budget"):
        load_tuning(write_tuning(tmp_path / "bad", case_budget={"wall": 3}))


def test_events_per_sample_is_a_budget_of_the_runs_samples(plant_fmu: Path) -> None:
    """events_per_sample 0.002 over 1000 samples: 2 events, said so in the reason; with a lower
    events key beside it, that one holds."""
    (rate,) = runs_from_document(_document(budget={"events_per_sample": 0.002}))
    limited = master.check_and_simulate(rate, check_plant(plant_fmu))
    assert re.fullmatch(
        r"budget exceeded \(\d+ events > 2, budget\.events_per_sample 0\.002 x 1000 samples\) by t = [\d.]+ s",
        limited.reason,
    )
    (both,) = runs_from_document(_document(budget={"events_per_sample": 0.002, "events": 1}))
    assert ", budget.events) by" in master.check_and_simulate(both, check_plant(plant_fmu)).reason


@pytest.mark.slow
def test_the_same_tuning_gives_the_same_trials_on_a_busy_machine(tmp_path: Path, plant_fmu: Path) -> None:
    """A small study run twice, the second time beside two processes that keep both cores busy:
    trials.csv is the same but for its duration_s column (the trials' wall time). A budget low
    enough to end some cases shows it decides the same way both times."""
    from test_tune import write_tuning

    changes = {"optimiser": {"sampler": "tpe", "trials": 3, "batch": 3, "seed": 5}, "case_budget": {"events": 8}}
    quiet = tc.tune(write_tuning(tmp_path / "quiet", plant_fmu, **copy.deepcopy(changes)), workers=1)
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        loaded = tc.tune(write_tuning(tmp_path / "loaded", plant_fmu, **copy.deepcopy(changes)), workers=1)
    finally:
        for process in busy:
            process.kill()
            process.wait()
    first = pd.read_csv(quiet.output / "trials.csv").drop(columns="duration_s")
    second = pd.read_csv(loaded.output / "trials.csv").drop(columns="duration_s")
    pd.testing.assert_frame_equal(first, second, check_exact=True)
    assert len(first) == 4 and (first["state"] == "complete").all()
