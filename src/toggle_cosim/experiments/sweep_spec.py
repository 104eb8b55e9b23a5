"""The sweep file: its schema, loading and validation, and the expansion into cases.

    name: sweep_FE_mB                      # optional, default: the file's stem
    description: F_E by m_B, with and without friction
    base: fig4_nominal.yaml                # a scenario file, relative to this file
    variant: [friction, no_friction]       # optional filter on the base's variants (a name or a list)
    fmu: ../fmus/ToggleLSM.fmu             # optional, relative to this file; else the base's fmu:
    mode: grid                             # grid (cartesian product, default) or zip
    axes:                                  # dotted scenario keys -> values
      plant.F_E: {linspace: [0, 150, 16]}
      plant.m_B: {values: [4.43, 6.645, 8.86]}
      controller.gains.beta: {random: {low: 40, high: 90, n: 5, seed: 1}}
      plant.parameters.mechanism.r3: {values: [0.27, 0.28]}   # after plant.parameters. the rest is one FMU name
      # plant.F_E.start_time: {values: [0.2, 0.3]}             # a key of the base's signal (plant.F_E: {kind: step, ...})
    output: ../out/sweeps/sweep_FE_mB      # relative to this file; default out/sweeps/<name>
    heatmap: {x: plant.F_E, y: plant.m_B}  # optional, default: the first two axes

Cases are the base's variants (all, or those `variant:` names) times the axis combinations
(grid: every combination, first axis outermost; zip: the i-th value of every axis together).
Every case document is the base scenario with the variant and the case's values applied, and is
valid before anything runs: one bad case is bad input, refused with the message of the first bad
case. The scenario loader's checks are made per axis value, not per case: the axes fall into
groups whose keys the checks read together (`check_group`: the sampling and every input signal,
the stroke, the controller, the rest of the plant; a key of its own otherwise), and each
combination of one group's values is checked once, as the variant's document with those values
set. No check reads keys of two groups, so a case is valid when each of its groups' combinations
is; a 400 × 250 grid is 650 checks, not 100,000.

Each case has a stable id, a hash of its resolved scenario document (the base's content, the
variant and the case's values), so a re-run finds the cases already done and skips them.

`--out` (the command line) overrides `output:`; without either the output is
`out/sweeps/<name>` under the current folder.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toggle_cosim.cosim.summary import RunSummary
from toggle_cosim.experiments.scenario import SCHEMA as SCENARIO_SCHEMA
from toggle_cosim.experiments.scenario import ScenarioError, load_scenario, merge_documents, runs_from_document
from toggle_cosim.messages import schema_text, value_text
from toggle_cosim.signals.schema import signal_keys

STANDARD_PARAMETERS = ("plant.F_E", "plant.m_B", "plant.mu", "T_s", "t_end")
METRICS = (*RunSummary.__dataclass_fields__, "fric_share_end")

_NUMBER = {"type": "number"}
_SCALAR = {"type": ["number", "string", "boolean"]}
_AXIS = {
    "type": "object",
    "minProperties": 1,
    "maxProperties": 1,
    "additionalProperties": False,
    "properties": {
        "values": {"type": "array", "minItems": 1, "items": _SCALAR},
        "linspace": {
            "type": "array",
            "minItems": 3,
            "maxItems": 3,
            "prefixItems": [_NUMBER, _NUMBER, {"type": "integer", "minimum": 1, "maximum": 100_000}],
        },
        "random": {
            "type": "object",
            "additionalProperties": False,
            "required": ["low", "high", "n", "seed"],
            "properties": {
                "low": _NUMBER,
                "high": _NUMBER,
                "n": {"type": "integer", "minimum": 1, "maximum": 100_000},
                "seed": {"type": "integer", "minimum": 0},
            },
        },
    },
}
SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "additionalProperties": False,
    "required": ["base", "axes"],
    "properties": {
        "name": {"type": "string", "pattern": r"^[A-Za-z0-9_][A-Za-z0-9_.-]*\Z"},
        "description": {"type": "string"},
        "base": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z"},
        "variant": {"anyOf": [{"type": "string"}, {"type": "array", "minItems": 1, "items": {"type": "string"}}]},
        "fmu": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z"},
        "mode": {"enum": ["grid", "zip"]},
        "axes": {
            "type": "object",
            "minProperties": 1,
            "propertyNames": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_.\[\]]*\Z"},
            "additionalProperties": _AXIS,
        },
        "output": {"type": "string", "minLength": 1, "pattern": r"^[^\x00]*\Z"},
        "heatmap": {
            "type": "object",
            "additionalProperties": False,
            "required": ["x", "y"],
            "properties": {"x": {"type": "string"}, "y": {"type": "string"}},
        },
    },
}
MAX_CASES = 1_000_000
_IGNORED_IN_ID = ("name", "description", "fmu", "variants")  # do not change what a case computes


class SweepError(Exception):
    """A sweep that cannot run; str() is the one-line message for the user."""


# -- the sweep file ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One co-simulation of the sweep: plain, picklable data."""

    index: int
    case_id: str
    variant: str | None
    values: dict[str, Any]  # axis key -> value
    document: dict[str, Any]  # the validated scenario document (no variants, no fmu)
    parameters: dict[str, Any]  # table columns: standard parameters and axis values
    source: str | None = None  # the base scenario file (controller.python is imported from its folder)

    def payload(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "case_id": self.case_id,
            "variant": self.variant,
            "document": self.document,
            "parameters": self.parameters,
            # absolute: a worker (a Dask worker in another folder) finds the base scenario's
            # folder, and the controller.python module and controller.fmu beside it, as we do
            "source": None if self.source is None else os.path.abspath(self.source),
        }


