"""Build the controller FMU: generate its C and modelDescription.xml, compile with the shell,
zip with the sources (`fmu_export.packaging`: binaries folder, compiler, zip).

The C compiler sees, in a fresh temporary folder, the generated law (vsc_law.c, vsc_model.h)
and the generic shell shipped in this package (shell/: the instance core and the FMI layer of
the version built). The FMU carries them all under sources/ (FMI 3.0: with
sources/buildDescription.xml), so `cc -shared -fPIC -ffp-contract=off sources/*.c -lm` with the
FMI headers on the include path rebuilds the binary.
"""

from __future__ import annotations

import hashlib
import tempfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from toggle_cosim import __version__
from toggle_cosim.controller_fmu.model_description import fmi2_model_description, fmi3_model_description
from toggle_cosim.controller_fmu.source import MODEL_IDENTIFIER, law_source, model_header
from toggle_cosim.fmu_export.packaging import (
    FMUBuildError,
    compile_binary,
    fmi3_build_description,
    platform_folder,
    platform_tuple,
    shared_library_suffix,
    zip_folder,
)

__all__ = ["FMI_VERSIONS", "LAW_FLAGS", "ControllerFMU", "build_controller_fmu"]

FMI_VERSIONS = ("2.0", "3.0")
# the law's bits equal the Python's only without contraction (FMA) and fast-math
LAW_FLAGS = (
    "-std=c99",
    "-O2",
    "-fPIC",
    "-shared",
    "-fvisibility=hidden",
    "-Wall",
    "-ffp-contract=off",
    "-fno-fast-math",
)
SHELL_HEADERS = ("vsc_core.h",)
CORE_UNITS = ("vsc_law.c", "vsc_core.c")
LAYERS = {"2.0": "vsc_fmi2.c", "3.0": "vsc_fmi3.c"}


@dataclass(frozen=True)
class ControllerFMU:
    """A built controller FMU."""

    path: Path
    fmi_version: str
    token: str
    size_bytes: int


def generated_sources() -> dict[str, str]:
    """The generated files of every build (without the token, which the header gets per build)."""
    return {"vsc_law.c": law_source()}


def _token(law: str, header: str, shell: str) -> str:
    """A GUID from the generated C and the shell: equal sources, equal token (the build is
    reproducible), any change of the law, a parameter or the shell a new one."""
    digest = hashlib.sha256("\0".join((law, header, shell)).encode()).hexdigest()
    return "{" + f"{digest[:8]}-{digest[8:12]}-{digest[12:16]}-{digest[16:20]}-{digest[20:32]}" + "}"


def build_controller_fmu(output: Path, fmi_version: str = "2.0") -> ControllerFMU:
    """Write the controller FMU `ToggleVSC` (FMI `fmi_version`, "2.0" or "3.0", Co-Simulation)
    to `output`, atomically. FMUBuildError names the step that failed."""
    if fmi_version not in FMI_VERSIONS:
        raise FMUBuildError(f"unsupported FMI version {fmi_version!r} (choose from {', '.join(FMI_VERSIONS)})")
    output = Path(output)
    shell = resources.files("toggle_cosim.controller_fmu") / "shell"
    layer = LAYERS[fmi_version]
    shell_files = {
        name: shell.joinpath(name).read_text(encoding="utf-8") for name in (*SHELL_HEADERS, "vsc_core.c", layer)
    }
    law = law_source()
    token = _token(law, model_header("{}"), "".join(shell_files.values()))
    compiled = (*CORE_UNITS, layer)
    tool = f"toggle-cosim {__version__}"
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-vsc-") as scratch:
        work = Path(scratch)
        sources = work / "sources"
        sources.mkdir()
        for name, text in {**shell_files, "vsc_law.c": law, "vsc_model.h": model_header(token)}.items():
            (sources / name).write_text(text, encoding="utf-8")
        if fmi_version == "3.0":
            (sources / "buildDescription.xml").write_text(
                fmi3_build_description(MODEL_IDENTIFIER, compiled), encoding="utf-8"
            )
            binaries = platform_tuple()
            description = fmi3_model_description(token, MODEL_IDENTIFIER, tool)
        else:
            binaries = platform_folder()
            description = fmi2_model_description(token, MODEL_IDENTIFIER, tool, compiled)
        binary_dir = work / "binaries" / binaries
        binary_dir.mkdir(parents=True)
        binary = binary_dir / f"{MODEL_IDENTIFIER}{shared_library_suffix()}"
        compile_binary(MODEL_IDENTIFIER, sources, compiled, LAW_FLAGS, binary)
        (work / "modelDescription.xml").write_text(description, encoding="utf-8")
        zip_folder(work, output)
    return ControllerFMU(output, fmi_version, token, output.stat().st_size)
