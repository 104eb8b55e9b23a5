"""The plain pair run as a two-part system in the execution (TOGGLE_COSIM_MASTER=execution) gives
the fixed loop's outcome: trace.csv byte for byte and run.json field for field (its timings and
its loop's reason aside), for every stored reference's scenario, a sweep and user controllers;
and what the pair's record has (T_h, S0, plausibility warnings, the work budget) every system
run has too.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
import yaml

import toggle_cosim as tc
from toggle_cosim import limits
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.cosim import master
from toggle_cosim.experiments import references
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.files.traces import write_csv, write_json
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.model import Port, Wiring

ROOT = Path(__file__).resolve().parent.parent
FOLDER = ROOT / "scenarios" / "references"
STORED = sorted(FOLDER.glob("*/*_ref.csv"))
TIMINGS = ("wall_time_s", "loop_time_s", "real_time_factor")


def _run(reference: Path):
    runs = load_scenario(ROOT / "scenarios" / f"{reference.parent.name}.yaml")
    return next(run for run in runs if f"{references.reference_stem(FOLDER, run)}_ref.csv" == str(reference))


def _both(run, plant, monkeypatch: pytest.MonkeyPatch, **kwargs):
    """The run in the fixed loop, then in the execution."""
    monkeypatch.delenv("TOGGLE_COSIM_MASTER", raising=False)
    fixed = master.simulate(run, plant, **kwargs)
    monkeypatch.setenv("TOGGLE_COSIM_MASTER", "execution")
    executed = master.simulate(run, plant, **kwargs)
    monkeypatch.delenv("TOGGLE_COSIM_MASTER")
    return fixed, executed


def _files(outcome, folder: Path) -> tuple[bytes, dict]:
    """trace.csv's bytes and run.json without its timings and its loop's reason, as the command writes them."""
    folder.mkdir(parents=True)
    write_csv(folder / "trace.csv", outcome.trace, every=int(outcome.run.resolved.get("record_every", 1)))
    write_json(folder / "run.json", outcome.record)
    record = json.loads((folder / "run.json").read_text())
    for key in TIMINGS:
        record.pop(key)
    record["loop"].pop("reason")
    return (folder / "trace.csv").read_bytes(), record


def _same_files(fixed, executed, folder: Path) -> None:
    trace_fixed, record_fixed = _files(fixed, folder / "pair")
    trace_executed, record_executed = _files(executed, folder / "execution")
    if fixed.run.coupling == "jacobi":  # the fixed loop runs jacobi in Python only, the execution in C too
        assert record_fixed["loop"].pop("kind") == "python"
        assert record_executed["loop"].pop("kind") in ("compiled", "python")
    assert record_executed == record_fixed
    assert trace_executed == trace_fixed


@pytest.fixture(scope="module")
def plants(plant_fmu: Path, no_gravity_fmu: Path):
    return {"plant": check_plant(plant_fmu), "no_gravity": check_plant(no_gravity_fmu)}


def _plant(plants, run):
    return plants["no_gravity" if run.scenario == "swap_no_gravity" else "plant"]


def _stored() -> list:
    """Every stored reference, the loads that change in time (a step, a measured table) included."""
    return [pytest.param(p, id=f"{p.parent.name}/{p.stem}") for p in STORED]


@pytest.mark.parametrize("reference", _stored())
def test_every_stored_reference_passes_through_the_execution(
    reference: Path, plants, monkeypatch: pytest.MonkeyPatch
) -> None:
    run = _run(reference)
    monkeypatch.setenv("TOGGLE_COSIM_MASTER", "execution")
    outcome = master.simulate(run, _plant(plants, run))
    assert outcome.complete, outcome.reason
    assert "system" not in outcome.record and outcome.record["loop"]["reason"].startswith("the pair as a system")
    checked = references.check(outcome, FOLDER)
    assert checked.passed, "; ".join(checked.failures)


@pytest.mark.parametrize("reference", _stored())
def test_every_stored_reference_s_run_writes_the_pair_s_files_through_the_execution(
    reference: Path, plants, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """trace.csv byte for byte, run.json equal but for its timings and loop.reason."""
    run = _run(reference)
    fixed, executed = _both(run, _plant(plants, run), monkeypatch)
    assert fixed.complete and executed.complete, executed.reason
    assert executed.record["loop"]["kind"] == "compiled"
    _same_files(fixed, executed, tmp_path)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_user_controllers_and_a_controller_fmu_give_the_pair_s_files(
    plants, vsc_fmu: Path, coupling: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The examples' PD law (which measures a_B, an output the command feeds directly), a
    python-control PID (natively in C) and a limited VSC, and the built-in law's controller FMU."""
    runs = [
        dataclasses.replace(r, t_end=0.2) for r in load_scenario(ROOT / "examples/controllers/user_controllers.yaml")
    ]
    fig5 = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0]
    runs.append(dataclasses.replace(fig5, t_end=0.2, controller=dataclasses.replace(fig5.controller, fmu=vsc_fmu)))
    for run in runs:
        fixed, executed = _both(dataclasses.replace(run, coupling=coupling), plants["plant"], monkeypatch)
        assert fixed.complete and executed.complete, (run.label, executed.reason)
        _same_files(fixed, executed, tmp_path / run.label / coupling)


