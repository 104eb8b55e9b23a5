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
it is there; `references --update` re-measures the values and keeps the tolerances.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path

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
    "trace_metrics",
    "update_invariants",
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
    invariant: Invariant
    measured: float | None  # None: the result has no such metric

    @property
    def passed(self) -> bool:
        if self.measured is None or not math.isfinite(self.measured):
            return False
        return abs(self.measured - self.invariant.value) <= self.invariant.tolerance

    @property
    def line(self) -> str:
        i = self.invariant
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


def check_invariants(trace: Trace, invariants: Mapping[str, Invariant]) -> tuple[InvariantResult, ...]:
    measured = trace_metrics(trace) if invariants else {}
    return tuple(InvariantResult(invariant, measured[name]) for name, invariant in invariants.items())


def update_invariants(path: Path, trace: Trace) -> Path | None:
    """Re-measure the values of an existing invariants file from `trace`, keeping its metrics and
    tolerances (`references --update`); None when there is no file."""
    invariants = load_invariants(path)
    if not invariants:
        return None
    measured = trace_metrics(trace)
    document = {"invariants": {}}
    for name, invariant in invariants.items():
        if measured[name] is None:
            raise CompareInputError(f"{path}: the run has no {name} (no S column?); remove the entry")
        entry = {"value": float(measured[name])}
        entry.update({k: getattr(invariant, k) for k in ("atol", "rtol") if getattr(invariant, k)})
        document["invariants"][name] = entry
    return write_text(path, yaml.safe_dump(document, sort_keys=False), "invariants", kind=INVARIANTS)
