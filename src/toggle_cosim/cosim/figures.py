"""A run's figures of merit and plausibility warnings from its trace, the one rule for every run:
the plain pair (columns `x_B`, `iq_ref`, ...) and a system (columns `plant.x_B`,
`controller.iq_ref`, ...: its plant's and controller's names, `Run.system`), whole or partial
(a run that failed or hit its time limit: the samples it recorded; `supervision`'s partial
outcome uses it too).
"""

from __future__ import annotations

import numpy as np

from toggle_cosim.cosim.plausibility import plausibility_warnings
from toggle_cosim.cosim.summary import RunSummary, summarize
from toggle_cosim.files.traces import Trace
from toggle_cosim.physics.mechanism import working_range
from toggle_cosim.physics.parameters import MechanismParameters
from toggle_cosim.runs.definition import Run

__all__ = ["run_figures", "trace_prefixes"]


def _number(value: object) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def trace_prefixes(run: Run, trace: Trace) -> tuple[str, str]:
    """The prefixes of the plant's and the controller's columns in the trace, read from its
    columns: none for the pair's (`x_B`), else the system's component names (`plant.`,
    `controller.`)."""
    if "x_B" in trace.names:
        return "", ""
    return f"{run.system.plant}.", f"{run.system.controller}."


def run_figures(run: Run, trace: Trace, controller: object) -> tuple[RunSummary | None, list[str]]:
    """A run's figures of merit and plausibility warnings (`plausibility`) from its trace; (None,
    []) before its second sample or without the plant's x_B and the controller's iq_ref.
    `controller`: the controller's state (or the controller), which gives T_h and S0 when it has
    them."""
    plant, control = trace_prefixes(run, trace)
    names = set(trace.names)

    def column(name: str) -> np.ndarray | None:
        return trace.column(name) if name in names else None

    x_B, iq_ref = column(f"{plant}x_B"), column(f"{control}iq_ref")
    if trace.data.shape[0] < 2 or x_B is None or iq_ref is None:
        return None, []
    S, phase = column(f"{control}S"), column(f"{control}phase")
    if S is None or phase is None:  # the pair's S and phase: both or neither
        S = phase = None
    summary = summarize(
        trace.time,
        x_B,
        iq_ref,
        column(f"{plant}E_in"),
        column(f"{plant}E_fric"),
        run.x_start,
        run.x_target,
        _number(getattr(controller, "T_h", None)),
        _number(getattr(controller, "S0", None)),
        S,
        phase,
        None if run.x_final == run.x_target else run.x_final,
    )
    limits = run.plant.working_range or working_range(MechanismParameters())
    return summary, plausibility_warnings(trace.time, x_B, iq_ref, run.plant.rated_current, limits, S, phase)
