"""The plant's interface contract, and the check that an FMU meets it before a run.

The contract is one machine-readable file, `contract.yaml` beside this module: each variable's
causality, type, unit, tier and meaning. Two tiers:

* required: the loop needs it (the inputs iq_ref and F_E, the outputs x_B and v_B, the
  parameters m_B and mu); an FMU without it is refused in one line;
* optional: recorded (and plotted) when present; its absence is reported (`PlantInterface.
  absent`, run.json, the console), not refused. `required_for` names the objectives that need
  an optional variable (theta1 and omega1 for the theta1 objective): `objective_requirements`.

Units: a different unit is refused; a missing unit attribute (PythonFMU writes none) is a
warning (`PlantInterface.warnings`). The docs' table is generated from the
same file (`contract_table`).
"""

from __future__ import annotations

import platform
import stat
import zipfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from xml.etree import ElementTree

from fmpy.model_description import ModelDescription, read_model_description

from toggle_cosim.files.checksums import file_sha256
from toggle_cosim.files.yaml_loader import parse_yaml

CAUSALITIES = ("input", "output", "parameter")
TIERS = ("required", "optional")
DIMENSIONLESS = "1"  # a unit the FMU may leave out without a warning
VARIABILITIES = {
    "input": ("continuous", "discrete"),
    "output": ("continuous", "discrete"),
    "parameter": ("fixed", "tunable"),
}
FMI_TYPES = {"Real": ("Real", "Float64"), "Boolean": ("Boolean",)}


@dataclass(frozen=True)
class ContractVariable:
    """One variable of the contract (a row of contract.yaml)."""

    name: str
    causality: str
    type: str  # Real (Real in FMI 2.0, Float64 in FMI 3.0) or Boolean
    unit: str | None  # None: not checked; "1": dimensionless, may be left out
    tier: str  # required or optional
    meaning: str
    required_for: tuple[str, ...] = ()  # objectives that need this optional variable

    @property
    def required(self) -> bool:
        return self.tier == "required"


def _variable(name: str, row: dict) -> ContractVariable:
    unit = row.get("unit")
    variable = ContractVariable(
        name=name,
        causality=row["causality"],
        type=row["type"],
        unit=None if unit in (None, "none") else str(unit),
        tier=row["tier"],
        meaning=row["meaning"],
        required_for=tuple(row.get("required_for", ())),
    )
    if variable.causality not in CAUSALITIES or variable.tier not in TIERS or variable.type not in FMI_TYPES:
        raise ValueError(
            f"contract.yaml: variable {name!r} has a causality, tier or type out of {CAUSALITIES}, {TIERS}"
        )
    return variable


def load_contract(text: str | None = None) -> tuple[ContractVariable, ...]:
    """The contract's variables in file order (the package's contract.yaml unless `text` is given)."""
    if text is None:
        text = resources.files("toggle_cosim.plant").joinpath("contract.yaml").read_text(encoding="utf-8")
    return tuple(_variable(name, row) for name, row in parse_yaml(text)["variables"].items())


CONTRACT = load_contract()
INPUTS = tuple(v.name for v in CONTRACT if v.causality == "input")
OUTPUTS = tuple(v.name for v in CONTRACT if v.causality == "output")  # the trace's order
REQUIRED = tuple(v.name for v in CONTRACT if v.required)


def contract_unit(name: str) -> str | None:
    """The unit the contract fixes for the variable `name` ("1": dimensionless); None for a
    variable the contract does not have or whose unit it does not check."""
    return next((v.unit for v in CONTRACT if v.name == name), None)


def objective_requirements(objective: str) -> tuple[str, ...]:
    """The optional variables a controller objective needs (theta1: theta1 and omega1)."""
    return tuple(v.name for v in CONTRACT if objective in v.required_for)


class ContractError(Exception):
    """The FMU cannot be the plant; str() is the one-line reason."""


