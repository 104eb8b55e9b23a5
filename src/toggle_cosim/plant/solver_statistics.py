"""The plant solver's statistics, read by name from a live plant FMU at the end of a run.

The plant FMU exposes its integrator's work, where it does, as Integer (FMI 2.0) or Int64
(FMI 3.0) variables of causality local, cumulative over the run: `STATISTICS`. An FMU that
declares none of them gives `NOT_EXPOSED`. The co-simulation session reads them into the run's
record; analysis/solver_stats.py stores them beside a reference and compares them.
"""

from __future__ import annotations

from typing import Any

STATISTICS = ("solver.steps", "solver.rejectedSteps", "solver.events")
NOT_EXPOSED = "not exposed"


def read_solver_statistics(slave: Any, model_description: Any) -> dict[str, int] | str:
    """The counts of `STATISTICS` that the FMU declares, read from the live instance `slave`
    (an fmpy FMU2Slave or FMU3Slave); NOT_EXPOSED when it declares none of them."""
    by_name = {v.name: v for v in model_description.modelVariables}
    present = [name for name in STATISTICS if name in by_name]
    if not present:
        return NOT_EXPOSED
    fmi3 = str(model_description.fmiVersion).startswith("3")
    counts: dict[str, int] = {}
    for name in present:
        reference = by_name[name].valueReference
        value = slave.getInt64([reference])[0] if fmi3 else slave.getInteger([reference])[0]
        counts[name] = int(value)
    return counts
