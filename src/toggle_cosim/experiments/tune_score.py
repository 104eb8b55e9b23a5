"""A trial's score from its cases' sweep rows (pure): the objectives (worst case or mean of a
metric over the map), each metric's worst and mean, and the constraints every case must meet.

An infeasible trial (a failed case, or a case that breaks a constraint) is told to the optimiser
with a penalty, PENALTY x (1 + the share of case-constraint violations), above every feasible
value (the optimisers rank trials, so a penalty only has to be larger); the history keeps its
true figures and says why it is infeasible.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from toggle_cosim.experiments.tune_spec import METRICS, Constraints, Objective

PENALTY = 1.0e6
WORKING_RANGE_FLAG = "(plant.working_range)"  # in a case's plausibility warnings (`cosim.plausibility`)


@dataclass(frozen=True)
class Score:
    """What one trial measured over the map."""

    objectives: list[float]  # as defined (worst or mean of the metric), nan where undefined
    told: list[float]  # what the optimiser is told: the objectives, or a penalty when infeasible
    feasible: bool
    violations: dict[str, int]  # constraint (or "failed") -> cases that break it
    figures: dict[str, float]  # worst_<metric>, mean_<metric> for every metric; cases, settled


def metric_values(rows: Sequence[Mapping[str, Any]], metric: str) -> list[float]:
    """The metric in each ok case (nan where a case has no value: a user controller has no S)."""
    spec = METRICS[metric]
    values = []
    for row in rows:
        if row.get("status") != "ok":
            continue
        value = row.get(spec.column)
        if value is None and metric == "settling_time":
            value = row["t_end"]  # never settled: counts the whole run
        if value is None or (isinstance(value, float) and math.isnan(value)):
            values.append(math.nan)
        else:
            values.append(abs(float(value)) if spec.absolute else float(value))
    return values


def _aggregate(values: list[float], over: str) -> float:
    if not values or any(math.isnan(v) for v in values):
        return math.nan
    return max(values) if over == "worst" else sum(values) / len(values)


def violations(rows: Sequence[Mapping[str, Any]], rated: Sequence[float], constraints: Constraints) -> dict[str, int]:
    """Per constraint, the cases that break it; "failed": the cases that did not run to the end."""
    broken = {"failed": 0}
    if constraints.settles:
        broken["settles"] = 0
    if constraints.final_error_below is not None:
        broken["final_error_below"] = 0
    if constraints.rated_current:
        broken["rated_current"] = 0
    if constraints.working_range:
        broken["working_range"] = 0
    for row, limit in zip(rows, rated, strict=True):
        if row.get("status") != "ok":
            broken["failed"] += 1
            continue
        if constraints.settles and row.get("settling_time_s") is None:
            broken["settles"] += 1
        if constraints.final_error_below is not None and not abs(row["final_error_m"]) < constraints.final_error_below:
            broken["final_error_below"] += 1
        if constraints.rated_current and not row["peak_iq_ref_A"] <= limit:
            broken["rated_current"] += 1
        if constraints.working_range and WORKING_RANGE_FLAG in (row.get("warnings") or ""):
            broken["working_range"] += 1
    return broken


def score(
    rows: Sequence[Mapping[str, Any]], rated: Sequence[float], objectives: Sequence[Objective], constraints: Constraints
) -> Score:
    """The trial's score from its cases' rows, in the map's order (`rated`: each case's rated current)."""
    figures: dict[str, float] = {"cases": float(len(rows))}
    figures["settled"] = float(sum(1 for r in rows if r.get("status") == "ok" and r.get("settling_time_s") is not None))
    for metric in METRICS:
        values = metric_values(rows, metric)
        figures[f"worst_{metric}"] = _aggregate(values, "worst")
        figures[f"mean_{metric}"] = _aggregate(values, "mean")
    values = [figures[f"{o.over}_{o.metric}"] for o in objectives]
    broken = violations(rows, rated, constraints)
    feasible = not any(broken.values()) and not any(math.isnan(v) for v in values)
    if feasible:
        told = list(values)
    else:
        share = sum(broken.values()) / max(1, len(rows))
        told = [PENALTY * (1.0 + share)] * len(values)
    return Score(values, told, feasible, broken, figures)