@dataclass(frozen=True)
class PlantInterface:
    """A checked plant FMU: where it is, what it is, and the value references the master uses."""

    path: Path
    model_description: ModelDescription
    fmi_version: str
    references: dict[str, int]
    types: dict[str, str]
    sha256: str  # of the FMU file as checked: run records name it, the description cache keys on it
    absent: tuple[str, ...] = ()  # the optional contract variables this FMU does not have
    warnings: tuple[str, ...] = ()  # what the check accepted with a warning (a missing unit)

    @property
    def recorded_outputs(self) -> tuple[str, ...]:
        """The contract's outputs this FMU has, in the contract's order (the trace's columns)."""
        return tuple(name for name in OUTPUTS if name not in self.absent)

    def contract_record(self) -> dict[str, list[str]]:
        """What run.json says about the contract: the optional variables absent, the warnings."""
        return {"absent": list(self.absent), "warnings": list(self.warnings)}

    def contract_notes(self) -> list[str]:
        """One line each for the console: the optional outputs absent, each warning."""
        outputs = [name for name in self.absent if name in OUTPUTS]
        lines = [f"{self.path}: optional outputs absent, not recorded: {', '.join(outputs)}"] if outputs else []
        return lines + [f"{self.path}: warning: {warning}" for warning in self.warnings]

    @property
    def guid(self) -> str:
        md = self.model_description
        return md.guid if md.fmiVersion.startswith("2") else md.instantiationToken

    @property
    def model_identifier(self) -> str:
        return self.model_description.coSimulation.modelIdentifier


def platform_binary_folders() -> tuple[str, ...]:
    system = platform.system()
    machine = platform.machine().lower()
    arch = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "aarch64", "arm64": "aarch64"}.get(machine, machine)
    fmi2 = {"Linux": "linux64", "Darwin": "darwin64", "Windows": "win64"}[system]
    fmi3 = f"{arch}-{ {'Linux': 'linux', 'Darwin': 'darwin', 'Windows': 'windows'}[system] }"
    return fmi2, fmi3


@dataclass(frozen=True)
class FmuArchive:
    """An FMU file whose archive passed the safety checks (`archive`) and whose model description
    fmpy read: the Co-Simulation FMI 2.0 or 3.0 FMU with a binary for this platform."""

    path: Path
    model_description: ModelDescription
    sha256: str


def read_fmu(path: Path, missing: str = "build it with 'toggle-cosim build' or fix the fmu: key") -> FmuArchive:
    """The checked archive and model description of the Co-Simulation FMU at `path` (FMI 2.0 or
    3.0, with a binary for this platform); raise ContractError naming the first problem. `missing`
    is the fix the message gives for a file that does not exist."""
    path = Path(path)
    if not path.is_file():
        raise ContractError(f"{path}: no such FMU file ({missing})")
    if not stat.S_ISREG(path.stat().st_mode):
        raise ContractError(f"{path}: not a regular file (give the .fmu file itself)")
    if not zipfile.is_zipfile(path):
        raise ContractError(f"{path}: not an FMU (not a zip archive)")
    from toggle_cosim.plant.archive import ArchiveError
    from toggle_cosim.plant.archive import read_model_description as read_archive

    try:
        names, description = read_archive(path)  # names, sizes and data checked before anything is used
    except ArchiveError as error:
        raise ContractError(f"{path}: unusable FMU archive: {error}") from error
    except (zipfile.BadZipFile, OSError, ValueError, NotImplementedError) as error:
        raise ContractError(f"{path}: not an FMU (damaged zip archive: {' '.join(str(error).split())})") from error
    if description is None:
        raise ContractError(f"{path}: not an FMU (no modelDescription.xml in the archive)")
    try:
        version = ElementTree.fromstring(description).get("fmiVersion")
    except ElementTree.ParseError as error:
        raise ContractError(f"{path}: unreadable modelDescription.xml ({error})") from error
    if version not in ("2.0", "3.0"):
        raise ContractError(f"{path}: FMI version {version} is not supported (use an FMI 2.0 or 3.0 FMU)")
    try:
        sha256 = file_sha256(path)
        md = read_model_description(str(path), validate=False)  # fmpy's own reader
    except Exception as error:  # noqa: BLE001 - fmpy raises several kinds for a broken description
        message = " ".join(str(error).split())
        raise ContractError(f"{path}: unreadable modelDescription.xml ({message})") from error
    if md.coSimulation is None:
        raise ContractError(f"{path}: the FMU does not support Co-Simulation (rebuild it with --interfaces both or cs)")
    identifier = md.coSimulation.modelIdentifier
    folder2, folder3 = platform_binary_folders()
    folder = folder2 if md.fmiVersion == "2.0" else folder3
    suffix = {"Linux": ".so", "Darwin": ".dylib", "Windows": ".dll"}[platform.system()]
    if f"binaries/{folder}/{identifier}{suffix}" not in names:
        raise ContractError(
            f"{path}: no binary for this platform (expected binaries/{folder}/{identifier}{suffix}; rebuild the FMU here)"
        )
    return FmuArchive(path, md, sha256)


