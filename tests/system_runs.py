"""A system run with the execution's options set by the test (a test helper): the run checked
as every run is (`master.check`), then executed by `systems.execute` with the given checkpoint
options, which `master.simulate` leaves at their defaults."""

from __future__ import annotations

from toggle_cosim.control.protocol import Controller
from toggle_cosim.cosim import master
from toggle_cosim.cosim.execution.system_retry import CheckpointOptions
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.cosim.systems import execute
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run


def simulate_system(
    run: Run,
    plant: PlantInterface,
    controller: Controller | None = None,
    coupling: str | None = None,
    checkpoints: CheckpointOptions | None = None,
) -> RunOutcome:
    """`run` on `plant` checked and executed as a system (a plain pair too, with the system's
    columns and run.json); a controller that cannot be built or checked: the refused outcome."""
    checked = master.check(run, plant, controller, coupling)
    if isinstance(checked, RunOutcome):
        return checked
    return execute(checked, checkpoints=checkpoints)
