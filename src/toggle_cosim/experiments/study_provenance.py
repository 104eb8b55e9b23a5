"""A study's provenance record (`provenance.srmd` in a sweep's or a tuning's output folder): its
own file, every file its cases use (one run per variant: the cases of a variant differ only in
the axes' values), the plant FMU, the tools, and its results table as the data it describes."""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from pathlib import Path

from toggle_cosim.cosim.run_provenance import RECORD_NAME, UsedFile, study_record_of, tools
from toggle_cosim.experiments.scenario import runs_from_document
from toggle_cosim.experiments.sweep_spec import Case
from toggle_cosim.files.outputs import OutputError
from toggle_cosim.provenance.srmd import write_record


def case_runs(cases: Sequence[Case], base: Path):  # noqa: ANN201 - list[Run]
    """One run per variant of `cases` (the first case of each), built from its document."""
    firsts: dict[str | None, Case] = {}
    for case in cases:
        firsts.setdefault(case.variant, case)
    return [runs_from_document(copy.deepcopy(case.document), base)[0] for case in firsts.values()]


def write_study_record(
    folder: Path,
    name: str,
    specs: tuple[UsedFile, ...],
    cases: Sequence[Case],
    base: Path,
    plant: Path,
    data: Path | None,
    say: Callable[[str], None],
) -> Path | None:
    """Write the study's record into `folder`; a file that cannot be hashed, or a destination
    that is not a record, gives a warning line (`say`) and no record: the study's results stand."""
    try:
        record = study_record_of(name, specs, case_runs(cases, base), plant, folder, tools(), data)
        return write_record(folder / RECORD_NAME, record)
    except OSError as error:  # OutputError too: a destination that must not be written
        detail = str(error) if isinstance(error, OutputError) else f"{error.filename}: {error.strerror}"
        say(f"warning: {folder / RECORD_NAME}: provenance record not written ({detail})")
        return None


__all__ = ["case_runs", "write_study_record"]
