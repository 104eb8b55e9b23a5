"""The compiled system loop (`cosim.execution.system_loop`): a system's stepping plan run in C over a
component table and a connection table.

Behaviour checked: the plant FMU and the controller FMU ToggleVSC (FMI 2.0 and 3.0), wired as
the pair (the plant's outputs to the controller's inputs of the same name, the command to the
plant's iq_ref, F_E from a signal column), initialised here with fmpy as the master initialises
them and stepped by `SystemLoop`, give the master's trace of the same scenario
(`controller: {fmu: ...}`) bit for bit in every column the two share, under Gauss-Seidel and
under Jacobi; a run in two stretches gives the one-call run's bits; a connection with a factor
and an offset delivers factor · value + offset with Python's bits (read back from the FMU); a
call that fails stops the loop at its sample and names the component and the FMI function.
A three-FMU system assembled and initialised by the master (`cosim.systems.assemble`, the pair
and a second controller instance reading the plant) runs its first samples in the Python
execution and the rest in C with the all-Python run's bits; a system of the built-in law (run
natively in C) or of a controller FMU gets a loop, and none with TOGGLE_COSIM_KERNEL=0.
"""

from __future__ import annotations

import dataclasses
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fmpy import extract
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from toggle_cosim.controller_fmu import build_controller_fmu
from toggle_cosim.cosim.controllers import controller_for
from toggle_cosim.cosim.execution.algorithm import Execution, TraceObserver
from toggle_cosim.cosim.execution.fmi_pointers import fmu_functions
from toggle_cosim.cosim.execution.system_loop import (
    DONE,
    FMI_FAILED,
    SystemLoop,
    compiled_system,
    system_library,
    system_library_reason,
)
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.cosim.plant_inputs import input_samples, plant_settings
from toggle_cosim.cosim.systems import assemble, pair_connections
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.graph import gauss_seidel_order
from toggle_cosim.system.model import Connection, Interface, Part, Port, Wiring
from toggle_cosim.system.plan import Plan, build_plan

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "fig4_nominal.yaml"
SETTERS = {  # fmpy's setter per FMI type
    "Real": "setReal",
    "Float64": "setFloat64",
    "Integer": "setInteger",
    "Int32": "setInt32",
    "Int64": "setInt64",
    "Enumeration": "setInteger",
    "Boolean": "setBoolean",
}


@pytest.fixture(autouse=True)
def _needs_the_library() -> None:
    if system_library() is None:
        pytest.skip(f"no compiled system loop: {system_library_reason()}")


