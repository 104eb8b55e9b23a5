"""The plain pair runs as the two-part system it is, in the execution (`master.simulate` ->
`pair_execution`; every stored reference through it: test_references.py), with the pair's trace
columns and run.json (its loop's kind from what the execution did): the built-in law, user
controllers, a controller FMU, a sweep, the work budget, a plant's retries and failures and a
controller that raises give the pair's outcome; and what the pair's record has (T_h, S0,
plausibility warnings) every system run has too.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

import toggle_cosim as tc
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.cosim import master
from toggle_cosim.cosim.outcome import Stepping
from toggle_cosim.cosim.pair_execution import pair_loop
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.model import Port, Wiring

ROOT = Path(__file__).resolve().parent.parent
BUDGET_ROWS = 201  # samples 0 .. 200: t = 0.1 s
FAULT_ROWS = {"zeno": 401, "chatter": 501, "error": 201, "nan": 201}  # up to the failed step's start
EARLIER = {  # the retries that passed, in the pair's words, at the end of the reason
    "zeno": "(earlier, the plant's step at t = 0.1 s failed and passed when retried from a checkpoint)",
    "chatter": "(earlier, 300 of the plant's steps from t = 0.1 s to 0.2495 s failed and passed when retried",
}


@pytest.fixture(scope="module")
def plants(plant_fmu: Path, no_gravity_fmu: Path):
    return {"plant": check_plant(plant_fmu), "no_gravity": check_plant(no_gravity_fmu)}


def _plant(plants, run):
    return plants["no_gravity" if run.scenario == "swap_no_gravity" else "plant"]


@pytest.mark.parametrize(
    ("stepping", "kind"),
    [
        (Stepping(True, None, ("controller",)), "compiled"),
        (Stepping(True, None, ("controller",), (), 7), "compiled, then python"),
        (Stepping(True, None, (), (("controller", "a user's controller"),)), "python"),
        (Stepping(False, "no C compiler"), "python"),
        (None, "none"),
    ],
)
def test_the_pair_s_loop_kind_comes_from_what_the_execution_did(stepping, kind: str) -> None:
    """Not from the words of its reason: a reason that says otherwise does not change the kind."""
    loop = {"kind": "none", "reason": "in Python, called back from C; a sample the native controller handed back"}
    assert pair_loop(loop, stepping) == {
        "kind": kind,
        "reason": f"the pair as a system in the execution: {loop['reason']}",
    }


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_user_controllers_and_a_controller_fmu_run_with_the_pair_s_columns(
    plants, vsc_fmu: Path, coupling: str
) -> None:
    """The examples' PD law (which measures a_B, an output the command feeds directly), a
    python-control PID (natively in C) and a limited VSC, and the built-in law's controller FMU:
    complete, the pair's columns, the controller as the pair records it; the user's Python
    controllers called back from C ("python"), the others compiled."""
    runs = [
        dataclasses.replace(r, t_end=0.2) for r in load_scenario(ROOT / "examples/controllers/user_controllers.yaml")
    ]
    fig5 = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0]
    runs.append(dataclasses.replace(fig5, t_end=0.2, controller=dataclasses.replace(fig5.controller, fmu=vsc_fmu)))
    runs.append(dataclasses.replace(fig5, t_end=0.2))  # the built-in law, natively in C
    for run in runs:
        outcome = master.check_and_simulate(dataclasses.replace(run, coupling=coupling), plants["plant"])
        assert outcome.complete, (run.label, outcome.reason)
        diagnostics = tuple(outcome.record["controller"]["diagnostics"])
        assert outcome.trace.names == master.trace_names(plants["plant"], diagnostics, master.other_inputs(run))
        assert "system" not in outcome.record and "units" not in outcome.record
        natively = "natively in C" in outcome.record["loop"]["reason"]
        assert outcome.record["loop"]["kind"] == ("compiled" if natively or run.controller.fmu else "python"), run.label


def test_a_sweep_s_cases_give_the_rows_of_runs_alone(plant_fmu: Path, tmp_path: Path) -> None:
    """A sweep's cases, each on the plant instance its worker keeps in its pool, give the rows of
    the same case swept alone (the first case of a fresh worker), but for their wall times."""
    base = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    base.update(fmu=str(plant_fmu), t_end=0.2)
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    values = [0.0, 40.0, 80.0]
    sweep = {"base": "base.yaml", "variant": "friction", "axes": {"plant.F_E": {"values": values}}}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep))
    together = tc.sweep(tmp_path / "sweep.yaml", output=tmp_path / "together", workers=1)
    columns = [c for c in together.columns if not c.startswith(("wall", "case"))]
    assert list(together["status"]) == ["ok"] * 3
    (tmp_path / "one.yaml").write_text(yaml.safe_dump({**sweep, "axes": {"plant.F_E": {"values": [values[-1]]}}}))
    alone = tc.sweep(tmp_path / "one.yaml", output=tmp_path / "alone", workers=1)
    assert alone[columns].iloc[0].equals(together[columns].iloc[-1])


# -- what every system run's record has, as the pair's ------------------------------------------
def _recorded(run):
    ports = ("plant.x_B", "plant.E_in", "plant.E_fric", "controller.iq_ref", "controller.S", "controller.phase")
    return dataclasses.replace(run, system=Wiring(record=tuple(Port.parse(p) for p in ports)))


def test_a_system_run_has_the_pair_s_summary_warnings_and_solver_statistics(plants) -> None:
    """T_h and S0 from its native controller, the plausibility flags (a 2 A rating: the command
    exceeds it), the plant's solver counts."""
    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    run = dataclasses.replace(run, t_end=0.2, plant=dataclasses.replace(run.plant, rated_current=2.0))
    fixed = master.check_and_simulate(run, plants["plant"])
    system = master.check_and_simulate(_recorded(run), plants["plant"])
    assert system.complete, system.reason
    assert system.summary == fixed.summary and system.summary.hitting_time_s is not None
    assert system.warnings == fixed.warnings and system.warnings[0].startswith("|i_q*| exceeds the rated current 2 A")
    assert system.record["solver_statistics"] == fixed.record["solver_statistics"]
    assert isinstance(system.record["solver_statistics"], dict)


