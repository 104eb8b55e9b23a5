"""A user's Python controller in a system's compiled loop (`cosim.execution.system_python`): every FMU call
stays in C, and the C calls the controller back into Python at its turns of each sample.

Behaviour checked: the press example's four components with the examples' Python controllers (a
PD law, the limited VSC) and a PID written here (an integral and a filtered derivative as its
state) run in the compiled loop, and the trace has the Python execution's bits in every column,
under Gauss-Seidel and Jacobi; a controller that raises at a sample ends the run with the reason,
the rows and the run.json of the Python execution; an interrupt, raised by the controller's code
or sent while an FMU runs in C, interrupts the run in both forms at the same sample, and nothing
is printed and dropped in the callback.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import signal
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from system_runs import simulate_system
from test_system_retries import _c, _refusing_part

from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.cosim import systems
from toggle_cosim.cosim.controllers import controller_for
from toggle_cosim.cosim.execution.system_loop import system_library, system_library_reason
from toggle_cosim.cosim.execution.system_retry import CheckpointOptions
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.runs.definition import Run
from toggle_cosim.system.model import Part, Wiring

ROOT = Path(__file__).resolve().parent.parent
PRESS = ROOT / "examples" / "press_system" / "press.yaml"
CALLED_BACK = "controller in Python, called back from C"

pytestmark = pytest.mark.skipif(system_library() is None, reason=f"no system loop: {system_library_reason()}")


def _examples() -> object:
    """examples/controllers/my_controllers.py, imported from its file."""
    path = ROOT / "examples" / "controllers" / "my_controllers.py"
    spec = importlib.util.spec_from_file_location("my_controllers_for_tests", path)
    module = sys.modules.setdefault(spec.name, importlib.util.module_from_spec(spec))
    if not hasattr(module, "PDController"):
        spec.loader.exec_module(module)
    return module


class _Pid:
    """A discrete PID on x_B written against the protocol: the integral of the error and a
    first-order filtered derivative of x_B are its state (a tuple)."""

    diagnostics = ("e",)
    measured = ("x_B", "v_B")

    def __init__(self, target: float, T_s: float) -> None:
        self.target, self.T_s, self.a = target, T_s, 0.9

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return (0.0, measurement["x_B"], 0.0)

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        integral, last, derivative = state
        x = measurement["x_B"]
        e = self.target - x
        derivative = self.a * derivative + (1.0 - self.a) * (x - last) / self.T_s
        u = 40.0 * e + 80.0 * integral - 5.0 * derivative - 0.5 * measurement["v_B"]
        return ControlStep(u, (e,), (integral + e * self.T_s, x, derivative))


def _press(parts: dict[str, Path], t_end: float) -> Run:
    """examples/press_system/press.yaml's first variant (plant, sensor, controller, die) for t_end."""
    document = yaml.safe_load(PRESS.read_text(encoding="utf-8"))
    document["components"]["sensor"]["fmu"] = str(parts["PositionSensor"])
    document["components"]["die"]["fmu"] = str(parts["DieLoad"])
    return dataclasses.replace(runs_from_document(document, PRESS)[0], t_end=t_end)


def _controller(kind: str, run: Run, plant: object) -> object:
    examples = _examples()
    if kind == "pd":
        return examples.PDController(run.x_target, 12.0, 2.5)
    if kind == "limited_vsc":
        built = controller_for(run, plant.recorded_outputs)
        return examples.LimitedVSC(**{f.name: getattr(built, f.name) for f in dataclasses.fields(VSCController)})
    return _Pid(run.x_target, run.T_s)


def _both(
    run: Run, plant: object, make: object, monkeypatch: pytest.MonkeyPatch, coupling: str, interval: int = 200
) -> tuple:
    """The run with a fresh controller from `make()` in the compiled loop, then in the Python
    execution (no compiled loop made), a checkpoint every `interval` samples: the two outcomes."""
    options = CheckpointOptions(interval=interval)
    compiled = simulate_system(run, plant, controller=make(), coupling=coupling, checkpoints=options)
    with monkeypatch.context() as patch:
        patch.setattr(systems, "compiled_system", lambda *args, **kwargs: "the Python form, for the comparison")
        python = simulate_system(run, plant, controller=make(), coupling=coupling, checkpoints=options)
    assert compiled.record["loop"]["kind"] == "system, compiled"
    assert CALLED_BACK in compiled.record["loop"]["reason"], compiled.record["loop"]
    assert python.record["loop"]["kind"] == "system, python"
    return compiled, python


