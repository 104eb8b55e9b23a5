"""The provenance record of one run (`provenance.srmd`): every file that shaped its trace, named
by SHA3-256, with the tools' versions and what a repeat needs besides the files.

The files a run uses (`files_used`): the scenario file, the plant FMU, a controller FMU, each
system component's FMU, each input table's CSV file and a user controller's module (its file, or
every .py file of its package); for a run from an SSP, the .ssp archive alone (its FMUs and
parameter files are inside it). The record lies in the run's folder as RECORD_NAME and names
the run's trace.csv as the result it describes (`srmd.Record.data`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.cosim import user_code
from toggle_cosim.provenance import srmd
from toggle_cosim.runs.definition import Run
from toggle_cosim.signals.definitions import Table

RECORD_NAME = "provenance.srmd"  # in every run's folder, beside trace.csv and run.json

# what a repeat reads from a record's settings
SOURCE, SCENARIO, VARIANT, COUPLING = "source", "scenario", "variant", "coupling"


@dataclass(frozen=True)
class UsedFile:
    """A file a run used: its path, STC's kind of it and what the run used it as."""

    path: Path
    kind: str
    role: str


def from_ssp(run: Run) -> bool:
    """Whether the run is an SSP's variant (its files are in the archive)."""
    return isinstance(run.resolved, Mapping) and "ssp" in run.resolved


def _module_files(run: Run) -> list[UsedFile]:
    if run.controller.python is None:
        return []
    name = run.controller.python.partition(":")[0]
    found = user_code.locate(name, run.source.parent if run.source is not None else None)
    if found.package is not None:
        files = sorted(found.package.rglob("*.py"))
    else:
        files = [found.path] if found.path is not None else []
    return [UsedFile(path, "method", "controller-module") for path in files]


def _tables(run: Run) -> list[UsedFile]:
    signals = [run.plant.F_E, *run.plant.inputs.values()]
    paths = dict.fromkeys(Path(s.source.path) for s in signals if isinstance(s, Table) and s.source is not None)
    return [UsedFile(path, "parameter", "input-table") for path in paths]


def files_used(run: Run, plant: Path) -> tuple[UsedFile, ...]:
    """Every file that shapes `run`'s result with `plant` as its plant FMU, in a fixed order,
    each once; a user controller's module is found again (`user_code.locate`), not imported."""
    if from_ssp(run):
        assert run.source is not None
        return (UsedFile(Path(run.source), "system", "ssp"),)
    found = [UsedFile(Path(run.source), "testcase", "scenario")] if run.source is not None else []
    found.append(UsedFile(Path(plant), "model", "plant"))
    if run.controller.fmu is not None:
        found.append(UsedFile(Path(run.controller.fmu), "model", "controller-fmu"))
    found += [UsedFile(Path(part.fmu), "model", f"component {part.name}") for part in run.system.parts]
    found += _tables(run) + _module_files(run)
    return _deduplicated(found)


def tools() -> tuple[tuple[str, str], ...]:
    """The versions a record names: Python's, the platform's, the recorded packages'
    (`outcome.installed_versions`) and the C compiler's path when there is one."""
    from toggle_cosim.cosim.outcome import installed_versions
    from toggle_cosim.native import c_compiler

    try:
        return (*installed_versions(), ("c-compiler", c_compiler()))
    except RuntimeError:  # no compiler: none is named
        return installed_versions()


def run_settings(run: Run) -> tuple[tuple[str, str], ...]:
    """What a repeat needs besides the files: where the run came from (a scenario file or an
    SSP), its scenario and variant names and its coupling."""
    return (
        (SOURCE, "ssp" if from_ssp(run) else "scenario"),
        (SCENARIO, run.scenario),
        (VARIANT, run.variant or ""),
        (COUPLING, run.coupling),
    )


def _deduplicated(found: list[UsedFile]) -> tuple[UsedFile, ...]:
    seen: set[Path] = set()
    unique = []
    for used in found:
        if used.path.absolute() not in seen:
            seen.add(used.path.absolute())
            unique.append(used)
    return tuple(unique)


def _generator(tools: tuple[tuple[str, str], ...]) -> str:
    return f"toggle-cosim {dict(tools).get('toggle-cosim', '')}".strip()


def record_of(
    run: Run,
    plant: Path,
    folder: Path,
    tools: tuple[tuple[str, str], ...],
    plant_tool: str | None = None,
) -> srmd.Record:
    """The record of `run` for its `folder` (which holds its trace.csv): each file it used,
    hashed now, the tools' versions and `plant_tool`, the plant FMU's generationTool."""
    resources = tuple(
        srmd.resource(used.path, folder, used.kind, used.role, plant_tool if used.role == "plant" else None)
        for used in files_used(run, plant)
    )
    return srmd.Record(
        name=run.label,
        resources=resources,
        tools=tools,
        settings=run_settings(run),
        data=srmd.resource(folder / "trace.csv", folder, "result", "result"),
        created=srmd.now(),
        generation_tool=_generator(tools),
    )


def study_record_of(
    name: str,
    specs: tuple[UsedFile, ...],
    runs: list[Run],
    plant: Path,
    folder: Path,
    tools: tuple[tuple[str, str], ...],
    data: Path | None = None,
) -> srmd.Record:
    """The record of a study (a sweep or a tuning) in its output `folder`: its own files
    (`specs`: the sweep or tuning file), then every file its cases' `runs` use with `plant`
    (`files_used`, each once), the tools' versions, and the study's table `data` when written."""
    used = _deduplicated([*specs, *(item for run in runs for item in files_used(run, plant))])
    return srmd.Record(
        name=name,
        resources=tuple(srmd.resource(item.path, folder, item.kind, item.role) for item in used),
        tools=tools,
        settings=((SOURCE, "study"),),
        data=srmd.resource(data, folder, "result", "result") if data is not None and data.is_file() else None,
        created=srmd.now(),
        generation_tool=_generator(tools),
    )


__all__ = ["RECORD_NAME", "UsedFile", "files_used", "from_ssp", "record_of", "run_settings", "study_record_of", "tools"]
