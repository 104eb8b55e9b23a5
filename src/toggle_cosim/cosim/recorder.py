"""The trace of a run as it is being made, and the hooks called as samples are stepped.

After FMPy's `simulateCS`, whose `Recorder` collects the outputs and whose `step_finished`
callback sees every step. Here the recorder is a preallocated (samples x columns) float64
array, filled with NaN: its own, or a buffer it is given (a disk-backed map the supervising
process reads, `supervision`), written in place by both steppers (the compiled loop writes
into the same memory). `rows` counts the samples recorded; `trace()` is the Trace of them.
All samples are recorded; the scenario key record_every thins only the CSV (`traces`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from toggle_cosim.files.traces import Trace


class Recorder:
    """Columns: time, the plant outputs, the inputs iq_ref and F_E, the controller's diagnostics,
    then the plant's `extra` other inputs (`Run.plant.inputs`, col_x on); one row per sample 0 .. n."""

    def __init__(self, names: Sequence[str], n: int, buffer: np.ndarray | None = None, extra: int = 0) -> None:
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
        self.rows = 0

    def outputs(self, k: int) -> np.ndarray:
        """The plant-output cells of row k (a view: the session reads the FMU's outputs into it)."""
        return self.data[k, 1 : 1 + self.n_out]

    def inputs(self, k: int) -> tuple[float, ...]:
        """The inputs (iq_ref, F_E, then the other inputs) sent to the plant after sample k, as recorded."""
        row = self.data[k]
        return (row[self.col_u], row[self.col_u + 1], *row[self.col_x :])

    def truncate(self, rows: int) -> None:
        """Keep the first `rows` samples: the later ones are unset (NaN) again, in the buffer
        too, so a supervising process that counts the set rows sees the same number."""
        if rows < self.rows:
            self.data[rows : self.rows] = np.nan
            self.rows = rows

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
