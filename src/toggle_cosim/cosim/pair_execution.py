"""The plain pair, a plant FMU and its controller (`Run.system.is_pair`: a scenario without
`components:`, `connections:` or `record:`), run as the two-part system it is: the plant and its
controller stepped by the execution (`systems.execute`), with the pair's trace and run.json.

`master.simulate` sends every plain pair here, checked (`checked.check_run`). The run is the pair's wiring (each controller
input from the plant output of its name, the command to the plant's iq_ref, the load and the
plant's other inputs fed by their signals) with a `record:` list of the pair's columns
(`checked.pair_ports`, set by the check), so that:

* the trace has the pair's columns in the pair's order and names (`trace_names`: time, the
  plant's recorded outputs, iq_ref, F_E, the controller's diagnostics, the other inputs), the
  columns of every stored reference;
* run.json is the pair's: the controller as the pair records it (`controllers.controller_record`),
  the retries without the component's name, no `system` or `units` entries, and `loop.kind` in
  the pair's words, from what the execution did (`outcome.Stepping`): "compiled" (the compiled
  system loop), "compiled, then python" (a sample handed back to the Python execution),
  "python"; `loop.reason` says what the execution did;
* a plant's failures and retries are said in the pair's words (`PlantWords`);
* checkpoints and the work budget fall at the pair's samples: its first sample runs alone, then
  stretches of `system_retry.CHECKPOINT_SAMPLES` (`CheckpointOptions.lead`).

The summary (with T_h and S0), the plausibility warnings and the solver statistics are the
execution's own, as for every system run (`figures.run_figures`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from fmpy.fmi1 import FMICallException

from toggle_cosim import interrupts
from toggle_cosim.control.controller import VSCController
from toggle_cosim.cosim.checked import CheckedRun, pair_ports
from toggle_cosim.cosim.controllers import controller_record
from toggle_cosim.cosim.execution.instance_pool import InstancePool
from toggle_cosim.cosim.execution.slaves import SlaveError
from toggle_cosim.cosim.execution.system_retry import CheckpointOptions, ComponentWords, failure_text
from toggle_cosim.cosim.outcome import RunOutcome, Stepping
from toggle_cosim.cosim.outcome import refused_outcome as refused
from toggle_cosim.cosim.plant_inputs import other_inputs
from toggle_cosim.cosim.systems import execute
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import said_in
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run
from toggle_cosim.system.model import Wiring

__all__ = [
    "close_controller",
    "pair_loop",
    "pair_ports",
    "refused_outcome",
    "simulate_pair_as_system",
    "trace_names",
]


def trace_names(
    plant: PlantInterface, diagnostics: tuple[str, ...] = VSCController.diagnostics, inputs: tuple[str, ...] = ()
) -> tuple[str, ...]:
    """The columns of the plain pair's trace: time, then the variables of its recorded ports
    (`checked.pair_ports`, the one definition: the plant's recorded outputs, the inputs iq_ref and
    F_E, the controller's diagnostics (the built-in law's by default), then the plant's other
    inputs the run sets, `inputs`: `other_inputs(run)`)."""
    return ("time", *(port.variable for port in pair_ports(Wiring(), plant, tuple(diagnostics), tuple(inputs))))


def close_controller(controller: object) -> None:
    """Call the controller's close(), if it has one; whatever it raises is ignored (the run's
    outcome stands), but for an interrupt or exit the code raised itself."""
    close = getattr(controller, "close", None)
    if callable(close):
        try:
            close()
        except BaseException as error:  # noqa: BLE001 - freeing never changes a run's outcome
            if not interrupts.raised_by_code(error):  # SystemExit, or KeyboardInterrupt in a run's child
                raise


def refused_outcome(run: Run, plant: PlantInterface, reason: str, started: float) -> RunOutcome:
    """The outcome of a run whose controller could not be built or checked (`outcome.refused_outcome`):
    the plain pair's trace has the pair's columns (`trace_names`), any other system's only time."""
    names = trace_names(plant, inputs=other_inputs(run)) if run.system.is_pair else ("time",)
    return refused(run, plant, reason, started, names)


