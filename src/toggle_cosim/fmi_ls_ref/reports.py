"""The reports of `toggle-cosim verify`, the same as `toggle-cosim references` writes: a JUnit
XML and a Markdown summary (one entry per carried experiment), the envelopes and PNG of each
failing variable under `<out>/<experiment>/`, and optionally the HTML page of the comparisons."""

from __future__ import annotations

from pathlib import Path

from toggle_cosim.analysis.ci_reports import CheckedTrace, write_junit, write_markdown_summary
from toggle_cosim.analysis.compare import write_report
from toggle_cosim.analysis.compare_command import plots_of
from toggle_cosim.fmi_ls_ref.verify import Verification


def write_verification_reports(verification: Verification, out: Path, junit: Path, summary: Path) -> list[Path]:
    """The JUnit XML and the Markdown summary (the plots of failing variables are linked from it)."""
    checked = []
    for check in verification.checks:
        plots: dict[str, Path] = {}
        if not check.passed:
            written = write_report(check.comparison, Path(out) / check.label, check.trace, check.reference)
            plots = plots_of(check.comparison, written)
        checked.append(CheckedTrace(check.label, check.comparison, plots))
    return [write_junit(checked, junit), write_markdown_summary(checked, summary)]


def write_verification_html(verification: Verification, path: Path) -> Path:
    """The page of the comparisons, failing ones first."""
    from toggle_cosim.analysis.html_report import Comparison, comparison_section, write_report

    comparisons = sorted(
        (Comparison(check.label, check.comparison, check.reference, {}) for check in verification.checks),
        key=lambda item: item.comparison.passed,
    )
    failed = sum(1 for item in comparisons if not item.comparison.passed)
    title = f"toggle-cosim verify {verification.fmu.name}: {len(comparisons) - failed} passed, {failed} failed"
    return write_report(path, title, [comparison_section(comparisons)])
