"""An SSP archive -> what our master runs for one of its variants (`read_ssp`, `open_ssp`).

A variant is a root SSD (SSP 1.0.1, section 3): `SystemStructure.ssd`, the default, and any other
`*.ssd` at the archive's top level, each named by its `name` attribute (or its file name). What
runs is read from the chosen SSD and its .ssv files only: the components (the controller is the
FMU with an output iq_ref, the plant the one with an input iq_ref, whatever their names; every
other FMU component a part of the run's system, `Run.system`), the values their bindings give
(`bindings`: every binding, later ones taking priority, then the system's), the stop time of its
DefaultExperiment and the controller's T_s. Annotations are not read; an SSP 2.0 root SSD's
MetaData and Signature elements are kept as written (`SspStudy.metadata`, `.signatures`, and
run.json) and decide nothing (`versions`).

Checked before any run, each failure one SspError line naming the file and the fix: a zip
archive, safe (`plant.archive`); the variants (`variants`: names, bounds, set names); every .ssv
within bounds and valid against the SSP schemas of its version, 1.0 or 2.0 (`checks`); two or
more FMU components, Co-Simulation (not SSP 2.0's Scheduled Execution), whose FMUs
the archive holds; the connections (`wiring`: kinds, units, transformations, algebraic loops).
Connections exactly the pair's loop and no other component: `Run.system` is the plain pair
(`Wiring()` with the SSD's component names), which the master runs as the scenario's pair, bit for bit;
anything else: the parts and every connection in document order; every bound name a
parameter or input of its FMU, of its type, finite; the values within the scenario's ranges
(`as_scenario`); the experiment starting at 0 and ending at a whole number of samples.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import shutil
import tempfile
import zipfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from toggle_cosim.files.checksums import file_sha256
from toggle_cosim.runs.definition import Run
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.bindings import Binding, BindingBudget, Value, bindings_of, merged
from toggle_cosim.ssp.checks import Element, SspError, open_archive
from toggle_cosim.ssp.fmus import FmuVariables, describe
from toggle_cosim.ssp.variants import Variant, check_set_names, choose, root_ssds
from toggle_cosim.ssp.versions import MetaData, Signature, metadata_of, signatures_of
from toggle_cosim.ssp.wiring import connectors_of, is_pair_loop, read_connections
from toggle_cosim.system.interfaces import SettableError, settable_type
from toggle_cosim.system.model import Connection, Part, Wiring

__all__ = ["Component", "SspStudy", "open_ssp", "open_ssp_variants", "read_ssp", "read_ssp_variants"]

NS = layout.NAMESPACES


@dataclass(frozen=True)
class Component:
    """One component as it runs: its name in the SSD, its FMU (archive member, extracted copy,
    SHA-256) and every value its bindings set, in the order they are set."""

    name: str
    source: str
    fmu: Path
    sha256: str
    values: tuple[tuple[str, Value], ...]

    def record(self) -> dict[str, Any]:
        """What run.json says about the component."""
        return {"name": self.name, "source": self.source, "sha256": self.sha256, "values": dict(self.values)}


@dataclass(frozen=True)
class SspStudy:
    """One variant of an SSP, ready for our master.

    `plant_values` are what the master sets on the plant before initialisation (F_E, the plant's
    input, apart); `controller_values` the controller FMU's parameters; `run` the run with the
    SSP's t_end, T_s, F_E and plant values, its record naming the SSP, the variant and each
    component's source, hash and values, and its `system` (`Run.system`). `plant_fmu`,
    `controller_fmu` and each part's FMU are extracted copies; `parts` the other components.
    `version` is the root SSD's SSP version ("1.0", "2.0"); `metadata` and `signatures` its own
    SSP 2.0 MetaData and Signature elements, as written (passed through: nothing in them decides
    what runs)."""

    path: Path
    variant: str
    member: str
    variants: tuple[str, ...]
    plant: Component
    controller: Component
    F_E: float
    t_end: float
    T_s: float
    run: Run
    parts: tuple[Component, ...] = ()
    version: str = "1.0"
    metadata: tuple[MetaData, ...] = ()
    signatures: tuple[Signature, ...] = ()

    @property
    def plant_fmu(self) -> Path:
        return self.plant.fmu

    @property
    def controller_fmu(self) -> Path:
        return self.controller.fmu

    @property
    def plant_values(self) -> tuple[tuple[str, Value], ...]:
        return tuple((n, v) for n, v in self.plant.values if n != layout.EXTERNAL_FORCE)

    @property
    def controller_values(self) -> tuple[tuple[str, Value], ...]:
        return self.controller.values


def _elements(ssd: Element, where: str) -> list[Element]:
    system = ssd.find("ssd:System", NS)
    if system.find("ssd:Connectors", NS) is not None and len(system.find("ssd:Connectors", NS)):
        raise SspError(f"{where}: the system has connectors of its own (not supported; connect the components)")
    elements = system.find("ssd:Elements", NS)
    children = list(elements) if elements is not None else []
    seen: set[str] = set()
    for child in children:
        name = child.get("name") or ""
        if "." in name or not name.isprintable() or not name.strip():
            raise SspError(
                f"{where}: component name {name!r} is not a name the master can use (no dots, no control "
                "characters: it writes a component's variables as component.variable; rename it)"
            )
        if name in seen:
            raise SspError(f"{where}: two components are named {name!r} (give each its own name)")
        seen.add(name)
        kind = child.tag.rsplit("}", 1)[-1]
        if kind != "Component":
            raise SspError(f"{where}: a {kind} in the system (our master runs FMU components only; remove it)")
        if child.get("type", layout.FMU_TYPE) != layout.FMU_TYPE:
            raise SspError(
                f"{where}: component {child.get('name')!r} is of type {child.get('type')!r} (only FMUs, "
                f"{layout.FMU_TYPE}, are supported)"
            )
        if child.get("implementation") == "ScheduledExecution":
            raise SspError(
                f"{where}: component {child.get('name')!r} asks for implementation 'ScheduledExecution' (SSP 2.0 "
                "Scheduled Execution is not supported: our master runs Co-Simulation; give implementation "
                "'CoSimulation' or 'any')"
            )
        if child.get("implementation", "any") not in ("any", "CoSimulation"):
            raise SspError(
                f"{where}: component {child.get('name')!r} asks for implementation "
                f"{child.get('implementation')!r} (our master runs Co-Simulation only)"
            )
    if len(children) < 2:
        raise SspError(
            f"{where}: {len(children)} component{'' if len(children) == 1 else 's'}; our master runs at least a plant "
            "and a controller (two FMU components)"
        )
    return children


def _member_of(source: str, archive: zipfile.ZipFile, where: str, what: str) -> str:
    member = str(PurePosixPath(source))
    if ":" in source.split("/", 1)[0] or member not in archive.namelist():
        raise SspError(f"{where}: {what} {source!r} is not in the archive (add it, or fix the source)")
    return member


class _Extracted:
    """The archive's FMUs extracted into `folder`, each member once (its own numbered folder: no
    name from the archive decides where a file goes beyond its last part)."""

    def __init__(self, archive: zipfile.ZipFile, path: Path, folder: Path) -> None:
        self.archive, self.path, self.folder = archive, path, folder
        self.fmus: dict[str, tuple[Path, FmuVariables, str]] = {}

    def get(self, member: str, what: str) -> tuple[Path, FmuVariables, str]:
        if member not in self.fmus:
            target = self.folder / str(len(self.fmus)) / PurePosixPath(member).name
            target.parent.mkdir(parents=True, exist_ok=True)
            with self.archive.open(member) as source, open(target, "wb") as copy:
                shutil.copyfileobj(source, copy)
            if not zipfile.is_zipfile(target):
                raise SspError(f"{self.path}: {member}: the {what} FMU is not a zip archive (give an FMU)")
            variables = describe(target, what, label=f"{self.path}: {member}")
            self.fmus[member] = (target, variables, file_sha256(target))
        return self.fmus[member]


def _roles(
    children: list[Element], fmus: dict[str, FmuVariables], connections: Sequence[Connection], where: str
) -> tuple[str, str]:
    """(plant, controller): the plant has an input iq_ref (where several have one, the one that meets
    the plant contract's required variables), the controller an output iq_ref (where several have
    one, the one whose iq_ref is connected)."""

    def causality(name: str) -> str | None:
        variable = fmus[name].variables.get(layout.COMMAND)
        return variable.causality if variable is not None else None

    names = [child.get("name") for child in children]
    controllers = [n for n in names if causality(n) == "output"]
    plants = [n for n in names if causality(n) == "input"]
    if len(plants) > 1:
        plants = [n for n in plants if _meets_contract(fmus[n])]
    if len(controllers) > 1:
        connected = {c.start.component for c in connections if c.start.variable == layout.COMMAND}
        controllers = [n for n in controllers if n in connected]
    if len(controllers) != 1 or len(plants) != 1:
        raise SspError(
            f"{where}: cannot tell the plant from the controller (one FMU needs an output {layout.COMMAND}, the "
            f"other an input {layout.COMMAND}; the components are {', '.join(names)})"
        )
    return plants[0], controllers[0]


def _meets_contract(fmu: FmuVariables) -> bool:
    """Whether the FMU has every variable the plant contract requires, of its causality."""
    from toggle_cosim.plant.contract import load_contract

    return all(
        (variable := fmu.variables.get(entry.name)) is not None and variable.causality == entry.causality
        for entry in load_contract()
        if entry.required
    )


def _typed(fmu: FmuVariables, name: str, value: Value, kind: str, unit: str | None, where: str) -> Value:
    """The value as the FMU variable's type, checked: a parameter or input, of its type, its unit."""
    try:
        target = settable_type(fmu.variables.get(name), name, value)
    except SettableError as error:
        raise SspError(f"{fmu.label}: {error}, which {where} sets (fix the name or the value)") from None
    if target == "Boolean" and kind != "Boolean":
        raise SspError(f"{where}: {name} is a Boolean; give it as <ssv:Boolean>, not {kind} {value!r}")
    if target != "Boolean" and kind == "Boolean":
        raise SspError(f"{where}: {name} is {target}; give it as a number, not a Boolean")
    own = fmu.unit(name)
    if unit and own and unit != own:
        raise SspError(f"{where}: {name} is given in {unit}, its FMU's unit is {own} (give the value in {own})")
    return int(value) if target == "Integer" else (bool(value) if target == "Boolean" else float(value))


