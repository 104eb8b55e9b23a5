"""Compare a result trace against a stored reference trace with a funnel (tube) in time and value.

This is the check csv-compare (FMI cross-check) and BuildingsPy (regression tests) run in CI:
around every sample of the reference a rectangle is drawn, ``±half_width`` in time and
``±half_height`` in value; the funnel is the envelope of those rectangles, built by the funnel
library of LBNL through `pyfunnel.compareAndReport`. A result sample outside the funnel has the
error ``max(0, y - upper) - min(0, y - lower)`` (the distance to the funnel, in the variable's
units); a variable passes when that error is 0 at every check point: the result's own samples,
or, when the result is sampled more densely than the reference, the reference's sample times
(`toggle_cosim.analysis.sampling`), so the verdict does not depend on how either was sampled.

Tolerances (per variable, `Tolerance`):

* value: ``half_height = max(atol, rtol * (max - min of the reference variable))`` -- the range
  relative tolerance of csv-compare, with an absolute floor for variables that are constant in
  the reference (range 0);
* time: ``half_width = ttol * (StopTime - StartTime)`` of the reference -- **relative to the time
  span**, so one tolerance file fits a 1.5 s stroke and a 60 s endurance run alike.

Defaults (`DEFAULT_TOLERANCE`): ``rtol = 2e-3`` is csv-compare's tolerance as the FMI cross-check
importers report it (ToleranceY = 2e-3 of the range); ``ttol = 1e-3`` of the span (1.5 ms for a
1.5 s run, three controller samples at T_s = 0.5 ms: a switching event that moves by a sample or
two passes, a lag does not); ``atol = 1e-9`` only keeps a constant variable from having a
zero-height tube while staying far below anything physical in m, A, N or V (csv-compare uses a
2e-15 minimum tube, which rounding in another build can exceed).

Files: traces are CSV in the FMI cross-check layout (header of quoted names, "time" first, one
row per sample, time strictly increasing; `toggle_cosim.analysis.csv_traces`) or Modelica MAT v4
result files (`analysis.trace_formats`); a stored reference is ``<name>_ref.csv`` plus the
cross-check options file ``<name>_ref.opt`` (``StartTime, StopTime, StepSize, RelTol`` lines;
`analysis.reference_files`). Every problem with an input raises `CompareInputError` whose message is one line naming the file,
the problem and the fix; `compare_command.run_compare` turns it into ``error: ...`` on stderr and exit status 2.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import math
import os
import re
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.analysis.csv_traces import CompareInputError, check_finite, check_trace, float_or_none
from toggle_cosim.analysis.sampling import RESULT_GRID, SpanMismatch, check_points, reference_range
from toggle_cosim.files.outputs import CSV, PNG, replacing, write_file
from toggle_cosim.files.traces import Trace, write_csv
from toggle_cosim.messages import schema_text

__all__ = [
    "DEFAULT_TOLERANCE",
    "ComparisonResult",
    "Envelope",
    "Tolerance",
    "VariableResult",
    "compare_traces",
    "format_table",
    "load_tolerances",
    "write_report",
]


# ----------------------------------------------------------------------------- tolerances


@dataclass(frozen=True)
class Tolerance:
    """Funnel size for one variable.

    atol: absolute value tolerance, in the variable's units.
    rtol: value tolerance relative to the variable's range (max - min) in the reference.
    ttol: time tolerance relative to the reference's time span (StopTime - StartTime).
    The tube half-height is max(atol, rtol * range); its half-width is ttol * span.
    """

    atol: float
    rtol: float
    ttol: float

    def __post_init__(self) -> None:
        for name in ("atol", "rtol", "ttol"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"Tolerance.{name} must be a finite number >= 0, not {value!r}")
        for name in ("rtol", "ttol"):
            if getattr(self, name) > 1:
                raise ValueError(f"Tolerance.{name} is relative and must be <= 1, not {getattr(self, name)!r}")

    def half_height(self, reference_values: np.ndarray) -> float:
        span = float(np.max(reference_values) - np.min(reference_values))
        return max(float(self.atol), float(self.rtol) * span)

    def half_width(self, reference_time: np.ndarray) -> float:
        return float(self.ttol) * float(reference_time[-1] - reference_time[0])


DEFAULT_TOLERANCE = Tolerance(atol=1e-9, rtol=2e-3, ttol=1e-3)


# ----------------------------------------------------------------------------- results


@dataclass(frozen=True)
class Envelope:
    """The funnel of one variable: its edges as the funnel library built them, and at the result's samples."""

    lower_time: np.ndarray
    lower: np.ndarray
    upper_time: np.ndarray
    upper: np.ndarray
    time: np.ndarray  # the check points (toggle_cosim.analysis.sampling)
    result: np.ndarray
    lower_at_result: np.ndarray
    upper_at_result: np.ndarray
    error: np.ndarray  # distance of each result sample to the funnel (0 inside), from the funnel library


