"""`toggle-cosim tune`: a controller's parameters tuned for the worst case of a robustness map
(`experiments.tune_run`; docs/designing.md)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from toggle_cosim import interrupts
from toggle_cosim.cli.app import main, require
from toggle_cosim.cli.execution import (
    CASE_TIMEOUT_OPTION,
    FMU_OPTION,
    QUIET_OPTION,
    SCHEDULER_OPTION,
    WORKERS_OPTION,
)


@main.command()
@click.argument("tune_file", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "-o",
    type=click.Path(path_type=Path),
    default=None,
    help="Output folder (default: the tuning file's output: key, else out/tune/<name> under the current folder).",
)
@click.option("--trials", type=click.IntRange(min=1), default=None, help="Trial budget (default: optimiser.trials).")
@SCHEDULER_OPTION
@WORKERS_OPTION
@FMU_OPTION
@CASE_TIMEOUT_OPTION
@QUIET_OPTION
def tune(
    tune_file: Path,
    out: Path | None,
    trials: int | None,
    scheduler: str | None,
    workers: int | None,
    fmu: Path | None,
    case_timeout: float | None,
    quiet: bool,
) -> None:
    """Tune a controller's parameters over a sweep's cases (resumable) -> the best as a scenario,
    the trial history, the maps before and after."""
    require("optuna", "pyarrow", "pandas", "tqdm", "matplotlib")
    from toggle_cosim.experiments.tune_run import run_tuning

    code = run_tuning(
        tune_file,
        output=out,
        fmu=fmu,
        scheduler=scheduler,
        workers=workers,
        progress=not quiet,
        case_timeout=case_timeout,
        trials=trials,
    )
    if code == interrupts.EXIT_INTERRUPTED:
        interrupts.exit_interrupted()
    sys.exit(code)
