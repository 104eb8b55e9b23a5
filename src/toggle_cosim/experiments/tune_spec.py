"""The tuning file: its schema, loading and validation, and the cases a trial runs.

    name: tune_integral                    # optional, default: the file's stem
    description: the integral law over the F_E x m_B map
    sweep: sweep_law_FE_mB.yaml            # the map: the cases of this sweep file (relative to this file)
    fix: {controller.law: integral}        # optional: an axis held at one of its values, or any
                                           # scenario key set in every case (t_end: 0.5)
    parameters:                            # the scenario keys tuned, with their bounds
      controller.C_I: {low: 4, high: 60}
      controller.K_I: {low: 4, high: 900, log: true}
    objective: {metric: settling_time, over: worst}   # or a list of two: a Pareto front
    constraints:                           # every case must meet them, else the trial is infeasible
      settles: true                        # the 2 % band reached and kept by t_end
      final_error_below: 1.0e-4            # m, |final error|
      rated_current: true                  # peak |i_q*| <= plant.rated_current
      working_range: true                  # x_B stays in plant.working_range
    optimiser: {sampler: tpe, trials: 60, batch: 4, seed: 1}
    case_budget: {events: 12000}           # optional: the keys of budget set in every case (default
                                           # {events_per_sample: 4}); none: the scenario's own, if any
    output: ../out/tune/tune_integral      # relative to this file; default out/tune/<name>

Tuned keys are scenario keys, set in every case as a sweep's axes are (`sweep_spec.set_key`):
built-in gains (controller.gains.C, controller.C_I), a Python factory's parameters
(controller.parameters.NAME), a controller FMU's parameters (controller.parameters.NAME), the
plant's parameters. Both bounds are checked as values of the key before anything runs.

Every case runs under a work budget (`cosim.execution.budget`): a case that chatters ends at the same
sample, failed, on a quiet and on a busy machine, so the same file gives the same trials.
`case_budget`'s keys (by default `budget.DEFAULT_BUDGET`, 4 plant events per sample) are fixed
keys like `fix`'s (budget.events_per_sample: 4), set in every case and in the sweep files and
scenario a tuning writes; the wall-clock limit stays, a safety net the budget keeps cases far from.
"""

from __future__ import annotations

import copy
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toggle_cosim.cosim.execution.budget import DEFAULT_BUDGET
from toggle_cosim.experiments.scenario import SCHEMA as SCENARIO_SCHEMA
from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document
from toggle_cosim.experiments.sweep_spec import (
    Case,
    Sweep,
    SweepError,
    case_id,
    check_axis_key,
    checked_document,
    get_key,
    load_sweep,
    set_key,
)


class TuneError(Exception):
    """A tuning that cannot run; str() is the one-line message for the user."""


@dataclass(frozen=True)
class Metric:
    """A figure of merit an objective can use: its column in a sweep table, unit and meaning."""

    column: str
    unit: str
    meaning: str
    absolute: bool = False  # the magnitude counts (final error)


# The objectives' metrics, by the name a tuning file uses; each is a column of the sweep table.
METRICS: dict[str, Metric] = {
    "settling_time": Metric("settling_time_s", "s", "settling time (2 % band); a case that never settles counts t_end"),
    "final_error": Metric("final_error_m", "m", "|x_B* - x_B| at t_end", absolute=True),
    "overshoot": Metric("overshoot_percent", "%", "overshoot past the target, % of the stroke"),
    "peak_command": Metric("peak_iq_ref_A", "A", "peak |i_q*|"),
    "input_energy": Metric("E_in_J", "J", "work of the thrust at t_end"),
    "chattering": Metric("iq_total_variation_A_per_s", "A/s", "total variation of i_q* per second"),
    "S_sign_changes": Metric("S_sign_changes_per_s", "1/s", "sign changes of S per second in the sliding phase"),
}
AGGREGATES = ("worst", "mean")
SAMPLERS = ("tpe", "cmaes", "random")

