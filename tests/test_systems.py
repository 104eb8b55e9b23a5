"""A system is the master's unit: components, connections, the order they are stepped in.

The physics of the pair is checked elsewhere; here the claim is that the system execution makes
exactly the calls of the plant + controller loop (bit for bit, both couplings, built-in law and
controller FMU), that connections are followed (a crossed wiring changes the trace), and that
the order, the algebraic loops, the units and the scenario keys behave as documented.
"""

from __future__ import annotations

import dataclasses
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from toggle_cosim.cosim import master, systems
from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.graph import AlgebraicLoop, algebraic_loop, gauss_seidel_order
from toggle_cosim.system.model import Connection, Interface, Part, Port, Wiring
from toggle_cosim.system.plan import SIGNAL, build_plan

ROOT = Path(__file__).resolve().parent.parent


def _c(text: str) -> Connection:
    start, end = (Port.parse(side.strip()) for side in text.split("->"))
    return Connection(start, end)


# -- order and algebraic loops (pure) ------------------------------------------------------------
PLANT = Interface(("iq_ref", "F_E"), ("x_B", "v_B", "P"), {"x_B": (), "v_B": (), "P": ("iq_ref",)})
LAW = Interface(("x",), ("u",), {"u": ("x",)})
SENSOR = Interface(("x",), ("x_m",), {"x_m": ()})  # a filter: no direct feedthrough
LOAD = Interface(("x",), ("F",), {"F": ("x",)})  # a contact force: direct feedthrough


def test_gauss_seidel_puts_a_feedthrough_component_after_its_sources() -> None:
    interfaces = {"plant": PLANT, "ctrl": LAW, "load": LOAD}
    wires = [
        _c("plant.x_B -> ctrl.x"),
        _c("ctrl.u -> plant.iq_ref"),
        _c("plant.x_B -> load.x"),
        _c("load.F -> plant.F_E"),
    ]
    # the plant's power P depends on iq_ref, but nothing is connected to P: the plant goes first
    assert gauss_seidel_order(["load", "ctrl", "plant"], wires, interfaces) == ("plant", "load", "ctrl")


def test_a_sensor_without_feedthrough_may_go_before_its_source() -> None:
    interfaces = {"plant": PLANT, "sensor": SENSOR, "ctrl": LAW}
    wires = [_c("plant.x_B -> sensor.x"), _c("sensor.x_m -> ctrl.x"), _c("ctrl.u -> plant.iq_ref")]
    # the sensor's output is its state: it is read first, the law then has its input, the plant last
    assert gauss_seidel_order(["sensor", "plant", "ctrl"], wires, interfaces) == ("sensor", "ctrl", "plant")


def test_an_algebraic_loop_is_refused_naming_its_cycle() -> None:
    interfaces = {"a": LOAD, "b": LAW}
    wires = [_c("a.F -> b.x"), _c("b.u -> a.x")]
    assert algebraic_loop(wires, interfaces) == ["a.F", "b.x", "b.u", "a.x", "a.F"]
    with pytest.raises(AlgebraicLoop, match=r"a\.F -> b\.x -> b\.u -> a\.x -> a\.F"):
        gauss_seidel_order(["a", "b"], wires, interfaces)
    # the same ring through a component without direct feedthrough is no loop
    assert (
        algebraic_loop(
            [_c("a.F -> b.x"), _c("b.u -> sensor.x"), _c("sensor.x_m -> a.x")], {**interfaces, "sensor": SENSOR}
        )
        is None
    )


def test_the_plan_sets_inputs_from_later_components_after_every_output() -> None:
    interfaces = {"plant": PLANT, "ctrl": LAW}
    wires = [_c("plant.x_B -> ctrl.x"), _c("ctrl.u -> plant.iq_ref")]
    plan = build_plan(("plant", "ctrl"), interfaces, wires, [Port("plant", "F_E")], None, jacobi=False)
    # buffer: plant x_B v_B P | iq_ref F_E | ctrl u | x
    assert plan.outputs == ((0, 1, 2), (5,)) and plan.inputs == ((3, 4), (6,))
    assert plan.feed_source[3] == 5 and plan.feed_source[4] == SIGNAL and plan.feed_source[6] == 0
    # iq_ref late (its source comes later), F_E late (a signal: sent after the outputs at t_k are
    # read, as the pair sends it); ctrl.x early (the plant is read before it)
    assert plan.early == ((), (0,)) and plan.late[0] == (0, 1)
    # initialisation sets the signal before the first outputs are read
    assert plan.init_early == ((1,), (0,)) and plan.init_late[0] == (0,)
    jacobi = build_plan(("plant", "ctrl"), interfaces, wires, [Port("plant", "F_E")], None, jacobi=True)
    assert jacobi.early == ((), ()) and jacobi.init_early == plan.init_early
    assert plan.names == ("time", "plant.x_B", "plant.v_B", "plant.P", "plant.iq_ref", "plant.F_E", "ctrl.u", "ctrl.x")


