"""Signals: what a plant input is over time, defined once as typed, pure data.

A signal is a constant, a profile (step, ramp, pulse train, sine, piecewise-linear points) or a
table (times and values with `hold` or `linear` interpolation, e.g. read from a CSV file by
`signals.tables`). Each is a frozen dataclass with `at(times)`: the signal at an array of
times, vectorised with numpy (np.interp for linear tables, np.searchsorted for a hold). The
profiles follow Modelica.Blocks.Sources (Step, Ramp, Pulse, Sine: offset, height or amplitude,
start_time), so a control engineer reads them as they know them.

Edges (the value a sample sees exactly at a breakpoint): every signal is continuous from the
right. A sample at t_k sees the value *after* an edge at τ when t_k ≥ τ: a step at 0.75 s is
seen by the sample at t = 0.75 s, a pulse is high on [start, start + width) of each period,
a `hold` table gives the value of the last row whose time is ≤ t_k. Times within EDGE_TOLERANCE
of an edge count as on it, so the rounding of k·T_s never moves an edge by a sample.

The parameters of each kind (their names, bounds, which are required) are the dataclass fields
and their metadata: `signals.schema` generates the scenario's JSON Schema from them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Literal

import numpy as np

EDGE_TOLERANCE = 1e-12  # s: a sample this close to an edge counts as on it (k * T_s rounding)
VALUE_BOUND = 1e6  # |a value parameter| at most this (a schema bound against typing errors)
TIME_BOUND = 1e3  # s: times and periods at most this (a run lasts at most 100 s)
INTERPOLATIONS = ("hold", "linear")


def _value(description: str, default: float | None = None) -> Any:
    metadata = {"description": description, "minimum": -VALUE_BOUND, "maximum": VALUE_BOUND}
    return field(metadata=metadata) if default is None else field(default=default, metadata=metadata)


def _time(description: str, default: float | None = None, positive: bool = False) -> Any:
    bounds = {"exclusiveMinimum": 0} if positive else {"minimum": 0}
    metadata = {"description": description, **bounds, "maximum": TIME_BOUND}
    return field(metadata=metadata) if default is None else field(default=default, metadata=metadata)


class SignalError(ValueError):
    """A signal that cannot be used; str() is the one-line reason (the caller adds file and key)."""


@dataclass(frozen=True)
class Constant:
    """One value for the whole run (a plain number in a scenario: `F_E: 100.0`)."""

    kind: ClassVar[str] = "constant"
    value: float = _value("the value, in the input's unit")

    def at(self, times: np.ndarray) -> np.ndarray:
        return np.full(np.shape(times), float(self.value))


@dataclass(frozen=True)
class Step:
    """offset before start_time, offset + height from start_time on (Modelica's Step)."""

    kind: ClassVar[str] = "step"
    height: float = _value("the change at start_time, in the input's unit")
    start_time: float = _time("when the step is taken, s")
    offset: float = _value("the value before start_time", default=0.0)

    def at(self, times: np.ndarray) -> np.ndarray:
        t = np.asarray(times, dtype=float)
        return np.where(t >= self.start_time - EDGE_TOLERANCE, self.offset + self.height, float(self.offset))


@dataclass(frozen=True)
class Ramp:
    """offset until start_time, then linear to offset + height over `duration`, then held
    (Modelica's Ramp)."""

    kind: ClassVar[str] = "ramp"
    height: float = _value("the change over the ramp, in the input's unit")
    duration: float = _time("how long the ramp lasts, s", positive=True)
    start_time: float = _time("when the ramp starts, s", default=0.0)
    offset: float = _value("the value before start_time", default=0.0)

    def at(self, times: np.ndarray) -> np.ndarray:
        t = np.asarray(times, dtype=float)
        share = np.clip((t - self.start_time) / self.duration, 0.0, 1.0)
        return self.offset + share * self.height


@dataclass(frozen=True)
class Pulse:
    """A pulse train: offset + amplitude on [start_time + j·period, start_time + j·period + width)
    for j = 0, 1, ... (`count` pulses, or without end), offset elsewhere (Modelica's Pulse, with
    the width in seconds)."""

    kind: ClassVar[str] = "pulse"
    amplitude: float = _value("the pulse's height above offset, in the input's unit")
    period: float = _time("time from one pulse's start to the next, s", positive=True)
    width: float = _time("how long each pulse lasts, s (less than period)", positive=True)
    start_time: float = _time("when the first pulse starts, s", default=0.0)
    offset: float = _value("the value between pulses", default=0.0)
    count: int | None = field(
        default=None, metadata={"description": "how many pulses (default: no end)", "minimum": 1, "maximum": 10**9}
    )

    def __post_init__(self) -> None:
        if not self.width < self.period:
            raise SignalError(f"width {self.width} s is not shorter than period {self.period} s (make width < period)")

    def at(self, times: np.ndarray) -> np.ndarray:
        t = np.asarray(times, dtype=float) - self.start_time
        j = np.floor((t + EDGE_TOLERANCE) / self.period)
        into = t - j * self.period
        on = (t >= -EDGE_TOLERANCE) & (into < self.width - EDGE_TOLERANCE)
        if self.count is not None:
            on &= j < self.count
        return np.where(on, self.offset + self.amplitude, float(self.offset))


@dataclass(frozen=True)
class Sine:
    """offset + amplitude·sin(2π·frequency·(t − start_time) + phase) from start_time on, offset
    before (Modelica's Sine)."""

    kind: ClassVar[str] = "sine"
    amplitude: float = _value("the sine's amplitude, in the input's unit")
    frequency: float = field(metadata={"description": "frequency in Hz", "exclusiveMinimum": 0, "maximum": VALUE_BOUND})
    phase: float = field(
        default=0.0, metadata={"description": "phase at start_time, rad", "minimum": -100.0, "maximum": 100.0}
    )
    start_time: float = _time("when the sine starts, s", default=0.0)
    offset: float = _value("the value the sine swings about", default=0.0)

    def at(self, times: np.ndarray) -> np.ndarray:
        t = np.asarray(times, dtype=float) - self.start_time
        swing = self.amplitude * np.sin(2.0 * math.pi * self.frequency * t + self.phase)
        return self.offset + np.where(t >= -EDGE_TOLERANCE, swing, 0.0)


@dataclass(frozen=True)
class TableSource:
    """Where a table came from: its CSV file (as the scenario names it, resolved), the file's
    SHA-256, the value column and the unit its header gives (None: none given)."""

    path: str
    sha256: str
    column: str
    unit: str | None


def frozen_floats(values: Any) -> np.ndarray:
    """`values` as a read-only one-dimensional float64 array, copied unless it already is one: a
    table's columns are shared by every run that reads them and never changed."""
    if (
        isinstance(values, np.ndarray)
        and values.dtype == np.float64
        and values.ndim == 1
        and not values.flags.writeable
    ):
        return values
    array = np.array(values, dtype=np.float64).reshape(-1)
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class Table:
    """Values at times (strictly increasing, finite), between them `hold` (the last row's value)
    or `linear` (np.interp). A table must cover the run: first time ≤ 0, last ≥ t_end
    (`check_covers`). `points` in a scenario, or a CSV file (`source`). The times and values
    are read-only float64 arrays (8 bytes a number, however long the table); two tables are
    equal when their rows, interpolation and source are."""

    kind: ClassVar[str] = "table"
    times: np.ndarray
    values: np.ndarray
    interpolation: Literal["hold", "linear"] = "linear"
    source: TableSource | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "times", frozen_floats(self.times))
        object.__setattr__(self, "values", frozen_floats(self.values))
        check_table(self.times, self.values)
        if self.interpolation not in INTERPOLATIONS:
            raise SignalError(f"interpolation {self.interpolation!r}: choose hold or linear")

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Table):
            return NotImplemented
        return (
            (self.interpolation, self.source) == (other.interpolation, other.source)
            and np.array_equal(self.times, other.times)
            and np.array_equal(self.values, other.values)
        )

    def __hash__(self) -> int:
        return hash((self.interpolation, self.source, len(self.times), float(self.times[0]), float(self.values[0])))

    def at(self, times: np.ndarray) -> np.ndarray:
        t = np.asarray(times, dtype=float)
        xp, fp = self.times, self.values
        if self.interpolation == "linear":
            return np.interp(t, xp, fp)
        rows = np.searchsorted(xp, t + EDGE_TOLERANCE, side="right") - 1
        return fp[np.clip(rows, 0, len(fp) - 1)]

    def check_covers(self, t_end: float) -> None:
        """Raise SignalError unless the table spans [0, t_end]."""
        if self.times[0] > 0.0:
            raise SignalError(f"the table starts at t = {self.times[0]:g} s, after 0 (add a row at time 0)")
        if self.times[-1] < t_end - EDGE_TOLERANCE:
            raise SignalError(
                f"the table ends at t = {self.times[-1]:g} s, before the run's t_end = {t_end:g} s "
                "(add rows up to t_end, or shorten t_end)"
            )


