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

__all__ = ["LoadedRun", "check_variables", "fmu_units", "load_runs", "record_units", "run_folders"]

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
    time in s, the rest from the plant FMU it names (`fmu_units`); a system's run records its
    columns' units itself (`units`)."""
    if isinstance(record.get("units"), Mapping):
        units = {str(name): str(unit) for name, unit in record["units"].items()}
        return {name: units[name] for name in names if name in units}
    units = {"time": "s", **fmu_units((record.get("fmu") or {}).get("path"), cache)}
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


def load_runs(paths: Iterable[Path], incomplete: bool = False) -> list[LoadedRun]:
    """Every run at `paths` (see the module text), in the order given; a label met twice gets
    the number of its place appended. With `incomplete`, a run that did not complete is loaded
    with the samples it has, even none. Raises ResultsError naming the path for one that holds
    no run or cannot be read."""
    cache: dict[str, dict[str, str]] = {}
    runs: list[LoadedRun] = []
    for path in map(Path, paths):
        if path.is_file():
            runs.append(_from_trace_file(path, cache, incomplete))
            continue
        if not path.is_dir():
            raise ResultsError(f"{path}: no such results folder or trace file; give a folder 'toggle-cosim run' wrote")
        folders = run_folders(path, records=incomplete)
        if not folders:
            raise ResultsError(
                f"{path}: no run results here (expected <variant>/trace.csv; run 'toggle-cosim run' first)"
            )
        runs += [_from_trace_file(folder / TRACE_FILE, cache, incomplete) for folder in folders]
    seen: dict[str, int] = {}
    unique = []
    for run in runs:
        seen[run.label] = seen.get(run.label, 0) + 1
        if seen[run.label] > 1:
            run = LoadedRun(f"{run.label} ({seen[run.label]})", run.trace, run.units, run.record, run.source)
        unique.append(run)
    return unique


def check_variables(runs: Sequence[LoadedRun], variables: Sequence[str]) -> None:
    """Raise ResultsError naming the first run that lacks one of `variables`, with what it has."""
    for run in runs:
        missing = [name for name in variables if name not in run.variables]
        if missing:
            raise ResultsError(
                f"{run.source}: run {run.label!r} has no variable {', '.join(map(repr, missing))}; "
                f"it has {', '.join(run.variables)}"
            )
