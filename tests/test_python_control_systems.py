"""python-control systems as controllers everywhere (docs/controllers.md, "A python-control system").

Behaviour checked: `tc.simulate(..., controller=<TransferFunction or StateSpace>)` adapts the system
as a scenario's is and runs it compiled; `DiscreteSystemController` is public; a continuous-time
system is refused before any run (a ValueError from Python) unless controller.discretise names
the method, which samples it as `control.sample_system` does; a two-input system reads
[r − y0, y − y0] and runs in C with the Python execution's bits; the 2-DOF PID of the examples
(derivative on the measurement, setpoint weight) starts without a kick where the PID on the
error kicks past the rated current, from YAML and from `tc.simulate`; with stroke.trajectory
the reference r is the sampled profile x*(t_k).
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import control
import numpy as np
import pytest
import yaml

import toggle_cosim as tc
from toggle_cosim.control.lti import DiscreteSystemController
from toggle_cosim.control.protocol import ControllerContext
from toggle_cosim.control.trajectory import SampledReference, build
from toggle_cosim.cosim.execution.system_loop import system_library
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples" / "controllers"
PID_2DOF = EXAMPLES / "pid_2dof.yaml"
T_END = 0.3  # s: 600 samples, the integral and the derivative both at work

pytestmark = pytest.mark.skipif(system_library() is None, reason="no C compiler for the compiled loop")


def _factories():  # noqa: ANN202
    sys.path.insert(0, str(EXAMPLES))
    try:
        import my_controllers
    finally:
        sys.path.remove(str(EXAMPLES))
    return my_controllers


def _runs() -> dict[str, tc.Run]:
    return {run.variant: dataclasses.replace(run, t_end=T_END) for run in load_scenario(PID_2DOF)}


def _system(run: tc.Run, name: str | None = None):  # noqa: ANN202
    """The system the variant's factory makes (its parameters), or the factory `name`'s."""
    context = ControllerContext(run.T_s, run.t_end, run.x_start, run.x_target, "x_B", run.label)
    factory = getattr(_factories(), name or run.controller.python.partition(":")[2])
    return factory(context, **run.controller.parameters)


def _same_bits(a, b) -> None:  # noqa: ANN001
    assert a.trace.names == b.trace.names
    for column in a.trace.names:
        assert np.array_equal(a.trace.column(column), b.trace.column(column)), column


def test_the_adapter_is_public() -> None:
    assert "DiscreteSystemController" in tc.__all__ and tc.DiscreteSystemController is DiscreteSystemController


def test_simulate_takes_a_python_control_system_and_runs_it_compiled(plant_fmu: Path) -> None:
    """A transfer function given to tc.simulate is adapted (e = x_target − x_B, the run's
    controller.error) and gives the trace of the adapter built by hand, bit for bit."""
    run = _runs()["pid"]
    system = _system(run)
    given = tc.simulate(run, plant_fmu, controller=system, supervised=False)
    by_hand = tc.simulate(
        run, plant_fmu, controller=DiscreteSystemController(system, "x_B", run.x_target, run.T_s), supervised=False
    )
    assert given.status == "complete" and given.record["loop"]["kind"] == "compiled", given.record["loop"]
    _same_bits(given, by_hand)


def test_simulate_refuses_a_continuous_system_before_any_run(plant_fmu: Path, monkeypatch) -> None:  # noqa: ANN001
    run = _runs()["pid"]
    started = []
    monkeypatch.setattr("toggle_cosim.api.simulation._outcome", lambda *args, **kwargs: started.append(args))
    with pytest.raises(ValueError, match=r"^controller: the python-control system is a continuous-time system") as e:
        tc.simulate(run, plant_fmu, controller=control.tf([10.0, 1.0], [1.0, 0.0]), supervised=False)
    assert "controller.discretise" in str(e.value) and "\n" not in str(e.value)
    assert started == []


def test_discretise_samples_a_continuous_system_by_the_named_method(plant_fmu: Path) -> None:
    """controller.discretise: tustin gives the run of the system sampled by control.sample_system."""
    run = _runs()["pid"]
    continuous = control.tf([12.0, 10.0], [1.0, 0.0])  # a PI: Kp + Ki/s
    discretised = dataclasses.replace(run, controller=dataclasses.replace(run.controller, discretise="tustin"))
    sampled = tc.simulate(run, plant_fmu, controller=control.sample_system(continuous, run.T_s, method="tustin"))
    named = tc.simulate(discretised, plant_fmu, controller=continuous)
    assert named.status == "complete" and named.record["controller"]["system"]["discretise"] == "tustin"
    _same_bits(named, sampled)
    discrete = dataclasses.replace(discretised, controller=dataclasses.replace(run.controller, discretise="zoh"))
    with pytest.raises(ValueError, match=r"a discrete-time system \(dt = 0.0005 s\) with controller.discretise: zoh"):
        tc.simulate(discrete, plant_fmu, controller=_system(run))


@pytest.mark.parametrize("variant", ["pid_2dof", "pid_2dof_trajectory"])
def test_a_two_input_system_runs_in_c_with_the_python_loops_bits(variant: str, plant_fmu: Path, monkeypatch) -> None:  # noqa: ANN001
    """The 2-DOF PID (inputs [r − y0, y − y0]) in C and in Python give the same trace, every
    column; its command is the system's response to the recorded r and y (forced_response)."""
    run = _runs()[variant]
    plant = check_plant(plant_fmu)
    system = _system(run)
    compiled = tc.simulate(run, plant_fmu, controller=system, supervised=False)
    with monkeypatch.context() as patch:
        patch.setenv("TOGGLE_COSIM_KERNEL", "0")
        adapter = DiscreteSystemController(system, "x_B", run.x_target, run.T_s, reference=_reference(run))
        python = check_and_simulate(run, plant, controller=adapter)
    assert (
        compiled.record["loop"]["kind"] == "compiled"
        and "(controller natively in C)" in compiled.record["loop"]["reason"]
    )
    assert python.record["loop"]["kind"] == "python"
    _same_bits(compiled, python)
    y = compiled.trace.column("x_B")
    r = y + compiled.trace.column("e")  # e = r − y
    expected = control.forced_response(system, U=np.vstack([r - y[0], y - y[0]])).outputs
    u = compiled.trace.column("iq_ref")
    assert np.max(np.abs(u)) > 0.1 and np.max(np.abs(u - expected)) <= 1e-9 * np.max(np.abs(expected))