def check_table(times: Sequence[float], values: Sequence[float], label: Callable[[int], str] | None = None) -> None:
    """Raise SignalError unless times and values are as long, at least 2, finite, and the times
    strictly increasing; the message names the first bad row (`label(i)`, default "row i + 1")."""
    if len(times) != len(values):
        raise SignalError(f"{len(times)} times and {len(values)} values (give one value per time)")
    if len(times) < 2:
        raise SignalError(f"a table needs at least 2 rows, not {len(times)}")
    if label is None:

        def label(i: int) -> str:
            return f"row {i + 1}"

    t, v = np.asarray(times, dtype=float), np.asarray(values, dtype=float)
    bad = np.flatnonzero(~(np.isfinite(t) & np.isfinite(v)))
    if bad.size:
        i = int(bad[0])
        raise SignalError(f"{label(i)}: ({float(t[i])!r}, {float(v[i])!r}) is not finite (give finite numbers)")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        i = int(back[0]) + 1  # the first row whose time does not increase
        what = "repeats" if t[i] == t[i - 1] else "comes before"
        raise SignalError(
            f"{label(i)}: time {float(t[i])!r} {what} the time of {label(i - 1)} ({float(t[i - 1])!r}); "
            "times must increase strictly (sort the table, drop repeated times)"
        )