def test_a_reference_signal_is_set_with_the_measurements_it_goes_with() -> None:
    """A tracking controller's reference (a signal in `references`) is set early, with what it
    measures, when every input a connection feeds it is early: its outputs at t_k are computed
    from the measurement and the reference at t_k. Read before its source, or under Jacobi, its
    measurement is late, and so is the reference."""
    tracking = Interface(("x", "x_ref"), ("u",))
    interfaces = {"plant": PLANT, "ctrl": tracking}
    wires = [_c("plant.x_B -> ctrl.x"), _c("ctrl.u -> plant.iq_ref")]
    signals, reference = [Port("plant", "F_E"), Port("ctrl", "x_ref")], [Port("ctrl", "x_ref")]
    plan = build_plan(("plant", "ctrl"), interfaces, wires, signals, None, False, reference)
    assert plan.early == ((), (0, 1)) and plan.init_early == ((1,), (0, 1))
    assert build_plan(("plant", "ctrl"), interfaces, wires, signals, None, False).early == ((), (0,))
    assert build_plan(("plant", "ctrl"), interfaces, wires, signals, None, True, reference).early == ((), ())
    assert build_plan(("ctrl", "plant"), interfaces, wires, signals, None, False, reference).early[0] == ()


def test_unit_conversions_come_from_the_units_and_refuse_other_dimensions() -> None:
    wire = _c("a.y -> b.u")
    assert systems.unit_conversion(wire, ("m", None), ("m", None)) is None
    with pytest.raises(systems.SystemError_, match="different dimensions"):
        systems.unit_conversion(wire, ("m", None), ("m/s", None))

    class Base:
        def __init__(self, **kw):
            self.__dict__.update({k: 0 for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")}, factor=1.0, offset=0.0)
            self.__dict__.update(kw)

    class Unit:
        def __init__(self, name, **kw):
            self.name, self.baseUnit = name, Base(**kw)

    class Description:
        unitDefinitions = [Unit("mm", m=1, factor=0.001), Unit("degC", K=1, offset=273.15)]

    factor, offset = systems.unit_conversion(wire, ("m", Description), ("mm", Description))
    assert (factor, offset) == (1000.0, 0.0)
    factor, offset = systems.unit_conversion(wire, ("degC", Description), ("K", Description))
    assert factor == 1.0 and offset == pytest.approx(273.15, abs=1e-12)


# -- the pair as a system -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def plant(plant_fmu: Path):
    return check_plant(plant_fmu)


def _short(run, **changes):
    return dataclasses.replace(run, t_end=0.3, **changes)


@pytest.mark.parametrize("engine", ["compiled", "python"])
@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("law", ["built-in", "fmu"])
def test_the_pair_as_a_system_gives_the_fixed_loops_bits(
    plant, vsc_fmu: Path, coupling: str, law: str, engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The built-in law runs natively in the compiled system loop (its generated C), and as a
    native Python component without it; a controller FMU in either loop."""
    run = _short(load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0], coupling=coupling)
    if law == "fmu":
        run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=vsc_fmu))
    fixed = master.check_and_simulate(run, plant)
    if engine == "python":
        monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    wired = Wiring(connections=systems.pair_connections(Wiring(), ("x_B", "v_B")))
    system = master.check_and_simulate(dataclasses.replace(run, system=wired), plant)
    assert fixed.complete and system.complete, system.reason
    assert system.record["loop"]["kind"] == f"system, {engine}"
    kinds = [component.get("kind", "") for component in system.record["system"]["components"]]
    assert (kinds[1] == "native controller") == (law == "built-in")
    natively = system.record["loop"]["reason"].endswith("(controller natively in C)")
    assert natively == (law == "built-in" and engine == "compiled"), system.record["loop"]
    for name, column in (
        ("x_B", "plant.x_B"),
        ("v_B", "plant.v_B"),
        ("iq_ref", "controller.iq_ref"),
        ("F_E", "plant.F_E"),
    ):
        assert np.array_equal(fixed.trace.column(name), system.trace.column(column)), name
    # the phase switch happened inside the window: the comparison covers both phases
    assert set(np.unique(fixed.trace.column("phase"))) == {0.0, 1.0}


@pytest.mark.parametrize("law", ["built-in", "fmu"])
def test_a_system_at_another_sample_time_gives_the_pairs_bits(plant, vsc_fmu: Path, law: str) -> None:
    """At T_s = 1 ms (the law's FMU has 0.5 ms as its default step, and steps at its parameter
    T_s, which the master sets to the run's): the pair wired as a system, and `record:` alone,
    run the built-in law (natively) or a controller FMU of the built-in law in the compiled
    system loop and give the pair's fixed loop at 1 ms bit for bit."""
    run = _short(load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")[0], T_s=0.001)
    if law == "fmu":
        run = dataclasses.replace(run, controller=dataclasses.replace(run.controller, fmu=vsc_fmu))
    fixed = master.check_and_simulate(run, plant)
    assert fixed.complete, fixed.reason
    wired = Wiring(connections=systems.pair_connections(Wiring(), ("x_B", "v_B")))
    recorded = Wiring(record=(Port("plant", "x_B"), Port("controller", "iq_ref")))
    for wiring in (wired, recorded):
        system = master.check_and_simulate(dataclasses.replace(run, system=wiring), plant)
        assert system.complete, system.reason
        assert system.record["loop"]["kind"] == "system, compiled"
        assert len(system.trace.time) == 301 and system.trace.time[1] == 0.001
        for name in ("x_B", "iq_ref"):
            column = f"{'plant' if name == 'x_B' else 'controller'}.{name}"
            assert np.array_equal(fixed.trace.column(name), system.trace.column(column)), name


def test_a_crossed_wiring_changes_the_trace(plant, vsc_fmu: Path) -> None:
    """x_B and v_B crossed (both in m and m/s: refused), and the command into F_E: runs, but as wired."""
    run = _short(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0])
    crossed = Wiring(
        connections=(
            _c("plant.x_B -> controller.v_B"),
            _c("plant.v_B -> controller.x_B"),
            _c("controller.iq_ref -> plant.iq_ref"),
        )
    )
    with pytest.raises(systems.SystemError_, match="different dimensions"):
        master.check_and_simulate(dataclasses.replace(run, system=crossed), plant)
    # the command wired into the load input (A into N: refused as well)
    into_load = Wiring(
        connections=(
            _c("plant.x_B -> controller.x_B"),
            _c("plant.v_B -> controller.v_B"),
            _c("controller.iq_ref -> plant.F_E"),
        )
    )
    with pytest.raises(systems.SystemError_, match="different dimensions"):
        master.check_and_simulate(dataclasses.replace(run, system=into_load), plant)
    # no command at all: the plant's iq_ref keeps its start value (0 A), the slider never gets there
    open_loop = Wiring(connections=(_c("plant.x_B -> controller.x_B"), _c("plant.v_B -> controller.v_B")))
    outcome = master.check_and_simulate(dataclasses.replace(run, system=open_loop), plant)
    fixed = master.check_and_simulate(run, plant)
    assert outcome.complete
    assert not np.array_equal(outcome.trace.column("plant.x_B"), fixed.trace.column("x_B"))
    assert "plant.iq_ref" not in outcome.trace.names  # an input nothing feeds is not a connector of the run
    assert abs(outcome.trace.column("plant.x_B")[-1] - fixed.trace.column("x_B")[-1]) > 0.01


def test_record_selects_variables_of_any_component(plant) -> None:
    run = _short(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0])
    chosen = (Port("plant", "lambda1"), Port("plant", "x_B"), Port("controller", "S"), Port("plant", "theta1"))
    outcome = master.check_and_simulate(dataclasses.replace(run, system=Wiring(record=chosen)), plant)
    fixed = master.check_and_simulate(run, plant)
    assert outcome.trace.names == ("time", "plant.lambda1", "plant.x_B", "controller.S", "plant.theta1")
    for name in ("lambda1", "x_B", "S", "theta1"):
        assert np.array_equal(
            outcome.trace.column(next(n for n in outcome.trace.names if n.endswith(f".{name}"))),
            fixed.trace.column(name),
        )
    # any variable of an FMU component, not only its connectors: a parameter reads back as set
    chosen = (Port("plant", "x_B"), Port("plant", "m_B"))
    outcome = master.check_and_simulate(dataclasses.replace(run, system=Wiring(record=chosen)), plant)
    assert np.all(outcome.trace.column("plant.m_B") == run.plant.m_B)
    assert outcome.record["units"]["plant.m_B"] == "kg" and outcome.record["units"]["plant.x_B"] == "m"
    with pytest.raises(systems.SystemError_, match="not a variable of the system"):
        master.check_and_simulate(dataclasses.replace(run, system=Wiring(record=(Port("plant", "nope"),))), plant)


# -- the scenario keys --------------------------------------------------------------------------
def _scenario(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "system.yaml"
    path.write_text(
        textwrap.dedent(
            """\
            name: system
            t_end: 0.1
            T_s: 0.0005
            stroke: {x_start: 0.2329, x_target: 0.3199}
            """
        )
        + textwrap.dedent(body)
    )
    return path


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            "connections: [plant.x_B -> sensor.x]\n",
            "key connections[0]: 'plant.x_B -> sensor.x' names the component 'sensor'",
        ),
        ("components: {sensor: {fmu: nothere.fmu}}\n", "key components.sensor.fmu: no such file"),
        ("components: {plant: {fmu: x.fmu}}\n", "key components: 'plant' is taken by the scenario's own plant"),
        ("components: {'1x': {fmu: x.fmu}}\n", "key components: '1x' is not a component name"),
        ("record: [x_B]\n", "key record.0: 'x_B' is not a port (write 'component.variable'"),
        ("connections: ['plant.x_B => c.x']\n", "key connections.0: 'plant.x_B => c.x' is not a connection"),
        ("connections: ['plant.x_B->controller.x_B->plant.iq_ref']\n", "is not one connection"),
        ("record: [ghost.x]\n", "key record[0]: 'ghost.x' names the component 'ghost'"),
        (
            "variants: {v: {components: {extra: {parameters: {a: 1}}}}}\n",
            "key components.extra.fmu (variant v): missing",
        ),
        (
            "plant: {F_E: 10}\nconnections: [plant.x_B -> controller.x_B, plant.x_B -> plant.F_E]\n",
            "key plant.F_E: the connection plant.x_B -> plant.F_E feeds plant.F_E too",
        ),
    ],
)
def test_bad_system_keys_are_one_line_naming_the_key(tmp_path: Path, body: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=re.escape(message)):
        load_scenario(_scenario(tmp_path, body))


def test_the_run_command_refuses_a_bad_connection_before_any_run(plant_fmu: Path, tmp_path: Path) -> None:
    path = _scenario(
        tmp_path,
        f"""\
        fmu: {plant_fmu}
        connections: [plant.x_B -> controller.x_B, plant.v_B -> controller.S, controller.iq_ref -> plant.iq_ref]
        """,
    )
    done = subprocess.run(
        [sys.executable, "-m", "toggle_cosim", "run", str(path), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "controller.S, which is not a Real input of 'controller'" in done.stderr
    assert not (tmp_path / "out").exists()


def test_a_part_that_is_not_an_fmu_or_that_others_may_change_is_refused(
    plant, press_parts: dict[str, Path], tmp_path: Path
) -> None:
    """A part is code the command runs: checked as any FMU (a zip archive with a binary for this
    platform), and refused when another user could change it, each in one line naming the key."""
    import shutil

    run = _short(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0])
    wires = (*systems.pair_connections(Wiring(), ("x_B", "v_B")), _c("plant.x_B -> die.x"))
    fake = tmp_path / "Fake.fmu"
    fake.write_text("not a zip")
    wiring = Wiring(parts=(Part("die", fake),), connections=wires)
    with pytest.raises(systems.SystemError_, match=r"key components\.die\.fmu: .*not an FMU \(not a zip archive\)"):
        systems.system_columns(dataclasses.replace(run, system=wiring), plant)
    shared = tmp_path / "shared"
    shared.mkdir()
    die = shared / "DieLoad.fmu"
    shutil.copy(press_parts["DieLoad"], die)
    die.chmod(0o664)
    wiring = Wiring(parts=(Part("die", die),), connections=wires)
    with pytest.raises(systems.SystemError_, match="key components.die.fmu: .*writable by group or others"):
        systems.system_columns(dataclasses.replace(run, system=wiring), plant)
    die.chmod(0o644)
    assert "die.F" in systems.system_columns(dataclasses.replace(run, system=wiring), plant)


class _PD:
    """A user's controller without `measured`: it reads x_B and v_B from its measurement."""

    diagnostics = ("e",)

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return None

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        from toggle_cosim.control.protocol import ControlStep

        e = 0.3199 - measurement["x_B"]
        return ControlStep(12.0 * e - 2.5 * measurement["v_B"], (e,), state)


def test_a_python_controller_reads_its_connected_inputs_only(plant) -> None:
    """A controller without `measured` may be wired to any plant output of its measurement's
    names: with x_B and v_B connected it gives the pair's Python loop bit for bit; with v_B left
    unconnected its read of v_B fails the run naming the name, never a silent 0."""
    run = _short(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0])
    fixed = master.check_and_simulate(run, plant, controller=_PD())
    wired = Wiring(connections=systems.pair_connections(Wiring(), ("x_B", "v_B")))
    system = master.check_and_simulate(dataclasses.replace(run, system=wired), plant, controller=_PD())
    assert fixed.complete and system.complete, system.reason
    assert np.array_equal(fixed.trace.column("x_B"), system.trace.column("plant.x_B"))
    assert np.array_equal(fixed.trace.column("iq_ref"), system.trace.column("controller.iq_ref"))
    half = Wiring(connections=(_c("plant.x_B -> controller.x_B"), _c("controller.iq_ref -> plant.iq_ref")))
    failed = master.check_and_simulate(dataclasses.replace(run, system=half), plant, controller=_PD())
    assert not failed.complete and "KeyError" in failed.reason and "'v_B'" in failed.reason


FAULTY_PART = '''
import ctypes
import time
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class FaultyPart(Fmi2Slave):
    """y = x; its doStep from t = 0.005 s dereferences a null pointer (mode 0) or never returns (mode 1)."""

    author = "toggle-cosim tests"
    description = "a part that crashes or hangs"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.x, self.mode = 0.0, 0.0
        self.register_variable(Real("x", causality=Fmi2Causality.input))
        self.register_variable(Real("mode", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("y", causality=Fmi2Causality.output, getter=lambda: self.x))

    def do_step(self, current_time: float, step_size: float) -> bool:
        if current_time >= 0.005:
            if self.mode == 0.0:
                ctypes.string_at(0)
            time.sleep(600)
        return True
'''


@pytest.mark.slow
@pytest.mark.parametrize(
    ("mode", "kernel", "said"),
    [
        (0, "1", "ended the run's process: it was killed by SIGSEGV while the master called it"),
        (0, "0", "ended the run's process: it was killed by SIGSEGV while the master called it"),
        (1, "1", "did not return: time limit 2 s exceeded while the master called it"),
    ],
)
def test_a_part_that_crashes_or_hangs_is_named_in_the_reason(
    plant_fmu: Path, tmp_path: Path, mode: int, kernel: str, said: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A part's doStep from t = 0.005 s segfaults (in the compiled system loop and in the Python
    one) or hangs: the run fails with a reason that names the component and its FMU, not the
    plant; the trace holds the samples before it."""
    from python_fmus import build_python_fmu

    build_python_fmu(FAULTY_PART, tmp_path, "FaultyPart")
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", kernel)
    path = _scenario(
        tmp_path,
        f"""\
        fmu: {plant_fmu}
        components: {{faulty: {{fmu: FaultyPart.fmu, parameters: {{mode: {mode}}}}}}}
        connections:
          - plant.x_B -> controller.x_B
          - plant.v_B -> controller.v_B
          - controller.iq_ref -> plant.iq_ref
          - plant.x_B -> faulty.x
        """,
    )
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-m", "toggle_cosim", "run", str(path), "--out", str(out), "-q", "--time-limit", "2"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1, done.stderr
    record = json.loads((out / "system" / "run" / "run.json").read_text(encoding="utf-8"))
    assert record["status"] == "failed"
    assert record["reason"] == f"component 'faulty' (FaultyPart.fmu) {said} at t = 0.005 s", record["reason"]
    assert record["samples"] == 11  # t = 0 .. 0.005 s recorded, the step from 0.005 s not done


# -- recording variables of other types ---------------------------------------------------------
def _typed_part(folder: Path, *defines: str) -> Path:
    """tests/models/typed_part built into `folder`: an FMI 2.0 part in C whose Integer `count`
    (the doSteps taken) and Boolean `flag` (count is odd) share value references 1 and 2 with the
    Reals y = x + 1000 and z = -7, as FMI 2.0 allows; a String local `label` too. `defines`: -D
    options for the C compiler."""
    import shutil
    import zipfile

    source = ROOT / "tests" / "models" / "typed_part"
    library = folder / "SharedRefs.so"
    compiler = shutil.which("cc") or shutil.which("gcc")
    command = [compiler, "-shared", "-fPIC", "-O1", *defines, "-o", str(library), str(source / "SharedRefs.c")]
    subprocess.run(command, check=True)
    fmu = folder / "SharedRefs.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.write(source / "modelDescription.xml", "modelDescription.xml")
        archive.write(library, "binaries/linux64/SharedRefs.so")
    fmu.chmod(0o644)
    return fmu


@pytest.fixture(scope="module")
def typed_part(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _typed_part(tmp_path_factory.mktemp("typed-part"))


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_integer_and_boolean_variables_are_recorded_with_their_type(
    plant, typed_part: Path, engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`record:` of a part's Integer and Boolean outputs (sharing value references with Reals) and
    of the plant's Integer solver.steps reads each with its own getter: count is the sample k,
    flag k mod 2, y = x_B + 1000 (not the Real of count's reference), solver.steps the plant's
    integrator steps (0 at t = 0, growing); the same values in both loops."""
    if engine == "python":
        monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.01)
    wires = (*systems.pair_connections(Wiring(), ("x_B", "v_B")), _c("plant.x_B -> shared.x"))
    chosen = tuple(
        Port.parse(p) for p in ("shared.count", "shared.flag", "shared.y", "plant.x_B", "plant.solver.steps")
    )
    wiring = Wiring(parts=(Part("shared", typed_part),), connections=wires, record=chosen)
    outcome = master.check_and_simulate(dataclasses.replace(run, system=wiring), plant)
    assert outcome.complete, outcome.reason
    assert outcome.record["loop"]["kind"] == f"system, {engine}"
    k = np.arange(21)
    assert np.array_equal(outcome.trace.column("shared.count"), k)
    assert np.array_equal(outcome.trace.column("shared.flag"), k % 2)
    assert np.array_equal(outcome.trace.column("shared.y"), outcome.trace.column("plant.x_B") + 1000.0)
    steps = outcome.trace.column("plant.solver.steps")
    assert steps[0] == 0 and np.all(np.diff(steps) > 0) and np.all(steps == np.round(steps))


