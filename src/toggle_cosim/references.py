"""Stored reference traces of the shipped scenario runs, and the regression check against them.

Layout (FMI cross-check style), one folder per scenario:

    scenarios/references/tolerances.yaml              default and per-variable tolerances
    scenarios/references/<scenario>/tolerances.yaml  optional, per-scenario overrides
    scenarios/references/<scenario>/<variant>_ref.csv
    scenarios/references/<scenario>/<variant>_ref.opt

A reference keeps every `DECIMATION`-th sample of the run (every 5 ms at T_s = 0.5 ms), so the
repository stays small; the check compares the result at the same samples. References change
only through `toggle-cosim references --update`, never as a side effect of a run or a test.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.compare import (
    DEFAULT_TOLERANCE,
    ComparisonResult,
    Tolerance,
    compare_traces,
    load_tolerances,
    read_reference,
    write_reference,
)
from toggle_cosim.master import RunOutcome
from toggle_cosim.scenario import Run
from toggle_cosim.traces import Trace

DECIMATION = 10
REFERENCE_RELTOL = 1e-8  # the FMU's default solver.relTol, recorded in the .opt file


@dataclass(frozen=True)
class ReferenceCheck:
    label: str
    comparison: ComparisonResult

    @property
    def failures(self) -> list[str]:
        return [f"{self.label}: {v.name} off by {v.max_error:.3g} at t = {v.time_of_max_error:.4f} s"
                for v in self.comparison.variables if not v.passed]


def reference_stem(folder: Path, run: Run) -> Path:
    return Path(folder) / run.scenario / (run.variant or "run")


def decimate(trace: Trace) -> Trace:
    """Every DECIMATION-th sample, always keeping the last one (the cross-check StopTime)."""
    rows = list(range(0, trace.data.shape[0], DECIMATION))
    if rows[-1] != trace.data.shape[0] - 1:
        rows.append(trace.data.shape[0] - 1)
    return Trace(trace.names, trace.data[rows])


def tolerances_for(folder: Path, scenario: str) -> tuple[Tolerance, dict[str, Tolerance]]:
    """The global tolerance file, then the scenario's own entries on top of it."""
    default, per_variable = DEFAULT_TOLERANCE, {}
    common = Path(folder) / "tolerances.yaml"
    if common.is_file():
        default, per_variable = load_tolerances(common)
    own = Path(folder) / scenario / "tolerances.yaml"
    if own.is_file():
        own_default, own_variables = load_tolerances(own)
        default = own_default if own_default != DEFAULT_TOLERANCE else default
        per_variable = {**per_variable, **own_variables}
    return default, per_variable


def store(outcome: RunOutcome, folder: Path) -> Path:
    run = outcome.run
    csv_path, _ = write_reference(decimate(outcome.trace), reference_stem(folder, run), 0.0, run.t_end,
                                  run.T_s, REFERENCE_RELTOL)
    return csv_path


def check(outcome: RunOutcome, folder: Path) -> ReferenceCheck:
    """Compare a run with its stored reference (raises CompareInputError if there is none)."""
    run = outcome.run
    reference, _ = read_reference(reference_stem(folder, run))
    default, per_variable = tolerances_for(folder, run.scenario)
    comparison = compare_traces(
        decimate(outcome.trace), reference, per_variable, default,
        result_label=f"run {run.label}", reference_label=str(reference_stem(folder, run)) + "_ref.csv",
    )
    return ReferenceCheck(run.label, comparison)
