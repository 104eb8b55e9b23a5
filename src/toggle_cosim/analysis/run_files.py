"""Runs read back from what `toggle-cosim run` and `paper` wrote, or from any trace file, for the
plots and reports that overlay them: each with a label, its trace, its units and its run record.

A RUN argument may be:

* a trace file (`.csv` in the FMI cross-check layout, or a Modelica `.mat` result file); a
  `trace.csv` with a `run.json` beside it is that run;
* a run's folder (`<variant>/` holding trace.csv and run.json);
* a scenario's results folder (`<scenario>/<variant>/trace.csv`), every variant;
* an output folder of several scenarios (`out/`, as `paper` leaves it), every run in it.

A run that did not complete (its run.json says "failed" or "interrupted") may have stopped
before its first sample: its trace.csv then holds a header only, or is missing. `load_runs(...,
incomplete=True)` (the HTML report) loads such a run with the samples it has, so that its record
and reason can be shown; by default (the figures) a trace without samples is refused.

Units come from the plant FMU the run record names (its modelDescription: the unit of each
output and input, `plant.contract.declared_unit`); "time" is in s. A trace without a run record,
or whose FMU is no longer there, has no units beyond time: its panels say so in no unit.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.analysis.results_figure import ResultsError, read_run_record
from toggle_cosim.files.traces import Trace

__all__ = [
    "LoadedRun",
    "check_variables",
    "distinct_labels",
    "fmu_units",
    "load_runs",
    "record_units",
    "label_groups",
    "run_folders",
]

TRACE_FILE = "trace.csv"
RECORD_FILE = "run.json"
INCOMPLETE = ("failed", "interrupted")  # the run.json statuses of a run that did not run to its end


@dataclass(frozen=True)
class LoadedRun:
    """One run to draw: `label` (scenario/variant, or the trace file's name), its trace, {column:
    unit}, its run record (run.json; empty for a bare trace file) and the file it came from."""

    label: str
    trace: Trace
    units: Mapping[str, str]
    record: Mapping[str, Any] = field(default_factory=dict)
    source: Path = Path()

    @property
    def variables(self) -> tuple[str, ...]:
        """The trace's columns but time."""
        return self.trace.names[1:]

    @property
    def incomplete(self) -> bool:
        """True when its run record says the run did not run to its end (failed, interrupted)."""
        return self.record.get("status") in INCOMPLETE

    @property
    def drawable(self) -> bool:
        """True when the trace spans a time interval (two samples or more): a curve to draw."""
        return self.trace.data.shape[0] >= 2


def fmu_units(fmu: str | Path | None, cache: dict[str, dict[str, str]] | None = None) -> dict[str, str]:
    """{variable: unit} of the FMU at `fmu` (each model variable that declares a unit, itself or
    through its type); {} when there is no such FMU any more or it cannot be read."""
    from toggle_cosim.plant.contract import ContractError, declared_unit, read_fmu

    if not fmu:
        return {}
    key = str(fmu)
    if cache is not None and key in cache:
        return cache[key]
    try:
        description = read_fmu(Path(fmu)).model_description
        units = {v.name: str(unit) for v in description.modelVariables if (unit := declared_unit(v)) is not None}
    except (ContractError, OSError, ValueError):
        units = {}
    if cache is not None:
        cache[key] = units
    return units


def record_units(
    record: Mapping[str, Any], names: Sequence[str], cache: dict[str, dict[str, str]] | None = None
) -> dict[str, str]:
    """{column: unit} of the trace columns `names` of the run that `record` (run.json) describes:
    time in s, the plant's columns from the plant FMU it names (`fmu_units`), the law's
    diagnostics e, S, phase by `control.controller.diagnostic_units` (as `Result` gives them); a
    system's run records its columns' units itself (`units`)."""
    if isinstance(record.get("units"), Mapping):
        units = {str(name): str(unit) for name, unit in record["units"].items()}
        return {name: units[name] for name in names if name in units}
    from toggle_cosim.control.controller import diagnostic_units

    plant = fmu_units((record.get("fmu") or {}).get("path"), cache)
    controller = (record.get("resolved") or {}).get("controller") or {}
    objective = controller.get("objective", "x_B") if isinstance(controller, Mapping) else "x_B"
    units = {"time": "s", **diagnostic_units(str(objective), plant), **plant}
    return {name: units[name] for name in names if name in units}


def run_folders(path: Path, records: bool = False) -> list[Path]:
    """The run folders (holding trace.csv, or with `records` run.json) at `path`: itself, its
    children, or its grandchildren, in name order; [] when there are none."""
    files = (TRACE_FILE, RECORD_FILE) if records else (TRACE_FILE,)

    def is_run(folder: Path) -> bool:
        return any((folder / name).is_file() for name in files)

    if is_run(path):
        return [path]
    children = sorted(p for p in path.iterdir() if p.is_dir())
    runs = [p for p in children if is_run(p)]
    if runs:
        return runs
    return [q for p in children for q in sorted(p.iterdir()) if q.is_dir() and is_run(q)]


def _read_trace(path: Path) -> Trace:
    from toggle_cosim.analysis.csv_traces import CompareInputError
    from toggle_cosim.analysis.trace_formats import read_any_trace

    try:
        return read_any_trace(path)
    except (CompareInputError, OSError, ValueError) as error:
        detail = " ".join(str(error).split())
        raise ResultsError(f"{path}: unreadable trace ({detail}); give a trace CSV or a Modelica .mat file") from error


