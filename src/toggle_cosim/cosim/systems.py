"""A system's run: the components of a checked run (`checked.CheckedRun`) instantiated and
stepped by an `Execution` (execution.py), and its outcome.

Every run's system is stepped here, the plain pair's too (through `pair_execution`).
What a run is made of (the plant, the controller, the parts, the signals), how its connections,
units, order and record are checked and its plan built is `checked.check_run`'s, in the process
that starts the run; here those components become slaves and are stepped:

* an FMU component (the plant, a controller FMU, a part) as an `FmuSlave`, its instance loaded
  here or taken from a pool (`instance_pool`);
* any other controller (the built-in law, a user's Python controller, a python-control system)
  natively (`ControllerSlave`; the built-in law and a python-control system then run in C in the
  compiled system loop: `system_natives`).

Either loop runs in stretches between checkpoints (`system_retry.SystemCheckpoints`): a
component's refused step is retried from the last one, and run.json lists each retry
(`retries`) and says whether retries are on (`system.checkpoints`).

A controller FMU runs with the execution's finiteness guard (`guard.controller_guard`, made by
the check): a value it would measure that is not finite, or a command it gives that is not, ends
the run at that sample, in both loops, as a native controller's own check does.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from toggle_cosim.control.protocol import Controller
from toggle_cosim.cosim.checked import (
    CheckedRun,
    FmuComponent,
    SystemError_,
    built,
    check_run,
    component_names,
    pair_connections,
    unit_conversion,
)
from toggle_cosim.cosim.controllers import user_controller
from toggle_cosim.cosim.execution.algorithm import Execution, TraceObserver
from toggle_cosim.cosim.execution.budget import BudgetExceeded, WorkBudget
from toggle_cosim.cosim.execution.instance_pool import InstancePool
from toggle_cosim.cosim.execution.slaves import ControllerSlave, FmuSlave, Slave, SlaveError
from toggle_cosim.cosim.execution.system_loop import FMI_FAILED, HAND_BACK, NOT_FINITE, SystemLoop, compiled_system
from toggle_cosim.cosim.execution.system_retry import CheckpointOptions, FailureWords, SystemCheckpoints
from toggle_cosim.cosim.figures import run_figures
from toggle_cosim.cosim.outcome import RunOutcome, Stepping, run_record
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import bounded_text
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run
from toggle_cosim.system.model import Connection
from toggle_cosim.system.plan import Plan

__all__ = [
    "SystemError_",
    "Assembly",
    "assemble",
    "component_names",
    "execute",
    "instantiate",
    "pair_connections",
    "ready",
    "system_columns",
    "unit_conversion",
]


@dataclass
class Assembly:
    """A run's system ready to step: its slaves (in stepping order), plan, signal table and
    connections, and what run.json says of its components."""

    slaves: list[Slave]
    plan: Plan
    signals: np.ndarray
    connections: tuple[Connection, ...]
    components: list[dict[str, Any]]
    units: dict[str, str]  # {column: unit} of the recorded columns that declare one

    def close(self, reuse: bool = False) -> None:
        """Free every component; FMU components taken from a pool go back to it, reset for the
        next run when `reuse` (the run was complete), else freed (`instance_pool`)."""
        for slave in self.slaves:
            if isinstance(slave, FmuSlave):
                slave.close(reuse)
            else:
                slave.close()


def ready(checked: CheckedRun) -> CheckedRun:
    """`checked` with its controller.python built here, in this process (`controllers.user_controller`:
    the user's factory runs), and checked (`checked.built`); a checked run that needs no
    building as it is. A run's supervised child builds it itself (`supervision`). Raises
    ControllerError or SystemError_."""
    if not checked.builds_controller:
        return checked
    return built(checked, user_controller(checked.run, checked.plant.recorded_outputs))


def instantiate(checked: CheckedRun, pool: InstancePool | None = None) -> Assembly:
    """The slaves of a complete checked run, in its stepping order (nothing is loaded until the
    execution initialises them): an FMU component as an `FmuSlave` (its instance from `pool`
    when given), a native controller as a `ControllerSlave`."""
    assert checked.plan is not None and checked.signals is not None
    slaves: dict[str, Slave] = {}
    for component in checked.components:
        assert component is not None
        if isinstance(component, FmuComponent):
            slaves[component.name] = FmuSlave(
                component.name, component.fmu, component.values, pool=pool, interface=component.interface
            )
        else:
            slaves[component.name] = ControllerSlave(
                component.name, component.controller, component.diagnostics, component.interface
            )
    return Assembly(
        [slaves[name] for name in checked.order],
        checked.plan,
        checked.signals,
        checked.connections,
        [dict(record) for record in checked.records],
        dict(checked.units),
    )


def assemble(
    run: Run,
    plant: PlantInterface,
    controller: Controller | None = None,
    coupling: str | None = None,
    pool: InstancePool | None = None,
) -> Assembly:
    """The run's system checked (`checked.check_run`, its controller.python built here: `ready`)
    and its slaves made (`instantiate`). Raises SystemError_ (one line) for a system that cannot
    run as written, ControllerError for a controller that cannot be built."""
    return instantiate(ready(check_run(run, plant, controller, coupling)), pool)


def system_columns(run: Run, plant: PlantInterface, controller: Controller | None = None) -> tuple[str, ...]:
    """The trace columns of a system run (the plan's recorded ports), without running it (a
    controller.python is built here: `ready`)."""
    return ready(check_run(run, plant, controller)).names


def _compiled_forward(
    loop: SystemLoop,
    slaves: Sequence[Slave],
    n: int,
    progress: Callable[[float], None] | None,
    run: Run,
    execution: Execution,
) -> tuple[Callable[[int, int], int], Callable[[], int | None]]:
    """Samples k .. stop - 1 in C (`forward`), in stretches of 1 % for the progress hook; a failed
    call raises the SlaveError the Python execution raises for it (with the FMU's last log line,
    its `k` the sample). The loop counts the rows it records in the observer's count.

    The native controllers' slaves and the C's memory hold the same thing whenever `forward` is
    not running: it gives the C what the slaves hold as it starts (a checkpoint put back, a sample
    the Python execution retook) and the slaves what the C holds as it returns (a checkpoint
    saved next). A sample a native controller hands back goes, with every later one, to the
    Python `execution`; `handed()` is that sample (None: none was)."""
    every = max(n // 100, 1) if progress is not None else n + 1
    handed: list[int] = []

    def forward(k: int, stop: int) -> int:
        if handed:
            return execution.advance(k, stop)
        loop.hand_over()
        while k < stop:
            code, k_next = loop.run(k, min(k + every - k % every, stop))
            if code == FMI_FAILED:
                error = loop.failure()
                slave = slaves[loop.plan.order.index(error.component)]
                failure = getattr(slave, "failure", None)
                raised = failure(error.function, error.t, error.status) if callable(failure) else SlaveError(str(error))
                raised.k = k_next
                raise raised
            if code == NOT_FINITE:
                raise loop.refusal()
            if code == HAND_BACK:
                loop.give_back()
                handed.append(k_next)
                return execution.advance(k_next, stop)
            k = k_next
            if progress is not None and (k % every == 0 or k > n):
                progress(min(k, n) * run.T_s / run.t_end)
        loop.take_back()
        return k

    return forward, lambda: handed[0] if handed else None


def plant_statistics(slave: Slave) -> dict[str, int] | str | None:
    """The plant component's solver counts now (`FmuSlave.solver_statistics`), None if it has none."""
    read = getattr(slave, "solver_statistics", None)
    return read() if callable(read) else None


def _controller_state(slaves: Sequence[Slave], name: str, controller: object) -> object:
    """What gives the run's T_h and S0 (`figures.run_figures`): a native controller's state as
    the run left it, else the controller given."""
    for slave in slaves:
        if slave.name == name and isinstance(slave, ControllerSlave):
            return slave.sample_state().state
    return controller


def loop_words(stepping: Stepping, components: int, plan: Plan, T_s: float) -> dict[str, str]:
    """run.json's `loop`: its kind ("system, compiled" or "system, python") and, in words, how
    the execution stepped the run's `components` in the plan's order (`stepping`)."""
    coupled = "jacobi" if plan.jacobi else "gauss-seidel"
    where = f"in Python ({stepping.why_python})"
    if stepping.compiled:
        parts = [f"{', '.join(stepping.natives)} natively in C"] if stepping.natives else []
        parts += [f"{name} in Python, called back from C ({why})" for name, why in stepping.called_back]
        where = "in the compiled system loop" + (f" ({'; '.join(parts)})" if parts else "")
        if stepping.handed_back is not None:
            where += (
                f", from t = {stepping.handed_back * T_s:.6g} s in Python (a sample the native controller handed back)"
            )
    return {
        "kind": "system, compiled" if stepping.compiled else "system, python",
        "reason": f"{components} components, {coupled}, in the order {', '.join(plan.order)}, {where}",
    }


def execute(
    checked: CheckedRun,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    checkpoints: CheckpointOptions | None = None,
    pool: InstancePool | None = None,
    words: FailureWords | None = None,
    started: float | None = None,
) -> RunOutcome:
    """Run a complete checked system (module docstring): instantiate and step its components;
    never raises for a component's failure: the outcome is failed with the reason and the
    trace up to the last complete sample. `calling` (an int64 array, e.g. a word shared with a
    supervising process): element 0 holds, while a component is called, its id
    (`component_names`), and 0 outside the run's loop. `checkpoints`: how a refused step is
    retried (`system_retry`; default every 200 samples, in 10 substeps), `words` how failures
    are said (`system_retry.FailureWords`; default each names its component). `pool`: the FMU
    components' instances kept from run to run (`instance_pool`), reset after a complete run.
    `started`: the run's perf_counter() start (None: now)."""
    started = clock.perf_counter() if started is None else started
    run, plant = checked.run, checked.plant
    n = run.steps
    assembly = instantiate(checked, pool)
    plan = assembly.plan
    data = buffer if buffer is not None else np.full((n + 1, len(plan.names)), np.nan)
    observer = TraceObserver(plan, data, count)
    hooks = []
    if progress is not None:
        every = max(n // 100, 1)
        hooks.append(lambda k: progress(k * run.T_s / run.t_end) if k % every == 0 else None)
    calling = calling if calling is not None else np.zeros(1, dtype=np.int64)
    ids, guard = checked.ids, checked.guard
    execution = Execution(
        plan, assembly.slaves, assembly.signals, n, run.T_s, run.t_end, [observer], hooks, calling, ids, guard
    )
    reason, interrupted = None, False
    loop_started = loop_finished = clock.perf_counter()
    compiled: SystemLoop | str = "the run ended before its first sample"
    policy = SystemCheckpoints.of(checkpoints or CheckpointOptions(), assembly.slaves, run.T_s, calling, ids, words)
    policy.configure(*assembly.slaves)
    plant_slave = next(slave for slave in assembly.slaves if slave.name == run.system.plant)
    budget = WorkBudget.of(run.resolved.get("budget"), n)

    def counted(k: int) -> None:
        """The plant's work after a stretch, against the run's budget (`budget`)."""
        if budget is not None and k > 0:
            exceeded = budget.exceeded(plant_statistics(plant_slave), (k - 1) * run.T_s)
            if exceeded is not None:
                raise BudgetExceeded(exceeded)

    def retake(k: int, c: int, substeps: int) -> None:
        execution.advance(k, k + 1, split=(c, substeps))

    handed: int | None = None
    finished = False  # the loop returned: the instances may be reset for another run
    try:
        execution.initialize()
        loop_started = clock.perf_counter()
        compiled = compiled_system(
            plan, assembly.slaves, assembly.signals, data, n, run.T_s, observer.count, calling, ids, guard
        )
        if isinstance(compiled, SystemLoop):
            policy.configure(compiled)
            forward, handed_at = _compiled_forward(compiled, assembly.slaves, n, progress, run, execution)
            try:
                policy.drive(forward, retake, 0, n, counted)
            finally:
                handed = handed_at()
        else:
            policy.drive(execution.advance, retake, 0, n, counted)
        loop_finished, finished = clock.perf_counter(), True
    except KeyboardInterrupt:
        loop_finished, interrupted = clock.perf_counter(), True
        reason = f"interrupted (SIGINT or SIGTERM) at t = {max(observer.rows - 1, 0) * run.T_s:.6g} s"
    except SlaveError as error:
        loop_finished = clock.perf_counter()
        reason = policy.words.reason(error, (error.k or 0) * run.T_s)
    except BudgetExceeded as error:  # the plant's work past the run's budget: the same sample on any machine
        loop_finished = clock.perf_counter()
        reason = str(error)
    finally:
        calling[0] = 0
        solver_statistics = plant_statistics(plant_slave)
        controller_state = _controller_state(assembly.slaves, run.system.controller, checked.controller)
        assembly.close(reuse=finished and observer.rows == n + 1)
    rows = observer.rows
    trace = Trace(plan.names, data[:rows])
    retried = policy.words.retried(policy.passed())
    if reason is not None and retried is not None:
        reason = f"{reason} (earlier, {retried})"
    reason = bounded_text(reason) if reason is not None else None
    complete = reason is None and rows == n + 1
    summary, warnings = run_figures(run, trace, controller_state)
    if retried is not None:  # what the first one failed with, in run.json's retries too
        warnings = [*warnings, bounded_text(f"{retried[0].upper()}{retried[1:]}: {policy.passed()[0]['error']}")]
    wall = clock.perf_counter() - started
    status = "complete" if complete else "interrupted" if interrupted else "failed"
    stepping = (
        Stepping(True, None, compiled.native_names, tuple(compiled.in_python), handed)
        if isinstance(compiled, SystemLoop)
        else Stepping(False, compiled)
    )
    loop = loop_words(stepping, len(assembly.slaves), plan, run.T_s)
    record = run_record(
        run,
        plant,
        status,
        reason,
        rows,
        wall,
        loop_finished - loop_started,
        summary,
        policy.retries,
        loop,
        solver_statistics,
        warnings=warnings,
        controller=next((c for c in assembly.components if c["name"] == run.system.controller), None),
    )
    record["system"] = {
        "components": assembly.components,
        "order": list(plan.order),
        "connections": [
            {
                "start": str(c_.start),
                "end": str(c_.end),
                **({} if c_.identity else {"factor": c_.factor, "offset": c_.offset}),
            }
            for c_ in assembly.connections
        ],
        "signals": [str(port) for port in plan.signals],
        "recorded": list(plan.names[1:]),
        "checkpoints": policy.record(),
    }
    record["units"] = assembly.units
    return RunOutcome(
        run, trace, complete, reason, wall, loop_finished - loop_started, summary, record, interrupted, stepping
    )
