"""`toggle-cosim report`, the HTML report of `references --html` and `sweep --html`, and
`plot --vars/--reference`: runs of any scenario or plant overlaid, variable by variable."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import click

from toggle_cosim.cli.app import InputError, check_output, main, require
from toggle_cosim.files.outputs import HTML

REPORT_FILE = "report.html"


def parse_vars(text: str | None) -> list[str] | None:
    """`--vars x_B,iq_ref` as names (None when not given); an empty name is bad input."""
    if text is None:
        return None
    names = [name.strip() for name in text.split(",")]
    if not all(names):
        raise InputError(f"--vars {text!r}: an empty variable name; give names separated by commas, e.g. x_B,iq_ref")
    return list(dict.fromkeys(names))


def _loaded(paths: Sequence[Path], labels: Sequence[str] | None = None, incomplete: bool = False) -> list[Any]:
    from toggle_cosim.analysis.results_figure import ResultsError
    from toggle_cosim.analysis.run_files import load_runs

    try:
        return load_runs(paths, labels, incomplete)
    except ResultsError as error:
        raise InputError(str(error)) from error


def _reference_band(runs: Sequence[Any], reference: Path, variables: Sequence[str]) -> Any:
    """The reference file and its funnels around the first run's `variables` it has (tolerance
    files by place, as `compare` finds them)."""
    from toggle_cosim.analysis.compare import compare_traces
    from toggle_cosim.analysis.csv_traces import CompareInputError
    from toggle_cosim.analysis.tolerance_files import tolerances_for_reference
    from toggle_cosim.analysis.trace_formats import read_any_trace
    from toggle_cosim.analysis.variable_figure import ReferenceBand

    try:
        trace = read_any_trace(reference)
        default, tolerances, files = tolerances_for_reference(reference, None)
        shared = [name for name in variables if name in trace.names and name in runs[0].trace.names]
        if not shared:
            raise CompareInputError(f"{reference}: has none of the variables {', '.join(variables)}; it has "
                                    f"{', '.join(trace.names[1:])}")  # fmt: skip
        comparison = compare_traces(
            runs[0].trace,
            trace,
            tolerances,
            default,
            shared,
            result_label=str(runs[0].source),
            reference_label=str(reference),
            tolerances_label=str(files[-1]) if files else "tolerances",
        )
    except CompareInputError as error:
        raise InputError(str(error)) from error
    return ReferenceBand(f"reference {reference.name}", trace, comparison)


def _default_output(first: Path, name: str) -> Path:
    return (first if first.is_dir() else first.parent) / name


def plot_variables(
    results: Sequence[Path],
    variables: list[str] | None,
    reference: Path | None,
    output: Path | None,
    labels: Sequence[str] | None = None,
) -> Path:
    """`plot RUN... --vars ... [--reference REF] [--label NAME]...`: every run overlaid into one
    PNG (default RUN/variables.png of the first RUN), each named by its --label (one per RUN)
    or by `run_files.distinct_labels`; without --vars the variables every run has."""
    from toggle_cosim.analysis.results_figure import ResultsError
    from toggle_cosim.analysis.run_files import check_variables
    from toggle_cosim.analysis.variable_figure import default_variables, save_figure, variables_figure

    runs = _loaded(results, labels)
    chosen = variables or default_variables(runs)
    try:
        check_variables(runs, chosen)
    except ResultsError as error:
        raise InputError(str(error)) from error
    band = _reference_band(runs, reference, chosen) if reference is not None else None
    output = output or _default_output(results[0], "variables.png")
    title = ", ".join(dict.fromkeys(str(run.record.get("scenario") or run.label.split("/")[0]) for run in runs))
    try:
        return save_figure(variables_figure(runs, chosen, title, band), output)
    except OSError as error:
        raise InputError(f"{output}: cannot write the figure ({error.strerror or error})") from error


def is_paper_plant(folder: Path) -> bool:
    """True when `folder`'s runs can be drawn as the paper's nine panels (the plant has the
    paper's Lagrange multipliers and joint forces), or when it cannot tell (then the nine-panel
    figure's own checks name the problem)."""
    from toggle_cosim.analysis.plots import PANELS
    from toggle_cosim.analysis.results_figure import ResultsError
    from toggle_cosim.analysis.run_files import load_runs

    try:
        runs = load_runs([folder])
    except ResultsError:
        return True
    wanted = [key if not key.isdigit() else f"N{key}" for _, key, _ in PANELS]
    return all(all(name in run.variables for name in wanted) for run in runs)


# ----------------------------------------------------------------------------- the HTML report


def _runs_of_outcomes(outcomes: Sequence[Any]) -> list[Any]:
    from toggle_cosim.analysis.run_files import LoadedRun, record_units

    cache: dict[str, dict[str, str]] = {}
    return [LoadedRun(o.run.label, o.trace, record_units(o.record, o.trace.names, cache), o.record) for o in outcomes]


def _plain_name(name: object) -> bool:
    """True for a name that is one folder or file name: the reference it names stays inside the
    references folder whatever a run.json says."""
    return isinstance(name, str) and name not in ("", ".", "..") and not set(name) & {"/", "\\", "\0"}


def reference_comparisons(runs: Sequence[Any], folder: Path) -> list[Any]:
    """Each run with a stored reference in `folder` (`<scenario>/<variant>_ref.csv`) compared
    with it as `references` does (its tolerance files by place); a run without two samples to
    compare (it failed at its start) is left out, its record says why."""
    from toggle_cosim.analysis.compare_command import compare_with_file
    from toggle_cosim.analysis.csv_traces import CompareInputError
    from toggle_cosim.analysis.html_report import Comparison

    comparisons = []
    for run in runs:
        scenario, variant = run.record.get("scenario"), run.record.get("variant") or "run"
        if not (_plain_name(scenario) and _plain_name(variant)) or not run.drawable:
            continue  # a name from run.json that is a path (`..`, `a/b`) names no stored reference
        path = Path(folder) / scenario / f"{variant}_ref.csv"
        if not path.is_file():
            continue
        try:
            checked = compare_with_file(run.trace, path, result_label=f"run {run.label}")
        except CompareInputError as error:
            raise InputError(str(error)) from error
        comparisons.append(Comparison(run.label, checked.comparison, checked.reference, run.units))
    return comparisons


def write_checks_report(output: Path, checks: Sequence[tuple[Any, Any, Path]], outcomes: Sequence[Any]) -> Path:
    """The page of `references --html`: the runs that failed with their reasons, the comparisons
    it made ((ReferenceCheck, trace, reference stem) each), failing ones first, then the runs
    overlaid and their records (`outcomes`: every run, complete or not)."""
    from toggle_cosim.analysis.html_report import Comparison
    from toggle_cosim.analysis.reference_files import read_reference

    runs = _runs_of_outcomes(outcomes)
    units = {run.label: run.units for run in runs}
    comparisons = [
        Comparison(check.label, check.comparison, read_reference(stem)[0], units.get(check.label, {}))
        for check, _, stem in checks
    ]
    comparisons.sort(key=lambda item: item.comparison.passed)  # stable: failing first, in run order
    failed = sum(1 for item in comparisons if not item.comparison.passed)
    title = f"toggle-cosim references: {len(comparisons) - failed} passed, {failed} failed"
    return write_runs_report(output, title, runs, comparisons)


def write_runs_report(
    output: Path, title: str, runs: Sequence[Any], comparisons: Sequence[Any] = (), variables: list[str] | None = None
) -> Path:
    """The page of runs: the runs that did not complete with their reasons, the comparisons
    (failing ones open), the runs overlaid (those with samples to draw), their records."""
    from toggle_cosim.analysis.html_report import (
        comparison_section,
        failures_section,
        overlay_section,
        records_section,
        write_report,
    )

    sections = []
    if any(run.incomplete for run in runs):
        sections.append(failures_section(runs))
    if comparisons:
        sections.append(comparison_section(comparisons))
    if any(run.drawable for run in runs):
        sections.append(overlay_section(runs, variables))
    if runs:
        sections.append(records_section(runs, folder=Path(output).parent))
    return write_report(output, title, sections)


def write_sweep_report(folder: Path, output: Path) -> Path:
    """The page of a sweep output folder: its heat maps (cells open the kept traces)."""
    from toggle_cosim.analysis.html_report import sweep_section, write_report
    from toggle_cosim.experiments.sweep_report import SweepFolderError, read_sweep_folder

    try:
        sweep = read_sweep_folder(folder)
    except SweepFolderError as error:
        raise InputError(str(error)) from error
    kept = "cells open their case's trace" if sweep.traces else "no traces kept (sweep --keep-traces keeps them)"
    return write_report(output, f"sweep {sweep.name}", [sweep_section(sweep)], note=f"{len(sweep.table)} cases; {kept}")


@main.command()
@click.argument("folders", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--out",
    "-o",
    "output",
    type=click.Path(path_type=Path),
    default=None,
    help=f"HTML file to write (default: FOLDER/{REPORT_FILE} of the first FOLDER).",
)
@click.option(
    "--vars", "variables", default=None, metavar="NAMES", help="Variables to offer, comma-separated (default: all)."
)
@click.option(
    "--references",
    "references_folder",
    type=click.Path(path_type=Path),
    default=None,
    help="Stored references' folder: each run with a reference there is compared with it (funnel band, failing points).",
)
def report(
    folders: tuple[Path, ...], output: Path | None, variables: str | None, references_folder: Path | None
) -> None:
    """One self-contained HTML page (opens offline) of results folders or trace files: the runs
    overlaid with the variable to choose, their run records, and with --references each run
    against its reference; of a sweep output folder: its heat maps."""
    require("plotly")
    from toggle_cosim.experiments.sweep_report import is_sweep_folder

    names = parse_vars(variables)
    output = output or _default_output(folders[0], REPORT_FILE)
    check_output(output, "HTML report (--out)", HTML)
    sweeps = [folder for folder in folders if folder.is_dir() and is_sweep_folder(folder)]
    if sweeps:
        if len(folders) > 1:
            raise InputError(f"{sweeps[0]}: a sweep's report is a page of its own; give the sweep folder alone")
        click.echo(f"wrote {write_sweep_report(sweeps[0], output)}")
        return
    runs = _loaded(folders, incomplete=True)
    if names:
        from toggle_cosim.analysis.results_figure import ResultsError
        from toggle_cosim.analysis.run_files import check_variables

        try:
            check_variables([run for run in runs if run.drawable], names)
        except ResultsError as error:
            raise InputError(str(error)) from error
    if references_folder is not None and not references_folder.is_dir():
        raise InputError(
            f"{references_folder}: no such references folder (--references); give the folder of <scenario>/<variant>_ref.csv"
        )
    comparisons = reference_comparisons(runs, references_folder) if references_folder is not None else []
    title = "toggle-cosim report: " + ", ".join(str(folder) for folder in folders)
    click.echo(f"wrote {write_runs_report(output, title, runs, comparisons, names)}")
