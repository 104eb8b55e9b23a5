"""A command whose optional extra is not installed says which extra to install, in one line,
exit 2, before it writes anything; and `toggle-cosim build` without options builds the shipped
plants into ./fmus of the current folder (the compiler itself replaced by a recorder here: the
real build runs in test_installed_package.py and the documentation's examples)."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.cli.app import DEFAULT_SOURCE, EXTRAS

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "fig4_nominal.yaml"
REFERENCE = ROOT / "scenarios" / "references" / "fig4_nominal" / "friction_ref.csv"


def _invoke(arguments: list[str]):  # noqa: ANN202 - click's Result
    return CliRunner().invoke(main, arguments, catch_exceptions=False)


@pytest.mark.parametrize(
    ("missing", "arguments", "extra"),
    [
        ("modelica", ["build", "--model", "ToggleLSM.Plant", "--out", "fmus/x.fmu"], "build"),
        ("matplotlib", ["plot", "out/fig4_nominal"], "plot"),
        ("pyarrow", ["sweep", str(ROOT / "scenarios" / "sweep_FE_mB.yaml")], "sweep"),
        ("junitparser", ["references", str(SCENARIO)], "ci"),
        ("junitparser", ["compare", str(REFERENCE), str(REFERENCE), "--junit", "r.xml"], "ci"),
        ("matplotlib", ["paper", "--skip-build"], "plot"),
        ("modelica", ["paper"], "build"),
        ("plotly", ["report", "out"], "report"),
        ("plotly", ["references", str(SCENARIO), "--html"], "report"),
        ("plotly", ["sweep", str(ROOT / "scenarios" / "sweep_FE_mB.yaml"), "--html"], "report"),
    ],
)
def test_a_missing_extra_is_named_in_one_line(
    missing: str, arguments: list[str], extra: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, missing, None)  # `import missing` now raises ModuleNotFoundError
    result = _invoke(arguments)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert f"pip install 'toggle-cosim[{extra}]'" in lines[0] and f"'{missing}'" in lines[0]
    assert lines[0].startswith(f"error: toggle-cosim {arguments[0]} needs")
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_a_module_missing_deep_inside_a_command_is_named_too(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Not only the modules a command checks first: any import of an extra's module."""
    monkeypatch.setitem(sys.modules, "buildingspy", None)
    monkeypatch.setitem(sys.modules, "buildingspy.io", None)
    monkeypatch.setitem(sys.modules, "buildingspy.io.outputfile", None)
    mat = tmp_path / "result.mat"
    mat.write_bytes(b"\0" * 64)
    result = _invoke(["compare", str(mat), str(REFERENCE)])
    assert result.exit_code == 2
    assert "pip install 'toggle-cosim[ci]'" in result.output


def test_a_missing_core_module_is_not_disguised_as_an_extra() -> None:
    """A module outside every extra means a broken installation: no advice to install an extra."""
    from toggle_cosim.cli.app import missing_extra

    assert missing_extra(ModuleNotFoundError("x", name="numpy"), "toggle-cosim run") is None
    assert "[sweep]" in missing_extra(ModuleNotFoundError("x", name="distributed.client"), "toggle-cosim sweep")


def test_every_extra_module_is_declared_in_its_extra() -> None:
    """EXTRAS (module -> extra) and pyproject.toml's optional dependencies say the same."""
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    distribution = {"dask": "distributed"}  # a module that comes with another distribution of the extra
    for module, extra in EXTRAS.items():
        names = [requirement.split("=")[0].split(">")[0].split("<")[0].lower() for requirement in extras[extra]]
        assert distribution.get(module, module) in names, (module, extra)


@pytest.mark.slow
def test_build_without_options_builds_the_shipped_plants_into_fmus_here(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    calls = []

    def recorder(source: Path, model: str, output: Path, fmi_version: str, interfaces: str):  # noqa: ANN202
        calls.append((source, model, output, interfaces))
        fmu = SimpleNamespace(path=output, fmi_version=fmi_version, interfaces={"CoSimulation"}, size_bytes=1, guid="g")
        return SimpleNamespace(
            fmu=fmu,
            variables=1,
            states=1,
            event_indicators=0,
            compile_seconds=0.0,
            package_seconds=0.0,
            from_cache=False,
        )

    monkeypatch.setattr("toggle_cosim.fmu_export.build_fmu", recorder)
    monkeypatch.setattr("toggle_cosim.cli.build_command._carry_evidence", lambda *args: "nothing (stubbed)")
    monkeypatch.chdir(tmp_path)
    assert _invoke(["build"]).exit_code == 0
    assert _invoke(["build", "--interfaces", "cs"]).exit_code == 0
    assert _invoke(["build", "--model", "ToggleLSM.Plant", "--interfaces", "me", "--fmi-version", "3.0"]).exit_code == 0
    assert [(model, str(output), interfaces) for _, model, output, interfaces in calls] == [
        ("ToggleLSM.Plant", "fmus/ToggleLSM.fmu", "both"),
        ("ToggleLSM.PlantNoGravity", "fmus/ToggleLSM_NoGravity.fmu", "both"),
        ("ToggleLSM.Plant", "fmus/ToggleLSM_CS.fmu", "cs"),  # never the default FMU's name
        ("ToggleLSM.PlantNoGravity", "fmus/ToggleLSM_NoGravity_CS.fmu", "cs"),
        ("ToggleLSM.Plant", "fmus/ToggleLSM3_ME.fmu", "me"),
    ]
    assert all(source == DEFAULT_SOURCE and (source / "package.mo").is_file() for source, *_ in calls)


def test_build_refuses_to_overwrite_a_file_that_is_not_an_fmu(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    precious = tmp_path / "notes.fmu"
    precious.write_text("not an FMU", encoding="utf-8")
    result = _invoke(["build", "--out", str(precious)])
    assert result.exit_code == 2 and "exists and is not an FMU" in result.output
    assert precious.read_text(encoding="utf-8") == "not an FMU"


def test_init_copies_the_shipped_scenarios_once(tmp_path: Path) -> None:
    result = _invoke(["init", str(tmp_path / "study")])
    assert result.exit_code == 0, result.output
    copied = tmp_path / "study" / "scenarios"
    assert (copied / "fig4_nominal.yaml").read_bytes() == SCENARIO.read_bytes()
    assert (copied / "references" / "fig4_nominal" / "friction_ref.csv").read_bytes() == REFERENCE.read_bytes()
    again = _invoke(["init", str(tmp_path / "study")])
    assert again.exit_code == 2 and "exists already" in again.output
