"""A user's plant with an input of its own (`plant.inputs`): the template plant of
examples/modelica_plant with a disturbance force F_D beside F_E. A signal on F_D is sent at every
sample and recorded in its own column after the diagnostics, in the compiled and the Python loop
alike; since the plant takes F_D as it takes F_E (m ẍ = K_F i_q* − F_E − F_D − friction), a load on
F_D gives the trace of the same load on F_E bit for bit. Names the plant does not have, outputs
named as inputs and tables in the wrong unit are one line, exit 2."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.cosim.master import check_and_simulate, trace_names
from toggle_cosim.experiments.scenario import ScenarioError, runs_from_document
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.signals.definitions import Step, sample

ROOT = Path(__file__).resolve().parent.parent
TEMPLATE = ROOT / "examples" / "modelica_plant" / "GuidedMass.mo"
STEP = {"kind": "step", "start_time": 0.05, "height": 20.0}


@pytest.fixture(scope="module")
def disturbed_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The template with a second force input F_D [N] (built from Modelica by our build)."""
    from toggle_cosim.fmu_export import build_fmu

    text = TEMPLATE.read_text(encoding="utf-8").replace("model GuidedMass", "model DisturbedMass")
    text = text.replace("end GuidedMass;", "end DisturbedMass;")
    text = text.replace(
        "  output Real x_B(",
        '  input Real F_D(unit = "N") "A disturbance force on slider B, as F_E";\n  output Real x_B(',
    )
    text = text.replace("- F_E - mu", "- F_E - F_D - mu")
    assert "F_D - mu" in text
    folder = tmp_path_factory.mktemp("disturbed")
    (folder / "DisturbedMass.mo").write_text(text, encoding="utf-8")
    return build_fmu(folder / "DisturbedMass.mo", "DisturbedMass", folder / "DisturbedMass.fmu").fmu.path


def _document(fmu: Path, plant: dict) -> dict:
    return {
        "name": "disturbed",
        "fmu": str(fmu),
        "t_end": 0.2,
        "T_s": 0.0005,
        "stroke": {"x_start": 0.2329, "x_target": 0.3199},
        "plant": {"m_B": 4.43, "mu": 0.2, **plant},
    }


def _run(fmu: Path, plant: dict):
    return runs_from_document(_document(fmu, plant))[0]


def test_an_input_of_the_users_plant_is_sent_and_recorded_at_every_sample(
    disturbed_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plant = check_plant(disturbed_fmu)
    run = _run(disturbed_fmu, {"inputs": {"F_D": STEP}})
    compiled = check_and_simulate(run, plant)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    python = check_and_simulate(run, plant)
    assert compiled.complete and compiled.record["loop"]["kind"] == "compiled"
    assert compiled.trace.names == (*trace_names(plant), "F_D")  # after the diagnostics
    assert np.array_equal(compiled.trace.data, python.trace.data)
    assert np.array_equal(compiled.trace.column("F_D"), sample(Step(20.0, 0.05), run.steps, run.T_s))
    assert np.array_equal(compiled.trace.column("F_E"), np.zeros(run.steps + 1))
    assert compiled.record["inputs"]["F_D"] == {"kind": "step", "height": 20.0, "start_time": 0.05, "offset": 0.0}
    # the plant feels it: the same load on F_E gives the same motion, bit for bit
    on_F_E = check_and_simulate(_run(disturbed_fmu, {"F_E": STEP}), plant)
    for name in ("x_B", "v_B", "iq_ref", "S"):
        assert np.array_equal(compiled.trace.column(name), on_F_E.trace.column(name)), name
    assert not np.array_equal(
        compiled.trace.column("x_B"), check_and_simulate(_run(disturbed_fmu, {}), plant).trace.column("x_B")
    )


def test_jacobi_sends_the_other_inputs_of_the_sample(disturbed_fmu: Path) -> None:
    plant = check_plant(disturbed_fmu)
    outcome = check_and_simulate(_run(disturbed_fmu, {"inputs": {"F_D": STEP}}), plant, coupling="jacobi")
    on_F_E = check_and_simulate(_run(disturbed_fmu, {"F_E": STEP}), plant, coupling="jacobi")
    assert outcome.complete and np.array_equal(outcome.trace.column("x_B"), on_F_E.trace.column("x_B"))


@pytest.mark.parametrize(
    ("inputs", "message"),
    [
        (
            {"F_X": 1.0},
            "key plant.inputs.F_X: the plant FMU {fmu} has no variable 'F_X' (its inputs: iq_ref, F_E, F_D)",
        ),
        ({"x_B": 1.0}, "key plant.inputs.x_B: 'x_B' is a Real output of the plant FMU, not a Real input"),
    ],
)
def test_an_input_the_plant_does_not_have_is_one_line_exit_2(
    disturbed_fmu: Path, tmp_path: Path, inputs: dict, message: str
) -> None:
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump(_document(disturbed_fmu, {"inputs": inputs})))
    ran = CliRunner().invoke(main, ["run", str(scenario), "--out", str(tmp_path / "out"), "-q"])
    assert ran.exit_code == 2 and not (tmp_path / "out").exists()
    error = [line for line in ran.output.splitlines() if line.startswith("error:")]  # after the plant's notes
    assert error == [f"error: {scenario}: {message.format(fmu=disturbed_fmu)}"]


def test_a_table_in_another_unit_than_the_input_is_refused(disturbed_fmu: Path, tmp_path: Path) -> None:
    (tmp_path / "d.csv").write_text("time [s],F_D [kN]\n0,0\n1,0.02\n", encoding="utf-8")
    table = {"kind": "table", "file": "d.csv", "interpolation": "linear"}
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump(_document(disturbed_fmu, {"inputs": {"F_D": table}})))
    ran = CliRunner().invoke(main, ["run", str(scenario), "--out", str(tmp_path / "out"), "-q"])
    assert ran.exit_code == 2 and not (tmp_path / "out").exists()
    assert (
        "key plant.inputs.F_D: " in ran.output
        and "gives column F_D in 'kN', the plant FMU's F_D is in 'N'" in ran.output
    )


@pytest.mark.parametrize("name", ["F_E", "iq_ref"])
def test_the_contract_inputs_cannot_be_set_as_other_inputs(name: str, tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match=f"key plant.inputs.{name}: {name} cannot be set here"):
        _run(tmp_path / "x.fmu", {"inputs": {name: 1.0}})
