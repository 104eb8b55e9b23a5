"""The co-simulation loop: a plant FMU and the discrete VSC, stepped every T_s.

    instantiate -> set parameters -> initialise -> every T_s: read outputs, control,
    set inputs, doStep -> terminate, free

The loop allocates nothing per step: value references are resolved once, the trace is a
preallocated array, and the FMU calls go straight to its C functions (`fmu_io`). The first
sample (which starts the controller) runs in Python; the rest run in C (`compiled_loop`,
generated from the same law definition, `control.laws`), in one call, or in stretches between
progress reports. Without a C compiler, or from a sample it hands back (non-finite outputs, a
controller fault), the loop runs in Python with the same result; run.json says which loop ran
and why. The FMU is freed on every exit path. A plant fault (an error status, non-finite
outputs) ends the run early: the trace up to the fault is kept and the run is marked
incomplete with the reason.
"""

from __future__ import annotations

import functools
import hashlib
import math
import platform
import sys
import time as clock
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from fmpy.fmi1 import FMICallException

from toggle_cosim.analysis.solver_stats import NOT_EXPOSED, read_solver_statistics
from toggle_cosim.controller import VSCController
from toggle_cosim.compiled_loop import FMI_FAILED, HAND_BACK, kernel_reason
from toggle_cosim.fmu_io import PlantFMU
from toggle_cosim.friction import friction_settings
from toggle_cosim.motor import thrust_constant
from toggle_cosim.parameters import MechanismParameters, MotorParameters
from toggle_cosim.plant import PlantInterface
from toggle_cosim.scenario import Run
from toggle_cosim.summary import RunSummary, summarize
from toggle_cosim.traces import Trace

CONTROL_COLUMNS = ("iq_ref", "F_E", "S", "phase", "e")
CHECKPOINT_SAMPLES = 200  # the FMU state is saved every this many samples (where it can be)
RETRY_SUBSTEPS = 10  # a failed step is retried from the checkpoint in this many smaller steps
RETRIED_STATUSES = (2, 3)  # discard, error; fatal is not retried (the FMU is beyond recovery)


class _StepFailed(Exception):
    """doStep failed at sample k (after sample k was recorded)."""

    def __init__(self, k: int, error: FMICallException) -> None:
        super().__init__(str(error))
        self.k, self.error = k, error


class _RetryFailed(Exception):
    """The retry from the checkpoint failed as well; the message tells both failures."""
PHASES = {"reaching": 0.0, "sliding": 1.0}


