"""A run is checked once, in the process that starts it (`cosim.checked.check_run`): a
supervised run's parent checks it before the fork and its child only instantiates and steps what
was checked; the check loads no binary and runs no code of the user's, so a controller.python is
left for the run's child to build.
"""

from __future__ import annotations

import dataclasses
import os
import sys
from pathlib import Path

import pytest

from toggle_cosim.cosim import controllers
from toggle_cosim.cosim.isolation.supervised_batch import run_supervised
from toggle_cosim.cosim.isolation.supervision import probe_columns, simulate_supervised
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.model import Port, Wiring

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def plant(plant_fmu: Path):
    return check_plant(plant_fmu)


def _fmu_run(vsc_fmu: Path):
    """fig5's run, 0.05 s of it, with the built-in law's controller FMU."""
    run = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0]
    return dataclasses.replace(run, t_end=0.05, controller=dataclasses.replace(run.controller, fmu=vsc_fmu))


def _reads(monkeypatch: pytest.MonkeyPatch, log: Path) -> None:
    """Each read of a controller FMU's contract appends the reading process's id to `log`: a
    line written in a run's child is there for the parent to read."""
    real = controllers.check_controller_fmu

    def counted(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        with open(log, "a", encoding="utf-8") as stream:
            stream.write(f"{os.getpid()}\n")
        return real(*args, **kwargs)

    monkeypatch.setattr(controllers, "check_controller_fmu", counted)


@pytest.mark.parametrize("system", ["pair", "record"])
def test_a_supervised_run_is_checked_once_in_its_parent_and_never_in_its_child(
    plant, vsc_fmu: Path, system: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The controller FMU's contract is read once, by the supervising process, for the plain
    pair and for a system with a `record:` list; the child that runs it reads it no more, and
    the run completes."""
    run = _fmu_run(vsc_fmu)
    if system == "record":
        run = dataclasses.replace(run, system=Wiring(record=(Port("plant", "x_B"), Port("controller", "iq_ref"))))
    log = tmp_path / "reads.txt"
    _reads(monkeypatch, log)
    outcome = simulate_supervised(run, plant, scratch=tmp_path)
    assert outcome.complete, outcome.reason
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())]


@pytest.mark.parametrize("system", ["pair", "record"])
@pytest.mark.parametrize("law", ["built-in", "fmu"])
def test_simulate_steps_what_was_checked_and_checks_nothing(
    plant, vsc_fmu: Path, system: str, law: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`master.simulate` takes a checked run and only instantiates and steps it: with the check,
    the controller's resolution, the contract reads and the controller.python build all made to
    fail, a run checked before runs to the end, twice, with the trace bit for bit that of
    `check_and_simulate` (which checks it itself)."""
    from toggle_cosim.cosim import checked as checked_module
    from toggle_cosim.cosim import master, systems
    from toggle_cosim.plant import contract

    run = _fmu_run(vsc_fmu)
    if law == "built-in":
        run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=None))
    if system == "record":
        run = dataclasses.replace(run, system=Wiring(record=(Port("plant", "x_B"), Port("controller", "iq_ref"))))
    whole = master.check_and_simulate(run, plant)
    checked = master.check(run, plant)
    assert not isinstance(checked, master.RunOutcome) and checked.complete

    def checks_again(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("simulate checked the run again")

    for owner, name in (
        (checked_module, "check_run"),
        (checked_module, "built"),
        (master, "check_run"),
        (systems, "ready"),
        (controllers, "own_controller"),
        (controllers, "check_controller_fmu"),
        (contract, "read_fmu"),
    ):
        monkeypatch.setattr(owner, name, checks_again)
    for _ in range(2):
        outcome = master.simulate(checked)
        assert outcome.complete, outcome.reason
        assert outcome.trace.names == whole.trace.names
        assert outcome.trace.data.tobytes() == whole.trace.data.tobytes()


def test_simulate_checks_a_run_once_for_its_refusals_and_its_run(
    plant_fmu: Path, vsc_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`tc.simulate` refuses bad input before the run starts with the same check the run then
    uses: one contract read in all, by this process, the run's child none."""
    import toggle_cosim as tc

    run = dataclasses.replace(_fmu_run(vsc_fmu), system=Wiring(record=(Port("plant", "x_B"),)))
    log = tmp_path / "reads.txt"
    _reads(monkeypatch, log)
    result = tc.simulate(run, plant_fmu)
    assert result.status == "complete", result.reason
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())]


