"""A run as a system (`system.model`), and the run of one (`simulate_system`).

Every run's system (`Run.system`; the plain pair through `pair_execution`) is stepped by an
`Execution` (execution.py) over these components:

* the plant (component `plant`, or an SSD's name for it): the run's plant FMU with the values
  the scenario gives it (`master.plant_settings`);
* the controller (`controller`): a controller FMU as an FMU component, any other controller (the
  built-in law, a user's Python controller, a python-control system) natively (`ControllerSlave`);
* the parts (`Wiring.parts`): FMUs with their values;
* the signals: the plant inputs the scenario gives as numbers or signals in time (F_E,
  plant.inputs) that no connection feeds, sampled at every t_k (`master.input_samples`).

Connections are the run's own, or the pair's wiring (each controller input from the plant output
of its name, the command to the plant's iq_ref). Each is checked before anything is loaded:
both ends exist, it runs from an output to an input, no input is fed twice, the units match or
convert (`unit_conversion`: the same dimension, factor and offset from the FMUs' unit
definitions; anything else refused). The order comes from the connections and the components'
direct dependencies (`system.graph`): an algebraic loop is refused naming its cycle. The pair's
own wiring is stepped in the pair's order, the plant then the controller: the plant's outputs
at t_k are read before the command of sample k is set (a controller that measures an output the
command feeds directly, such as a_B, reads it with the command of sample k - 1).

The trace records every connector (`component.variable`: outputs, then fed inputs, in stepping
order) or the run's `record:` list, which may name any variable of an FMU component.

Either loop runs in stretches between checkpoints (`system_retry.SystemCheckpoints`): a
component's refused step is retried from the last one, and run.json lists each retry
(`retries`) and says whether retries are on (`system.checkpoints`).
"""

from __future__ import annotations

import dataclasses
import functools
import time as clock
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.control.protocol import Controller, ControllerError, check_controller
from toggle_cosim.cosim.budget import BudgetExceeded, WorkBudget
from toggle_cosim.cosim.controllers import ControllerFmuPart, controller_for
from toggle_cosim.cosim.execution import Execution, TraceObserver
from toggle_cosim.cosim.figures import run_figures
from toggle_cosim.cosim.fmi_pointers import RECORDED_TYPES
from toggle_cosim.cosim.instance_pool import InstancePool
from toggle_cosim.cosim.outcome import RunOutcome, Stepping, run_record
from toggle_cosim.cosim.plant_inputs import input_samples, plant_settings
from toggle_cosim.cosim.slaves import ControllerSlave, FmuSlave, Slave, SlaveError
from toggle_cosim.cosim.system_loop import FMI_FAILED, HAND_BACK, SystemLoop, compiled_system
from toggle_cosim.cosim.system_retry import CheckpointOptions, FailureWords, SystemCheckpoints
from toggle_cosim.cosim.user_code import check_owned
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import bounded_text
from toggle_cosim.plant.contract import ContractError, FmuArchive, PlantInterface, read_fmu
from toggle_cosim.runs.definition import Run
from toggle_cosim.system.graph import AlgebraicLoop, gauss_seidel_order
from toggle_cosim.system.interfaces import SettableError, check_settable
from toggle_cosim.system.model import Connection, Interface, Part, Port, Wiring
from toggle_cosim.system.plan import Plan, build_plan
from toggle_cosim.system.units import BASE, UnitDefinitionError, conversion, unit_meaning

__all__ = [
    "SystemError_",
    "Assembly",
    "assemble",
    "component_names",
    "simulate_system",
    "system_columns",
    "unit_conversion",
]

COMMAND = "iq_ref"


class SystemError_(ValueError):  # noqa: N801 - `SystemError` is a builtin
    """A system that cannot run as written; str() is one line naming what and the fix."""


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


