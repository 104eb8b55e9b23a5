"""The project's own files from Python: the shipped scenarios, the plant FMU (built from the
Modelica source when it is missing) and the stored reference of a run.

The project folder is the nearest folder from the current one upward that holds `scenarios/`
and `modelica/ToggleLSM/` (a notebook in `examples/` finds the checkout above it), else the
checkout this package was installed from in editable mode. Without one (an installed package
used from any folder), the scenarios and the Modelica source shipped inside the package are
used, and plant FMUs are built into `fmus/` of the current folder.
"""

from __future__ import annotations

from pathlib import Path

from toggle_cosim.experiments import shipped
from toggle_cosim.experiments.references import reference_stem
from toggle_cosim.runs.definition import Run

__all__ = ["plant_fmu", "project_folder", "shipped_scenarios", "stored_reference"]


def project_folder() -> Path | None:
    """The toggle-cosim project folder (see the module's docstring); None if there is none."""
    return shipped.project_folder() or shipped.project_folder(Path(__file__).resolve().parent)


def _scenario_folder() -> Path:
    """The project's scenarios/, else the package's shipped copy."""
    root = project_folder()
    return root / shipped.SCENARIOS if root is not None else shipped.SHIPPED_SCENARIO_FOLDER


def shipped_scenarios() -> dict[str, Path]:
    """The scenario files the project ships, by name: the paper's cases first
    (fig4_nominal, fig5_external_force, fig6_mass_variation), then the others."""
    folder = _scenario_folder()
    return {name: folder / f"{name}.yaml" for name in shipped.SHIPPED_SCENARIOS if (folder / f"{name}.yaml").is_file()}


def _older_than_source(fmu: Path, source: Path) -> bool:
    """Whether a file of the Modelica source changed after `fmu` was written (as make decides)."""
    built = fmu.stat().st_mtime_ns
    return any(path.stat().st_mtime_ns > built for path in source.rglob("*") if path.is_file())


def plant_fmu(model: str = shipped.DEFAULT_MODEL, *, rebuild: bool = False) -> Path:
    """The path of a shipped plant FMU (default `fmus/ToggleLSM.fmu`, the paper's plant;
    "ToggleLSM.PlantNoGravity" is the other), built from the project's Modelica source first if
    it is not there, is older than a file of the source, or `rebuild` is true (the Modelica
    compiler and a C compiler: about a minute). Raises the build's ModelCompileError or
    FMUBuildError if it cannot be built."""
    builds = dict(shipped.DEFAULT_BUILDS)
    if model not in builds:
        raise ValueError(f"model {model!r} is not a shipped plant (choose one of {', '.join(builds)})")
    root = project_folder()
    if root is None:
        path, source = Path.cwd() / builds[model], shipped.DEFAULT_SOURCE
    else:
        path, source = root / builds[model], root / shipped.PROJECT_SOURCE
    if rebuild or not path.is_file() or _older_than_source(path, source):
        from toggle_cosim.fmu_export import build_fmu

        build_fmu(source, model, path)
    return path


def stored_reference(run: Run) -> Path:
    """The stored reference trace of a shipped scenario's run:
    `scenarios/references/<scenario>/<variant>_ref.csv` (it may not exist for other runs)."""
    stem = reference_stem(_scenario_folder() / "references", run)
    return stem.with_name(f"{stem.name}_ref.csv")
