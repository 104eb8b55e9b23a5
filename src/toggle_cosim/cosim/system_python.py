"""Components of a system's compiled loop (`cosim.system_loop`) that run in Python: a user's
Python controller (a `ControllerSlave` whose controller is not a native kind, `system_natives`),
or any slave without C calls. Every FMU call of the run stays in C; at such a component's turns
of a sample the C calls back into Python (system_skeleton.c's `call_python`), which makes the
slave's own calls with the values the C gathered:

* CALL_EARLY: `set` its early inputs (when it has any), `get` its outputs straight into their
  slots of the loop's buffer;
* CALL_LATE: `set` its late inputs;
* CALL_STEP: `do_step(t_k, T_s)`.

These are the calls, in the order and with the values, that the Python execution
(`cosim.execution.Execution`) makes, so the trace has its bits and the slave holds its own
state (a checkpoint saves and restores it as ever).

What the slave's code raises (an error, SystemExit, an interrupt landing in the callback) is not
lost in the callback: it is kept, the callback does not say it is done, the C stops the loop at
that sample (RAISED), and `Callbacks.reraise` raises it from the loop's `run`, where the Python
execution would have raised it. An interrupt that lands as the callback starts, before its own
handler runs, reaches Python's unraisable hook instead: `Callbacks.catching` takes it from there
for the duration of the C call.
"""

from __future__ import annotations

import contextlib
import ctypes
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, NoReturn

import numpy as np

from toggle_cosim.cosim.slaves import SlaveError

__all__ = ["CALLBACK", "Callbacks", "PythonComponent"]

CALL_EARLY, CALL_LATE, CALL_STEP = 1, 2, 3  # system_skeleton.c's turns of a component run in Python

CALLBACK = ctypes.CFUNCTYPE(None, ctypes.c_long, ctypes.c_long, ctypes.c_long)  # python_t


@dataclass(frozen=True)
class PythonComponent:
    """A component the compiled loop calls back into Python for: its slave (`cosim.slaves.Slave`),
    and why it is not run in C (run.json's loop reason)."""

    slave: Any
    why: str


@dataclass(frozen=True)
class Turns:
    """What the callback needs of one component run in Python: its slave, the positions among its
    fed inputs of its early and late inputs, its scratch (the values the C gathered) and its
    outputs' slots of the buffer, as ctypes arrays over the C's memory."""

    slave: Any
    early: tuple[int, ...]
    late: tuple[int, ...]
    scratch: ctypes.Array
    outputs: ctypes.Array


class Callbacks:
    """The one callback of a loop for all of its components run in Python (module docstring).
    `turns`: per component index in the plan's order, its `Turns`; T_s the communication step."""

    def __init__(self, turns: dict[int, Turns], T_s: float) -> None:
        self.turns, self.T_s = turns, float(T_s)
        self.answered = np.zeros(1, dtype=np.int64)  # system_t's answered
        self.raised: list[BaseException] = []
        self._python = self._callback()
        self.function = CALLBACK(self._python)

    def _callback(self) -> Any:
        turns, T_s, answered, raised = self.turns, self.T_s, self.answered, self.raised

        def call_python(c: int, call: int, k: int) -> None:
            try:
                turn = turns[c]
                t = k * T_s
                if call == CALL_EARLY:
                    if turn.early:
                        turn.slave.set(turn.early, turn.scratch[: len(turn.early)], t)
                    turn.slave.get(turn.outputs, t)
                elif call == CALL_LATE:
                    turn.slave.set(turn.late, turn.scratch[: len(turn.late)], t)
                else:
                    turn.slave.do_step(t, T_s)
                answered[0] = 1
            except BaseException as error:  # noqa: BLE001 - kept, and raised by `reraise` once the C has returned
                raised.append(error)

        return call_python

    @contextlib.contextmanager
    def catching(self) -> Iterator[None]:
        """While the C runs: an exception that escapes the callback (an interrupt landing before
        its handler runs) is kept for `reraise`, not printed and dropped by ctypes."""
        previous, python = sys.unraisablehook, self._python
        named = repr(python)  # Python 3.13 names the callback in err_msg, 3.12 gives it as object

        def hook(info: Any) -> None:
            error = getattr(info, "exc_value", None)
            if error is not None and (info.object is python or named in (info.err_msg or "")):
                self.raised.append(error)
                return
            previous(info)

        sys.unraisablehook = hook
        try:
            yield
        finally:
            sys.unraisablehook = previous

    def reraise(self, component: str, k: int) -> NoReturn:
        """Raise what the callback of `component` kept at sample k (a SlaveError gets k, as the
        Python execution gives it)."""
        if not self.raised:
            raise SlaveError(f"component {component!r}: its call at sample {k} did not return", component)
        error = self.raised[0]
        self.raised.clear()
        if isinstance(error, SlaveError):
            error.k = k
        raise error


def turns_of(
    slave: Any, early: Sequence[int], late: Sequence[int], scratch: ctypes.Array, buffer: np.ndarray, out0: int, n: int
) -> Turns:
    """A component's `Turns`: its outputs the n slots of `buffer` from out0 (a ctypes array over
    them, so `get` writes where the C reads)."""
    outputs = (ctypes.c_double * max(n, 1)).from_address(buffer.ctypes.data + out0 * buffer.itemsize)
    return Turns(slave, tuple(early), tuple(late), scratch, outputs)
