"""`toggle-cosim compare` and `references`: traces against stored references, with CI reports."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

import click

from toggle_cosim.cli.app import (
    DEFAULT_OUT,
    DEFAULT_REFERENCES,
    SHIPPED_SCENARIOS,
    InputError,
    RunFailed,
    check_output,
    main,
    require,
)
from toggle_cosim.cli.execution import (
    JOBS_OPTION,
    TIME_LIMIT_OPTION,
    check_report_outputs,
    load_runs,
    outcomes_of,
    report_options,
)
from toggle_cosim.files.outputs import HTML


@main.command()
@click.argument("result", type=click.Path(path_type=Path))
@click.argument("reference", type=click.Path(path_type=Path))
@click.option(
    "--tolerances",
    type=click.Path(path_type=Path),
    default=None,
    help="YAML: {variable: {atol, rtol, ttol}, default: {...}} (default: the tolerances.yaml files "
    "in the reference's folder and its parent).",
)
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    default=None,
    help="Folder for the envelopes and plots of failing variables.",
)
@click.option(
    "--junit",
    type=click.Path(path_type=Path),
    default=None,
    help="Write a JUnit XML report: one test case per variable.",
)
@click.option(
    "--summary", type=click.Path(path_type=Path), default=None, help="Write a Markdown table (for a CI job summary)."
)
@click.option(
    "--fail-on-solver-change", is_flag=True, help="A change of the stored solver statistics fails (default: a warning)."
)
def compare(
    result: Path,
    reference: Path,
    tolerances: Path | None,
    out: Path | None,
    junit: Path | None,
    summary: Path | None,
    fail_on_solver_change: bool,
) -> None:
    """Compare RESULT with REFERENCE (CSV or Modelica .mat traces) in a funnel; exit 0 pass, 1 fail, 2 bad input."""
    from toggle_cosim.analysis.compare_command import run_compare

    require(*(("junitparser",) if junit else ()), *(("matplotlib",) if out else ()))

    sys.exit(
        run_compare(
            result,
            reference,
            tolerances,
            out,
            junit=junit,
            summary=summary,
            fail_on_solver_change=fail_on_solver_change,
        )
    )


@main.command()
@click.argument("scenarios", nargs=-1, type=click.Path(path_type=Path))
@click.option("--update", is_flag=True, help="Rewrite the stored references from fresh runs (review the diff!).")
@click.option("--folder", type=click.Path(path_type=Path), default=DEFAULT_REFERENCES, show_default=True)
@click.option("--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU for every scenario.")
@report_options(DEFAULT_OUT / "references")
@click.option(
    "--fail-on-solver-change", is_flag=True, help="A change of the stored solver statistics fails (default: a warning)."
)
@click.option(
    "--html",
    is_flag=True,
    help="Also write OUT/report.html: each run against its reference (funnel band), runs overlaid.",
)
@TIME_LIMIT_OPTION
@JOBS_OPTION
def references(
    scenarios: tuple[Path, ...],
    update: bool,
    folder: Path,
    fmu: Path | None,
    out: Path,
    junit: Path | None,
    summary: Path | None,
    fail_on_solver_change: bool,
    html: bool,
    time_limit: float | None,
    jobs: int | None,
) -> None:
    """Check scenario runs against their stored reference traces in --folder (or --update them);
    without SCENARIOS, the shipped scenarios in ./scenarios (`toggle-cosim init` copies them there)."""
    from toggle_cosim.analysis.reference_reports import write_reference_reports
    from toggle_cosim.experiments import references as refs

    check_report_outputs(out, junit, summary)
    if not update:
        require("junitparser", "matplotlib", *(("plotly",) if html else ()))
    if html and update:
        raise InputError("--html reports a check against the references; --update rewrites them: give one of the two")
    if html:
        from toggle_cosim.cli.report_command import REPORT_FILE

        check_output(out / REPORT_FILE, "HTML report", HTML)
    files = list(scenarios) or [Path("scenarios") / f"{name}.yaml" for name in SHIPPED_SCENARIOS]
    if not scenarios and not Path("scenarios").is_dir():
        raise InputError(
            "scenarios: no such folder here; name scenario files, or copy the shipped ones with 'toggle-cosim init'"
        )
    pairs = load_runs(files, fmu)
    failures: list[str] = []
    checks = []
    finished = []  # the runs, for the HTML report (a failed one is listed there with its reason)
    with contextlib.closing(outcomes_of(pairs, folder if update else None, True, time_limit, jobs)) as results:
        for outcome in results:
            failures += _check_reference(outcome, refs, folder, update, fail_on_solver_change, checks)
            if html:
                finished.append(outcome)
    if not update:
        written = write_reference_reports(
            checks, out, junit or out / "junit.xml", summary or out / "summary.md", fail_on_solver_change
        )
        if html:
            from toggle_cosim.cli.report_command import write_checks_report

            written.append(write_checks_report(out / REPORT_FILE, checks, finished))
        click.echo(f"reports: {', '.join(str(path) for path in written)}")
    if failures:
        raise RunFailed("; ".join(failures))


def _check_reference(outcome, refs, folder: Path, update: bool, fail_on_solver_change: bool, checks: list) -> list[str]:  # noqa: ANN001
    """One run of `references`: store it (--update) or check it; the failures it adds."""
    from toggle_cosim.analysis.compare import format_table
    from toggle_cosim.analysis.csv_traces import CompareInputError

    run = outcome.run
    if outcome.interrupted:
        raise KeyboardInterrupt
    if not outcome.complete:  # the other runs go on; the command fails at the end
        click.echo(f"{run.label}: FAILED ({outcome.reason})")
        return [f"{run.label}: {outcome.reason}"]
    if update:
        click.echo(f"{run.label}: wrote {refs.store(outcome, folder)}")
        return []
    try:
        checked = refs.check(outcome, folder)
    except (CompareInputError, ValueError) as error:
        raise InputError(str(error)) from error
    click.echo(f"{run.label}: {'pass' if checked.passed else 'FAIL'}")
    if not checked.comparison.passed:
        click.echo(format_table(checked.comparison))
    for invariant in checked.invariants:
        if not invariant.passed:
            click.echo(f"FAIL: invariant {invariant.line}")
    for line in checked.solver_changes:
        click.echo(f"{'FAIL' if fail_on_solver_change else 'warning'}: {line}")
    checks.append((checked, outcome.trace, refs.reference_stem(folder, run)))
    return [*checked.failures, *(checked.solver_changes if fail_on_solver_change else [])]
