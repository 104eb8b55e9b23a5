"""The plain plant + controller run: a plant FMU and a discrete controller, stepped every T_s.

    instantiate -> set parameters -> initialise -> every T_s: read outputs, control,
    set inputs, doStep -> terminate, free

A run with parts around the pair, connections of its own or a `record:` list is a system, which
`systems.simulate_system` runs; the plain pair runs here, in a loop fixed to its two parts, which
gives the system execution's values bit for bit and keeps what only it has (the compiled law with
hand-back, python-control systems in C, a work budget, a kept plant session; a system's run has
checkpoint retries of its own, `system_retry`).

`simulate_pair` assembles the parts (after FMPy's simulateCS, with its Recorder and step hook):
a `PlantSession` (session.py), a `Recorder` and step hooks (recorder.py), the controller
(the one given, else the scenario's: `controllers`), the steppers (stepper.py: the first
sample in Python, which starts the controller; for the built-in law and a controller FMU the
rest in the compiled loop generated from `control.laws` (which calls the FMU's C functions),
handed over to Python at a sample the C hands back, or all in Python without a C compiler;
any other controller in Python at every sample) and the
`CheckpointPolicy` (retry.py). run.json says which loop ran and why. The FMU is freed on
every exit path. A plant fault (an error status, non-finite outputs) or a controller failure
ends the run early: the trace up to the fault is kept and the run is marked failed with the
reason. A controller with a `close()` (a controller FMU) is closed on every exit path too.

The load F_E (`Run.plant.F_E`) and the plant's other inputs (`Run.plant.inputs`), each a number
or a signal in time (`signals`), are sampled once before the loop at every communication point
t_k = k·T_s (`input_samples`); sample k sends row k in both loops and both couplings and records
it (F_E's column, and one column per other input after the diagnostics); initialisation sends row 0.

Coupling (`Run.coupling`, or simulate's `coupling`): "gauss-seidel" (the default) drives the
plant over [t_k, t_k+1] with the command the controller computed from the plant's outputs at t_k;
"jacobi" drives it with the command of sample k - 1 (sample 0's at k = 0), as a master that steps
every FMU and only then exchanges values does, and row k of the trace holds the plant's outputs
at t_k with the controller's outputs (command and diagnostics) of sample k - 1: the values every
variable has at t_k in such a master. The compiled loop runs gauss-seidel only; jacobi runs the
Python loop, and run.json says so. A failed step retried from a checkpoint that passes is kept
in run.json's `retries` and said in a warning; the run goes on, and if it fails later it is
reported failed at that later step (its reason ends with the earlier retries), its trace kept
up to the sample that step started from. A plant failure's reason ends with what the FMU
logged about it (its last message with a failing status). A finished run is checked for
plausibility (`plausibility`): its warnings go into run.json.
"""

from __future__ import annotations

import dataclasses
import time as clock
from collections.abc import Callable

import numpy as np

from toggle_cosim import interrupts
from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import COMMAND_COLUMNS, Controller, ControllerError, check_controller
from toggle_cosim.cosim.budget import BudgetExceeded, WorkBudget
from toggle_cosim.cosim.controllers import controller_for, controller_record
from toggle_cosim.cosim.figures import run_figures
from toggle_cosim.cosim.outcome import RunOutcome, run_record
from toggle_cosim.cosim.plant_inputs import input_samples, other_inputs, plant_settings
from toggle_cosim.cosim.recorder import ProgressHook, Recorder
from toggle_cosim.cosim.retry import CheckpointPolicy, failure_text
from toggle_cosim.cosim.session import PlantSession
from toggle_cosim.cosim.stepper import (
    CompiledStepper,
    ControllerFailed,
    HandOver,
    LoopState,
    PythonStepper,
    Timing,
    compiled_controller,
)
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import bounded_text
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import COUPLINGS, Run

__all__ = [
    "JACOBI_REASON",
    "RunOutcome",
    "close_controller",
    "open_session",
    "refused_outcome",
    "simulate_pair",
    "trace_names",
]
JACOBI_REASON = "coupling jacobi: the compiled loop runs gauss-seidel only, so the Python loop delays the command"
INPUTS = COMMAND_COLUMNS


def trace_names(
    plant: PlantInterface, diagnostics: tuple[str, ...] = VSCController.diagnostics, inputs: tuple[str, ...] = ()
) -> tuple[str, ...]:
    """The columns of a run's trace: time, the plant's recorded outputs, the inputs (iq_ref,
    F_E), the controller's diagnostics (the built-in law's by default), then the plant's other
    inputs the run sets (`inputs`: `other_inputs(run)`)."""
    return ("time", *plant.recorded_outputs, *INPUTS, *diagnostics, *inputs)


