"""Reference trajectories of the slider: q*(t), q̇*(t), q̈*(t) for the built-in laws to track.

A profile is a chain of segments of constant jerk (`Segment`), from rest to rest:

* point to point, trapezoidal (`kind: trapezoid`): accelerate at a_max, cruise at v_max,
  decelerate at a_max (triangular, never reaching v_max, when the stroke is short);
* point to point, S-curve (`kind: scurve`): the same with the acceleration ramped at the jerk
  limit j_max (seven segments; fewer when a limit is not reached);
* a cycle (`kind: cycle`): extend from x_start to x_target, dwell, retract to x_start, dwell,
  `repeat` times (the moves trapezoidal, or S-curves when j_max is given); the last dwell is
  omitted and the profile then holds x_start.

Before the profile starts it holds its first position, after its end its last, with zero rate
and acceleration. `evaluate` is the one definition of the profile; `sample` evaluates it once
per run at t_k = k·T_s into the (n + 1, 3) array both loops read (`controller.VSCController`
in Python, the compiled loop in C).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = ["KINDS", "ProfileSpec", "SampledReference", "Segment", "Trajectory", "build", "evaluate", "sample"]

KINDS = ("trapezoid", "scurve", "cycle")
Kind = Literal["trapezoid", "scurve", "cycle"]


@dataclass(frozen=True)
class ProfileSpec:
    """A profile as a scenario gives it (stroke.trajectory), with the stroke's end points.

    Attributes:
        kind: "trapezoid", "scurve" or "cycle".
        x_start, x_target: the stroke's end points [m].
        v_max: velocity limit [m/s] (> 0).
        a_max: acceleration limit [m/s²] (> 0).
        j_max: jerk limit [m/s³]: required for "scurve"; for "cycle" the moves are S-curves
            when it is given, trapezoids when it is None.
        dwell: a cycle's dwell at each end [s] (≥ 0).
        repeat: a cycle's number of extend-dwell-retract cycles (≥ 1).
        t_start: when the first move starts [s] (≥ 0).
    """

    kind: Kind
    x_start: float
    x_target: float
    v_max: float
    a_max: float
    j_max: float | None = None
    dwell: float = 0.0
    repeat: int = 1
    t_start: float = 0.0


@dataclass(frozen=True)
class Segment:
    """A stretch of constant jerk from time t0 for `duration` seconds, starting at position x0,
    velocity v0 and acceleration a0: x(t0 + τ) = x0 + v0 τ + a0 τ²/2 + jerk τ³/6."""

    t0: float
    duration: float
    x0: float
    v0: float
    a0: float
    jerk: float


@dataclass(frozen=True)
class Trajectory:
    """A profile: its segments in time order, and the position it holds before and after them."""

    segments: tuple[Segment, ...]
    x_first: float
    x_last: float

    @property
    def end(self) -> float:
        """When the last segment ends [s] (the profile's start when it has none)."""
        if not self.segments:
            return 0.0
        last = self.segments[-1]
        return last.t0 + last.duration


def _phases(distance: float, v_max: float, a_max: float, j_max: float | None) -> list[tuple[float, float, float]]:
    """The (duration, a0, jerk) phases of a rest-to-rest move over `distance` > 0 in the positive
    direction under the limits (segments of zero duration left out)."""
    if j_max is None:  # trapezoid
        if distance >= v_max * v_max / a_max:
            t_a, v = v_max / a_max, v_max
        else:  # triangular
            t_a = math.sqrt(distance / a_max)
            v = a_max * t_a
        t_v = (distance - v * t_a) / v
        phases = [(t_a, a_max, 0.0), (t_v, 0.0, 0.0), (t_a, -a_max, 0.0)]
    else:  # S-curve: jerk-limited ramps of the acceleration
        v = v_max

        def accel_time(v: float) -> tuple[float, float, float]:
            """(T_j, T_ca, peak acceleration) of the ramp from 0 to v."""
            if v * j_max >= a_max * a_max:
                return a_max / j_max, v / a_max - a_max / j_max, a_max
            t_j = math.sqrt(v / j_max)
            return t_j, 0.0, j_max * t_j

        t_j, t_ca, a = accel_time(v)
        if v * (2.0 * t_j + t_ca) > distance:  # v_max not reached: the highest velocity that fits
            v = 0.5 * a_max * (-a_max / j_max + math.sqrt(a_max * a_max / (j_max * j_max) + 4.0 * distance / a_max))
            if v * j_max < a_max * a_max:
                v = (distance * math.sqrt(j_max) / 2.0) ** (2.0 / 3.0)
            t_j, t_ca, a = accel_time(v)
        t_v = max(distance - v * (2.0 * t_j + t_ca), 0.0) / v
        phases = [
            (t_j, 0.0, j_max),
            (t_ca, a, 0.0),
            (t_j, a, -j_max),
            (t_v, 0.0, 0.0),
            (t_j, 0.0, -j_max),
            (t_ca, -a, 0.0),
            (t_j, -a, j_max),
        ]
    return [phase for phase in phases if phase[0] > 0.0]


def _move(t0: float, x0: float, x1: float, spec: ProfileSpec, j_max: float | None) -> list[Segment]:
    """The segments of a rest-to-rest move from x0 to x1 starting at t0."""
    sign = 1.0 if x1 >= x0 else -1.0
    segments, t, x, v = [], t0, x0, 0.0
    for duration, a0, jerk in _phases(abs(x1 - x0), spec.v_max, spec.a_max, j_max):
        segment = Segment(t, duration, x, v, sign * a0, sign * jerk)
        segments.append(segment)
        x, v, _ = _at(segment, duration)
        t += duration
    return segments


def _dwell(t0: float, x: float, duration: float) -> list[Segment]:
    return [Segment(t0, duration, x, 0.0, 0.0, 0.0)] if duration > 0.0 else []


def build(spec: ProfileSpec) -> Trajectory:
    """The profile of `spec` (module docstring). Raises ValueError naming the setting at fault."""
    for name in ("v_max", "a_max"):
        value = getattr(spec, name)
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"{name}: must be a positive number, got {value!r}")
    if spec.kind not in KINDS:
        raise ValueError(f"kind: choose one of {', '.join(KINDS)}, not {spec.kind!r}")
    if spec.kind == "scurve" and spec.j_max is None:
        raise ValueError("j_max: an S-curve needs a jerk limit (give j_max, or use kind: trapezoid)")
    if spec.j_max is not None and not (math.isfinite(spec.j_max) and spec.j_max > 0.0):
        raise ValueError(f"j_max: must be a positive number, got {spec.j_max!r}")
    if not (math.isfinite(spec.dwell) and spec.dwell >= 0.0):
        raise ValueError(f"dwell: must be a non-negative number, got {spec.dwell!r}")
    if spec.repeat < 1:
        raise ValueError(f"repeat: must be at least 1, got {spec.repeat!r}")
    j_max = None if spec.kind == "trapezoid" else spec.j_max
    if spec.kind != "cycle":
        segments = _move(spec.t_start, spec.x_start, spec.x_target, spec, j_max)
        return Trajectory(tuple(segments), spec.x_start, spec.x_target)
    segments: list[Segment] = []
    t = spec.t_start
    for i in range(spec.repeat):
        for x0, x1 in ((spec.x_start, spec.x_target), (spec.x_target, spec.x_start)):
            segments += _move(t, x0, x1, spec, j_max)
            t = segments[-1].t0 + segments[-1].duration
            if not (i == spec.repeat - 1 and x1 == spec.x_start):
                segments += _dwell(t, x1, spec.dwell)
                t += spec.dwell
    return Trajectory(tuple(segments), spec.x_start, spec.x_start)


