"""A run's work budget: a limit on the simulated work its plant may do, counted by the plant
FMU's own solver statistics (`plant.solver_statistics`), so that whether a run stays within it
does not depend on how fast or busy the machine is (a wall-clock limit does).

    budget: {events: 20000}            # solver.events, the plant's events over the run
    budget: {events_per_sample: 4}     # the same, as so many events per sample of the run
    budget: {steps: 400000}            # solver.steps, its integrator's accepted steps

The execution (`system_retry.SystemCheckpoints.drive`) reads the counts after every stretch of
`CHECKPOINT_SAMPLES` samples and at the end, at the same samples on every machine: a run past
its budget ends there, failed, its trace kept, with the reason `exceeded`. A scenario key (any
run, a sweep's cases); `tune` sets DEFAULT_BUDGET on every case unless its file says otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

# The budget's keys and the plant's counters they limit (`solver_statistics.STATISTICS`).
COUNTERS = {"events": "solver.events", "steps": "solver.steps"}
DEFAULT_EVENTS_PER_SAMPLE = 4  # tune's default: events <= 4 x samples (a run that chatters has far more)
DEFAULT_BUDGET = {"events_per_sample": DEFAULT_EVENTS_PER_SAMPLE}


class BudgetExceeded(Exception):
    """The plant's work went past the run's budget; str() is the run's reason."""


@dataclass(frozen=True)
class WorkBudget:
    """The limits of a run's work (None: no limit on that count)."""

    events: int | None = None
    steps: int | None = None
    events_key: str = "budget.events"  # where the events limit comes from, for the reason

    @classmethod
    def of(cls, given: Mapping[str, Any] | None, samples: int) -> WorkBudget | None:
        """The budget of a scenario's `budget` key (validated by its schema) for a run of
        `samples` samples (events_per_sample: the lower of it and `events`), or None."""
        if not given:
            return None
        limits = {key: int(value) for key, value in given.items() if key in COUNTERS}
        rate = given.get("events_per_sample")
        if rate is not None and math.floor(float(rate) * samples) < limits.get("events", math.inf):
            limits["events"] = math.floor(float(rate) * samples)
            return cls(**limits, events_key=f"budget.events_per_sample {float(rate):g} x {samples} samples")
        return cls(**limits)

    def exceeded(self, counts: Mapping[str, int] | str, t: float) -> str | None:
        """Why the plant's cumulative `counts` (read at t) are past the budget, or None; a plant
        that exposes no counts (a string: `solver_statistics.NOT_EXPOSED`) cannot be held to one."""
        if isinstance(counts, str):
            return (
                f"budget: the plant FMU gives no solver statistics to count its work ({counts}); remove the budget key"
            )
        for key, counter in COUNTERS.items():
            limit = getattr(self, key)
            if limit is None:
                continue
            if counter not in counts:
                return f"budget: the plant FMU does not count {counter}; remove budget.{key}"
            if counts[counter] > limit:
                where = self.events_key if key == "events" else f"budget.{key}"
                return f"budget exceeded ({counts[counter]} {key} > {limit}, {where}) by t = {t:.6g} s"
        return None
