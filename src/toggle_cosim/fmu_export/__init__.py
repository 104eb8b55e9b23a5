"""Modelica source -> FMI 2.0 or 3.0 FMU (Co-Simulation, Model Exchange or both). `build_fmu` is the one entry point.
The Modelica compiler is imported when a model is compiled, not with this package.

source (package dir) --source.py--> IR --compile.py--> C + tables
    --model_description.py--> modelDescription.xml --package.py--> .fmu
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toggle_cosim import __version__
from toggle_cosim.fmu_export.interfaces import CHOICES as INTERFACE_CHOICES
from toggle_cosim.fmu_export.interfaces import DEFAULT as INTERFACES_DEFAULT
from toggle_cosim.fmu_export.packaging import FMUBuildError, model_identifier_for

if TYPE_CHECKING:
    from toggle_cosim.fmu_export.build_cache import CachedBuild
    from toggle_cosim.fmu_export.package import BuiltFMU

__all__ = [
    "FMI_VERSIONS",
    "INTERFACES_DEFAULT",
    "INTERFACE_CHOICES",
    "BuildReport",
    "FMUBuildError",
    "ModelCompileError",
    "build_fmu",
]


@dataclass(frozen=True)
class BuildReport:
    fmu: BuiltFMU
    compile_seconds: float
    package_seconds: float
    variables: int
    states: int
    event_indicators: int
    from_cache: bool = False  # a copy of an identical earlier build (`build_cache`): nothing compiled


def build_fmu(
    source: Path,
    model: str,
    output: Path,
    fmi_version: str = "2.0",
    interfaces: str | frozenset[str] = INTERFACES_DEFAULT,
) -> BuildReport:
    """Compile `model` from the Modelica `source` into the FMU `output`, an FMI 2.0 or FMI 3.0
    (`fmi_version="3.0"`) FMU offering `interfaces`: "both" (Co-Simulation and Model
    Exchange, the default), "cs" or "me". An identical earlier build kept in the user's build
    cache (`build_cache`) is copied instead of compiled (`BuildReport.from_cache`)."""
    from toggle_cosim.fmu_export import build_cache

    output = Path(output)
    offered = _offered(interfaces)
    key = None
    if build_cache.enabled() and offered is not None:
        try:
            key = build_cache.build_key(Path(source), model, model_identifier_for(output), fmi_version, offered)
        except OSError:
            key = None  # a source that cannot be read: the build says so, as without the cache
    if key is not None:
        found = build_cache.lookup(key)
        if found is not None:
            return _copied(found, output, fmi_version, offered)
    report = _compiled(Path(source), model, output, fmi_version, interfaces)
    if key is not None:
        facts = build_cache.CachedBuild(report.fmu.guid, report.variables, report.states, report.event_indicators)
        build_cache.keep(key, output, facts)
    return report


def _offered(interfaces: str | frozenset[str]) -> frozenset[str] | None:
    """The interfaces asked for, or None when they are not valid (the build then says why)."""
    from toggle_cosim.fmu_export import interfaces as interface_types

    try:
        return interface_types.parse(interfaces)
    except ValueError:
        return None


def _copied(found: tuple[bytes, CachedBuild], output: Path, fmi_version: str, offered: frozenset[str]) -> BuildReport:
    """The report of a build taken from the cache: its checked bytes written to `output` as every
    output is written (whole or not at all)."""
    from toggle_cosim.files.outputs import FMU, write_file
    from toggle_cosim.fmu_export.package import BuiltFMU

    data, facts = found
    started = time.perf_counter()
    write_file(output, lambda stream: stream.write(data), binary=True, what="FMU", kind=FMU)
    fmu = BuiltFMU(output, facts.guid, model_identifier_for(output), len(data), fmi_version, offered)
    return BuildReport(
        fmu=fmu,
        compile_seconds=0.0,
        package_seconds=time.perf_counter() - started,
        variables=facts.variables,
        states=facts.states,
        event_indicators=facts.event_indicators,
        from_cache=True,
    )


def _compiled(
    source: Path, model: str, output: Path, fmi_version: str, interfaces: str | frozenset[str]
) -> BuildReport:
    """Compile and package, as without the cache."""
    from toggle_cosim.fmu_export.compile import compile_model
    from toggle_cosim.fmu_export.package import write_fmu

    started = time.perf_counter()
    generated = compile_model(source, model)
    compiled = time.perf_counter()
    fmu = write_fmu(
        generated,
        output,
        tool=f"toggle-cosim {__version__} (modelica 0.0.205)",
        fmi_version=fmi_version,
        interfaces=interfaces,
    )
    finished = time.perf_counter()
    return BuildReport(
        fmu=fmu,
        compile_seconds=compiled - started,
        package_seconds=finished - compiled,
        variables=len(generated.variables),
        states=len(generated.states),
        event_indicators=generated.event_count,
    )


def __getattr__(name: str) -> Any:
    """The names that need the Modelica compiler (the `[build]` extra), imported on first use:
    the package's other modules (`packaging`, used by `controller_fmu`) do without it."""
    if name == "ModelCompileError":
        from toggle_cosim.fmu_export.compile import ModelCompileError

        return ModelCompileError
    if name == "FMI_VERSIONS":
        from toggle_cosim.fmu_export.package import FMI_VERSIONS

        return FMI_VERSIONS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
