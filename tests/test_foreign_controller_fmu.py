"""A foreign controller FMU (`controller: {fmu: PATH, parameters: {...}}`, docs/controllers.md):
a PD law on slider B written with PythonFMU (FMI 2.0 CS, built here), run by our master.

Behaviour checked: the recorded command is, at every sample, K_p (x* − x_B) − K_d v_B recomputed
here from the recorded x_B and v_B (with the scenario's parameters, and under jacobi coupling from
the previous row's), and its diagnostic e likewise; the FMU's instance, library and unzipped copy
are gone after a complete, a failed and an interrupted run (no folder left in the temporary
directory); an FMU failure fails the run with the FMU's log line in the reason; and each
refusal of `check_controller_fmu` (not a zip, no iq_ref, a wrong unit, an input the plant does
not have, Model Exchange only) and each bad key is one line with exit 2 through the CLI.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from python_fmus import build_python_fmu

from toggle_cosim.cli import main
from toggle_cosim.cosim.controllers import controller_for
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import ContractError, check_plant
from toggle_cosim.plant.controller_contract import check_controller_fmu

PD_LAW = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PDLaw(Fmi2Slave):
    """iq_ref = K_p (target - x_B) - K_d v_B from the inputs as set (direct feedthrough), and
    e = target - x_B; doStep raises from t = fail_at on."""

    author = "toggle-cosim tests"
    description = "PD law on x_B"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.x_B, self.v_B = 0.2329, 0.0
        self.K_p, self.K_d, self.target, self.fail_at = 40.0, 2.0, 0.3199, 1e9
        for name in ("x_B", "v_B"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("K_p", "K_d", "target", "fail_at"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("iq_ref", causality=Fmi2Causality.output, getter=self.command))
        self.register_variable(Real("e", causality=Fmi2Causality.output, getter=lambda: self.target - self.x_B))

    def command(self) -> float:
        return self.K_p * (self.target - self.x_B) - self.K_d * self.v_B

    def do_step(self, current_time: float, step_size: float) -> bool:
        if current_time >= self.fail_at:
            raise RuntimeError(f"the PD law gave up at t = {current_time:.4f} s")
        return True
'''
K_P, K_D, TARGET = 55.0, 2.5, 0.3199


@pytest.fixture(scope="module")
def pd_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_python_fmu(PD_LAW, tmp_path_factory.mktemp("pd-fmu"), "PDLaw")


def _scenario(folder: Path, plant: Path, fmu: Path | str, t_end: float = 0.2, **controller) -> Path:
    document = {
        "name": "pd_fmu",
        "t_end": t_end,
        "T_s": 0.0005,
        "fmu": str(plant),
        "stroke": {"x_start": 0.2329, "x_target": TARGET},
        "controller": {"fmu": str(fmu), "parameters": {"K_p": K_P, "K_d": K_D}, **controller},
        "variants": {"gauss_seidel": {}, "jacobi": {"coupling": "jacobi"}},
    }
    path = folder / "pd_fmu.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


def _edited(fmu: Path, out: Path, *replacements: tuple[str, str]) -> Path:
    """A copy of `fmu` with its modelDescription.xml edited (each (old, new) replaced once)."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as target:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == "modelDescription.xml":
                text = data.decode("utf-8")
                for old, new in replacements:
                    assert old in text, old
                    text = text.replace(old, new, 1)
                data = text.encode("utf-8")
            target.writestr(info, data)
    return out


