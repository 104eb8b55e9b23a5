"""Components of a system's compiled loop (`cosim.execution.system_loop`) that run in Python: a user's
Python controller (a `ControllerSlave` whose controller is not a native kind, `system_natives`),
or any slave without C calls. Every FMU call of the run stays in C; at such a component's early
turn of each sample k the C calls back into Python once (system_skeleton.c's `call_python`),
and the callback makes the slave's own calls with the values the C computed:

* first, from sample k - 1 (CALL_AFTER_STEP): `set` its late inputs (their values still in their
  slots of the loop's buffer) and `do_step(t_k-1, T_s)`;
* then `set` its early inputs (gathered in its scratch), and `get` its outputs straight into
  their slots of the buffer.

Where the loop returns between samples (a stretch's end, a sample handed back), the last
sample's late inputs and doStep are made from Python (`Turns.finish`) before anything else runs.
So the slave is given the calls, in the order and with the values, that the Python execution
(`cosim.execution.algorithm.Execution`) gives it: the trace has its bits, and the slave holds its own
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
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, NoReturn

import numpy as np

from toggle_cosim.cosim.execution.slaves import SlaveError

__all__ = ["CALLBACK", "Callbacks", "PythonComponent"]

CALL_EARLY, CALL_AFTER_STEP = 1, 2  # system_skeleton.c's call codes of a component run in Python

CALLBACK = ctypes.CFUNCTYPE(None, ctypes.c_long, ctypes.c_long, ctypes.c_long)  # python_t


@dataclass(frozen=True)
class PythonComponent:
    """A component the compiled loop calls back into Python for: its slave (`cosim.execution.slaves.Slave`),
    and why it is not run in C (run.json's loop reason)."""

    slave: Any
    why: str


@dataclass(frozen=True)
class Turns:
    """What the callback needs of one component run in Python: its slave, the positions among its
    fed inputs of its early and late inputs, the buffer slots of its late inputs, and as ctypes
    arrays over the C's memory its scratch (the early values the C gathered), its outputs' slots
    and the whole buffer (`memory`); T_s the communication step. `gathered`: the scratch's early
    values as a memoryview of doubles, read as a list of floats in one call (`tolist`)."""

    slave: Any
    early: tuple[int, ...]
    late: tuple[int, ...]
    late_slots: tuple[int, ...]
    scratch: ctypes.Array
    outputs: ctypes.Array
    memory: ctypes.Array
    T_s: float
    gathered: memoryview

    def finish(self, k: int) -> None:
        """Its late inputs and doStep of sample k, as the Python execution makes them."""
        t = k * self.T_s
        if self.late:
            memory = self.memory
            self.slave.set(self.late, [memory[slot] for slot in self.late_slots], t)
        self.slave.do_step(t, self.T_s)


class Callbacks:
    """The one callback of a loop for all of its components run in Python (module docstring).
    `turns`: per component index in the plan's order, its `Turns`; T_s the communication step."""

    def __init__(self, turns: dict[int, Turns], T_s: float) -> None:
        self.turns, self.T_s = turns, float(T_s)
        self.answered = np.zeros(1, dtype=np.int64)  # system_t's answered
        self.raised: list[BaseException] = []
        self.target = self._callback()  # the Python function the C calls
        self.function = CALLBACK(self.target)  # its C pointer, kept alive with the loop

    def _callback(self) -> Any:
        turns, T_s, answered, raised = self.turns, self.T_s, self.answered, self.raised

        def call_python(c: int, call: int, k: int) -> None:
            try:
                turn = turns[c]
                if call & CALL_AFTER_STEP:
                    try:
                        turn.finish(k - 1)
                    except SlaveError as error:
                        error.k = k - 1  # a failure of sample k - 1's calls, as the Python execution gives it
                        raise
                t = k * T_s
                early = turn.early
                if early:
                    turn.slave.set(early, turn.gathered.tolist(), t)
                turn.slave.get(turn.outputs, t)
                answered[0] = 1
            except BaseException as error:  # noqa: BLE001 - kept, and raised by `reraise` once the C has returned
                raised.append(error)

        return call_python

    def owns(self, info: Any) -> bool:
        """Whether an unraisable exception's `info` is one escaping this loop's callback (Python
        3.13 names the callback in err_msg, 3.12 gives it as the object)."""
        python = self.target
        return info.object is python or repr(python) in (info.err_msg or "")

    @contextlib.contextmanager
    def catching(self) -> Iterator[None]:
        """While the C runs: an exception that escapes the callback (an interrupt landing before
        its handler runs) is kept for `reraise`, not printed and dropped by ctypes."""
        with _catching(self):
            yield

    def reraise(self, component: str, k: int) -> NoReturn:
        """Raise what the callback of `component` kept at sample k (a SlaveError gets k, unless it
        is of the sample before's calls, as the Python execution gives it)."""
        if not self.raised:
            raise SlaveError(f"component {component!r}: its call at sample {k} did not return", component)
        error = self.raised[0]
        self.raised.clear()
        if isinstance(error, SlaveError) and error.k is None:
            error.k = k
        raise error


_lock = threading.Lock()
_active: list[Callbacks] = []  # the loops running now (any thread), whose callbacks' escapes `_hook` keeps
_previous: list[Any] = []  # the unraisable hook in place before the first of them started


def _hook(info: Any) -> None:
    """sys.unraisablehook while a loop with callbacks runs: an exception escaping one of their
    callbacks is kept by its loop; anything else goes to the hook in place before."""
    error = getattr(info, "exc_value", None)
    for callbacks in tuple(_active):
        if error is not None and callbacks.owns(info):
            callbacks.raised.append(error)
            return
    (_previous[0] if _previous else sys.__unraisablehook__)(info)


@contextlib.contextmanager
def _catching(callbacks: Callbacks) -> Iterator[None]:
    """`_hook` installed from the first loop's start to the last one's end, whichever threads run them."""
    with _lock:
        if not _active:
            _previous[:] = [sys.unraisablehook]
            sys.unraisablehook = _hook
        _active.append(callbacks)
    try:
        yield
    finally:
        with _lock:
            _active.remove(callbacks)
            if not _active and sys.unraisablehook is _hook:
                sys.unraisablehook = _previous.pop()


def turns_of(
    slave: Any,
    early: Sequence[int],
    late: Sequence[int],
    late_slots: Sequence[int],
    scratch: ctypes.Array,
    buffer: np.ndarray,
    out0: int,
    n: int,
    T_s: float,
) -> Turns:
    """A component's `Turns`: its outputs the n slots of `buffer` from out0 (ctypes arrays over the
    buffer, so `get` writes where the C reads, and the late values read are Python floats)."""
    memory = (ctypes.c_double * buffer.size).from_address(buffer.ctypes.data)
    outputs = (ctypes.c_double * max(n, 1)).from_address(buffer.ctypes.data + out0 * buffer.itemsize)
    gathered = memoryview(scratch).cast("B").cast("d")[: len(early)]
    return Turns(slave, tuple(early), tuple(late), tuple(late_slots), scratch, outputs, memory, float(T_s), gathered)