def _finite_time(text: str | None, what: str, where: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise SspError(f"{where}: DefaultExperiment {what} {text!r} is not a finite time (give the run's end in s)")
    return value


def _experiment(ssd: Element, where: str) -> float:
    default = ssd.find("ssd:DefaultExperiment", NS)
    if default is None or default.get("stopTime") is None:
        raise SspError(f"{where}: no DefaultExperiment stopTime (give the run's end time t_end there)")
    start = _finite_time(default.get("startTime", "0"), "startTime", where)
    if start != 0.0:
        raise SspError(f"{where}: DefaultExperiment startTime {start!r} s (our master starts at 0; give 0)")
    return _finite_time(default.get("stopTime"), "stopTime", where)


def _osp_step(ssd: Element) -> float | None:
    for algorithm in ssd.iterfind("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation/*/*", NS):
        if algorithm.tag == f"{{{layout.OSP_NS}}}FixedStepAlgorithm" and algorithm.get("baseStepSize"):
            try:
                return float(algorithm.get("baseStepSize"))
            except ValueError:
                return math.nan
    return None


def _start(fmu: FmuVariables, name: str) -> Value | None:
    variable = fmu.variables.get(name)
    if variable is None or variable.start is None:
        return None
    text = str(variable.start)
    if variable.type == "Boolean":
        return text.lower() in ("true", "1")
    try:
        return int(text) if variable.type in ("Integer", "Int32") else float(text)
    except ValueError:  # a start value that is no number: as if none (the checks then ask for one)
        return None


def _component_values(
    component: Element,
    extra: list[Binding],
    fmu: FmuVariables,
    archive: zipfile.ZipFile,
    path: Path,
    where: str,
    budget: BindingBudget,
) -> tuple[tuple[str, Value], ...]:
    """Every value set on the component: its bindings, then the system's (priority), checked."""
    own = bindings_of(component, archive, str(path), f"{where}: component {component.get('name')!r}", budget)
    values = merged([*own, *extra])
    return tuple(
        (name, _typed(fmu, name, value, kind, unit, f"{where}: component {component.get('name')!r}"))
        for name, (value, kind, unit) in values.items()
    )


def _system_bindings(  # noqa: ANN202
    ssd: Element, archive: zipfile.ZipFile, path: Path, where: str, names: list[str], budget: BindingBudget
):
    """The system's bindings, split by component (`plant.mu` -> plant's mu)."""
    system = ssd.find("ssd:System", NS)
    split: dict[str, list[Binding]] = {name: [] for name in names}
    for binding in bindings_of(system, archive, str(path), f"{where}: the system", budget):
        parts: dict[str, list] = {name: [] for name in names}
        for name, value, kind, unit in binding.values:
            element, _, variable = name.partition(".")
            if element not in parts or not variable:
                raise SspError(
                    f"{where}: the system's binding {binding.source} sets {name!r}, which names no component's "
                    f"variable (write COMPONENT.VARIABLE with one of {', '.join(names)})"
                )
            parts[element].append((variable, value, kind, unit))
        for element, values in parts.items():
            split[element].append(Binding(binding.set_name, binding.source, tuple(values)))
    return split


@dataclass(frozen=True)
class _System:
    """A root SSD's components and wiring: the plant, the controller, the other FMU components
    (parts, in document order) and the system around the pair (`Wiring`)."""

    plant: Component
    controller: Component
    parts: tuple[Component, ...]
    plant_fmu: FmuVariables
    controller_fmu: FmuVariables
    wiring: Wiring


def _components(variant: Variant, archive: zipfile.ZipFile, path: Path, fmus: _Extracted) -> _System:
    """The components of a root SSD with their FMUs' variables: wiring read and checked (`wiring`),
    values bound (`_component_values`). The connections exactly the pair's loop and no other
    component: the plain pair (`Wiring` with no parts and no connections), which the master runs as
    the scenario's pair; otherwise every component and connection."""
    where = f"{path}: {variant.member}"
    children = _elements(variant.ssd, where)
    found: dict[str, tuple[str, Path, FmuVariables, str]] = {}
    for child in children:
        name = child.get("name")
        member = _member_of(child.get("source"), archive, where, f"component {name!r}'s FMU")
        found[name] = (member, *fmus.get(member, "component"))
    variables = {name: entry[2] for name, entry in found.items()}
    connectors = {child.get("name"): connectors_of(child, variables[child.get("name")], where) for child in children}
    connections = read_connections(variant.ssd, where, variables, connectors)
    plant, controller = _roles(children, variables, connections, where)
    if getattr(variables[controller].model_description, "coSimulation", None) is None:
        raise SspError(f"{variables[controller].label}: the controller FMU has no Co-Simulation interface")
    for name, fmu in variables.items():
        if getattr(fmu.model_description, "coSimulation", None) is None:
            raise SspError(
                f"{fmu.label}: component {name!r}'s FMU has no Co-Simulation interface (Model Exchange only; our "
                "master runs Co-Simulation FMUs: export it for Co-Simulation)"
            )
    budget = BindingBudget(where)
    system = _system_bindings(variant.ssd, archive, path, where, list(found), budget)
    components = {}
    for child in children:
        name = child.get("name")
        member, fmu_path, fmu, sha256 = found[name]
        values = _component_values(child, system[name], fmu, archive, path, where, budget)
        components[name] = Component(name, member, fmu_path, sha256, values)
    parts = tuple(components[name] for name in components if name not in (plant, controller))
    if not parts and is_pair_loop(connections, plant, controller, variables):
        wiring = Wiring(plant=plant, controller=controller)
    else:
        wiring = Wiring(
            parts=tuple(Part(p.name, p.fmu, p.values, p.source) for p in parts),
            connections=connections,
            plant=plant,
            controller=controller,
        )
    return _System(components[plant], components[controller], parts, variables[plant], variables[controller], wiring)


def _with_starts(component: Component, fmu: FmuVariables, names: Sequence[str]) -> dict[str, Value]:
    """The component's values over its FMU's start values of `names`."""
    starts = {name: start for name in names if (start := _start(fmu, name)) is not None}
    return {**starts, **dict(component.values)}


def _study(variant: Variant, names: tuple[str, ...], archive: zipfile.ZipFile, path: Path, fmus: _Extracted):  # noqa: ANN202
    """One variant as our master runs it: components, experiment, and the run checked by the
    scenario's rules (`as_scenario`), its record saying what runs."""
    from toggle_cosim.experiments.scenario import ScenarioError
    from toggle_cosim.ssp.as_scenario import CONTROLLER_NAMES, PLANT_NAMES, run_of_values

    where = f"{path}: {variant.member}"
    system = _components(variant, archive, path, fmus)
    plant, controller, plant_fmu, controller_fmu = (
        system.plant,
        system.controller,
        system.plant_fmu,
        system.controller_fmu,
    )
    t_end = _experiment(variant.ssd, where)
    plant_all = _with_starts(plant, plant_fmu, PLANT_NAMES)
    controller_all = _with_starts(controller, controller_fmu, (*CONTROLLER_NAMES, "T_s"))
    T_s = controller_all.get("T_s")
    if T_s is None or isinstance(T_s, bool):
        raise SspError(f"{where}: the controller binds no T_s and its FMU has none (give its sample time T_s)")
    step = _osp_step(variant.ssd)
    if step is not None and step != T_s:
        raise SspError(
            f"{where}: the OSP annotation's baseStepSize {step!r} s is not the controller's T_s = {T_s!r} s "
            "(libcosim would step at the other; make them equal)"
        )
    element = variant.ssd.find("ssd:System", NS)
    try:
        run = run_of_values(
            element.get("name"), element.get("description", ""), t_end, float(T_s), plant_all, controller_all
        )
    except ScenarioError as error:
        raise SspError(
            f"{where}: {error} (read from the variant's parameter values, to which the scenario's ranges apply; "
            "fix the value)"
        ) from None
    F_E = float(plant_all.get(layout.EXTERNAL_FORCE, 0.0))
    record = {
        "file": str(path),
        "sha256": file_sha256(path),
        "variant": variant.name,
        "ssd": variant.member,
        "components": {"plant": plant.record(), "controller": controller.record()},
    }
    metadata, signatures = metadata_of(variant.ssd), signatures_of(variant.ssd)
    if variant.ssd.get("version") != "1.0":
        record["version"] = variant.ssd.get("version")
    if metadata:
        record["metadata"] = [entry.record() for entry in metadata]
    if signatures:
        record["signatures"] = [signature.record() for signature in signatures]
    if not system.wiring.is_pair:
        record["parts"] = [part.record() for part in system.parts]
        record["connections"] = [
            {"start": str(c.start), "end": str(c.end), "factor": c.factor, "offset": c.offset}
            for c in system.wiring.connections
        ]
    run = dataclasses.replace(
        run,
        variant=variant.name,
        source=path,
        fmu=plant.fmu,
        plant=dataclasses.replace(
            run.plant, F_E=F_E, fmu_values=tuple((n, v) for n, v in plant.values if n != layout.EXTERNAL_FORCE)
        ),
        resolved={"ssp": record},
        system=system.wiring,
    )
    return SspStudy(
        path,
        variant.name,
        variant.member,
        names,
        plant,
        controller,
        F_E,
        t_end,
        float(T_s),
        run,
        system.parts,
        variant.ssd.get("version"),
        metadata,
        signatures,
    )


def read_ssp_variants(path: Path, asked: Sequence[str | None], folder: Path) -> tuple[SspStudy, ...]:
    """Read and check the SSP at `path` for each variant asked (None: the default), every one
    checked before any is returned; the FMUs are extracted into `folder` (the caller removes it).
    Raises SspError with the one-line reason."""
    path = Path(path)
    with open_archive(path) as archive:
        found = root_ssds(archive, path)
        check_set_names(found, archive, path)
        chosen = [choose(found, name, path) for name in asked]
        names = tuple(variant.name for variant in found)
        fmus = _Extracted(archive, path, folder)
        studies = tuple(_study(variant, names, archive, path, fmus) for variant in dict.fromkeys(chosen))
    return studies


def read_ssp(path: Path, variant: str | None = None, folder: Path | None = None) -> SspStudy:
    """One variant of the SSP at `path` (None: the default), FMUs extracted into `folder` (None: a
    temporary folder the caller removes; `open_ssp` does). No folder is left on an error."""
    made = folder is None
    folder = Path(tempfile.mkdtemp(prefix="toggle-cosim-ssp-")) if folder is None else Path(folder)
    try:
        return read_ssp_variants(path, [variant], folder)[0]
    except BaseException:
        if made:
            shutil.rmtree(folder, ignore_errors=True)
        raise


@contextlib.contextmanager
def open_ssp(path: Path, variant: str | None = None) -> Iterator[SspStudy]:
    """`read_ssp` with the FMUs in a temporary folder that lives as long as the block."""
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-ssp-") as folder:
        yield read_ssp(path, variant, Path(folder))


@contextlib.contextmanager
def open_ssp_variants(path: Path, asked: Sequence[str | None]) -> Iterator[tuple[SspStudy, ...]]:
    """`read_ssp_variants` with the FMUs in a temporary folder that lives as long as the block."""
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-ssp-") as folder:
        yield read_ssp_variants(path, asked, Path(folder))