def test_the_run_gives_the_pd_law_at_every_sample_under_both_couplings(
    tmp_path: Path, plant_fmu: Path, pd_fmu: Path
) -> None:
    """`toggle-cosim run`: at every one of the 401 samples iq_ref = K_p (x* − x_B) − K_d v_B and
    e = x* − x_B, from the same row (gauss-seidel) or from the row before (jacobi; row 0 from
    itself); the parameters reached the FMU (K_p = 55, not its 40); run.json names the FMU and
    the loop that called it."""
    scenario = _scenario(tmp_path, plant_fmu, pd_fmu.name)
    (tmp_path / pd_fmu.name).write_bytes(pd_fmu.read_bytes())  # relative to the scenario file
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    for variant in ("gauss_seidel", "jacobi"):
        trace = read_csv(out / "pd_fmu" / variant / "trace.csv")
        record = json.loads((out / "pd_fmu" / variant / "run.json").read_text(encoding="utf-8"))
        assert record["status"] == "complete" and len(trace.time) == 401
        assert record["coupling"] == variant.replace("_", "-")
        assert record["controller"]["fmu"]["path"] == str(tmp_path / pd_fmu.name)
        assert record["controller"]["diagnostics"] == ["e"]
        # the FMU's C functions are called from the compiled loop under either coupling
        assert record["loop"]["kind"] == "compiled"
        x_B, v_B = trace.column("x_B"), trace.column("v_B")
        law = K_P * (TARGET - x_B) - K_D * v_B
        error = TARGET - x_B
        if variant == "jacobi":
            law, error = np.concatenate([law[:1], law[:-1]]), np.concatenate([error[:1], error[:-1]])
        np.testing.assert_allclose(trace.column("iq_ref"), law, rtol=0, atol=1e-12)
        np.testing.assert_allclose(trace.column("e"), error, rtol=0, atol=1e-15)
        assert np.ptp(trace.column("iq_ref")) > 1.0  # the loop moved: a law that did nothing would not
    gs = read_csv(out / "pd_fmu" / "gauss_seidel" / "trace.csv").column("x_B")
    jac = read_csv(out / "pd_fmu" / "jacobi" / "trace.csv").column("x_B")
    assert np.max(np.abs(gs - jac)) > 1e-6  # the one-sample delay moves the slider