def declared_unit(variable) -> str | None:  # noqa: ANN001 - fmpy's ScalarVariable
    """The unit a model variable declares, itself or through its type; None if none."""
    if variable.unit is not None:
        return variable.unit
    return variable.declaredType.unit if variable.declaredType else None


def check_plant(path: Path) -> PlantInterface:
    """Check `path` against the contract; raise ContractError naming the first problem."""
    archive = read_fmu(path)
    path, md, sha256 = archive.path, archive.model_description, archive.sha256
    variables = {v.name: v for v in md.modelVariables}
    references: dict[str, int] = {}
    types: dict[str, str] = {}
    absent: list[str] = []
    unitless: list[ContractVariable] = []
    for entry in CONTRACT:
        variable = variables.get(entry.name)
        if variable is None or (not entry.required and variable.causality != entry.causality):
            if entry.required:
                raise ContractError(
                    f"{path}: missing contract variable {entry.name!r} (a required {entry.causality}, "
                    f"{entry.meaning}); see docs/plant-contract.md"
                )
            absent.append(entry.name)  # an optional name used otherwise in the FMU is not the contract's
            continue
        if _check_variable(path, entry, variable):
            unitless.append(entry)
        references[entry.name] = variable.valueReference
        types[entry.name] = variable.type
    shared: dict[tuple[str, int], str] = {}
    for name in references:  # two contract variables on one value reference read the same number
        kind = "any" if md.fmiVersion.startswith("3") else types[name]
        other = shared.setdefault((kind, references[name]), name)
        if other != name:
            raise ContractError(
                f"{path}: variables {other!r} and {name!r} share the value reference {references[name]};"
                " the contract needs each on its own"
            )
    for variable in md.modelVariables:
        references.setdefault(variable.name, variable.valueReference)
        types.setdefault(variable.name, variable.type)
    warnings = ()
    if unitless:
        warnings = (
            "no unit declared for "
            + ", ".join(f"{v.name} (taken as {v.unit})" for v in unitless)
            + "; the values are read and written in the contract's units",
        )
    return PlantInterface(path, md, md.fmiVersion, references, types, sha256, tuple(absent), warnings)


def _check_variable(path: Path, entry: ContractVariable, variable) -> bool:  # noqa: ANN001 - fmpy's variable
    """Raise ContractError if `variable` cannot be the contract's `entry`; True if it declares
    no unit where the contract has one (a warning, not a refusal)."""
    name, causality = entry.name, entry.causality
    if variable.causality != causality:
        raise ContractError(
            f"{path}: variable {name!r} has causality {variable.causality}, the contract needs {causality}"
        )
    declared = declared_unit(variable)
    unitless = False
    if entry.unit == DIMENSIONLESS:
        if declared not in (None, "", DIMENSIONLESS):
            raise ContractError(f"{path}: variable {name!r} has unit {declared!r}, the contract needs it dimensionless")
    elif entry.unit is not None and declared is None:
        unitless = True
    elif entry.unit is not None and declared != entry.unit:
        raise ContractError(f"{path}: variable {name!r} has unit {declared!r}, the contract needs {entry.unit!r}")
    wanted = FMI_TYPES[entry.type]
    if variable.type not in wanted:
        need = "Real (FMI 2.0) or Float64 (FMI 3.0)" if entry.type == "Real" else entry.type
        raise ContractError(f"{path}: variable {name!r} has type {variable.type}, the contract needs {need}")
    allowed = VARIABILITIES[causality]
    if variable.variability not in allowed:
        raise ContractError(
            f"{path}: variable {name!r} has variability {variable.variability}, the contract needs "
            f"{' or '.join(allowed)} for a {causality}"
        )
    return unitless
