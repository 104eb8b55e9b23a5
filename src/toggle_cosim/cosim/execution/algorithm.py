"""An execution: a system's slaves stepped by one algorithm, with observers (after libcosim's
execution, algorithm and observers).

* `Execution` owns the slaves (`slaves`), in the plan's stepping order, the plan
  (`system.plan`: the buffer, the feeds, which inputs are set early and which late) and the
  signal table (the inputs fed by signals, sampled at every t_k). `initialize` instantiates
  every slave, sets its values, enters initialisation, runs one Gauss-Seidel pass at t = 0
  whatever the coupling (so every connected input starts from its source's initial output, the
  fixed point libcosim's initialisation iterates to) and exits initialisation;
  `advance(k, stop)` runs samples k .. stop - 1; `advance(k, k + 1, split=(c, m))` runs sample
  k with component c stepping in m substeps of T_s / m (a checkpoint retry, `system_retry`).
* The algorithm is the plan's: Gauss-Seidel (its order, early and late inputs) or Jacobi (every
  input late). Both are the sample procedure of `system.plan`, which the C loop
  (`cosim.execution.system_loop`) runs too.
* Observers see every sample after it is complete: `TraceObserver` writes row k of the trace
  (the plan's recorded slots), a progress hook reports.

A failed call raises `SlaveError` (the component, the call, the time; its `k` the sample); the
samples before it are in the trace. The finiteness guard (`guard`, an option) checks its slots
as they are set and read, and raises its `refusal` before the call that would pass the value
on. A native controller is told which outputs feed what it measures (`ControllerSlave.fed_from`),
to name one that is not finite. Before each call of a slave its id goes into `calling[0]` (the
compiled loop does the same), so a supervising process that shares that word knows whose call
ended the process.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from toggle_cosim.cosim.execution.guard import FiniteGuard, refusal
from toggle_cosim.cosim.execution.slaves import Slave, SlaveError
from toggle_cosim.system.plan import SIGNAL, Plan

__all__ = ["Execution", "Observer", "TraceObserver", "row_count"]


def row_count(count: np.ndarray | None = None) -> np.ndarray:
    """The row count a trace observer keeps its `rows` in: `count` (checked: one int64, set to 0),
    or a new one. A supervising process passes one it shares with the child (`supervision`)."""
    if count is None:
        return np.zeros(1, dtype=np.int64)
    if count.shape != (1,) or count.dtype != np.int64 or not count.flags.c_contiguous:
        raise ValueError(f"the row count must be one C-contiguous int64, not {count.dtype} {count.shape}")
    count[0] = 0
    return count


class Observer(Protocol):
    def observe(self, k: int, t: float, values: np.ndarray) -> None:
        """Sample k at t is complete: `values` is the plan's buffer."""
        ...


class TraceObserver:
    """Records the plan's recorded slots into row k of `data` ((n + 1) x (1 + len(record)),
    column 0 the time); `rows` counts the samples recorded, in `count` (`row_count`:
    its own, or one shared with a supervising process; the compiled loop counts in it too),
    never from the values: a recorded NaN is a value."""

    def __init__(self, plan: Plan, data: np.ndarray, count: np.ndarray | None = None) -> None:
        self.data, self.columns, self.count = data, np.asarray(plan.record, dtype=np.int64), row_count(count)

    @property
    def rows(self) -> int:
        """The samples recorded (rows 0 .. rows - 1), as counted, whatever their values."""
        return int(self.count[0])

    def observe(self, k: int, t: float, values: np.ndarray) -> None:
        row = self.data[k]
        row[0] = t
        row[1:] = values[self.columns]
        self.count[0] = k + 1


