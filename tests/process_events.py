"""Events about other processes that tests wait on instead of waiting a fixed time: a condition
becomes true (a file written, a plant holding), the processes that carry a mark in their
environment are gone, a program has installed its own signal handlers.

Every wait polls its event every few milliseconds and gives up after WITHIN_S, a hang guard far
beyond what any event takes on a loaded machine: a test fails there only if the event never comes.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from pathlib import Path

WITHIN_S = 60.0
POLL_S = 0.005


def wait_until(condition: Callable[[], object], what: str, within: float = WITHIN_S) -> None:
    """Return once `condition()` is true; AssertionError naming `what` if it is not within `within` s."""
    deadline = time.monotonic() + within
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {within:g} s")
        time.sleep(POLL_S)


def marked(mark: str) -> list[int]:
    """The processes whose environment carries `mark` (one test's helpers: a killed process's
    environment reads empty, so it is not counted from the moment it has exited)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if mark.encode() in (entry / "environ").read_bytes():
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


def wait_gone(mark: str, within: float = WITHIN_S) -> None:
    """Return once no process carries `mark`; AssertionError with those left after `within` s."""
    try:
        wait_until(lambda: not marked(mark), f"the processes carrying {mark} to end", within)
    except AssertionError as error:
        raise AssertionError(f"{error}; left: {marked(mark)}") from None


def catches(pid: int, number: int) -> bool:
    """True if process `pid` has a handler of its own for signal `number` (/proc's SigCgt mask)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = int(status.split("SigCgt:")[1].split()[0], 16)
    return bool(caught & (1 << (number - 1)))


def program_running(pid: int) -> bool:
    """True once a toggle-cosim command's own code runs: it catches SIGTERM
    (`interrupts.install_for_start_up`, its first act; the interpreter alone does not)."""
    return catches(pid, signal.SIGTERM)
