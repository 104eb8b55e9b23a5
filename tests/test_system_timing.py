"""A system sends a signal-fed input when the pair does: after the component's outputs at t_k are
read, with the values it steps with (`system.plan`). So a scenario run as the pair and the same
scenario run as a system (`record:` added) give the same trace, every column bit for bit, for
loads that change during the run: a step, a measured table and a sine, under Gauss-Seidel and
Jacobi, in the compiled system loop and in the Python execution.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim.cosim import master
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.model import Port, Wiring

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"


@pytest.fixture(scope="module")
def plant(plant_fmu: Path):
    return check_plant(plant_fmu)


def _sine_load(folder: Path) -> Path:
    """step_load with F_E a sine about 50 N: the load changes at every sample from t = 0."""
    text = (SCENARIOS / "step_load.yaml").read_text(encoding="utf-8")
    text = text.replace("fmu: ../fmus/ToggleLSM.fmu", f"fmu: {ROOT / 'fmus' / 'ToggleLSM.fmu'}")
    text = text.replace(
        "F_E: {kind: step, start_time: 0.25, height: 100.0}",
        "F_E: {kind: sine, amplitude: 40.0, frequency: 20.0, offset: 50.0}",
    )
    assert "kind: sine" in text
    path = folder / "sine_load.yaml"
    path.write_text(text, encoding="utf-8")
    return path


# the scenario (None: the sine, written per test) and the end of the window, which holds the load's change
LOADS = {
    "step_load": (SCENARIOS / "step_load.yaml", 0.3),  # 0 -> 100 N at t = 0.25 s
    "measured_load": (SCENARIOS / "measured_load.yaml", 0.4),  # contact from t = 0.30 s
    "sine_load": (None, 0.1),
}


def _system_port(name: str, run, plant) -> Port:
    """The system's port of the pair's trace column `name`: the plant's outputs and inputs (F_E,
    the others) are the plant's, the command and the diagnostics the controller's."""
    if name in plant.recorded_outputs or name == "F_E" or name in run.plant.inputs:
        return Port("plant", name)
    return Port("controller", name)


def first_difference(pair, system, ports) -> str | None:
    """Where the two traces first differ (the column, the sample and both values), or None."""
    columns = [("time", "time"), *((name, str(port)) for name, port in ports)]
    for ours, theirs in columns:
        a, b = pair.trace.column(ours), system.trace.column(theirs)
        if a.shape != b.shape:
            return f"{ours}: {a.shape[0]} samples in the pair, {b.shape[0]} in the system"
        unequal = np.flatnonzero(a != b)
        if unequal.size:
            k = int(unequal[0])
            return (
                f"{ours} first differs at sample {k} (t = {pair.trace.time[k]:.6g} s): pair {a[k]!r}, system {b[k]!r}"
            )
    return None


@pytest.mark.parametrize("engine", ["compiled", "python"])
@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("load", list(LOADS))
def test_a_system_run_records_the_pairs_trace_in_every_column(
    plant, tmp_path: Path, load: str, coupling: str, engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 34, item 2: with `record:` of every column of the pair's trace (all plant outputs,
    the command, the loads, the controller's diagnostics), the system's trace equals the pair's,
    column by column, sample by sample, while the load changes (at the step of step_load the
    plant's N12 differed by 38 N when the system set F_E before it read the outputs)."""
    path, t_end = LOADS[load]
    run = load_scenario(path or _sine_load(tmp_path))[0]
    run = dataclasses.replace(run, t_end=t_end, coupling=coupling)
    pair = master.check_and_simulate(run, plant)
    assert pair.complete, pair.reason
    # the load changes inside the window, so its timing is what the comparison checks
    assert np.unique(pair.trace.column("F_E")).size > 1
    ports = [(name, _system_port(name, run, plant)) for name in pair.trace.names[1:]]
    if engine == "python":
        monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    system = master.check_and_simulate(
        dataclasses.replace(run, system=Wiring(record=tuple(port for _, port in ports))), plant
    )
    assert system.complete, system.reason
    assert system.record["loop"]["kind"] == f"system, {engine}"
    assert system.trace.names == ("time", *(str(port) for _, port in ports))
    difference = first_difference(pair, system, ports)
    assert difference is None, difference