def test_a_string_is_not_recorded_and_an_integer_is_not_connected(plant, typed_part: Path) -> None:
    """A String variable in `record:`, and a connection from an Integer output: each refused in one
    line before anything is loaded."""
    run = _short(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0])
    wires = (*systems.pair_connections(Wiring(), ("x_B", "v_B")), _c("plant.x_B -> shared.x"))
    label = Wiring(parts=(Part("shared", typed_part),), connections=wires, record=(Port("shared", "label"),))
    with pytest.raises(systems.SystemError_, match=r"key record: shared\.label is a String variable; the trace holds"):
        systems.system_columns(dataclasses.replace(run, system=label), plant)
    counted = Wiring(
        parts=(Part("shared", typed_part),),
        connections=(*wires, _c("shared.count -> plant.F_E")),
        record=(Port("shared", "count"),),
    )
    with pytest.raises(systems.SystemError_, match=r"starts at shared\.count, which is not a Real output of 'shared'"):
        systems.system_columns(dataclasses.replace(run, system=counted), plant)


def test_a_part_whose_binary_lacks_a_function_fails_naming_it(plant, tmp_path: Path) -> None:
    """The part's library does not export fmi2CancelStep, which fmpy binds when it loads it: the
    run fails with a reason naming the component, its FMU and the missing function (not a Python
    error said of the plant)."""
    part = _typed_part(tmp_path, "-Dfmi2CancelStep=notExported")
    run = _short(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0])
    wires = (*systems.pair_connections(Wiring(), ("x_B", "v_B")), _c("plant.x_B -> shared.x"))
    wiring = Wiring(parts=(Part("shared", part),), connections=wires)
    outcome = master.check_and_simulate(dataclasses.replace(run, system=wiring), plant)
    assert not outcome.complete
    assert outcome.reason.startswith("component 'shared' (SharedRefs.fmu): its binary could not be loaded (")
    assert "fmi2CancelStep" in outcome.reason