def unit_conversion(
    connection: Connection, start: tuple[str | None, Any], end: tuple[str | None, Any]
) -> tuple[float, float] | None:
    """The (factor, offset) that turns the start's unit into the end's (None: the same unit, or
    either has none: the value is passed as it is). `start`, `end`: (unit, the FMU's model
    description or None). SystemError_ for units of different dimensions or unknown units."""
    (unit_s, desc_s), (unit_e, desc_e) = start, end
    if not unit_s or not unit_e or unit_s == unit_e:
        return None
    try:
        m_s, m_e = unit_meaning(unit_s, desc_s), unit_meaning(unit_e, desc_e)
    except UnitDefinitionError as error:
        raise SystemError_(f"the connection {connection}: {error}") from None
    if m_s is None or m_e is None:
        unknown = unit_s if m_s is None else unit_e
        raise SystemError_(
            f"the connection {connection} joins the units {unit_s!r} and {unit_e!r}, and {unknown!r} is not defined "
            "(declare it in the FMU's UnitDefinitions or connect variables of the same unit)"
        )
    if m_s[: len(BASE)] != m_e[: len(BASE)]:
        raise SystemError_(
            f"the connection {connection} joins {unit_s!r} to {unit_e!r}, of different dimensions (connect "
            "variables of the same quantity)"
        )
    if m_s[-2:] == m_e[-2:]:
        return None
    return conversion(m_s, m_e)


def component_names(wiring: Wiring) -> tuple[str, ...]:
    """A system's components as a run lists them: the plant, the controller, then the parts in
    the order written. A component's id while the master calls it is 1 + its place here
    (`simulate_system`'s `calling`)."""
    return (wiring.plant, wiring.controller, *(part.name for part in wiring.parts))


def pair_connections(wiring: Wiring, controller_inputs: Sequence[str]) -> tuple[Connection, ...]:
    """The pair's wiring: each controller input from the plant output of its name, the command to the plant."""
    p, c = wiring.plant, wiring.controller
    return (
        *(Connection(Port(p, name), Port(c, name)) for name in controller_inputs),
        Connection(Port(c, COMMAND), Port(p, COMMAND)),
    )


def _check_connections(connections: Sequence[Connection], interfaces: Mapping[str, Interface], where: str) -> None:
    fed: dict[Port, Connection] = {}
    for connection in connections:
        for side, port in (("start", connection.start), ("end", connection.end)):
            interface = interfaces.get(port.component)
            if interface is None:
                raise SystemError_(
                    f"{where}: the connection {connection} names the component {port.component!r}, which the system "
                    f"does not have (its components: {', '.join(interfaces)})"
                )
            wanted = (
                tuple(v for v in interface.outputs if v not in interface.typed) if side == "start" else interface.inputs
            )
            if port.variable not in wanted:
                kind = "output" if side == "start" else "input"
                known = ", ".join(wanted) or "none"
                raise SystemError_(
                    f"{where}: the connection {connection} {'starts' if side == 'start' else 'ends'} at {port}, which "
                    f"is not a Real {kind} of {port.component!r} (its {kind}s: {known}); a connection runs from an "
                    "output to an input"
                )
        if connection.end in fed:
            raise SystemError_(
                f"{where}: the connections {fed[connection.end]} and {connection} both drive {connection.end} "
                "(an input takes one connection; remove one)"
            )
        fed[connection.end] = connection


def _controller_slave(
    run: Run,
    name: str,
    controller: Controller | None,
    outputs: Sequence[str],
    units: Mapping[str, str | None],
    pool: InstancePool | None = None,
) -> Slave:
    """The run's controller as a component: a controller FMU as an FMU; any other natively (the
    built-in law and a python-control system then run in C in the compiled system loop:
    `system_natives`), its connectors in the units of the plant variables of their names (`units`)."""
    if controller is None:
        controller = controller_for(run, outputs)
    if isinstance(controller, ControllerFmuPart):
        return FmuSlave(name, controller.fmu, controller.settings, pool=pool)
    diagnostics = check_controller(controller, outputs)
    return ControllerSlave(name, controller, diagnostics, COMMAND, units, outputs)


