"""The build cache: an FMU built before from the same inputs is copied, not compiled again.

A build is named by the SHA-256 of everything that decides the FMU's bytes (`build_key`): the
Modelica source (the relative path and bytes of every `.mo` and `package.order` of a package
folder, or the one `.mo` file), the model, the FMU's model identifier (from the output's file
name), the FMI version, the interfaces, toggle-cosim's and the `modelica` compiler's versions,
every file of this package (the builder's Python, `shell/` C sources and `fmi_headers/`), the C
compiler's path and `--version`, and the platform. Any change to one of them is another name.

The FMU is kept in the user's private cache (`native.cache_folder`) under the rules of
`native`: stored with its SHA-256 recorded beside it, and taken back only when it is this
user's, writable by no one else and has those bytes. A cache that cannot be used never fails a
build: the FMU is compiled as without it. `TOGGLE_COSIM_BUILD_CACHE=0` turns the cache off.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from toggle_cosim import __version__
from toggle_cosim.native import CacheError, cache_folder, cached_bytes, read_private, store

SWITCH = "TOGGLE_COSIM_BUILD_CACHE"  # "0" turns the cache off
PACKAGE = Path(__file__).resolve().parent  # fmu_export/: the builder's own code, shell/ and fmi_headers/


@dataclass(frozen=True)
class CachedBuild:
    """What a build report says of an FMU besides the file itself, kept beside it in the cache."""

    guid: str
    variables: int
    states: int
    event_indicators: int

    def text(self) -> str:
        return f"{self.guid}\n{self.variables}\n{self.states}\n{self.event_indicators}"

    @classmethod
    def parse(cls, text: str) -> CachedBuild | None:
        """The facts written by `text`, or None for anything else."""
        lines = text.split("\n")
        if len(lines) != 4 or not all(n.isdigit() for n in lines[1:]):
            return None
        return cls(lines[0], int(lines[1]), int(lines[2]), int(lines[3]))


def enabled() -> bool:
    """False when TOGGLE_COSIM_BUILD_CACHE=0 (the value is checked with the other flags in `limits`)."""
    return os.environ.get(SWITCH, "1").strip() != "0"


def source_files(source: Path) -> list[Path]:
    """The files of the Modelica `source` that a build reads: of a package folder, every `.mo`
    and `package.order` under it (sorted); of a single file, that file."""
    if source.is_dir():
        return sorted(p for p in source.rglob("*") if p.is_file() and (p.suffix == ".mo" or p.name == "package.order"))
    return [source]


def _tree(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts)


def _compiler_identity() -> bytes:
    """The C compiler's path and its `--version` output (empty when it cannot be run: the build
    then fails, before anything is stored)."""
    from toggle_cosim.native import c_compiler

    try:
        compiler = c_compiler()
        version = subprocess.run([compiler, "--version"], capture_output=True, check=False, timeout=60).stdout
    except (RuntimeError, OSError, subprocess.SubprocessError):
        return b""
    return compiler.encode() + b"\0" + version


def _modelica_version() -> str:
    try:
        return metadata.version("modelica")
    except metadata.PackageNotFoundError:
        return ""


def build_key(source: Path, model: str, identifier: str, fmi_version: str, interfaces: frozenset[str]) -> str:
    """The SHA-256 (hex) of everything that decides the bytes of the FMU built from these inputs."""
    digest = hashlib.sha256()

    def field(data: bytes) -> None:
        digest.update(len(data).to_bytes(8, "big") + data)  # length-prefixed: no two inputs read alike

    source = Path(source)
    for path in source_files(source):
        field(path.relative_to(source).as_posix().encode() if source.is_dir() else path.name.encode())
        field(path.read_bytes())
    for text in (model, identifier, fmi_version, ",".join(sorted(interfaces)), __version__, _modelica_version()):
        field(text.encode())
    for path in _tree(PACKAGE):
        field(path.relative_to(PACKAGE).as_posix().encode())
        field(path.read_bytes())
    field(_compiler_identity())
    field(f"{platform.system()} {platform.machine()} {sys.maxsize > 2**32}".encode())
    return digest.hexdigest()


def _names(key: str) -> tuple[str, str]:
    stem = f"fmu-{key[:32]}"
    return f"{stem}.fmu", f"{stem}.facts"


def lookup(key: str) -> tuple[bytes, CachedBuild] | None:
    """The FMU stored under `key` (its bytes, checked against the SHA-256 recorded when it was
    stored) and its facts, or None: not there, not private, other bytes, or no usable cache."""
    fmu_name, facts_name = _names(key)
    try:
        folder = cache_folder()
    except (CacheError, OSError):
        return None
    data = cached_bytes(folder, fmu_name, "FMU")
    facts = cached_bytes(folder, facts_name, "FMU facts")
    if data is None or facts is None:
        return None
    try:
        parsed = CachedBuild.parse(facts.decode("ascii"))
    except UnicodeDecodeError:
        return None
    return (data, parsed) if parsed is not None else None


def keep(key: str, fmu: Path, facts: CachedBuild) -> None:
    """Store the FMU just written at `fmu` (a regular file of this user's) and its facts under
    `key`. Nothing is stored, and one warning line at most says why, when the cache cannot be
    used: the build itself has succeeded."""
    fmu_name, facts_name = _names(key)
    try:
        data = read_private(fmu, "FMU")
        folder = cache_folder()
        store(folder, facts_name, lambda path: path.write_text(facts.text(), encoding="ascii"), 0o600)
        store(folder, fmu_name, lambda path: path.write_bytes(data), 0o600)
    except CacheError:
        return  # cache_folder has said why, once; an output that is not a private file is not kept
    except OSError as error:
        sys.stderr.write(f"warning: the build cache could not keep {fmu}: {error.strerror or error}\n")
