"""Checkpoint retries of a system's run (`cosim.execution.system_retry`), the pair's for every component:
a part FMU that refuses a few steps (fmi2Discard) is retried from a checkpoint and its run
completes; one that refuses every step ends the run with its retry listed; one that cannot save
its state is not retried, and run.json says so; the compiled system loop and the Python
execution give the same retries and trace. And the guard on what a native controller measures:
a value that is not finite ends the run naming the output it came from and the time.

The part (tests/models/refusing_part, C) integrates its input, y += x h, and refuses the steps
from t in [refuse_from, refuse_until) unless they are shorter than pass_below; it records the
last doStep's noSetFMUStatePriorToCurrentPoint in its output no_prior.
"""

from __future__ import annotations

import dataclasses
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from system_runs import simulate_system

from toggle_cosim.cosim import systems
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.system.model import Connection, Part, Port, Wiring

ROOT = Path(__file__).resolve().parent.parent
T_S = 0.0005  # fig4_nominal's sample time
START = 0.03  # the first refused step's start: sample 60
SAMPLES = 101  # t_end 0.05 s


def _c(text: str) -> Connection:
    start, end = (Port.parse(side.strip()) for side in text.split("->"))
    return Connection(start, end)


def _refusing_part(folder: Path, saves: bool = True, *defines: str) -> Path:
    """tests/models/refusing_part built into folder/Refusing.fmu; `saves` False: its description
    does not declare canGetAndSetFMUstate; `defines`: -D options for the C compiler."""
    source = ROOT / "tests" / "models" / "refusing_part"
    library = folder / "Refusing.so"
    compiler = shutil.which("cc") or shutil.which("gcc")
    command = [compiler, "-shared", "-fPIC", "-O1", *defines, "-o", str(library), str(source / "Refusing.c")]
    subprocess.run(command, check=True)
    description = (source / "modelDescription.xml").read_text(encoding="utf-8")
    if not saves:
        description = description.replace(' canGetAndSetFMUstate="true"', "")
    fmu = folder / "Refusing.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr("modelDescription.xml", description)
        archive.write(library, "binaries/linux64/Refusing.so")
    fmu.chmod(0o644)
    return fmu


@pytest.fixture(scope="module")
def refusing(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _refusing_part(tmp_path_factory.mktemp("refusing"))


@pytest.fixture(scope="module")
def plant(plant_fmu: Path):
    return check_plant(plant_fmu)


def _run(part: Path, **values: float):
    """fig4_nominal for 0.05 s with the part `refuser` integrating x_B (its output feeds nothing,
    so the plant and the controller never see a retry's rounding), with its `values`."""
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.05)
    wires = (*systems.pair_connections(Wiring(), ("x_B", "v_B")), _c("plant.x_B -> refuser.x"))
    chosen = tuple(
        Port.parse(p) for p in ("plant.x_B", "plant.v_B", "controller.iq_ref", "refuser.y", "refuser.no_prior")
    )
    wiring = Wiring(parts=(Part("refuser", part, tuple(values.items())),), connections=wires, record=chosen)
    return dataclasses.replace(run, system=wiring)


def _simulate(
    run, plant, engine: str, monkeypatch: pytest.MonkeyPatch, coupling: str | None = None, controller=None, **options
):
    """The run by the compiled system loop or the Python execution, with its checkpoint options
    (and a controller of the protocol in place of the scenario's)."""
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "1" if engine == "compiled" else "0")
    if options:
        from toggle_cosim.cosim.execution.system_retry import CheckpointOptions

        outcome = simulate_system(
            run, plant, coupling=coupling, checkpoints=CheckpointOptions(**options), controller=controller
        )
    else:
        outcome = simulate_system(run, plant, coupling=coupling, controller=controller)
    assert outcome.record["loop"]["kind"] == f"system, {engine}"
    return outcome


