"""A signal as a scenario writes it, and the JSON Schema of that, generated from the signal
dataclasses (`definitions`): a kind's keys are its fields, their bounds the fields' metadata.

    F_E: 100.0                                                     # a constant, as always
    F_E: {kind: step, start_time: 0.75, height: 100.0}             # offset 0 before
    F_E: {kind: ramp, start_time: 0.5, duration: 0.25, height: 80.0}
    F_E: {kind: pulse, period: 0.4, width: 0.1, amplitude: 50.0, start_time: 0.2, count: 3}
    F_E: {kind: sine, amplitude: 20.0, frequency: 2.0, offset: 50.0}
    F_E: {kind: points, points: [[0, 0], [0.8, 0], [1.0, 120], [1.5, 120]]}   # linear between
    F_E: {kind: table, file: load.csv, interpolation: hold}        # column: NAME, if not F_E

`signal_from_document` turns such a value into a `Signal`; a CSV file is read relative to the
scenario's folder (`tables.read_table`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING
from pathlib import Path
from typing import Any

from toggle_cosim.signals.definitions import (
    INTERPOLATIONS,
    PROFILES,
    TIME_BOUND,
    VALUE_BOUND,
    Signal,
    Table,
    parameters,
)
from toggle_cosim.signals.tables import read_table

TABLE_KINDS = ("points", "table")
KINDS = (*PROFILES, *TABLE_KINDS)
MAX_POINTS = 10_000  # rows of an inline `points` list (a longer table belongs in a CSV file)

_TABLE_KEYS: dict[str, dict[str, Any]] = {
    "points": {
        "points": {
            "type": "array",
            "minItems": 2,
            "maxItems": MAX_POINTS,
            "items": {
                "type": "array",
                "minItems": 2,
                "maxItems": 2,
                "items": {"type": "number", "minimum": -VALUE_BOUND, "maximum": VALUE_BOUND},
            },
            "description": "[[time s, value], ...], times increasing",
        },
        "interpolation": {"enum": list(INTERPOLATIONS), "description": "linear (default) or hold"},
    },
    "table": {
        "file": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z", "description": "a CSV file"},
        "interpolation": {"enum": list(INTERPOLATIONS), "description": "hold or linear between rows"},
        "column": {"type": "string", "minLength": 1, "description": "the value column (default: the input's name)"},
    },
}
_TABLE_REQUIRED = {"points": ["points"], "table": ["file", "interpolation"]}


def _field_schema(f: Any) -> dict[str, Any]:
    kind = "integer" if f.name == "count" else "number"
    return {"type": kind, **f.metadata}


def _kind_schema(kind: str) -> dict[str, Any]:
    if kind in PROFILES:
        fields = parameters(PROFILES[kind])
        keys = {f.name: _field_schema(f) for f in fields}
        required = [f.name for f in fields if f.default is MISSING]
    else:
        keys, required = _TABLE_KEYS[kind], _TABLE_REQUIRED[kind]
    return {
        "if": {"properties": {"kind": {"const": kind}}, "required": ["kind"]},
        "then": {
            "additionalProperties": False,
            "required": required,
            "properties": {"kind": {"const": kind}, **keys},
        },
    }


SCHEMA_KEYS: dict[str, tuple[str, ...]] = {
    kind: tuple(key for key in _kind_schema(kind)["then"]["properties"] if key != "kind") for kind in KINDS
}  # each kind's keys, as the schema has them (docs/scenarios.md lists them)


def signal_schema(minimum: float, maximum: float, description: str) -> dict[str, Any]:
    """The schema of an input's value in a scenario: a number in [minimum, maximum] (a constant),
    or a mapping with a `kind` and that kind's keys."""
    return {
        "type": ["number", "object"],
        "minimum": minimum,
        "maximum": maximum,
        "description": f"{description}: a number, or a signal (kind: {', '.join(KINDS)}; docs/scenarios.md)",
        "if": {"type": "object"},
        "then": {
            "required": ["kind"],
            "properties": {"kind": {"enum": list(KINDS)}},
            "allOf": [_kind_schema(kind) for kind in KINDS],
        },
    }


def signal_keys(schema: Mapping[str, Any]) -> dict[str, Any]:
    """Every key a signal mapping may hold under `schema` (a signal_schema), with its schema: for
    a sweep axis that names a signal's parameter (plant.F_E.start_time)."""
    keys: dict[str, Any] = {}
    for branch in schema.get("then", {}).get("allOf", ()):
        keys.update(branch["then"]["properties"])
    return keys


def signal_from_document(value: Any, input_name: str, folder: Path | None) -> float | Signal:
    """The input's value from its (schema-checked) scenario value: a number stays a float (a
    constant, today's runs unchanged), a mapping becomes its Signal. Raises SignalError."""
    if not isinstance(value, Mapping):
        return float(value)
    kind = value["kind"]
    if kind in PROFILES:
        cls = PROFILES[kind]
        given = {f.name: value[f.name] for f in parameters(cls) if f.name in value}
        return cls(**{k: v if k == "count" else float(v) for k, v in given.items()})
    if kind == "points":
        rows = value["points"]
        return Table(
            tuple(float(t) for t, _ in rows), tuple(float(v) for _, v in rows), value.get("interpolation", "linear")
        )
    path = Path(value["file"])
    if folder is not None and not path.is_absolute():
        path = folder / path
    return read_table(path, value["interpolation"], input_name, value.get("column"), shown=str(path))


__all__ = ["KINDS", "SCHEMA_KEYS", "TIME_BOUND", "signal_from_document", "signal_keys", "signal_schema"]
