"""Reports of trace comparisons for CI: JUnit XML (test-report viewers) and a Markdown table
(a CI job summary), one entry per compared trace.

JUnit: one `<testsuite>` per compared trace, one `<testcase>` per variable (classname = the
trace's label, name = the variable); a failing variable carries a `<failure>` whose message gives
its largest distance to the funnel and when it happens. Solver statistics that changed add a
test case "solver statistics" that fails under `--fail-on-solver-change` and is otherwise passed
with the change in its system-out (a warning). Each invariant of the reference
(`analysis.invariants`) is a test case "invariant <metric>", skipped where the trace is not sampled
as its values were measured. Written with junitparser.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from toggle_cosim.analysis.compare import ComparisonResult, VariableResult
from toggle_cosim.analysis.invariants import InvariantResult
from toggle_cosim.analysis.page_text import markdown_cell
from toggle_cosim.analysis.solver_stats import SolverCheck
from toggle_cosim.files.outputs import JUNIT, MARKDOWN, replacing, write_text

__all__ = ["CheckedTrace", "failure_message", "markdown_summary", "write_junit", "write_markdown_summary"]

SOLVER_CASE = "solver statistics"


@dataclass(frozen=True)
class CheckedTrace:
    """One compared trace: its label (e.g. "fig4_nominal/friction"), the comparison, the PNGs of its
    failing variables ({variable: path}), and its solver statistics check (None: not compared)."""

    label: str
    comparison: ComparisonResult
    plots: dict[str, Path] = field(default_factory=dict)
    solver: SolverCheck | None = None
    solver_fails: bool = False  # --fail-on-solver-change
    invariants: tuple[InvariantResult, ...] = ()  # the reference's invariants, checked

    @property
    def passed(self) -> bool:
        solver_failed = self.solver_fails and self.solver is not None and self.solver.changed
        return self.comparison.passed and not solver_failed and all(i.passed for i in self.invariants)


def failure_message(variable: VariableResult) -> str:
    when = "-" if variable.time_of_max_error is None else f"{variable.time_of_max_error:.6g} s"
    return (
        f"max error {variable.max_error:.3e} at t = {when} (funnel ±{variable.half_height:.3g} in value, "
        f"±{variable.half_width:.3g} s in time)"
    )


def write_junit(checks: Sequence[CheckedTrace], path: Path | str) -> Path:
    """Write the JUnit XML report to `path` (atomically: a temporary file renamed into place)."""
    from junitparser import Failure, JUnitXml, Skipped, TestCase, TestSuite

    report = JUnitXml(name="toggle-cosim compare")
    for check in checks:
        suite = TestSuite(check.label)
        suite.add_property("checked at", check.comparison.grid)
        for variable in check.comparison.variables:
            case = TestCase(variable.name, classname=check.label, time=0.0)
            if not variable.passed:
                failure = Failure(failure_message(variable), type_="OutsideFunnel")
                failure.text = failure_message(variable) + (
                    f"\nplot: {check.plots[variable.name]}" if variable.name in check.plots else ""
                )
                case.result = [failure]
            suite.add_testcase(case)
        for invariant in check.invariants:
            case = TestCase(f"invariant {invariant.invariant.name}", classname=check.label, time=0.0)
            if invariant.unchecked is not None:
                case.result = [Skipped(invariant.line)]
            elif not invariant.passed:
                case.result = [Failure(invariant.line, type_="InvariantChanged")]
            suite.add_testcase(case)
        if check.solver is not None and check.solver.changed:
            case = TestCase(SOLVER_CASE, classname=check.label, time=0.0)
            text = "; ".join(check.solver.lines)
            if check.solver_fails:
                case.result = [Failure(f"solver statistics changed: {text}", type_="SolverChanged")]
            else:
                case.system_out = f"warning: solver statistics changed: {text}"
            suite.add_testcase(case)
        suite.update_statistics()
        report.add_testsuite(suite)
    report.update_statistics()
    path = Path(path)
    with replacing(path, "JUnit report", kind=JUNIT) as temporary:
        report.write(str(temporary), pretty=True)
    return path


def markdown_summary(checks: Sequence[CheckedTrace], link_base: Path | None = None) -> str:
    """A Markdown report: one row per trace, then one row per failing variable (with its plot);
    names and messages from the traces go through `markdown_cell`, so they show as written."""
    lines = [
        "| trace | checked at | variables | passed | failed | solver statistics | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for check in checks:
        total = len(check.comparison.variables)
        failed = len(check.comparison.failed)
        solver = "-" if check.solver is None else check.solver.status
        verdict = "pass" if check.passed else "**FAIL**"
        lines.append(
            f"| {markdown_cell(check.label)} | {check.comparison.grid} | {total} | {total - failed} | {failed} | {solver} "
            f"| {verdict} |"
        )
    failing = [(check, v) for check in checks for v in check.comparison.variables if not v.passed]
    if failing:
        lines += [
            "",
            "| trace | variable | max error | at t [s] | funnel (value, time) | plot |",
            "|---|---|---|---|---|---|",
        ]
        for check, v in failing:
            when = "-" if v.time_of_max_error is None else f"{v.time_of_max_error:.6g}"
            plot = check.plots.get(v.name)
            shown = "-"
            if plot is not None:
                target = os.path.relpath(plot, link_base) if link_base is not None else str(plot)
                shown = f"[{markdown_cell(Path(plot).name)}]({quote(target)})"  # a link that cannot end early
            lines.append(
                f"| {markdown_cell(check.label)} | {markdown_cell(v.name)} | {v.max_error:.3e} | {when} | ±{v.half_height:.3g}, "
                f"±{v.half_width:.3g} s | {shown} |"
            )
    broken = [(check, i) for check in checks for i in check.invariants if not i.passed]
    if broken:
        lines.append("")
        lines += [f"- FAIL: {markdown_cell(check.label)}: invariant {markdown_cell(i.line)}" for check, i in broken]
    changed = [check for check in checks if check.solver is not None and check.solver.changed]
    if changed:
        lines.append("")
        for check in changed:
            word = "FAIL" if check.solver_fails else "warning"
            changes = markdown_cell("; ".join(check.solver.lines))
            lines.append(f"- {word}: {markdown_cell(check.label)}: solver statistics changed: {changes}")
    return "\n".join(lines) + "\n"


def write_markdown_summary(checks: Sequence[CheckedTrace], path: Path | str) -> Path:
    path = Path(path)
    text = markdown_summary(checks, link_base=path.resolve().parent)
    write_text(path, text, "Markdown summary", kind=MARKDOWN)
    return path