@dataclass(frozen=True)
class Sweep:
    path: Path
    name: str
    description: str
    base: Path
    fmu: Path | None
    mode: str
    axes: dict[str, list[Any]]
    variants: list[str | None]
    output: Path
    heatmap: tuple[str, str] | None
    cases: list[Case]
    parameter_columns: list[str]
    parameter_types: dict[str, str]  # column -> "float" | "bool" | "string"


def split_key(key: str) -> list[str]:
    """A dotted axis key as a path into the scenario document. After `plant.parameters.` the rest
    is one FMU variable name (those contain dots: mechanism.r3)."""
    parts = key.split(".")
    if parts[:2] == ["plant", "parameters"] and len(parts) > 2:
        return ["plant", "parameters", ".".join(parts[2:])]
    return parts


def check_axis_key(key: str, what: str = "axis ") -> None:
    """Refuse keys the scenario schema does not have (and keys that do not hold one value);
    `what` names the key in the message ("axis ", or a tuning file's "key parameters.")."""
    path = split_key(key)
    if path[0] in ("name", "description", "fmu", "variants"):
        raise SweepError(f"{what}{key}: {path[0]} cannot be swept (sweep a physical or numerical key)")
    schema: Mapping[str, Any] = SCENARIO_SCHEMA
    for depth, part in enumerate(path):
        properties = schema.get("properties", {}) or signal_keys(schema)  # a signal's: plant.F_E.start_time
        if part in properties:
            schema = properties[part]
        elif "additionalProperties" in schema and isinstance(schema["additionalProperties"], Mapping):
            schema = schema["additionalProperties"]
        else:
            where = ".".join(path[:depth]) or "(top level)"
            allowed = ", ".join(sorted(properties)) or "none"
            raise SweepError(f"{what}{key}: unknown scenario key {part!r} under {where} (allowed there: {allowed})")
    if schema.get("type") == "object" or "properties" in schema:
        raise SweepError(f"{what}{key}: a group of keys, not one value (name one key inside it, e.g. {key}.<key>)")


