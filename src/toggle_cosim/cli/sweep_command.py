"""`toggle-cosim sweep`: a parameter sweep on a local pool or a Dask cluster (`experiments.sweep_run`)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from toggle_cosim import interrupts
from toggle_cosim.cli.app import check_output, main, require
from toggle_cosim.cli.execution import (
    CASE_TIMEOUT_OPTION,
    FMU_OPTION,
    QUIET_OPTION,
    SCHEDULER_OPTION,
    WORKERS_OPTION,
)
from toggle_cosim.files.outputs import HTML


def _check_report_output(sweep_file: Path, out: Path | None) -> None:
    """Refuse, before any case runs, a report path that must not be written (a link, a folder);
    a sweep file that cannot be read is left to the sweep, which says why."""
    from toggle_cosim.cli.report_command import REPORT_FILE
    from toggle_cosim.experiments.sweep_spec import SweepError, load_sweep

    try:
        folder = load_sweep(sweep_file, out).output
    except (SweepError, OSError, ValueError):
        return
    check_output(folder / REPORT_FILE, "HTML report (--html)", HTML)


@main.command()
@click.argument("sweep_file", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "-o",
    type=click.Path(path_type=Path),
    default=None,
    help="Output folder (default: the sweep file's output: key, else out/sweeps/<name> under the current folder).",
)
@SCHEDULER_OPTION
@WORKERS_OPTION
@FMU_OPTION
@click.option("--retry-failed", is_flag=True, help="Run again the cases that failed last time.")
@CASE_TIMEOUT_OPTION
@click.option(
    "--keep-traces",
    is_flag=True,
    help="Store every case's whole trace in OUTPUT/traces/ (compressed Parquet, by case_id).",
)
@QUIET_OPTION
@click.option(
    "--html",
    is_flag=True,
    help="Also write OUTPUT/report.html: the heat maps in a browser page (cells open kept traces).",
)
def sweep(
    sweep_file: Path,
    out: Path | None,
    scheduler: str | None,
    workers: int | None,
    fmu: Path | None,
    retry_failed: bool,
    case_timeout: float | None,
    keep_traces: bool,
    quiet: bool,
    html: bool,
) -> None:
    """Parameter sweep: one co-simulation per case -> results.parquet and heat maps (resumable)."""
    require("pyarrow", "pandas", "distributed", "tqdm", "matplotlib", *(("plotly",) if html else ()))
    if html:
        _check_report_output(sweep_file, out)
    from toggle_cosim.experiments.sweep_run import run_sweep

    code = run_sweep(
        sweep_file,
        scheduler,
        workers,
        fmu,
        output=out,
        retry_failed=retry_failed,
        progress=not quiet,
        case_timeout=case_timeout,
        keep_traces=keep_traces,
    )
    if code == interrupts.EXIT_INTERRUPTED:
        interrupts.exit_interrupted()
    if not html:  # sweep.json says how the run ended: a later signal changes nothing
        interrupts.ignore()
    if html and code in (0, 1):  # a table to show: every case ran, some may have failed
        from toggle_cosim.cli.report_command import REPORT_FILE, write_sweep_report
        from toggle_cosim.experiments.sweep_spec import load_sweep

        folder = load_sweep(sweep_file, out).output
        click.echo(f"wrote {write_sweep_report(folder, folder / REPORT_FILE)}")
    sys.exit(code)