_NUMBER = {"type": "number"}
_OBJECTIVE = {
    "type": "object",
    "additionalProperties": False,
    "required": ["metric"],
    "properties": {"metric": {"type": "string"}, "over": {"type": "string"}},
}
SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "required": ["sweep", "parameters", "objective"],
    "properties": {
        "name": {"type": "string", "pattern": r"^[A-Za-z0-9_][A-Za-z0-9_.-]*\Z"},
        "description": {"type": "string"},
        "sweep": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z"},
        "fix": {
            "type": "object",
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_.\[\]]*\Z"},
            "additionalProperties": {"type": ["number", "string", "boolean"]},
        },
        "parameters": {
            "type": "object",
            "minProperties": 1,
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_.\[\]]*\Z"},
            "additionalProperties": {
                "type": "object",
                "additionalProperties": False,
                "required": ["low", "high"],
                "properties": {"low": _NUMBER, "high": _NUMBER, "log": {"type": "boolean"}},
            },
        },
        "objective": {"anyOf": [_OBJECTIVE, {"type": "array", "minItems": 1, "maxItems": 2, "items": _OBJECTIVE}]},
        "constraints": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "settles": {"type": "boolean"},
                "final_error_below": {"type": "number", "exclusiveMinimum": 0},
                "rated_current": {"type": "boolean"},
                "working_range": {"type": "boolean"},
            },
        },
        "optimiser": {
            "type": "object",
            "additionalProperties": False,
            "properties": {
                "sampler": {"type": "string"},
                "trials": {"type": "integer", "minimum": 1, "maximum": 100_000},
                "batch": {"type": "integer", "minimum": 1, "maximum": 1000},
                "seed": {"type": "integer", "minimum": 0},
            },
        },
        "case_budget": {"anyOf": [SCENARIO_SCHEMA["properties"]["budget"], {"const": "none"}]},
        "output": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z"},
    },
}


@dataclass(frozen=True)
class Parameter:
    """A tuned scenario key, its bounds and its value in the map's cases (None: not set there)."""

    key: str
    low: float
    high: float
    log: bool
    start: float | None


@dataclass(frozen=True)
class Objective:
    """`over` ("worst" or "mean") of `metric` (a name of METRICS) over the map's cases; minimised."""

    metric: str
    over: str

    @property
    def label(self) -> str:
        return f"{self.over}_{self.metric}"


@dataclass(frozen=True)
class Constraints:
    """What every case of a feasible trial meets (a failed case makes the trial infeasible too)."""

    settles: bool = False
    final_error_below: float | None = None  # m
    rated_current: bool = False
    working_range: bool = False


@dataclass(frozen=True)
class Tuning:
    """A loaded tuning file: the map (its cases after `fix`), what is tuned and how."""

    path: Path
    name: str
    description: str
    sweep: Sweep
    fixed: dict[str, Any]
    cases: list[Case]
    rated_currents: list[float]  # each case's plant.rated_current, A
    parameters: list[Parameter]
    objectives: list[Objective]
    constraints: Constraints
    sampler: str
    trials: int
    batch: int
    seed: int
    output: Path

    def values(self, point: dict[str, float]) -> dict[str, Any]:
        """The scenario keys a trial sets: the fixed keys that are not axes, then the tuned ones."""
        return {**{k: v for k, v in self.fixed.items() if k not in self.sweep.axes}, **point}

    def trial_cases(self, point: dict[str, float]) -> list[Case]:
        """The map's cases with the tuned keys at `point` (key -> value): plain sweep cases, each with
        its own case_id, run by the sweep engine."""
        cases = []
        for case in self.cases:
            document = copy.deepcopy(case.document)
            for key, value in point.items():
                set_key(document, key, value)
            cases.append(
                Case(
                    index=case.index,
                    case_id=case_id(document, case.variant),
                    variant=case.variant,
                    values=case.values,
                    document=document,
                    parameters=case.parameters,
                    source=case.source,
                )
            )
        return cases


def load_tuning(path: Path, output: Path | None = None) -> Tuning:
    """Read and validate a tuning file, its sweep and every case. Raises TuneError('FILE: problem')."""
    path = Path(path)
    try:
        return _load_tuning(path, output)
    except (TuneError, SweepError) as error:
        message = " ".join(str(error).split())
        raise TuneError(message if message.startswith(f"{path}:") else f"{path}: {message}") from None


def _load_tuning(path: Path, output: Path | None) -> Tuning:
    document = checked_document(
        path,
        "tuning file",
        SCHEMA,
        TuneError,
        "a tuning needs sweep:, parameters: and objective:",
        "sweep, parameters, objective, constraints, ...",
    )
    folder = path.parent
    sweep_path = Path(os.path.normpath(folder / document["sweep"]))
    try:
        sweep = load_sweep(sweep_path)
    except SweepError as error:
        raise TuneError(f"key sweep: {error}") from None
    fixed = {**_budget_keys(document.get("case_budget", DEFAULT_BUDGET)), **(document.get("fix") or {})}
    cases = _fixed_cases(sweep, fixed)
    parameters = [_parameter(key, spec, fixed, sweep, cases) for key, spec in document["parameters"].items()]
    objectives = _objectives(document["objective"])
    constraints = Constraints(**(document.get("constraints") or {}))
    optimiser = document.get("optimiser") or {}
    sampler = optimiser.get("sampler", "tpe")
    if sampler not in SAMPLERS:
        raise TuneError(f"key optimiser.sampler: {sampler!r} is not a sampler (choose one of {', '.join(SAMPLERS)})")
    if sampler == "cmaes" and len(objectives) > 1:
        raise TuneError("key optimiser.sampler: cmaes minimises one objective; with two use tpe or random")
    if sampler == "cmaes" and len(parameters) < 2:
        raise TuneError("key optimiser.sampler: cmaes needs at least two tuned parameters; with one use tpe")
    rated = []
    for case in cases:
        (run,) = runs_from_document(copy.deepcopy(case.document), sweep.base)
        rated.append(run.plant.rated_current)
    name = document.get("name", path.stem)
    if output is None:
        output = folder / document["output"] if "output" in document else Path("out") / "tune" / name
    return Tuning(
        path=path,
        name=name,
        description=document.get("description", ""),
        sweep=sweep,
        fixed=fixed,
        cases=cases,
        rated_currents=rated,
        parameters=parameters,
        objectives=objectives,
        constraints=constraints,
        sampler=sampler,
        trials=int(optimiser.get("trials", 50)),
        batch=int(optimiser.get("batch", 4)),
        seed=int(optimiser.get("seed", 0)),
        output=Path(os.path.normpath(output)),
    )


