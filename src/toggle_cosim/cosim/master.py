"""The co-simulation master: a run of a scenario or an SSP, checked (`check`), then simulated
(`simulate`).

`check` resolves and checks the run in the process that starts it (`checked.check_run`: its
components, controller, connections, units, order, plan and columns; no binary loaded) and
builds its controller.python there (`systems.ready`). `simulate` only instantiates and steps
what was checked (`systems.execute`): its components stepped in the order of its connections,
in the compiled system loop where it can, with checkpoint retries of every component
(`system_retry`) and, given a pool, its FMU instances kept loaded from run to run
(`instance_pool`). A supervised run is checked in the parent and simulated in its child
(`isolation.supervision`); `check_and_simulate` does both in this process. The plain pair, a
plant FMU and its controller (a scenario without `components:`, `connections:` or `record:`,
and an SSP of exactly that loop), is the two-part system it is, run with the pair's trace
columns and run.json (`pair_execution`).
"""

from __future__ import annotations

import dataclasses
import time as clock
from collections.abc import Callable

import numpy as np

from toggle_cosim.control.protocol import Controller, ControllerError
from toggle_cosim.cosim.checked import CheckedRun, check_run
from toggle_cosim.cosim.execution.instance_pool import InstancePool
from toggle_cosim.cosim.execution.system_retry import CheckpointOptions
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.cosim.pair_execution import close_controller, refused_outcome, simulate_pair_as_system, trace_names
from toggle_cosim.cosim.plant_inputs import input_samples, other_inputs, plant_settings
from toggle_cosim.cosim.systems import execute, ready
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import COUPLINGS, Run

__all__ = [
    "RunOutcome",
    "check",
    "check_and_simulate",
    "close_controller",
    "input_samples",
    "other_inputs",
    "plant_settings",
    "refused_outcome",
    "simulate",
    "trace_names",
]


def check(
    run: Run,
    plant: PlantInterface,
    controller: Controller | None = None,
    coupling: str | None = None,
    checked: CheckedRun | None = None,
    started: float | None = None,
) -> CheckedRun | RunOutcome:
    """`run` against `plant` checked (`checked.check_run`, with `controller`, any object that
    meets the controller protocol, None: the run's own; `coupling`, "gauss-seidel" or "jacobi",
    None: the run's own) and its controller.python built in this process (`systems.ready`):
    what `simulate` runs. `checked`: the run as `checked.check_run` checked it (with `run`,
    `plant`, `controller` and `coupling`) by a caller that checked it before (a command checks
    every run before the first starts): only its controller.python is built here. A controller
    that cannot be built or checked gives the failed run's outcome instead (`refused_outcome`;
    `started`: the run's perf_counter() start, None: now). Raises ValueError for an unknown
    coupling, SystemError_ for a system that cannot run as written."""
    if coupling is not None and coupling not in COUPLINGS:
        raise ValueError(f"coupling: choose one of {', '.join(COUPLINGS)}, not {coupling!r}")
    started = clock.perf_counter() if started is None else started
    try:
        return ready(checked if checked is not None else check_run(run, plant, controller, coupling))
    except ControllerError as error:
        close_controller(controller)
        return refused_outcome(dataclasses.replace(run, coupling=coupling or run.coupling), plant, str(error), started)


def simulate(
    run: CheckedRun,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    pool: InstancePool | None = None,
    checkpoints: CheckpointOptions | None = None,
    started: float | None = None,
) -> RunOutcome:
    """Instantiate and step `run`, checked and complete (`check`; in a supervised run's child,
    as the parent checked it and the child built its controller): nothing is checked here.
    Never raises for a plant, part or controller fault: see RunOutcome.

    `buffer`, if given, is the trace's storage ((steps + 1) x columns, filled with NaN), and
    `count`, if given, the one int64 the number of samples recorded is kept in as they are
    recorded (both shared with a supervising process, `supervision`). `calling`: where the
    execution writes which component it calls (`systems.execute`). `pool` (`instance_pool`):
    the FMU components' instances, the plant's included, kept loaded from run to run by the
    caller. `checkpoints`: how a refused step is retried (`system_retry.CheckpointOptions`;
    None: every 200 samples, in 10 substeps). `started`: the run's perf_counter() start (None:
    now)."""
    if not isinstance(run, CheckedRun):
        raise TypeError(
            f"simulate takes a checked run (master.check), not {type(run).__name__}: "
            "for a run and its plant, call master.check_and_simulate(run, plant, ...)"
        )
    if run.pair:
        return simulate_pair_as_system(run, progress, buffer, count, calling, pool, checkpoints, started)
    return execute(run, progress, buffer, count, calling, checkpoints, pool, started=started)


def check_and_simulate(
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
    checkpoints: CheckpointOptions | None = None,
) -> RunOutcome:
    """One run in this process: `check`, then `simulate` (arguments as theirs); a controller
    that cannot be built or checked fails the run."""
    started = clock.perf_counter()
    ready_run = check(run, plant, controller, coupling, checked, started)
    if isinstance(ready_run, RunOutcome):
        return ready_run
    return simulate(ready_run, progress, buffer, count, calling, pool, checkpoints, started)
