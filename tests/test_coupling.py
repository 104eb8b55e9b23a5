"""Coupling of plant and controller (`--coupling`, docs/controllers.md, "Coupling").

gauss-seidel (the default): the command u_k the controller computes from the plant's outputs y_k
drives the plant over [t_k, t_k+1]. jacobi: u_{k-1} does (u_0 at k = 0), and row k records y_k
with the controller's outputs of sample k - 1. Checked here on the trace itself:

* row k's iq_ref (and diagnostics) equal what the controller computes from row k - 1's
  measurement, evaluated here by the controller's own start/step over the recorded rows (the
  built-in law, and a Python PD law given to `simulate`);
* the plant's x_B follows the recorded (delayed) command: the plant FMU driven open loop here
  by fmpy with row k's iq_ref over [t_k, t_k+1] gives the recorded x_B bit for bit, and driven
  by the undelayed command it does not;
* gauss-seidel named explicitly is the default run, bit for bit, on the compiled loop.

The controller FMU generated from the law (`toggle_cosim.controller_fmu`, ToggleVSC) must give
the built-in run bit for bit under both couplings (skipped until that module exists).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from fmpy import extract
from fmpy.fmi2 import FMU2Slave

from toggle_cosim.cli import main
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.controller_fmu import build_controller_fmu
from toggle_cosim.cosim.controllers import builtin_controller
from toggle_cosim.cosim.master import check_and_simulate, plant_settings
from toggle_cosim.experiments.scenario import ScenarioError, load_scenario, runs_from_document
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"
T_SHORT = 0.3  # s: the reaching phase and the start of sliding


def _short(name: str, variant: str, t_end: float = T_SHORT):  # noqa: ANN202
    run = next(run for run in load_scenario(SCENARIOS / f"{name}.yaml") if run.variant == variant)
    return dataclasses.replace(run, t_end=t_end)


def _measurements(trace) -> list[dict[str, float]]:  # noqa: ANN001
    names = trace.names[1 : trace.names.index("iq_ref")]
    return [dict(zip(names, map(float, row[1 : 1 + len(names)]), strict=True)) for row in trace.data]


def _replayed(controller, trace, T_s: float) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """(u_k, diagnostics_k) the controller computes from each recorded row's measurement."""
    rows = _measurements(trace)
    state = controller.start(0.0, rows[0])
    commands, diagnostics = [], []
    for k, measurement in enumerate(rows):
        result = controller.step(state, k * T_s, measurement)
        commands.append(result.command)
        diagnostics.append(result.diagnostics)
        state = result.state
    return np.array(commands), np.array(diagnostics)


def _open_loop_x_B(plant, run, commands: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """The plant driven by fmpy alone (not our session): the run's settings, then commands[k]
    held over [t_k, t_k+1]; x_B at every sample."""
    md = plant.model_description
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(plant.path)),
        modelIdentifier=plant.model_identifier,
        instanceName="replay",
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0, stopTime=run.t_end)
    for name, value in plant_settings(run, plant):
        vr = [plant.references[name]]
        slave.setBoolean(vr, [value]) if plant.types[name] == "Boolean" else slave.setReal(vr, [float(value)])
    inputs = [plant.references["iq_ref"], plant.references["F_E"]]
    slave.enterInitializationMode()
    slave.setReal(inputs, [0.0, run.plant.F_E])
    slave.exitInitializationMode()
    x_B = [slave.getReal([plant.references["x_B"]])[0]]
    for k in range(len(commands) - 1):
        slave.setReal(inputs, [float(commands[k]), run.plant.F_E])
        slave.doStep(k * run.T_s, run.T_s)
        x_B.append(slave.getReal([plant.references["x_B"]])[0])
    slave.terminate()
    slave.freeInstance()
    return np.array(x_B)


class PDLaw:
    """A PD law on x_B (protocol: start, step, diagnostics) with a state that counts samples."""

    diagnostics = ("e", "samples")

    def __init__(self, K_p: float = 60.0, K_d: float = 3.0, target: float = 0.3199) -> None:
        self.K_p, self.K_d, self.target = K_p, K_d, target

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return 0

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        e = self.target - measurement["x_B"]
        return ControlStep(self.K_p * e - self.K_d * measurement["v_B"], (e, float(state)), state + 1)


@pytest.mark.parametrize("which", ["builtin", "python"])
def test_jacobi_records_and_applies_the_previous_samples_command(which: str, plant_fmu: Path) -> None:
    plant = check_plant(plant_fmu)
    run = _short("fig4_nominal", "friction")
    controller = PDLaw() if which == "python" else None
    outcome = check_and_simulate(run, plant, controller=controller, coupling="jacobi")
    assert outcome.complete and outcome.record["coupling"] == "jacobi"
    assert outcome.record["loop"]["kind"] == ("python" if which == "python" else "compiled")
    assert ", jacobi, " in outcome.record["loop"]["reason"]
    trace = outcome.trace
    u, diagnostics = _replayed(PDLaw() if which == "python" else builtin_controller(run), trace, run.T_s)
    iq_ref = trace.column("iq_ref")
    names = PDLaw.diagnostics if which == "python" else ("S", "phase", "e")
    recorded = np.column_stack([trace.column(name) for name in names])
    # row k holds sample k - 1's outputs (sample 0's in row 0), bit for bit
    assert np.array_equal(iq_ref[1:], u[:-1]) and iq_ref[0] == u[0]
    assert np.array_equal(recorded[1:], diagnostics[:-1]) and np.array_equal(recorded[0], diagnostics[0])
    assert np.max(np.abs(u[1:] - u[:-1])) > 0.05  # a delay of one sample is visible in the command
    # the plant followed the recorded, delayed command, not the controller's own
    x_B = trace.column("x_B")
    assert np.array_equal(_open_loop_x_B(plant, run, iq_ref), x_B)
    assert np.max(np.abs(_open_loop_x_B(plant, run, u) - x_B)) > 1e-7


