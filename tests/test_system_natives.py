"""The built-in law and python-control systems as native kinds of a system's compiled loop
(`cosim.execution.system_natives`, cosim/execution/system_skeleton.c).

Behaviour checked: a system whose controller is the built-in law (either law, tracking a sampled
trajectory or a constant target) or a python-control system runs entirely in C, and run.json's
`loop` says so; for every shipped scenario with a stored reference, the python-control PIDs of
examples/controllers/pid_2dof.yaml and a tracking scenario, the system's trace has the pair
loop's bits in every column the two share; under Gauss-Seidel and Jacobi the C form has the bits
of the Python form (the same `ControllerSlave` stepped by the Python execution); a sample the C
cannot take (a state that overflows) goes to the Python execution with the rest of the run,
which ends as the Python form ends; a controller whose step is its own runs in Python, called
back from the compiled loop, with a reason naming it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from system_runs import simulate_system

from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.lti import DiscreteSystemController
from toggle_cosim.cosim import systems
from toggle_cosim.cosim.controllers import controller_for
from toggle_cosim.cosim.execution.system_loop import system_library, system_library_reason
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.cosim.systems import pair_connections
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.runs.definition import Run
from toggle_cosim.system.model import Wiring

ROOT = Path(__file__).resolve().parent.parent
REFERENCES = sorted(path.name for path in (ROOT / "scenarios" / "references").iterdir() if path.is_dir())
PID_2DOF = ROOT / "examples" / "controllers" / "pid_2dof.yaml"
NATIVE = "(controller natively in C)"

pytestmark = pytest.mark.skipif(system_library() is None, reason=f"no system loop: {system_library_reason()}")


def _as_system(run: Run, measured: tuple[str, ...] = ("x_B", "v_B")) -> Run:
    """The run's pair as a system: the controller's inputs from the plant outputs of their names."""
    return dataclasses.replace(run, system=Wiring(connections=pair_connections(Wiring(), measured)))


def _measured(run: Run) -> tuple[str, ...]:
    return ("theta1", "omega1") if run.controller.objective == "theta1" else ("x_B", "v_B")


def _same_as_the_pair(system: object, pair: object) -> int:
    """Every column of the pair's trace against the system's column of that variable: the same
    bits. Returns how many were compared."""
    compared = 0
    for name in pair.trace.names[1:]:
        for port in (f"plant.{name}", f"controller.{name}"):
            if port in system.trace.names:
                assert np.array_equal(system.trace.column(port), pair.trace.column(name)), port
                compared += 1
    assert np.array_equal(system.trace.time, pair.trace.time)
    return compared


@pytest.mark.parametrize("scenario", REFERENCES)
def test_every_referenced_scenario_as_a_system_runs_the_law_in_c_with_the_pair_s_bits(
    scenario: str, plant_fmu: Path, no_gravity_fmu: Path
) -> None:
    """Each variant of a shipped scenario with a stored reference (the paper's figures, the
    integral law, the tracking press cycle, ...) as a two-part system: the built-in law runs in
    the compiled system loop, natively, and every column the pair's trace has (the plant's
    outputs, iq_ref, S, phase, e) has the pair loop's bits, those that a load changing in time
    feeds straight through included (a signal-fed input is set after the outputs are read, as the
    pair sets it)."""
    plant = check_plant(no_gravity_fmu if scenario == "swap_no_gravity" else plant_fmu)
    for run in load_scenario(ROOT / "scenarios" / f"{scenario}.yaml"):
        pair = check_and_simulate(run, plant)
        system = simulate_system(_as_system(run, _measured(run)), plant)
        assert pair.complete and system.complete, (pair.reason, system.reason)
        assert system.record["loop"]["kind"] == "system, compiled"
        assert system.record["loop"]["reason"].endswith(NATIVE), system.record["loop"]
        assert _same_as_the_pair(system, pair) >= len(pair.trace.names) - 1, run.label


def _pid_runs() -> dict[str, Run]:
    return {run.variant: run for run in load_scenario(PID_2DOF)}


@pytest.mark.parametrize("variant", ["pid", "pid_2dof", "pid_2dof_trajectory"])
def test_a_python_control_pid_runs_in_c_inside_a_system_with_the_pair_s_bits(variant: str, plant_fmu: Path) -> None:
    """The PIDs of examples/controllers/pid_2dof.yaml (on the error; 2-DOF on [r − y0, y − y0];
    2-DOF tracking the trapezoid) as the controller of a two-part system: natively in C, and
    every column with the pair loop's bits."""
    plant = check_plant(plant_fmu)
    run = dataclasses.replace(_pid_runs()[variant], t_end=0.3)
    pair = check_and_simulate(run, plant)
    system = simulate_system(_as_system(run, ("x_B",)), plant)
    assert pair.complete and system.complete, (pair.reason, system.reason)
    assert system.record["loop"]["reason"].endswith(NATIVE), system.record["loop"]
    assert _same_as_the_pair(system, pair) >= len(pair.trace.names) - 1
    assert np.ptp(system.trace.column("controller.iq_ref")) > 0.1


