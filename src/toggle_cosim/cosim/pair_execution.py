"""The plain pair run as the two-part system it is: the plant and its controller stepped by the
execution (`systems.execute`), with the fixed loop's outcome (`pair.simulate_pair`).

`master.simulate` sends the pair here under TOGGLE_COSIM_MASTER=execution (`limits.pair_as_execution`).
The run is the pair's wiring (each controller input from the plant output of its name, the
command to the plant's iq_ref, the load and the plant's other inputs fed by their signals) with a
`record:` list of the pair's columns (`checked.pair_ports`, set by the run's check), so that:

* the trace has the pair's columns in the pair's order and names (`CheckedRun.names`: time, the
  plant's recorded outputs, iq_ref, F_E, the controller's diagnostics, the other inputs), and
  trace.csv is the pair's;
* run.json is the pair's: the controller as the pair records it (`controllers.controller_record`),
  the retries without the component's name, no `system` or `units` entries, and `loop.kind` in
  the pair's words: "compiled" (the compiled system loop), "compiled, then python" (a sample
  handed back to the Python execution), "python"; `loop.reason` says what the execution did;
* a plant's failures and retries are said in the pair's words (`PlantWords`);
* checkpoints and the work budget fall at the pair's samples: its first sample runs alone, then
  stretches of `retry.CHECKPOINT_SAMPLES` (`CheckpointOptions.lead`).

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

from toggle_cosim.cosim.checked import CheckedRun, pair_ports
from toggle_cosim.cosim.controllers import controller_record
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.cosim.pair import retried_words
from toggle_cosim.cosim.retry import failure_text
from toggle_cosim.cosim.slaves import SlaveError
from toggle_cosim.cosim.system_retry import CheckpointOptions, ComponentWords
from toggle_cosim.cosim.systems import execute
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import said_in

__all__ = ["pair_loop", "pair_ports", "simulate_pair_as_system"]


def pair_loop(loop: dict[str, Any]) -> dict[str, Any]:
    """run.json's `loop` of the execution in the pair's kinds (module docstring)."""
    reason = str(loop.get("reason", ""))
    if loop.get("kind") != "system, compiled":
        kind = "python" if loop.get("kind") == "system, python" else str(loop.get("kind"))
    elif "in Python, called back from C" in reason:  # the controller's own code runs at every sample
        kind = "python"
    else:
        kind = (
            "compiled, then python"
            if "in Python (a sample the native controller handed back)" in reason
            else "compiled"
        )
    return {"kind": kind, "reason": f"the pair as a system in the execution: {reason}"}


@dataclass(frozen=True)
class PlantWords:
    """The pair's words for its plant's failures (`pair.simulate_pair`): a failed call as FMPy
    says it with what the FMU logged (`retry.failure_text`), the retries as "the plant's
    step(s)" (`pair.retried_words`), the reason "plant FMU failed at t = ...: ..."; a native
    controller's failure "controller failed: ...", and a plant output it measures that is not finite "plant
    outputs became non-finite at t = ..." as the pair says them."""

    plant: str
    controller: str
    T_s: float

    def step(self, error: SlaveError, before: str | None = None) -> str:
        if error.component != self.plant or not error.function or not isinstance(error.status, int):
            return ComponentWords().step(error, before)
        logged = error.logged
        if before is not None and logged is not None and said_in(logged, before):  # said once
            logged = None
        return failure_text(FMICallException(error.function, error.status), logged)

    def retried(self, passed: Sequence[dict[str, Any]]) -> str | None:
        if all(entry["component"] == self.plant for entry in passed):
            return retried_words(passed, self.T_s)
        return ComponentWords().retried(passed)

    def reason(self, error: SlaveError, t: float) -> str:
        if error.not_finite:  # what the controller measures: the plant's outputs
            return f"plant outputs became non-finite at t = {t:.6g} s"
        said, own = str(error), f"component {self.controller!r}: "
        if said.startswith(own):  # its step raised, or its command was refused
            return f"controller failed: {said.removeprefix(own)}"
        if error.component != self.plant:
            return said
        return f"plant FMU failed at t = {t:.6g} s: {str(error) if error.retried else self.step(error)}"


def simulate_pair_as_system(
    checked: CheckedRun,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    count: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    started: float | None = None,
) -> RunOutcome:
    """Run the plain pair, checked (`checked.check_run`: its trace the pair's columns,
    `CheckedRun.pair`), in the execution with the fixed loop's trace and run.json (module
    docstring); arguments as `systems.execute`'s. Never raises for a plant or controller fault:
    see RunOutcome."""
    run = checked.run
    outcome = execute(
        checked,
        progress,
        buffer,
        count,
        calling,
        checkpoints=CheckpointOptions(lead=1),
        words=PlantWords(run.system.plant, run.system.controller, run.T_s),
        started=started,
    )
    record = {key: value for key, value in outcome.record.items() if key not in ("system", "units")}
    record["controller"] = controller_record(run, checked.controller)
    record["loop"] = pair_loop(outcome.record["loop"])
    record["retries"] = [
        {key: value for key, value in entry.items() if key != "component"} for entry in record["retries"]
    ]
    return dataclasses.replace(outcome, trace=Trace(checked.names, outcome.trace.data), record=record)