Signal = Constant | Step | Ramp | Pulse | Sine | Table
PROFILES: dict[str, type] = {cls.kind: cls for cls in (Step, Ramp, Pulse, Sine)}


def parameters(kind: type) -> tuple[Any, ...]:
    """The dataclass fields of a profile kind: its scenario parameters."""
    return tuple(f for f in fields(kind) if f.name != "kind")


def as_signal(value: float | Signal) -> Signal:
    """A number as the Constant it stands for; a Signal as it is."""
    return Constant(float(value)) if isinstance(value, (int, float)) else value


def sample(signal: Signal, n: int, T_s: float) -> np.ndarray:
    """The signal at t_k = k·T_s for k = 0 .. n (float64, n + 1 values): the times as the master's
    loop computes them (k * T_s), so sample k sends exactly entry k."""
    times = np.arange(n + 1, dtype=np.float64) * T_s
    return np.ascontiguousarray(signal.at(times), dtype=np.float64)


def describe(signal: Signal) -> dict[str, Any]:
    """What run.json records of a signal: its kind and parameters (a table: interpolation, rows,
    its first and last time, and the CSV's path, SHA-256, column and unit; or its points)."""
    if isinstance(signal, Constant):
        return {"kind": "constant", "value": signal.value}
    if isinstance(signal, Table):
        record: dict[str, Any] = {
            "kind": "table",
            "interpolation": signal.interpolation,
            "rows": len(signal.times),
            "t_first": float(signal.times[0]),
            "t_last": float(signal.times[-1]),
        }
        if signal.source is None:
            record["points"] = [list(p) for p in zip(signal.times.tolist(), signal.values.tolist(), strict=True)]
        else:
            source = signal.source
            record |= {"file": source.path, "sha256": source.sha256, "column": source.column, "unit": source.unit}
        return record
    return {"kind": signal.kind, **{f.name: getattr(signal, f.name) for f in parameters(type(signal))}}
