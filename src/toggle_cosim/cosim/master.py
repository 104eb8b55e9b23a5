"""The co-simulation master: a plant FMU and the discrete VSC, stepped every T_s.

    instantiate -> set parameters -> initialise -> every T_s: read outputs, control,
    set inputs, doStep -> terminate, free

`simulate` assembles the parts (after FMPy's simulateCS, with its Recorder and step hook):
a `PlantSession` (session.py), a `Recorder` and step hooks (recorder.py), the steppers
(stepper.py: the first sample in Python, which starts the controller; the rest in the
compiled loop generated from `control.laws`, handed over to Python at a sample the C hands
back, or all in Python without a C compiler) and the `CheckpointPolicy` (retry.py). The
loop allocates nothing per step. run.json says which loop ran and why. The FMU is freed on
every exit path. A plant fault (an error status, non-finite outputs) ends the run early:
the trace up to the fault is kept and the run is marked failed with the reason.
"""

from __future__ import annotations

import time as clock
from collections.abc import Callable

import numpy as np

from toggle_cosim.control.controller import VSCController
from toggle_cosim.cosim.outcome import RunOutcome, run_record
from toggle_cosim.cosim.recorder import CONTROL_COLUMNS, ProgressHook, Recorder
from toggle_cosim.cosim.retry import CheckpointPolicy
from toggle_cosim.cosim.session import PlantSession
from toggle_cosim.cosim.stepper import CompiledStepper, HandOver, LoopState, PythonStepper, Timing
from toggle_cosim.cosim.summary import summarize
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import MechanismParameters, MotorParameters
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.plant.friction import friction_settings
from toggle_cosim.runs.definition import Run

__all__ = ["RunOutcome", "make_controller", "open_session", "plant_settings", "simulate", "trace_names"]
INPUTS = ("iq_ref", "F_E")


def make_controller(run: Run) -> VSCController:
    """The controller of a run, with its own nominal model (never the plant's parameters)."""
    nominal = MechanismParameters(mB=run.controller.nominal_m_B, mu=0.0)
    return VSCController(
        gains=run.controller.gains,
        nominal=nominal,
        K_f=thrust_constant(MotorParameters()),
        target=run.x_target,
        objective=run.controller.objective,
        law=run.controller.law,
        C_I=run.controller.C_I,
        K_I=run.controller.K_I,
        i_max=run.controller.i_max,
        T_s=run.T_s,
    )


def plant_settings(run: Run, plant: PlantInterface) -> list[tuple[str, float | bool]]:
    """The plant parameters a run sets before initialisation, in order."""
    settings: list[tuple[str, float | bool]] = [("m_B", run.plant.m_B), ("mu", run.plant.mu)]
    available = plant.references
    if "x_B0" in available:
        settings.append(("x_B0", run.x_start))
    if "idealCurrentLoop" in available:
        settings.append(("idealCurrentLoop", run.plant.current_loop == "ideal"))
    elif run.plant.current_loop == "ideal":
        raise ValueError(
            f"{plant.path}: the plant has no parameter idealCurrentLoop, so plant.current_loop: ideal cannot be set"
        )
    if run.plant.K is not None:
        settings.append(("K", run.plant.K))
    settings += friction_settings(run.plant.friction_model, run.plant.mu, run.plant.mu_s, available, plant.path)
    for name, value in run.plant.parameters.items():
        if name not in available:
            raise ValueError(f"key plant.parameters.{name}: the plant FMU has no variable {name!r}")
        settings.append((name, value))
    return settings


def trace_names(plant: PlantInterface) -> tuple[str, ...]:
    """The columns of a run's trace: time, the plant's recorded outputs, the controller's columns."""
    return ("time", *plant.recorded_outputs, *CONTROL_COLUMNS)


def open_session(plant: PlantInterface, instance_name: str) -> PlantSession:
    """A session of `plant` with the master's outputs and inputs: the FMU unzipped and its binary
    loaded, no instance yet. `simulate(..., session=)` runs on it, run after run."""
    return PlantSession(plant, instance_name, list(plant.recorded_outputs), list(INPUTS))