@pytest.fixture(scope="module")
def toggle_vsc(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("system-loop-vsc")
    return {v: Path(build_controller_fmu(folder / f"ToggleVSC{v[0]}.fmu", v).path) for v in ("2.0", "3.0")}


def _set(slave: Any, kind: str, reference: int, value: object) -> None:
    value = bool(value) if kind == "Boolean" else int(value) if "Int" in kind or kind == "Enumeration" else float(value)
    getattr(slave, SETTERS[kind])([reference], [value])


def _slave(path: Path, token: str, identifier: str, fmi3: bool, name: str, folders: list[str]) -> Any:
    folder = extract(str(path))
    folders.append(folder)
    kind = FMU3Slave if fmi3 else FMU2Slave
    return kind(guid=token, unzipDirectory=folder, modelIdentifier=identifier, instanceName=name)


def _initialise(slave: Any, fmi3: bool, t_end: float, values: Sequence[tuple[int, str, object]], inputs=()) -> None:  # noqa: ANN001
    """Instantiate, set the parameters, initialise with the inputs: as the master does."""
    slave.instantiate(visible=False, loggingOn=False)
    if not fmi3:
        slave.setupExperiment(startTime=0.0, stopTime=t_end)
    for reference, kind, value in values:
        _set(slave, kind, reference, value)
    if fmi3:
        slave.enterInitializationMode(startTime=0.0, stopTime=t_end)
    else:
        slave.enterInitializationMode()
    for reference, kind, value in inputs:
        _set(slave, kind, reference, value)
    slave.exitInitializationMode()


@dataclasses.dataclass
class Pair:
    """The plant + controller-FMU system, initialised, with its plan and a loop over it."""

    run: Any
    plan: Plan
    loop: SystemLoop
    trace: np.ndarray
    slaves: tuple[Any, Any]
    controller: Any
    functions: tuple[Any, ...]


@contextmanager
def pair_system(
    plant_fmu: Path,
    controller_fmu: Path,
    jacobi: bool = False,
    conversions: dict[str, tuple[float, float]] | None = None,
) -> Iterator[Pair]:
    """fig4_nominal/friction with the controller FMU as a system: the pair's wiring (controller
    input v from plant.v, with `conversions[v]` = (factor, offset) where given), F_E from the
    signal table's only column; every port recorded."""
    plant = check_plant(plant_fmu)
    run = load_scenario(SCENARIO)[0]
    run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=controller_fmu))
    controller = controller_for(run, plant.recorded_outputs)
    fmu = controller.fmu
    commands = ("iq_ref", *fmu.diagnostics)
    interfaces = {
        "plant": Interface(inputs=("iq_ref", "F_E"), outputs=tuple(plant.recorded_outputs)),
        "controller": Interface(inputs=fmu.inputs, outputs=commands, depends={o: fmu.inputs for o in commands}),
    }
    conversions = conversions or {}
    connections = [
        Connection(Port("plant", v), Port("controller", v), *conversions.get(v, (1.0, 0.0))) for v in fmu.inputs
    ]
    connections.append(Connection(Port("controller", "iq_ref"), Port("plant", "iq_ref")))
    order = gauss_seidel_order(("plant", "controller"), connections, interfaces)
    plan = build_plan(order, interfaces, connections, (Port("plant", "F_E"),), None, jacobi)
    n = run.steps
    signals = np.ascontiguousarray(input_samples(run, n)[:, :1])
    folders: list[str] = []
    slaves: list[Any] = []
    try:
        fmi3 = fmu.fmi_version.startswith("3")
        plant_slave = _slave(plant.path, plant.model_description.guid, plant.model_identifier, False, "plant", folders)
        slaves.append(plant_slave)
        settings = [(plant.references[k], plant.types[k], v) for k, v in plant_settings(run, plant)]
        start = [(plant.references["iq_ref"], "Real", 0.0), (plant.references["F_E"], "Real", signals[0, 0])]
        _initialise(plant_slave, False, run.t_end, settings, start)
        control = _slave(fmu.path, fmu.token, fmu.model_identifier, fmi3, "controller", folders)
        slaves.append(control)
        _initialise(control, fmi3, run.t_end, [(fmu.references[k], fmu.types[k], v) for k, v in controller.settings])
        functions = []
        for c, (slave, references) in enumerate(zip(slaves, (plant.references, fmu.references), strict=True)):
            outputs = [references[v] for v in plan.output_names[c]]
            functions.append(fmu_functions(slave, outputs, [references[v] for v in plan.input_names[c]]))
        trace = np.full((n + 1, len(plan.names)), np.nan)
        loop = SystemLoop(plan, functions, signals, trace, n, run.T_s)
        yield Pair(run, plan, loop, trace, (plant_slave, control), controller, tuple(functions))
    finally:
        for slave in slaves:
            try:
                slave.terminate()
            finally:
                slave.freeInstance()
        for folder in folders:
            shutil.rmtree(folder, ignore_errors=True)


def _column(pair: Pair, port: str) -> np.ndarray:
    return pair.trace[:, pair.plan.names.index(port)]


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("fmi_version", ["2.0", "3.0"])
def test_the_pair_as_a_system_in_c_gives_the_master_s_trace_bit_for_bit(
    fmi_version: str, coupling: str, plant_fmu: Path, toggle_vsc: dict[str, Path]
) -> None:
    """fig4 with ToggleVSC: every column the system's trace shares with the master's run of the
    same scenario (x_B, v_B, iq_ref, the diagnostics, every plant output) has the same bits."""
    fmu = toggle_vsc[fmi_version]
    with pair_system(plant_fmu, fmu, jacobi=coupling == "jacobi") as pair:
        assert pair.plan.order == ("plant", "controller")
        assert pair.loop.run(0, pair.run.steps + 1) == (DONE, pair.run.steps + 1)
        master = check_and_simulate(pair.run, check_plant(plant_fmu), coupling=coupling)
        assert master.complete, master.reason
        assert np.array_equal(pair.trace[:, 0], master.trace.time)
        shared = 0
        for name in master.trace.names[1:]:
            for port in (f"plant.{name}", f"controller.{name}"):
                if port in pair.plan.names:
                    assert np.array_equal(_column(pair, port), master.trace.column(name)), port
                    shared += 1
        assert shared >= len(master.trace.names) - 1  # every master column is in the system's trace
        assert np.array_equal(_column(pair, "controller.iq_ref"), _column(pair, "plant.iq_ref"))
        assert np.ptp(_column(pair, "plant.x_B")) > 0.05 and np.ptp(_column(pair, "plant.iq_ref")) > 1.0


