"""The results table of a set of runs, as Markdown (the README quotes it)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from toggle_cosim.master import RunOutcome
from toggle_cosim.traces import atomic_write


def _cell(value: float | None, scale: float = 1.0, fmt: str = ".3f") -> str:
    return "—" if value is None else format(value * scale, fmt)


def summary_table(outcomes: Sequence[RunOutcome]) -> str:
    lines = [
        "| run | status | final error [mm] | settling (2 %) [s] | overshoot [%] | peak abs i_q* [A] | T_h [s] | S(t0) [m/s] | E_in [J] | E_fric [J] | E_fric/E_in at 10 % stroke |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for outcome in outcomes:
        s = outcome.summary
        status = "complete" if outcome.complete else f"incomplete: {outcome.reason}"
        if s is None:
            lines.append(f"| {outcome.run.label} | {status} |" + " — |" * 9)
            continue
        lines.append(
            f"| {outcome.run.label} | {status} | {_cell(s.final_error_m, 1e3, '+.4f')} | {_cell(s.settling_time_s)} | "
            f"{_cell(s.overshoot_percent, 1, '.2f')} | {_cell(s.peak_iq_ref_A, 1, '.2f')} | {_cell(s.hitting_time_s, 1, '.4f')} | "
            f"{_cell(s.S0_m_per_s, 1, '.4f')} | {_cell(s.E_in_J, 1, '.4f')} | {_cell(s.E_fric_J, 1, '.4f')} | "
            f"{_cell(s.fric_share_start, 1, '.3f')} |"
        )
    return "\n".join(lines) + "\n"


def write_summary(outcomes: Sequence[RunOutcome], path: Path) -> Path:
    text = "# Results of the paper's runs\n\n" + summary_table(outcomes)
    atomic_write(Path(path), lambda stream: stream.write(text))
    return Path(path)
