"""A finished run as the master returns it (`RunOutcome`), and what run.json says about it."""

from __future__ import annotations

import functools
import os
import platform
import sys
import time as clock
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from toggle_cosim.cosim.summary import RunSummary
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import bounded_text
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run
from toggle_cosim.signals.definitions import as_signal, describe


@dataclass(frozen=True)
class Stepping:
    """How the execution stepped a run, as data (run.json's `loop` says it in words): in the
    compiled system loop or in Python (`why_python`: why not compiled), the native controllers
    the C ran (`natives`), the components it called back in Python, with why (`called_back`),
    and the sample a native controller handed back to Python, from which the Python execution
    ran the rest (`handed_back`; None: none was)."""

    compiled: bool
    why_python: str | None = None
    natives: tuple[str, ...] = ()
    called_back: tuple[tuple[str, str], ...] = ()
    handed_back: int | None = None


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
    stepping: Stepping | None = None  # how the execution stepped it; None: it never started

    @property
    def warnings(self) -> tuple[str, ...]:
        """The run's plausibility flags (`plausibility`), as run.json records them."""
        return tuple(self.record.get("warnings") or ())

    def detached(self, keep_trace: bool = False) -> RunOutcome:
        """This outcome without its hold on the run's trace buffer (a supervised run's trace is a
        view of a file-backed map, which keeps a descriptor and scratch space until its last view
        goes): the trace copied into memory, or, without `keep_trace`, only its column names."""
        rows = self.trace.data if keep_trace else self.trace.data[:0]
        return replace(self, trace=Trace(self.trace.names, np.array(rows)))


RECORDED_PACKAGES = ("toggle-cosim", "fmpy", "numpy", "scipy", "pandas", "modelica")


def platform_text() -> str:
    """platform.platform() without its processor field, which costs a `uname -p` subprocess
    (about 15 ms) and equals the machine field or is empty on the platforms we run on."""
    uname = os.uname()
    library, version = platform.libc_ver()
    text = f"{uname.sysname}-{uname.release}-{uname.machine}"
    return f"{text}-with-{library}{version}" if library else text


@functools.cache
def installed_versions() -> tuple[tuple[str, str], ...]:
    """Python's, the platform's and RECORDED_PACKAGES' versions (importlib.metadata), looked up
    once per process (the parent does it before forking the runs' children)."""
    from importlib import metadata

    found = {"python": sys.version.split()[0], "platform": platform_text()}
    for name in RECORDED_PACKAGES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return tuple(found.items())


def run_record(
    run: Run,
    plant: PlantInterface,
    status: str,
    reason: str | None,
    rows: int,
    wall: float,
    loop_seconds: float,
    summary: RunSummary | None = None,
    retries: list | None = None,
    loop: dict[str, Any] | None = None,
    solver_statistics: dict[str, int] | str | None = None,
    warnings: list[str] | None = None,
    controller: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """What run.json says about a run: status is "complete", "failed" or "interrupted"; `loop` says
    which loop ran and why, `solver_statistics` the plant integrator's counts (None: not read, e.g.
    when the supervised child died before reporting them), `warnings` its plausibility flags,
    `plant_contract` the optional contract variables the plant does not have, `inputs` each
    signal-driven input's definition (`signals.definitions.describe`: a table's CSV with its
    path and SHA-256), `controller` which
    controller ran (`controllers.controller_record`; None: not known, e.g. it could not be built);
    `summary_partial` that `summary` is of the samples recorded before the run failed or was
    interrupted, not of the whole run."""
    return {
        "scenario": run.scenario,
        "variant": run.variant,
        "scenario_file": str(run.source) if run.source else None,
        "description": run.description,
        "resolved": run.resolved,
        "fmu": {
            "path": str(plant.path),
            "sha256": plant.sha256,
            "guid": plant.guid,
            "fmi_version": plant.fmi_version,
            "model_name": plant.model_description.modelName,
        },
        "plant_contract": plant.contract_record(),
        "status": status,
        "reason": reason,
        "warnings": list(warnings or []),
        "samples": rows,
        "retries": retries or [],
        "controller": controller,
        "coupling": run.coupling,
        "inputs": {
            "F_E": describe(as_signal(run.plant.F_E)),
            **{name: describe(as_signal(value)) for name, value in run.plant.inputs.items()},
        },
        "loop": loop or {"kind": "unknown", "reason": "the run did not report its loop"},
        "wall_time_s": wall,
        "loop_time_s": loop_seconds,
        "real_time_factor": max(rows - 1, 0) * run.T_s / max(loop_seconds, 1e-12),
        "summary": summary.as_dict() if summary else None,
        "summary_partial": summary is not None and status != "complete",  # of the samples before the run ended
        "solver_statistics": solver_statistics,
        "versions": dict(installed_versions()),  # a fresh dict for every record
    }


def refused_outcome(
    run: Run, plant: PlantInterface, reason: str, started: float, names: tuple[str, ...] = ("time",)
) -> RunOutcome:
    """The outcome of a run whose controller could not be built or checked (`reason`, the
    ControllerError's message): failed with "controller: ...", no sample, an empty trace of
    `names`; `started` is the run's perf_counter() start."""
    reason = bounded_text(reason if reason.startswith("controller: ") else f"controller: {reason}")
    loop = {"kind": "none", "reason": "the controller could not be built"}
    wall = clock.perf_counter() - started
    record = run_record(run, plant, "failed", reason, 0, wall, 0.0, None, [], loop, None)
    return RunOutcome(run, Trace(names, np.empty((0, len(names)))), False, reason, wall, 0.0, None, record)