def test_a_sweep_case_whose_part_crashes_names_the_part(plant_fmu: Path, tmp_path: Path) -> None:
    """In a sweep, a case whose part segfaults in its doStep (its plant host dies) fails with the
    reason naming the component and its FMU; the sweep goes on to the next case."""
    from python_fmus import build_python_fmu

    from toggle_cosim.experiments.sweep import read_results, run_sweep

    build_python_fmu(FAULTY_PART, tmp_path, "FaultyPart")
    _scenario(
        tmp_path,
        f"""\
        fmu: {plant_fmu}
        components: {{faulty: {{fmu: FaultyPart.fmu, parameters: {{mode: 0}}}}}}
        connections:
          - plant.x_B -> controller.x_B
          - plant.v_B -> controller.v_B
          - controller.iq_ref -> plant.iq_ref
          - plant.x_B -> faulty.x
        """,
    )
    sweep = {"base": "system.yaml", "axes": {"plant.F_E": {"values": [0.0, 10.0]}}, "output": "swept"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, plant_fmu, progress=False, keep_traces=False) == 1
    table = read_results(tmp_path / "swept")
    assert list(table["status"]) == ["failed", "failed"]
    for reason in table["reason"]:
        assert reason == (
            "component 'faulty' (FaultyPart.fmu) ended the run's process: it was killed by SIGSEGV while the master"
            " called it at t = 0.005 s"
        ), reason


