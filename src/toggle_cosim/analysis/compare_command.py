"""`toggle-cosim compare`: read two traces, find their tolerances, compare, print and report.

Exit status: 0 every variable passes, 1 any fails (or the solver statistics changed under
`--fail-on-solver-change`), 2 bad input: one line `error: ...` on stderr, no report written.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.analysis.ci_reports import CheckedTrace, write_junit, write_markdown_summary
from toggle_cosim.analysis.compare import ComparisonResult, compare_traces, format_table, write_report
from toggle_cosim.analysis.csv_traces import CompareInputError
from toggle_cosim.analysis.invariants import check_invariants, invariants_path, load_invariants
from toggle_cosim.analysis.reference_files import check_span, read_options, reference_paths
from toggle_cosim.analysis.solver_stats import (
    SolverCheck,
    compare_solver_statistics,
    read_statistics_file,
    statistics_path,
)
from toggle_cosim.analysis.tolerance_files import tolerances_for_reference
from toggle_cosim.analysis.trace_formats import read_any_trace
from toggle_cosim.files.bounded import JSON_LIMIT, read_text_bounded
from toggle_cosim.files.outputs import JUNIT, MARKDOWN, OutputError, OutputKind, check_destination
from toggle_cosim.files.traces import Trace

__all__ = ["FileComparison", "compare_with_file", "plots_of", "run_compare", "solver_check", "trace_label"]


def trace_label(reference_path: Path) -> str:
    """`<folder>/<name>` of a reference `<folder>/<name>_ref.csv` (the run it stands for)."""
    stem = reference_path.stem.removesuffix("_ref")
    return f"{reference_path.resolve().parent.name}/{stem}"


def plots_of(comparison: ComparisonResult, written: list[Path]) -> dict[str, Path]:
    """{failing variable: its PNG} from the files `write_report` wrote (in the variables' order)."""
    pngs = [path for path in written if path.suffix == ".png"]
    return dict(zip(comparison.failed, pngs, strict=True))


def _result_statistics(result_path: Path) -> dict[str, int] | str | None:
    """The solver statistics in run.json beside a result trace, None when there is no run.json."""
    record = result_path.with_name("run.json")
    if not record.is_file():
        return None
    try:
        return json.loads(read_text_bounded(record, JSON_LIMIT, "run record")).get("solver_statistics")
    except (OSError, ValueError, AttributeError) as error:  # InputFileError is a ValueError
        raise CompareInputError(f"{record}: is not a readable run record ({error}); rerun or remove it") from error


def _check_output(path: Path | None, what: str, kind: OutputKind) -> None:
    if path is None:
        return
    try:
        check_destination(path, what, kind)
    except OutputError as error:
        raise CompareInputError(str(error)) from error


@dataclass(frozen=True)
class FileComparison:
    """A trace compared with a reference file: the verdict per variable, the tolerance files
    that applied (by place, or the one given) and the reference as read."""

    comparison: ComparisonResult
    tolerance_files: list[Path]
    reference: Trace


def compare_with_file(
    result: Trace, reference_path: Path | str, tolerance_path: Path | str | None = None, result_label: str = "result"
) -> FileComparison:
    """Compare `result` with the reference trace file `reference_path` as `toggle-cosim compare`
    does: its tolerance files by place (or `tolerance_path`), and for a `<name>_ref.csv` with its
    `<name>_ref.opt` beside it, the span check of both traces. Raises CompareInputError."""
    reference_path = Path(reference_path)
    reference = read_any_trace(reference_path)
    options = _reference_options(reference, reference_path)
    return _compared(reference, options, result, reference_path, tolerance_path, result_label)


def _reference_options(reference: Trace, reference_path: Path) -> dict[str, float | str] | None:
    """The options file of a `<name>_ref.csv` (None for another trace), the reference's span checked against it."""
    _, opt_path = reference_paths(reference_path)
    if not (reference_path.name.endswith("_ref.csv") and opt_path.exists()):
        return None
    options = read_options(opt_path)
    check_span(reference, options, str(reference_path), opt_path)
    return options


def _compared(
    reference: Trace,
    options: dict[str, float | str] | None,
    result: Trace,
    reference_path: Path,
    tolerance_path: Path | str | None,
    result_label: str,
) -> FileComparison:
    default, tolerances, files = tolerances_for_reference(reference_path, tolerance_path)
    if options is not None:
        span = float(options["StopTime"]) - float(options["StartTime"])
        slack = min(tolerances.get(name, default).ttol for name in reference.names[1:]) * span
        check_span(result, options, result_label, reference_paths(reference_path)[1], slack)
    comparison = compare_traces(
        result,
        reference,
        tolerances,
        default,
        result_label=result_label,
        reference_label=str(reference_path),
        tolerances_label=str(files[-1]) if files else "tolerances",
    )
    return FileComparison(comparison, files, reference)


def solver_check(reference_path: Path | str, current: dict[str, int] | str | None) -> SolverCheck | None:
    """The solver statistics stored beside a reference against a result's (`current`, from its
    run record); None when neither has any."""
    stored = read_statistics_file(statistics_path(Path(reference_path)))
    if stored is not None or isinstance(current, dict):
        return compare_solver_statistics(stored, current)
    return None


def run_compare(
    result_path: Path | str,
    reference_path: Path | str,
    tolerance_path: Path | str | None = None,
    out_dir: Path | str | None = None,
    *,
    junit: Path | str | None = None,
    summary: Path | str | None = None,
    fail_on_solver_change: bool = False,
) -> int:
    """`toggle-cosim compare RESULT REFERENCE [--tolerances FILE] [--out DIR] [--junit XML] [--summary MD]`.

    Traces are CSV (FMI cross-check / FMPy) or Modelica MAT v4 result files. Without
    `tolerance_path` the tolerance files lying beside the reference apply
    (`toggle_cosim.analysis.tolerance_files`). When REFERENCE is `<name>_ref.csv` with
    `<name>_ref.opt` beside it, the result must run from its StartTime to its StopTime, within the
    time tolerance. With `out_dir`, the envelopes and a PNG of each failing variable are written
    there; `junit` and `summary` write the CI reports.
    """
    try:
        reference_path, result_path = Path(reference_path), Path(result_path)
        if out_dir is not None and Path(out_dir).exists() and not Path(out_dir).is_dir():
            raise CompareInputError(f"{out_dir}: exists and is not a directory; give a folder for the report")
        _check_output(None if junit is None else Path(junit), "JUnit report", JUNIT)
        _check_output(None if summary is None else Path(summary), "Markdown summary", MARKDOWN)
        reference = read_any_trace(reference_path)
        options = _reference_options(reference, reference_path)
        result = read_any_trace(result_path)
        checked = _compared(reference, options, result, reference_path, tolerance_path, str(result_path))
        comparison, files = checked.comparison, checked.tolerance_files
        solver = solver_check(reference_path, _result_statistics(result_path))
        step = float(options["StepSize"]) if options is not None else 0.0  # the invariants' sampling
        step = step if step > 0 else None  # no options file, or a variable step: not known
        invariants = check_invariants(result, load_invariants(invariants_path(reference_path)), step)
    except (CompareInputError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(format_table(comparison))
    print(
        f"checked at the {comparison.grid}; tolerances: "
        + (", ".join(str(path) for path in files) if files else "built-in defaults")
    )
    if solver is not None:
        word = "FAIL" if fail_on_solver_change and solver.changed else "warning" if solver.changed else "note"
        for line in solver.lines or ("solver statistics unchanged",):
            print(f"{word if solver.lines else 'solver'}: {line}")
    for invariant in invariants:
        print(f"invariant {invariant.line}")
    check = CheckedTrace(
        trace_label(reference_path),
        comparison,
        solver=solver,
        solver_fails=fail_on_solver_change,
        invariants=invariants,
    )
    try:
        if out_dir is not None:
            written = write_report(comparison, Path(out_dir), result, reference)
            plots = plots_of(comparison, written)
            check = CheckedTrace(check.label, comparison, plots, solver, fail_on_solver_change, invariants)
            print(f"report: {len(written)} files in {out_dir}")
        if junit is not None:
            print(f"junit: {write_junit([check], junit)}")
        if summary is not None:
            print(f"summary: {write_markdown_summary([check], summary)}")
    except OutputError as error:  # one line naming the path already
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(
            f"error: {error.filename or out_dir}: cannot write the report ({error.strerror or error}); "
            "check the folder",
            file=sys.stderr,
        )
        return 2
    return 0 if check.passed else 1
