"""The CI reports of `toggle-cosim references`: the same JUnit XML and Markdown summary as
`toggle-cosim compare` writes, one entry per shipped run, and a PNG of each failing variable
under `<out>/<scenario>/<variant>/`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from toggle_cosim.analysis.ci_reports import CheckedTrace, write_junit, write_markdown_summary
from toggle_cosim.analysis.compare import write_report
from toggle_cosim.analysis.compare_command import plots_of
from toggle_cosim.analysis.reference_files import read_reference
from toggle_cosim.files.traces import Trace

__all__ = ["write_reference_reports"]


def write_reference_reports(
    checks: Sequence[tuple[Any, Trace, Path]],
    out: Path,
    junit: Path,
    summary: Path,
    fail_on_solver_change: bool = False,
) -> list[Path]:
    """checks: (ReferenceCheck, the run's trace, the reference's path stem) per run. Returns the
    report files written (the JUnit XML and the Markdown summary; the plots are linked from it)."""
    checked: list[CheckedTrace] = []
    for check, trace, stem in checks:
        plots: dict[str, Path] = {}
        if not check.comparison.passed:
            reference, _ = read_reference(stem)
            written = write_report(check.comparison, Path(out) / check.label, trace, reference)
            plots = plots_of(check.comparison, written)
        checked.append(
            CheckedTrace(check.label, check.comparison, plots, check.solver, fail_on_solver_change, check.invariants)
        )
    return [write_junit(checked, junit), write_markdown_summary(checked, summary)]