@dataclass(frozen=True)
class VariableResult:
    name: str
    passed: bool
    max_error: float  # largest distance of a result sample outside the funnel, 0 if all inside
    time_of_max_error: float | None  # first time the largest error occurs; None when it is 0
    tolerance: Tolerance
    half_height: float  # tube half-height in value, in the variable's units
    half_width: float  # tube half-width in time, s
    envelope: Envelope | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class ComparisonResult:
    variables: tuple[VariableResult, ...]
    passed: bool
    grid: str = RESULT_GRID  # where the funnel was checked (toggle_cosim.analysis.sampling)

    @property
    def failed(self) -> tuple[str, ...]:
        return tuple(v.name for v in self.variables if not v.passed)

    def __getitem__(self, name: str) -> VariableResult:
        for variable in self.variables:
            if variable.name == name:
                return variable
        raise KeyError(name)


# ----------------------------------------------------------------------------- the comparison


def _funnel(
    t_ref: np.ndarray,
    y_ref: np.ndarray,
    t_res: np.ndarray,
    y_res: np.ndarray,
    half_width: float,
    half_height: float,
    workdir: str,
    name: str,
) -> Envelope:
    import pyfunnel

    log = io.StringIO()
    with contextlib.redirect_stdout(log):  # pyfunnel prints its warnings
        status = pyfunnel.compareAndReport(
            xReference=t_ref.tolist(),
            yReference=y_ref.tolist(),
            xTest=t_res.tolist(),
            yTest=y_res.tolist(),
            outputDirectory=workdir,
            atolx=half_width,
            atoly=half_height,
            ltolx=0.0,
            ltoly=0.0,
            rtolx=0.0,
            rtoly=0.0,
        )
    if status != 0:
        detail = " ".join(log.getvalue().split()) or f"status {status}"
        raise CompareInputError(f"variable {name!r}: the funnel library could not compare it ({detail})")

    def load(file: str) -> tuple[np.ndarray, np.ndarray]:
        table = np.loadtxt(os.path.join(workdir, file), delimiter=",", skiprows=1, ndmin=2)
        return table[:, 0], table[:, 1]

    lower_t, lower = load("lowerBound.csv")
    upper_t, upper = load("upperBound.csv")
    error_t, error = load("errors.csv")
    if error.shape != y_res.shape:  # one error per result sample, at the result's times
        raise CompareInputError(
            f"variable {name!r}: the funnel library returned {error.size} errors for {y_res.size} samples"
        )
    return Envelope(
        lower_time=lower_t,
        lower=lower,
        upper_time=upper_t,
        upper=upper,
        time=t_res.copy(),
        result=y_res.copy(),
        lower_at_result=np.interp(t_res, lower_t, lower),
        upper_at_result=np.interp(t_res, upper_t, upper),
        error=error,
    )


def _between_samples(
    envelope: Envelope, low: np.ndarray, high: np.ndarray, ref_low: np.ndarray, ref_high: np.ndarray, half_height: float
) -> Envelope:
    """Widen the check where a check point falls between two samples of a trace (see
    toggle_cosim.analysis.sampling): the result counts with every value between its neighbouring
    samples, the funnel also holds the reference's neighbouring values ± the value tube."""
    widened = (low != high) | np.isfinite(ref_low)
    if not np.any(widened):
        return envelope
    lower = np.where(
        np.isfinite(ref_low), np.minimum(envelope.lower_at_result, ref_low - half_height), envelope.lower_at_result
    )
    upper = np.where(
        np.isfinite(ref_high), np.maximum(envelope.upper_at_result, ref_high + half_height), envelope.upper_at_result
    )
    error = np.maximum(0.0, np.maximum(low - upper, lower - high))
    return dataclasses.replace(
        envelope, lower_at_result=lower, upper_at_result=upper, error=np.where(widened, error, envelope.error)
    )


