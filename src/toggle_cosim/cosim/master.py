"""The co-simulation master: `simulate` runs one run of a scenario or an SSP.

A run's system (`Run.system`) decides how it is stepped:

* the plain pair, a plant FMU and its controller (a scenario without `components:`,
  `connections:` or `record:`, and an SSP of exactly that loop): the pair's fixed loop
  (`pair.simulate_pair`, with the compiled law, hand-back to Python, checkpoint retries and a
  plant session kept across runs);
* any other system: checked once (`checked.check_run`: components, controller, connections,
  units, order, plan, columns; nothing loaded), then executed (`systems.execute`): its
  components instantiated and stepped in the order of its connections, in the compiled system
  loop where every component is an FMU, with checkpoint retries of every component
  (`system_retry`) and, given a pool, its FMU instances kept loaded from run to run
  (`instance_pool`). A caller that checked the run before (a supervising process, before it
  forks the run's child) passes the result (`checked=`) and nothing is checked again.

The pair run as a system gives the fixed loop's values bit for bit (tests/test_systems.py).
With TOGGLE_COSIM_MASTER=execution (`limits.pair_as_execution`; default: the fixed loop) the
plain pair runs as that two-part system in the execution, with the fixed loop's trace columns and
run.json (`pair_execution`); a kept plant `session` is then not used (the execution loads its own).
"""

from __future__ import annotations

import dataclasses
import time as clock
from collections.abc import Callable

import numpy as np

from toggle_cosim import limits
from toggle_cosim.control.protocol import Controller, ControllerError
from toggle_cosim.cosim.checked import CheckedRun, check_run
from toggle_cosim.cosim.instance_pool import InstancePool
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.cosim.pair import (
    JACOBI_REASON,
    close_controller,
    open_session,
    refused_outcome,
    simulate_pair,
    trace_names,
)
from toggle_cosim.cosim.pair_execution import simulate_pair_as_system
from toggle_cosim.cosim.plant_inputs import input_samples, other_inputs, plant_settings
from toggle_cosim.cosim.session import PlantSession
from toggle_cosim.cosim.systems import execute, ready, refused
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import COUPLINGS, Run

__all__ = [
    "JACOBI_REASON",
    "RunOutcome",
    "close_controller",
    "input_samples",
    "other_inputs",
    "open_session",
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
    session: PlantSession | None = None,
    coupling: str | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    pool: InstancePool | None = None,
    checked: CheckedRun | None = None,
) -> RunOutcome:
    """Run one scenario variant against `plant`: the plain pair in its fixed loop, any other
    system as an execution of its components (module docstring). Never raises for a plant, part
    or controller fault: see RunOutcome.

    `controller`: any object that meets the controller protocol (`control.protocol`); None: the
    run's own. `buffer`, if given, is the trace's storage ((steps + 1) x columns, filled with NaN),
    and `count`, if given, the one int64 the number of samples recorded is kept in as they are
    recorded (both shared with a supervising process, `supervision`).
    `session` (the plain pair only, `open_session`): a plant already loaded that the caller keeps.
    `coupling`: "gauss-seidel" or "jacobi"; None: the run's own (`Run.coupling`). `calling`
    (a system only): where the execution writes which component it calls
    (`systems.simulate_system`). `pool` (a system only, `instance_pool`): its FMU components'
    instances, kept loaded from run to run by the caller. `checked`: the run as `checked.check_run`
    checked it (with `run`, `plant`, `controller` and `coupling`), by a caller that checked it
    before (a supervising process before the fork); None: checked here. A controller.python
    still to be built is built here (`systems.ready`)."""
    if run.system.is_pair and not limits.pair_as_execution():
        return simulate_pair(run, plant, progress, buffer, controller, session, coupling, count)
    if coupling is not None and coupling not in COUPLINGS:
        raise ValueError(f"coupling: choose one of {', '.join(COUPLINGS)}, not {coupling!r}")
    if session is not None and not run.system.is_pair:
        close_controller(controller)
        raise ValueError("a system's run loads its own components: simulate it without session=")
    started = clock.perf_counter()
    try:
        if checked is None:
            checked = check_run(run, plant, controller, coupling)
        checked = ready(checked)  # a controller.python built here, in this process
    except ControllerError as error:
        close_controller(controller)
        if run.system.is_pair:
            return refused_outcome(run, plant, str(error), started)
        return refused(dataclasses.replace(run, coupling=coupling or run.coupling), plant, error, started)
    if checked.pair:
        return simulate_pair_as_system(checked, progress, buffer, count, calling, started)
    return execute(checked, progress, buffer, count, calling, pool=pool, started=started)
