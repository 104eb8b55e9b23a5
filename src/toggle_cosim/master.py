"""The co-simulation loop: a plant FMU and the discrete VSC, stepped every T_s.

    instantiate -> set parameters -> initialise -> every T_s: read outputs, control,
    set inputs, doStep -> terminate, free

The loop allocates nothing per step: value references are resolved once, the trace is a
preallocated array, and the FMU calls go straight to its C functions (`fmu_io`). The FMU is
freed on every exit path. A plant fault (an error status, non-finite outputs) ends the run
early: the trace up to the fault is kept and the run is marked incomplete with the reason.
"""

from __future__ import annotations

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

from toggle_cosim.controller import VSCController
from toggle_cosim.fmu_io import PlantFMU
from toggle_cosim.motor import thrust_constant
from toggle_cosim.parameters import MechanismParameters, MotorParameters
from toggle_cosim.plant import PlantInterface
from toggle_cosim.scenario import Run
from toggle_cosim.summary import RunSummary, summarize
from toggle_cosim.traces import Trace

CONTROL_COLUMNS = ("iq_ref", "F_E", "S", "phase", "e")
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


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with Path(path).open("rb") as stream:
        for chunk in iter(lambda: stream.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _versions() -> dict[str, str]:
    found = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in ("toggle-cosim", "fmpy", "numpy", "scipy", "pandas", "modelica"):
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


def make_controller(run: Run) -> VSCController:
    """The controller of a run, with its own nominal model (never the plant's parameters)."""
    nominal = MechanismParameters(mB=run.controller.nominal_m_B, mu=0.0)
    return VSCController(
        gains=run.controller.gains,
        nominal=nominal,
        K_f=thrust_constant(MotorParameters()),
        target=run.x_target,
        objective=run.controller.objective,
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
    for name, value in run.plant.parameters.items():
        if name not in available:
            raise ValueError(f"key plant.parameters.{name}: the plant FMU has no variable {name!r}")
        settings.append((name, value))
    return settings


def simulate(run: Run, plant: PlantInterface, progress: Callable[[float], None] | None = None) -> RunOutcome:
    """Run one scenario variant against `plant`. Never raises for a plant fault: see RunOutcome."""
    started = clock.perf_counter()
    controller = make_controller(run)
    n = run.steps
    outputs = list(plant.recorded_outputs)
    names = ("time", *outputs, *CONTROL_COLUMNS)
    data = np.full((n + 1, len(names)), np.nan)
    n_out = len(outputs)
    i_x, i_v = 1 + outputs.index("x_B"), 1 + outputs.index("v_B")
    col_u = 1 + n_out
    fmu = PlantFMU(plant, run.label, outputs, ["iq_ref", "F_E"])
    rows = 0
    reason: str | None = None
    F_E = run.plant.F_E
    state = None
    loop_started = loop_finished = clock.perf_counter()
    try:
        fmu.instantiate(0.0, run.t_end)
        for name, value in _plant_settings(run, plant):
            fmu.set_value(name, value)
        fmu.enter_initialization()
        fmu.write_inputs((0.0, F_E))
        fmu.exit_initialization()
        T_s = run.T_s
        every = max(n // 100, 1)
        loop_started = clock.perf_counter()
        for k in range(n + 1):
            t = k * T_s
            row = data[k]
            row[0] = t
            fmu.read_outputs(row[1 : 1 + n_out])
            x_B, v_B = row[i_x], row[i_v]
            if not (math.isfinite(x_B) and math.isfinite(v_B)):
                reason = f"plant outputs became non-finite at t = {t:.6g} s"
                break
            if state is None:
                state = controller.start(t, (x_B, v_B))
            u, control = controller.step(state, t, x_B, v_B)
            row[col_u : col_u + 5] = (u, F_E, control.S, PHASES[control.phase], control.e)
            rows = k + 1
            if k == n:
                break
            fmu.write_inputs((u, F_E))
            fmu.do_step(t, T_s)
            if progress is not None and k % every == 0:
                progress(t / run.t_end)
        loop_finished = clock.perf_counter()
    except Exception as error:  # noqa: BLE001 - any plant failure ends the run cleanly
        loop_finished = clock.perf_counter()
        reason = f"plant FMU failed at t = {rows * run.T_s:.6g} s: {error}"
    finally:
        fmu.close()
    trace = Trace(names, data[:rows].copy())
    complete = reason is None and rows == n + 1
    summary = None
    if rows > 1 and state is not None:
        summary = summarize(
            trace.time, trace.column("x_B"), trace.column("iq_ref"), trace.column("E_in"),
            trace.column("E_fric"), run.x_start, run.x_target, state.T_h, state.S0,
        )
    wall = clock.perf_counter() - started
    record = {
        "scenario": run.scenario,
        "variant": run.variant,
        "scenario_file": str(run.source) if run.source else None,
        "description": run.description,
        "resolved": run.resolved,
        "fmu": {"path": str(plant.path), "sha256": file_sha256(plant.path), "guid": plant.guid,
                "fmi_version": plant.fmi_version, "model_name": plant.model_description.modelName},
        "status": "complete" if complete else "incomplete",
        "reason": reason,
        "samples": rows,
        "wall_time_s": wall,
        "loop_time_s": loop_finished - loop_started,
        "real_time_factor": (rows - 1) * run.T_s / max(loop_finished - loop_started, 1e-12),
        "summary": summary.as_dict() if summary else None,
        "versions": _versions(),
    }
    return RunOutcome(run, trace, complete, reason, wall, loop_finished - loop_started, summary, record)