def _same_record(compiled: object, python: object) -> None:
    """run.json of the two forms: the same, but for which loop ran and how long it took."""
    timing = ("loop", "wall_time_s", "loop_time_s", "real_time_factor")
    assert {k: v for k, v in compiled.record.items() if k not in timing} == {
        k: v for k, v in python.record.items() if k not in timing
    }


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("kind", ["pd", "limited_vsc", "pid"])
def test_a_python_controller_in_the_press_system_has_the_python_execution_s_bits(
    kind: str, coupling: str, plant_fmu: Path, press_parts: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The press system's four components with a Python controller: the compiled loop runs it
    (the controller called back into Python), and every column of the trace has the bits of the
    Python execution's, under either coupling."""
    plant = check_plant(plant_fmu)
    run = _press(press_parts, 0.1)
    compiled, python = _both(run, plant, lambda: _controller(kind, run, plant), monkeypatch, coupling)
    assert compiled.complete and python.complete, (compiled.reason, python.reason)
    assert compiled.trace.names == python.trace.names
    for name in compiled.trace.names:
        assert np.array_equal(compiled.trace.column(name), python.trace.column(name)), name
    assert np.ptp(compiled.trace.column("controller.iq_ref")) > 0.1  # the command moves: not a constant compared
    _same_record(compiled, python)


class _RaisesAt(_Pid):
    """The PID, whose step raises from t = 0.01 s (sample 20)."""

    def __init__(self, target: float, T_s: float, error: BaseException) -> None:
        super().__init__(target, T_s)
        self.error = error

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        if t >= 0.01:
            raise self.error
        return super().step(state, t, measurement)


def _fig4_system(t_end: float = 0.05) -> Run:
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=t_end)
    return dataclasses.replace(run, system=Wiring(connections=systems.pair_connections(Wiring(), ("x_B", "v_B"))))


