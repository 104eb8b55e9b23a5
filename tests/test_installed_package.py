"""The package works outside its clone: a wheel built from this repository, installed into a
fresh virtual environment in a temporary folder, builds a plant from Modelica source that lies
in no project, runs and compares a shipped scenario, and runs the CI workflow template for a
repository of one's own (templates/ci/toggle-cosim-references.yml) step by step.

To stay fast and offline the fresh environment installs the wheel without its dependencies and
finds them through a .pth file naming a folder of links to this environment's installed
packages (toggle-cosim itself left out, so only the wheel's copy can be imported)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
TEMPLATE = ROOT / "templates" / "ci" / "toggle-cosim-references.yml"


def _run(command: list[str] | str, cwd: Path, env: dict[str, str], timeout: float = 300) -> str:
    result = subprocess.run(
        command,
        cwd=cwd,
        env=env,
        shell=isinstance(command, str),
        executable="/bin/bash" if isinstance(command, str) else None,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert result.returncode == 0, f"{command} in {cwd}: exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    return result.stdout


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A wheel of this repository, built the ordinary way (pip, isolated build)."""
    folder = tmp_path_factory.mktemp("wheel")
    _run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(folder), str(ROOT)],
        cwd=folder,
        env=dict(os.environ),
    )
    return next(folder.glob("toggle_cosim-*.whl"))


@pytest.fixture(scope="module")
def fresh_python(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A new virtual environment outside the clone whose dependencies come from this one."""
    base = tmp_path_factory.mktemp("venv")
    _run([sys.executable, "-m", "venv", "--without-pip", str(base / "venv")], cwd=base, env=dict(os.environ))
    deps = base / "deps"
    deps.mkdir()
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if entry.name.startswith(("toggle_cosim", "__editable__", "_toggle_cosim")) or entry.suffix == ".pth":
            continue
        (deps / entry.name).symlink_to(entry)
    python = base / "venv" / "bin" / "python"
    site = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    Path(site, "dependencies.pth").write_text(f"{deps}\n", encoding="utf-8")
    return python


def test_the_wheel_carries_the_modelica_source_the_scenarios_and_the_licence(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    assert "toggle_cosim/shipped/ToggleLSM/package.mo" in names
    assert "toggle_cosim/shipped/ToggleLSM/Plant.mo" in names
    assert "toggle_cosim/shipped/scenarios/fig4_nominal.yaml" in names
    assert "toggle_cosim/shipped/scenarios/references/tolerances.yaml" in names
    assert "toggle_cosim/shipped/scenarios/references/fig4_nominal/friction_ref.csv" in names
    assert "toggle_cosim/py.typed" in names and "toggle_cosim/__main__.py" in names
    assert any(name.endswith(".dist-info/licenses/LICENSE") for name in names)
    metadata = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "License-Expression: MIT" in metadata
    assert "Provides-Extra: build" in metadata and "Provides-Extra: all" in metadata
    from toggle_cosim import __version__

    assert f"Version: {__version__}\n" in metadata  # the one version, read from toggle_cosim.__version__


def test_a_wheel_outside_the_clone_builds_runs_compares_and_runs_the_ci_template(
    wheel: Path, fresh_python: Path, tmp_path: Path
) -> None:
    """The CI template's steps in a temporary repository of one's own: its install step installs
    the wheel, its build step builds the plant from a Modelica package with no pyproject.toml
    around it, its references step checks the repository's scenario against its reference."""
    repository = tmp_path / "my-plant"
    repository.mkdir()
    bin_folder = fresh_python.parent
    env = {
        **os.environ,
        "PATH": f"{bin_folder}{os.pathsep}{os.environ['PATH']}",
        "VIRTUAL_ENV": str(bin_folder.parent),
        "PIP_NO_DEPS": "1",  # the dependencies come through the .pth file (see the module's docstring)
        "PIP_NO_INDEX": "1",
        "GITHUB_STEP_SUMMARY": str(tmp_path / "step_summary.md"),
    }
    env.pop("PYTHONPATH", None)
    # the repository: the shipped scenarios (`toggle-cosim init`), one of them kept with its
    # references, and a copy of the shipped Modelica package as its own source
    workflow = yaml.safe_load(TEMPLATE.read_text(encoding="utf-8"))
    steps = [step for step in workflow["jobs"]["references"]["steps"] if "run" in step]
    variables = {**workflow["env"], "TOGGLE_COSIM_PACKAGE": str(wheel)}
    _run(steps[0]["run"], repository, {**env, **variables})  # Install toggle-cosim
    where = _run(
        [str(fresh_python), "-c", "import toggle_cosim, sys; print(toggle_cosim.__file__)"], repository, env
    ).strip()
    assert not Path(where).is_relative_to(ROOT), where  # the wheel's copy, not the clone's
    assert "Usage" in _run([str(fresh_python), "-m", "toggle_cosim", "--help"], repository, env)
    _run(["toggle-cosim", "init", "shipped"], repository, env)
    scenarios = repository / "scenarios"
    (scenarios / "references").mkdir(parents=True)
    shutil.copy(repository / "shipped/scenarios/fig4_nominal.yaml", scenarios)
    shutil.copy(repository / "shipped/scenarios/references/tolerances.yaml", scenarios / "references")
    shutil.copytree(repository / "shipped/scenarios/references/fig4_nominal", scenarios / "references/fig4_nominal")
    shipped_source = Path(where).parent / "shipped" / "ToggleLSM"
    shutil.copytree(shipped_source, repository / "modelica" / "ToggleLSM")
    assert not any(folder.joinpath("pyproject.toml").exists() for folder in (repository, *repository.parents))

    for step in steps[1:]:  # build, references, job summary
        _run(step["run"], repository, {**env, **variables})
    assert (repository / variables["FMU"]).is_file()
    assert "fig4_nominal" in (tmp_path / "step_summary.md").read_text(encoding="utf-8")
    junit = (repository / "reports" / "references.xml").read_text(encoding="utf-8")
    assert 'failures="0"' in junit and "x_B" in junit
    report = (repository / "reports" / "references" / "report.html").read_text(encoding="utf-8")
    assert "fig4_nominal/friction: PASS" in report and "<script src" not in report  # plotly.js inside

    # a shipped scenario run and compared with its stored reference, from the installed package
    _run(["toggle-cosim", "run", "scenarios/fig4_nominal.yaml", "--out", "out"], repository, env)
    compared = _run(
        [
            "toggle-cosim",
            "compare",
            "out/fig4_nominal/friction/trace.csv",
            "scenarios/references/fig4_nominal/friction_ref.csv",
        ],
        repository,
        env,
    )
    assert "pass" in compared


def test_the_ci_template_installs_builds_and_checks_references_with_folder() -> None:
    workflow = yaml.safe_load(TEMPLATE.read_text(encoding="utf-8"))
    runs = [step["run"] for step in workflow["jobs"]["references"]["steps"] if "run" in step]
    assert runs[0].startswith("python -m pip install")
    assert runs[1].startswith("toggle-cosim build --source")
    assert "toggle-cosim references" in runs[2] and "--folder" in runs[2] and "--junit" in runs[2]
    assert "--html" in runs[2]
    assert "GITHUB_STEP_SUMMARY" in runs[3]
    uploads = [step for step in workflow["jobs"]["references"]["steps"] if "upload-artifact" in step.get("uses", "")]
    assert [step["with"]["path"] for step in uploads] == ["reports/", "reports/references/report.html"]
