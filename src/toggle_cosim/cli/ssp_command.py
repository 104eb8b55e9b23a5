"""`toggle-cosim ssp`: a scenario file as an SSP 1.0 or 2.0 archive (`toggle_cosim.ssp.writer`), and the
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
    default=None,
    help=f"Controller FMU (default: {DEFAULT_CONTROLLER.name} beside the plant FMU, where build writes it).",
)
@click.option(
    "--variant",
    "variants",
    multiple=True,
    metavar="NAME",
    help="Write only this variant (repeat for several; default: every variant, the first as SystemStructure.ssd).",
)
@click.option(
    "--ssp-version",
    "version",
    metavar="VERSION",
    default=None,
    help="The SSP version to write: 1.0 (the default: what libcosim and Ecos read) or 2.0 (Float64 connectors, as "
    "OMSimulator writes them).",
)
def ssp(
    scenario: Path,
    output: Path,
    plant: Path | None,
    controller: Path | None,
    variants: tuple[str, ...],
    version: str | None,
) -> None:
    """Write SCENARIO as an SSP archive (1.0 unless --ssp-version 2.0): one root SSD per variant
    (SystemStructure.ssd the first), with the plant and controller FMUs and one parameter set per component."""
    from toggle_cosim.experiments.scenario import ScenarioError
    from toggle_cosim.ssp.checks import SspError
    from toggle_cosim.ssp.writer import write_ssp

    check_output(output, "SSP (--out)", SSP)
    try:
        chosen = {} if version is None else {"version": version}  # none given: the writer's default
        written = write_ssp(scenario, output, plant, controller, variants, **chosen)
    except (ScenarioError, SspError) as error:
        raise InputError(str(error)) from error
    click.echo(f"wrote {written}")


def is_ssp(path: Path) -> bool:
    return Path(path).suffix.lower() == ".ssp"


def ssp_runs(paths: Sequence[Path], variants: Sequence[str], stack: contextlib.ExitStack) -> list:
    """The runs of each SSP: the variants named (each a root SSD, by its name), else its default
    (SystemStructure.ssd); every one read and checked before any runs, the FMUs extracted into
    folders that `stack` removes."""
    from toggle_cosim.ssp.checks import SspError
    from toggle_cosim.ssp.reader import open_ssp_variants
    from toggle_cosim.ssp.run import run_from_ssp

    asked = list(variants) or [None]
    seen: set[Path] = set()
    for path in paths:
        if Path(path).resolve() in seen:
            raise InputError(f"{path} is given twice: its runs would write the same folders (give it once)")
        seen.add(Path(path).resolve())
    runs = []
    try:
        for path in paths:
            studies = stack.enter_context(open_ssp_variants(path, asked))
            runs.extend(run_from_ssp(study) for study in studies)
    except SspError as error:
        raise InputError(str(error)) from error
    return runs