def test_runs_at_once_are_each_checked_once_in_the_parent(
    plant, vsc_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three system runs, two at a time (`supervised_batch`): three contract reads, all by the
    supervising process, none by the children; every run completes."""
    run = _fmu_run(vsc_fmu)
    runs = [dataclasses.replace(run, system=Wiring(record=(Port("plant", "x_B"),)), t_end=0.02) for k in range(3)]
    log = tmp_path / "reads.txt"
    _reads(monkeypatch, log)
    outcomes = list(run_supervised([(r, plant) for r in runs], jobs=2, scratch=tmp_path))
    assert [outcome.complete for outcome in outcomes] == [True] * 3, [o.reason for o in outcomes]
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())] * 3


def test_columns_the_check_knows_are_probed_without_a_child(
    plant, vsc_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A system's columns with a controller FMU come from the parent's check: one contract read,
    here, and the FMU's diagnostics among the pair's columns."""
    log = tmp_path / "reads.txt"
    _reads(monkeypatch, log)
    columns = probe_columns(_fmu_run(vsc_fmu), plant)
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())]
    assert columns[:3] == ("time", *plant.recorded_outputs[:2]) and "iq_ref" in columns


def test_the_check_leaves_a_controller_python_unimported(plant, tmp_path: Path) -> None:
    """A controller.python beside the scenario is found and its ownership checked, never
    imported: the check stops before what only the built controller can tell (its columns)."""
    (tmp_path / "never_imported_law.py").write_text("raise SystemExit('imported')\ndef make(context): ...\n")
    scenario = tmp_path / "law.yaml"
    scenario.write_text(
        "name: law\nt_end: 0.01\nT_s: 0.0005\nstroke: {x_start: 0.2329, x_target: 0.3199}\n"
        "controller: {python: 'never_imported_law:make'}\n"
    )
    from toggle_cosim.cosim.checked import check_run

    (run,) = load_scenario(scenario)
    checked = check_run(run, plant)
    assert checked.builds_controller and not checked.complete and checked.names == ()
    assert "never_imported_law" not in sys.modules


def _fmu_scenario(folder: Path, vsc_fmu: Path, variants: int = 1) -> Path:
    """A short scenario with the built-in law's controller FMU, `variants` variants of it."""
    import yaml

    document = {
        "name": "fmu_law",
        "t_end": 0.02,
        "T_s": 0.0005,
        "stroke": {"x_start": 0.2329, "x_target": 0.3199},
        "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
        "controller": {"fmu": str(vsc_fmu)},
    }
    if variants > 1:
        document["variants"] = {f"v{k}": {"plant": {"F_E": 10.0 * k}} for k in range(variants)}
    path = folder / "fmu_law.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


def test_a_sweep_checks_each_case_once_in_its_process_and_its_host_never(
    plant_fmu: Path, vsc_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sweep of four cases with a controller FMU: four contract reads, one per case, all by
    the sweep's process (before the cases start, or as each is handed to its plant host); the
    host that runs them reads none, and every case is ok."""
    import yaml

    from toggle_cosim.experiments.sweep import execute_sweep, load_sweep, read_results

    _fmu_scenario(tmp_path, vsc_fmu)
    sweep_file = tmp_path / "sweep.yaml"
    sweep_file.write_text(
        yaml.safe_dump({"base": "fmu_law.yaml", "axes": {"plant.F_E": {"values": [0, 10, 20, 30]}}, "output": "out"}),
        encoding="utf-8",
    )
    log = tmp_path / "reads.txt"
    _reads(monkeypatch, log)
    sweep = load_sweep(sweep_file)
    result = execute_sweep(sweep, fmu=plant_fmu, workers=1, progress=False)
    table = read_results(sweep.output)
    assert (result.ran, result.failed) == (4, 0) and (table["status"] == "ok").all(), list(table["reason"])
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())] * 4


def test_the_run_command_checks_each_run_once_in_its_process(
    plant_fmu: Path, vsc_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`toggle-cosim run` of a scenario with three variants and a controller FMU, two at a
    time: three contract reads, one per run, all by the command's process (the check before any
    run starts is the one the run uses); the runs' children read none, and all complete."""
    from click.testing import CliRunner

    from toggle_cosim.cli import main

    scenario = _fmu_scenario(tmp_path, vsc_fmu, variants=3)
    log = tmp_path / "reads.txt"
    _reads(monkeypatch, log)
    out = tmp_path / "out"
    args = ["run", str(scenario), "--fmu", str(plant_fmu), "--out", str(out), "-q", "--jobs", "2"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert log.read_text(encoding="utf-8").split() == [str(os.getpid())] * 3


def test_simulate_refuses_a_run_that_was_not_checked(plant) -> None:
    """`master.simulate` takes what `master.check` returns; given a scenario's run (as its
    earlier form took), it says which call to make instead."""
    from toggle_cosim.cosim import master

    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    with pytest.raises(TypeError, match=r"master\.check_and_simulate\(run, plant"):
        master.simulate(run, plant)
