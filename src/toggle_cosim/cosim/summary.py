"""Figures of merit of one run, computed from its trace (pure functions)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class RunSummary:
    """What the results table (`summary.md`, docs/paper.md) reports for a run."""

    final_error_m: float  # x_B* - x_B at t_end
    settling_time_s: float | None  # last entry into the 2 % band of the stroke, None if never settled
    overshoot_percent: float  # max(x_B - x_B*, 0) over the stroke, in %
    peak_iq_ref_A: float  # max |i_q*|
    hitting_time_s: float | None  # T_h of eq. (21); None for a controller without one
    S0_m_per_s: float | None  # S(t0), the reaching-phase start of eq. (21); None for a controller without one
    E_in_J: float | None  # work of the thrust at t_end (None: the plant has no output E_in)
    E_fric_J: float | None  # energy taken by joint friction at t_end, signed (None: no output E_fric)
    fric_share_start: float | None  # E_fric / E_in when x_B has covered 10 % of the stroke (None: not known)
    time_10_percent_s: float | None  # when x_B has covered 10 % of the stroke

    def as_dict(self) -> dict[str, float | None]:
        return asdict(self)


def summarize(
    time: np.ndarray,
    x_B: np.ndarray,
    iq_ref: np.ndarray,
    E_in: np.ndarray | None,
    E_fric: np.ndarray | None,
    x_start: float,
    x_target: float,
    hitting_time: float | None,
    S0: float | None,
) -> RunSummary:
    stroke = x_target - x_start
    error = x_target - x_B
    band = 0.02 * abs(stroke)
    outside = np.nonzero(np.abs(error) > band)[0]
    if outside.size == 0:
        settling: float | None = float(time[0])
    elif outside[-1] == len(time) - 1:
        settling = None
    else:
        settling = float(time[outside[-1] + 1])
    overshoot = max(float(np.max((x_B - x_target) * np.sign(stroke))), 0.0) / abs(stroke) * 100.0
    travelled = (x_B - x_start) / stroke
    reached = np.nonzero(travelled >= 0.1)[0]
    share = t10 = None
    if reached.size:
        k = int(reached[0])
        t10 = float(time[k])
        if E_in is not None and E_fric is not None and E_in[k] != 0:
            share = float(E_fric[k] / E_in[k])
    return RunSummary(
        final_error_m=float(error[-1]),
        settling_time_s=settling,
        overshoot_percent=overshoot,
        peak_iq_ref_A=float(np.max(np.abs(iq_ref))),
        hitting_time_s=hitting_time,
        S0_m_per_s=S0,
        E_in_J=None if E_in is None else float(E_in[-1]),
        E_fric_J=None if E_fric is None else float(E_fric[-1]),
        fric_share_start=share,
        time_10_percent_s=t10,
    )
