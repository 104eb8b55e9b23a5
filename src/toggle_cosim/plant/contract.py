"""The plant's interface contract, and the check that an FMU meets it before a run.

Any FMU that provides these variables (names, causality and units) can be the plant:

* inputs   iq_ref (A, the current command i_q*), F_E (N, >= 0 resists the forward stroke)
* outputs  x_B v_B theta1 theta2 theta5 x_C i_q F_C lambda1 lambda2, the normal and friction
           force at joints (1,2) (2,3) (3,4) (2,5) (5,6) as N12.. and Ff12.., and the
           energies E_in E_fric E_load E_mech
* parameters m_B (kg), mu (1); optional: idealCurrentLoop (Boolean), K (rad/s), x_B0 (m),
  frictionModel (1 paper, 2 dissipative, 3 stick_slip; without it only the paper's model), mu_s (1)
* optional outputs, recorded when present: a_B, omega1, v_C, Phi1, Phi2
"""

from __future__ import annotations

import platform
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

from fmpy.model_description import ModelDescription

from toggle_cosim.files.checksums import file_sha256
from toggle_cosim.plant.description_cache import read_description

JOINTS = ("12", "23", "34", "25", "56")
INPUTS = {"iq_ref": "A", "F_E": "N"}
OUTPUTS = {
    "x_B": "m",
    "v_B": "m/s",
    "theta1": "rad",
    "theta2": "rad",
    "theta5": "rad",
    "x_C": "m",
    "i_q": "A",
    "F_C": "N",
    "lambda1": "N",
    "lambda2": "N",
    **{f"N{j}": "N" for j in JOINTS},
    **{f"Ff{j}": "N" for j in JOINTS},
    "E_in": "J",
    "E_fric": "J",
    "E_load": "J",
    "E_mech": "J",
}
OPTIONAL_OUTPUTS = {"a_B": "m/s2", "omega1": "rad/s", "v_C": "m/s", "Phi1": "m", "Phi2": "m"}
PARAMETERS = {"m_B": "kg", "mu": None}
OPTIONAL_PARAMETERS = {"idealCurrentLoop": None, "K": "rad/s", "x_B0": "m", "frictionModel": None, "mu_s": None}
VARIABILITIES = {
    "input": ("continuous", "discrete"),
    "output": ("continuous", "discrete"),
    "parameter": ("fixed", "tunable"),
}


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

    @property
    def recorded_outputs(self) -> tuple[str, ...]:
        """The contract's outputs, then the optional ones this FMU has."""
        return (*OUTPUTS, *(name for name in OPTIONAL_OUTPUTS if name in self.references))

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


def check_plant(path: Path) -> PlantInterface:
    """Check `path` against the contract; raise ContractError naming the first problem."""
    path = Path(path)
    if not path.is_file():
        raise ContractError(f"{path}: no such FMU file (build it with 'toggle-cosim build' or fix the fmu: key)")
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
        md = read_description(path, sha256)  # fmpy's parse, kept between commands (`description_cache`)
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
    variables = {v.name: v for v in md.modelVariables}
    references: dict[str, int] = {}
    types: dict[str, str] = {}

    def require(name: str, causalities: tuple[str, ...], unit: str | None, optional: bool = False) -> None:
        variable = variables.get(name)
        if variable is None:
            if optional:
                return
            raise ContractError(
                f"{path}: missing contract variable {name!r} ({causalities[0]}); see docs/plant-contract.md"
            )
        if variable.causality not in causalities:
            raise ContractError(
                f"{path}: variable {name!r} has causality {variable.causality}, the contract needs {causalities[0]}"
            )
        declared = (
            variable.unit
            if variable.unit is not None
            else (variable.declaredType.unit if variable.declaredType else None)
        )
        if unit is not None and declared != unit:
            raise ContractError(f"{path}: variable {name!r} has unit {declared!r}, the contract needs {unit!r}")
        wanted = "Boolean" if name == "idealCurrentLoop" else ("Real", "Float64")
        if variable.type not in ((wanted,) if isinstance(wanted, str) else wanted):
            need = wanted if isinstance(wanted, str) else "Real (FMI 2.0) or Float64 (FMI 3.0)"
            raise ContractError(f"{path}: variable {name!r} has type {variable.type}, the contract needs {need}")
        allowed = VARIABILITIES[causalities[0]]
        if variable.variability not in allowed:
            raise ContractError(
                f"{path}: variable {name!r} has variability {variable.variability}, the contract needs "
                f"{' or '.join(allowed)} for a {causalities[0]}"
            )
        references[name] = variable.valueReference
        types[name] = variable.type

    for name, unit in INPUTS.items():
        require(name, ("input",), unit)
    for name, unit in OUTPUTS.items():
        require(name, ("output",), unit)
    for name, unit in OPTIONAL_OUTPUTS.items():
        require(name, ("output",), unit, optional=True)
    for name, unit in PARAMETERS.items():
        require(name, ("parameter",), unit)
    for name, unit in OPTIONAL_PARAMETERS.items():
        require(name, ("parameter",), unit, optional=True)
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
    return PlantInterface(path, md, md.fmiVersion, references, types, sha256)