class Execution:
    """The slaves of a plan (in its order), the signal table ((n + 1) x m: column j feeds
    plan.signals[j]), n samples of T_s, and the observers (module docstring)."""

    def __init__(
        self,
        plan: Plan,
        slaves: Sequence[Slave],
        signals: np.ndarray,
        n: int,
        T_s: float,
        t_end: float,
        observers: Sequence[Observer] = (),
        hooks: Sequence[Callable[[int], None]] = (),
        calling: np.ndarray | None = None,
        ids: Sequence[int] | None = None,
        guard: FiniteGuard | None = None,
    ) -> None:
        """`calling`: an int64 array whose element 0 gets, before each call of a slave, its entry
        of `ids` (per slave, in plan order; default 1, 2, ...). `guard`: the slots whose values
        must be finite (`guard`; None: none)."""
        self.plan, self.slaves, self.signals = plan, tuple(slaves), signals
        self.calling = calling if calling is not None else np.zeros(1, dtype=np.int64)
        self.ids = tuple(ids) if ids is not None else tuple(range(1, len(self.slaves) + 1))
        self.n, self.T_s, self.t_end = n, float(T_s), float(t_end)
        self.observers, self.hooks = tuple(observers), tuple(hooks)
        self.values = np.zeros(plan.size, dtype=np.float64)
        for c, slave in enumerate(self.slaves):
            slave.bind(plan.input_names[c], plan.output_names[c])
            fed_from = getattr(slave, "fed_from", None)
            if callable(fed_from):
                fed_from(list(plan.fed_by[c]))
        self._out = [(ctypes.c_double * max(len(slots), 1))() for slots in plan.outputs]
        source = plan.feed_source
        self._feeds = [
            [(slot, int(source[slot]), float(plan.feed_factor[slot]), float(plan.feed_offset[slot])) for slot in slots]
            for slots in plan.inputs
        ]
        self._early = plan.early
        self._late = plan.late
        self._guard_in = guard.inputs if guard is not None else (frozenset(),) * len(self.slaves)
        self._guard_out = guard.outputs if guard is not None else ((),) * len(self.slaves)

    def _check(self, c: int, positions: Sequence[int], values: Sequence[float], t: float) -> None:
        """The guard (`guard`) on the inputs `positions` of component c about to be set to `values`."""
        guarded = self._guard_in[c]
        for i, value in zip(positions, values, strict=True):
            if i in guarded and not math.isfinite(value):
                raise refusal(self.plan, c, self.plan.inputs[c][i], value, t)

    def _feed(self, c: int, positions: Sequence[int], k: int) -> list[float]:
        """Compute the inputs `positions` of component c at sample k into the buffer; their values."""
        values, feeds, out = self.values, self._feeds[c], []
        for i in positions:
            slot, source, factor, offset = feeds[i]
            if source <= SIGNAL:
                value = float(self.signals[k, SIGNAL - source])
            else:
                value = float(values[source])
                if factor != 1.0 or offset != 0.0:
                    value = factor * value + offset
            values[slot] = value
            out.append(value)
        return out

    def _read(self, c: int, t: float) -> None:
        slots, out = self.plan.outputs[c], self._out[c]
        self.slaves[c].get(out, t)
        if slots:
            self.values[slots[0] : slots[0] + len(slots)] = out[: len(slots)]
        for j in self._guard_out[c]:
            if not math.isfinite(out[j]):
                raise refusal(self.plan, c, slots[j], out[j], t)

    def _pass(
        self, k: int, t: float, early: Sequence[tuple[int, ...]], late: Sequence[tuple[int, ...]]
    ) -> list[list[float]]:
        """Every component in order: its early inputs set, its outputs read; then the values of
        the late inputs, per component (computed into the buffer, not yet set)."""
        calling, ids, guard_in = self.calling, self.ids, self._guard_in
        for c, slave in enumerate(self.slaves):
            calling[0] = ids[c]
            if early[c]:
                values = self._feed(c, early[c], k)
                if guard_in[c]:
                    self._check(c, early[c], values, t)
                slave.set(early[c], values, t)
            self._read(c, t)
        return [self._feed(c, late[c], k) for c in range(len(self.slaves))]

    def _set_late(self, t: float, late: Sequence[tuple[int, ...]], values: Sequence[Sequence[float]]) -> None:
        for c, slave in enumerate(self.slaves):
            if late[c]:
                self.calling[0] = self.ids[c]
                if self._guard_in[c]:
                    self._check(c, late[c], values[c], t)
                slave.set(late[c], values[c], t)

    def initialize(self) -> None:
        """Instantiate, set values, initialise every slave with its inputs from one pass at t = 0."""
        for c, slave in enumerate(self.slaves):
            self.calling[0] = self.ids[c]
            slave.instantiate(self.t_end)
        for c, slave in enumerate(self.slaves):
            self.calling[0] = self.ids[c]
            slave.enter_initialization()
        late = self.plan.init_late
        self._set_late(0.0, late, self._pass(0, 0.0, self.plan.init_early, late))
        for c, slave in enumerate(self.slaves):
            self.calling[0] = self.ids[c]
            slave.exit_initialization()

    def advance(self, k: int, stop: int, split: tuple[int, int] | None = None) -> int:
        """Samples k .. stop - 1 (the last, n, is read and recorded, not stepped); the next sample.
        `split` (c, m): component c steps in m substeps of T_s / m, its inputs held. A failed call's
        SlaveError gets the sample in `k`."""
        T_s, n, slaves, observers, hooks = self.T_s, self.n, self.slaves, self.observers, self.hooks
        calling, ids = self.calling, self.ids
        early, late = self._early, self._late
        split_c, parts = split if split is not None else (-1, 1)
        try:
            while k < stop:
                t = k * T_s
                values = self._pass(k, t, early, late)
                for observer in observers:
                    observer.observe(k, t, self.values)
                if k == n:
                    return k + 1
                self._set_late(t, late, values)
                for c, slave in enumerate(slaves):
                    calling[0] = ids[c]
                    if c == split_c:
                        h = T_s / parts
                        for m in range(parts):
                            slave.do_step(t + m * h, h)
                    else:
                        slave.do_step(t, T_s)
                for hook in hooks:
                    hook(k)
                k += 1
        except SlaveError as error:
            error.k = k
            raise
        return k