@pytest.fixture
def scratch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The temporary directory the FMUs unzip into, empty at the start."""
    folder = tmp_path / "scratch"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def _in_process(tmp_path: Path, plant: Path, fmu: Path, **parameters):  # noqa: ANN202
    run = load_scenario(_scenario(tmp_path, plant, fmu, t_end=0.1))[0]
    settings = dataclasses.replace(run.controller, parameters={**run.controller.parameters, **parameters})
    run = dataclasses.replace(run, controller=settings)
    plant_interface = check_plant(plant)
    return run, plant_interface, controller_for(run, plant_interface.recorded_outputs)


def test_the_fmu_is_freed_after_complete_failed_and_interrupted_runs(
    tmp_path: Path, scratch: Path, plant_fmu: Path, pd_fmu: Path
) -> None:
    """In-process runs: after each, the controller is unloaded and nothing is left in the
    temporary directory (neither its unzipped copy nor the plant's); the failed run's reason
    holds the FMU's log line; the interrupted run stops where it was interrupted."""
    run, plant, controller = _in_process(tmp_path, plant_fmu, pd_fmu)
    outcome = check_and_simulate(run, plant, controller=controller)
    assert outcome.complete and os.listdir(scratch) == []

    run, plant, controller = _in_process(tmp_path, plant_fmu, pd_fmu, fail_at=0.05)
    outcome = check_and_simulate(run, plant, controller=controller)
    assert not outcome.complete and outcome.record["status"] == "failed"
    assert outcome.reason.startswith("controller failed: ") and "fmi2DoStep at t = 0.05 s" in outcome.reason
    assert "the PD law gave up at t = 0.0500 s" in outcome.reason  # the FMU's own log line
    assert "\n" not in outcome.reason and len(outcome.trace.time) == 101  # samples 0 .. 0.05 s kept
    assert os.listdir(scratch) == []

    def interrupt(fraction: float) -> None:
        if fraction >= 0.5:
            raise KeyboardInterrupt

    run, plant, controller = _in_process(tmp_path, plant_fmu, pd_fmu)
    outcome = check_and_simulate(run, plant, progress=interrupt, controller=controller)
    assert outcome.interrupted and outcome.record["status"] == "interrupted"
    assert 100 <= len(outcome.trace.time) < 201
    assert os.listdir(scratch) == []


def test_a_supervised_run_leaves_nothing_behind(tmp_path: Path, scratch: Path, plant_fmu: Path, pd_fmu: Path) -> None:
    """The FMU is loaded in the supervised run's child, not in the parent, and the run's folder
    (with both unzipped copies) is gone after it; the trace is the in-process run's, bit for bit."""
    from toggle_cosim.cosim.isolation.supervision import simulate_supervised

    run, plant, controller = _in_process(tmp_path, plant_fmu, pd_fmu)
    outcome = simulate_supervised(run, plant, controller=controller)
    assert outcome.complete and os.listdir(scratch) == []
    again = check_and_simulate(run, plant)
    assert np.array_equal(outcome.trace.data, again.trace.data)


REFUSALS = {
    "not a zip": (lambda fmu, out: (out.write_text("not an FMU"), out)[1], "not an FMU (not a zip archive)"),
    "no iq_ref": (
        lambda fmu, out: _edited(fmu, out, ('name="iq_ref"', 'name="i_cmd"')),
        "the controller FMU has no output 'iq_ref'",
    ),
    "wrong unit": (
        lambda fmu, out: _edited(fmu, out, ('name="iq_ref"', 'name="iq_ref"'), ("<Real", '<Real unit="mA"')),
        None,  # the first Real is an input or an output: the message names it below
    ),
    "input the plant lacks": (
        lambda fmu, out: _edited(fmu, out, ('name="v_B"', 'name="v_A"')),
        "the controller FMU's input 'v_A' is not an output of the plant",
    ),
    "model exchange only": (
        lambda fmu, out: _edited(fmu, out, ("<CoSimulation", "<ModelExchange")),
        "the FMU does not support Co-Simulation",
    ),
    "a fixed step of its own": (
        lambda fmu, out: _fixed_step(fmu, out),
        "the controller FMU steps only at its own step 0.001 s, not T_s = 0.0005 s",
    ),
}


def _fixed_step(fmu: Path, out: Path) -> Path:
    """A copy of `fmu` that steps only at its own step, 1 ms (no parameter T_s: not the built-in law's)."""
    return _edited(
        fmu,
        out,
        ('canHandleVariableCommunicationStepSize="true"', 'canHandleVariableCommunicationStepSize="false"'),
        ("<ModelVariables>", '<DefaultExperiment stepSize="0.001"/>\n\t<ModelVariables>'),
    )


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_a_controller_fmu_that_breaks_the_contract_is_refused_in_one_line(
    case: str, tmp_path: Path, plant_fmu: Path, pd_fmu: Path
) -> None:
    make, expected = REFUSALS[case]
    bad = make(pd_fmu, tmp_path / "Bad.fmu")
    scenario = _scenario(tmp_path, plant_fmu, "Bad.fmu")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(out), "-q"])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert lines[0].startswith(f"error: {scenario}: key controller.fmu: {bad}: "), lines[0]
    if expected is None:
        assert "has unit 'mA', it must be" in lines[0]
    else:
        assert expected in lines[0]
    assert not out.exists()  # nothing written


def test_a_fixed_step_fmu_in_a_system_is_refused_in_one_line(tmp_path: Path, plant_fmu: Path, pd_fmu: Path) -> None:
    """A controller FMU that steps only at 1 ms, in a system (`record:`) at T_s = 0.5 ms: one line
    naming the file and the fix, exit 2, before any run, nothing written."""
    bad = _fixed_step(pd_fmu, tmp_path / "Fixed.fmu")
    scenario = _scenario(tmp_path, plant_fmu, "Fixed.fmu")
    document = yaml.safe_load(scenario.read_text(encoding="utf-8"))
    document["record"] = ["plant.x_B", "controller.iq_ref"]
    scenario.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(out), "-q"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert lines[0].startswith(
        f"error: {scenario}: key controller.fmu: {bad}: the controller FMU steps only at its own"
    )
    assert "(set T_s to its step, or rebuild it for T_s)" in lines[0]
    assert not out.exists()


