"""The co-simulation master: `simulate` runs one run of a scenario or an SSP.

Every run is first checked (`checked.check_run`: its components, controller, connections, units,
order, plan and columns; nothing loaded, no code of the user's run), then executed
(`systems.execute`): its components instantiated and stepped in the order of its connections, in
the compiled system loop where it can, with checkpoint retries of every component
(`system_retry`) and, given a pool, its FMU instances kept loaded from run to run
(`instance_pool`). A caller that checked the run before (a supervising process, before it forks
the run's child) passes the result (`checked=`) and nothing is checked again. The plain pair, a
plant FMU and its controller (a scenario without `components:`, `connections:` or `record:`, and
an SSP of exactly that loop), is the two-part system it is, run with the pair's trace columns and
run.json (`pair_execution`).
"""

from __future__ import annotations

import dataclasses
import time as clock
from collections.abc import Callable

import numpy as np

from toggle_cosim.control.protocol import Controller, ControllerError
from toggle_cosim.cosim.checked import CheckedRun, check_run
from toggle_cosim.cosim.execution.instance_pool import InstancePool
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.cosim.pair_execution import close_controller, refused_outcome, simulate_pair_as_system, trace_names
from toggle_cosim.cosim.plant_inputs import input_samples, other_inputs, plant_settings
from toggle_cosim.cosim.systems import execute, ready
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import COUPLINGS, Run

__all__ = [
    "RunOutcome",
    "close_controller",
    "input_samples",
    "other_inputs",
    "plant_settings",
    "refused_outcome",
    "simulate",
    "trace_names",
]


def simulate(
    run: Run,
    plant: PlantInterface,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    controller: Controller | None = None,
    coupling: str | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    pool: InstancePool | None = None,
    checked: CheckedRun | None = None,
) -> RunOutcome:
    """Run one scenario variant against `plant`: its system checked, then executed (module
    docstring). Never raises for a plant, part or controller fault: see RunOutcome.

    `controller`: any object that meets the controller protocol (`control.protocol`); None: the
    run's own. `buffer`, if given, is the trace's storage ((steps + 1) x columns, filled with NaN),
    and `count`, if given, the one int64 the number of samples recorded is kept in as they are
    recorded (both shared with a supervising process, `supervision`).
    `coupling`: "gauss-seidel" or "jacobi"; None: the run's own (`Run.coupling`). `calling`:
    where the execution writes which component it calls (`systems.execute`). `pool`
    (`instance_pool`): the FMU components' instances, the plant's included, kept loaded from run
    to run by the caller. `checked`: the run as `checked.check_run` checked it (with `run`,
    `plant`, `controller` and `coupling`), by a caller that checked it before (a supervising
    process before the fork); None: checked here. A controller.python still to be built is
    built here (`systems.ready`)."""
    if coupling is not None and coupling not in COUPLINGS:
        raise ValueError(f"coupling: choose one of {', '.join(COUPLINGS)}, not {coupling!r}")
    started = clock.perf_counter()
    try:
        if checked is None:
            checked = check_run(run, plant, controller, coupling)
        checked = ready(checked)  # a controller.python built here, in this process
    except ControllerError as error:
        close_controller(controller)
        return refused_outcome(dataclasses.replace(run, coupling=coupling or run.coupling), plant, str(error), started)
    if checked.pair:
        return simulate_pair_as_system(checked, progress, buffer, count, calling, pool=pool, started=started)
    return execute(checked, progress, buffer, count, calling, pool=pool, started=started)