def test_gauss_seidel_named_is_the_default_run_bit_for_bit(plant_fmu: Path) -> None:
    """The built-in law on the compiled loop, the default and the named coupling: the same bits,
    and its command is the law evaluated on the same row (no delay); jacobi differs."""
    plant = check_plant(plant_fmu)
    run = _short("fig5_external_force", "friction")
    default = check_and_simulate(run, plant)
    named = check_and_simulate(run, plant, coupling="gauss-seidel")
    assert default.record["loop"]["kind"] == "compiled" and default.record["coupling"] == "gauss-seidel"
    assert np.array_equal(default.trace.data, named.trace.data)
    u, _ = _replayed(builtin_controller(run), default.trace, run.T_s)
    assert np.array_equal(default.trace.column("iq_ref"), u)
    jacobi = check_and_simulate(run, plant, coupling="jacobi")
    assert np.max(np.abs(jacobi.trace.column("x_B") - default.trace.column("x_B"))) > 1e-6


def test_the_coupling_key_and_option(tmp_path: Path, plant_fmu: Path) -> None:
    """`coupling:` at the top level and in a variant; --coupling overrides both; run.json says
    which ran; a bad value is one line, exit 2."""
    document = yaml.safe_load((SCENARIOS / "fig4_nominal.yaml").read_text(encoding="utf-8"))
    document.update(t_end=0.05, fmu=str(plant_fmu), coupling="jacobi")
    document["variants"]["no_friction"]["coupling"] = "gauss-seidel"
    path = tmp_path / "coupled.yaml"
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    couplings = {run.variant: run.coupling for run in load_scenario(path)}
    assert couplings == {"friction": "jacobi", "no_friction": "gauss-seidel"}
    for option, expected in (([], couplings), (["--coupling", "gauss-seidel"], None)):
        out = tmp_path / f"out{len(option)}"
        result = CliRunner().invoke(main, ["run", str(path), "--out", str(out), "-q", *option])
        assert result.exit_code == 0, result.output
        for variant in ("friction", "no_friction"):
            # a --coupling that differs from the file's own writes beside the file's results
            overridden = expected is None and couplings[variant] != "gauss-seidel"
            top = document["name"] + ("_gauss-seidel" if overridden else "")
            record = json.loads((out / top / variant / "run.json").read_text(encoding="utf-8"))
            assert record["coupling"] == (expected[variant] if expected else "gauss-seidel")
    result = CliRunner().invoke(main, ["run", str(path), "--coupling", "seidel", "--out", str(tmp_path / "x")])
    assert result.exit_code == 2 and "seidel" in result.output
    document["coupling"] = "gauss_seidel"
    with pytest.raises(
        ScenarioError, match=r"key coupling: 'gauss_seidel' is not allowed \(choose one of gauss-seidel, jacobi\)"
    ):
        runs_from_document(document)


def test_the_python_api_takes_the_coupling(plant_fmu: Path) -> None:
    import toggle_cosim as tc

    run = _short("fig4_nominal", "friction", t_end=0.05)
    result = tc.simulate(run, plant_fmu, supervised=False, coupling="jacobi")
    assert result.record["coupling"] == "jacobi"
    with pytest.raises(ValueError, match="coupling: choose one of gauss-seidel, jacobi"):
        tc.simulate(run, plant_fmu, coupling="parallel")


BIT_FOR_BIT = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation", "integral_load")


@pytest.mark.slow
@pytest.mark.parametrize("fmi_version", ["2.0", "3.0"])
@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_the_generated_controller_fmu_is_the_builtin_law_bit_for_bit(
    fmi_version: str, coupling: str, tmp_path: Path, plant_fmu: Path
) -> None:
    """`controller: {fmu: ToggleVSC.fmu}` gives every column of the built-in run's trace (x_B,
    iq_ref, S, phase, e, ...) with the same bits, for every run of the paper's figures and the
    integral law, under both couplings."""
    fmu = build_controller_fmu(tmp_path / "ToggleVSC.fmu", fmi_version).path
    plant = check_plant(plant_fmu)
    for name in BIT_FOR_BIT:
        for run in load_scenario(SCENARIOS / f"{name}.yaml"):
            builtin = check_and_simulate(run, plant, coupling=coupling)
            with_fmu = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=Path(fmu)))
            outcome = check_and_simulate(with_fmu, plant, coupling=coupling)
            assert builtin.complete and outcome.complete, (run.label, outcome.reason)
            assert outcome.record["controller"]["fmu"]["law_parameters"] is True
            for column in builtin.trace.names:
                assert np.array_equal(builtin.trace.column(column), outcome.trace.column(column)), (run.label, column)