def _budget_keys(given: dict[str, float] | str) -> dict[str, float]:
    """The fixed keys of a tuning's `case_budget` (the scenario key budget's): none for "none"."""
    return {} if given == "none" else {f"budget.{key}": value for key, value in given.items()}


def _fixed_cases(sweep: Sweep, fixed: dict[str, Any]) -> list[Case]:
    """The sweep's cases with `fix` applied: an axis keeps the cases at its value; any other
    scenario key is set in every case (and checked as the sweep checks its cases)."""
    cases = list(sweep.cases)
    for key, value in fixed.items():
        if key in sweep.axes and sweep.mode == "zip":
            raise TuneError(
                f"key fix.{key}: an axis of a zip sweep (its values pair with the others'); write a sweep without it"
            )
        if key in sweep.axes:
            kept = [case for case in cases if case.values[key] == value]
            if not kept:
                have = ", ".join(map(repr, sweep.axes[key]))
                raise TuneError(f"key fix.{key}: {value!r} is not a value of that axis of the sweep (it has: {have})")
            cases = kept
        else:
            check_axis_key(key, "key fix.")
    others = {k: v for k, v in fixed.items() if k not in sweep.axes}
    if not others:
        return cases
    changed = []
    for case in cases:
        document = copy.deepcopy(case.document)
        for key, value in others.items():
            set_key(document, key, value)
        try:
            (run,) = runs_from_document(copy.deepcopy(document), sweep.base)
        except ScenarioError as error:
            raise TuneError(f"key fix: case {case.index}: {error}") from None
        parameters = {**case.parameters, "T_s": run.T_s, "t_end": run.t_end, "plant.mu": run.plant.mu}
        changed.append(
            Case(
                case.index,
                case_id(document, case.variant),
                case.variant,
                case.values,
                document,
                parameters,
                case.source,
            )
        )
    return changed


def _parameter(key: str, spec: dict[str, Any], fixed: dict[str, Any], sweep: Sweep, cases: list[Case]) -> Parameter:
    check_axis_key(key, "key parameters.")
    if key in sweep.axes:
        raise TuneError(f"key parameters.{key}: an axis of the sweep (the map); tune another key or fix: the axis")
    if key in fixed:
        raise TuneError(f"key parameters.{key}: also under fix: (tune it or fix it, not both)")
    low, high, log = float(spec["low"]), float(spec["high"]), bool(spec.get("log", False))
    if not (math.isfinite(low) and math.isfinite(high)):
        raise TuneError(f"key parameters.{key}: the bounds must be finite numbers")
    if not low < high:
        raise TuneError(f"key parameters.{key}: low {low:g} is not below high {high:g} (write low < high)")
    if log and low <= 0:
        raise TuneError(f"key parameters.{key}: log: true needs low > 0 (it is {low:g})")
    for bound in (low, high):  # both bounds must be values the scenario accepts for this key
        document = copy.deepcopy(cases[0].document)
        set_key(document, key, bound)
        try:
            runs_from_document(document, sweep.base)
        except ScenarioError as error:
            raise TuneError(f"key parameters.{key}: the bound {bound:g} is not a valid value: {error}") from None
    start = get_key(cases[0].document, key)
    start = float(start) if isinstance(start, (int, float)) and not isinstance(start, bool) else None
    return Parameter(key, low, high, log, start)


def _objectives(given: Any) -> list[Objective]:
    objectives = []
    for item in given if isinstance(given, list) else [given]:
        metric, over = item["metric"], item.get("over", "worst")
        if metric not in METRICS:
            raise TuneError(f"key objective.metric: unknown metric {metric!r} (choose one of {', '.join(METRICS)})")
        if over not in AGGREGATES:
            raise TuneError(f"key objective.over: {over!r} is not allowed (choose one of {', '.join(AGGREGATES)})")
        objectives.append(Objective(metric, over))
    if len({o.label for o in objectives}) < len(objectives):
        raise TuneError("key objective: the two objectives are the same (give two different ones)")
    return objectives