def _reference(run: tc.Run) -> SampledReference | None:
    return None if run.trajectory is None else SampledReference.of(build(run.trajectory), run.steps, run.T_s)


def test_the_trajectory_is_the_reference(plant_fmu: Path) -> None:
    """With stroke.trajectory, r at sample k is the sampled profile's x*(t_k): e = x*(t_k) − x_B."""
    run = _runs()["pid_2dof_trajectory"]
    result = tc.simulate(run, plant_fmu)
    reference = _reference(run).values[:, 0]
    assert result.status == "complete" and result.record["controller"]["system"]["reference"] == "stroke.trajectory"
    assert np.array_equal(result.trace.column("e"), reference - result.trace.column("x_B"))
    assert reference[0] == run.x_start and reference[-1] > reference[100]  # the profile moves


def test_the_2dof_pid_starts_without_a_kick(plant_fmu: Path) -> None:
    """From YAML: the PID on the error kicks past the rated current at t = 0 (the derivative of
    the error's step) and is flagged; the 2-DOF PID with the same gains (derivative on the
    measurement, b = 0.6) starts at Kp b (x_target − x_start) and stays within it. From
    tc.simulate with the system itself: the same trace."""
    runs = _runs()
    error_pid, two_dof = tc.simulate(runs["pid"], plant_fmu), tc.simulate(runs["pid_2dof"], plant_fmu)
    rated = runs["pid"].plant.rated_current
    assert abs(error_pid.trace.column("iq_ref")[0]) > rated
    assert any("exceeds the rated current" in warning for warning in error_pid.record["warnings"])
    u = two_dof.trace.column("iq_ref")
    p = runs["pid_2dof"].controller.parameters
    stroke = runs["pid_2dof"].x_target - runs["pid_2dof"].x_start
    assert u[0] == pytest.approx(p["Kp"] * p["b"] * stroke + p["Ki"] * runs["pid_2dof"].T_s * stroke, rel=1e-9)
    assert np.max(np.abs(u)) < rated and two_dof.record["warnings"] == []
    assert two_dof.record["loop"]["kind"] == "compiled"
    live = tc.simulate(runs["pid_2dof"], plant_fmu, controller=_system(runs["pid_2dof"]))
    assert np.array_equal(live.trace.column("iq_ref"), u)


def test_a_scenario_keys_a_python_control_system_may_take(tmp_path: Path) -> None:
    document = yaml.safe_load(PID_2DOF.read_text(encoding="utf-8"))
    document.pop("variants")
    document["controller"] = {"python": "m:f", "error": {"output": "x_B"}, "discretise": "tustin"}
    (run,) = runs_from_document(document)
    assert run.controller.discretise == "tustin"
    document["controller"]["discretise"] = "bogus"
    with pytest.raises(tc.ScenarioError, match=r"key controller\.discretise"):
        runs_from_document(document)
    document["controller"] = {"law": "paper", "discretise": "tustin"}
    with pytest.raises(tc.ScenarioError, match=r"^key controller\.discretise: only with controller\.python"):
        runs_from_document(document)
