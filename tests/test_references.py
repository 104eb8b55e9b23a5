"""Regression check: every shipped scenario run, re-run from the Modelica source, stays inside
the funnel of its stored reference trace; a changed model parameter does not."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from junitparser import JUnitXml

from toggle_cosim.analysis.reference_reports import write_reference_reports
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments import references
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "scenarios" / "references"
SHIPPED = (
    "fig4_nominal",
    "fig5_external_force",
    "fig6_mass_variation",
    "swap_no_gravity",
    "integral_load",
    "friction_models",
)


def _runs():
    for name in SHIPPED:
        for run in load_scenario(ROOT / "scenarios" / f"{name}.yaml"):
            yield pytest.param(run, id=run.label)


@pytest.mark.parametrize("run", list(_runs()))
def test_shipped_run_matches_its_reference(run, plant_fmu: Path, no_gravity_fmu: Path) -> None:
    fmu = no_gravity_fmu if run.scenario == "swap_no_gravity" else plant_fmu
    outcome = check_and_simulate(run, check_plant(fmu))
    assert outcome.complete, outcome.reason
    checked = references.check(outcome, FOLDER)
    assert checked.passed, "moved beyond tolerance: " + "; ".join(checked.failures)  # funnel and invariants


@pytest.mark.slow
def test_a_perturbed_model_parameter_fails_the_check_and_names_the_variables(plant_fmu: Path, tmp_path: Path) -> None:
    """Raising the friction coefficient from 0.2 to 0.25 in the plant (a model change the
    controller does not know about) must move the nominal run outside its funnel; the CI reports
    of `toggle-cosim references` say so, one JUnit test case per variable."""
    run = next(r for r in load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml") if r.variant == "friction")
    perturbed = dataclasses.replace(run, plant=dataclasses.replace(run.plant, mu=0.25))
    outcome = check_and_simulate(perturbed, check_plant(plant_fmu))
    checked = references.check(outcome, FOLDER)
    assert not checked.comparison.passed
    failed = {v.name for v in checked.comparison.variables if not v.passed}
    assert {"Ff12", "E_fric"} <= failed  # friction forces and energy scale with mu
    assert "x_B" not in failed  # the controller keeps the position on course
    assert all(message.startswith("fig4_nominal/friction: ") for message in checked.failures)

    junit, summary = write_reference_reports(
        [(checked, outcome.trace, references.reference_stem(FOLDER, run))],
        tmp_path,
        tmp_path / "junit.xml",
        tmp_path / "summary.md",
    )
    xml = JUnitXml.fromfile(str(junit))
    # one case per variable, one per invariant stored beside the reference, and one for the solver
    # statistics: the changed friction changes the integrator's work, a warning (not a failure)
    # without the flag
    assert checked.solver is not None and checked.solver.changed
    assert len(checked.invariants) == 3
    broken = sum(not i.passed for i in checked.invariants)
    assert (xml.tests, xml.failures) == (len(checked.comparison.variables) + 3 + 1, len(failed) + broken)
    assert sorted(
        p.stem.removesuffix("_funnel") for p in (tmp_path / "fig4_nominal" / "friction").glob("*.png")
    ) == sorted(failed)
    assert "| fig4_nominal/friction | reference samples | 34 |" in summary.read_text()


def test_the_swapped_plant_differs_from_the_original(plant_fmu: Path, no_gravity_fmu: Path) -> None:
    """The no-gravity plant meets the same contract but is a different plant: its run leaves
    the nominal run's funnel (lambda1 carries the links' weight in the original)."""
    run = load_scenario(ROOT / "scenarios" / "swap_no_gravity.yaml")[0]
    nominal_reference = dataclasses.replace(run, scenario="fig4_nominal", variant="friction")
    checked = references.check(check_and_simulate(nominal_reference, check_plant(no_gravity_fmu)), FOLDER)
    assert not checked.comparison.passed
    assert "lambda1" in {v.name for v in checked.comparison.variables if not v.passed}