def assemble(
    run: Run,
    plant: PlantInterface,
    controller: Controller | None = None,
    coupling: str | None = None,
    pool: InstancePool | None = None,
) -> Assembly:
    """The run's system, checked and loaded (module docstring). Raises SystemError_ (one line) for
    a system that cannot run as written, ControllerError for a controller that cannot be built.
    `pool`: where the FMU components' instances come from and go back to (`instance_pool`)."""
    wiring, where = run.system, f"scenario {run.scenario}"
    jacobi = (coupling or run.coupling) == "jacobi"
    requested: dict[str, list[str]] = {}
    for port in wiring.record or ():
        requested.setdefault(port.component, []).append(port.variable)
    slaves: dict[str, Slave] = {}
    try:
        slaves[wiring.plant] = FmuSlave(
            wiring.plant, plant, plant_settings(run, plant), requested.get(wiring.plant, ()), pool
        )
        slaves[wiring.controller] = _controller_slave(
            run, wiring.controller, controller, plant.recorded_outputs, slaves[wiring.plant].interface.units, pool
        )
        for part in wiring.parts:
            if part.name in slaves:
                raise SystemError_(f"{where}: two components are named {part.name!r} (give each its own name)")
            slaves[part.name] = FmuSlave(
                part.name, _checked_part(part, run.source), part.values, requested.get(part.name, ()), pool
            )
        interfaces = {name: slave.interface for name, slave in slaves.items()}
        plant_outputs = set(interfaces[wiring.plant].outputs)  # a controller FMU's reference inputs stay unfed
        controller_inputs = [name for name in interfaces[wiring.controller].inputs if name in plant_outputs]
        connections = (
            wiring.connections if wiring.connections is not None else pair_connections(wiring, controller_inputs)
        )
        _check_connections(connections, interfaces, where)
        descriptions = {name: getattr(slave, "description", None) for name, slave in slaves.items()}
        converted = []
        for connection in connections:
            conversion = unit_conversion(
                connection,
                (
                    interfaces[connection.start.component].units.get(connection.start.variable),
                    descriptions[connection.start.component],
                ),
                (
                    interfaces[connection.end.component].units.get(connection.end.variable),
                    descriptions[connection.end.component],
                ),
            )
            if conversion is not None:
                factor, offset = conversion
                connection = Connection(
                    connection.start,
                    connection.end,
                    factor * connection.factor,
                    factor * connection.offset + offset,
                )
            converted.append(connection)
        connections = tuple(converted)
        fed = {connection.end for connection in connections}
        signals = [("F_E", run.plant.F_E), *run.plant.inputs.items()]
        signal_ports, columns = [], []
        plant_inputs = interfaces[wiring.plant].inputs
        for index, (name, _) in enumerate(signals):
            port = Port(wiring.plant, name)
            if port in fed or name not in plant_inputs:
                continue
            signal_ports.append(port)
            columns.append(index)
        for port in wiring.record or ():
            interface = interfaces.get(port.component)
            if interface is None or (port.variable not in interface.outputs and port.variable not in interface.inputs):
                raise SystemError_(
                    f"{where}: key record: {port} is not a variable of the system (its components: "
                    f"{', '.join(interfaces)}; an FMU's variables by their names in its modelDescription.xml)"
                )
            kind = interface.typed.get(port.variable)
            if kind is not None and kind not in RECORDED_TYPES:
                raise SystemError_(
                    f"{where}: key record: {port} is a {kind} variable; the trace holds numbers (record Real, Integer,"
                    " Boolean or Enumeration variables)"
                )
            if port.variable in interface.inputs and port not in fed and port not in signal_ports:
                raise SystemError_(
                    f"{where}: key record: {port} is an input nothing feeds (connect it, or record another variable)"
                )
        try:
            order = (
                (wiring.plant, wiring.controller)  # the pair's own wiring: the fixed loop's order
                if wiring.connections is None and not wiring.parts
                else gauss_seidel_order(list(slaves), connections, interfaces)
            )
        except AlgebraicLoop as error:
            raise SystemError_(f"{where}: {error}") from None
        plan = build_plan(order, interfaces, connections, signal_ports, wiring.record, jacobi)
        samples = input_samples(run, run.steps)
        table = np.ascontiguousarray(samples[:, columns], dtype=np.float64).reshape(run.steps + 1, len(columns))
        components = [_component_record(name, slaves[name], order) for name in slaves]
        units = {"time": "s"}
        for column in plan.names[1:]:
            port = Port.parse(column)
            unit = interfaces[port.component].units.get(port.variable)
            if unit:
                units[column] = unit
        return Assembly([slaves[name] for name in order], plan, table, connections, components, units)
    except BaseException:
        for slave in slaves.values():
            slave.close()
        raise


@functools.lru_cache(maxsize=64)
def _read_part(path: Path, size: int, mtime_ns: int, missing: str) -> FmuArchive:
    """`read_fmu` of a part's file, kept while the file is unchanged (its size and time): a run's
    system is checked before the run, and assembled again in the run's process."""
    return read_fmu(path, missing=missing)


