"""Compile the generated C with the generic shell and zip it into an FMU.

The C compiler runs in a fresh temporary directory on exactly two kinds of file: the C this
package generated from the Modelica source, and the shell sources shipped inside this package
(`shell/`). The FMU carries the same sources under `sources/`, so it can be rebuilt.
"""

from __future__ import annotations

import os
import platform
import re
import shutil
import subprocess
import tempfile
import zipfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import fmpy

from toggle_cosim.build.compile import GeneratedModel
from toggle_cosim.build.model_description import fmi2_model_description

SHELL_FILES = ("md_model.h", "solver.h", "solver.c", "fmi2.c")
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-fvisibility=hidden", "-Wall")


class FMUBuildError(Exception):
    """The FMU could not be built; the message says which step failed and why."""


@dataclass(frozen=True)
class BuiltFMU:
    path: Path
    guid: str
    model_identifier: str
    size_bytes: int


def platform_folder() -> str:
    """The FMI 2.0 name of this platform's binaries folder."""
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(platform.system())
    if system is None:
        raise FMUBuildError(f"unsupported platform {platform.system()}")
    bits = "64" if platform.architecture()[0] == "64bit" else "32"
    return f"{system}{bits}"


def shared_library_suffix() -> str:
    return {"Linux": ".so", "Darwin": ".dylib", "Windows": ".dll"}[platform.system()]


def model_identifier_for(path: Path) -> str:
    """A C identifier from the FMU's file name (FMI: the modelIdentifier names the binary)."""
    identifier = re.sub(r"\W", "_", path.stem)
    if not identifier or identifier[0].isdigit():
        identifier = f"m_{identifier}"
    return identifier


def _fmi_headers() -> Path:
    return Path(fmpy.__file__).parent / "c-code"


def _compiler() -> str:
    for name in (os.environ.get("CC", ""), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    raise FMUBuildError("no C compiler found (set CC or install gcc)")


def write_fmu(model: GeneratedModel, output: Path, tool: str) -> BuiltFMU:
    """Compile `model` and write the FMU to `output` (atomically: a temporary name, then rename)."""
    output = Path(output)
    identifier = model_identifier_for(output)
    with tempfile.TemporaryDirectory(prefix="toggle-cosim-build-") as scratch:
        work = Path(scratch)
        sources = work / "sources"
        sources.mkdir()
        shell = resources.files("toggle_cosim.build") / "shell"
        for name in SHELL_FILES:
            (sources / name).write_text(shell.joinpath(name).read_text(encoding="utf-8"), encoding="utf-8")
        (sources / "model.c").write_text(model.c_source, encoding="utf-8")
        binary_dir = work / "binaries" / platform_folder()
        binary_dir.mkdir(parents=True)
        binary = binary_dir / f"{identifier}{shared_library_suffix()}"
        command = [
            _compiler(), *CFLAGS, f"-I{sources}", f"-I{_fmi_headers()}",
            *(str(sources / n) for n in ("solver.c", "fmi2.c", "model.c")),
            "-o", str(binary), "-lm",
        ]
        result = subprocess.run(command, capture_output=True, text=True, check=False)
        if result.returncode != 0:
            raise FMUBuildError(f"C compiler failed for {model.name}:\n{result.stderr.strip()[:4000]}")
        (work / "modelDescription.xml").write_text(
            fmi2_model_description(model, identifier, tool), encoding="utf-8"
        )
        output.parent.mkdir(parents=True, exist_ok=True)
        partial = output.with_name(f".{output.name}.partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for file in sorted(work.rglob("*")):
                if file.is_file():
                    archive.write(file, file.relative_to(work).as_posix())
        os.replace(partial, output)
    return BuiltFMU(output, model.guid, identifier, output.stat().st_size)
