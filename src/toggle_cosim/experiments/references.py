"""Stored reference traces of the shipped scenario runs, and the regression check against them.

Layout (FMI cross-check style), one folder per scenario:

    scenarios/references/tolerances.yaml              default and per-variable tolerances
    scenarios/references/<scenario>/tolerances.yaml  optional, per-scenario overrides
    scenarios/references/<scenario>/<variant>_ref.csv
    scenarios/references/<scenario>/<variant>_ref.opt
    scenarios/references/<scenario>/<variant>_ref_solver.json   solver statistics, where the FMU exposes them
    scenarios/references/<scenario>/<variant>_ref_invariants.yaml  optional: metrics held within a tolerance

A reference keeps every `DECIMATION`-th sample of the run (every 5 ms at T_s = 0.5 ms), so the
repository stays small; the check compares the full-resolution run with it, and the comparison
looks only at the reference's samples (`toggle_cosim.analysis.sampling`). References change
only through `toggle-cosim references --update`, never as a side effect of a run or a test.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.analysis.compare import ComparisonResult, Tolerance, compare_traces
from toggle_cosim.analysis.invariants import (
    InvariantResult,
    check_invariants,
    invariants_path,
    load_invariants,
    update_invariants,
)
from toggle_cosim.analysis.reference_files import read_reference, write_reference
from toggle_cosim.analysis.solver_stats import (
    SolverCheck,
    compare_solver_statistics,
    read_statistics_file,
    statistics_path,
    write_statistics_file,
)
from toggle_cosim.analysis.tolerance_files import TOLERANCE_FILE, merged_tolerances
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.files.traces import Trace
from toggle_cosim.runs.definition import Run

DECIMATION = 10
REFERENCE_RELTOL = 1e-8  # the FMU's default solver.relTol, recorded in the .opt file


@dataclass(frozen=True)
class ReferenceCheck:
    label: str
    comparison: ComparisonResult
    solver: SolverCheck | None = None  # None: no statistics stored with the reference and none from the run
    invariants: tuple[InvariantResult, ...] = ()  # the reference's invariants file, checked (analysis.invariants)

    @property
    def passed(self) -> bool:
        return self.comparison.passed and all(invariant.passed for invariant in self.invariants)

    @property
    def failures(self) -> list[str]:
        return [
            f"{self.label}: {v.name} off by {v.max_error:.3g} at t = {v.time_of_max_error:.4f} s"
            for v in self.comparison.variables
            if not v.passed
        ] + [f"{self.label}: invariant {i.line}" for i in self.invariants if not i.passed]

    @property
    def solver_changes(self) -> list[str]:
        changed = self.solver is not None and self.solver.changed
        return [f"{self.label}: solver statistics changed: {line}" for line in self.solver.lines] if changed else []


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
    files = [Path(folder) / TOLERANCE_FILE, Path(folder) / scenario / TOLERANCE_FILE]
    return merged_tolerances([path for path in files if path.is_file()])


def store(outcome: RunOutcome, folder: Path) -> Path:
    """Write the reference of a run: the decimated trace, its options file, and its solver
    statistics when the FMU exposes them."""
    run = outcome.run
    csv_path, _ = write_reference(
        decimate(outcome.trace), reference_stem(folder, run), 0.0, run.t_end, run.T_s, REFERENCE_RELTOL
    )
    counts = outcome.record.get("solver_statistics")
    if isinstance(counts, dict) and counts:
        write_statistics_file(statistics_path(csv_path), counts)
    update_invariants(invariants_path(csv_path), outcome.trace)  # an existing file's values, re-measured
    return csv_path


def check(outcome: RunOutcome, folder: Path) -> ReferenceCheck:
    """Compare a run with its stored reference (raises CompareInputError if there is none).

    The full-resolution trace is compared; the funnel is checked at the reference's samples.
    """
    run = outcome.run
    stem = reference_stem(folder, run)
    reference, _ = read_reference(stem)
    default, per_variable = tolerances_for(folder, run.scenario)
    comparison = compare_traces(
        outcome.trace,
        reference,
        per_variable,
        default,
        result_label=f"run {run.label}",
        reference_label=str(stem) + "_ref.csv",
    )
    stored = read_statistics_file(statistics_path(Path(str(stem) + "_ref.csv")))
    current = outcome.record.get("solver_statistics")
    solver = None
    if stored is not None or isinstance(current, dict):
        solver = compare_solver_statistics(stored, current)
    invariants = check_invariants(
        outcome.trace, load_invariants(invariants_path(Path(str(stem) + "_ref.csv"))), run.T_s
    )
    return ReferenceCheck(run.label, comparison, solver, invariants)
