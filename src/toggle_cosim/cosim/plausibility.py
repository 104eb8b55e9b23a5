"""Plausibility flags of a finished run (pure functions of its trace): results that the
simulation computed correctly but that a real drive could not give. A flagged run keeps its
status (the simulation did finish); the flags go into run.json (`warnings`), the summary table
and the console, and a sweep's `warnings` column.

* the command exceeds the motor's rating: max |i_q*| > `plant.rated_current` (default 10 A,
  assumed: the paper gives no rating; `runs.definition.PlantSettings`);
* slider B leaves its working range: x_B outside `plant.working_range` (default the linkage's,
  10 mm inside its two dead points, `physics.mechanism.working_range`).
"""

from __future__ import annotations

import numpy as np


def plausibility_warnings(
    time: np.ndarray, x_B: np.ndarray, iq_ref: np.ndarray, rated_current: float, working_range: tuple[float, float]
) -> list[str]:
    """One line per limit the run passed (none for a plausible run), with when and by how much."""
    warnings = []
    command = np.abs(iq_ref)
    over = np.flatnonzero(command > rated_current)
    if over.size:
        k = int(np.argmax(command))
        warnings.append(
            f"|i_q*| exceeds the rated current {rated_current:g} A (plant.rated_current) from t = {time[over[0]]:.6g} s;"
            f" peak {command[k]:.4g} A at t = {time[k]:.6g} s"
        )
    low, high = working_range
    outside = np.flatnonzero((x_B < low) | (x_B > high))
    if outside.size:
        warnings.append(
            f"slider B leaves its working range {low:.4f} m to {high:.4f} m (plant.working_range) at"
            f" t = {time[outside[0]]:.6g} s; x_B spans {float(np.min(x_B)):.5f} m to {float(np.max(x_B)):.5f} m"
        )
    return warnings
