"""`toggle-cosim init`: a working folder with the shipped scenarios and their stored references.

After `pip install toggle-cosim` the scenarios live in the installed package; `init` copies them
into FOLDER/scenarios, so that the commands find them where they look by default
(`scenarios/`, `scenarios/references/`) and each scenario's `fmu: ../fmus/...` names the FMUs
that `toggle-cosim build` writes into FOLDER/fmus.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import click

from toggle_cosim.cli.app import SHIPPED_SCENARIO_FOLDER, InputError, main


def copy_scenarios(folder: Path) -> Path:
    """Copy the shipped scenarios into `folder`/scenarios, whole or not at all; refuse to
    overwrite anything. Returns the new folder."""
    target = folder / "scenarios"
    if target.exists() or target.is_symlink():
        raise InputError(f"{target}: exists already; init copies the shipped scenarios only into a new folder")
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder}: is a file; give a folder to init")
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder, prefix=".init-") as scratch:
        staged = Path(scratch) / "scenarios"
        shutil.copytree(SHIPPED_SCENARIO_FOLDER, staged, ignore=shutil.ignore_patterns("__pycache__"))
        staged.rename(target)
    return target


@main.command()
@click.argument("folder", type=click.Path(path_type=Path), default=Path("."))
def init(folder: Path) -> None:
    """Copy the shipped scenarios and their references into FOLDER/scenarios (default: here)."""
    target = copy_scenarios(folder)
    count = sum(1 for _ in target.glob("*.yaml"))
    click.echo(f"wrote {target} ({count} scenario files and their references); next: toggle-cosim build")