def set_key(document: dict[str, Any], key: str, value: Any) -> None:
    """Set the dotted scenario key `key` (`split_key`) in `document`, making its groups as needed."""
    node = document
    path = split_key(key)
    for part in path[:-1]:
        child = node.get(part)
        if not isinstance(child, dict):
            child = {}
            node[part] = child
        node = child
    node[path[-1]] = value


def get_key(document: Mapping[str, Any], key: str) -> Any:
    """The value of the dotted scenario key `key` in `document`, None where it is not set."""
    node: Any = document
    for part in split_key(key):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def check_group(key: str) -> str:
    """The group of an axis key: keys that the scenario's checks (`scenario.validate_document`'s
    schema and `scenario._build_run`) read together share one. T_s, t_end and the plant's input
    signals (a table must cover t_end; a signal's keys are checked together) are "sampling"; the
    stroke's ends, the controller's keys and the plant's other keys are one group each."""
    path = split_key(key)
    if key in ("T_s", "t_end") or path[:2] in (["plant", "F_E"], ["plant", "inputs"]):
        return "sampling"
    return path[0] if path[0] in ("stroke", "controller", "plant") and len(path) > 1 else key


def with_values(document: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """`document` with the axis values set (as `set_key` sets them), sharing the subtrees no axis
    key passes through: the mappings along each key's path are copied, the rest is not. Neither
    the result nor `document` may be changed in place afterwards."""
    result = dict(document)
    for key, value in values.items():
        node = result
        path = split_key(key)
        for part in path[:-1]:
            child = node.get(part)
            child = dict(child) if isinstance(child, dict) else {}
            node[part] = child
            node = child
        node[path[-1]] = value
    return result


class _CaseIds:
    """case_id() of a variant's cases, fast: the canonical JSON of the variant's document is
    written once with a placeholder at each axis key, and a case's text is that with the case's
    values in place (the same text case_id hashes). Falls back to case_id where an axis key does
    not hold its placeholder in the text (a key under another axis key)."""

    def __init__(self, resolved: Mapping[str, Any], variant: str | None, keys: list[str]) -> None:
        self.variant, self.resolved = variant, resolved
        marks = {key: f"\x00axis{i}\x00" for i, key in enumerate(keys)}
        text = _id_text(with_values(resolved, marks), variant)
        quoted = {key: json.dumps(mark) for key, mark in marks.items()}
        where = sorted((text.find(q), key) for key, q in quoted.items())
        self.parts: list[str] | None = None
        if all(text.count(q) == 1 for q in quoted.values()):
            parts, at = [], 0
            for position, key in where:
                parts.append(text[at:position])
                at = position + len(quoted[key])
            parts.append(text[at:])
            self.parts, self.order = parts, [key for _, key in where]

    def __call__(self, values: Mapping[str, Any], document: Mapping[str, Any]) -> str:
        if self.parts is None:
            return case_id(document, self.variant)
        pieces = [self.parts[0]]
        for key, part in zip(self.order, self.parts[1:], strict=True):
            pieces.append(json.dumps(_canonical(values[key])))
            pieces.append(part)
        return hashlib.sha256("".join(pieces).encode("utf-8")).hexdigest()[:16]


def _axis_values(key: str, spec: Mapping[str, Any]) -> list[Any]:
    import numpy as np

    if "values" in spec:
        values = list(spec["values"])
    elif "linspace" in spec:
        start, stop, n = spec["linspace"]
        values = [float(v) for v in np.linspace(float(start), float(stop), int(n))]
    else:
        r = spec["random"]
        low, high = float(r["low"]), float(r["high"])
        if not low <= high:
            raise SweepError(f"axis {key}: random low {low} is above high {high}")
        values = [float(v) for v in np.random.default_rng(int(r["seed"])).uniform(low, high, int(r["n"]))]
    for value in values:
        if isinstance(value, float) and not math.isfinite(value):
            raise SweepError(f"axis {key}: {value!r} is not a finite number")
    return values


def _canonical(node: Any) -> Any:
    """JSON-ready copy with integers as floats, so 150 and 150.0 are the same case."""
    if isinstance(node, dict):
        return {str(k): _canonical(v) for k, v in node.items()}
    if isinstance(node, (list, tuple)):
        return [_canonical(v) for v in node]
    if isinstance(node, bool) or node is None or isinstance(node, str):
        return node
    import numpy as np

    if isinstance(node, (int, float, np.integer, np.floating)):
        return float(node)
    return str(node)


def case_id(document: Mapping[str, Any], variant: str | None) -> str:
    """Stable id of a case: a hash of what it computes (its resolved scenario document and variant)."""
    return hashlib.sha256(_id_text(document, variant).encode("utf-8")).hexdigest()[:16]


def _id_text(document: Mapping[str, Any], variant: str | None) -> str:
    """The text case_id hashes: the canonical JSON of the variant and the document's content."""
    content = {k: v for k, v in document.items() if k not in _IGNORED_IN_ID}
    return json.dumps({"variant": variant, "scenario": _canonical(content)}, sort_keys=True, separators=(",", ":"))


def schema_message(error: Any) -> str:  # a jsonschema.ValidationError
    key = ".".join(str(p) for p in error.absolute_path) or "(top level)"
    if error.validator == "additionalProperties":
        extra = sorted(set(error.instance) - set(error.schema.get("properties", {})))
        allowed = ", ".join(sorted(error.schema.get("properties", {}))) or "none"
        where = f"{key}." if error.absolute_path else ""
        return f"unknown key {where}{extra[0]} (allowed here: {allowed})"
    if error.validator == "required":
        return f"missing key{' in ' + key if error.absolute_path else ''}: {schema_text(error.message, error.instance)}"
    if error.validator in ("minProperties", "maxProperties") and len(error.absolute_path) == 2:
        return f"key {key}: give exactly one of values, linspace, random"
    if error.validator == "enum":
        choices = ", ".join(map(str, error.validator_value))
        return f"key {key}: {value_text(error.instance)} is not allowed (choose one of {choices})"
    return f"key {key}: {schema_text(error.message, error.instance)}"


def checked_document(
    path: Path, what: str, schema: dict, error: type[Exception], needs: str, keys: str
) -> dict[str, Any]:
    """A YAML file (a sweep's, a tuning's) read and checked against its JSON schema: the mapping,
    or `error` with one line: the file is empty (`needs` says what it needs), not a mapping
    (`keys` names its keys), or the schema's first error, the outermost first."""
    document = read_yaml(path, what)
    if document is None:
        raise error(f"the file is empty ({needs})")
    if not isinstance(document, dict):
        raise error(f"the file must hold a YAML mapping ({keys})")
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(
        validator.iter_errors(document), key=lambda e: (len(e.absolute_path), list(map(str, e.absolute_path)))
    )
    if errors:
        raise error(schema_message(errors[0]))
    return document


def read_yaml(path: Path, what: str) -> Any:
    from toggle_cosim.files.yaml_loader import YamlError, load_yaml

    try:
        return load_yaml(path, what)
    except YamlError as error:
        raise SweepError(str(error)) from error


def _column_type(values: Iterable[Any]) -> str:
    values = list(values)
    if all(isinstance(v, bool) for v in values):
        return "bool"
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return "float"
    return "string"


_OWNER = {"plant.F_E": "sampling", "T_s": "sampling", "t_end": "sampling", "plant.m_B": "plant", "plant.mu": "plant"}


def _standard_parameters(run: Any) -> dict[str, Any]:
    return {
        "plant.F_E": run.plant.F_E if isinstance(run.plant.F_E, float) else math.nan,  # NaN: a signal
        "plant.m_B": run.plant.m_B,
        "plant.mu": run.plant.mu,
        "T_s": run.T_s,
        "t_end": run.t_end,
    }


def _assemble_cases(
    base: dict[str, Any],
    variants_doc: Mapping[str, Any],
    variants: list[str | None],
    axes: dict[str, list[Any]],
    combos: list[tuple[Any, ...]],
    base_path: Path,
) -> list[Case]:
    """The cases, in order, each checked through its groups' combinations (module docstring):
    each combination of a group's values is checked once per variant; a case holding a bad one,
    or repeating an earlier case, is refused with the message the whole case's check gives."""
    keys = list(axes)
    groups: dict[str, list[int]] = {}
    for i, key in enumerate(keys):
        groups.setdefault(check_group(key), []).append(i)
    cases: list[Case] = []
    seen: dict[str, int] = {}
    source = str(base_path)
    for variant in variants:
        resolved = merge_documents(base, variants_doc[variant]) if variant is not None else copy.deepcopy(base)
        (base_run,) = runs_from_document(copy.deepcopy(resolved), base_path)  # valid: the base loaded
        checked: dict[str, dict[tuple[Any, ...], dict[str, Any] | None]] = {}
        for group, members in groups.items():
            results: dict[tuple[Any, ...], dict[str, Any] | None] = {}
            for combo in combos:
                part = tuple(combo[i] for i in members)
                key = tuple(map(_identity, part))
                if key in results:
                    continue
                document = with_values(resolved, {keys[i]: value for i, value in zip(members, part, strict=True)})
                try:
                    (run,) = runs_from_document(copy.deepcopy(document), base_path)
                    results[key] = _standard_parameters(run)
                except ScenarioError:
                    results[key] = None
            checked[group] = results
        standard = _standard_parameters(base_run)
        ids = _CaseIds(resolved, variant, keys)
        for combo in combos:
            index = len(cases)
            values = dict(zip(keys, combo, strict=True))
            document = with_values(resolved, values)
            parameters = dict(standard)
            for group, members in groups.items():
                found = checked[group][tuple(_identity(combo[i]) for i in members)]
                if found is None:
                    _refuse(document, variant, values, index, base_path)
                parameters.update((name, found[name]) for name, owner in _OWNER.items() if owner == group)
            identifier = ids(values, document)
            if identifier in seen:
                label = ", ".join(f"{k}={v!r}" for k, v in values.items())
                raise SweepError(
                    f"cases {seen[identifier]} and {index} are the same co-simulation ({label}); "
                    "remove the repeated axis value"
                )
            seen[identifier] = index
            for key, value in values.items():
                parameters[key] = float(value) if isinstance(value, int) and not isinstance(value, bool) else value
            cases.append(Case(index, identifier, variant, values, document, parameters, source))
    return cases


def _identity(value: Any) -> tuple[type, Any]:
    """An axis value as a lookup key: 1, 1.0 and True stay apart (they may check differently)."""
    return (type(value), value)


def _refuse(document: dict[str, Any], variant: str | None, values: Mapping[str, Any], index: int, base: Path) -> None:
    """Raise the error of the case `index` as the whole case's check gives it."""
    label = ", ".join(f"{k}={v!r}" for k, v in values.items())
    where = f"variant {variant}, " if variant else ""
    try:
        runs_from_document(copy.deepcopy(document), base)
    except ScenarioError as error:
        raise SweepError(f"case {index} ({where}{label}): {error}") from error
    raise SweepError(f"case {index} ({where}{label}): one of its values fails the scenario's checks")


def load_sweep(path: Path, output: Path | None = None) -> Sweep:
    """Read and validate a sweep file and every case it defines. Raises SweepError('FILE: problem')."""
    path = Path(path)
    try:
        return _load_sweep(path, output)
    except SweepError as error:
        message = str(error)
        raise SweepError(message if message.startswith(f"{path}:") else f"{path}: {message}") from error


def _load_sweep(path: Path, output: Path | None) -> Sweep:
    document = checked_document(
        path,
        "sweep file",
        SCHEMA,
        SweepError,
        "a sweep needs base: and axes:",
        "base, axes, mode, output, heatmap, ...",
    )
    folder = path.parent
    base_path = Path(os.path.normpath(folder / document["base"]))
    try:
        load_scenario(base_path)  # the base alone must be a valid scenario
    except ScenarioError as error:
        raise SweepError(f"key base: {error}") from error
    base_doc = read_yaml(base_path, "base scenario")
    variants_doc: dict[str, Any] = base_doc.get("variants") or {}
    wanted = document.get("variant")
    if wanted is None:
        variants: list[str | None] = list(variants_doc) or [None]
    else:
        wanted = [wanted] if isinstance(wanted, str) else list(wanted)
        for name in wanted:
            if name not in variants_doc:
                have = ", ".join(variants_doc) or "none"
                raise SweepError(f"key variant: the base scenario has no variant {name!r} (it has: {have})")
        variants = list(dict.fromkeys(wanted))
    axes: dict[str, list[Any]] = {}
    for key, spec in document["axes"].items():
        if key == "variant":
            raise SweepError("axis variant: choose variants with the variant: key, not as an axis")
        check_axis_key(key)
        axes[key] = _axis_values(key, spec)
    mode = document.get("mode", "grid")
    if mode == "zip":
        lengths = {key: len(values) for key, values in axes.items()}
        if len(set(lengths.values())) > 1:
            raise SweepError(
                "mode zip: every axis needs the same number of values ("
                + ", ".join(f"{k}: {n}" for k, n in lengths.items())
                + ")"
            )
        combos: Iterable[tuple[Any, ...]] = zip(*axes.values(), strict=True)
        count = len(variants) * next(iter(lengths.values()))
    else:
        combos = itertools.product(*axes.values())
        count = len(variants) * math.prod(len(v) for v in axes.values())
    if count > MAX_CASES:
        raise SweepError(f"key axes: {count} cases is more than {MAX_CASES} (split the sweep)")
    combos = list(combos)

    base_clean = {k: v for k, v in base_doc.items() if k not in ("variants", "fmu")}
    cases = _assemble_cases(base_clean, variants_doc, variants, axes, combos, base_path)

    parameter_columns = [*STANDARD_PARAMETERS, *(k for k in axes if k not in STANDARD_PARAMETERS)]
    parameter_types = {k: "float" for k in STANDARD_PARAMETERS}
    for key in axes:
        if key not in STANDARD_PARAMETERS:
            parameter_types[key] = _column_type(c.parameters[key] for c in cases)

    heatmap: tuple[str, str] | None = None
    choices = [*axes, "variant"] if len(variants) > 1 else list(axes)
    if "heatmap" in document:
        x, y = document["heatmap"]["x"], document["heatmap"]["y"]
        for which, key in (("x", x), ("y", y)):
            if key not in choices:
                raise SweepError(
                    f"key heatmap.{which}: {key!r} is not an axis of this sweep (choose one of {', '.join(choices)})"
                )
        if x == y:
            raise SweepError("key heatmap: x and y are the same axis")
        heatmap = (x, y)
    elif len(choices) >= 2:
        heatmap = (choices[0], choices[1])

    name = document.get("name", path.stem)
    if output is None:
        output = folder / document["output"] if "output" in document else Path("out") / "sweeps" / name
    fmu = None
    if "fmu" in document:
        fmu = folder / document["fmu"]
    elif base_doc.get("fmu"):
        fmu = base_path.parent / base_doc["fmu"]
    return Sweep(
        path=path,
        name=name,
        description=document.get("description", ""),
        base=base_path,
        fmu=fmu,
        mode=mode,
        axes=axes,
        variants=variants,
        output=Path(os.path.normpath(output)),
        heatmap=heatmap,
        cases=cases,
        parameter_columns=parameter_columns,
        parameter_types=parameter_types,
    )
