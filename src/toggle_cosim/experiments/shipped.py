"""What the project ships and where it lies, in the package and in a project folder: the plant's Modelica source
and the FMUs built from it, the scenario files and their stored references. The command line's
defaults (`cli.app`) and the Python API's look-ups (`api.project`) both read these."""

from __future__ import annotations

from pathlib import Path

# The Modelica package and the scenarios shipped with the package (package data; in a clone,
# links to the repository's modelica/ToggleLSM and scenarios/, so there is one copy of each).
SHIPPED = Path(__file__).resolve().parent.parent / "shipped"
DEFAULT_SOURCE = SHIPPED / "ToggleLSM"  # what `toggle-cosim build` compiles when no --source is given
SHIPPED_SCENARIO_FOLDER = SHIPPED / "scenarios"
PROJECT_SOURCE = Path("modelica/ToggleLSM")  # where a project folder (a clone) keeps the Modelica source
DEFAULT_MODEL = "ToggleLSM.Plant"
DEFAULT_FMU = Path("fmus/ToggleLSM.fmu")
# What `toggle-cosim build` writes when no --model is given: every shipped plant.
DEFAULT_BUILDS = (
    (DEFAULT_MODEL, DEFAULT_FMU),
    ("ToggleLSM.PlantNoGravity", Path("fmus/ToggleLSM_NoGravity.fmu")),
)
# The controller FMU (built from control/laws.py, no Modelica): its --model name and files.
CONTROLLER_MODEL = "ToggleVSC"
DEFAULT_CONTROLLER = Path(f"fmus/{CONTROLLER_MODEL}.fmu")
SCENARIOS = Path("scenarios")
DEFAULT_REFERENCES = SCENARIOS / "references"
PAPER_SCENARIOS = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")
SHIPPED_SCENARIOS = (
    *PAPER_SCENARIOS,
    "swap_no_gravity",
    "integral_load",
    "friction_models",
    "step_load",
    "measured_load",
)


def project_folder(start: Path | None = None) -> Path | None:
    """The nearest folder from `start` (default: the current folder) upward that holds the
    project's scenarios and Modelica source; None when there is none."""
    here = (Path(start) if start is not None else Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if (folder / SCENARIOS).is_dir() and (folder / PROJECT_SOURCE).is_dir():
            return folder
    return None