def open_session(plant: PlantInterface, instance_name: str, inputs: tuple[str, ...] = ()) -> PlantSession:
    """A session of `plant` with the master's outputs and inputs (iq_ref, F_E, then `inputs`, the
    plant's other inputs a run sets): the FMU unzipped and its binary loaded, no instance yet.
    `simulate(..., session=)` runs on it, run after run (runs with those other inputs)."""
    return PlantSession(plant, instance_name, list(plant.recorded_outputs), [*INPUTS, *inputs])


def _initialise(session: PlantSession, run: Run, plant: PlantInterface, sent: tuple[float, ...]) -> None:
    """Instantiate, set the parameters, and initialise with the inputs (0, then u(0) of the others)."""
    session.instantiate(0.0, run.t_end)
    for name, value in plant_settings(run, plant):
        try:
            session.set_value(name, value)
        except Exception as error:  # noqa: BLE001 - name the variable and the value
            raise RuntimeError(f"setting {name} = {value!r} failed ({error})") from None
    session.enter_initialization()
    session.write_inputs((0.0, *sent))
    session.exit_initialization()


def retried_words(passed: list[dict], T_s: float) -> str | None:
    """The plant steps that failed and passed when retried from a checkpoint, in words (a run's
    warning; a failure reason's note, short so the reason's own words stay in its bound), or None."""
    if not passed:
        return None
    if len(passed) == 1:
        return f"the plant's step at t = {passed[0]['t']:.6g} s failed and passed when retried from a checkpoint"
    return (
        f"{len(passed)} of the plant's steps from t = {passed[0]['t']:.6g} s to {passed[-1]['t']:.6g} s failed "
        "and passed when retried from a checkpoint"
    )


