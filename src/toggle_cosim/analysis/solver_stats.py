"""Solver statistics of the plant FMU: read at the end of a run, stored beside a reference, compared.

Like BuildingsPy's regression tests, a reference also records how hard the plant's solver worked:
its integration steps, rejected steps and events over the run. The same trace can hide a solver
change (a tolerance, an event that is now found by iteration, a step size that collapses), and
these counts show it.

The plant FMU exposes them, where it does, as Integer (FMI 2.0) or Int64 (FMI 3.0) variables of
causality local, cumulative over the run: `STATISTICS` in plant/solver_statistics.py, which reads
them from the live FMU by name; an FMU without them is recorded as "not exposed" and nothing is
compared. This module keeps the files and the comparison.

Files: `<name>_ref_solver.json` beside `<name>_ref.csv`, `{"solver.steps": 1234, ...}`; a run's
`run.json` holds the same mapping under "solver_statistics" (or the string "not exposed").
A change is a warning; `--fail-on-solver-change` makes it a failure.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.files.bounded import JSON_LIMIT, read_text_bounded
from toggle_cosim.files.outputs import JSON, write_text

__all__ = [
    "SolverCheck",
    "compare_solver_statistics",
    "read_statistics_file",
    "statistics_path",
    "write_statistics_file",
]


def statistics_path(reference_csv: Path | str) -> Path:
    """`<name>_ref_solver.json` beside `<name>_ref.csv` (any other CSV: `<stem>_solver.json`)."""
    path = Path(reference_csv)
    return path.with_name(f"{path.stem}_solver.json")


def write_statistics_file(path: Path, counts: Mapping[str, int]) -> Path:
    write_text(path, json.dumps(dict(counts), indent=2) + "\n", "solver statistics", kind=JSON)
    return Path(path)


def read_statistics_file(path: Path | str) -> dict[str, int] | None:
    """The stored counts, or None when there is no such file; ValueError naming the file when it is malformed."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        document = json.loads(read_text_bounded(path, JSON_LIMIT, "solver statistics file"))
    except (OSError, ValueError) as error:  # InputFileError and JSONDecodeError are ValueErrors
        raise ValueError(
            f"{path}: unreadable solver statistics ({error}); rewrite it with "
            "`toggle-cosim references --update` or delete it"
        ) from error
    if not isinstance(document, dict) or not all(
        isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool) for k, v in document.items()
    ):
        raise ValueError(
            f"{path}: solver statistics must be a mapping of names to integers; rewrite it with "
            "`toggle-cosim references --update` or delete it"
        )
    return document


@dataclass(frozen=True)
class SolverCheck:
    """Result of comparing a run's solver statistics with the stored ones.

    status: "same", "changed", or "unavailable" (one side has none: nothing compared).
    lines: one human-readable line per changed count, or why nothing was compared.
    """

    status: str
    lines: tuple[str, ...]

    @property
    def changed(self) -> bool:
        return self.status == "changed"


def compare_solver_statistics(
    reference: Mapping[str, int] | str | None, result: Mapping[str, int] | str | None
) -> SolverCheck:
    """Compare counts exactly: the plant is deterministic, so any difference is a solver change."""
    if not isinstance(reference, Mapping) or not reference:
        return SolverCheck("unavailable", ("no solver statistics stored with the reference",))
    if not isinstance(result, Mapping) or not result:
        return SolverCheck("unavailable", ("the result's FMU does not expose solver statistics",))
    lines = []
    for name in sorted(set(reference) | set(result)):
        before, after = reference.get(name), result.get(name)
        if before == after:
            continue
        if before is None or after is None:
            lines.append(f"{name}: {'-' if before is None else before} -> {'-' if after is None else after}")
        else:
            change = f" ({(after - before) / before:+.1%})" if before else ""
            lines.append(f"{name}: {before} -> {after}{change}")
    return SolverCheck("changed", tuple(lines)) if lines else SolverCheck("same", ())
