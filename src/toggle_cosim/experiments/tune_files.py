"""The files a tuning writes besides its study: the sweep files of the map (the starting
controller's and the tuned one's) and the tuned scenario (the base scenario with the fixed and
tuned keys set), each loadable by `toggle-cosim run` and `toggle-cosim sweep`."""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

from toggle_cosim.experiments.sweep_spec import get_key, read_yaml, set_key
from toggle_cosim.experiments.tune_spec import Tuning
from toggle_cosim.files.outputs import OutputKind, write_text

_MARK = "# written by toggle-cosim tune"  # the first line of every YAML file a tuning writes


def _ours(path: Path) -> bool:
    with open(path, "rb") as stream:
        return stream.read(len(_MARK)) == _MARK.encode()


# the kind of the YAML files a tuning writes: a re-run replaces them, never a file the user wrote
TUNE_YAML = OutputKind(f"a YAML file a tuning wrote (its first line '{_MARK} ...')", _ours)


def _relative(target: Path, folder: Path) -> str:
    """`target` as a path from `folder` (both made absolute), as a file written in `folder` names it."""
    return os.path.relpath(Path(target).resolve(), Path(folder).resolve())


def _dump(document: dict[str, Any], header: str) -> str:
    import yaml

    if not header.startswith(_MARK.removeprefix("# ")):  # the first line tells the file is ours (TUNE_YAML)
        header = f"{_MARK.removeprefix('# ')}\n{header}"
    lines = "".join(f"# {line}\n" for line in header.splitlines())
    return lines + yaml.safe_dump(document, sort_keys=False, allow_unicode=True, width=120)


def map_sweep(
    tuning: Tuning, folder: Path, name: str, fmu: Path | None, point: dict[str, float] | None = None
) -> dict[str, Any]:
    """A sweep file's document for the tuning's map over its base scenario: the fixed keys and the
    tuned values `point` (none: the starting controller) as one-value axes, then the map's other
    axes with their values; written in `folder` (its paths are relative to it). Its cases are the
    trial's, and a controller.python module is found beside the base scenario, as in the trials."""
    sweep = tuning.sweep
    base = sweep.base
    values = {**tuning.fixed, **(point or {})}
    # zip mode pairs the i-th values of every axis: a one-value axis repeats its value
    repeat = len(next(iter(sweep.axes.values()))) if sweep.mode == "zip" else 1
    axes: dict[str, Any] = {key: {"values": [value] * repeat} for key, value in values.items()}
    for key, spec in sweep.axes.items():
        if key not in values:
            axes[key] = {"values": list(spec)}
    document: dict[str, Any] = {"name": name, "description": f"{tuning.name}: the map of {sweep.name}"}
    document["base"] = _relative(base, folder)
    if sweep.variants != [None]:
        document["variant"] = list(sweep.variants)
    if fmu is not None:
        document["fmu"] = _relative(fmu, folder)
    document["mode"] = sweep.mode
    document["axes"] = axes
    if sweep.heatmap is not None and all(k in axes or k == "variant" for k in sweep.heatmap):
        document["heatmap"] = {"x": sweep.heatmap[0], "y": sweep.heatmap[1]}
    return document


def write_map_sweep(path: Path, document: dict[str, Any], header: str) -> Path:
    """Write a sweep file of `map_sweep` (atomically)."""
    return write_text(path, _dump(document, header), what="sweep file", kind=TUNE_YAML)


def tuned_scenario(tuning: Tuning, point: dict[str, float], folder: Path) -> dict[str, Any]:
    """The base scenario with the fixed keys and the tuned values `point` set, its paths made
    relative to `folder`: only the variants the map ran are kept; a key is set in each of them
    that sets it, and at the top level where it is set there or no variant sets it."""
    base = tuning.sweep.base
    document = copy.deepcopy(read_yaml(base, "base scenario"))
    document["name"] = tuning.name
    document["description"] = f"tuned by {tuning.path.name} over {tuning.sweep.path.name}: " + ", ".join(
        f"{k} = {v:.6g}" for k, v in point.items()
    )
    for key in ("fmu",):
        if isinstance(document.get(key), str) and not Path(document[key]).is_absolute():
            document[key] = _relative(base.parent / document[key], folder)
    for node in [document, *(document.get("variants") or {}).values()]:
        controller = node.get("controller") if isinstance(node, dict) else None
        fmu = controller.get("fmu") if isinstance(controller, dict) else None
        if isinstance(fmu, str) and not Path(fmu).is_absolute():
            controller["fmu"] = _relative(base.parent / fmu, folder)
    variants = document.get("variants") or {}
    if variants and tuning.sweep.variants != [None]:  # the map's variants only: the values were tuned for them
        document["variants"] = variants = {name: variants[name] for name in tuning.sweep.variants}
    values = {**tuning.fixed, **point}
    for key, value in values.items():
        where = [v for v in variants.values() if isinstance(v, dict) and get_key(v, key) is not None]
        if get_key(document, key) is not None or not where:
            set_key(document, key, value)
        for variant in where:  # a variant that sets the key would override the top level's value
            set_key(variant, key, value)
    return document


def write_scenario(path: Path, document: dict[str, Any], header: str) -> Path:
    """Write a scenario document (atomically)."""
    return write_text(path, _dump(document, header), what="tuned scenario", kind=TUNE_YAML)