def simulate_pair(
    run: Run,
    plant: PlantInterface,
    progress: Callable[[float], None] | None = None,
    buffer: np.ndarray | None = None,
    controller: Controller | None = None,
    session: PlantSession | None = None,
    coupling: str | None = None,
    count: np.ndarray | None = None,
) -> RunOutcome:
    """Run one plain plant + controller run (`master.simulate` hands it here) against `plant`.
    Never raises for a plant or controller fault: see RunOutcome.

    `controller`: any object that meets the controller protocol (`control.protocol`); None: the
    run's own (`controllers.controller_for`: the scenario's built-in law, or its
    controller.python). The compiled loop runs the built-in law and a controller FMU (under
    gauss-seidel coupling); any other controller runs in Python at every sample, and run.json
    says which loop ran and why.

    `buffer`, if given, is the trace's storage ((steps + 1) x columns, filled with NaN), e.g. a
    file-backed map shared with a supervising process (`supervision`); the trace is then a view of it.
    `count`, if given, is where the samples recorded are counted as they are (`recorder.row_count`).
    `session`, if given (`open_session`), is a plant already loaded that the caller keeps: the run
    gets an instance of it (reset after a complete run for the next, else freed), not a new copy.
    `coupling`: "gauss-seidel" or "jacobi" (module docstring); None: the run's own (`Run.coupling`)."""
    started = clock.perf_counter()
    if coupling is not None and coupling != run.coupling:
        if coupling not in COUPLINGS:
            raise ValueError(f"coupling: choose one of {', '.join(COUPLINGS)}, not {coupling!r}")
        run = dataclasses.replace(run, coupling=coupling)
    jacobi = run.coupling == "jacobi"
    try:
        if controller is None:
            controller = controller_for(run, plant.recorded_outputs)
        diagnostics = check_controller(controller, plant.recorded_outputs)
    except ControllerError as error:
        close_controller(controller)
        return refused_outcome(run, plant, str(error), started)
    n, others = run.steps, other_inputs(run)
    if session is not None and session.inputs != (*INPUTS, *others):
        close_controller(controller)
        raise ValueError(f"the session sets the inputs {session.inputs}, the run {(*INPUTS, *others)}")
    recorder = Recorder(trace_names(plant, diagnostics, others), n, buffer, extra=len(others), count=count)
    own_session = session is None
    if session is None:
        session = open_session(plant, run.label, others)
    timing, state = Timing(n, run.T_s, input_samples(run, n)), LoopState()
    hooks = [ProgressHook(progress, n, run.T_s, run.t_end)] if progress is not None else []
    policy = CheckpointPolicy(saving=session.can_save_state, budget=WorkBudget.of(run.resolved.get("budget"), n))
    loop = {"kind": "python", "reason": "the run ended before the second sample"}
    interrupted = False
    loop_started = loop_finished = clock.perf_counter()
    try:
        _initialise(session, run, plant, tuple(float(value) for value in timing.load[0]))
        policy.configure(session)
        python = PythonStepper(session, controller, recorder, timing, state, hooks, jacobi=jacobi)
        loop_started = clock.perf_counter()
        k = python.advance(0, 1)  # the first sample starts the controller (S0, T_h)
        if k == 1 and n > 0:
            law = JACOBI_REASON if jacobi else compiled_controller(controller, state.controller)
            compiled = (
                law
                if isinstance(law, str)
                else CompiledStepper.build(
                    session,
                    recorder,
                    timing,
                    state,
                    law,
                    controller.measured,
                    hooks,
                    controller.reference if isinstance(controller, VSCController) else None,
                )
            )
            stepper = HandOver(python, compiled)
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
    except ControllerFailed as error:
        loop_finished = clock.perf_counter()
        state.reason = f"controller failed: {error}"
    except BudgetExceeded as error:  # the plant's work past the run's budget: the same sample on any machine
        loop_finished = clock.perf_counter()
        state.reason = str(error)
    except Exception as error:  # noqa: BLE001 - any plant failure ends the run cleanly
        loop_finished = clock.perf_counter()
        said = failure_text(error, session.logged_error())  # the FMU's own words on what went wrong
        state.reason = f"plant FMU failed at t = {max(recorder.rows - 1, 0) * run.T_s:.6g} s: {said}"
    finally:
        close_controller(controller)
        solver_statistics = session.solver_statistics()
        if own_session:
            session.close()
        else:  # a kept plant: reset after a complete run for the next, else freed
            session.release(reuse=state.reason is None and recorder.rows == n + 1 and not interrupted)
    retried = retried_words(policy.passed(), run.T_s)
    if state.reason is not None and retried is not None:
        state.reason = f"{state.reason} (earlier, {retried})"
    trace, rows, reason = recorder.trace(), recorder.rows, state.reason
    reason = bounded_text(reason) if reason is not None else None  # one line, whatever the plant or controller said
    complete = reason is None and rows == n + 1
    summary, warnings = run_figures(run, trace, state.controller)
    if retried is not None:  # what the first one failed with, in run.json's retries too
        warnings = [*warnings, bounded_text(f"{retried[0].upper()}{retried[1:]}: {policy.passed()[0]['error']}")]
    wall = clock.perf_counter() - started
    status = "complete" if complete else "interrupted" if interrupted else "failed"
    loop_seconds = loop_finished - loop_started
    record = run_record(
        run,
        plant,
        status,
        reason,
        rows,
        wall,
        loop_seconds,
        summary,
        policy.retries,
        loop,
        solver_statistics,
        warnings=warnings,
        controller=controller_record(run, controller),
    )
    return RunOutcome(run, trace, complete, reason, wall, loop_seconds, summary, record, interrupted)


def close_controller(controller: object) -> None:
    """Call the controller's close(), if it has one (a controller FMU frees its instance, its
    library and its unzipped copy); whatever it raises is ignored (the run's outcome stands)."""
    close = getattr(controller, "close", None)
    if callable(close):
        try:
            close()
        except BaseException as error:  # noqa: BLE001 - freeing never changes a run's outcome
            if not interrupts.raised_by_code(error):  # SystemExit, or KeyboardInterrupt in a run's child
                raise


def refused_outcome(run: Run, plant: PlantInterface, reason: str, started: float) -> RunOutcome:
    """The outcome of a run whose controller could not be built (`reason`, a ControllerError's
    message): failed, no sample; `started` is the run's perf_counter() start."""
    names = trace_names(plant, inputs=other_inputs(run))
    trace = Trace(names, np.empty((0, len(names))))
    reason = bounded_text(reason if reason.startswith("controller: ") else f"controller: {reason}")
    loop = {"kind": "none", "reason": "the controller could not be built"}
    wall = clock.perf_counter() - started
    record = run_record(
        run, plant, "failed", reason, 0, wall, 0.0, None, [], loop, None, warnings=None, controller=None
    )
    return RunOutcome(run, trace, False, reason, wall, 0.0, None, record)