def test_a_sweep_over_the_sample_time_runs_a_system_at_each(plant_fmu: Path, tmp_path: Path) -> None:
    """`record:` makes the pair a system, whose built-in law runs as its FMU: a sweep over T_s
    (0.5 ms, the FMU's default step, and 1 ms) completes every case."""
    from toggle_cosim.experiments.sweep import read_results, run_sweep

    _scenario(tmp_path, f"fmu: {plant_fmu}\nrecord: [plant.x_B, controller.iq_ref]\n")
    sweep = {"base": "system.yaml", "axes": {"T_s": {"values": [0.0005, 0.001]}}, "output": "swept"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, plant_fmu, progress=False, keep_traces=False) == 0
    table = read_results(tmp_path / "swept")
    assert list(table["status"]) == ["ok", "ok"], list(table["reason"])
    assert list(table["samples"]) == [201, 101]


def test_a_sample_time_of_its_own_for_the_law_fmu_is_refused_in_one_line(
    plant_fmu: Path, vsc_fmu: Path, tmp_path: Path
) -> None:
    """A controller FMU of the built-in law steps at its parameter T_s, which the master sets to the
    run's: controller.parameters.T_s other than the run's is refused before any run, exit 2, one
    line naming the key (the FMU would refuse every step); the run's own value is accepted."""
    out = tmp_path / "out"
    for given, code in ((0.0005, 2), (0.001, 0)):
        path = _scenario(
            tmp_path,
            f"fmu: {plant_fmu}\ncontroller: {{fmu: {vsc_fmu}, parameters: {{T_s: {given}}}}}\n",
        )
        text = path.read_text(encoding="utf-8").replace("T_s: 0.0005\n", "T_s: 0.001\n", 1)
        path.write_text(text.replace("t_end: 0.1", "t_end: 0.01"), encoding="utf-8")
        done = subprocess.run(
            [sys.executable, "-m", "toggle_cosim", "run", str(path), "--out", str(out), "-q"],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == code, done.stderr
        if code == 2:
            assert done.stderr.count("\n") == 1, done.stderr
            assert "key controller.parameters.T_s: the controller FMU ToggleVSC.fmu steps at its parameter T_s" in (
                done.stderr
            )
            assert not out.exists()


@pytest.fixture(scope="module")
def nan_part(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A part whose output y turns NaN at t = 0.01 s (`nan_values.PART`, a Python FMU)."""
    from nan_values import PART
    from python_fmus import build_python_fmu

    return build_python_fmu(PART, tmp_path_factory.mktemp("nan-part"), "NanAfter")


@pytest.mark.parametrize("engine", ["compiled", "python"])
@pytest.mark.parametrize(
    "record", [["plant.x_B", "probe.y"], ["probe.y", "plant.x_B"]], ids=["recorded-last", "recorded-first"]
)
def test_a_part_output_that_turns_nan_is_written_in_every_row_of_the_trace(
    plant_fmu: Path, nan_part: Path, tmp_path: Path, record: list[str], engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 37, item 1: a part's output NaN from t = 0.01 s, recorded in the trace's last column
    or not, by the compiled system loop or the Python execution. The run is complete (the part's
    output is recorded, not measured by the controller), trace.csv has every sample, run.json
    counts them, and the NaN read back."""
    from nan_values import FINITE, SAMPLES, nan_part_scenario, run_scenario

    if engine == "python":
        monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    run_record, trace = run_scenario(nan_part_scenario(tmp_path, nan_part, record), plant_fmu, tmp_path / "out")
    assert run_record["status"] == "complete" and run_record["samples"] == trace.data.shape[0] == SAMPLES
    assert run_record["loop"]["kind"] == f"system, {engine}"
    assert trace.names == ("time", *record)
    y = trace.column("probe.y")
    assert np.all(np.isfinite(y[:FINITE])) and np.all(np.isnan(y[FINITE:]))
    assert np.array_equal(y[:FINITE], trace.column("plant.x_B")[:FINITE])
    assert np.all(np.isfinite(trace.column("plant.x_B")))


def _folder_bytes(folder: Path) -> int:
    return sum(path.stat().st_size for path in folder.rglob("*") if path.is_file() and not path.is_symlink())


def test_one_fmu_used_by_many_components_is_unzipped_once(
    plant, press_parts: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """20 sensors of one FMU padded with a 5 MiB member: the temporary disk the run uses once
    every component is instantiated is under two unzipped copies (one shared by the 20, the
    plant's own), and nothing is left behind after the run."""
    import os
    import shutil
    import tempfile
    import zipfile

    from toggle_cosim.cosim.execution.slaves import FmuSlave

    parts = tmp_path / "parts"
    parts.mkdir(mode=0o755)
    padded = parts / "Sensor.fmu"
    shutil.copy(press_parts["PositionSensor"], padded)
    with zipfile.ZipFile(padded, "a") as archive:
        archive.writestr("resources/padding.bin", os.urandom(5 << 20), compress_type=zipfile.ZIP_STORED)
    padded.chmod(0o644)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    used: list[int] = []
    enter = FmuSlave.enter_initialization

    def measured(self: FmuSlave) -> None:  # every component is unzipped by now (Execution.initialize)
        used.append(_folder_bytes(scratch))
        enter(self)

    monkeypatch.setattr(FmuSlave, "enter_initialization", measured)
    n = 20
    sensors = tuple(Part(f"s{i}", padded) for i in range(n))
    wires = (*systems.pair_connections(Wiring(), ("x_B", "v_B")), *(_c(f"plant.x_B -> s{i}.x") for i in range(n)))
    run = dataclasses.replace(
        load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0],
        t_end=0.01,
        system=Wiring(parts=sensors, connections=wires, record=(Port("plant", "x_B"), Port(f"s{n - 1}", "x_m"))),
    )
    outcome = master.check_and_simulate(run, plant)
    assert outcome.complete, outcome.reason
    assert outcome.trace.column(f"s{n - 1}.x_m")[-1] > 0.2  # the last sensor ran, reading x_B
    assert used and 5 << 20 < max(used) < 2 * (5 << 20)
    assert list(scratch.iterdir()) == []


@pytest.mark.parametrize("factor", [0.0, float("nan"), float("inf")])
def test_a_unit_defined_with_factor_zero_or_not_finite_is_refused_naming_it(factor: float) -> None:
    """An FMU's UnitDefinitions read for a connection: a factor of 0 (every value 0, a conversion
    into it a division by 0) or a number that is not finite is refused as the connection's error."""
    from types import SimpleNamespace

    base = SimpleNamespace(kg=0, m=1, s=0, A=0, K=0, mol=0, cd=0, rad=0, factor=factor, offset=0.0)
    description = SimpleNamespace(unitDefinitions=[SimpleNamespace(name="mm", baseUnit=base)])
    with pytest.raises(systems.SystemError_, match=r"plant\.x_B -> s\.x: the unit 'mm' is defined with factor"):
        systems.unit_conversion(_c("plant.x_B -> s.x"), ("m", None), ("mm", description))


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        ("{nope: 1}", "the FMU has no variable 'nope'"),
        ("{x_m: 1}", "'x_m' is an output of the FMU, not a parameter or input"),
        ("{x_f: 0.3}", "'x_f' is a local variable (a state or an internal one) of the FMU, not a parameter or input"),
        ("{T_f: true}", "variable 'T_f' is a Real, but its value is True (give a finite number)"),
    ],
)
def test_a_parts_value_it_cannot_take_is_one_refusal_before_any_run(
    plant_fmu: Path, press_parts: dict[str, Path], tmp_path: Path, parameters: str, message: str
) -> None:
    """A part's parameters are checked as an SSP's bindings are (`system.interfaces.check_settable`):
    an unknown name, an output or a state, a Real given a Boolean (YAML's `true` would have been
    set as 1.0) is one line, exit 2, before any run, nothing written."""
    from click.testing import CliRunner

    from toggle_cosim.cli import main

    path = _scenario(
        tmp_path,
        f"""\
        fmu: {plant_fmu}
        components: {{s: {{fmu: {press_parts["PositionSensor"]}, parameters: {parameters}}}}}
        connections: [plant.x_B -> controller.x_B, plant.v_B -> controller.v_B, controller.iq_ref -> plant.iq_ref,
                      plant.x_B -> s.x]
        """,
    )
    result = CliRunner().invoke(main, ["run", str(path), "--out", str(tmp_path / "out"), "-q"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output
    assert lines[0].startswith(f"error: {path}: key components.s.parameters: {message}"), lines[0]
    assert "Traceback" not in result.output and not (tmp_path / "out").exists()
