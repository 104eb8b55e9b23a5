"""Compile the generated C with the generic shell and zip it into an FMU (FMI 2.0 or 3.0).

The C compiler runs in a fresh temporary directory on exactly two kinds of file: the C this
package generated from the Modelica source, and the shell sources shipped inside this package
(`shell/`). The FMU carries the same sources under `sources/`, so it can be rebuilt (an FMI 3.0
FMU also says how, in `sources/buildDescription.xml`).

The two FMI versions share the solver core (`shell/solver.c`) and the generic FMU shell
(`shell/instance.c`: state machine, get/set, FMU states, logging), and differ only in the thin
FMI layer (`shell/fmi2.c` or `shell/fmi3.c`), the binaries folder name and the XML written next
to it; `FMI_VERSIONS` holds those differences. The layer #includes `instance.c`, so the
translation units compiled are solver.c, the layer and model.c (all the buildDescription.xml
lists); `instance.c` travels in `sources/` beside the headers.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from toggle_cosim.fmu_export import interfaces as interface_types
from toggle_cosim.fmu_export.compile import GeneratedModel
from toggle_cosim.fmu_export.model_description import fmi2_model_description, fmi3_model_description
from toggle_cosim.fmu_export.packaging import (
    FMUBuildError,
    compile_binary,
    fmi3_build_description,
    model_identifier_for,
    platform_folder,
    platform_tuple,
    shared_library_suffix,
    zip_folder,
)
from toggle_cosim.fmu_export.shell_settings import HEADER_NAME, settings_header

# The shell files every FMU carries in sources/, whatever its FMI version (and md_settings.h,
# written from shell_settings.py).
CORE_FILES = ("md_model.h", "solver.h", "solver.c", "instance.h", "instance.c")
# The translation units compiled into every binary, besides the FMI layer and model.c
# (instance.c is not one: each layer #includes it).
CORE_UNITS = ("solver.c", "instance.c")
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall")


@dataclass(frozen=True)
class BuiltFMU:
    path: Path
    guid: str
    model_identifier: str
    size_bytes: int
    fmi_version: str = "2.0"
    interfaces: frozenset[str] = interface_types.CHOICES[interface_types.DEFAULT]


@dataclass(frozen=True)
class FMIVersion:
    """What differs between the FMI versions this package can write."""

    interface: str  # the shell's FMI layer, compiled with CORE_UNITS
    binaries_folder: Callable[[], str]
    model_description: Callable[..., str]  # (model, identifier, tool, interfaces, sources)
    build_description: Callable[[str, tuple[str, ...]], str] | None


FMI_VERSIONS = {
    "2.0": FMIVersion("fmi2.c", platform_folder, fmi2_model_description, None),
    "3.0": FMIVersion("fmi3.c", platform_tuple, fmi3_model_description, fmi3_build_description),
}


def write_fmu(
    model: GeneratedModel,
    output: Path,
    tool: str,
    fmi_version: str = "2.0",
    interfaces: str | frozenset[str] = interface_types.DEFAULT,
) -> BuiltFMU:
    """Compile `model` and write the FMU for `fmi_version` ("2.0" or "3.0") offering
    `interfaces` ("both", "cs", "me") to `output` (atomically: a temporary name, then rename).

    One binary serves every choice; the choice decides what modelDescription.xml offers and
    what the binary accepts (MD_INTERFACES, defined at the top of model.c)."""
    version = FMI_VERSIONS.get(fmi_version)
    if version is None:
        raise FMUBuildError(f"unsupported FMI version {fmi_version!r} (choose from {', '.join(FMI_VERSIONS)})")
    try:
        offered = interface_types.parse(interfaces)
    except ValueError as error:
        raise FMUBuildError(str(error)) from error
    output = Path(output)
    identifier = model_identifier_for(output)
    compiled = (*CORE_UNITS, version.interface, "model.c")
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-build-") as scratch:
        work = Path(scratch)
        sources = work / "sources"
        sources.mkdir()
        shell = resources.files("toggle_cosim.fmu_export") / "shell"
        for name in (*CORE_FILES, version.interface):
            (sources / name).write_text(shell.joinpath(name).read_text(encoding="utf-8"), encoding="utf-8")
        (sources / HEADER_NAME).write_text(settings_header(), encoding="utf-8")
        (sources / "model.c").write_text(
            f"#define MD_INTERFACES ({interface_types.c_mask(offered)})\n{model.c_source}", encoding="utf-8"
        )
        if version.build_description is not None:
            (sources / "buildDescription.xml").write_text(
                version.build_description(identifier, compiled), encoding="utf-8"
            )
        binary_dir = work / "binaries" / version.binaries_folder()
        binary_dir.mkdir(parents=True)
        binary = binary_dir / f"{identifier}{shared_library_suffix()}"
        compile_binary(model.name, sources, compiled, CFLAGS, binary)
        (work / "modelDescription.xml").write_text(
            version.model_description(model, identifier, tool, offered, compiled), encoding="utf-8"
        )
        zip_folder(work, output)
    return BuiltFMU(output, model.guid, identifier, output.stat().st_size, fmi_version, offered)