def _initialise(session: PlantSession, run: Run, plant: PlantInterface) -> None:
    session.instantiate(0.0, run.t_end)
    for name, value in plant_settings(run, plant):
        try:
            session.set_value(name, value)
        except Exception as error:  # noqa: BLE001 - name the variable and the value
            raise RuntimeError(f"setting {name} = {value!r} failed ({error})") from None
    session.enter_initialization()
    session.write_inputs((0.0, run.plant.F_E))
    session.exit_initialization()


def simulate(
    run: Run,
    plant: PlantInterface,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    session: PlantSession | None = None,
) -> RunOutcome:
    """Run one scenario variant against `plant`. Never raises for a plant fault: see RunOutcome.

    `buffer`, if given, is the trace's storage ((steps + 1) x columns, filled with NaN), e.g. a
    file-backed map shared with a supervising process (`supervision`); the trace is then a view of it.
    `session`, if given (`open_session`), is a plant already loaded that the caller keeps: the run
    gets an instance of it (reset after a complete run for the next, else freed), not a new copy."""
    started = clock.perf_counter()
    controller = make_controller(run)
    n = run.steps
    recorder = Recorder(trace_names(plant), n, buffer)
    own_session = session is None
    if session is None:
        session = open_session(plant, run.label)
    timing, state = Timing(n, run.T_s, run.plant.F_E), LoopState()
    hooks = [ProgressHook(progress, n, run.T_s, run.t_end)] if progress is not None else []
    policy = CheckpointPolicy(saving=session.can_save_state)
    loop = {"kind": "python", "reason": "the run ended before the second sample"}
    interrupted = False
    loop_started = loop_finished = clock.perf_counter()
    try:
        _initialise(session, run, plant)
        policy.configure(session)
        python = PythonStepper(session, controller, recorder, timing, state, hooks)
        loop_started = clock.perf_counter()
        k = python.advance(0, 1)  # the first sample starts the controller (S0, T_h)
        if k == 1 and n > 0:
            stepper = HandOver(
                python, CompiledStepper.build(session, recorder, timing, state, state.controller.law, hooks)
            )
            if stepper.compiled is not None:
                policy.configure(stepper.compiled.loop)
            try:
                policy.drive(stepper, session, recorder, k, n, run.T_s)
            finally:
                loop = stepper.loop
        loop_finished = clock.perf_counter()
    except KeyboardInterrupt:
        loop_finished = clock.perf_counter()
        interrupted = True
        state.reason = f"interrupted (SIGINT or SIGTERM) at t = {max(recorder.rows - 1, 0) * run.T_s:.6g} s"
    except Exception as error:  # noqa: BLE001 - any plant failure ends the run cleanly
        loop_finished = clock.perf_counter()
        state.reason = f"plant FMU failed at t = {max(recorder.rows - 1, 0) * run.T_s:.6g} s: {error}"
    finally:
        solver_statistics = session.solver_statistics()
        complete = state.reason is None and recorder.rows == n + 1 and not interrupted
        if own_session:
            session.close()
        else:
            session.release(reuse=complete)
    trace, rows, reason = recorder.trace(), recorder.rows, state.reason
    summary = None
    if rows > 1 and state.controller is not None:
        summary = summarize(
            trace.time,
            trace.column("x_B"),
            trace.column("iq_ref"),
            trace.column("E_in"),
            trace.column("E_fric"),
            run.x_start,
            run.x_target,
            state.controller.T_h,
            state.controller.S0,
        )
    wall = clock.perf_counter() - started
    status = "complete" if complete else "interrupted" if interrupted else "failed"
    loop_seconds = loop_finished - loop_started
    record = run_record(
        run, plant, status, reason, rows, wall, loop_seconds, summary, policy.retries, loop, solver_statistics
    )
    return RunOutcome(run, trace, complete, reason, wall, loop_seconds, summary, record, interrupted)