def pair_loop(loop: dict[str, Any], stepping: Stepping | None) -> dict[str, Any]:
    """run.json's `loop` of the execution (`loop`, with what it did: `stepping`) in the pair's
    kinds (module docstring); a run that never stepped keeps its kind ("none")."""
    if stepping is None:
        kind = str(loop.get("kind"))
    elif not stepping.compiled or stepping.called_back:  # the controller's own code runs at every sample
        kind = "python"
    else:
        kind = "compiled, then python" if stepping.handed_back is not None else "compiled"
    return {"kind": kind, "reason": f"the pair as a system in the execution: {loop.get('reason', '')}"}


@dataclass(frozen=True)
class PlantWords:
    """The pair's words for its plant's failures: a failed call as FMPy says it with what the FMU
    logged (`system_retry.failure_text`), the retries as "the plant's step(s)", the reason "plant
    FMU failed at t = ...: ..."; the controller's failure "controller failed: ..." (a controller
    FMU's with its file name: "controller failed: Law.fmu: fmi2DoStep at t = ..."), and a
    plant output it measures that is not finite "plant outputs became non-finite at t = ..."."""

    plant: str
    controller: str

    def step(self, error: SlaveError, before: str | None = None) -> str:
        if error.component != self.plant or not error.function or not isinstance(error.status, int):
            return ComponentWords().step(error, before)
        logged = error.logged
        if before is not None and logged is not None and said_in(logged, before):  # said once
            logged = None
        return failure_text(FMICallException(error.function, error.status), logged)

    def retried(self, passed: Sequence[dict[str, Any]]) -> str | None:
        """The plant's steps that failed and passed when retried from a checkpoint, in words (a
        run's warning; a failure reason's note, short so the reason's own words stay in its
        bound), or None; another component's as every system says them."""
        if not passed:
            return None
        if not all(entry["component"] == self.plant for entry in passed):
            return ComponentWords().retried(passed)
        if len(passed) == 1:
            return f"the plant's step at t = {passed[0]['t']:.6g} s failed and passed when retried from a checkpoint"
        return (
            f"{len(passed)} of the plant's steps from t = {passed[0]['t']:.6g} s to {passed[-1]['t']:.6g} s failed "
            "and passed when retried from a checkpoint"
        )

    def reason(self, error: SlaveError, t: float) -> str:
        if error.not_finite:  # what the controller measures: the plant's outputs
            return f"plant outputs became non-finite at t = {t:.6g} s"
        said, own = str(error), f"component {self.controller!r}"
        if said.startswith(f"{own}: "):  # its step raised, or its command was refused
            return f"controller failed: {said.removeprefix(f'{own}: ')}"
        if error.component == self.controller and said.startswith(f"{own} ("):  # a controller FMU's call
            return f"controller failed: {said.removeprefix(f'{own} (').replace('): ', ': ', 1)}"
        if error.component != self.plant:
            return said
        return f"plant FMU failed at t = {t:.6g} s: {str(error) if error.retried else self.step(error)}"


def simulate_pair_as_system(
    checked: CheckedRun,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    pool: InstancePool | None = None,
    checkpoints: CheckpointOptions | None = None,
    started: float | None = None,
) -> RunOutcome:
    """Run the plain pair, checked (`checked.check_run`: its trace the pair's columns,
    `CheckedRun.pair`), in the execution with the pair's trace and run.json (module docstring);
    arguments as `systems.execute`'s (the checkpoints' `lead` is the pair's: 1). Never raises
    for a plant or controller fault: see RunOutcome."""
    run = checked.run
    outcome = execute(
        checked,
        progress,
        buffer,
        count,
        calling,
        checkpoints=dataclasses.replace(checkpoints or CheckpointOptions(), lead=1),
        pool=pool,
        words=PlantWords(run.system.plant, run.system.controller),
        started=started,
    )
    record = {key: value for key, value in outcome.record.items() if key not in ("system", "units")}
    record["controller"] = controller_record(run, checked.controller)
    record["loop"] = pair_loop(outcome.record["loop"], outcome.stepping)
    record["retries"] = [
        {key: value for key, value in entry.items() if key != "component"} for entry in record["retries"]
    ]
    return dataclasses.replace(outcome, trace=Trace(checked.names, outcome.trace.data), record=record)
