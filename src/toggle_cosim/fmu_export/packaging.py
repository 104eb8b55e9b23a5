"""What every FMU this project builds shares, whatever its model: the platform's binaries folder
names (FMI 2.0 and 3.0), the vendored FMI headers, the C compiler, the FMI 3.0 build description,
the compiler's first error line, and the zip of a built folder. No Modelica here: the controller
FMU (`controller_fmu`) is built with these alone."""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from importlib import resources
from pathlib import Path

from toggle_cosim.files.outputs import FMU, replacing
from toggle_cosim.native import c_compiler


class FMUBuildError(Exception):
    """The FMU could not be built; the message says which step failed and why."""


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


def first_compiler_error(messages: str, returncode: int) -> str:
    """The compiler's first error line (file:line:column: error: ...), else its first line, else
    its exit status: what a one-line build error shows."""
    lines = [line.strip() for line in messages.splitlines() if line.strip()]
    for line in lines:
        if "error" in line.lower() and not line.lower().startswith("compilation terminated"):
            return line
    return lines[0] if lines else f"it exited with status {returncode} and printed nothing"


def compile_binary(name: str, sources: Path, units: tuple[str, ...], flags: tuple[str, ...], binary: Path) -> None:
    """Compile the C files `units` of the folder `sources` (with the FMI headers and `sources`
    on the include path, linked with libm) into the shared library `binary`; FMUBuildError with
    the compiler's first error line, naming the FMU `name`."""
    command = [
        find_c_compiler(),
        *flags,
        f"-I{sources}",
        f"-I{fmi_headers()}",
        *(str(sources / n) for n in units),
        "-o",
        str(binary),
        "-lm",
    ]
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        messages = result.stderr.replace(f"{sources}{os.sep}", "").strip()
        raise FMUBuildError(
            f"C compiler failed for {name}: {first_compiler_error(messages, result.returncode)}\n{messages[:4000]}"
        )
    if not binary.is_file() or binary.stat().st_size == 0:
        raise FMUBuildError(
            f"C compiler exited 0 but wrote no library {binary.name} for {name} (check the compiler {command[0]})"
        )


def zip_folder(folder: Path, output: Path) -> None:
    """Zip every file under `folder` (sorted, paths relative to it) into `output`, atomically:
    a unique temporary name, renamed into place."""
    with replacing(output, "FMU", kind=FMU) as partial, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for file in sorted(folder.rglob("*")):
            if file.is_file():
                archive.write(file, file.relative_to(folder).as_posix())
