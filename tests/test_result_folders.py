"""Results of different sources or settings never share a folder (`runs.definition.results_folder`):
a scenario file's run as the file says it writes OUT/<scenario>/<variant>, an SSP's run
OUT/<archive>_ssp/<set>, a run under a --coupling the file does not give OUT/<scenario>_<coupling>/<variant>;
a re-run that replaces its own results says so on its line; two runs that would write one folder,
or a foreign file where a run's trace goes, are refused before any run."""

from __future__ import annotations

import dataclasses
from pathlib import Path, PurePosixPath

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.files.traces import read_csv
from toggle_cosim.runs.definition import results_folder

ROOT = Path(__file__).resolve().parents[1]
FIG4 = ROOT / "scenarios" / "fig4_nominal.yaml"


def _short_fig4(tmp_path: Path, plant_fmu: Path, **keys: object) -> Path:
    document = yaml.safe_load(FIG4.read_text(encoding="utf-8"))
    document.update(t_end=0.02, fmu=str(plant_fmu), **keys)
    path = tmp_path / "fig4.yaml"
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    return path


def test_each_source_and_setting_has_its_own_folder() -> None:
    friction = next(run for run in load_scenario(FIG4) if run.variant == "friction")
    assert results_folder(friction) == PurePosixPath("fig4_nominal/friction")  # unchanged for users and docs
    assert friction.folder == results_folder(friction)
    jacobi = dataclasses.replace(friction, coupling="jacobi")
    assert results_folder(jacobi) == PurePosixPath("fig4_nominal_jacobi/friction")
    ssp = dataclasses.replace(friction, source=Path("out/fig4.ssp"))
    assert results_folder(ssp) == PurePosixPath("fig4_ssp/friction")
    assert results_folder(dataclasses.replace(ssp, coupling="jacobi")) == PurePosixPath("fig4_ssp_jacobi/friction")
    # a file that asks for jacobi itself keeps the plain folder; --coupling gauss-seidel then gets its own
    declared = dataclasses.replace(jacobi, resolved={**jacobi.resolved, "coupling": "jacobi"})
    assert results_folder(declared) == PurePosixPath("fig4_nominal/friction")
    back = dataclasses.replace(declared, coupling="gauss-seidel")
    assert results_folder(back) == PurePosixPath("fig4_nominal_gauss-seidel/friction")


@pytest.mark.slow
def test_a_jacobi_run_keeps_the_default_runs_results_and_a_rerun_says_it_replaced_its_own(
    tmp_path: Path, plant_fmu: Path
) -> None:
    scenario = _short_fig4(tmp_path, plant_fmu)
    out = tmp_path / "out"
    first = CliRunner().invoke(main, ["run", str(scenario), "--out", str(out), "-q", "-j", "1"])
    assert first.exit_code == 0, first.output
    assert "replaced" not in first.output
    default = (out / "fig4_nominal" / "friction" / "trace.csv").read_bytes()
    jacobi = CliRunner().invoke(
        main, ["run", str(scenario), "--out", str(out), "-q", "-j", "1", "--coupling", "jacobi"]
    )
    assert jacobi.exit_code == 0, jacobi.output
    assert (out / "fig4_nominal" / "friction" / "trace.csv").read_bytes() == default  # not replaced
    assert (out / "fig4_nominal_jacobi" / "friction" / "trace.csv").read_bytes() != default
    assert "replaced" not in jacobi.output
    again = CliRunner().invoke(main, ["run", str(scenario), "--out", str(out), "-q", "-j", "1"])
    assert again.exit_code == 0, again.output
    lines = again.output.strip().splitlines()
    assert len(lines) == 2 and all(
        line.endswith(f"-> {out / 'fig4_nominal' / variant} (replaced the earlier run's files there)")
        for line, variant in zip(lines, ("friction", "no_friction"), strict=True)
    ), again.output


@pytest.mark.slow
def test_an_ssp_run_keeps_the_yaml_runs_results(tmp_path: Path, plant_fmu: Path) -> None:
    """`run out/fig4.ssp --parameter-set friction` used to replace out/fig4_nominal/friction."""
    from toggle_cosim.controller_fmu import build_controller_fmu
    from toggle_cosim.ssp.writer import write_ssp

    scenario = _short_fig4(tmp_path, plant_fmu)
    out = tmp_path / "out"
    assert CliRunner().invoke(main, ["run", str(scenario), "--out", str(out), "-q", "-j", "1"]).exit_code == 0
    default = (out / "fig4_nominal" / "friction" / "trace.csv").read_bytes()
    controller = build_controller_fmu(tmp_path / "ToggleVSC.fmu").path
    study = write_ssp(scenario, out / "fig4.ssp", plant_fmu, controller)
    ran = CliRunner().invoke(main, ["run", str(study), "--parameter-set", "friction", "--out", str(out), "-q"])
    assert ran.exit_code == 0, ran.output
    assert ran.output.rstrip().endswith(f"-> {out / 'fig4_ssp' / 'friction'}"), ran.output
    assert (out / "fig4_nominal" / "friction" / "trace.csv").read_bytes() == default
    yaml_run, ssp_run = (read_csv(out / top / "friction" / "trace.csv") for top in ("fig4_nominal", "fig4_ssp"))
    assert np.array_equal(yaml_run.column("x_B"), ssp_run.column("x_B"))  # the same run, bit for bit


def test_two_runs_of_one_folder_and_a_foreign_file_are_refused_before_any_run(tmp_path: Path, plant_fmu: Path) -> None:
    scenario = _short_fig4(tmp_path, plant_fmu)
    out = tmp_path / "out"
    # a scenario named like another's folder under --coupling jacobi
    renamed = tmp_path / "renamed.yaml"
    document = yaml.safe_load(scenario.read_text(encoding="utf-8"))
    document.update(name="fig4_nominal_jacobi", coupling="jacobi")  # its own runs: plain folders
    renamed.write_text(yaml.safe_dump(document), encoding="utf-8")
    both = CliRunner().invoke(main, ["run", str(scenario), str(renamed), "--out", str(out), "--coupling", "jacobi"])
    assert both.exit_code == 2, both.output
    assert both.output == (
        f"error: {scenario} and {renamed}: both runs would write {out / 'fig4_nominal_jacobi' / 'friction'}; "
        "run them into different --out folders\n"
    )
    assert not out.exists()
    notes = out / "fig4_nominal" / "no_friction" / "trace.csv"
    notes.parent.mkdir(parents=True)
    notes.write_text("my notes\n")
    refused = CliRunner().invoke(main, ["run", str(scenario), "--out", str(out)])
    assert refused.exit_code == 2, refused.output
    assert "trace.csv: exists and is not a CSV table" in refused.output and refused.output.count("\n") == 1
    assert notes.read_text() == "my notes\n"
    assert not (out / "fig4_nominal" / "friction").exists()  # no run started


@pytest.mark.parametrize("page", ["ssp.md", "controllers.md"])
def test_the_docs_name_the_folders_runs_write(page: str) -> None:
    text = (ROOT / "docs" / page).read_text(encoding="utf-8")
    wanted = {"ssp.md": "out/fig4_ssp/friction", "controllers.md": "out/fig4_nominal_jacobi/friction"}[page]
    assert wanted in text
