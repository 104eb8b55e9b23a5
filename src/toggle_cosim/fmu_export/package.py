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

import os
import platform
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from toggle_cosim.files.outputs import replacing
from toggle_cosim.fmu_export import interfaces as interface_types
from toggle_cosim.fmu_export.compile import GeneratedModel
from toggle_cosim.fmu_export.model_description import fmi2_model_description, fmi3_model_description
from toggle_cosim.fmu_export.shell_settings import HEADER_NAME, settings_header
from toggle_cosim.native import c_compiler

# The shell files every FMU carries in sources/, whatever its FMI version (and md_settings.h,
# written from shell_settings.py).
CORE_FILES = ("md_model.h", "solver.h", "solver.c", "instance.h", "instance.c")
# The translation units compiled into every binary, besides the FMI layer and model.c
# (instance.c is not one: each layer #includes it).
CORE_UNITS = ("solver.c", "instance.c")
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall")


class FMUBuildError(Exception):
    """The FMU could not be built; the message says which step failed and why."""


@dataclass(frozen=True)
class BuiltFMU:
    path: Path
    guid: str
    model_identifier: str
    size_bytes: int
    fmi_version: str = "2.0"
    interfaces: frozenset[str] = interface_types.CHOICES[interface_types.DEFAULT]


def platform_folder() -> str:
    """The FMI 2.0 name of this platform's binaries folder."""
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(platform.system())
    if system is None:
        raise FMUBuildError(f"unsupported platform {platform.system()}")
    bits = "64" if platform.architecture()[0] == "64bit" else "32"
    return f"{system}{bits}"


def platform_tuple() -> str:
    """The FMI 3.0 name of this platform's binaries folder, `<arch>-<os>` such as `x86_64-linux`
    (FMI 3.0, "Structure of the ZIP file"), for the interpreter's own bitness (the library is
    loaded into this process)."""
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "windows"}.get(platform.system())
    if system is None:
        raise FMUBuildError(f"unsupported platform {platform.system()}")
    machine = platform.machine().lower()
    bits64 = sys.maxsize > 2**32
    if machine in {"x86_64", "amd64", "x64", "i386", "i486", "i586", "i686", "x86"}:
        architecture = "x86_64" if bits64 else "x86"
    elif machine in {"aarch64", "arm64", "armv8l", "armv8b"}:
        architecture = "aarch64" if bits64 else "aarch32"
    elif machine.startswith("arm"):
        architecture = "aarch32"
    elif machine in {"ppc64", "ppc64le"}:
        architecture = "ppc64"
    else:
        raise FMUBuildError(f"unsupported architecture {platform.machine()}")
    return f"{architecture}-{system}"


def shared_library_suffix() -> str:
    return {"Linux": ".so", "Darwin": ".dylib", "Windows": ".dll"}[platform.system()]


def model_identifier_for(path: Path) -> str:
    """A C identifier from the FMU's file name (FMI: the modelIdentifier names the binary)."""
    identifier = re.sub(r"\W", "_", path.stem)
    if not identifier or identifier[0].isdigit():
        identifier = f"m_{identifier}"
    return identifier


def fmi_headers() -> Path:
    """The FMI 2.0 / 3.0 standard headers vendored in this package (fmi_headers/, BSD-2-Clause,
    see its LICENSE.txt): the build does not depend on another package's data files."""
    return Path(str(resources.files("toggle_cosim.fmu_export") / "fmi_headers"))


def find_c_compiler() -> str:
    """The C compiler to use (`native.c_compiler`: $CC, else cc, gcc or clang, as a full path)."""
    try:
        return c_compiler()
    except RuntimeError as error:
        raise FMUBuildError(str(error)) from None


def fmi3_build_description(model_identifier: str, source_files: tuple[str, ...]) -> str:
    """sources/buildDescription.xml (FMI 3.0, "Build Configurations"): the C files to compile
    into the binary, all in `sources/` (the headers they include sit beside them; the FMI
    headers are the importer's), C99, linked with the C math library. No `platform`
    attribute: the sources are portable, so this is the fallback configuration for any."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    configuration = ET.SubElement(root, "BuildConfiguration", modelIdentifier=model_identifier)
    file_set = ET.SubElement(configuration, "SourceFileSet", language="C99")
    for name in source_files:
        ET.SubElement(file_set, "SourceFile", name=name)
    ET.SubElement(configuration, "Library", name="m", external="true", description="the C math library (libm)")
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


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


def first_compiler_error(messages: str, returncode: int) -> str:
    """The compiler's first error line (file:line:column: error: ...), else its first line, else
    its exit status: what a one-line build error shows."""
    lines = [line.strip() for line in messages.splitlines() if line.strip()]
    for line in lines:
        if "error" in line.lower() and not line.lower().startswith("compilation terminated"):
            return line
    return lines[0] if lines else f"it exited with status {returncode} and printed nothing"


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
        command = [
            find_c_compiler(),
            *CFLAGS,
            f"-I{sources}",
            f"-I{fmi_headers()}",
            *(str(sources / n) for n in compiled),
            "-o",
            str(binary),
            "-lm",
        ]
        result = subprocess.run(command, capture_output=True, text=True, check=False)
        if result.returncode != 0:
            messages = result.stderr.replace(f"{sources}{os.sep}", "").strip()
            raise FMUBuildError(
                f"C compiler failed for {model.name}: {first_compiler_error(messages, result.returncode)}\n"
                f"{messages[:4000]}"
            )
        if not binary.is_file() or binary.stat().st_size == 0:
            raise FMUBuildError(
                f"C compiler exited 0 but wrote no library {binary.name} for {model.name} "
                f"(check the compiler {command[0]})"
            )
        (work / "modelDescription.xml").write_text(
            version.model_description(model, identifier, tool, offered, compiled), encoding="utf-8"
        )
        with replacing(output) as partial, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for file in sorted(work.rglob("*")):  # a unique temporary name, renamed into place
                if file.is_file():
                    archive.write(file, file.relative_to(work).as_posix())
    return BuiltFMU(output, model.guid, identifier, output.stat().st_size, fmi_version, offered)