def test_a_sweep_gives_the_pair_s_rows_through_the_execution(
    plant_fmu: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A sweep's cases (each on the plant instance its worker keeps, in the fixed loop) give the
    same rows in the execution, but for their wall times."""
    base = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    base.update(fmu=str(plant_fmu), t_end=0.2)
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    sweep = {"base": "base.yaml", "variant": "friction", "axes": {"plant.F_E": {"values": [0.0, 40.0, 80.0]}}}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep))
    tables = {}
    for master_ in ("pair", "execution"):
        monkeypatch.setenv("TOGGLE_COSIM_MASTER", master_)
        tables[master_] = tc.sweep(tmp_path / "sweep.yaml", output=tmp_path / master_, workers=1)
    columns = [c for c in tables["pair"].columns if not c.startswith("wall")]
    assert list(tables["pair"]["status"]) == ["ok"] * 3
    assert tables["execution"][columns].equals(tables["pair"][columns])


def test_the_master_variable_is_checked_with_the_others(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("TOGGLE_COSIM_MASTER", raising=False)
    assert not limits.pair_as_execution()  # the default: the fixed loop
    monkeypatch.setenv("TOGGLE_COSIM_MASTER", "execution")
    assert limits.pair_as_execution()
    monkeypatch.setenv("TOGGLE_COSIM_MASTER", "libcosim")
    with pytest.raises(limits.LimitError, match=r"^TOGGLE_COSIM_MASTER='libcosim': give pair or execution, or"):
        limits.check_environment()


# -- what every system run's record has, as the pair's ------------------------------------------
def _recorded(run):
    ports = ("plant.x_B", "plant.E_in", "plant.E_fric", "controller.iq_ref", "controller.S", "controller.phase")
    return dataclasses.replace(run, system=Wiring(record=tuple(Port.parse(p) for p in ports)))


def test_a_system_run_has_the_pair_s_summary_warnings_and_solver_statistics(plants) -> None:
    """T_h and S0 from its native controller, the plausibility flags (a 2 A rating: the command
    exceeds it), the plant's solver counts."""
    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    run = dataclasses.replace(run, t_end=0.2, plant=dataclasses.replace(run.plant, rated_current=2.0))
    fixed = master.simulate(run, plants["plant"])
    system = master.simulate(_recorded(run), plants["plant"])
    assert system.complete, system.reason
    assert system.summary == fixed.summary and system.summary.hitting_time_s is not None
    assert system.warnings == fixed.warnings and system.warnings[0].startswith("|i_q*| exceeds the rated current 2 A")
    assert system.record["solver_statistics"] == fixed.record["solver_statistics"]
    assert isinstance(system.record["solver_statistics"], dict)


def test_the_pair_s_budget_ends_the_execution_at_the_pair_s_sample(
    plants, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The pair counts the plant's work after its first sample and every 200 samples from there
    (t = 0.1 s at 0.5 ms); the execution at the same samples, with the same reason and trace."""
    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    run = dataclasses.replace(run, t_end=0.3, resolved={**run.resolved, "budget": {"steps": 50}})
    fixed, executed = _both(run, plants["plant"], monkeypatch)
    assert fixed.reason is not None and "budget.steps) by t = 0.1 s" in fixed.reason
    _same_files(fixed, executed, tmp_path)


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
    every step) or answering NaN (nan): the same trace, retries, warnings and reason."""
    from fault_plants import fault_environment, make_faulty_fmu

    faulty = check_plant(make_faulty_fmu(plant_fmu, tmp_path / f"{kind}.fmu"))
    environment = fault_environment(kind, 0.1, faulty.references)
    for name in ("TOGGLE_FAULT_KIND", "TOGGLE_FAULT_TIME", "TOGGLE_FAULT_MIN_FE", "TOGGLE_FAULT_FE_VR"):
        monkeypatch.setenv(name, environment[name])
    monkeypatch.setenv("TOGGLE_FAULT_END", repr(end))
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.3)
    fixed, executed = _both(run, faulty, monkeypatch)
    assert not fixed.complete and fixed.reason.startswith(reason), fixed.reason
    assert bool(fixed.record["retries"]) == (kind != "nan")
    _same_files(fixed, executed, tmp_path / "files")


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


def test_a_controller_that_raises_fails_the_run_in_the_pair_s_words(
    plants, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """ "controller failed: the controller's step raised at t = 0.005 s: ...", the same trace."""
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.02)
    fixed, executed = _both(run, plants["plant"], monkeypatch, controller=_RaisesAt())
    assert fixed.reason.startswith("controller failed: the controller's step raised at t = 0.005 s"), fixed.reason
    _same_files(fixed, executed, tmp_path)