def test_the_unit_of_iq_ref_must_be_ampere(tmp_path: Path, pd_fmu: Path) -> None:
    """A command in mA is refused; the same FMU with A passes, without the warning for iq_ref."""
    start = '<ScalarVariable name="iq_ref"'
    with zipfile.ZipFile(pd_fmu) as archive:
        text = archive.read("modelDescription.xml").decode()
    block = text[text.index(start) :]
    real = block[block.index("<Real") : block.index("<Real") + 5]
    for unit, refused in (("mA", True), ("A", False)):
        edited = block.replace(real, f'<Real unit="{unit}"', 1)
        fmu = _edited(pd_fmu, tmp_path / f"{unit}.fmu", (block, edited))
        if refused:
            with pytest.raises(ContractError, match=r"output 'iq_ref' has unit 'mA', it must be 'A'"):
                check_controller_fmu(fmu, ("x_B", "v_B"))
        else:
            checked = check_controller_fmu(fmu, ("x_B", "v_B"))
            assert not any("iq_ref" in warning for warning in checked.warnings)
            assert any("x_B" in warning for warning in checked.warnings)  # the inputs still have none


@pytest.mark.parametrize(
    ("controller", "message"),
    [
        ({"python": "mod:factory"}, "controller.python and controller.fmu name two controllers (keep one)"),
        ({"error": {"output": "x_B"}}, "key controller.error (variant gauss_seidel): only with controller.python"),
        ({"parameters": {"K_x": 1.0}}, "key controller.parameters.K_x: the controller FMU PDLaw.fmu has no parameter"),
    ],
)
def test_bad_controller_keys_are_one_line(
    controller: dict, message: str, tmp_path: Path, plant_fmu: Path, pd_fmu: Path
) -> None:
    scenario = _scenario(tmp_path, plant_fmu, pd_fmu, **controller)
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2, result.output
    assert len(result.output.strip().splitlines()) == 1 and message in result.output, result.output


def test_a_missing_fmu_names_the_key_and_the_fix(tmp_path: Path, plant_fmu: Path) -> None:
    scenario = _scenario(tmp_path, plant_fmu, "controllers/Missing.fmu")
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2
    assert f"key controller.fmu: {tmp_path / 'controllers' / 'Missing.fmu'}: no such FMU file" in result.output
    assert "relative to the scenario file" in result.output


PD_LAW_MODELICA = """
model PDLaw "PD law on slider B"
  parameter Real K_p(unit = "A/m") = 40.0;
  parameter Real K_d(unit = "A.s/m") = 2.0;
  parameter Real target(unit = "m") = 0.3199;
  input Real x_B(unit = "m", start = 0.2329);
  input Real v_B(unit = "m/s", start = 0.0);
  output Real iq_ref(unit = "A");
  output Real e(unit = "m");
equation
  e = target - x_B;
  iq_ref = K_p * e - K_d * v_B;
end PDLaw;
"""


@pytest.mark.slow
def test_the_same_law_as_an_fmi3_fmu_gives_the_same_trace(tmp_path: Path, plant_fmu: Path, pd_fmu: Path) -> None:
    """The PD law written in Modelica and exported as an FMI 3.0 Co-Simulation FMU (units
    declared: no warning) runs through fmi3SetFloat64/GetFloat64/DoStep and gives the PythonFMU
    FMI 2.0 FMU's trace bit for bit, under both couplings."""
    from toggle_cosim.fmu_export import build_fmu

    source = tmp_path / "PDLaw.mo"
    source.write_text(PD_LAW_MODELICA, encoding="utf-8")
    fmi3 = build_fmu(source, "PDLaw", tmp_path / "PDLaw3.fmu", fmi_version="3.0", interfaces="cs").fmu.path
    plant = check_plant(plant_fmu)
    assert check_controller_fmu(fmi3, plant.recorded_outputs).warnings == ()
    for run in load_scenario(_scenario(tmp_path, plant_fmu, pd_fmu, t_end=0.1)):
        two = check_and_simulate(run, plant)
        settings = dataclasses.replace(run.controller, fmu=fmi3)
        three = check_and_simulate(dataclasses.replace(run, controller=settings), plant)
        assert two.complete and three.complete, three.reason
        assert three.record["controller"]["fmu"]["fmi_version"] == "3.0"
        assert np.array_equal(two.trace.data, three.trace.data), run.label