def test_the_pair_s_budget_ends_the_run_at_the_pair_s_sample(plants) -> None:
    """The pair's plant work is counted after its first sample and every 200 samples from there
    (t = 0.1 s at 0.5 ms): the run ends there, failed, its trace kept up to that sample."""
    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    run = dataclasses.replace(run, t_end=0.3, resolved={**run.resolved, "budget": {"steps": 50}})
    outcome = master.check_and_simulate(run, plants["plant"])
    assert outcome.reason is not None and "budget.steps) by t = 0.1 s" in outcome.reason
    assert len(outcome.trace.data) == BUDGET_ROWS


@pytest.mark.parametrize(
    ("kind", "end", "reason"),
    [
        ("zeno", 0.2, "plant FMU failed at t = 0.2 s: "),
        ("chatter", 0.25, "plant FMU failed at t = 0.25 s: "),
        ("error", 1e300, "plant FMU failed at t = 0.1 s: "),
        ("nan", 1e300, "plant outputs became non-finite at t = 0.1005 s"),
    ],
)
def test_a_plant_s_retries_and_failure_are_said_in_the_pair_s_words(
    plant_fmu: Path, kind: str, end: float, reason: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The shim plant (`fault_plants`) refusing steps from t = 0.1 s (zeno: once, a retry passes,
    and every step from 0.2 s; chatter: every full step, each retry passing until 0.25 s; error:
    every step) or answering NaN (nan): the pair's reason and retries, the trace kept up to the
    sample the failed step started from."""
    from fault_plants import fault_environment, make_faulty_fmu

    faulty = check_plant(make_faulty_fmu(plant_fmu, tmp_path / f"{kind}.fmu"))
    environment = fault_environment(kind, 0.1, faulty.references)
    for name in ("TOGGLE_FAULT_KIND", "TOGGLE_FAULT_TIME", "TOGGLE_FAULT_MIN_FE", "TOGGLE_FAULT_FE_VR"):
        monkeypatch.setenv(name, environment[name])
    monkeypatch.setenv("TOGGLE_FAULT_END", repr(end))
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.3)
    outcome = master.check_and_simulate(run, faulty)
    assert not outcome.complete and outcome.reason.startswith(reason), outcome.reason
    assert bool(outcome.record["retries"]) == (kind != "nan")
    assert all(set(entry) == {"t", "error", "outcome"} for entry in outcome.record["retries"])  # no component
    assert (EARLIER[kind] in outcome.reason) if kind in EARLIER else "earlier" not in outcome.reason
    assert len(outcome.trace.data) == FAULT_ROWS[kind]


class _RaisesAt:
    """A user's controller (the protocol): i_q* = 20 (x* − x_B) until its step raises from t = 5 ms."""

    diagnostics = ("e",)

    def start(self, t0: float, measurement: object) -> None:
        return None

    def step(self, state: None, t: float, measurement) -> ControlStep:  # noqa: ANN001
        if t >= 0.005 - 1e-12:
            raise RuntimeError("the law gave up")
        error = 0.3199 - measurement["x_B"]
        return ControlStep(20.0 * error, (error,), state)


def test_a_controller_that_raises_fails_the_run_in_the_pair_s_words(plants) -> None:
    """ "controller failed: the controller's step raised at t = 0.005 s: ...", the trace up to
    the sample before (t = 0.0045 s)."""
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.02)
    outcome = master.check_and_simulate(run, plants["plant"], controller=_RaisesAt())
    assert outcome.reason.startswith("controller failed: the controller's step raised at t = 0.005 s"), outcome.reason
    assert outcome.record["loop"]["kind"] == "python"
    assert len(outcome.trace.data) == 10