def _at(segment: Segment, tau: float) -> tuple[float, float, float]:
    """(x, v, a) of a segment τ seconds after its start."""
    j, a0, v0 = segment.jerk, segment.a0, segment.v0
    return (
        segment.x0 + tau * (v0 + tau * (a0 / 2.0 + tau * j / 6.0)),
        v0 + tau * (a0 + tau * j / 2.0),
        a0 + tau * j,
    )


def evaluate(trajectory: Trajectory, t: float) -> tuple[float, float, float]:
    """(q*, q̇*, q̈*) of the profile at time t: its first position before it starts, its last after
    it ends (at rest), else the segment's polynomial."""
    segments = trajectory.segments
    if not segments or t < segments[0].t0:
        return trajectory.x_first, 0.0, 0.0
    if t >= trajectory.end:
        return trajectory.x_last, 0.0, 0.0
    i = bisect.bisect_right([s.t0 for s in segments], t) - 1
    return _at(segments[i], t - segments[i].t0)


def sample(trajectory: Trajectory, n: int, T_s: float) -> np.ndarray:
    """The profile at t_k = k·T_s, k = 0 .. n: an (n + 1, 3) float64 array in C order, row k
    (q*, q̇*, q̈*) = evaluate(trajectory, k·T_s)."""
    rows = [evaluate(trajectory, k * T_s) for k in range(n + 1)]
    return np.ascontiguousarray(np.array(rows, dtype=np.float64).reshape(n + 1, 3))


@dataclass(frozen=True, eq=False)
class SampledReference:
    """A profile sampled once per run: `values` row k = (q*, q̇*, q̈*) at t_k = k·T_s, k = 0 .. n
    (`sample`), the array the compiled loop reads; `at` gives the Python loop the same row (the
    same floats), and evaluates the profile itself at a time off the sample grid."""

    trajectory: Trajectory
    T_s: float
    values: np.ndarray

    @classmethod
    def of(cls, trajectory: Trajectory, n: int, T_s: float) -> SampledReference:
        """`trajectory` sampled at k·T_s, k = 0 .. n."""
        return cls(trajectory, T_s, sample(trajectory, n, T_s))

    def __post_init__(self) -> None:
        object.__setattr__(self, "_rows", [tuple(row) for row in self.values.tolist()])

    def at(self, t: float) -> tuple[float, float, float]:
        """(q*, q̇*, q̈*) at t: row k where t = k·T_s, else `evaluate(trajectory, t)`."""
        rows = self._rows  # type: ignore[attr-defined]
        k = round(t / self.T_s)
        if 0 <= k < len(rows) and k * self.T_s == t:
            return rows[k]
        return evaluate(self.trajectory, t)
