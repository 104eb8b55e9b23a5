"""Why a supervised run's process ended, in words: the plant's crash or exit, or its
controller's, told apart by what the trace holds (pure functions of a wait status, a reason and
the trace buffer; `supervision` and the sweep's plant hosts say them)."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np

from toggle_cosim.runs.definition import Run

__all__ = [
    "building_reason",
    "component_reason",
    "component_words",
    "controller_words",
    "ended_cleanly",
    "exit_reason",
    "in_controller_reason",
    "stopped_in_controller",
]


def exit_reason(status: int | None) -> str:
    """Why a plant process ended without answering, from its wait status."""
    if status is not None and os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        name = signal.Signals(number).name if number in set(signal.Signals) else f"signal {number}"
        return f"the plant process was killed by {name}"
    if status is not None:
        return f"the plant process exited with status {os.waitstatus_to_exitcode(status)} before the run ended"
    return "the plant process ended without an answer"


def ended_cleanly(status: int | None) -> bool:
    """Whether a run's process ended as a run that sent its answer ends: exit status 0 (None: its
    status is unknown, already reaped)."""
    return status is None or (os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0)


def stopped_in_controller(
    buffer: np.ndarray, rows: int, n_outputs: int, names: tuple[str, ...], calling: np.ndarray | None = None
) -> bool:
    """True when a run's process ended (or was ended) inside its controller: the first unfinished
    sample of the trace `buffer` has every plant output read but no command, and both loops write
    a sample in that order (read the plant, run the controller, record the command, step the plant).
    The pair run in the execution records a sample whole: there `calling` (the component it was
    calling, 1 + its place in `systems.component_names`: 2 is the controller) says it."""
    if calling is not None and int(calling[0]) != 0:
        return int(calling[0]) == CONTROLLER_ID
    if rows >= buffer.shape[0] or "iq_ref" not in names:
        return False
    row = buffer[rows]
    return bool(np.all(np.isfinite(row[1 : 1 + n_outputs])) and np.isnan(row[names.index("iq_ref")]))


CONTROLLER_ID = 2  # the controller's id while the master calls it (`systems.component_names`: plant, controller, ...)


def controller_words(python: str | None, fmu: Path | str | None, building: bool = False) -> str:
    """A run's controller in words, for a failure while it was built (`building`) or ran."""
    if fmu is not None:
        return f"the controller FMU {Path(fmu).name} (controller.fmu)"
    if python is not None:
        return f"the controller's {'module or factory ' if building else ''}{python} (controller.python)"
    return "the controller"


def in_controller_reason(reason: str, words: str, t: float, by_limit: bool) -> str:
    """Why a run failed whose process ended (`reason`, said of the plant process) or reached its
    time limit (`by_limit`) while its controller (`words`) computed the sample at `t`."""
    sample = f" while it computed the sample at t = {t:.6g} s"
    if by_limit:
        return f"controller: {words} did not finish its step: {reason}{sample}"
    said = reason.replace("the plant process", "it", 1) if reason.startswith("the plant process") else reason
    return f"controller: {words} ended the run's process: {said}{sample}"


def component_words(run: Run, plant: Path, name: str) -> str:
    """A system's component in words, for a failure while the master called it: its name and its
    FMU's file (the plant's `plant`, a part's), or what the controller is."""
    wiring = run.system
    if name == wiring.plant:
        what = Path(plant).name
    elif name == wiring.controller:
        python, fmu = run.controller.python, run.controller.fmu
        what = controller_words(python, fmu) if python or fmu else "the built-in law"
    else:
        what = next((Path(part.fmu).name for part in wiring.parts if part.name == name), "")
    return f"component {name!r} ({what})"


def component_reason(reason: str, words: str, at: str, by_limit: bool) -> str:
    """Why a system's run failed whose process ended (`reason`, said of the plant process) or
    reached its time limit (`by_limit`) while the master called the component `words`
    (`component_words`; `at`: " at t = ..." of the last sample recorded)."""
    if by_limit:
        return f"{words} did not return: {reason} while the master called it{at}"
    said = reason.replace("the plant process", "it", 1) if reason.startswith("the plant process") else reason
    return f"{words} ended the run's process: {said} while the master called it{at}"


def building_reason(run: Run, limit: str | None, answer: tuple | None, status: int | None) -> str:
    """Why a run failed whose child ended (or was ended: `limit`) while it built the user's
    controller: its import, its factory or loading its FMU."""
    words = controller_words(run.controller.python, run.controller.fmu, building=True)
    if limit is not None:
        return f"controller: building {words} did not finish: {limit}"
    if answer is not None and answer[0] == "error":
        return f"controller: building {words} failed: {answer[1]}"
    if status is not None and os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        name = signal.Signals(number).name if number in set(signal.Signals) else f"signal {number}"
        return f"controller: {words} crashed the run's process while it was imported or built (killed by {name})"
    code = os.waitstatus_to_exitcode(status) if status is not None else None
    said = f"with status {code}" if code is not None else "without an answer"
    return (
        f"controller: {words} ended the run's process {said} while it was imported or built"
        " (os._exit, or a signal it sent itself); nothing was run"
    )