@pytest.mark.parametrize(
    ("interval", "coupling"),
    [(200, "gauss-seidel"), (25, "gauss-seidel"), (25, "jacobi")],
    ids=["every-200", "every-25", "every-25-jacobi"],
)
def test_a_part_that_refuses_three_steps_is_retried_and_its_run_completes(
    plant, refusing: Path, interval: int, coupling: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The part discards its steps from t = 0.03, 0.0305 and 0.031 s (samples 60 .. 62) unless
    shorter than T_s / 2: each is retried from the checkpoint (sample 0, or 50 with a checkpoint
    every 25 samples) in 10 substeps, which pass, and the run completes, with the three retries
    in run.json, in the compiled loop and in the Python execution alike (the same retries, the
    same trace bit for bit), under either coupling. Against the undisturbed run, every column the retries do not touch
    is equal bit for bit (the part's output feeds nothing), and the part's integral y within
    1e-15 relative: a retried step adds x T_s as ten additions of x T_s / 10, which round
    differently in the last bits (a few ulps of y ~ 0.01, three times)."""
    clean = _simulate(_run(refusing), plant, "compiled", monkeypatch, coupling)
    assert clean.complete and clean.record["retries"] == []
    refused = _run(refusing, refuse_from=START, refuse_until=START + 2.5 * T_S, pass_below=T_S / 2)
    outcomes = {
        engine: _simulate(refused, plant, engine, monkeypatch, coupling, interval=interval)
        for engine in ("compiled", "python")
    }
    native = outcomes["compiled"].record["loop"]["reason"]
    assert "(controller natively in C)" in native, native  # its state is checkpointed too
    for outcome in outcomes.values():
        assert outcome.complete, outcome.reason
        assert outcome.record["samples"] == SAMPLES
        retries = outcome.record["retries"]
        assert [(r["component"], r["outcome"]) for r in retries] == [("refuser", "passed")] * 3
        assert [r["t"] for r in retries] == pytest.approx([START, START + T_S, START + 2 * T_S], abs=1e-12)
        assert (
            "fmi2DoStep at t = 0.03 s returned status 2; it logged [DISCARD] refused the step of 0.0005 s"
            in (retries[0]["error"])
        )
        assert outcome.record["system"]["checkpoints"] == {"interval": interval, "substeps": 10, "retries": "on"}
        assert outcome.record["warnings"] == [
            "3 steps of component 'refuser' from t = 0.03 s to 0.031 s failed and passed when retried from a "
            f"checkpoint: {retries[0]['error']}"
        ]
        for name in ("plant.x_B", "plant.v_B", "controller.iq_ref"):
            assert np.array_equal(outcome.trace.column(name), clean.trace.column(name)), name
        np.testing.assert_allclose(outcome.trace.column("refuser.y"), clean.trace.column("refuser.y"), rtol=1e-15)
        assert np.all(outcome.trace.column("refuser.no_prior")[1:] == 0.0)  # checkpoints may be restored
    compiled, python = outcomes["compiled"], outcomes["python"]
    assert compiled.record["retries"] == python.record["retries"]
    assert np.array_equal(compiled.trace.data, python.trace.data)


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_a_part_that_always_refuses_ends_the_run_failed_with_its_retry_listed(
    plant, refusing: Path, engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The part discards every step from t = 0.03 s, substeps too: the retry from the checkpoint
    fails as well, the run fails with a reason that tells both failures with what the part
    logged, its retry is listed as failed, and the trace holds the samples up to t = 0.03 s."""
    outcome = _simulate(_run(refusing, refuse_from=START, refuse_until=1.0), plant, engine, monkeypatch)
    assert not outcome.complete and outcome.record["status"] == "failed"
    assert outcome.record["retries"] == [
        {
            "component": "refuser",
            "t": pytest.approx(START, abs=1e-12),
            "error": "component 'refuser' (Refusing.fmu): fmi2DoStep at t = 0.03 s returned status 2; it logged "
            "[DISCARD] refused the step of 0.0005 s at t = 0.03 s",
            "outcome": "failed",
        }
    ]
    assert outcome.reason == (
        "component 'refuser' (Refusing.fmu): fmi2DoStep at t = 0.03 s returned status 2; it logged [DISCARD] refused the step "
        "of 0.0005 s at t = 0.03 s. Retried from the checkpoint at t = 0 s in 10 substeps: fmi2DoStep at t = 0.03 s "
        "returned status 2; it logged [DISCARD] refused the step of 5e-05 s at t = 0.03 s"
    )
    assert outcome.record["samples"] == 61  # t = 0 .. 0.03 s recorded, its step not done
    assert outcome.trace.time[-1] == pytest.approx(START, abs=1e-12)


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_a_part_that_cannot_save_its_state_is_not_retried(
    plant, tmp_path: Path, engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The part does not declare canGetAndSetFMUstate: no checkpoint is kept (run.json says why,
    naming it), every doStep is told so (noSetFMUStatePriorToCurrentPoint true, as the pair does
    for a plant that cannot save its state), and its first refused step ends the run, unretried."""
    part = _refusing_part(tmp_path, saves=False)
    outcome = _simulate(
        _run(part, refuse_from=START, refuse_until=START + 2.5 * T_S, pass_below=T_S / 2), plant, engine, monkeypatch
    )
    assert not outcome.complete and outcome.record["retries"] == []
    assert outcome.reason.startswith("component 'refuser' (Refusing.fmu): fmi2DoStep at t = 0.03 s returned status 2")
    assert "Retried" not in outcome.reason
    assert outcome.record["system"]["checkpoints"] == {
        "interval": 200,
        "substeps": 10,
        "retries": "off",
        "reason": "component 'refuser' (Refusing.fmu) cannot save its state (its FMU does not declare "
        "canGetAndSetFMUstate)",
    }
    assert np.all(outcome.trace.column("refuser.no_prior")[1:] == 1.0)


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_a_part_that_declares_it_can_save_its_state_but_refuses_leaves_the_run_without_checkpoints(
    plant, tmp_path: Path, engine: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The part declares canGetAndSetFMUstate, yet its fmi2GetFMUstate returns fmi2Error: the
    first checkpoint (t = 0) fails, the run goes on without any (run.json says why, naming the
    part and the call) and, nothing refused, completes with the undisturbed values."""
    part = _refusing_part(tmp_path, True, "-DREFUSE_STATE")
    outcome = _simulate(_run(part), plant, engine, monkeypatch)
    assert outcome.complete, outcome.reason
    assert outcome.record["samples"] == SAMPLES and outcome.record["retries"] == []
    checkpoints = outcome.record["system"]["checkpoints"]
    assert checkpoints["retries"] == "off"
    assert checkpoints["reason"] == (
        "component 'refuser' (Refusing.fmu): fmi2GetFMUstate returned status 3 at t = 0 s; no checkpoint is kept "
        "from then on"
    )


class _Measures:
    """A PD law that measures x_B and v_B (`measured`)."""

    diagnostics = ("e",)
    measured = ("x_B", "v_B")

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return None

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        from toggle_cosim.control.protocol import ControlStep

        e = 0.3199 - measurement["x_B"]
        return ControlStep(12.0 * e - 2.5 * measurement["v_B"], (e,), state)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_a_value_a_native_controller_measures_that_is_not_finite_ends_the_run_naming_its_source(
    plant, tmp_path: Path, coupling: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A part's output y, NaN from t = 0.01 s, is what the Python controller measures as x_B:
    the run fails at that sample with one line naming the part, its output and the time (the
    controller is never given the NaN), its trace up to the sample before (under Jacobi the
    controller's inputs are set after the sample's row: one row more), in the compiled loop (the
    controller called back into Python) as in the Python execution."""
    from nan_values import PART
    from python_fmus import build_python_fmu

    probe = build_python_fmu(PART, tmp_path, "NanAfter")
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.02)
    wires = tuple(
        _c(text)
        for text in (
            "plant.x_B -> probe.x",
            "probe.y -> controller.x_B",
            "plant.v_B -> controller.v_B",
            "controller.iq_ref -> plant.iq_ref",
        )
    )
    wiring = Wiring(parts=(Part("probe", probe),), connections=wires)
    run = dataclasses.replace(run, system=wiring)
    outcomes = [_simulate(run, plant, engine, monkeypatch, coupling, _Measures()) for engine in ("compiled", "python")]
    for outcome in outcomes:
        assert not outcome.complete
        assert outcome.reason == (
            "component 'probe': its output y is nan at t = 0.01 s, measured by the native controller 'controller', "
            "which takes finite values only"
        )
        assert outcome.record["samples"] == (21 if coupling == "jacobi" else 20)  # t = 0 .. 0.0095 (0.01) s
    assert np.array_equal(outcomes[0].trace.data, outcomes[1].trace.data, equal_nan=True)


class _Integrating:
    """A PI law on x_B with damping on v_B; its state is the integral of the error."""

    diagnostics = ("integral",)
    measured = ("x_B", "v_B")

    def start(self, t0, measurement):  # noqa: ANN001, ANN201
        return 0.0

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        from toggle_cosim.control.protocol import ControlStep

        e = 0.3199 - measurement["x_B"]
        return ControlStep(12.0 * e + 40.0 * state - 2.5 * measurement["v_B"], (state,), state + e * T_S)


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_a_python_controllers_state_is_put_back_with_the_parts(
    plant, refusing: Path, coupling: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With a Python controller whose state is an integral (a component the compiled system loop
    calls back into Python), a refused step is retried with every component put back to the
    checkpoint, the controller's state too: the plant's and the controller's columns equal the
    undisturbed run's bit for bit (an integral counted twice over the replayed samples would not),
    and the compiled loop and the Python execution give the same retries and the same trace."""
    refused = _run(refusing, refuse_from=START, refuse_until=START + 2.5 * T_S, pass_below=T_S / 2)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "1")
    clean = simulate_system(_run(refusing), plant, controller=_Integrating(), coupling=coupling)
    outcomes = {
        engine: _simulate(refused, plant, engine, monkeypatch, coupling, interval=25, controller=_Integrating())
        for engine in ("compiled", "python")
    }
    assert "controller in Python, called back from C" in outcomes["compiled"].record["loop"]["reason"]
    for outcome in outcomes.values():
        assert outcome.complete, outcome.reason
        assert [r["outcome"] for r in outcome.record["retries"]] == ["passed"] * 3
        for name in ("plant.x_B", "plant.v_B", "controller.iq_ref"):
            assert np.array_equal(outcome.trace.column(name), clean.trace.column(name)), name
    compiled, python = outcomes["compiled"], outcomes["python"]
    assert compiled.record["retries"] == python.record["retries"]
    assert np.array_equal(compiled.trace.data, python.trace.data)


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_an_fmu_component_is_put_back_to_its_checkpoint(
    press_parts: dict[str, Path], tmp_path: Path, version: str
) -> None:
    """The press example's sensor (a first-order lag, so its outputs follow its history) as an
    FMI 2.0 and an FMI 3.0 component: saved after 5 steps, stepped 5 more, put back and stepped the
    same 5 again, it gives the same outputs bit for bit; the saved state is freed with it."""
    import ctypes

    from toggle_cosim.cosim.execution.slaves import FmuSlave
    from toggle_cosim.fmu_export import build_fmu
    from toggle_cosim.plant.contract import read_fmu

    if version == "2.0":
        path = press_parts["PositionSensor"]
    else:
        source = ROOT / "examples" / "press_system" / "PositionSensor.mo"
        path = build_fmu(source, "PositionSensor", tmp_path / "PositionSensor3.fmu", "3.0", "cs").fmu.path
    slave = FmuSlave("sensor", read_fmu(path))
    assert slave.cannot_save_state is None
    inputs = range(len(slave.interface.inputs))
    out = (ctypes.c_double * len(slave.interface.outputs))()
    slave.instantiate(1.0)
    try:
        slave.enter_initialization()
        slave.exit_initialization()

        def steps(k0: int, k1: int) -> list[float]:
            for k in range(k0, k1):
                slave.set(inputs, [0.01 * (k + 1)] * len(inputs), k * T_S)
                slave.do_step(k * T_S, T_S)
            slave.get(out, k1 * T_S)
            return list(out)

        steps(0, 5)
        slave.save_state()
        first = steps(5, 10)
        slave.restore_state()
        assert steps(5, 10) == first
        assert first != steps(10, 11)  # the outputs move: the equality above is not of constants
    finally:
        slave.close()
