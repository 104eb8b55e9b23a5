"""Invariants of a reference: figures of merit of a run held within a tolerance, beside the funnel.

A sliding-mode trace need not be reproducible sample for sample across CPUs (a sign of S can flip
a sample earlier), while its chattering and its reaching are: the file
`<name>_ref_invariants.yaml` beside a reference `<name>_ref.csv` holds them::

    invariants:
      iq_total_variation_A_per_s: {value: 3.1688, rtol: 0.02}
      S_sign_changes_per_s: {value: 2.05, atol: 1.5}
      reaching_time_s: {value: 0.03525, atol: 0.002}

Each metric is one of `cosim.summary.VscMetrics`' (computed from the result's trace columns
time, iq_ref, S, phase by `vsc_metrics`, their one definition); it passes when
|measured − value| <= max(atol, rtol |value|) (atol and rtol default to 0). A metric the result
does not have (no S column) fails. `toggle-cosim compare` and `references` check the file when
it is there; `references --update` re-measures the values and keeps the tolerances, the
comments and the layout, writing a value that moved at its tolerance's precision.

The metrics depend on the sampling: the command's total variation and S's sign changes over
every 10th sample are not those over every sample. The stored values are measured on the run's
full trace, one sample every T_s (the reference's `.opt` StepSize), so an invariant is checked
only on a trace sampled every T_s (`sampled_every`): a stored reference (decimated), or a trace
thinned by record_every, leaves it unchecked, with the reason, and neither passes nor fails it.
Without an options file the sampling is unknown and the invariants are checked on any trace.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import yaml

from toggle_cosim.analysis.csv_traces import CompareInputError
from toggle_cosim.cosim.summary import VscMetrics, vsc_metrics
from toggle_cosim.files.outputs import INVARIANTS, write_text
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import schema_text

__all__ = [
    "METRICS",
    "Invariant",
    "InvariantResult",
    "check_invariants",
    "invariants_path",
    "load_invariants",
    "sampled_every",
    "stored_text",
    "trace_metrics",
    "update_invariants",
    "updated_text",
]

METRICS = tuple(f.name for f in fields(VscMetrics))
_ENTRY = {
    "type": "object",
    "additionalProperties": False,
    "required": ["value"],
    "properties": {
        "value": {"type": "number"},
        "atol": {"type": "number", "minimum": 0},
        "rtol": {"type": "number", "minimum": 0},
    },
}
SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "required": ["invariants"],
    "properties": {
        "invariants": {
            "type": "object",
            "minProperties": 1,
            "propertyNames": {"enum": list(METRICS)},
            "additionalProperties": _ENTRY,
        }
    },
}
_FIX = f"write invariants: {{metric: {{value:, atol:, rtol:}}}} with metrics from {', '.join(METRICS)}"


@dataclass(frozen=True)
class Invariant:
    """A metric's stored value and its tolerance: passes within max(atol, rtol |value|)."""

    name: str
    value: float
    atol: float = 0.0
    rtol: float = 0.0

    @property
    def tolerance(self) -> float:
        return max(self.atol, self.rtol * abs(self.value))


@dataclass(frozen=True)
class InvariantResult:
    """An invariant against a trace: its measured value, or why it was not checked (`unchecked`:
    the trace is not sampled as the stored value was; such a result neither passes nor fails)."""

    invariant: Invariant
    measured: float | None  # None: the result has no such metric
    unchecked: str | None = None

    @property
    def passed(self) -> bool:
        if self.unchecked is not None:
            return True  # nothing measured: no verdict against the check
        if self.measured is None or not math.isfinite(self.measured):
            return False
        return abs(self.measured - self.invariant.value) <= self.invariant.tolerance

    @property
    def line(self) -> str:
        i = self.invariant
        if self.unchecked is not None:
            return f"{i.name}: not checked ({self.unchecked})"
        measured = "absent" if self.measured is None else f"{self.measured:.6g}"
        return f"{i.name} = {measured} (stored {i.value:.6g} ± {i.tolerance:.3g}): {'pass' if self.passed else 'FAIL'}"


def invariants_path(reference_csv: Path | str) -> Path:
    """`<name>_ref_invariants.yaml` beside `<name>_ref.csv`."""
    path = Path(reference_csv)
    return path.with_name(f"{path.stem}_invariants.yaml")