def _samples_kept(path: Path) -> Trace | None:
    """The samples an incomplete run's trace.csv holds when they are too few for a trace (a
    header only, or one row): None when it is not such a file (then its defect is reported)."""
    from toggle_cosim.files.traces import read_csv

    if not (path.exists() or path.is_symlink()):  # no file at all (a folder or a link is a defect)
        return Trace(("time",), np.empty((0, 1)))
    try:
        trace = read_csv(path)
    except (OSError, ValueError):
        return None
    return trace if trace.data.shape[0] < 2 and trace.names[:1] == ("time",) else None


def _from_trace_file(path: Path, cache: dict[str, dict[str, str]], incomplete: bool = False) -> LoadedRun:
    record: dict[str, Any] = {}
    label = path.stem
    beside = path.with_name(RECORD_FILE)
    if path.name == TRACE_FILE and beside.is_file():
        try:
            record = read_run_record(beside)
        except (OSError, ValueError) as error:
            detail = " ".join(str(error).split())
            raise ResultsError(
                f"{beside}: unreadable run record ({detail}); run it again with 'toggle-cosim run'"
            ) from error
        label = "/".join(str(part) for part in (record.get("scenario"), record.get("variant")) if part)
        label = label or path.parent.name
    try:
        trace = _read_trace(path)
    except ResultsError:
        kept = _samples_kept(path) if incomplete and record.get("status") in INCOMPLETE else None
        if kept is None:
            raise
        trace = kept
    return LoadedRun(label, trace, record_units(record, trace.names, cache), record, path)


def load_runs(paths: Iterable[Path], labels: Sequence[str] | None = None, incomplete: bool = False) -> list[LoadedRun]:
    """Every run at `paths` (see the module text), in the order given, labelled by
    `distinct_labels`, or by `labels`: one per path (a path holding several runs labels each
    `LABEL: scenario/variant`). With `incomplete`, a run that did not complete is loaded with
    the samples it has, even none. Raises ResultsError naming the path for one that holds no run
    or cannot be read, and for a number of labels other than the number of paths."""
    paths = [Path(path) for path in paths]
    _check_label_count(labels, len(paths))  # before any file is read
    cache: dict[str, dict[str, str]] = {}
    groups: list[list[LoadedRun]] = []
    for path in paths:
        if path.is_file():
            groups.append([_from_trace_file(path, cache, incomplete)])
            continue
        if not path.is_dir():
            raise ResultsError(f"{path}: no such results folder or trace file; give a folder 'toggle-cosim run' wrote")
        folders = run_folders(path, records=incomplete)
        if not folders:
            raise ResultsError(
                f"{path}: no run results here (expected <variant>/trace.csv; run 'toggle-cosim run' first)"
            )
        groups.append([_from_trace_file(folder / TRACE_FILE, cache, incomplete) for folder in folders])
    return label_groups(groups, labels)


def _check_label_count(labels: Sequence[str] | None, results: int) -> None:
    if labels is not None and len(labels) != results:
        raise ResultsError(f"{len(labels)} label(s) for {results} result(s); give one label per result, in order")


def label_groups(groups: Sequence[Sequence[LoadedRun]], labels: Sequence[str] | None) -> list[LoadedRun]:
    """The runs of `groups` (the runs of each result given, in order) labelled by `labels`, one
    per group (`LABEL: scenario/variant` for each run of a group of several), or by
    `distinct_labels` when None. Raises ResultsError for a number of labels other than the
    number of groups."""
    from dataclasses import replace

    runs = [run for group in groups for run in group]
    if labels is None:
        return [replace(run, label=label) for run, label in zip(runs, distinct_labels(runs), strict=True)]
    _check_label_count(labels, len(groups))
    named = [
        label if len(group) == 1 else f"{label}: {run.label}"
        for label, group in zip(labels, groups, strict=True)
        for run in group
    ]
    return [replace(run, label=label) for run, label in zip(runs, named, strict=True)]


def _folder_parts(source: Path) -> tuple[str, ...]:
    """The parts of the folder a run came from (its trace file's folder, or the file itself for
    a bare trace file), relative to the working folder when it is under it."""
    place = source.parent if source.name == TRACE_FILE else source
    place = Path(place).absolute()
    try:
        place = place.relative_to(Path.cwd())
    except ValueError:
        pass
    return place.parts


def distinct_labels(runs: Sequence[LoadedRun]) -> list[str]:
    """Each run's label (scenario/variant), where it is unique; runs that share one are told
    apart by their folders: the folder's path with the leading parts those runs' paths share left out
    (`pid/fig5_external_force/friction` for `out/pid/...` beside `out/vsc/...`), and by their
    place (`label (2)`) when even the folders are the same."""
    labels = [run.label for run in runs]
    for label in dict.fromkeys(labels):
        members = [index for index, other in enumerate(labels) if other == label]
        if len(members) < 2:
            continue
        parts = [_folder_parts(runs[index].source) for index in members]
        lead = 0
        while all(len(p) > lead + 1 for p in parts) and len({p[lead] for p in parts}) == 1:
            lead += 1
        shown = ["/".join(p[lead:]) for p in parts]
        if len(set(shown)) < len(shown):  # the same folder given twice: the place tells them apart
            shown = [label if n == 0 else f"{label} ({n + 1})" for n in range(len(members))]
        for index, text in zip(members, shown, strict=True):
            labels[index] = text
    return labels


def check_variables(runs: Sequence[LoadedRun], variables: Sequence[str]) -> None:
    """Raise ResultsError naming the first run that lacks one of `variables`, with what it has."""
    for run in runs:
        missing = [name for name in variables if name not in run.variables]
        if missing:
            raise ResultsError(
                f"{run.source}: run {run.label!r} has no variable {', '.join(map(repr, missing))}; "
                f"it has {', '.join(run.variables)}"
            )