def compare_traces(
    result: Trace,
    reference: Trace,
    tolerances: Mapping[str, Tolerance],
    default: Tolerance,
    variables: Sequence[str] | None = None,
    *,
    result_label: str = "result",
    reference_label: str = "reference",
    tolerances_label: str = "tolerances",
) -> ComparisonResult:
    """Funnel-compare `result` against `reference`, variable by variable.

    variables: the names to compare (default: every column of the reference but time). A name
    of `tolerances` that the reference lacks is an error (a typo would silently fall back to the
    default). The labels name the inputs in error messages (run_compare passes the file paths).
    """
    check_trace(reference, reference_label)
    check_trace(result, result_label)
    if variables is None:
        selected = [name for name in reference.names[1:]]
    else:
        selected = list(dict.fromkeys(variables))
        unknown = [name for name in selected if name == "time" or name not in reference.names]
        if unknown:
            raise CompareInputError(f"{reference_label}: has no variable {', '.join(map(repr, unknown))} to compare")
    if not selected:
        raise CompareInputError(f'{reference_label}: has no variables besides "time"; nothing to compare')
    missing = [name for name in selected if name not in result.names]
    if missing:
        shown = ", ".join(missing[:8]) + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
        raise CompareInputError(
            f"{result_label}: lacks {len(missing)} variable(s) of the reference: {shown}; write them to the result"
        )
    check_finite(reference, selected, reference_label)
    check_finite(result, selected, result_label)
    strangers = [name for name in tolerances if name not in reference.names[1:]]
    if strangers:
        raise CompareInputError(
            f"{tolerances_label}: key {strangers[0]!r} is not a variable of the reference {reference_label}; "
            "fix the name or remove the entry"
        )

    t_ref = np.asarray(reference.time, dtype=float)
    chosen = {name: tolerances.get(name, default) for name in selected}
    sizes = {
        name: (
            chosen[name].half_height(np.asarray(reference.column(name), dtype=float)),
            chosen[name].half_width(t_ref),
        )
        for name in selected
    }
    try:
        points = check_points(
            np.asarray(result.time, dtype=float),
            np.column_stack([result.column(name) for name in selected]),
            t_ref,
            min(width for _, width in sizes.values()),
        )
    except SpanMismatch as error:
        raise CompareInputError(
            f"{result_label}: time {error.word} at {error.result_time:.17g} s but the reference {reference_label} "
            f"{error.word} at {error.reference_time:.17g} s, more than the time tolerance "
            f"({error.tolerance:.3g} s) apart; rerun over the reference's time span"
        ) from None
    outcomes = []
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-funnel-") as workdir:
        for column, name in enumerate(selected):
            tolerance = chosen[name]
            y_ref = np.asarray(reference.column(name), dtype=float)
            half_height, half_width = sizes[name]
            envelope = _funnel(
                t_ref, y_ref, points.time, points.values[:, column], half_width, half_height, workdir, name
            )
            envelope = _between_samples(
                envelope,
                points.low[:, column],
                points.high[:, column],
                *reference_range(points.time, t_ref, y_ref),
                half_height,
            )
            worst = int(np.argmax(envelope.error))
            max_error = float(envelope.error[worst])
            outcomes.append(
                VariableResult(
                    name=name,
                    passed=max_error <= 0.0,
                    max_error=max(max_error, 0.0),
                    time_of_max_error=float(envelope.time[worst]) if max_error > 0 else None,
                    tolerance=tolerance,
                    half_height=half_height,
                    half_width=half_width,
                    envelope=envelope,
                )
            )
    return ComparisonResult(variables=tuple(outcomes), passed=all(v.passed for v in outcomes), grid=points.grid)


# ----------------------------------------------------------------------------- terminal table


def format_table(result: ComparisonResult) -> str:
    """One line per variable: name, max error, time of the max error, PASS/FAIL; a header and a total line."""
    width = max([len("variable"), *(len(v.name) for v in result.variables)])
    lines = [f"{'variable':<{width}}  {'max error':>10}  {'at t [s]':>12}  result"]
    for v in result.variables:
        when = "-" if v.time_of_max_error is None else f"{v.time_of_max_error:.6g}"
        lines.append(f"{v.name:<{width}}  {v.max_error:>10.3e}  {when:>12}  {'PASS' if v.passed else 'FAIL'}")
    failed = len(result.failed)
    lines.append(f"{len(result.variables)} variables: {len(result.variables) - failed} passed, {failed} failed")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- report files


def _file_stem(name: str, taken: set[str]) -> str:
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "variable"
    candidate, number = stem, 2
    while candidate.lower() in taken:
        candidate, number = f"{stem}_{number}", number + 1
    taken.add(candidate.lower())
    return candidate


