"""Tolerance files that apply to a reference by where they lie, so no flag is needed.

For a reference `<folder>/<name>_ref.csv` (or any trace used as a reference) the files
`<folder>/../tolerances.yaml` and `<folder>/tolerances.yaml` apply, in that order: the parent
folder's file holds the defaults of a collection of references (`scenarios/references/`), the
reference's own folder adds or overrides entries for its scenario. `--tolerances FILE` replaces
both. Each file is read by `toggle_cosim.analysis.compare.load_tolerances`; anything at one of
those places that is not a readable regular file (a folder, a link to a device, a link that
leads nowhere) is bad input, not a file to skip.
"""

from __future__ import annotations

import os
from pathlib import Path

from toggle_cosim.analysis.compare import DEFAULT_TOLERANCE, Tolerance, load_tolerances

__all__ = ["TOLERANCE_FILE", "applicable_tolerance_files", "merged_tolerances", "tolerances_for_reference"]

TOLERANCE_FILE = "tolerances.yaml"


def applicable_tolerance_files(reference: Path | str) -> list[Path]:
    """The tolerance files that apply to `reference` by place, the general one first."""
    folder = Path(reference).resolve().parent
    candidates = [folder.parent / TOLERANCE_FILE, folder / TOLERANCE_FILE]
    here = Path.cwd().resolve()
    return [
        path.relative_to(here) if path.is_relative_to(here) else path
        for path in dict.fromkeys(candidates)
        if os.path.lexists(path)  # whatever is there: a folder or a link to a device is refused, not skipped
    ]


def merged_tolerances(files: list[Path]) -> tuple[Tolerance, dict[str, Tolerance]]:
    """Read `files` in order; a later file's entries replace earlier ones, and its `default` entry
    (when it gives one other than the built-in default) replaces the earlier default."""
    default, per_variable = DEFAULT_TOLERANCE, {}
    for path in files:
        own_default, own_variables = load_tolerances(path)
        default = own_default if own_default != DEFAULT_TOLERANCE else default
        per_variable = {**per_variable, **own_variables}
    return default, per_variable


def tolerances_for_reference(
    reference: Path | str, explicit: Path | str | None = None
) -> tuple[Tolerance, dict[str, Tolerance], list[Path]]:
    """(default, per-variable tolerances, the files they came from) for `reference`; `explicit`
    (the --tolerances option) replaces the files found by place."""
    files = [Path(explicit)] if explicit is not None else applicable_tolerance_files(reference)
    default, per_variable = merged_tolerances(files)
    return default, per_variable, files
