"""Each optional extra, installed alone from the project's wheel into a clean virtual environment
outside the clone (its dependencies resolved by pip, nothing linked from the development
environment), runs its own commands:

| extra | commands run |
|---|---|
| (core) | `run` a scenario with a prebuilt plant FMU, `compare` its trace with the stored reference |
| build | `build` a plant FMU from the shipped Modelica source |
| sweep | a two-case `sweep` with its table and heat maps |
| ci | `references` with its JUnit report and Markdown summary |
| plot | `run`, then `plot` the results folder |
| design | `linearize` into a .mat file, and `tc.linearize(...).system` as a python-control StateSpace |
| report | `run`, then `report` the results folder as one HTML page |
| docs | `mkdocs build` of a page rendering `toggle_cosim.simulate`'s docstring from the installed package |

`pip install 'toggle-cosim[build]'` used to leave `toggle-cosim build` without scipy, which the
pinned Modelica compiler imports: the development environment (every extra, and the test extra's
scipy) hid it. The environments are made two at a time with pip and its cache (the machine's
package index or mirror): the core once into a new venv, each extra into a hard-linked copy of
it (see `environments`). Measured on two shared cores under a load average of 4: about 250 s
for the module, 166 s of it the environments (with the session's plant FMU and wheel), 35 s the
CI template's steps."""

from __future__ import annotations

import concurrent.futures
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.slow  # each extra installed alone into a fresh venv (minutes)

ROOT = Path(__file__).resolve().parents[1]
TEMPLATE = ROOT / "templates" / "ci" / "toggle-cosim-references.yml"
EXTRAS = ("core", "build", "sweep", "ci", "plot", "design", "report", "docs")


def _run(command: list[str], cwd: Path, env: dict[str, str], timeout: float = 300) -> str:
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout, check=False)
    assert result.returncode == 0, f"{command} in {cwd}: exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    return result.stdout


def _clean_env(venv: Path) -> dict[str, str]:
    """The environment of a user of `venv`: its bin first on PATH, nothing of ours on the path."""
    env = {key: value for key, value in os.environ.items() if not key.startswith(("PYTHON", "VIRTUAL_ENV"))}
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{os.environ['PATH']}", VIRTUAL_ENV=str(venv))
    return env


