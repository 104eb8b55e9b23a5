"""Plausibility flags of a finished run (pure functions of its trace): results that the
simulation computed correctly but that a real drive could not give. A flagged run keeps its
status (the simulation did finish); the flags go into run.json (`warnings`), the summary table
and the console, and a sweep's `warnings` column.

* the command exceeds the motor's rating: max |i_q*| > `plant.rated_current` (default 10 A,
  assumed: the paper gives no rating; `runs.definition.PlantSettings`);
* slider B leaves its working range: x_B outside `plant.working_range` (default the linkage's,
  10 mm inside its two dead points, `physics.mechanism.working_range`);
* the command chatters: the total variation of i_q* per second over the run, Σ|Δi_q*| / duration,
  exceeds `CHATTER_TOTAL_VARIATION` A/s, or the sliding variable S changes sign more than
  `CHATTER_SIGN_CHANGES` times per second of the sliding phase (where the controller records S
  and phase); both measured by `summary.vsc_metrics`. A smooth stroke gives a few A/s and a few
  sign changes; a command that switches every sample, or a loop that resonates (±3 A at 70 Hz:
  about 840 A/s), gives hundreds.
"""

from __future__ import annotations

import numpy as np

from toggle_cosim.cosim.summary import vsc_metrics

CHATTER_TOTAL_VARIATION = 500.0  # A/s: Σ|Δi_q*| over the run / its duration
CHATTER_SIGN_CHANGES = 100.0  # 1/s: sign changes of S while sliding / the sliding phase's duration


def plausibility_warnings(
    time: np.ndarray,
    x_B: np.ndarray,
    iq_ref: np.ndarray,
    rated_current: float,
    working_range: tuple[float, float],
    S: np.ndarray | None = None,
    phase: np.ndarray | None = None,
) -> list[str]:
    """One line per limit the run passed (none for a plausible run), with when and by how much.
    `S`, `phase`: the controller's sliding variable and phase, where it records them (the
    chattering flag counts S's sign changes while sliding)."""
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
    metrics = vsc_metrics(time, iq_ref, S, phase)
    variation, changes = metrics.iq_total_variation_A_per_s, metrics.S_sign_changes_per_s
    if (variation is not None and variation > CHATTER_TOTAL_VARIATION) or (
        changes is not None and changes > CHATTER_SIGN_CHANGES
    ):
        sign_changes = "" if changes is None else f", S changes sign {changes:.4g} times/s while sliding"
        warnings.append(
            f"the command chatters: i_q* varies by {variation or 0.0:.4g} A/s{sign_changes} (limits"
            f" {CHATTER_TOTAL_VARIATION:g} A/s and {CHATTER_SIGN_CHANGES:g} sign changes/s; a smooth stroke gives a"
            " few)"
        )
    return warnings
