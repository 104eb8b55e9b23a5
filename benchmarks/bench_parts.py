"""What bench.py and system_bench.py share: the paper's runs, one simulate()'s loop cost
(`full_loop`, the built-in pair's figure the system rows are compared with) and the table the
figures are printed in. Both scripts import it; system_bench.py imports nothing of bench.py, so
it runs alone, and bench.py imports system_bench.py for its section of the table."""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator
from pathlib import Path

from toggle_cosim.cosim import compiled_loop, master, pair, session
from toggle_cosim.experiments.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"
PAPER = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")


def paper_runs() -> list:
    """Every variant of the paper's three scenarios (fig4, fig5, fig6)."""
    return [run for name in PAPER for run in load_scenario(SCENARIOS / f"{name}.yaml")]


class Timed(session.PlantSession):
    """PlantSession that notes the time from instantiate to the end of close (terminate, free)."""

    spans: list[float] = []

    def instantiate(self, start: float, stop: float) -> None:
        self._bench_started = time.perf_counter()
        super().instantiate(start, stop)

    def close(self) -> None:
        super().close()
        if hasattr(self, "_bench_started"):
            Timed.spans.append(time.perf_counter() - self._bench_started)


@contextlib.contextmanager
def loop_switch(python_loop: bool) -> Iterator[str]:
    """With python_loop, the compiled loop switched off (TOGGLE_COSIM_KERNEL=0) inside; yields
    the loop kind run.json must then report."""
    saved = os.environ.get("TOGGLE_COSIM_KERNEL")
    if python_loop:
        os.environ["TOGGLE_COSIM_KERNEL"] = "0"
    try:
        yield "python" if python_loop or not compiled_loop.kernel_available() else "compiled"
    finally:
        if python_loop:
            if saved is None:
                os.environ.pop("TOGGLE_COSIM_KERNEL", None)
            else:
                os.environ["TOGGLE_COSIM_KERNEL"] = saved


def full_loop(plant, run, python_loop: bool = False) -> dict:
    """One simulate(): per-step loop cost and three real-time factors. python_loop: with the
    compiled loop switched off (TOGGLE_COSIM_KERNEL=0)."""
    Timed.spans.clear()
    original, pair.PlantSession = pair.PlantSession, Timed  # the pair's fixed loop opens its session
    try:
        with loop_switch(python_loop) as expected:
            outcome = master.simulate(run, plant)
    finally:
        pair.PlantSession = original
    if not outcome.complete:
        raise RuntimeError(f"{run.label}: {outcome.reason}")
    if outcome.record["loop"]["kind"] != expected:  # measure the loop we say we measure, or stop
        raise RuntimeError(f"{run.label}: expected the {expected} loop, ran {outcome.record['loop']}")
    steps = outcome.trace.data.shape[0] - 1
    simulated = steps * run.T_s
    return {
        "per_step": outcome.loop_seconds / steps,
        "rtf_loop": simulated / outcome.loop_seconds,
        "rtf_inst": simulated / Timed.spans[-1],
        "rtf_simulate": simulated / outcome.wall_seconds,
        "u": outcome.trace.column("iq_ref").copy(),
        "outcome": outcome,
    }


class Table:
    """The rows of the printed table (sections, figures, lines of text) and the targets checked."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, ...]] = []
        self.checks: list[tuple[str, bool, str]] = []

    def section(self, title: str) -> None:
        self.rows.append(("section", title))

    def add(self, label: str, value: str, note: str = "") -> None:
        self.rows.append(("row", label, value, note))

    def text(self, line: str) -> None:
        self.rows.append(("text", line))

    def check(self, label: str, ok: bool, detail: str) -> None:
        self.checks.append((label, ok, detail))

    def print(self) -> None:
        width = max(len(r[1]) for r in self.rows if r[0] == "row") + 2
        vwidth = max(len(r[2]) for r in self.rows if r[0] == "row")
        for row in self.rows:
            if row[0] == "section":
                print(f"\n{row[1]}")
            elif row[0] == "text":
                print(f"  {row[1]}")
            else:
                _, label, value, note = row
                print(f"  {label:<{width}}{value:>{vwidth}}   {note}".rstrip())
        print("\nTargets")
        for label, ok, detail in self.checks:
            print(f"  [{'PASS' if ok else 'FAIL'}] {label}: {detail}")


def us(seconds: float) -> str:
    return f"{seconds * 1e6:.2f} us"
