"""The trace of a run as it is being made, and the hooks called as samples are stepped.

After FMPy's `simulateCS`, whose `Recorder` collects the outputs and whose `step_finished`
callback sees every step. Here the recorder is a preallocated (samples x columns) float64
array, filled with NaN: its own, or a buffer it is given (a disk-backed map the supervising
process reads, `supervision`), written in place by both steppers (the compiled loop writes
into the same memory). `rows` counts the samples recorded: it lives in `count`, one int64 (its
own, or a shared one the supervising process reads), set after each whole sample by whichever
loop records it, the C loops included. The count is never read from the values: a NaN or an
infinity in a row is a value like any other. `trace()` is the Trace of the counted rows.
All samples are recorded; the scenario key record_every thins only the CSV (`traces`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from toggle_cosim.files.traces import Trace


def row_count(count: np.ndarray | None = None) -> np.ndarray:
    """The row count a recorder keeps its `rows` in: `count` (checked: one int64, set to 0), or a
    new one. A supervising process passes one it shares with the child (`supervision`)."""
    if count is None:
        return np.zeros(1, dtype=np.int64)
    if count.shape != (1,) or count.dtype != np.int64 or not count.flags.c_contiguous:
        raise ValueError(f"the row count must be one C-contiguous int64, not {count.dtype} {count.shape}")
    count[0] = 0
    return count


class Recorder:
    """Columns: time, the plant outputs, the inputs iq_ref and F_E, the controller's diagnostics,
    then the plant's `extra` other inputs (`Run.plant.inputs`, col_x on); one row per sample 0 .. n.
    `count`: the shared row count (`row_count`); None: its own."""

    def __init__(
        self,
        names: Sequence[str],
        n: int,
        buffer: np.ndarray | None = None,
        extra: int = 0,
        count: np.ndarray | None = None,
    ) -> None:
        self.names = tuple(names)
        self.n = n
        shape = (n + 1, len(self.names))
        if buffer is not None and (buffer.shape != shape or buffer.dtype != np.float64):
            raise ValueError(f"the trace buffer must be float64 of shape {shape}, not {buffer.dtype} {buffer.shape}")
        self.data = np.full(shape, np.nan) if buffer is None else buffer
        self._owned = buffer is None
        self.col_u = self.names.index("iq_ref")
        self.n_out = self.col_u - 1
        self.i_x, self.i_v = self.names.index("x_B"), self.names.index("v_B")
        self.col_x = len(self.names) - extra  # the first of the other inputs' columns
        self.count = row_count(count)

    @property
    def rows(self) -> int:
        """The samples recorded (rows 0 .. rows - 1), as counted, whatever their values."""
        return int(self.count[0])

    @rows.setter
    def rows(self, rows: int) -> None:
        self.count[0] = rows

    def outputs(self, k: int) -> np.ndarray:
        """The plant-output cells of row k (a view: the session reads the FMU's outputs into it)."""
        return self.data[k, 1 : 1 + self.n_out]

    def inputs(self, k: int) -> tuple[float, ...]:
        """The inputs (iq_ref, F_E, then the other inputs) sent to the plant after sample k, as recorded."""
        row = self.data[k]
        return (row[self.col_u], row[self.col_u + 1], *row[self.col_x :])

    def truncate(self, rows: int) -> None:
        """Keep the first `rows` samples: the count goes back, and the later rows are unset (NaN)
        again, in a shared buffer too."""
        recorded = self.rows
        if rows < recorded:
            self.rows = rows
            self.data[rows:recorded] = np.nan

    def trace(self) -> Trace:
        """The samples recorded so far: a copy of an own array, a view of a given buffer."""
        rows = self.data[: self.rows]
        return Trace(self.names, rows.copy() if self._owned else rows)


class StepHook(Protocol):
    """Called after the doStep of every `every`-th sample k (k % every == 0, k < n)."""

    every: int

    def __call__(self, k: int) -> None: ...


class ProgressHook:
    """Reports the fraction of the run done, every 1 % of the samples (at least every sample)."""

    def __init__(self, report: Callable[[float], None], n: int, T_s: float, t_end: float) -> None:
        self.report, self.T_s, self.t_end = report, T_s, t_end
        self.every = max(n // 100, 1)

    def __call__(self, k: int) -> None:
        self.report(k * self.T_s / self.t_end)