def _install(requirement: str, venv: Path) -> Path:
    """pip installs `requirement` (and what it needs, resolved as for any user) into `venv`."""
    install = [sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python"), "install", "-q", requirement]
    _run(install, venv.parent, _clean_env(venv), timeout=900)
    return venv


def _copy(core: Path, venv: Path) -> Path:
    """A copy of the core environment (hard links: seconds, no space), its scripts pointed at its
    own interpreter; pip never writes into an installed file, so the core stays as it was."""
    subprocess.run(["cp", "-al", str(core), str(venv)], check=True, timeout=120)
    for script in (venv / "bin").iterdir():
        if script.is_file() and not script.is_symlink():
            text = script.read_bytes()
            if text.startswith(b"#!" + str(core).encode()):
                script.unlink()
                script.write_bytes(text.replace(str(core).encode(), str(venv).encode(), 1))
                script.chmod(0o755)
    return venv


@pytest.fixture(scope="module")
def environments(project_wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The core (the wheel and its dependencies) installed once into a new venv; each extra then
    in a copy of it, `toggle-cosim[extra]` resolved by pip on top of the core: the environment a
    user gets from `pip install 'toggle-cosim[extra]'`, two installs at a time."""
    base = tmp_path_factory.mktemp("extras")
    core = base / "core"
    subprocess.run(
        [sys.executable, "-m", "venv", str(core)], check=True, timeout=300
    )  # with pip: the template calls it
    _install(str(project_wheel), core)
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        made = {
            extra: pool.submit(_install, f"toggle-cosim[{extra}] @ {project_wheel.as_uri()}", _copy(core, base / extra))
            for extra in EXTRAS[1:]
        }
        made["template"] = pool.submit(_copy, core, base / "template")  # the CI template installs into it
        return {"core": core, **{extra: future.result() for extra, future in made.items()}}


def _short_scenario(folder: Path, plant_fmu: Path) -> Path:
    """The shipped fig4_nominal scenario with its references (`toggle-cosim init`), the plant FMU given."""
    path = folder / "scenarios" / "fig4_nominal.yaml"
    document = yaml.safe_load(path.read_text(encoding="utf-8"))
    document["fmu"] = str(plant_fmu)
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    return path


@pytest.mark.parametrize("extra", EXTRAS)
def test_each_extra_alone_runs_its_commands(
    extra: str, environments: dict[str, Path], plant_fmu: Path, tmp_path: Path
) -> None:
    venv = environments[extra]
    env = _clean_env(venv)
    python, program = str(venv / "bin" / "python"), str(venv / "bin" / "toggle-cosim")
    where = _run([python, "-c", "import toggle_cosim; print(toggle_cosim.__file__)"], tmp_path, env).strip()
    assert not Path(where).is_relative_to(ROOT), where  # the wheel's copy
    probe = "import importlib.util as u; print(u.find_spec('pytest') is None)"
    assert _run([python, "-c", probe], tmp_path, env).strip() == "True"  # nothing of the development environment
    _run([program, "init", "."], tmp_path, env)
    scenario = _short_scenario(tmp_path, plant_fmu)
    if extra == "core":
        _run([program, "run", str(scenario), "--out", "out", "-q"], tmp_path, env)
        reference = tmp_path / "scenarios" / "references" / "fig4_nominal" / "friction_ref.csv"
        assert "pass" in _run(
            [program, "compare", "out/fig4_nominal/friction/trace.csv", str(reference)], tmp_path, env
        )
    elif extra == "build":
        built = _run([program, "build", "--model", "ToggleLSM.Plant", "--out", "fmus/mine.fmu"], tmp_path, env)
        assert built.startswith("built fmus/mine.fmu") and (tmp_path / "fmus" / "mine.fmu").is_file()
    elif extra == "sweep":
        sweep = tmp_path / "sweep.yaml"
        sweep.write_text(
            yaml.safe_dump({"base": "scenarios/fig4_nominal.yaml", "axes": {"plant.F_E": {"values": [0.0, 20.0]}}}),
            encoding="utf-8",
        )
        _run([program, "sweep", str(sweep), "--out", "swept", "--workers", "2", "-q"], tmp_path, env)
        assert (tmp_path / "swept" / "results.parquet").is_file()
        assert list((tmp_path / "swept" / "heatmaps").glob("*.png"))
    elif extra == "ci":
        _run(
            [program, "references", str(scenario), "--folder", "scenarios/references", "--out", "reports"]
            + ["--junit", "reports/references.xml", "--summary", "reports/references.md"],
            tmp_path,
            env,
        )
        assert 'failures="0"' in (tmp_path / "reports" / "references.xml").read_text(encoding="utf-8")
    elif extra == "plot":
        _run([program, "run", str(scenario), "--out", "out", "-q"], tmp_path, env)
        _run([program, "plot", "out/fig4_nominal"], tmp_path, env)
        assert (tmp_path / "out" / "fig4_nominal" / "figure.png").read_bytes()[:4] == b"\x89PNG"
    elif extra == "report":
        _run([program, "run", str(scenario), "--out", "out", "-q"], tmp_path, env)
        _run([program, "report", "out/fig4_nominal", "--out", "page.html"], tmp_path, env)
        assert (tmp_path / "page.html").read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    elif extra == "design":
        arguments = [str(scenario), "--variant", "no_friction", "--x-B", "0.3", "-o", "lin.mat"]
        _run([program, "linearize", *arguments], tmp_path, env)
        assert (tmp_path / "lin.mat").read_bytes().startswith(b"MATLAB 5.0 MAT-file")
        script = (
            "import toggle_cosim as tc; "
            f"run = tc.load_scenario({str(scenario)!r})['no_friction']; "
            "print(type(tc.linearize(run, 0.3).system).__name__)"
        )
        assert _run([python, "-c", script], tmp_path, env).strip() == "StateSpace"
    else:
        (tmp_path / "docs").mkdir()
        (tmp_path / "docs" / "index.md").write_text("# API\n\n::: toggle_cosim.api.simulation.simulate\n")
        config = {
            "site_name": "mine",
            "theme": {"name": "material"},
            "plugins": [
                "search",
                {
                    "mkdocstrings": {
                        "handlers": {"python": {"options": {"show_source": False, "show_root_heading": True}}}
                    }
                },
            ],
        }
        (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config), encoding="utf-8")
        _run([python, "-m", "mkdocs", "build", "--strict", "--site-dir", "site"], tmp_path, env)
        assert "doc-heading" in (tmp_path / "site" / "index.html").read_text(encoding="utf-8")


def test_the_ci_template_runs_as_written(environments: dict[str, Path], project_wheel: Path, tmp_path: Path) -> None:
    """templates/ci/toggle-cosim-references.yml's steps in a repository of one's own: its install
    line with TOGGLE_COSIM_SOURCE left empty stops with one line (exit 2); with the file URL of a
    wheel it installs toggle-cosim[build,ci] (pip resolving the extras' dependencies), then builds
    the plant from a Modelica package that lies in no project and checks the repository's
    scenario against its reference, with the JUnit report and the job summary."""
    venv = environments["template"]
    env = {**_clean_env(venv), "GITHUB_STEP_SUMMARY": str(tmp_path / "step_summary.md")}
    repository = tmp_path / "my-plant"
    repository.mkdir()
    workflow = yaml.safe_load(TEMPLATE.read_text(encoding="utf-8"))
    steps = [step["run"] for step in workflow["jobs"]["references"]["steps"] if "run" in step]
    unset = subprocess.run(
        ["bash", "-e", "-c", steps[0]], cwd=repository, env={**env, **workflow["env"]}, capture_output=True, text=True
    )
    assert unset.returncode == 2 and unset.stderr.count("\n") == 1, unset.stderr
    assert "set TOGGLE_COSIM_SOURCE" in unset.stderr
    variables = {**workflow["env"], "TOGGLE_COSIM_SOURCE": project_wheel.as_uri()}
    _run(["bash", "-e", "-c", steps[0]], repository, {**env, **variables}, timeout=900)  # Install toggle-cosim
    python = str(venv / "bin" / "python")
    where = _run([python, "-c", "import toggle_cosim; print(toggle_cosim.__file__)"], repository, env).strip()
    _run([str(venv / "bin" / "toggle-cosim"), "init", "shipped"], repository, env)
    scenarios = repository / "scenarios"
    (scenarios / "references").mkdir(parents=True)
    shipped = repository / "shipped" / "scenarios"
    (scenarios / "fig4_nominal.yaml").write_bytes((shipped / "fig4_nominal.yaml").read_bytes())
    (scenarios / "references" / "tolerances.yaml").write_bytes(
        (shipped / "references" / "tolerances.yaml").read_bytes()
    )
    shutil.copytree(shipped / "references" / "fig4_nominal", scenarios / "references" / "fig4_nominal")
    shutil.copytree(Path(where).parent / "shipped" / "ToggleLSM", repository / "modelica" / "ToggleLSM")
    assert not any((folder / "pyproject.toml").exists() for folder in (repository, *repository.parents))
    for step in steps[1:]:  # build, references, pack and verify, job summary
        _run(["bash", "-e", "-c", step], repository, {**env, **variables})
    assert (repository / variables["FMU"]).is_file()
    assert "fig4_nominal" in (tmp_path / "step_summary.md").read_text(encoding="utf-8")
    junit = (repository / "reports" / "references.xml").read_text(encoding="utf-8")
    assert 'failures="0"' in junit and "x_B" in junit
    verified = (repository / "reports" / "verify.xml").read_text(encoding="utf-8")
    assert 'failures="0"' in verified and "fig4_nominal/friction" in verified
    report = (repository / "reports" / "references" / "report.html").read_text(encoding="utf-8")
    assert "fig4_nominal/friction: PASS" in report and "<script src" not in report  # plotly.js inside