def _checked_part(part: Part, source: Path | None) -> FmuArchive:
    """A part's FMU checked as any FMU the master runs (a zip archive, safe, FMI 2.0 or 3.0,
    Co-Simulation, a binary for this platform: `plant.contract.read_fmu`) and, being code this
    command runs, owned by the user (`user_code.check_owned`), its values each a parameter or
    input of the FMU, of its type (`system.interfaces.check_settable`): the checked archive (path,
    model description, SHA-256), or SystemError_ naming the key and the fix."""
    ssp = source is not None and Path(source).suffix.lower() == ".ssp"
    key = f"component {part.name!r}" if ssp else f"key components.{part.name}.fmu"
    try:
        missing = f"build it, or fix {key}"
        try:
            status = part.fmu.stat()
        except OSError:
            archive = read_fmu(part.fmu, missing=missing)  # its own message for a missing file
        else:
            archive = _read_part(part.fmu.resolve(), status.st_size, status.st_mtime_ns, missing)
            check_owned(part.fmu, key)
    except ContractError as error:
        raise SystemError_(f"{key}: {error}") from None
    except ControllerError as error:
        raise SystemError_(str(error)) from None
    try:  # the one check of a component's values (the SSP reader's too), before any run
        check_settable(archive.model_description, part.values)
    except SettableError as error:
        where = f"component {part.name!r}" if ssp else f"key components.{part.name}.parameters"
        raise SystemError_(
            f"{where}: {error} ({part.fmu.name}; give a parameter or input of its FMU, or fix the name or the value)"
        ) from None
    return archive


def _component_record(name: str, slave: Slave, order: Sequence[str]) -> dict[str, Any]:
    record: dict[str, Any] = {"name": name, "position": order.index(name)}
    if isinstance(slave, FmuSlave):
        record.update(fmu=str(slave.path), sha256=slave.sha256, values=dict(slave.values))
        if slave.origin:
            record["kind"] = slave.origin
    else:
        record.update(kind="native controller", type=type(slave.controller).__qualname__)
    return record


def system_columns(run: Run, plant: PlantInterface, controller: Controller | None = None) -> tuple[str, ...]:
    """The trace columns of a system run (the plan's recorded ports), without running it."""
    assembly = assemble(run, plant, controller)
    for slave in assembly.slaves:  # nothing is loaded yet; the controller stays open for the run
        if isinstance(slave, FmuSlave):
            slave.close()
    return assembly.plan.names


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


def simulate_system(
    run: Run,
    plant: PlantInterface,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    controller: Controller | None = None,
    coupling: str | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    checkpoints: CheckpointOptions | None = None,
    pool: InstancePool | None = None,
    words: FailureWords | None = None,
) -> RunOutcome:
    """Run a system (module docstring); never raises for a component's failure: the outcome is
    failed with the reason and the trace up to the last complete sample. SystemError_ or
    ControllerError for a system that cannot be assembled. `calling` (an int64 array, e.g. a
    word shared with a supervising process): element 0 holds, while a component is called, its
    id (`component_names`), and 0 outside the run's loop. `checkpoints`: how a refused step is
    retried (`system_retry`; default every 200 samples, in 10 substeps), `words` how failures
    are said (`system_retry.FailureWords`; default each names its component). `pool`: the FMU
    components' instances kept from run to run (`instance_pool`), reset after a complete run."""
    started = clock.perf_counter()
    if coupling is not None and coupling != run.coupling:
        run = dataclasses.replace(run, coupling=coupling)
    n = run.steps
    try:
        assembly = assemble(run, plant, controller, pool=pool)
    except ControllerError as error:
        reason = bounded_text(str(error) if str(error).startswith("controller: ") else f"controller: {error}")
        wall = clock.perf_counter() - started
        loop = {"kind": "none", "reason": "the controller could not be built"}
        record = run_record(run, plant, "failed", reason, 0, wall, 0.0, None, [], loop, None)
        return RunOutcome(run, Trace(("time",), np.empty((0, 1))), False, reason, wall, 0.0, None, record)
    plan = assembly.plan
    data = buffer if buffer is not None else np.full((n + 1, len(plan.names)), np.nan)
    observer = TraceObserver(plan, data, count)
    hooks = []
    if progress is not None:
        every = max(n // 100, 1)
        hooks.append(lambda k: progress(k * run.T_s / run.t_end) if k % every == 0 else None)
    calling = calling if calling is not None else np.zeros(1, dtype=np.int64)
    names = component_names(run.system)
    ids = [names.index(name) + 1 for name in plan.order]
    execution = Execution(
        plan, assembly.slaves, assembly.signals, n, run.T_s, run.t_end, [observer], hooks, calling, ids
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
            plan, assembly.slaves, assembly.signals, data, n, run.T_s, observer.count, calling, ids
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
        controller_state = _controller_state(assembly.slaves, run.system.controller, controller)
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
