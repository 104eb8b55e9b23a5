"""Figures of merit of one run, computed from its trace (pure functions).

Besides the stroke's figures (final error, settling, overshoot, peak command, energies), the
measures of a variable structure controller's chattering and reaching (`vsc_metrics`, one
definition used by the summary and by the invariants of a reference, `analysis.invariants`):

* the total variation of the command per second, Σ|i_q*(k+1) − i_q*(k)| / (t_end − t_0) [A/s];
* the sign changes of S per second in the sliding phase (samples with phase = 1) [1/s];
* the reaching time measured: from the first sample to where S first reaches 0 (its sign
  changes, located by linear interpolation between samples) [s], and its ratio to eq. (21)'s T_h.

A controller without the diagnostics S and phase (a user controller) has no S metrics: they are
None, not zero.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class RunSummary:
    """What the results table (`summary.md`, docs/paper.md) reports for a run."""

    final_error_m: float  # x_B* - x_B at t_end (x_B*: where the reference ends)
    settling_time_s: float | None  # last entry into the 2 % band of the stroke, None if never settled
    overshoot_percent: float  # max(x_B - x_B*, 0) over the stroke, in %
    peak_iq_ref_A: float  # max |i_q*|
    hitting_time_s: float | None  # T_h of eq. (21); None for a controller without one
    S0_m_per_s: float | None  # S(t0), the reaching-phase start of eq. (21); None for a controller without one
    E_in_J: float | None  # work of the thrust at t_end (None: the plant has no output E_in)
    E_fric_J: float | None  # energy taken by joint friction at t_end, signed (None: no output E_fric)
    fric_share_start: float | None  # E_fric / E_in when x_B has covered 10 % of the stroke (None: not known)
    time_10_percent_s: float | None  # when x_B has covered 10 % of the stroke
    iq_total_variation_A_per_s: float | None = None  # Σ|Δi_q*| / duration (None: fewer than two samples)
    S_sign_changes_per_s: float | None = None  # sign changes of S in the sliding phase per second (None: no S)
    reaching_time_s: float | None = None  # measured: first sample to S = 0 (None: no S, or S never reaches 0)
    reaching_time_over_T_h: float | None = None  # reaching_time_s / T_h (None: either unknown, or T_h = 0)

    def as_dict(self) -> dict[str, float | None]:
        return asdict(self)


@dataclass(frozen=True)
class VscMetrics:
    """Chattering and reaching of a run (see the module's docstring); None where not defined."""

    iq_total_variation_A_per_s: float | None
    S_sign_changes_per_s: float | None
    reaching_time_s: float | None

    def as_dict(self) -> dict[str, float | None]:
        return asdict(self)


def _sign_changes(S: np.ndarray) -> int:
    signs = np.sign(S)
    signs = signs[signs != 0]  # a sample exactly on the surface is not a change by itself
    return int(np.count_nonzero(signs[1:] != signs[:-1]))


def _reaching_time(time: np.ndarray, S: np.ndarray) -> float | None:
    if S[0] == 0:
        return 0.0
    crossed = np.nonzero(np.sign(S[1:]) != np.sign(S[0]))[0]
    if crossed.size == 0:
        return None
    k = int(crossed[0]) + 1  # S[k - 1] has S[0]'s sign, S[k] is 0 or has the other
    fraction = S[k - 1] / (S[k - 1] - S[k])
    return float(time[k - 1] + fraction * (time[k] - time[k - 1]) - time[0])


def vsc_metrics(
    time: np.ndarray, iq_ref: np.ndarray, S: np.ndarray | None = None, phase: np.ndarray | None = None
) -> VscMetrics:
    """The command's total variation per second, S's sign changes per second in the sliding
    phase and the measured reaching time, from the trace's columns."""
    duration = float(time[-1] - time[0]) if len(time) > 1 else 0.0
    variation = float(np.sum(np.abs(np.diff(iq_ref))) / duration) if duration > 0 else None
    if S is None or phase is None or len(S) == 0:
        return VscMetrics(variation, None, None)
    sliding = np.nonzero(phase == 1.0)[0]
    changes = None
    if sliding.size > 1:
        span = float(time[sliding[-1]] - time[sliding[0]])
        changes = _sign_changes(S[sliding]) / span if span > 0 else None
    return VscMetrics(variation, changes, _reaching_time(time, S))


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
    S: np.ndarray | None = None,
    phase: np.ndarray | None = None,
    x_final: float | None = None,
) -> RunSummary:
    """The run's figures of merit; S and phase: the controller's diagnostics columns, if it has them;
    x_final: where the reference ends, if not at x_target (a cycle's, at x_start): the final error
    and the settling band are measured from it."""
    stroke = x_target - x_start
    error = (x_target if x_final is None else x_final) - x_B
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
    vsc = vsc_metrics(time, iq_ref, S, phase)
    ratio = None
    if vsc.reaching_time_s is not None and hitting_time:
        ratio = vsc.reaching_time_s / hitting_time
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
        iq_total_variation_A_per_s=vsc.iq_total_variation_A_per_s,
        S_sign_changes_per_s=vsc.S_sign_changes_per_s,
        reaching_time_s=vsc.reaching_time_s,
        reaching_time_over_T_h=ratio,
    )
