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
from toggle_cosim.fmu_export.packaging import FMUBuildError

if TYPE_CHECKING:
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


def build_fmu(
    source: Path,
    model: str,
    output: Path,
    fmi_version: str = "2.0",
    interfaces: str | frozenset[str] = INTERFACES_DEFAULT,
) -> BuildReport:
    """Compile `model` from the Modelica `source` into the FMU `output`, an FMI 2.0 or FMI 3.0
    (`fmi_version="3.0"`) FMU offering `interfaces`: "both" (Co-Simulation and Model
    Exchange, the default), "cs" or "me"."""
    from toggle_cosim.fmu_export.compile import compile_model
    from toggle_cosim.fmu_export.package import write_fmu

    started = time.perf_counter()
    generated = compile_model(Path(source), model)
    compiled = time.perf_counter()
    fmu = write_fmu(
        generated,
        Path(output),
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