def test_stretches_resume_where_the_last_one_stopped(plant_fmu: Path, toggle_vsc: dict[str, Path]) -> None:
    """Samples 0 .. 999, then 1000 .. n in a second call: the master's trace, bit for bit."""
    with pair_system(plant_fmu, toggle_vsc["2.0"]) as pair:
        n = pair.run.steps
        assert pair.loop.run(0, 1000) == (DONE, 1000)
        assert np.isnan(pair.trace[1000:, 1]).all()
        assert pair.loop.run(1000, n + 1) == (DONE, n + 1)
        master = check_and_simulate(pair.run, check_plant(plant_fmu))
        assert np.array_equal(_column(pair, "plant.x_B"), master.trace.column("x_B"))
        with pytest.raises(ValueError, match="not within"):
            pair.loop.run(0, n + 2)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_a_converted_connection_delivers_factor_times_value_plus_offset(
    coupling: str, plant_fmu: Path, toggle_vsc: dict[str, Path]
) -> None:
    """plant.theta1 -> controller.theta1 in mrad plus 0.5 (factor 1000, offset 0.5; the x_B law
    does not read theta1): the recorded input is 1000 · theta1 + 0.5 with Python's bits at every
    sample, the controller FMU holds the last value sent, and the trajectory is the pair's."""
    factor, offset = 1000.0, 0.5
    with pair_system(plant_fmu, toggle_vsc["2.0"], coupling == "jacobi", {"theta1": (factor, offset)}) as pair:
        n = pair.run.steps
        assert pair.loop.run(0, n + 1) == (DONE, n + 1)
        theta1, sent = _column(pair, "plant.theta1"), _column(pair, "controller.theta1")
        assert np.array_equal(sent, np.array([factor * value + offset for value in theta1.tolist()]))
        assert not np.array_equal(sent, theta1)
        assert np.array_equal(_column(pair, "controller.x_B"), _column(pair, "plant.x_B"))  # identity: a copy
        # the last value the FMU was sent: sample n's (Gauss-Seidel sets it early), n - 1's (Jacobi: late)
        last = n if coupling == "gauss-seidel" else n - 1
        assert pair.slaves[1].getReal([pair.controller.fmu.references["theta1"]]) == [sent[last]]
        master = check_and_simulate(pair.run, check_plant(plant_fmu), coupling=coupling)
        assert np.array_equal(_column(pair, "plant.x_B"), master.trace.column("x_B"))


@pytest.mark.parametrize("fmi_version", ["2.0", "3.0"])
def test_a_failing_call_names_the_component_and_the_function(
    fmi_version: str, plant_fmu: Path, toggle_vsc: dict[str, Path]
) -> None:
    """x_B sent in mm to a controller that reads metres (factor 1000): ToggleVSC cannot evaluate
    its law there and returns Error from its getReal at sample 0; the loop stops there, records
    nothing of that row, and the failure names the controller and fmi2GetReal / fmi3GetFloat64."""
    with pair_system(plant_fmu, toggle_vsc[fmi_version], conversions={"x_B": (1000.0, 0.0)}) as pair:
        code, k = pair.loop.run(0, pair.run.steps + 1)
        assert (code, k) == (FMI_FAILED, 0)
        error = pair.loop.failure()
        function = "fmi3GetFloat64" if fmi_version == "3.0" else "fmi2GetReal"
        assert (error.component, error.function, error.status, error.t) == ("controller", function, 3, 0.0)
        assert str(error) == f"component controller: {function} returned status 3 at t = 0 s"
        assert np.isnan(pair.trace[0, 0])