def load_invariants(path: Path | str) -> dict[str, Invariant]:
    """The invariants of a file; {} when there is no file there. CompareInputError (one line) for a bad one."""
    import jsonschema

    from toggle_cosim.files.yaml_loader import YamlError, load_yaml

    path = Path(path)
    if not path.is_file():
        if path.exists() or path.is_symlink():
            raise CompareInputError(f"{path}: is not a regular file; {_FIX}")
        return {}
    try:
        document = load_yaml(path, "invariants file")
    except YamlError as error:
        raise CompareInputError(f"{error} (it is not valid YAML for an invariants file); fix the syntax") from error
    error = jsonschema.exceptions.best_match(jsonschema.Draft202012Validator(SCHEMA).iter_errors(document))
    if error is not None:
        key = ".".join(str(part) for part in error.absolute_path) or "(top level)"
        raise CompareInputError(f"{path}: key {key!r}: {schema_text(error.message, error.instance)}; {_FIX}")
    return {name: Invariant(name, **entry) for name, entry in document["invariants"].items()}


def trace_metrics(trace: Trace) -> dict[str, float | None]:
    """The invariant metrics of a trace, from its columns time, iq_ref and (if present) S and phase."""
    diagnostics = [trace.column(name) if name in trace.names else None for name in ("S", "phase")]
    return vsc_metrics(trace.time, trace.column("iq_ref"), *diagnostics).as_dict()


def sampled_every(time: np.ndarray, step: float) -> bool:
    """Whether `time` is a sample every `step` s from its first (to 1e-6 of a step: a time
    written with 17 digits reads back within far less), as the stored invariants are measured."""
    if time.size < 2 or not step > 0:
        return False
    return bool(np.all(np.abs(np.diff(time) - step) <= 1e-6 * step))


def check_invariants(
    trace: Trace, invariants: Mapping[str, Invariant], step: float | None = None
) -> tuple[InvariantResult, ...]:
    """Each invariant against the trace's metrics. `step`: the sampling the stored values were
    measured at (the run's T_s, a reference's StepSize); a trace not sampled every `step` leaves
    them unchecked, with the reason (module docstring). None: checked at any sampling."""
    if invariants and step is not None and not sampled_every(trace.time, step):
        time = trace.time
        spacing = f"{float(np.median(np.diff(time))):.6g} s" if time.size > 1 else "no interval"
        why = (
            f"the values are measured at every sample, T_s = {step:.6g} s; this trace's samples are {spacing} apart: "
            "compare the run's own trace.csv written without record_every"
        )
        return tuple(InvariantResult(invariant, None, why) for invariant in invariants.values())
    measured = trace_metrics(trace) if invariants else {}
    return tuple(InvariantResult(invariant, measured[name]) for name, invariant in invariants.items())


def stored_text(value: float, tolerance: float) -> str:
    """`value` as the invariants file writes it: at the precision of its tolerance, the fewest
    decimals that round it by less than tolerance/10 (all of its digits without a tolerance)."""
    if tolerance <= 0 or not math.isfinite(tolerance):
        return repr(float(value))
    decimals = max(0, math.ceil(-math.log10(tolerance / 20)))
    return f"{value:.{decimals}f}"


def _value_spans(text: str) -> dict[str, tuple[int, int]]:
    """{metric: (start, end)} of each metric's `value:` scalar in the file's text (PyYAML's node
    marks), so that only those characters change and the comments, order and layout stay."""
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    spans: dict[str, tuple[int, int]] = {}
    for key, entries in root.value:
        if key.value != "invariants":
            continue
        for metric, entry in entries.value:
            for field, scalar in entry.value:
                if field.value == "value":
                    spans[metric.value] = (scalar.start_mark.index, scalar.end_mark.index)
    return spans


def updated_text(text: str, invariants: Mapping[str, Invariant], measured: Mapping[str, float]) -> str:
    """The invariants file's `text` with each metric's value re-measured: a value the
    measurement moved by less than a tenth of its tolerance keeps its text, another is written at
    its tolerance's precision (`stored_text`); nothing else in the text changes. Pure."""
    spans = _value_spans(text)
    for name, (start, end) in sorted(spans.items(), key=lambda item: item[1], reverse=True):
        invariant, value = invariants[name], float(measured[name])
        tolerance = max(invariant.atol, invariant.rtol * abs(value))
        if abs(value - invariant.value) < tolerance / 10:
            continue
        text = text[:start] + stored_text(value, tolerance) + text[end:]
    return text


def update_invariants(path: Path, trace: Trace) -> Path | None:
    """Re-measure the values of an existing invariants file from `trace`, keeping its metrics,
    tolerances, comments and layout (`references --update`; `updated_text`); the file is left
    as it is when no value moved. None when there is no file."""
    from toggle_cosim.files.bounded import YAML_LIMIT, read_text_bounded

    invariants = load_invariants(path)
    if not invariants:
        return None
    measured = trace_metrics(trace)
    for name in invariants:
        if measured[name] is None:
            raise CompareInputError(f"{path}: the run has no {name} (no S column?); remove the entry")
    text = read_text_bounded(path, YAML_LIMIT, "invariants file")
    updated = updated_text(text, invariants, {name: float(measured[name]) for name in invariants})
    if updated == text:
        return path
    return write_text(path, updated, "invariants", kind=INVARIANTS)