@pytest.mark.parametrize("interval", [200, 21], ids=["mid-stretch", "at-a-stretch-end"])
@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_a_controller_that_raises_at_a_sample_ends_both_forms_alike(
    coupling: str, interval: int, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The controller's step raises at t = 0.01 s (sample 20): the run fails with the same reason
    (naming the component, the step, the time and the error), the same rows and the same run.json
    in the compiled loop as in the Python execution. (Under Jacobi the controller computes at its
    doStep, after the sample's row: one row more; with a checkpoint every 21 samples that doStep
    is the last of a stretch, made once the C has returned.)"""
    plant = check_plant(plant_fmu)
    run = _fig4_system()
    make = lambda: _RaisesAt(run.x_target, run.T_s, ValueError("the user's bug"))  # noqa: E731
    compiled, python = _both(run, plant, make, monkeypatch, coupling, interval)
    assert not compiled.complete and not compiled.interrupted
    assert compiled.reason == python.reason
    assert compiled.reason == (
        "component 'controller': the controller's step raised at t = 0.01 s: ValueError: the user's bug"
    )
    assert compiled.record["samples"] == (21 if coupling == "jacobi" else 20)
    assert np.array_equal(compiled.trace.data, python.trace.data)
    _same_record(compiled, python)


def test_an_interrupt_raised_in_the_controller_interrupts_the_run(
    plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """KeyboardInterrupt from the controller's step (in the command's own process: an interrupt,
    not the code's failure) is not kept in the callback: the run is interrupted at that sample in
    the compiled loop as in the Python execution, with the same rows and reason."""
    plant = check_plant(plant_fmu)
    run = _fig4_system()
    make = lambda: _RaisesAt(run.x_target, run.T_s, KeyboardInterrupt())  # noqa: E731
    compiled, python = _both(run, plant, make, monkeypatch, "gauss-seidel")
    for outcome in (compiled, python):
        assert outcome.interrupted and outcome.record["status"] == "interrupted", outcome.reason
    assert compiled.reason == python.reason == "interrupted (SIGINT or SIGTERM) at t = 0.0095 s"
    assert np.array_equal(compiled.trace.data, python.trace.data)


def test_sigint_sent_while_an_fmu_steps_in_c_interrupts_the_run(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    """A part FMU that sends the process SIGINT from its doStep at t = 0.01 s, beside a Python
    controller: the interrupt lands while the C runs, and Python raises it as the next Python code
    starts, the controller's callback (before its own handler can catch it). The run is
    interrupted in the compiled loop as in the Python execution, with the same rows, and
    nothing says an exception was ignored."""
    part = _refusing_part(tmp_path, True, "-DINTERRUPT_AT=0.01")
    plant = check_plant(plant_fmu)
    base = _fig4_system()
    wires = (*base.system.connections, _c("plant.x_B -> probe.x"))
    run = dataclasses.replace(base, system=Wiring(parts=(Part("probe", part),), connections=wires))
    old = signal.signal(signal.SIGINT, signal.default_int_handler)  # SIGINT raises KeyboardInterrupt, as in a command
    try:
        compiled, python = _both(run, plant, lambda: _Pid(run.x_target, run.T_s), monkeypatch, "gauss-seidel")
    finally:
        signal.signal(signal.SIGINT, old)
    for outcome in (compiled, python):
        assert outcome.interrupted and outcome.record["status"] == "interrupted", outcome.reason
    assert compiled.reason == python.reason
    assert compiled.record["samples"] == python.record["samples"] == 21  # t = 0 .. 0.01 s recorded
    assert np.array_equal(compiled.trace.data, python.trace.data)
    assert "ignored" not in capfd.readouterr().err


def test_an_exception_escaping_the_callback_is_kept_by_its_loop_and_the_hook_put_back() -> None:
    """While a loop with callbacks runs (two at once, as two threads would), an exception that
    escapes a callback (Python reports it as unraisable, naming the callback) is kept by that
    loop, to be raised from its `run`; any other unraisable goes to the hook in place before;
    once the last loop has returned, that hook is back."""
    import sys
    from types import SimpleNamespace

    from toggle_cosim.cosim.execution.system_python import Callbacks

    first, second = Callbacks({}, 0.001), Callbacks({}, 0.001)
    before, other = sys.unraisablehook, []

    def escaped(callbacks: Callbacks, error: BaseException) -> SimpleNamespace:
        said = f"Exception ignored on calling ctypes callback function {callbacks.target!r}"
        return SimpleNamespace(exc_value=error, object=None, err_msg=said, exc_type=type(error), exc_traceback=None)

    sys.unraisablehook = other.append
    try:
        with first.catching():
            with second.catching():
                interrupt = KeyboardInterrupt()
                sys.unraisablehook(escaped(second, interrupt))
                sys.unraisablehook(SimpleNamespace(exc_value=ValueError("a __del__"), object=None, err_msg="x"))
            assert second.raised == [interrupt] and first.raised == [] and len(other) == 1
        assert sys.unraisablehook == other.append
    finally:
        sys.unraisablehook = before


class _Recording:
    """A controller that keeps each measurement it is given and what it held then; its command
    is its input c."""

    diagnostics = ()

    def __init__(self) -> None:
        self.seen: list[tuple[object, dict[str, float]]] = []

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return None

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        self.seen.append((measurement, dict(measurement)))
        return ControlStep(measurement["c"], (), state)


def _controller_slave(controller: object) -> object:
    """A native controller component measuring a, b and c, each fed by the plant's output of its name."""
    from toggle_cosim.cosim.execution.slaves import ControllerSlave
    from toggle_cosim.system.model import Interface

    slave = ControllerSlave("controller", controller, (), Interface(("a", "b", "c"), ("iq_ref",)))
    slave.fed_from(tuple(f"component 'plant': its output {name}" for name in "abc"))
    return slave


def test_a_controller_is_given_one_view_of_its_inputs_holding_each_sample_s_values() -> None:
    """At each sample the controller's measurement holds the inputs as set for that sample; it
    is the same read-only view every sample (no new object per sample), so a value is read
    during the call and a copy (dict(measurement)) is what keeps one."""
    import ctypes

    controller = _Recording()
    slave = _controller_slave(controller)
    out = (ctypes.c_double * 1)()
    for k, values in enumerate([(1.0, 2.0, 3.0), (4.0, 5.0, 6.5)]):
        slave.set((0, 1, 2), values, k * 0.5)
        slave.get(out, k * 0.5)
        slave.do_step(k * 0.5, 0.5)
        assert out[0] == values[2]
    (first, held_first), (second, held_second) = controller.seen
    assert first is second
    assert held_first == {"a": 1.0, "b": 2.0, "c": 3.0} and held_second == {"a": 4.0, "b": 5.0, "c": 6.5}


@pytest.mark.parametrize(
    ("values", "refused"),
    [
        ((1.0, float("nan"), 2.0), "component 'plant': its output b is nan at t = 0.25 s"),
        ((float("inf"), float("-inf"), 0.0), "component 'plant': its output a is inf at t = 0.25 s"),
        ((0.0, 1.0, float("-inf")), "component 'plant': its output c is -inf at t = 0.25 s"),
    ],
)
def test_every_input_set_at_once_is_refused_only_for_a_value_that_is_not_finite(values: tuple, refused: str) -> None:
    """A sample of every input at once is checked in one go: finite values whose sum overflows
    to infinity are taken as they are, a NaN or an infinity (infinities of both signs too, whose
    sum is NaN) is refused naming the first such input, its value and the time."""
    import ctypes

    from toggle_cosim.cosim.execution.slaves import SlaveError

    controller = _Recording()
    slave = _controller_slave(controller)
    slave.set((0, 1, 2), (1e308, 1e308, -1.0), 0.0)
    slave.get((ctypes.c_double * 1)(), 0.0)
    assert controller.seen[-1][1] == {"a": 1e308, "b": 1e308, "c": -1.0}
    with pytest.raises(SlaveError) as caught:
        slave.set((0, 1, 2), values, 0.25)
    assert str(caught.value) == (
        f"{refused}, measured by the native controller 'controller', which takes finite values only"
    )
    assert caught.value.not_finite
