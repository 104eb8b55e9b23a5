"""`toggle-cosim ssp`: a scenario file as an SSP 1.0 archive (`toggle_cosim.ssp.writer`), and the
loading of SSPs for `toggle-cosim run` (`ssp_runs`)."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from pathlib import Path

import click

from toggle_cosim.cli.app import DEFAULT_CONTROLLER, InputError, check_output, main
from toggle_cosim.files.outputs import SSP


@main.command()
@click.argument("scenario", type=click.Path(path_type=Path))
@click.option("--out", "-o", "output", type=click.Path(path_type=Path), required=True, help="The .ssp file to write.")
@click.option(
    "--plant", type=click.Path(path_type=Path), default=None, help="Plant FMU (default: the scenario's fmu: key)."
)
@click.option(
    "--controller",
    type=click.Path(path_type=Path),
    default=DEFAULT_CONTROLLER,
    show_default=True,
    help="Controller FMU.",
)
def ssp(scenario: Path, output: Path, plant: Path | None, controller: Path) -> None:
    """Write SCENARIO (its variants as parameter sets, with the plant and controller FMUs) as an SSP 1.0 archive."""
    from toggle_cosim.experiments.scenario import ScenarioError
    from toggle_cosim.ssp.checks import SspError
    from toggle_cosim.ssp.writer import write_ssp

    check_output(output, "SSP (--out)", SSP)
    try:
        written = write_ssp(scenario, output, plant, controller)
    except (ScenarioError, SspError) as error:
        raise InputError(str(error)) from error
    click.echo(f"wrote {written}")


def is_ssp(path: Path) -> bool:
    return Path(path).suffix.lower() == ".ssp"


def ssp_runs(paths: Sequence[Path], parameter_set: str | None, stack: contextlib.ExitStack) -> list:
    """The runs of each SSP: the parameter set named, else every set in order; the FMUs extracted
    into folders that `stack` removes."""
    from toggle_cosim.ssp.checks import SspError
    from toggle_cosim.ssp.reader import open_ssp, open_ssp_sets
    from toggle_cosim.ssp.run import run_from_ssp

    runs = []
    try:
        for path in paths:
            if parameter_set is None:
                studies = stack.enter_context(open_ssp_sets(path))
            else:
                studies = (stack.enter_context(open_ssp(path, parameter_set)),)
            runs.extend(run_from_ssp(study) for study in studies)
    except SspError as error:
        raise InputError(str(error)) from error
    return runs
