"""The template plants in examples/ (a Modelica plant and a PythonFMU plant, each with only the
contract's required variables and x_B0): each builds, passes `check_plant` with its optional
outputs reported absent, and runs examples/guided_mass.yaml through `toggle-cosim run`; `plot`,
the summary table, the claims and a sweep cope with the missing columns.

The physics check: sliding forward, both plants are m_B ẍ = K_F i_q* − F_E − μ m_B g with the
command held over each sample, so each step is x_{k+1} = x_k + v_k T_s + a_k T_s²/2; the
recorded trace must follow it with and without friction (a wrong sign, force constant, mass,
friction or hold moves a step by 2.5e-7 m or more)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import OUTPUTS, ContractError, check_plant

pytestmark = pytest.mark.slow  # builds and runs the Modelica and PythonFMU templates

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
SCENARIO = EXAMPLES / "guided_mass.yaml"
K_F = 56.96  # N/A, both templates' thrust constant
REQUIRED_COLUMNS = ["time", "x_B", "v_B", "iq_ref", "F_E", "S", "phase", "e"]


@pytest.fixture(scope="module")
def modelica_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Built with the documented command, `toggle-cosim build --source ... --model ...`, in a
    project of its own (the build writes only inside the project it runs in)."""
    project = tmp_path_factory.mktemp("user-project")
    (project / "pyproject.toml").write_text('[project]\nname = "my-plant"\n')
    (project / "plant").mkdir()
    (project / "plant" / "GuidedMass.mo").write_bytes((EXAMPLES / "modelica_plant" / "GuidedMass.mo").read_bytes())
    command = [str(Path(sys.executable).parent / "toggle-cosim"), "build", "--source", "plant/GuidedMass.mo"]
    command += ["--model", "GuidedMass", "--out", "fmus/GuidedMass.fmu"]
    built = subprocess.run(command, cwd=project, capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stderr
    return project / "fmus" / "GuidedMass.fmu"


@pytest.fixture(scope="module")
def pythonfmu_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("pythonfmu")
    script = EXAMPLES / "pythonfmu_plant" / "guided_mass.py"
    command = [str(Path(sys.executable).parent / "pythonfmu"), "build", "-f", str(script), "-d", str(folder)]
    built = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert built.returncode == 0, built.stderr
    return folder / "GuidedMass.fmu"


def _run(fmu: Path, out: Path):  # noqa: ANN202
    result = CliRunner().invoke(main, ["run", str(SCENARIO), "--fmu", str(fmu), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    return result


def _step_residual(trace, mu: float, m_B: float = 4.43, T_s: float = 0.0005) -> tuple[float, int]:  # noqa: ANN001
    """Largest |x_{k+1} − (x_k + v_k T_s + a_k T_s²/2)| over the steps that slide forward fast
    (v_B > 0.05 m/s at both ends), a_k = (K_F i_q* − F_E)/m_B − μ g; and how many steps that is."""
    x, v = trace.column("x_B"), trace.column("v_B")
    a = (K_F * trace.column("iq_ref") - trace.column("F_E")) / m_B - mu * 9.81
    fast = (v[:-1] > 0.05) & (v[1:] > 0.05)
    predicted = x[:-1] + v[:-1] * T_s + 0.5 * a[:-1] * T_s * T_s
    return float(np.max(np.abs(x[1:] - predicted)[fast])), int(np.count_nonzero(fast))


def _check_run(out: Path, tolerance: float) -> None:
    folder = out / "guided_mass"
    for variant, mu in (("friction", 0.2), ("no_friction", 0.0)):
        record = json.loads((folder / variant / "run.json").read_text())
        assert record["status"] == "complete" and record["warnings"] == []
        assert "theta1" in record["plant_contract"]["absent"] and "E_in" in record["plant_contract"]["absent"]
        assert record["summary"]["E_in_J"] is None and record["summary"]["fric_share_start"] is None
        assert abs(record["summary"]["final_error_m"]) < 2e-3  # the paper's VSC reaches the target on this plant
        trace = read_csv(folder / variant / "trace.csv")
        assert list(trace.names) == REQUIRED_COLUMNS
        residual, steps = _step_residual(trace, mu)
        # friction moves a step by μ g T_s²/2 = 2.5e-7 m: the residual tells the two models apart
        assert steps > 300 and residual < tolerance, (variant, residual, steps)
        assert _step_residual(trace, 0.2 - mu)[0] > 2e-7


def test_the_pythonfmu_template_without_units_runs_a_scenario(pythonfmu_template: Path, tmp_path: Path) -> None:
    plant = check_plant(pythonfmu_template)
    assert plant.recorded_outputs == ("x_B", "v_B")
    assert set(plant.absent) == {*OUTPUTS, "idealCurrentLoop", "K", "frictionModel", "mu_s"} - {"x_B", "v_B"}
    (warning,) = plant.warnings  # PythonFMU writes no units: one warning, not a refusal
    assert warning.startswith("no unit declared for iq_ref (taken as A), F_E (taken as N), x_B (taken as m)")
    result = _run(pythonfmu_template, tmp_path / "out")
    assert f"{pythonfmu_template}: optional outputs absent, not recorded: theta1, theta2" in result.stderr
    assert f"{pythonfmu_template}: warning: no unit declared for iq_ref" in result.stderr
    _check_run(tmp_path / "out", 1e-12)  # the template integrates the held command exactly


def test_the_modelica_template_builds_and_runs_a_scenario(modelica_template: Path, tmp_path: Path) -> None:
    plant = check_plant(modelica_template)
    assert plant.recorded_outputs == ("x_B", "v_B") and plant.warnings == ()
    assert "x_B0" not in plant.absent and "theta1" in plant.absent
    _run(modelica_template, tmp_path / "out")
    _check_run(tmp_path / "out", 2e-8)  # CVODE at relTol 1e-8; tanh(v/0.01) = 1 - 1e-4 at 0.05 m/s


def test_a_theta1_run_on_a_plant_without_theta1_is_refused_in_one_line(
    pythonfmu_template: Path, tmp_path: Path
) -> None:
    document = yaml.safe_load(SCENARIO.read_text())
    document["controller"]["objective"] = "theta1"
    scenario = tmp_path / "theta1.yaml"
    scenario.write_text(yaml.safe_dump(document))
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(scenario), "--fmu", str(pythonfmu_template), "--out", str(out)])
    assert result.exit_code == 2, result.output
    error = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(error) == 1 and "key controller.objective: theta1 needs the plant outputs theta1 and omega1" in error[0]
    assert "lacks 'theta1', 'omega1'" in error[0] and "Traceback" not in result.output and not out.exists()


def test_a_different_unit_is_still_refused(pythonfmu_template: Path, tmp_path: Path) -> None:
    """A missing unit warns; a unit other than the contract's is refused, in one line."""
    import zipfile

    bad = tmp_path / "mm.fmu"
    with zipfile.ZipFile(pythonfmu_template) as source, zipfile.ZipFile(bad, "w") as target:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(
                    b'causality="output">\n\t\t\t<Real/>', b'causality="output">\n\t\t\t<Real unit="mm"/>', 1
                )
            target.writestr(item, data)
    with pytest.raises(ContractError, match=r"variable 'x_B' has unit 'mm', the contract needs 'm'$"):
        check_plant(bad)


def test_plots_summaries_and_sweeps_cope_with_absent_outputs(modelica_template: Path, tmp_path: Path) -> None:
    """Everything downstream that reads optional columns, on a plant that has none of them."""
    from toggle_cosim.analysis.report import summary_table, write_summary
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.experiments.sweep import read_results, run_sweep

    _run(modelica_template, tmp_path / "out")
    drawn = CliRunner().invoke(main, ["plot", str(tmp_path / "out" / "guided_mass")])
    assert drawn.exit_code == 0, drawn.output
    assert (tmp_path / "out" / "guided_mass" / "figure.png").stat().st_size > 10_000

    plant = check_plant(modelica_template)
    paper = [
        ROOT / "scenarios" / f"{name}.yaml" for name in ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")
    ]
    outcomes = [check_and_simulate(run, plant) for path in paper for run in load_scenario(path)]
    assert all(o.complete for o in outcomes)
    table = summary_table(outcomes)
    assert "| fig4_nominal/friction | complete | " in table and "| — | — | — | — |" in table
    text = write_summary(outcomes, tmp_path / "summary.md").read_text()
    assert "Claims not checked: the plant has no output E_in, E_fric, N12" in text

    sweep = tmp_path / "sweep.yaml"
    axes = {"plant.F_E": {"values": [0.0, 20.0]}, "plant.m_B": {"values": [4.43, 6.0]}}
    document = {"base": str(SCENARIO), "axes": axes, "output": "sweep", "heatmap": {"x": "plant.F_E", "y": "plant.m_B"}}
    sweep.write_text(yaml.safe_dump(document))
    assert run_sweep(sweep, None, 1, modelica_template, progress=False) == 0
    results = read_results(tmp_path / "sweep")
    assert len(results) == 8 and (results["status"] == "ok").all()
    assert results["E_in_J"].isna().all() and results["fric_share_end"].isna().all()
    assert results["warnings"].isna().all() and results["final_error_m"].notna().all()
    assert len(list((tmp_path / "sweep" / "heatmaps").glob("heatmap_*.png"))) == 2  # one per variant


def test_plot_draws_the_pythonfmu_templates_own_variables(pythonfmu_template: Path, tmp_path: Path) -> None:
    """`plot` of a plant with only the contract's required outputs: without --vars the variables
    it has (no "not an output of this plant" panels), with --vars any of them beside another run."""
    from toggle_cosim.analysis.run_files import load_runs
    from toggle_cosim.analysis.variable_figure import default_variables
    from toggle_cosim.cli.report_command import is_paper_plant

    _run(pythonfmu_template, tmp_path / "out")
    folder = tmp_path / "out" / "guided_mass"
    assert not is_paper_plant(folder)
    assert default_variables(load_runs([folder])) == REQUIRED_COLUMNS[1:]
    drawn = CliRunner().invoke(main, ["plot", str(folder)])
    assert drawn.exit_code == 0, drawn.output
    assert drawn.output == f"wrote {folder / 'figure.png'}\n" and (folder / "figure.png").stat().st_size > 10_000
    chosen = CliRunner().invoke(main, ["plot", str(folder / "friction" / "trace.csv"), str(folder / "no_friction"),
                                       "--vars", "x_B,iq_ref", "--out", str(tmp_path / "x_B.png")])  # fmt: skip
    assert chosen.exit_code == 0, chosen.output
    assert (tmp_path / "x_B.png").stat().st_size > 10_000