def _python_form(monkeypatch: pytest.MonkeyPatch) -> None:
    """The next system runs in the Python execution: no compiled loop is made."""
    monkeypatch.setattr(systems, "compiled_system", lambda *args, **kwargs: "the Python form, for the comparison")


CASES = {  # (scenario, variant or None, t_end): the law's kinds and the LTI system's two forms
    "paper": (ROOT / "scenarios" / "fig4_nominal.yaml", None, 0.3),
    "integral": (ROOT / "scenarios" / "integral_load.yaml", None, 0.3),
    "tracking": (ROOT / "scenarios" / "press_cycle.yaml", None, 0.6),
    "pid": (PID_2DOF, "pid", 0.2),
    "pid_2dof_trajectory": (PID_2DOF, "pid_2dof_trajectory", 0.2),
}


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("case", list(CASES))
def test_the_c_form_has_the_python_form_s_bits(
    case: str, coupling: str, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same system with its controller stepped by the Python execution (`ControllerSlave`)
    and natively in the compiled loop: the same trace, every column, under either coupling."""
    path, variant, t_end = CASES[case]
    run = next(r for r in load_scenario(path) if variant is None or r.variant == variant)
    run = _as_system(dataclasses.replace(run, t_end=t_end), ("x_B",) if variant else ("x_B", "v_B"))
    plant = check_plant(plant_fmu)
    compiled = simulate_system(run, plant, coupling=coupling)
    with monkeypatch.context() as patch:
        _python_form(patch)
        python = simulate_system(run, plant, coupling=coupling)
    assert compiled.complete and python.complete, (compiled.reason, python.reason)
    assert compiled.record["loop"]["reason"].endswith(NATIVE)
    assert python.record["loop"]["kind"] == "system, python"
    assert compiled.trace.names == python.trace.names
    for name in compiled.trace.names:
        assert np.array_equal(compiled.trace.column(name), python.trace.column(name)), name


class _Overflowing(DiscreteSystemController):
    """Marks the class of the test's system; its start and step stay DiscreteSystemController's."""


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_a_sample_the_c_cannot_take_goes_to_python_with_the_rest_of_the_run(
    coupling: str, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A one-state system whose state grows a thousandfold per sample: its state overflows to
    infinity while its command is still finite, a sample the C hands back; the Python execution
    takes it and the rest of the run, which fails at the next sample (the command is infinite) as
    the Python form fails: the same reason, the same rows, and run.json says from when it ran in
    Python. (Under Jacobi the controller computes at its doStep, after the sample's row: the
    failure comes one recorded row later.)"""
    import control

    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.1)
    run = _as_system(run, ("x_B",))
    system = control.ss([[1000.0]], [[1.0]], [[1e-300]], [[0.0]], run.T_s)
    plant = check_plant(plant_fmu)

    def run_it() -> object:
        controller = _Overflowing(system, "x_B", run.x_target, run.T_s)
        return simulate_system(run, plant, controller=controller, coupling=coupling)

    compiled = run_it()
    with monkeypatch.context() as patch:
        _python_form(patch)
        python = run_it()
    assert not compiled.complete and compiled.reason == python.reason
    assert "command" in compiled.reason and "not a finite float" in compiled.reason
    assert compiled.trace.names == python.trace.names and len(compiled.trace.time) == len(python.trace.time) > 50
    for name in compiled.trace.names:
        assert np.array_equal(compiled.trace.column(name), python.trace.column(name)), name
    handed = len(python.trace.time) - (2 if coupling == "jacobi" else 1)  # the sample whose next state overflowed
    assert compiled.record["loop"]["reason"].endswith(
        f"{NATIVE}, from t = {handed * run.T_s:.6g} s in Python (a sample the native controller handed back)"
    ), compiled.record["loop"]


class _OwnStep(VSCController):
    def step(self, state, t, measurement):  # noqa: ANN001, ANN201 - the built-in step, as a subclass's own
        return super().step(state, t, measurement)


def test_a_controller_with_its_own_step_runs_in_python_and_says_why(plant_fmu: Path) -> None:
    """A subclass of the built-in law that overrides step is not the generated law: the compiled
    system loop calls it back into Python (`system_python`), and run.json names the component and
    the reason."""
    run = _as_system(dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.05))
    plant = check_plant(plant_fmu)
    built = controller_for(run, plant.recorded_outputs)
    own = _OwnStep(**{f.name: getattr(built, f.name) for f in dataclasses.fields(VSCController)})
    result = simulate_system(run, plant, controller=own)
    assert result.complete and result.record["loop"]["kind"] == "system, compiled"
    assert (
        "controller in Python, called back from C (_OwnStep: the controller's step is"
        in (result.record["loop"]["reason"])
    )