@dataclass(frozen=True)
class RunOutcome:
    """A finished (or stopped) run: its trace and what the run record says about it."""

    run: Run
    trace: Trace
    complete: bool
    reason: str | None
    wall_seconds: float
    loop_seconds: float
    summary: RunSummary | None
    record: dict[str, Any] = field(default_factory=dict)
    interrupted: bool = False  # stopped by SIGINT/SIGTERM: the caller should stop too


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with Path(path).open("rb") as stream:
        for chunk in iter(lambda: stream.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


@functools.cache
def _installed_versions() -> tuple[tuple[str, str], ...]:
    """Looked up once per process: importlib.metadata reads and parses every package's METADATA
    file on each call (~13 ms for these six, more than a paper run's whole loop)."""
    found = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in ("toggle-cosim", "fmpy", "numpy", "scipy", "pandas", "modelica"):
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return tuple(found.items())


def _versions() -> dict[str, str]:
    return dict(_installed_versions())  # a fresh dict for every record


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


def _plant_settings(run: Run, plant: PlantInterface) -> list[tuple[str, float | bool]]:
    settings: list[tuple[str, float | bool]] = [("m_B", run.plant.m_B), ("mu", run.plant.mu)]
    available = plant.references
    if "x_B0" in available:
        settings.append(("x_B0", run.x_start))
    if "idealCurrentLoop" in available:
        settings.append(("idealCurrentLoop", run.plant.current_loop == "ideal"))
    elif run.plant.current_loop == "ideal":
        raise ValueError(f"{plant.path}: the plant has no parameter idealCurrentLoop, so plant.current_loop: ideal cannot be set")
    if run.plant.K is not None:
        settings.append(("K", run.plant.K))
    settings += friction_settings(run.plant.friction_model, run.plant.mu, run.plant.mu_s, available, plant.path)
    for name, value in run.plant.parameters.items():
        if name not in available:
            raise ValueError(f"key plant.parameters.{name}: the plant FMU has no variable {name!r}")
        settings.append((name, value))
    return settings


def _solver_statistics(fmu: PlantFMU, plant: PlantInterface) -> dict[str, int] | str:
    """The plant solver's cumulative counts at the end of the run (toggle_cosim.analysis.solver_stats)."""
    if not getattr(fmu, "_instantiated", False):
        return NOT_EXPOSED
    try:
        return read_solver_statistics(fmu.fmu, plant.model_description)
    except Exception as error:  # noqa: BLE001 - a run's record never fails for its statistics
        return f"unreadable ({error})"


def trace_names(plant: PlantInterface) -> tuple[str, ...]:
    """The columns of a run's trace: time, the plant's recorded outputs, the controller's columns."""
    return ("time", *plant.recorded_outputs, *CONTROL_COLUMNS)


def simulate(run: Run, plant: PlantInterface, progress: Callable[[float], None] | None = None,
             buffer: np.ndarray | None = None) -> RunOutcome:
    """Run one scenario variant against `plant`. Never raises for a plant fault: see RunOutcome.

    `buffer`, if given, is the trace's storage ((steps + 1) x columns, filled with NaN), e.g. a
    file-backed map shared with a supervising process (`supervision`); the trace is then a view of it."""
    started = clock.perf_counter()
    controller = make_controller(run)
    n = run.steps
    outputs = list(plant.recorded_outputs)
    names = trace_names(plant)
    data = np.full((n + 1, len(names)), np.nan) if buffer is None else buffer
    n_out = len(outputs)
    i_x, i_v = 1 + outputs.index("x_B"), 1 + outputs.index("v_B")
    col_u = 1 + n_out
    fmu = PlantFMU(plant, run.label, outputs, ["iq_ref", "F_E"])
    rows = 0
    reason: str | None = None
    F_E = run.plant.F_E
    state = None
    retries: list[dict[str, Any]] = []
    interrupted = False
    loop: dict[str, Any] = {"kind": "python", "reason": "the run ended before the second sample"}
    loop_started = loop_finished = clock.perf_counter()
    try:
        fmu.instantiate(0.0, run.t_end)
        for name, value in _plant_settings(run, plant):
            try:
                fmu.set_value(name, value)
            except Exception as error:  # noqa: BLE001 - name the variable and the value
                raise RuntimeError(f"setting {name} = {value!r} failed ({error})") from None
        fmu.enter_initialization()
        fmu.write_inputs((0.0, F_E))
        fmu.exit_initialization()
        T_s, t_end = run.T_s, run.t_end
        every = max(n // 100, 1)
        read_outputs, write_inputs, do_step = fmu.read_outputs, fmu.write_inputs, fmu.do_step
        control_step, isfinite = controller.step, math.isfinite

        def python_steps(k0: int, k_end: int, read_first: bool = True) -> int:
            """Samples k0 .. k_end - 1 in Python; the next sample, or -1 when the outputs went
            non-finite (`reason` says so). A plant error raises. With read_first False the
            outputs of sample k0 are in the trace already (read by the compiled loop)."""
            nonlocal rows, state, reason, z
            for k in range(k0, k_end):
                t = k * T_s
                row = data[k]
                row[0] = t
                if read_first or k != k0:
                    read_outputs(row[1 : 1 + n_out])
                x_B, v_B = row[i_x], row[i_v]
                if not (isfinite(x_B) and isfinite(v_B)):
                    reason = f"plant outputs became non-finite at t = {t:.6g} s"
                    return -1
                if state is None:
                    state = controller.start(t, (x_B, v_B))
                    z = state.z
                elif state.z != z:
                    state = replace(state, z=z)
                u, control = control_step(state, t, x_B, v_B)
                z = control.z
                row[col_u : col_u + 5] = (u, F_E, control.S, PHASES[control.phase], control.e)
                rows = k + 1
                if k == n:
                    return k + 1
                write_inputs((u, F_E))
                try:
                    do_step(t, T_s)
                except FMICallException as error:
                    raise _StepFailed(k, error) from None
                if progress is not None and k % every == 0:
                    progress(t / t_end)
            return k_end

        z = 0.0  # the law's state (the integral law's integrator) at the next sample
        loop_started = clock.perf_counter()
        k = python_steps(0, 1)  # the first sample starts the controller (S0, T_h)
        compiled = None
        if k == 1 and n > 0:
            compiled = fmu.compiled_loop(data, n_out, i_x, i_v, col_u, n, T_s, F_E, state.law, z)
            loop = ({"kind": "compiled", "reason": "generated from control.laws; C compiler available"}
                    if compiled is not None else
                    {"kind": "python", "reason": kernel_reason() or "the FMU's C functions are not reachable"})

        def stretch(k: int, stop: int) -> int:
            """Samples k .. stop - 1, in C where it can, else in Python; the next sample or -1."""
            nonlocal rows, compiled, z, loop
            while compiled is not None and k < stop:
                # in C: up to the next sample that reports progress, or to the end of the stretch
                end = stop if progress is None else min(k + (every - k % every) % every + 1, stop)
                code, k = compiled.run(k, end)
                if code == FMI_FAILED:  # reading sample k failed, or setting/stepping after recording it
                    rows = k if compiled.fault_function == fmu._get_name else k + 1
                    error = FMICallException(function=compiled.fault_function, status=compiled.fault_status)
                    if compiled.fault_function == fmu._step_name:
                        raise _StepFailed(k, error)
                    raise error
                rows = k
                z = compiled.z
                if code == HAND_BACK:  # a sample the Python decides (non-finite outputs, a controller fault)
                    compiled = None
                    loop = {"kind": "compiled, then python",
                            "reason": f"the compiled loop handed sample {k} (t = {k * T_s:.6g} s) back to Python "
                                      "(non-finite outputs, or the law raises there)"}
                    return python_steps(k, stop, read_first=False) if k <= n else k
                if progress is not None and k - 1 < n and (k - 1) % every == 0:
                    progress((k - 1) * T_s / t_end)
            return python_steps(k, stop) if 0 < k < stop else k

        def retry(checkpoint: int, failed: int, error: FMICallException) -> None:
            """Back to the checkpoint, the recorded inputs replayed up to the failed sample, and
            its step again in RETRY_SUBSTEPS smaller steps; raises if that fails too."""
            try:
                fmu.restore_state()
                for j in range(checkpoint, failed):
                    write_inputs((data[j, col_u], data[j, col_u + 1]))
                    do_step(j * T_s, T_s)
                write_inputs((data[failed, col_u], data[failed, col_u + 1]))
                h = T_s / RETRY_SUBSTEPS
                for m in range(RETRY_SUBSTEPS):
                    do_step(failed * T_s + m * h, h)
            except FMICallException as again:
                raise _RetryFailed(
                    f"{error} Retried from the checkpoint at t = {checkpoint * T_s:.6g} s in {RETRY_SUBSTEPS} "
                    f"substeps: {again}"
                ) from again

        saving = fmu.can_save_state
        while 0 < k <= n:
            stop = min(k + CHECKPOINT_SAMPLES, n + 1)
            if saving:
                fmu.save_state()
            checkpoint = k
            try:
                k = stretch(k, stop)
            except _StepFailed as failure:
                if not saving or failure.error.status not in RETRIED_STATUSES:
                    raise failure.error from None
                retry(checkpoint, failure.k, failure.error)
                retries.append({"t": failure.k * T_s, "error": str(failure.error)})
                k = failure.k + 1
        loop_finished = clock.perf_counter()
    except KeyboardInterrupt:
        loop_finished = clock.perf_counter()
        interrupted = True
        reason = f"interrupted (SIGINT or SIGTERM) at t = {max(rows - 1, 0) * run.T_s:.6g} s"
    except Exception as error:  # noqa: BLE001 - any plant failure ends the run cleanly
        loop_finished = clock.perf_counter()
        reason = f"plant FMU failed at t = {max(rows - 1, 0) * run.T_s:.6g} s: {error}"
    finally:
        solver_statistics = _solver_statistics(fmu, plant)
        fmu.close()
    trace = Trace(names, data[:rows].copy() if buffer is None else data[:rows])
    complete = reason is None and rows == n + 1
    summary = None
    if rows > 1 and state is not None:
        summary = summarize(
            trace.time, trace.column("x_B"), trace.column("iq_ref"), trace.column("E_in"),
            trace.column("E_fric"), run.x_start, run.x_target, state.T_h, state.S0,
        )
    wall = clock.perf_counter() - started
    status = "complete" if complete else "interrupted" if interrupted else "failed"
    record = run_record(run, plant, status, reason, rows, wall, loop_finished - loop_started, summary, retries,
                        loop, solver_statistics)
    return RunOutcome(run, trace, complete, reason, wall, loop_finished - loop_started, summary, record, interrupted)


def run_record(run: Run, plant: PlantInterface, status: str, reason: str | None, rows: int, wall: float,
               loop_seconds: float, summary: RunSummary | None = None, retries: list | None = None,
               loop: dict[str, Any] | None = None, solver_statistics: dict[str, int] | str | None = None,
               ) -> dict[str, Any]:
    """What run.json says about a run: status is "complete", "failed" or "interrupted"; `loop` says
    which loop ran and why, `solver_statistics` the plant integrator's counts (None: not read, e.g.
    when the supervised child died before reporting them)."""
    return {
        "scenario": run.scenario,
        "variant": run.variant,
        "scenario_file": str(run.source) if run.source else None,
        "description": run.description,
        "resolved": run.resolved,
        "fmu": {"path": str(plant.path), "sha256": file_sha256(plant.path), "guid": plant.guid,
                "fmi_version": plant.fmi_version, "model_name": plant.model_description.modelName},
        "status": status,
        "reason": reason,
        "samples": rows,
        "retries": retries or [],
        "loop": loop or {"kind": "unknown", "reason": "the run did not report its loop"},
        "wall_time_s": wall,
        "loop_time_s": loop_seconds,
        "real_time_factor": max(rows - 1, 0) * run.T_s / max(loop_seconds, 1e-12),
        "summary": summary.as_dict() if summary else None,
        "solver_statistics": solver_statistics,
        "versions": _versions(),
    }
