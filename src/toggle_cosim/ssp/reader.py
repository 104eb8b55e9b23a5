"""An SSP archive -> what our master needs to run one of its parameter sets (`read_ssp`).

Checked, each failure one SspError line naming the file and the fix: a zip archive, safe
(`plant.archive`); a SystemStructure.ssd valid against the SSP 1.0 schema; components `plant` and
`controller` whose FMUs the archive holds; connectors the FMUs have; connections between existing
components and connectors, their units equal; the parameter set named (or the default, `layout`);
its .ssv files valid and naming variables the FMUs have; our annotation (T_s, the runs' scenario
documents) present and agreeing with the controller's T_s.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import shutil
import tempfile
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import TypeVar

from lxml import etree

from toggle_cosim.runs.definition import Run
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import Element, SspError, open_archive, parse_member
from toggle_cosim.ssp.fmus import FmuVariables, describe

__all__ = ["SspStudy", "open_ssp", "open_ssp_sets", "read_ssp", "read_ssp_sets"]

Value = float | bool | int
T = TypeVar("T")
NS = layout.NAMESPACES


@dataclass(frozen=True)
class SspStudy:
    """One parameter set of an SSP, ready for our master.

    `plant_values` are what the master sets on the plant before initialisation, in the .ssv's
    order (F_E, the plant's input, apart); `controller_values` the controller FMU's parameters;
    `run` the run for the records (labels, stroke, ...) with the SSP's t_end, T_s, F_E and plant
    values. `plant_fmu` and `controller_fmu` are extracted copies (`open_ssp`'s folder)."""

    path: Path
    parameter_set: str
    parameter_sets: tuple[str, ...]
    plant_fmu: Path
    controller_fmu: Path
    plant_values: tuple[tuple[str, Value], ...]
    F_E: float
    controller_values: tuple[tuple[str, Value], ...]
    t_end: float
    T_s: float
    run: Run


def _value(element: Element) -> Value:
    kind, text = etree.QName(element).localname, element.get("value")
    if kind == "Boolean":
        return text in ("true", "1")
    if kind == "Integer":
        return int(text)
    return float(text)


def _values(root: Element) -> tuple[tuple[str, Value], ...]:
    found = []
    for parameter in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        typed = [child for child in parameter if etree.QName(child).localname in ("Real", "Integer", "Boolean")]
        if typed:
            found.append((parameter.get("name"), _value(typed[0])))
    return tuple(found)


def _components(ssd: Element, where: str) -> dict[str, Element]:
    system = ssd.find("ssd:System", NS)
    components = {c.get("name"): c for c in system.iterfind("ssd:Elements/ssd:Component", NS)}
    for name in (layout.PLANT, layout.CONTROLLER):
        if name not in components:
            raise SspError(
                f"{where}: no component {name!r} (an SSP for our master has the components plant and controller)"
            )
    others = [name for name in components if name not in (layout.PLANT, layout.CONTROLLER)]
    if others or system.find("ssd:Elements/ssd:System", NS) is not None:
        what = f"the component {others[0]!r}" if others else "a subsystem"
        raise SspError(f"{where}: {what} besides plant and controller (our master runs those two only; remove it)")
    return components


def _connector_units(component: Element, fmu: FmuVariables, where: str) -> dict[str, str | None]:
    units = {}
    for connector in component.iterfind("ssd:Connectors/ssd:Connector", NS):
        name = connector.get("name")
        if name not in fmu.variables:
            raise SspError(
                f"{where}: component {component.get('name')!r} declares the connector {name!r}, which its FMU "
                f"{PurePosixPath(component.get('source')).name} does not have (remove it or fix the name)"
            )
        real = connector.find("ssc:Real", NS)
        units[name] = real.get("unit") if real is not None else None
    return units


def _check_connections(ssd: Element, units: dict[str, dict[str, str | None]], where: str) -> None:
    for connection in ssd.iterfind("ssd:System/ssd:Connections/ssd:Connection", NS):
        ends = []
        for side in ("start", "end"):
            element, connector = connection.get(f"{side}Element"), connection.get(f"{side}Connector")
            if element is None:
                raise SspError(
                    f"{where}: a connection to the system's own connector {connector!r} (system-level connectors "
                    "are not supported; connect the components directly)"
                )
            if element not in units:
                raise SspError(
                    f"{where}: a connection names the component {element!r}, which does not exist "
                    f"(choose one of {', '.join(units)})"
                )
            if connector not in units[element]:
                raise SspError(
                    f"{where}: a connection names the connector {element}.{connector}, which the component does "
                    "not declare (declare it in its Connectors or fix the name)"
                )
            ends.append((f"{element}.{connector}", units[element][connector]))
        (start, start_unit), (end, end_unit) = ends
        if start_unit and end_unit and start_unit != end_unit:
            raise SspError(
                f"{where}: the connection {start} -> {end} joins {start_unit} to {end_unit} "
                "(give both connectors the same unit)"
            )


def _bindings(component: Element) -> list[str]:
    return [b.get("source") for b in component.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS)]


def _experiment(ssd: Element, where: str) -> Element:
    for annotation in ssd.iterfind("ssd:Annotations/ssc:Annotation", NS):
        if annotation.get("type") == layout.ANNOTATION_TYPE:
            experiment = annotation.find(f"{{{layout.TOGGLE_NS}}}Experiment")
            if experiment is not None:
                return experiment
    raise SspError(
        f"{where}: no annotation {layout.ANNOTATION_TYPE} (T_s and the runs' settings); write the SSP with "
        "toggle-cosim ssp SCENARIO.yaml"
    )


def _member_of(source: str, archive: zipfile.ZipFile, where: str, what: str) -> str:
    member = str(PurePosixPath(source))
    if member not in archive.namelist():
        raise SspError(f"{where}: {what} {source!r} is not in the archive (add it, or fix the source)")
    return member


def _extract(archive: zipfile.ZipFile, member: str, folder: Path, name: str) -> Path:
    target = folder / name / PurePosixPath(member).name
    target.parent.mkdir(parents=True, exist_ok=True)
    with archive.open(member) as source, open(target, "wb") as copy:
        shutil.copyfileobj(source, copy)
    return target


def _run(experiment: Element, parameter_set: str, path: Path, where: str) -> Run:
    from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document

    entry = next((e for e in experiment if e.get("parameterSet") == parameter_set), None)
    if entry is None:
        raise SspError(
            f"{where}: the annotation has no run for the parameter set {parameter_set!r}; write the SSP again"
        )
    try:
        document = json.loads(entry.text or "")
        (run,) = runs_from_document(document, path)
    except (ValueError, ScenarioError) as error:
        raise SspError(f"{where}: the run of parameter set {parameter_set!r} cannot be read ({error})") from None
    return dataclasses.replace(run, variant=entry.get("variant"))


def _float(element: Element, name: str, where: str) -> float:
    """A finite number in an attribute that the schema does not type (our annotation's)."""
    try:
        value = float(element.get(name))
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise SspError(f"{where}: {name} = {element.get(name)!r} is not a finite number (write the SSP again)")
    return value


def _check_finite(values: tuple[tuple[str, Value], ...], where: str) -> None:
    for name, value in values:
        if not math.isfinite(value):
            raise SspError(f"{where}: {name} = {value!r} is not a finite number (give a finite value)")


def read_ssp(path: Path, parameter_set: str | None = None, folder: Path | None = None) -> SspStudy:
    """Read and check the SSP at `path` for one parameter set (None: the default, `layout`); the
    FMUs are extracted into `folder` (None: a new temporary folder, which the caller removes once
    done with the FMUs; `open_ssp` does). Raises SspError with the one-line reason (and then
    leaves no temporary folder)."""

    def choose(studies: tuple[SspStudy, ...]) -> SspStudy:
        names = studies[0].parameter_sets
        chosen = names[0] if parameter_set is None else parameter_set
        if chosen not in names:
            raise SspError(
                f"{path}: no parameter set {chosen!r} (choose one of {', '.join(names)} with --parameter-set)"
            )
        return studies[names.index(chosen)]

    return _reading(Path(path), folder, choose)


def read_ssp_sets(path: Path, folder: Path | None = None) -> tuple[SspStudy, ...]:
    """`read_ssp` for every parameter set, the default first, sharing one copy of the FMUs."""
    return _reading(Path(path), folder, lambda studies: studies)


def _reading(path: Path, folder: Path | None, pick: Callable[[tuple[SspStudy, ...]], T]) -> T:
    made = folder is None
    folder = Path(tempfile.mkdtemp(prefix="toggle-cosim-ssp-")) if folder is None else Path(folder)
    try:
        return pick(_read(path, folder))
    except BaseException:
        if made:
            shutil.rmtree(folder, ignore_errors=True)
        raise


def _read(path: Path, folder: Path) -> tuple[SspStudy, ...]:
    with open_archive(path) as archive:
        if layout.SSD_MEMBER not in archive.namelist():
            raise SspError(f"{path}: no {layout.SSD_MEMBER} in the archive (an SSP needs one at its top level)")
        where = f"{path}: {layout.SSD_MEMBER}"
        ssd = parse_member(archive, layout.SSD_MEMBER, "ssd", where)
        components = _components(ssd, where)
        fmus: dict[str, FmuVariables] = {}
        paths: dict[str, Path] = {}
        for name in (layout.PLANT, layout.CONTROLLER):
            member = _member_of(components[name].get("source"), archive, where, f"component {name!r}'s FMU")
            paths[name] = _extract(archive, member, folder, name)
            fmus[name] = describe(paths[name], name, label=f"{path}: {member}")
        units = {name: _connector_units(element, fmus[name], where) for name, element in components.items()}
        _check_connections(ssd, units, where)
        sets: dict[str, dict[str, tuple[tuple[str, Value], ...]]] = {}
        for name in (layout.PLANT, layout.CONTROLLER):
            for source in _bindings(components[name]):
                member = _member_of(source, archive, where, f"component {name!r}'s parameter binding")
                root = parse_member(archive, member, "ssv", f"{path}: {member}")
                values = _values(root)
                fmus[name].check_parameters(values, name, member)
                _check_finite(values, f"{path}: {member}")
                sets.setdefault(root.get("name"), {})[name] = values
        if not sets:
            raise SspError(f"{where}: no parameter set is bound (write the SSP with toggle-cosim ssp)")
        experiment = _experiment(ssd, where)
        T_s = _float(experiment, "T_s", where)
        default = ssd.find("ssd:DefaultExperiment", NS)
        stop = default.get("stopTime") if default is not None else None
        if stop is None:
            raise SspError(f"{where}: no DefaultExperiment stopTime (give the run's end time t_end there)")
        t_end = float(stop)
        if not 0 < T_s <= t_end or abs(round(t_end / T_s) * T_s - t_end) > 1e-9 * t_end:
            raise SspError(
                f"{where}: stopTime {t_end!r} s is not a whole number of samples T_s = {T_s!r} s (fix either)"
            )
        runs = {name: _run(experiment, name, path, where) for name in sets}
    names = tuple(sets)
    return tuple(_study(path, name, names, sets[name], runs[name], paths, t_end, T_s) for name in names)


def _study(
    path: Path,
    name: str,
    names: tuple[str, ...],
    values: dict[str, tuple[tuple[str, Value], ...]],
    run: Run,
    paths: dict[str, Path],
    t_end: float,
    T_s: float,
) -> SspStudy:
    """One parameter set's study: its values, and the run with the SSP's t_end, T_s, F_E and
    plant values (run.json names the SSP and the set)."""
    plant_values = values.get(layout.PLANT, ())
    controller_values = values.get(layout.CONTROLLER, ())
    given_T_s = dict(controller_values).get("T_s")
    if given_T_s is not None and given_T_s != T_s:
        raise SspError(
            f"{path}: parameter set {name!r} sets the controller's T_s = {given_T_s!r} s, the experiment's T_s is "
            f"{T_s!r} s (make them equal)"
        )
    F_E = next((float(v) for n, v in plant_values if n == layout.EXTERNAL_FORCE), run.plant.F_E)
    settings = tuple((n, v) for n, v in plant_values if n != layout.EXTERNAL_FORCE)
    run = dataclasses.replace(
        run,
        source=path,
        fmu=paths[layout.PLANT],
        t_end=t_end,
        T_s=T_s,
        plant=dataclasses.replace(run.plant, F_E=F_E, fmu_values=settings),
        resolved={**run.resolved, "ssp": {"file": str(path), "parameter_set": name}},
    )
    return SspStudy(
        path,
        name,
        names,
        paths[layout.PLANT],
        paths[layout.CONTROLLER],
        settings,
        F_E,
        controller_values,
        t_end,
        T_s,
        run,
    )


@contextlib.contextmanager
def open_ssp(path: Path, parameter_set: str | None = None) -> Iterator[SspStudy]:
    """`read_ssp` with the FMUs in a temporary folder that lives as long as the block."""
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-ssp-") as folder:
        yield read_ssp(path, parameter_set, Path(folder))


@contextlib.contextmanager
def open_ssp_sets(path: Path) -> Iterator[tuple[SspStudy, ...]]:
    """`read_ssp_sets` with the FMUs in a temporary folder that lives as long as the block."""
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-ssp-") as folder:
        yield read_ssp_sets(path, Path(folder))
