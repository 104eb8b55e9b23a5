"""Parameter sweeps: a base scenario, axes over scenario keys, one co-simulation per case.

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
    output: ../out/sweeps/sweep_FE_mB      # relative to this file; default out/sweeps/<name>
    heatmap: {x: plant.F_E, y: plant.m_B}  # optional, default: the first two axes

Cases are the base's variants (all, or those `variant:` names) times the axis combinations
(grid: every combination, first axis outermost; zip: the i-th value of every axis together).
Every case document is the base scenario with the variant and the case's values applied, and is
validated by the scenario loader before anything runs: one bad case is bad input.

Each case has a stable id, a hash of its resolved scenario document (the base's content, the
variant and the case's values), so a re-run finds the cases already done and skips them.

Execution: a local `ProcessPoolExecutor` (all cores by default) or an existing Dask
distributed cluster (`scheduler="tcp://host:8786"`); no scheduling of our own. The worker
function `run_case` takes plain data (the case document and the FMU path) and returns a plain
dict row; it never raises: an FMU error, a diverging run or any exception is a row with status
"failed" and the reason.

Results: each finished row is written at once to `OUTPUT/parts/<case_id>.parquet` (temporary
name, then rename), so a crash or a kill loses no finished case; at the end (and on Ctrl-C) the
rows are consolidated into `OUTPUT/results.parquet` (atomically), one row per case, and the
consolidated part files are removed. Heat maps land in `OUTPUT/heatmaps/`.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import hashlib
import itertools
import json
import math
import multiprocessing
import os
import platform
import re
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np

from toggle_cosim import interrupts
from toggle_cosim.scenario import SCHEMA as SCENARIO_SCHEMA
from toggle_cosim.scenario import ScenarioError, load_scenario, merge_documents, runs_from_document
from toggle_cosim.summary import RunSummary

__all__ = [
    "SweepError", "Sweep", "Case", "SweepResult", "load_sweep", "run_case", "execute_sweep", "run_sweep",
    "read_results", "write_heatmaps",
]

RESULTS_FILE = "results.parquet"
PARTS_DIR = "parts"
HEATMAP_DIR = "heatmaps"
MANIFEST_FILE = "sweep.json"
STANDARD_PARAMETERS = ("plant.F_E", "plant.m_B", "plant.mu", "T_s", "t_end")
METRICS = (*RunSummary.__dataclass_fields__, "fric_share_end")
EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130

_NUMBER = {"type": "number"}
_SCALAR = {"type": ["number", "string", "boolean"]}
_AXIS = {
    "type": "object",
    "minProperties": 1,
    "maxProperties": 1,
    "additionalProperties": False,
    "properties": {
        "values": {"type": "array", "minItems": 1, "items": _SCALAR},
        "linspace": {"type": "array", "minItems": 3, "maxItems": 3,
                     "prefixItems": [_NUMBER, _NUMBER, {"type": "integer", "minimum": 1, "maximum": 100_000}]},
        "random": {
            "type": "object",
            "additionalProperties": False,
            "required": ["low", "high", "n", "seed"],
            "properties": {"low": _NUMBER, "high": _NUMBER,
                           "n": {"type": "integer", "minimum": 1, "maximum": 100_000},
                           "seed": {"type": "integer", "minimum": 0}},
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

    def payload(self) -> dict[str, Any]:
        return {"index": self.index, "case_id": self.case_id, "variant": self.variant,
                "document": self.document, "parameters": self.parameters}


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


def _split_key(key: str) -> list[str]:
    """A dotted axis key as a path into the scenario document. After `plant.parameters.` the rest
    is one FMU variable name (those contain dots: mechanism.r3)."""
    parts = key.split(".")
    if parts[:2] == ["plant", "parameters"] and len(parts) > 2:
        return ["plant", "parameters", ".".join(parts[2:])]
    return parts


def _check_axis_key(key: str) -> None:
    """Refuse keys the scenario schema does not have (and keys that do not hold one value)."""
    path = _split_key(key)
    if path[0] in ("name", "description", "fmu", "variants"):
        raise SweepError(f"axis {key}: {path[0]} cannot be swept (sweep a physical or numerical key)")
    schema: Mapping[str, Any] = SCENARIO_SCHEMA
    for depth, part in enumerate(path):
        properties = schema.get("properties", {})
        if part in properties:
            schema = properties[part]
        elif "additionalProperties" in schema and isinstance(schema["additionalProperties"], Mapping):
            schema = schema["additionalProperties"]
        else:
            where = ".".join(path[:depth]) or "(top level)"
            allowed = ", ".join(sorted(properties)) or "none"
            raise SweepError(f"axis {key}: unknown scenario key {part!r} under {where} (allowed there: {allowed})")
    if schema.get("type") == "object" or "properties" in schema:
        raise SweepError(f"axis {key}: a group of keys, not one value (name one key inside it, e.g. {key}.<key>)")


def _set_key(document: dict[str, Any], key: str, value: Any) -> None:
    node = document
    path = _split_key(key)
    for part in path[:-1]:
        child = node.get(part)
        if not isinstance(child, dict):
            child = {}
            node[part] = child
        node = child
    node[path[-1]] = value


def _get_key(document: Mapping[str, Any], key: str) -> Any:
    node: Any = document
    for part in _split_key(key):
        if not isinstance(node, Mapping) or part not in node:
            return None
        node = node[part]
    return node


def _axis_values(key: str, spec: Mapping[str, Any]) -> list[Any]:
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
    if isinstance(node, (int, float, np.integer, np.floating)):
        return float(node)
    return str(node)


def case_id(document: Mapping[str, Any], variant: str | None) -> str:
    """Stable id of a case: a hash of what it computes (its resolved scenario document and variant)."""
    content = {k: v for k, v in document.items() if k not in _IGNORED_IN_ID}
    text = json.dumps({"variant": variant, "scenario": _canonical(content)}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _schema_message(error: jsonschema.ValidationError) -> str:
    key = ".".join(str(p) for p in error.absolute_path) or "(top level)"
    if error.validator == "additionalProperties":
        extra = sorted(set(error.instance) - set(error.schema.get("properties", {})))
        allowed = ", ".join(sorted(error.schema.get("properties", {}))) or "none"
        where = f"{key}." if error.absolute_path else ""
        return f"unknown key {where}{extra[0]} (allowed here: {allowed})"
    if error.validator == "required":
        return f"missing key{' in ' + key if error.absolute_path else ''}: {error.message}"
    if error.validator in ("minProperties", "maxProperties") and len(error.absolute_path) == 2:
        return f"key {key}: give exactly one of values, linspace, random"
    if error.validator == "enum":
        return f"key {key}: {error.instance!r} is not allowed (choose one of {', '.join(map(str, error.validator_value))})"
    return f"key {key}: {' '.join(error.message.split())}"


def _read_yaml(path: Path, what: str) -> Any:
    from toggle_cosim.yaml_loader import YamlError, load_yaml

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


def load_sweep(path: Path, output: Path | None = None) -> Sweep:
    """Read and validate a sweep file and every case it defines. Raises SweepError('FILE: problem')."""
    path = Path(path)
    try:
        return _load_sweep(path, output)
    except SweepError as error:
        message = str(error)
        raise SweepError(message if message.startswith(f"{path}:") else f"{path}: {message}") from error


def _load_sweep(path: Path, output: Path | None) -> Sweep:
    document = _read_yaml(path, "sweep file")
    if document is None:
        raise SweepError("the file is empty (a sweep needs base: and axes:)")
    if not isinstance(document, dict):
        raise SweepError("the file must hold a YAML mapping (base, axes, mode, output, heatmap, ...)")
    validator = jsonschema.Draft202012Validator(SCHEMA)
    errors = sorted(validator.iter_errors(document), key=lambda e: (len(e.absolute_path), list(map(str, e.absolute_path))))
    if errors:
        raise SweepError(_schema_message(errors[0]))
    folder = path.parent
    base_path = Path(os.path.normpath(folder / document["base"]))
    try:
        load_scenario(base_path)  # the base alone must be a valid scenario
    except ScenarioError as error:
        raise SweepError(f"key base: {error}") from error
    base_doc = _read_yaml(base_path, "base scenario")
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
        _check_axis_key(key)
        axes[key] = _axis_values(key, spec)
    mode = document.get("mode", "grid")
    if mode == "zip":
        lengths = {key: len(values) for key, values in axes.items()}
        if len(set(lengths.values())) > 1:
            raise SweepError("mode zip: every axis needs the same number of values (" +
                             ", ".join(f"{k}: {n}" for k, n in lengths.items()) + ")")
        combos: Iterable[tuple[Any, ...]] = zip(*axes.values(), strict=True)
        count = len(variants) * next(iter(lengths.values()))
    else:
        combos = itertools.product(*axes.values())
        count = len(variants) * math.prod(len(v) for v in axes.values())
    if count > MAX_CASES:
        raise SweepError(f"key axes: {count} cases is more than {MAX_CASES} (split the sweep)")
    combos = list(combos)

    base_clean = {k: v for k, v in base_doc.items() if k not in ("variants", "fmu")}
    cases: list[Case] = []
    seen: dict[str, int] = {}
    for variant in variants:
        resolved = merge_documents(base_clean, variants_doc[variant]) if variant is not None else copy.deepcopy(base_clean)
        for combo in combos:
            values = dict(zip(axes, combo, strict=True))
            case_doc = copy.deepcopy(resolved)
            for key, value in values.items():
                _set_key(case_doc, key, value)
            index = len(cases)
            label = ", ".join(f"{k}={v!r}" for k, v in values.items())
            try:
                (run,) = runs_from_document(case_doc)
            except ScenarioError as error:
                where = f"variant {variant}, " if variant else ""
                raise SweepError(f"case {index} ({where}{label}): {error}") from error
            identifier = case_id(case_doc, variant)
            if identifier in seen:
                raise SweepError(f"cases {seen[identifier]} and {index} are the same co-simulation ({label}); "
                                 "remove the repeated axis value")
            seen[identifier] = index
            parameters: dict[str, Any] = {
                "plant.F_E": run.plant.F_E, "plant.m_B": run.plant.m_B, "plant.mu": run.plant.mu,
                "T_s": run.T_s, "t_end": run.t_end,
            }
            for key, value in values.items():
                parameters[key] = float(value) if isinstance(value, int) and not isinstance(value, bool) else value
            cases.append(Case(index, identifier, variant, values, case_doc, parameters))

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
                raise SweepError(f"key heatmap.{which}: {key!r} is not an axis of this sweep (choose one of {', '.join(choices)})")
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
        path=path, name=name, description=document.get("description", ""), base=base_path, fmu=fmu, mode=mode,
        axes=axes, variants=variants, output=Path(os.path.normpath(output)), heatmap=heatmap, cases=cases,
        parameter_columns=parameter_columns, parameter_types=parameter_types,
    )


# -- the worker --------------------------------------------------------------------------------

_capture = threading.local()
_plant_cache: dict[tuple[str, int, int], Any] = {}
_sha_cache: dict[tuple[str, int, int], str] = {}


class _ThreadLogTee:
    """sys.stdout stand-in: text printed by a thread that is capturing goes to its buffer (fmpy
    prints the FMU's log messages), everything else to the real stream. Safe with Dask threads."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        buffer = getattr(_capture, "buffer", None)
        if buffer is not None:
            buffer.append(text)
            return len(text)
        return self._stream.write(text)

    def flush(self) -> None:
        if getattr(_capture, "buffer", None) is None and self._stream is not None:
            self._stream.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextlib.contextmanager
def _captured_fmu_log() -> Iterator[list[str]]:
    if not isinstance(sys.stdout, _ThreadLogTee):
        sys.stdout = _ThreadLogTee(sys.stdout)
    buffer: list[str] = []
    _capture.buffer = buffer
    try:
        yield buffer
    finally:
        _capture.buffer = None


def _file_key(path: Path) -> tuple[str, int, int]:
    stat = path.stat()
    return (str(path), stat.st_mtime_ns, stat.st_size)


def _sha256(path: Path) -> str:
    key = _file_key(path)
    if key not in _sha_cache:
        from toggle_cosim.cosim.outcome import file_sha256

        _sha_cache[key] = file_sha256(path)
    return _sha_cache[key]


def _plant(path: Path) -> Any:
    from toggle_cosim.plant import check_plant

    key = _file_key(path)
    if key not in _plant_cache:
        _plant_cache[key] = check_plant(path)
    return _plant_cache[key]


def _resolve_fmu(fmu: str, sha256: str | None, data: bytes | None = None) -> Path:
    """The FMU file this worker uses: `fmu` if it is there with the sweep's SHA-256, else a copy of
    `data` (the FMU's bytes, sent along by the Dask backend) in this machine's temporary folder.
    A different FMU at the same path (a stale build on another machine) is never used."""
    if sha256 is None:
        return Path(fmu)
    given = Path(fmu)
    found = None
    if given.is_file():
        found = _sha256(given)
        if found == sha256:
            return given
    if data is not None:
        cache = Path(tempfile.gettempdir()) / "toggle-cosim-fmus" / f"plant-{sha256[:32]}.fmu"
        if not (cache.is_file() and _sha256(cache) == sha256):
            cache.parent.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(prefix=".plant-", suffix=".partial", dir=cache.parent)
            with os.fdopen(handle, "wb") as stream:
                stream.write(data)
            os.replace(temporary, cache)
            if _sha256(cache) != sha256:
                raise ValueError(f"the FMU bytes received do not have the sweep's SHA-256 {sha256[:12]}")
        return cache
    detail = f"{given} has SHA-256 {found[:12]}" if found else f"no file {given}"
    raise FileNotFoundError(f"the sweep's FMU (SHA-256 {sha256[:12]}) is not on this machine: {detail}")


def run_case(case: Mapping[str, Any], fmu: str, fmu_sha256: str | None = None,
             fmu_data: bytes | None = None, time_limit: float | None = None) -> dict[str, Any]:
    """Run one case (a payload of plain data) on the plant FMU at `fmu` (checked against
    `fmu_sha256` if given; `fmu_data`, the FMU's bytes, stand in where that file is missing);
    return its table row.

    Never raises for a failure of the case: the row has status "failed" and the reason. The case
    runs supervised (`supervision`): a crash or hang of the plant, or `time_limit` (default: the
    case's time_limit key, else max(30 s, 20 x t_end)) exceeded, is a failed row."""
    from toggle_cosim.cosim.supervision import simulate_supervised

    started = time.perf_counter()
    row: dict[str, Any] = {
        "case": case["index"], "case_id": case["case_id"], "variant": case["variant"], **case["parameters"],
        "status": "failed", "reason": None, **dict.fromkeys(METRICS), "samples": None,
        "wall_s": None, "host": socket.gethostname(), "fmu_sha256": fmu_sha256,
    }
    try:
        with _captured_fmu_log() as log:
            try:
                (run,) = runs_from_document(copy.deepcopy(case["document"]))
                plant = _plant(_resolve_fmu(fmu, fmu_sha256, fmu_data))
                outcome = simulate_supervised(run, plant, time_limit=time_limit, capture_log=True)
            except Exception as error:  # noqa: BLE001 - any failure is the case's result
                outcome = None
                row["reason"] = " ".join(f"{type(error).__name__}: {error}".split())
        messages = [line.strip() for line in "".join(log).splitlines()
                    if line.startswith(("[ERROR]", "[FATAL]"))]
        if outcome is not None:
            row["samples"] = outcome.trace.data.shape[0]
            if outcome.complete and outcome.summary is not None:
                row["status"] = "ok"
                summary = outcome.summary.as_dict()
                row.update({k: (None if v is None else float(v)) for k, v in summary.items()})
                E_in, E_fric = summary["E_in_J"], summary["E_fric_J"]
                row["fric_share_end"] = float(E_fric / E_in) if E_in else None
            else:
                row["reason"] = outcome.reason or "the run ended without a summary"
        if row["status"] == "failed" and messages:
            row["reason"] = f"{row['reason']} [FMU log: {' | '.join(messages[:3])}]"
    except Exception as error:  # noqa: BLE001 - even a failure of the bookkeeping is a row
        row["status"] = "failed"
        row["reason"] = " ".join(f"{type(error).__name__}: {error}".split())
    row["wall_s"] = time.perf_counter() - started
    return row


# -- execution backends ------------------------------------------------------------------------

_slots: Any = None  # per-process: the shared array of "case running in worker slot i"
_slot: int = -1


def _pool_init(slots: Any, counter: Any) -> None:
    """Pool worker start: Ctrl-C is the parent's to handle; take a slot to report the running case."""
    global _slots, _slot
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    with counter.get_lock():
        _slot = counter.value
        counter.value += 1
    _slots = slots


def _pool_task(case: Mapping[str, Any], fmu: str, fmu_sha256: str | None, time_limit: float | None = None) -> dict[str, Any]:
    if _slots is not None and 0 <= _slot < len(_slots):
        _slots[_slot] = case["index"]
    try:
        return run_case(case, fmu, fmu_sha256, time_limit=time_limit)
    finally:
        if _slots is not None and 0 <= _slot < len(_slots):
            _slots[_slot] = -1


def _crash_row(case: Case, fmu_sha256: str | None, reason: str) -> dict[str, Any]:
    return {
        "case": case.index, "case_id": case.case_id, "variant": case.variant, **case.parameters,
        "status": "failed", "reason": reason, **dict.fromkeys(METRICS), "samples": None, "wall_s": None,
        "host": socket.gethostname(), "fmu_sha256": fmu_sha256,
    }


def _kill_workers(pool: ProcessPoolExecutor) -> None:
    """End the pool's workers now (an interrupt): their running cases' plants die with them."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        with contextlib.suppress(Exception):
            process.kill()


def _run_pool(cases: Sequence[Case], fmu: str, sha: str, workers: int, on_row: Callable[[dict[str, Any]], None],
              time_limit: float | None = None) -> None:
    """Local process pool. A worker process that dies (a crash inside the FMU) breaks the pool:
    the cases that were running then are re-run one at a time to find the one that crashes, which
    is recorded as failed; the others are resubmitted."""
    context = multiprocessing.get_context("spawn")
    pending = list(cases)
    isolate: list[Case] = []
    while pending or isolate:
        if isolate:
            batch, size = [isolate.pop(0)], 1
        else:
            batch, pending, size = pending, [], max(1, min(workers, len(pending)))
        slots = context.Array("q", [-1] * size, lock=False)
        counter = context.Value("i", 0)
        pool = ProcessPoolExecutor(max_workers=size, mp_context=context, initializer=_pool_init, initargs=(slots, counter))
        futures = {pool.submit(_pool_task, case.payload(), fmu, sha, time_limit): case for case in batch}
        broken: list[Case] = []
        running_at_break: set[int] = set()
        try:
            remaining = set(futures)
            while remaining:
                done, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for future in done:
                    try:
                        row = future.result()
                    except BrokenProcessPool:
                        if not running_at_break:
                            running_at_break = {int(i) for i in slots if i >= 0} or {-2}
                        broken.append(futures[future])
                        continue
                    except Exception as error:  # noqa: BLE001 - pickling and the like
                        row = _crash_row(futures[future], sha, " ".join(f"{type(error).__name__}: {error}".split()))
                    on_row(row)
        except BaseException:
            _kill_workers(pool)
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
        if broken:
            if size == 1 and len(batch) == 1:
                on_row(_crash_row(batch[0], sha, "the worker process died running this case (a crash in the FMU?)"))
                continue
            suspects = [c for c in broken if c.index in running_at_break] or broken
            isolate.extend(suspects)
            pending = [c for c in broken if c not in suspects] + pending


def connect(scheduler: str) -> Any:
    """A client of the Dask distributed cluster at `scheduler` (SweepError if it cannot be reached;
    the time allowed is dask's distributed.comm.timeouts.connect)."""
    try:
        from distributed import Client
    except ImportError as error:  # pragma: no cover - a declared dependency
        raise SweepError(f"--scheduler needs the 'distributed' package ({error})") from error
    try:
        return Client(scheduler, set_as_default=False)
    except Exception as error:  # noqa: BLE001 - OSError, TimeoutError, ValueError for a bad address
        raise SweepError(f"cannot connect to the Dask scheduler at {scheduler} ({' '.join(str(error).split())})") from error


def _run_dask(cases: Sequence[Case], fmu: str, sha: str, client: Any, on_row: Callable[[dict[str, Any]], None],
              time_limit: float | None = None) -> None:
    """An existing Dask distributed cluster: submit every case, collect as they complete. The FMU
    travels with the tasks: the workers need toggle-cosim installed, not the project's files."""
    from distributed import as_completed

    # the FMU's bytes go along (once per worker), for workers that do not share this file system
    fmu_data = client.scatter(Path(fmu).read_bytes(), broadcast=True, hash=False)
    futures = {}
    for case in cases:
        future = client.submit(run_case, case.payload(), fmu, sha, fmu_data, time_limit,
                               key=f"toggle-cosim-case-{case.case_id}", pure=False)
        futures[future] = case
    try:
        for future in as_completed(futures, loop=client.loop):
            case = futures[future]
            try:
                row = future.result()
            except Exception as error:  # noqa: BLE001 - KilledWorker, a lost connection, ...
                reason = " ".join(f"{type(error).__name__}: {error}".split())
                row = _crash_row(case, sha, f"the Dask task failed: {reason}")
            on_row(row)
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel(list(futures))
        raise
    finally:
        with contextlib.suppress(Exception):
            client.cancel([fmu_data])


def execute(cases: Sequence[Case], fmu: Path, scheduler: str | None, workers: int | None,
            on_row: Callable[[dict[str, Any]], None], fmu_sha256: str | None = None, client: Any = None,
            time_limit: float | None = None) -> None:
    """Run `cases` on the chosen backend and call `on_row(row)` in this process as each finishes:
    the Dask cluster at `scheduler` (or an open `client` of one), else a local process pool of
    `workers` processes (default: all cores)."""
    if not cases:
        return
    fmu = Path(fmu).resolve()
    if fmu_sha256 is None:
        fmu_sha256 = _sha256(fmu)
    if client is not None:
        _run_dask(cases, str(fmu), fmu_sha256, client, on_row, time_limit)
    elif scheduler:
        own = connect(scheduler)
        try:
            _run_dask(cases, str(fmu), fmu_sha256, own, on_row, time_limit)
        finally:
            with contextlib.suppress(Exception):
                own.close()
    else:
        _run_pool(cases, str(fmu), fmu_sha256, workers or os.cpu_count() or 1, on_row, time_limit)


# -- results -----------------------------------------------------------------------------------


def _arrow_schema(sweep: Sweep) -> Any:
    import pyarrow as pa

    pa.enable_signal_handlers(False)  # its own SIGINT handler would bypass ours (exit -2, not 130)

    types = {"float": pa.float64(), "bool": pa.bool_(), "string": pa.string()}
    fields = [pa.field("case", pa.int64()), pa.field("case_id", pa.string()), pa.field("variant", pa.string())]
    fields += [pa.field(c, types[sweep.parameter_types[c]]) for c in sweep.parameter_columns]
    fields += [pa.field("status", pa.string()), pa.field("reason", pa.string())]
    fields += [pa.field(m, pa.float64()) for m in METRICS]
    fields += [pa.field("samples", pa.int64()), pa.field("wall_s", pa.float64()), pa.field("host", pa.string()),
               pa.field("fmu_sha256", pa.string())]
    return pa.schema(fields)


def _coerce(value: Any, kind: str) -> Any:
    if value is None:
        return None
    if kind == "string":
        return value if isinstance(value, str) else str(value)
    if kind == "bool":
        return bool(value)
    if kind in ("double", "float"):
        return float(value)
    if kind == "int64":
        return int(value)
    return value


def _table(rows: Sequence[Mapping[str, Any]], schema: Any) -> Any:
    import pyarrow as pa

    columns = {}
    for f in schema:
        kind = str(f.type)
        columns[f.name] = pa.array([_coerce(r.get(f.name), kind) for r in rows], type=f.type)
    return pa.table(columns, schema=schema)


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _current_umask()


def _atomic_parquet(table: Any, path: Path) -> None:
    import pyarrow.parquet as pq

    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    os.close(handle)
    try:
        pq.write_table(table, temporary)
        with open(temporary, "rb") as stream:
            os.fsync(stream.fileno())
        os.chmod(temporary, 0o666 & ~_UMASK)  # mkstemp makes it private; the table is an ordinary file
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _read_rows(path: Path) -> list[dict[str, Any]]:
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


class ResultStore:
    """The sweep's output folder: one part file per finished case, consolidated into results.parquet."""

    def __init__(self, sweep: Sweep) -> None:
        self.sweep = sweep
        self.folder = sweep.output
        self.parts = self.folder / PARTS_DIR
        self.results = self.folder / RESULTS_FILE
        self.schema = _arrow_schema(sweep)
        self.wanted = {c.case_id for c in sweep.cases}
        self.rows: dict[str, dict[str, Any]] = {}  # finished cases of this sweep, by id
        self.unreadable: list[str] = []

    def load(self) -> None:
        """Read what earlier runs finished (results.parquet, then part files, newer wins)."""
        self.parts.mkdir(parents=True, exist_ok=True)
        for stale in self.parts.glob(".*.partial"):
            stale.unlink(missing_ok=True)
        for stale in self.folder.glob(".*.partial"):
            stale.unlink(missing_ok=True)
        sources = ([self.results] if self.results.is_file() else []) + sorted(self.parts.glob("*.parquet"))
        for source in sources:
            try:
                rows = _read_rows(source)
            except Exception as error:  # noqa: BLE001 - a torn file from a foreign writer: redo its cases
                self.unreadable.append(f"{source.name} ({type(error).__name__})")
                continue
            for row in rows:
                if row.get("case_id") in self.wanted:
                    self.rows[row["case_id"]] = row

    def add(self, row: dict[str, Any]) -> None:
        """Record a finished case at once: its own part file, written atomically."""
        self.rows[row["case_id"]] = row
        _atomic_parquet(_table([row], self.schema), self.parts / f"{row['case_id']}.parquet")

    def consolidate(self) -> Path:
        """results.parquet = this sweep's finished cases, in case order; then drop the part files it
        holds. Rows of cases that are not in this sweep (an earlier version of the file) stay as parts."""
        import pyarrow.parquet as pq

        order = {c.case_id: c for c in self.sweep.cases}
        rows = []
        for identifier, case in order.items():
            if identifier in self.rows:
                row = dict(self.rows[identifier])
                row["case"] = case.index  # the index in this version of the sweep file
                rows.append(row)
        if self.results.is_file():  # keep foreign rows of an earlier results table as part files
            with contextlib.suppress(Exception):
                old = pq.read_table(self.results)
                ids = old.column("case_id").to_pylist()
                for k, identifier in enumerate(ids):
                    target = self.parts / f"{identifier}.parquet"
                    if identifier not in self.wanted and not target.exists():
                        _atomic_parquet(old.slice(k, 1), target)
        _atomic_parquet(_table(rows, self.schema), self.results)
        for identifier in self.rows:
            (self.parts / f"{identifier}.parquet").unlink(missing_ok=True)
        with contextlib.suppress(OSError):
            self.parts.rmdir()  # only when empty: no empty folder is left behind
        return self.results


def read_results(path: Path) -> Any:
    """A sweep's results table as a pandas DataFrame (give results.parquet or its folder)."""
    import pandas as pd
    import pyarrow as pa

    pa.enable_signal_handlers(False)
    path = Path(path)
    return pd.read_parquet(path / RESULTS_FILE if path.is_dir() else path)


# -- figures -----------------------------------------------------------------------------------

PANELS = (
    ("final_error_m", "|final error| [mm]", lambda v: np.abs(v) * 1e3, "viridis"),
    ("settling_time_s", "settling time (2 %) [s]", lambda v: v, "viridis"),
    ("peak_iq_ref_A", "peak |i_q*| [A]", lambda v: v, "magma"),
    ("overshoot_percent", "overshoot [%]", lambda v: v, "viridis"),
    ("fric_share_start", "E_fric/E_in at 10 % stroke [%]", lambda v: v * 100, "cividis"),
    ("fric_share_end", "E_fric/E_in at t_end [%]", lambda v: v * 100, "cividis"),
)


def _label(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", text).strip("_") or "all"


def write_heatmaps(table: Any, sweep: Sweep) -> list[Path]:
    """One PNG per combination of the other axes: heat maps of the figures of merit over the two
    chosen axes. A failed case is a crossed cell; a run that never settles is a grey cell."""
    if sweep.heatmap is None or table.empty:
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x, y = sweep.heatmap
    others = [k for k in sweep.axes if k not in (x, y)]
    if len(sweep.variants) > 1 and "variant" not in (x, y):
        others.insert(0, "variant")
    folder = sweep.output / HEATMAP_DIR
    written = []
    groups = table.groupby(others, sort=True, dropna=False) if others else [((), table)]
    for key, group in groups:
        key = key if isinstance(key, tuple) else (key,)
        tag = ", ".join(f"{k} = {_label(v)}" for k, v in zip(others, key, strict=True))
        xs = sorted(group[x].dropna().unique(), key=lambda v: (isinstance(v, str), v))
        ys = sorted(group[y].dropna().unique(), key=lambda v: (isinstance(v, str), v))
        xi = {v: i for i, v in enumerate(xs)}
        yi = {v: i for i, v in enumerate(ys)}
        figure, axes = plt.subplots(2, 3, figsize=(16, 9), constrained_layout=True)
        annotate = len(xs) * len(ys) <= 100
        rows_i = np.array([yi[v] for v in group[y]], dtype=int)
        cols_j = np.array([xi[v] for v in group[x]], dtype=int)
        ok = (group["status"] == "ok").to_numpy()
        failed = np.zeros((len(ys), len(xs)), dtype=bool)
        failed[rows_i[~ok], cols_j[~ok]] = True
        for ax, (column, title, transform, cmap) in zip(axes.flat, PANELS, strict=True):
            grid = np.full((len(ys), len(xs)), np.nan)
            values = transform(group[column].to_numpy(dtype=float, na_value=np.nan))
            grid[rows_i[ok], cols_j[ok]] = values[ok]
            colormap = plt.get_cmap(cmap).with_extremes(bad="0.85")
            image = ax.imshow(np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap=colormap,
                              interpolation="nearest")
            figure.colorbar(image, ax=ax, shrink=0.9)
            for i, j in zip(*np.nonzero(failed), strict=True):
                ax.text(j, i, "✗", ha="center", va="center", color="red", fontsize=9)
            if annotate:
                finite = grid[np.isfinite(grid)]
                middle = (finite.min() + finite.max()) / 2 if finite.size else 0
                for (i, j), value in np.ndenumerate(grid):
                    if np.isfinite(value):
                        ax.text(j, i, f"{value:.3g}", ha="center", va="center", fontsize=6,
                                color="white" if value < middle else "black")
                    elif not failed[i, j] and column == "settling_time_s":
                        ax.text(j, i, "n/s", ha="center", va="center", fontsize=6, color="0.3")
            step_x = max(1, len(xs) // 12)
            step_y = max(1, len(ys) // 12)
            ax.set_xticks(range(0, len(xs), step_x), [_label(v) for v in xs[::step_x]], rotation=45, fontsize=8)
            ax.set_yticks(range(0, len(ys), step_y), [_label(v) for v in ys[::step_y]], fontsize=8)
            ax.set_xlabel(x)
            ax.set_ylabel(y)
            ax.set_title(title)
        n_failed = int((group["status"] != "ok").sum())
        figure.suptitle(f"{sweep.name}{': ' + tag if tag else ''}  ({len(group)} cases, {n_failed} failed ✗,"
                        " grey: no value / never settled)")
        name = "heatmap" + ("_" + _slug("_".join(f"{k}={_label(v)}" for k, v in zip(others, key, strict=True))) if others else "")
        path = folder / f"{name}.png"
        folder.mkdir(parents=True, exist_ok=True)
        partial = folder / f".{name}.partial.png"
        figure.savefig(partial, dpi=100)
        plt.close(figure)
        partial.replace(path)
        written.append(path)
    return written


# -- the sweep ---------------------------------------------------------------------------------


@dataclass
class SweepResult:
    total: int
    skipped: int  # finished by an earlier run
    ran: int = 0  # finished by this run
    done: int = 0  # cases in the final table
    failed: int = 0  # failed cases in the final table
    interrupted: bool = False
    wall_seconds: float = 0.0
    results: Path | None = None
    figures: list[Path] = field(default_factory=list)

    @property
    def rate(self) -> float:
        return self.ran / self.wall_seconds if self.wall_seconds > 0 else 0.0


@contextlib.contextmanager
def _exclusive(folder: Path) -> Iterator[None]:
    """One sweep at a time per output folder."""
    folder.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    with open(folder / ".lock", "w") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            raise SweepError(f"{folder}: another sweep is writing to this folder (wait for it or choose another output:)") from error
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _resolve_plant(sweep: Sweep, fmu: Path | None) -> tuple[Path, str]:
    from toggle_cosim.plant import ContractError, check_plant

    chosen = fmu if fmu is not None else sweep.fmu
    if chosen is None:
        raise SweepError(f"{sweep.path}: no fmu: key here or in the base scenario, and no --fmu option (name the plant FMU)")
    chosen = Path(chosen).resolve()
    from toggle_cosim.plant_probe import ProbeError, probe_binary

    try:
        plant = check_plant(chosen)
        probe_binary(plant)
    except (ContractError, ProbeError) as error:
        raise SweepError(str(error)) from error
    for key in sweep.axes:
        path = _split_key(key)
        if path[:2] == ["plant", "parameters"] and path[2] not in plant.references:
            raise SweepError(f"{sweep.path}: axis {key}: the plant FMU has no variable {path[2]!r}")
    names = {name for case in sweep.cases for name in (case.document.get("plant", {}).get("parameters") or {})}
    for name in sorted(names):
        if name not in plant.references:
            raise SweepError(f"{sweep.base}: key plant.parameters.{name}: the plant FMU has no variable {name!r}")
    from types import SimpleNamespace

    from toggle_cosim.plant_settings import SettingError, check_settings

    from toggle_cosim.cosim.master import trace_names
    from toggle_cosim.resources import max_output

    if sweep.cases:  # each case's trace buffer (8 bytes a value while it runs) within the output limit
        biggest = max(sweep.cases, key=lambda c: c.parameters["t_end"] / c.parameters["T_s"])
        samples = int(round(biggest.parameters["t_end"] / biggest.parameters["T_s"])) + 1
        size = samples * len(trace_names(plant)) * 8
        if size > max_output():
            raise SweepError(f"{sweep.path}: case {biggest.index} would hold {samples} samples x {len(trace_names(plant))}"
                             f" columns, about {size / 1e9:.2f} GB while it runs, over the {max_output() / 1e9:.2f} GB"
                             " output limit; raise T_s or shorten t_end (or raise TOGGLE_COSIM_MAX_OUTPUT)")
    seen = set()
    for case in sweep.cases:  # each distinct setting of the plant, before any case runs
        plant_doc = case.document.get("plant") or {}
        settings = SimpleNamespace(current_loop=plant_doc.get("current_loop", "first_order"),
                                   parameters=dict(plant_doc.get("parameters") or {}),
                                   friction_model=plant_doc.get("friction_model", "paper"),
                                   mu=plant_doc.get("mu", 0.0), mu_s=plant_doc.get("mu_s"))
        key = (settings.current_loop, settings.friction_model, repr(settings.mu), repr(settings.mu_s),
               repr(sorted(settings.parameters.items(), key=repr)))
        if key in seen:
            continue
        seen.add(key)
        try:
            check_settings(SimpleNamespace(plant=settings, variant=case.variant), plant)
        except SettingError as error:
            raise SweepError(f"{sweep.path}: case {case.index}: {error}") from error
    return chosen, _sha256(chosen)


def execute_sweep(sweep: Sweep, fmu: Path | None = None, scheduler: str | None = None, workers: int | None = None,
                  progress: bool = True, retry_failed: bool = False, log: Callable[[str], None] | None = None,
                  case_timeout: float | None = None) -> SweepResult:
    """Run the cases of `sweep` that are not done yet, write the table and the heat maps."""
    say = log or (lambda text: print(text, file=sys.stderr, flush=True))
    if workers is not None and workers < 1:
        raise SweepError(f"--workers {workers}: give at least 1")
    if scheduler and workers is not None:
        raise SweepError("--workers sets the local pool's size; with --scheduler the Dask cluster's workers run the cases")
    if case_timeout is not None and not (case_timeout > 0 and math.isfinite(case_timeout)):
        raise SweepError(f"--case-timeout {case_timeout}: give a positive number of seconds")
    fmu_path, sha = _resolve_plant(sweep, fmu)
    client = connect(scheduler) if scheduler else None  # before anything is written
    try:
        return _execute_sweep(sweep, fmu_path, sha, scheduler, client, workers, progress, retry_failed, say, case_timeout)
    finally:
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()


def _execute_sweep(sweep: Sweep, fmu_path: Path, sha: str, scheduler: str | None, client: Any, workers: int | None,
                   progress: bool, retry_failed: bool, say: Callable[[str], None],
                   case_timeout: float | None = None) -> SweepResult:
    with _exclusive(sweep.output):
        store = ResultStore(sweep)
        store.load()
        if store.unreadable:
            say(f"warning: unreadable result files, their cases run again: {', '.join(store.unreadable[:5])}")
        if retry_failed:
            store.rows = {k: r for k, r in store.rows.items() if r.get("status") == "ok"}
        todo = [c for c in sweep.cases if c.case_id not in store.rows]
        result = SweepResult(total=len(sweep.cases), skipped=len(sweep.cases) - len(todo))
        other_fmu = sum(1 for r in store.rows.values() if r.get("fmu_sha256") not in (None, sha))
        backend = f"Dask scheduler {scheduler}" if scheduler else f"local process pool, {workers or os.cpu_count()} workers"
        say(f"sweep {sweep.name}: {result.total} cases; skipped {result.skipped} already done; "
            f"running {len(todo)} on the {backend}")
        if other_fmu:
            say(f"warning: {other_fmu} finished cases were computed with a different FMU; "
                f"delete {sweep.output} to recompute them with this one")
        failed_now = 0
        bar = None
        if progress and todo:
            from tqdm import tqdm

            bar = tqdm(total=len(todo), file=sys.stderr, unit="case", dynamic_ncols=True, desc=sweep.name,
                       mininterval=0.2 if sys.stderr.isatty() else 5.0)
        run_started = time.perf_counter()

        def on_row(row: dict[str, Any]) -> None:
            nonlocal failed_now
            with interrupts.deferred():  # a part file is whole or not there
                store.add(row)
            result.ran += 1
            if row["status"] != "ok":
                failed_now += 1
            if bar is not None:
                rate = result.ran / max(time.perf_counter() - run_started, 1e-9)
                bar.set_postfix_str(f"done {result.ran}, failed {failed_now}, {rate:.1f} cases/s", refresh=False)
                bar.update(1)

        try:
            execute(todo, fmu_path, scheduler, workers, on_row, sha, client, case_timeout)
        except BaseException as error:
            if not interrupts.is_interrupt(error):
                raise
            result.interrupted = True
            interrupts.ignore()  # the sweep is ending: what follows is writing its table
        finally:
            result.wall_seconds = time.perf_counter() - run_started
            if bar is not None:
                bar.close()
            with interrupts.deferred():
                result.results = store.consolidate()
        finished = [row for identifier, row in store.rows.items() if identifier in store.wanted]
        result.done = len(finished)
        result.failed = sum(1 for row in finished if row.get("status") != "ok")
        if not result.interrupted:  # pandas and matplotlib only when there is time for them
            result.figures = write_heatmaps(read_results(result.results), sweep)
        with interrupts.deferred():
            _write_manifest(sweep, result, fmu_path, sha, scheduler, workers)
    return result


def _write_manifest(sweep: Sweep, result: SweepResult, fmu: Path, sha: str, scheduler: str | None, workers: int | None) -> None:
    from toggle_cosim.traces import write_json

    write_json(sweep.output / MANIFEST_FILE, {
        "sweep": sweep.name, "sweep_file": str(sweep.path), "base": str(sweep.base), "mode": sweep.mode,
        "axes": sweep.axes, "variants": sweep.variants, "cases": result.total,
        "fmu": {"path": str(fmu), "sha256": sha},
        "last_run": {"skipped": result.skipped, "ran": result.ran, "failed_in_table": result.failed,
                     "done_in_table": result.done, "interrupted": result.interrupted,
                     "wall_s": result.wall_seconds, "cases_per_s": result.rate,
                     "backend": f"dask:{scheduler}" if scheduler else f"pool:{workers or os.cpu_count()}",
                     "host": platform.node(), "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z")},
        "results": RESULTS_FILE, "heatmaps": [str(p.relative_to(sweep.output)) for p in result.figures],
    })


def run_sweep(sweep_path: Path, scheduler: str | None = None, workers: int | None = None, fmu: Path | None = None,
              *, output: Path | None = None, retry_failed: bool = False, progress: bool = True,
              case_timeout: float | None = None) -> int:
    """`toggle-cosim sweep SWEEP.yaml [--scheduler ADDRESS] [--workers N] [--fmu PATH]`.

    Exit status: 0 every case ok, 1 some case failed, 2 bad input (one `error: ...` line on
    stderr, nothing run), 130 interrupted (finished cases are kept; run again to finish)."""
    try:
        sweep = load_sweep(Path(sweep_path), output)
        result = execute_sweep(sweep, fmu, scheduler, workers, progress=progress, retry_failed=retry_failed,
                               case_timeout=case_timeout)
    except SweepError as error:
        print(f"error: {' '.join(str(error).split())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    ok = result.done - result.failed
    print(f"sweep {sweep.name}: ran {result.ran} cases in {result.wall_seconds:.1f} s ({result.rate:.1f} cases/s), "
          f"skipped {result.skipped} already done; table: {ok} ok, {result.failed} failed, "
          f"{result.total - result.done} not run, of {result.total} cases")
    print(f"wrote {result.results}")
    for figure in result.figures:
        print(f"wrote {figure}")
    if result.interrupted:
        print(f"interrupted: {result.done} of {result.total} cases done; run the same command again to finish", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_FAILED if result.failed else EXIT_OK


def main(argv: Sequence[str] | None = None) -> int:
    """`python -m toggle_cosim.sweep SWEEP.yaml ...` (the same as `toggle-cosim sweep`)."""
    parser = argparse.ArgumentParser(prog="toggle-cosim sweep", description=__doc__.splitlines()[0])
    parser.add_argument("sweep", type=Path)
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address (default: a local process pool)")
    parser.add_argument("--workers", type=int, default=None, help="local pool size (default: all cores)")
    parser.add_argument("--fmu", type=Path, default=None, help="plant FMU (overrides the fmu: keys)")
    parser.add_argument("--output", type=Path, default=None, help="output folder (overrides output:)")
    parser.add_argument("--retry-failed", action="store_true", help="run failed cases again")
    parser.add_argument("--case-timeout", type=float, default=None, help="wall-clock limit per case in s")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    return run_sweep(args.sweep, args.scheduler, args.workers, args.fmu, output=args.output,
                     retry_failed=args.retry_failed, progress=not args.quiet, case_timeout=args.case_timeout)


if __name__ == "__main__":
    sys.exit(main())
