"""`compare`: a result against a reference with the funnel of `toggle-cosim compare`.

    check = tc.compare(result, tc.stored_reference(result.run))
    assert check, check          # passes when every variable lies inside its funnel
    check.to_dataframe()         # per variable: passed, max deviation, tolerance, unit

Around every reference sample a rectangle ±half_width in time by ±half_height in value is drawn
(`analysis.compare`: half_height = max(atol, rtol x the reference's range), half_width = ttol x
its time span); a variable passes when every result sample lies inside their envelope.
A reference file gets the tolerance files that lie beside it (`scenarios/references/
tolerances.yaml`, then the scenario's own), as on the command line; an in-memory reference gets
the built-in defaults unless a tolerance file is given.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from toggle_cosim.analysis.compare import ComparisonResult, VariableResult, compare_traces, format_table
from toggle_cosim.analysis.compare_command import compare_with_file, solver_check
from toggle_cosim.analysis.csv_traces import CompareInputError
from toggle_cosim.analysis.solver_stats import SolverCheck, compare_solver_statistics
from toggle_cosim.analysis.tolerance_files import merged_tolerances
from toggle_cosim.api.result import Result
from toggle_cosim.files.traces import Trace

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["CompareInputError", "Comparison", "compare"]

TraceLike = Result | Trace | str | Path


@dataclass(frozen=True)
class Comparison:
    """The verdict of a funnel comparison; true (in `assert`, `if`) when every variable passed.

    Attributes:
        funnel: the per-variable verdicts (`analysis.compare.ComparisonResult`: passed, the
            largest distance outside the funnel and when, the tube's half-height and half-width).
        max_deviation: per variable, the largest |result − reference| at the reference's
            samples (the result interpolated linearly there), in the variable's unit.
        units: {variable: unit} where the result knew them.
        solver: the plant solver's counts against those stored with the reference (None when
            neither has any); a change is reported, not a failure.
        tolerance_files: the tolerance files that applied (none: the built-in defaults).

    Example:
        ```python
        check = tc.compare(result, tc.stored_reference(result.run))
        assert check, check.failed             # the variables outside their funnel, if any
        check.to_dataframe()                   # passed, max_deviation, tolerance, outside, at_time, unit
        check["x_B"].passed                    # one variable's verdict
        ```
    """

    funnel: ComparisonResult
    max_deviation: Mapping[str, float]
    units: Mapping[str, str]
    solver: SolverCheck | None
    tolerance_files: tuple[Path, ...]

    @property
    def passed(self) -> bool:
        return self.funnel.passed

    def __bool__(self) -> bool:
        return self.passed

    @property
    def failed(self) -> tuple[str, ...]:
        """The variables outside their funnel."""
        return self.funnel.failed

    def __getitem__(self, name: str) -> VariableResult:
        return self.funnel[name]

    def __str__(self) -> str:
        return f"{format_table(self.funnel)}\nchecked at the {self.funnel.grid}"

    def to_dataframe(self) -> pd.DataFrame:
        """One row per variable: passed, max_deviation, tolerance (the tube's half-height),
        outside (the largest distance outside the funnel, 0 when inside), at_time [s] (when),
        unit."""
        import pandas as pd

        rows = [
            {
                "variable": v.name,
                "passed": v.passed,
                "max_deviation": self.max_deviation[v.name],
                "tolerance": v.half_height,
                "outside": v.max_error,
                "at_time": v.time_of_max_error,
                "unit": self.units.get(v.name, ""),
            }
            for v in self.funnel.variables
        ]
        return pd.DataFrame(rows).set_index("variable")


def _trace(value: TraceLike, what: str) -> Trace:
    if isinstance(value, Result):
        return value.trace
    if isinstance(value, Trace):
        return value
    if isinstance(value, (str, Path)):
        from toggle_cosim.analysis.trace_formats import read_any_trace

        return read_any_trace(Path(value))
    raise TypeError(f"{what}: give a Result, a Trace or a trace file's path, not {type(value).__name__}")


def _label(value: TraceLike, what: str) -> str:
    if isinstance(value, Result):
        return f"run {value.label}"
    return str(value) if isinstance(value, (str, Path)) else what


def _deviations(result: Trace, reference: Trace, names: list[str]) -> dict[str, float]:
    """max |result − reference| at the reference's samples inside the result's time span."""
    t_ref = reference.time
    inside = (t_ref >= result.time[0]) & (t_ref <= result.time[-1])
    found = {}
    for name in names:
        interpolated = np.interp(t_ref[inside], result.time, result.column(name))
        found[name] = float(np.max(np.abs(interpolated - reference.column(name)[inside]), initial=0.0))
    return found


def _statistics(value: TraceLike) -> dict[str, int] | str | None:
    return value.record.get("solver_statistics") if isinstance(value, Result) else None


def compare(result: TraceLike, reference: TraceLike, *, tolerances: str | Path | None = None) -> Comparison:
    """Funnel-compare `result` with `reference`, variable by variable (every variable of the
    reference but time), as `toggle-cosim compare` does.

    Args:
        result: a `Result`, a `Trace`, or a trace file (CSV, or a Modelica .mat result).
        reference: the same kinds; a stored reference `<name>_ref.csv` (`tc.stored_reference(run)`)
            brings its options file's time span check and the tolerance files beside it.
        tolerances: a tolerance file (YAML: `default:` and per-variable atol, rtol, ttol) that
            replaces the ones found by place.

    Returns:
        The `Comparison`: true when every variable lies inside its funnel.

    Raises:
        CompareInputError: one line naming the input and the problem (a missing file, a variable
            the result lacks, time spans that do not match).

    Example:
        ```python
        result = tc.simulate(tc.load_scenario("scenarios/fig4_nominal.yaml")["friction"], tc.plant_fmu())
        check = tc.compare(result, tc.stored_reference(result.run))
        loose = tc.compare("out/fig4_nominal/friction/trace.csv", "my_ref.csv", tolerances="tolerances.yaml")
        ```
    """
    result_trace = _trace(result, "result")
    label = _label(result, "result")
    if isinstance(reference, (str, Path)):
        checked = compare_with_file(result_trace, reference, tolerances, label)
        funnel, files, reference_trace = checked.comparison, tuple(checked.tolerance_files), checked.reference
        solver = solver_check(reference, _statistics(result))
    else:
        reference_trace = _trace(reference, "reference")
        files = (Path(tolerances),) if tolerances is not None else ()
        default, per_variable = merged_tolerances(list(files))
        funnel = compare_traces(
            result_trace,
            reference_trace,
            per_variable,
            default,
            result_label=label,
            reference_label=_label(reference, "reference"),
            tolerances_label=str(tolerances) if tolerances is not None else "tolerances",
        )
        stored, current = _statistics(reference), _statistics(result)
        both = isinstance(reference, Result) and isinstance(result, Result)
        solver = compare_solver_statistics(stored, current) if both else None
    units = result.units if isinstance(result, Result) else reference.units if isinstance(reference, Result) else {}
    names = [v.name for v in funnel.variables]
    return Comparison(
        funnel, _deviations(result_trace, reference_trace, names), dict(units), solver, tuple(Path(f) for f in files)
    )
