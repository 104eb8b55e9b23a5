"""Shared fixtures: the plant FMU, built once per test session from the Modelica source."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest


def pytest_configure(config: pytest.Config) -> None:
    """A test runner started in the background by a shell without job control inherits SIGINT
    ignored, and Python then leaves it ignored, in this process and in every command it starts.
    The tests that interrupt a run as Ctrl-C or a notebook's stop button does need SIGINT to
    arrive: give this process Python's own handler, so its commands start with the default."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))  # reference_dynamics.py beside the tests


@pytest.fixture(scope="session")
def plant_build(tmp_path_factory: pytest.TempPathFactory):
    """Build fmus/ToggleLSM.fmu's twin from modelica/ToggleLSM into a temporary folder."""
    from toggle_cosim.fmu_export import build_fmu

    output = tmp_path_factory.mktemp("fmu") / "ToggleLSM.fmu"
    return build_fmu(ROOT / "modelica" / "ToggleLSM", "ToggleLSM.Plant", output)


@pytest.fixture(scope="session")
def plant_fmu(plant_build) -> Path:
    return plant_build.fmu.path


@pytest.fixture(scope="session")
def plant_model():
    """ToggleLSM.Plant compiled from modelica/ToggleLSM once per session (the Modelica compile is
    most of a build): the tests that package it in other forms share it."""
    from toggle_cosim.fmu_export.compile import compile_model

    return compile_model(ROOT / "modelica" / "ToggleLSM", "ToggleLSM.Plant")


@pytest.fixture(scope="session")
def plant3_fmu(plant_model, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The plant as FMI 3.0 (Co-Simulation and Model Exchange), packaged from `plant_model`."""
    from toggle_cosim import __version__
    from toggle_cosim.fmu_export.package import write_fmu

    output = tmp_path_factory.mktemp("fmu3") / "ToggleLSM3.fmu"
    return write_fmu(plant_model, output, f"toggle-cosim {__version__} (tests)", fmi_version="3.0").path


@pytest.fixture(scope="session")
def no_gravity_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The second plant, built from the variant ToggleLSM.PlantNoGravity of the same source."""
    from toggle_cosim.fmu_export import build_fmu

    output = tmp_path_factory.mktemp("fmu-nog") / "ToggleLSM_NoGravity.fmu"
    return build_fmu(ROOT / "modelica" / "ToggleLSM", "ToggleLSM.PlantNoGravity", output).fmu.path


PRESS_SYSTEM = ROOT / "examples" / "press_system"
PRESS_PARTS = ("PositionSensor", "DieLoad")


@pytest.fixture(scope="session")
def press_parts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The press example's parts (examples/press_system/*.mo), each built once per session as
    our build writes it for a user: FMI 2.0, Co-Simulation. Keys: the model names
    (PositionSensor, DieLoad); about 1 s each."""
    from toggle_cosim.fmu_export import build_fmu

    folder = tmp_path_factory.mktemp("press-parts")
    return {
        name: build_fmu(PRESS_SYSTEM / f"{name}.mo", name, folder / f"{name}.fmu", interfaces="cs").fmu.path
        for name in PRESS_PARTS
    }


@pytest.fixture(scope="session")
def shim_fmu(plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The plant behind the fault shim of `fault_plants` (TOGGLE_FAULT_* in the environment
    decide how it misbehaves; without them it is the plant)."""
    from fault_plants import make_faulty_fmu

    return make_faulty_fmu(plant_fmu, tmp_path_factory.mktemp("shim") / "Shim.fmu")


@pytest.fixture(scope="session")
def project_wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A wheel of this repository, built once the ordinary way (pip, isolated build)."""
    folder = tmp_path_factory.mktemp("wheel")
    built = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(folder), str(ROOT)],
        cwd=folder,
        env=dict(os.environ),
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert built.returncode == 0, built.stderr
    return next(folder.glob("toggle_cosim-*.whl"))


@pytest.fixture(scope="session")
def vsc_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in law's controller FMU (FMI 2.0 Co-Simulation), built once per session."""
    from toggle_cosim.controller_fmu import build_controller_fmu

    return build_controller_fmu(tmp_path_factory.mktemp("vsc") / "ToggleVSC.fmu", "2.0").path
