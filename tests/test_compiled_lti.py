"""python-control controllers in the compiled system loop (`system_natives`' second native kind).

Behaviour checked: a python-control system adapted by `control.lti` (the shipped example's PID, a
transfer function; a 4th-order state-space controller) runs in C and gives the Python loop's
trace bit for bit, every column (the C sums C x + D e and A x + B e in `lti_step`'s order,
compiled without contraction); the command is the system's own response to the recorded error
(python-control's forced_response, to 1e-9 of its scale: numpy sums in another order); a
subclass that overrides step runs in Python and says why; jacobi coupling runs in C too;
a state that overflows mid-run is handed back to Python, which fails the run at the same sample
with the same reason as the Python execution alone.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import control
import numpy as np
import pytest

from toggle_cosim.control.lti import DiscreteSystemController
from toggle_cosim.control.protocol import ControllerContext
from toggle_cosim.cosim.execution.system_loop import system_library
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "controllers" / "user_controllers.yaml"
T_END = 0.3  # s: 600 samples, the PID's integral and derivative both at work

pytestmark = pytest.mark.skipif(system_library() is None, reason="no C compiler for the compiled loop")


@pytest.fixture(scope="module")
def pid_run():
    run = next(r for r in load_scenario(EXAMPLE) if r.variant == "pid")
    return dataclasses.replace(run, t_end=T_END)


def _pid(run) -> control.TransferFunction:  # noqa: ANN001
    sys.path.insert(0, str(EXAMPLE.parent))
    try:
        from my_controllers import make_pid
    finally:
        sys.path.remove(str(EXAMPLE.parent))
    context = ControllerContext(run.T_s, run.t_end, run.x_start, run.x_target, "x_B", run.label)
    return make_pid(context, **run.controller.parameters)


def _fourth_order(run) -> control.StateSpace:  # noqa: ANN001
    """The PID in series with a discretised 2nd-order low-pass (40 Hz, ζ = 0.7): four states."""
    w = 2 * math.pi * 40.0
    low_pass = control.sample_system(control.tf([w * w], [1.0, 2 * 0.7 * w, w * w]), run.T_s, method="zoh")
    system = control.ss(control.series(_pid(run), low_pass))
    assert system.nstates == 4
    return system


def _both(run, plant, make, monkeypatch):  # noqa: ANN001, ANN202
    """(the outcome with the compiled loop, the outcome with the Python execution alone)."""
    compiled = check_and_simulate(run, plant, controller=make())
    with monkeypatch.context() as patch:
        patch.setenv("TOGGLE_COSIM_KERNEL", "0")
        python = check_and_simulate(run, plant, controller=make())
    return compiled, python


def _same_bits(a, b) -> None:  # noqa: ANN001
    assert a.trace.names == b.trace.names
    for column in a.trace.names:
        assert np.array_equal(a.trace.column(column), b.trace.column(column)), column


@pytest.mark.parametrize("which", ["pid", "fourth_order"])
def test_lti_controller_runs_in_c_with_the_python_loops_bits(which, pid_run, plant_fmu, monkeypatch) -> None:  # noqa: ANN001
    plant = check_plant(plant_fmu)
    system = _pid(pid_run) if which == "pid" else _fourth_order(pid_run)

    def make() -> DiscreteSystemController:
        return DiscreteSystemController(system, "x_B", pid_run.x_target, pid_run.T_s)

    compiled, python = _both(pid_run, plant, make, monkeypatch)
    assert compiled.complete and python.complete, (compiled.reason, python.reason)
    assert compiled.record["loop"]["kind"] == "compiled", compiled.record["loop"]
    assert "(controller natively in C)" in compiled.record["loop"]["reason"]
    assert python.record["loop"]["kind"] == "python"
    _same_bits(compiled, python)
    # the command is the system's response to the recorded error, x = 0 at the start
    e, u = compiled.trace.column("e"), compiled.trace.column("iq_ref")
    assert np.max(np.abs(e - (pid_run.x_target - compiled.trace.column("x_B")))) == 0.0
    expected = control.forced_response(control.ss(system), U=e).outputs
    assert np.max(np.abs(u)) > 0.1  # the controller acts: the comparison is not of zeros
    assert np.max(np.abs(u - expected)) <= 1e-9 * np.max(np.abs(expected))


def test_a_subclass_that_overrides_step_runs_in_python_and_jacobi_in_c(pid_run, plant_fmu) -> None:  # noqa: ANN001
    plant = check_plant(plant_fmu)
    system = _pid(pid_run)

    class Doubled(DiscreteSystemController):
        def step(self, state, t, measurement):  # noqa: ANN001, ANN202
            result = super().step(state, t, measurement)
            return dataclasses.replace(result, command=2.0 * result.command)

    doubled = check_and_simulate(pid_run, plant, controller=Doubled(system, "x_B", pid_run.x_target, pid_run.T_s))
    assert doubled.record["loop"]["kind"] == "python"
    assert "Doubled.step" in doubled.record["loop"]["reason"]
    plain = check_and_simulate(
        pid_run, plant, controller=DiscreteSystemController(system, "x_B", pid_run.x_target, pid_run.T_s)
    )
    assert doubled.trace.column("iq_ref")[0] == 2.0 * plain.trace.column("iq_ref")[0] != 0.0
    jacobi = check_and_simulate(
        pid_run,
        plant,
        controller=DiscreteSystemController(system, "x_B", pid_run.x_target, pid_run.T_s),
        coupling="jacobi",
    )
    assert jacobi.complete and jacobi.record["loop"]["kind"] == "compiled"
    assert (
        ", jacobi, " in jacobi.record["loop"]["reason"]
        and "(controller natively in C)" in jacobi.record["loop"]["reason"]
    )


def test_a_state_that_overflows_hands_back_and_fails_as_in_python(pid_run, plant_fmu, monkeypatch) -> None:  # noqa: ANN001
    """x ← 10 x + e overflows to inf after about 310 samples while u = 0·x stays 0; the sample
    whose next state is inf goes back to Python, and the next sample's u = 0·inf = nan fails the
    run there, as in the Python execution alone."""
    plant = check_plant(plant_fmu)
    system = control.ss([[10.0]], [[1.0]], [[0.0]], [[0.0]], pid_run.T_s)

    def make() -> DiscreteSystemController:
        return DiscreteSystemController(system, "x_B", pid_run.x_target, pid_run.T_s)

    compiled, python = _both(pid_run, plant, make, monkeypatch)
    assert not compiled.complete and compiled.reason == python.reason
    assert compiled.reason.startswith("controller failed: the controller's command at t = ")
    assert "nan" in compiled.reason
    assert compiled.record["loop"]["kind"] == "compiled, then python", compiled.record["loop"]
    rows = len(compiled.trace.column("time"))
    assert 250 < rows < pid_run.steps and rows == len(python.trace.column("time"))
    _same_bits(compiled, python)
