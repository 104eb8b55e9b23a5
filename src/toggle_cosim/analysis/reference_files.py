"""Stored references in the FMI cross-check layout: `<name>_ref.csv` and the options file
`<name>_ref.opt` (``StartTime, StopTime, StepSize, RelTol`` lines, ``//`` comments)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

from toggle_cosim.analysis.csv_traces import CompareInputError, check_trace, float_or_none, read_trace
from toggle_cosim.files.outputs import SETTINGS, write_text
from toggle_cosim.files.traces import Trace, write_csv

__all__ = ["read_options", "read_reference", "write_reference"]


_REQUIRED_OPTIONS = ("StartTime", "StopTime", "StepSize", "RelTol")
_NUMERIC_OPTIONS = (*_REQUIRED_OPTIONS, "AbsTol", "OutputIntervalLength")


def reference_paths(path_stem: Path | str) -> tuple[Path, Path]:
    stem = str(path_stem)
    for suffix in ("_ref.csv", "_ref.opt"):
        if stem.endswith(suffix):
            stem = stem[: -len(suffix)]
    return Path(f"{stem}_ref.csv"), Path(f"{stem}_ref.opt")


def _time_matches(a: float, b: float, span: float) -> bool:
    return abs(a - b) <= 1e-9 * max(abs(span), abs(a), abs(b), 1e-300)


def write_reference(
    trace: Trace, path_stem: Path | str, start: float, stop: float, step: float, reltol: float
) -> tuple[Path, Path]:
    """Store `trace` as a cross-check reference: <stem>_ref.csv and <stem>_ref.opt.

    path_stem is <folder>/<name> (a trailing _ref.csv or _ref.opt is dropped). step is the step
    size in s (0 for a variable-step solver); reltol the solver's relative tolerance. The trace
    must run from `start` to `stop`, as the cross-check rules require.
    """
    check_trace(trace, "trace")
    if not (math.isfinite(start) and math.isfinite(stop) and stop > start):
        raise ValueError(f"StopTime ({stop}) must be after StartTime ({start})")
    if not (math.isfinite(step) and step >= 0 and math.isfinite(reltol) and reltol >= 0):
        raise ValueError(f"StepSize ({step}) and RelTol ({reltol}) must be finite and >= 0")
    if not (_time_matches(trace.time[0], start, stop - start) and _time_matches(trace.time[-1], stop, stop - start)):
        raise ValueError(
            f"the trace runs from {trace.time[0]} to {trace.time[-1]} s, not from StartTime {start} "
            f"to StopTime {stop} s"
        )
    csv_path, opt_path = reference_paths(path_stem)
    write_csv(csv_path, trace)
    lines = [
        f"StartTime, {float(start)!r}",
        f"StopTime, {float(stop)!r}",
        f"StepSize, {float(step)!r}",
        f"RelTol, {float(reltol)!r}",
    ]
    write_text(opt_path, "\n".join(lines) + "\n", "reference settings", kind=SETTINGS)
    return csv_path, opt_path


def read_options(path: Path | str) -> dict[str, float | str]:
    """Read a cross-check options file (``Name, value`` lines; ``//`` comments allowed)."""
    path = Path(path)
    if not path.is_file():
        raise CompareInputError(
            f"{path}: no such file; a reference needs its options file beside it "
            "(StartTime, StopTime, StepSize, RelTol)"
        )
    from toggle_cosim.files.bounded import YAML_LIMIT, InputFileError, read_text_bounded

    try:
        text = read_text_bounded(path, YAML_LIMIT, "options file", encoding="utf-8-sig")
    except InputFileError as error:
        raise CompareInputError(str(error)) from error
    options: dict[str, float | str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.split("//", 1)[0].strip()
        if not line:
            continue
        key, comma, value = (part.strip() for part in line.partition(","))
        if not comma or not key or not value:
            raise CompareInputError(f"{path}: line {number} is not 'Name, value' ({line[:40]!r}); fix or remove it")
        if key in options:
            raise CompareInputError(f"{path}: line {number}: {key} is given twice; keep one")
        if key in _NUMERIC_OPTIONS:
            number_value = float_or_none(value)
            if number_value is None or not math.isfinite(number_value):
                raise CompareInputError(f"{path}: line {number}: {key} is {value!r}, not a number; write a number")
            options[key] = number_value
        else:
            options[key] = value
    missing = [key for key in _REQUIRED_OPTIONS if key not in options]
    if missing:
        raise CompareInputError(f"{path}: lacks {', '.join(missing)}; add a '{missing[0]}, <value>' line")
    if not float(options["StopTime"]) > float(options["StartTime"]):
        raise CompareInputError(f"{path}: StopTime {options['StopTime']} is not after StartTime {options['StartTime']}")
    for key in ("StepSize", "RelTol"):
        if float(options[key]) < 0:
            raise CompareInputError(f"{path}: {key} is negative; it must be >= 0 (StepSize 0 means variable step)")
    return options


def check_span(
    trace: Trace, options: Mapping[str, float | str], label: str, opt_path: Path, slack: float = 0.0
) -> None:
    """The trace must run from StartTime to StopTime, within `slack` seconds (the time tolerance)."""
    start, stop = float(options["StartTime"]), float(options["StopTime"])
    for value, target, word in ((trace.time[0], start, "StartTime"), (trace.time[-1], stop, "StopTime")):
        if abs(float(value) - target) > slack * (1 + 1e-9) and not _time_matches(float(value), target, stop - start):
            edge = "starts" if word == "StartTime" else "ends"
            raise CompareInputError(
                f"{label}: time {edge} at {value:.17g} s but {opt_path} gives {word} {target:.17g} s; "
                "run over the reference's time span"
            )


def read_reference(path_stem: Path | str) -> tuple[Trace, dict[str, float | str]]:
    """Read <stem>_ref.csv and <stem>_ref.opt; the trace must run from StartTime to StopTime."""
    csv_path, opt_path = reference_paths(path_stem)
    trace = read_trace(csv_path)
    options = read_options(opt_path)
    check_span(trace, options, str(csv_path), opt_path)
    return trace, options
