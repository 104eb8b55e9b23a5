"""The default experiment of a model, from its Modelica `experiment` annotation (Modelica
Language Specification, sec. 18.4: StartTime, StopTime, Tolerance, Interval), for the
modelDescription's <DefaultExperiment> (FMI: startTime, stopTime, tolerance, stepSize).

Nothing model-specific lives here: a model without the annotation gets no stop time, and
the tolerance defaults to the shell's own solver.relTol (shell_settings.py).
"""

from __future__ import annotations

from dataclasses import dataclass

from modelica.ir import nodes as ir

# Modelica annotation entry -> FMI DefaultExperiment attribute
_ATTRIBUTES = {"StartTime": "startTime", "StopTime": "stopTime", "Tolerance": "tolerance", "Interval": "stepSize"}


class ExperimentError(ValueError):
    """The experiment annotation holds something other than a number."""


@dataclass(frozen=True)
class Experiment:
    start_time: float | None = None
    stop_time: float | None = None
    tolerance: float | None = None
    step_size: float | None = None

    def attributes(self, default_tolerance: float) -> dict[str, str]:
        """The <DefaultExperiment> attributes: the annotated ones, the tolerance always."""
        values = {
            "startTime": self.start_time,
            "stopTime": self.stop_time,
            "tolerance": self.tolerance if self.tolerance is not None else default_tolerance,
            "stepSize": self.step_size,
        }
        return {name: repr(float(value)) for name, value in values.items() if value is not None}


def _number(node: object, model: str, entry: str) -> float:
    if isinstance(node, (ir.RealLiteral, ir.IntLiteral)):
        return float(node.value)
    raise ExperimentError(f"{model}: experiment({entry} = ...) must be a plain number (found {type(node).__name__})")


def experiment_of(model_class: ir.Class | None, model: str) -> Experiment:
    """The experiment annotation of `model_class` (an empty Experiment if it has none)."""
    annotation = getattr(model_class, "annotation", None)
    entries = getattr(annotation, "entries", None) or {}
    modification = entries.get("experiment")
    if modification is None:
        return Experiment()
    values: dict[str, float] = {}
    for entry, value in (modification.entries or {}).items():
        if entry in _ATTRIBUTES and value.value is not None:
            values[_ATTRIBUTES[entry]] = _number(value.value, model, entry)
    return Experiment(
        start_time=values.get("startTime"),
        stop_time=values.get("stopTime"),
        tolerance=values.get("tolerance"),
        step_size=values.get("stepSize"),
    )