def test_tables_that_do_not_fit_the_plan_are_refused(plant_fmu: Path, toggle_vsc: dict[str, Path]) -> None:
    """A trace of the wrong width, a signal table of the wrong shape, a missing component's
    calls: ValueError before anything runs; an FMU not instantiated has no C calls."""
    with pair_system(plant_fmu, toggle_vsc["2.0"]) as pair:
        n, T_s, plan = pair.run.steps, pair.run.T_s, pair.plan
        functions = pair.functions
        signals = np.zeros((n + 1, 1))
        with pytest.raises(ValueError, match="columns"):
            SystemLoop(plan, functions, signals, np.zeros((n + 1, 3)), n, T_s)
        with pytest.raises(ValueError, match="signal table"):
            SystemLoop(plan, functions, np.zeros((n, 1)), pair.trace, n, T_s)
        with pytest.raises(ValueError, match="2 components, 1 C calls"):
            SystemLoop(plan, functions[:1], signals, pair.trace, n, T_s)
    folder = extract(str(toggle_vsc["2.0"]))
    try:
        fresh = FMU2Slave(guid="-", unzipDirectory=folder, modelIdentifier="ToggleVSC", instanceName="fresh")
        with pytest.raises(ValueError, match="fresh: not instantiated"):
            fmu_functions(fresh, [], [])
        fresh.freeLibrary()
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_three_fmus_hand_over_from_the_python_execution_to_c_with_its_bits(
    coupling: str, plant_fmu: Path, toggle_vsc: dict[str, Path]
) -> None:
    """The pair plus a monitor (another ToggleVSC instance reading the plant's x_B, v_B, and theta1
    in mrad plus 0.5, which the x_B law does not read): samples 0 .. 499 in `Execution.advance`, 500 .. n in `SystemLoop`, on the
    same instances and buffer slots: every column of the trace equals the run all in Python."""
    plant = check_plant(plant_fmu)
    fmu = toggle_vsc["2.0"]
    run = load_scenario(SCENARIO)[0]
    run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=fmu), coupling=coupling)
    controller = controller_for(run, plant.recorded_outputs)
    inputs = [v for v in controller.fmu.inputs if v in plant.recorded_outputs]
    wiring = Wiring(parts=(Part("monitor", fmu, tuple(controller.settings)),))
    connections = pair_connections(wiring, inputs) + (
        Connection(Port("plant", "x_B"), Port("monitor", "x_B")),
        Connection(Port("plant", "v_B"), Port("monitor", "v_B")),
        Connection(Port("plant", "theta1"), Port("monitor", "theta1"), 1000.0, 0.5),
    )
    run = dataclasses.replace(run, system=dataclasses.replace(wiring, connections=connections))
    n, traces = run.steps, []
    for hand_over in (n + 1, 500):
        assembly = assemble(run, plant)
        try:
            assert assembly.plan.order == ("plant", "controller", "monitor")
            trace = np.full((n + 1, len(assembly.plan.names)), np.nan)
            execution = Execution(
                assembly.plan,
                assembly.slaves,
                assembly.signals,
                n,
                run.T_s,
                run.t_end,
                [TraceObserver(assembly.plan, trace)],
            )
            execution.initialize()
            assert execution.advance(0, hand_over) == hand_over
            if hand_over <= n:
                functions = [slave.c_functions() for slave in assembly.slaves]
                loop = SystemLoop(assembly.plan, functions, assembly.signals, trace, n, run.T_s)
                loop.buffer[:] = execution.values  # the slots as the Python samples left them
                assert loop.run(hand_over, n + 1) == (DONE, n + 1)
            traces.append((assembly.plan.names, trace))
        finally:
            assembly.close()
    (names, python), (_, compiled) = traces
    assert np.array_equal(python, compiled)
    theta1 = python[:, names.index("plant.theta1")].tolist()
    assert np.array_equal(python[:, names.index("monitor.theta1")], np.array([1000.0 * x + 0.5 for x in theta1]))
    assert np.array_equal(python[:, names.index("monitor.iq_ref")], python[:, names.index("controller.iq_ref")])


def test_a_system_of_the_built_in_law_or_a_controller_fmu_gets_a_loop(
    plant_fmu: Path, toggle_vsc: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """fig4 as a system: with the built-in law (a native controller, run in C) and with the
    controller FMU, `compiled_system` gives a loop that runs the system to its end; with
    TOGGLE_COSIM_KERNEL=0 it says the loop is switched off. (A controller run in Python:
    tests/test_system_natives.py.)"""
    plant = check_plant(plant_fmu)
    base = load_scenario(SCENARIO)[0]
    with_fmu = dataclasses.replace(base, controller=dataclasses.replace(base.controller, fmu=toggle_vsc["2.0"]))
    for run in (base, with_fmu):
        wiring = Wiring(connections=pair_connections(Wiring(), ("x_B", "v_B")))  # the law's measured inputs
        run = dataclasses.replace(run, system=wiring)
        assembly = assemble(run, plant)
        try:
            n, plan = run.steps, assembly.plan
            trace = np.full((n + 1, len(plan.names)), np.nan)
            execution = Execution(plan, assembly.slaves, assembly.signals, n, run.T_s, run.t_end)
            execution.initialize()
            made = compiled_system(plan, assembly.slaves, assembly.signals, trace, n, run.T_s)
            assert isinstance(made, SystemLoop), made
            assert made.native_names == (() if run.controller.fmu else ("controller",))
            assert made.run(0, n + 1) == (DONE, n + 1)
            assert np.ptp(trace[:, plan.names.index("plant.x_B")]) > 0.05
            monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
            off = compiled_system(plan, assembly.slaves, assembly.signals, trace, n, run.T_s)
            assert off == "no compiled system loop: disabled by TOGGLE_COSIM_KERNEL=0"
            monkeypatch.delenv("TOGGLE_COSIM_KERNEL")
        finally:
            assembly.close()