def draw_outside_points(ax: Any, envelope: Any, label: str) -> None:
    """Mark on a matplotlib axis the samples of a compared variable that lie outside its funnel."""
    outside = envelope.error > 0
    ax.plot(envelope.time[outside], envelope.result[outside], "o", color="C3", markersize=2.5, label=label)


def draw_funnel_band(ax: Any, variable: VariableResult, color: str, alpha: float) -> None:
    """Shade a compared variable's funnel on a matplotlib axis: the band between its lower and
    upper envelopes on their common time grid, labelled with the funnel's half-height and width."""
    envelope = variable.envelope
    assert envelope is not None
    grid = np.union1d(envelope.lower_time, envelope.upper_time)
    ax.fill_between(
        grid,
        np.interp(grid, envelope.lower_time, envelope.lower),
        np.interp(grid, envelope.upper_time, envelope.upper),
        color=color,
        alpha=alpha,
        linewidth=0,
        label=f"funnel (±{variable.half_height:.3g}, ±{variable.half_width:.3g} s)",
    )


def _plot(variable: VariableResult, reference: Trace, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    envelope = variable.envelope
    assert envelope is not None
    figure = Figure(figsize=(10, 6.5), layout="constrained")
    FigureCanvasAgg(figure)
    top, bottom = figure.subplots(2, 1, sharex=True, height_ratios=(3, 1.4))
    draw_funnel_band(top, variable, "C0", 0.18)
    top.plot(envelope.lower_time, envelope.lower, color="C0", linewidth=0.6)
    top.plot(envelope.upper_time, envelope.upper, color="C0", linewidth=0.6)
    top.plot(reference.time, reference.column(variable.name), color="k", linewidth=1.0, label="reference")
    top.plot(envelope.time, envelope.result, color="C3", linewidth=1.0, linestyle="--", label="result")
    draw_outside_points(top, envelope, "result outside the funnel")
    top.set_ylabel(variable.name)
    top.grid(True, alpha=0.3)
    top.legend(fontsize=8, loc="best")
    bottom.plot(envelope.time, envelope.error, color="C3", linewidth=1.0)
    if variable.time_of_max_error is not None:
        bottom.plot([variable.time_of_max_error], [variable.max_error], "v", color="k", markersize=6)
    bottom.set_ylabel("error")
    bottom.set_xlabel("time [s]")
    bottom.grid(True, alpha=0.3)
    when = "-" if variable.time_of_max_error is None else f"{variable.time_of_max_error:.6g} s"
    figure.suptitle(f"{variable.name}: FAIL, max error {variable.max_error:.3e} at t = {when}")
    with replacing(path, "figure", kind=PNG) as temporary:
        figure.savefig(temporary, format="png", dpi=100)


def write_report(
    result: ComparisonResult, out_dir: Path | str, result_trace: Trace, reference_trace: Trace
) -> list[Path]:
    """Write the comparison to `out_dir`; return the files written.

    summary.csv: one row per variable (pass/fail, max error and its time, tube size, tolerances).
    For each FAILING variable: <name>_funnel.csv (time, result, reference interpolated at the
    result's times, lower and upper funnel edges at those times, error) and <name>_funnel.png
    (reference, funnel, result; error below). Every file is written under a temporary name and
    renamed into place.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def summary(stream: Any) -> None:
        writer = csv.writer(stream, lineterminator="\n")
        writer.writerow(
            [
                "variable",
                "passed",
                "max_error",
                "time_of_max_error",
                "half_height",
                "half_width",
                "atol",
                "rtol",
                "ttol",
            ]
        )
        for v in result.variables:
            writer.writerow(
                [
                    v.name,
                    int(v.passed),
                    repr(v.max_error),
                    "" if v.time_of_max_error is None else repr(v.time_of_max_error),
                    repr(v.half_height),
                    repr(v.half_width),
                    repr(v.tolerance.atol),
                    repr(v.tolerance.rtol),
                    repr(v.tolerance.ttol),
                ]
            )

    write_file(out / "summary.csv", summary, kind=CSV)
    written.append(out / "summary.csv")
    taken: set[str] = {"summary"}
    for v in result.variables:
        if v.passed:
            continue
        envelope = v.envelope
        if envelope is None:
            raise ValueError(f"{v.name}: the comparison kept no envelope; compare with compare_traces")
        stem = _file_stem(v.name, taken)
        reference_at = np.interp(envelope.time, reference_trace.time, reference_trace.column(v.name))
        table = Trace(
            ("time", "result", "reference", "lower", "upper", "error"),
            np.column_stack(
                [
                    envelope.time,
                    envelope.result,
                    reference_at,
                    envelope.lower_at_result,
                    envelope.upper_at_result,
                    envelope.error,
                ]
            ),
        )
        write_csv(out / f"{stem}_funnel.csv", table)
        _plot(v, reference_trace, out / f"{stem}_funnel.png")
        written += [out / f"{stem}_funnel.csv", out / f"{stem}_funnel.png"]
    return written


# ----------------------------------------------------------------------------- tolerance files

_ENTRY_SCHEMA = {
    "type": "object",
    "properties": {
        "atol": {"type": "number", "minimum": 0},
        "rtol": {"type": "number", "minimum": 0, "maximum": 1},
        "ttol": {"type": "number", "minimum": 0, "maximum": 1},
    },
    "additionalProperties": False,
}
TOLERANCE_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "toggle-cosim compare tolerances: {variable: {atol, rtol, ttol}}, optional default entry",
    "type": "object",
    "propertyNames": {"minLength": 1},
    "additionalProperties": _ENTRY_SCHEMA,
}
_FIX = "each entry is a mapping of atol (>= 0), rtol and ttol (0 to 1)"


def _coerce_numbers(document: Any) -> Any:
    """PyYAML reads `1e-3` (no dot) as a string; take such strings as the numbers they spell."""
    if not isinstance(document, dict):
        return document
    coerced = {}
    for key, entry in document.items():
        if isinstance(entry, dict):
            entry = {
                k: (float(v) if isinstance(v, str) and float_or_none(v) is not None and math.isfinite(float(v)) else v)
                for k, v in entry.items()
            }
        coerced[key] = entry
    return coerced


def load_tolerances(path: Path | str) -> tuple[Tolerance, dict[str, Tolerance]]:
    """Read a YAML tolerance file: ``{variable: {atol:, rtol:, ttol:}}`` with an optional ``default:`` entry.

    Keys left out of an entry come from the `default` entry, and those left out of `default`
    from DEFAULT_TOLERANCE. Returns (default, {variable: tolerance}).
    """
    import jsonschema

    from toggle_cosim.files.bounded import file_problem
    from toggle_cosim.files.yaml_loader import YamlError, load_yaml

    path = Path(path)
    problem = file_problem(path)  # a link to /dev/zero, a loop, a folder: bad input, never skipped
    if problem:
        raise CompareInputError(f"{path}: {problem}; give the YAML tolerance file")
    try:
        document = load_yaml(path, "tolerance file")  # one hardened loader for every YAML file
    except YamlError as error:
        raise CompareInputError(f"{error} (it is not valid YAML for a tolerance file); fix the syntax") from error
    if document is None:
        raise CompareInputError(
            f"{path}: is empty; write {{variable: {{atol:, rtol:, ttol:}}}} entries or drop the option"
        )
    if not isinstance(document, dict):
        raise CompareInputError(
            f"{path}: must be a mapping of variable names to tolerances, not a {type(document).__name__}"
        )
    for key in document:
        if not isinstance(key, str):
            raise CompareInputError(f"{path}: key {key!r} is not a variable name; quote it")
    document = _coerce_numbers(document)
    for key, entry in document.items():  # NaN and infinities pass a schema's number bounds
        for name, value in entry.items() if isinstance(entry, dict) else ():
            if isinstance(value, float) and not math.isfinite(value):
                raise CompareInputError(f"{path}: key '{key}.{name}': {value!r} is not a finite number; {_FIX}")
    validator = jsonschema.Draft202012Validator(TOLERANCE_SCHEMA)
    error = jsonschema.exceptions.best_match(validator.iter_errors(document))
    if error is not None:
        key = ".".join(str(part) for part in error.absolute_path) or "(top level)"
        raise CompareInputError(f"{path}: key {key!r}: {schema_text(error.message, error.instance)}; {_FIX}")

    base = {"atol": DEFAULT_TOLERANCE.atol, "rtol": DEFAULT_TOLERANCE.rtol, "ttol": DEFAULT_TOLERANCE.ttol}
    base.update(document.get("default", {}))
    default = Tolerance(**base)
    per_variable = {name: Tolerance(**{**base, **entry}) for name, entry in document.items() if name != "default"}
    return default, per_variable
