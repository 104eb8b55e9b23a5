"""What bench.py and system_bench.py share: the paper's runs, one simulate()'s loop cost
(`full_loop`: the built-in law's pair, run by the execution, the figure the system rows are
compared with) and the table the figures are printed in. Both scripts import it; system_bench.py imports nothing of bench.py, so
it runs alone, and bench.py imports system_bench.py for its section of the table."""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator
from pathlib import Path

from toggle_cosim.cosim import master
from toggle_cosim.cosim.execution import slaves, system_loop
from toggle_cosim.experiments.scenario import load_scenario

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"
PAPER = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")


def paper_runs() -> list:
    """Every variant of the paper's three scenarios (fig4, fig5, fig6)."""
    return [run for name in PAPER for run in load_scenario(SCENARIOS / f"{name}.yaml")]


@contextlib.contextmanager
def instance_spans(component: str) -> Iterator[list[float]]:
    """The seconds from instantiate to the end of close (terminate, free) of each instance of the
    FMU component `component` made inside (`slaves.FmuSlave`), in order."""
    spans: list[float] = []
    started: dict[int, float] = {}
    instantiate, close = slaves.FmuSlave.instantiate, slaves.FmuSlave.close

    def timed_instantiate(self: slaves.FmuSlave, t_end: float) -> None:
        if self.name == component:
            started[id(self)] = time.perf_counter()
        instantiate(self, t_end)

    def timed_close(self: slaves.FmuSlave, reuse: bool = False) -> None:
        close(self, reuse)
        if id(self) in started:
            spans.append(time.perf_counter() - started.pop(id(self)))

    slaves.FmuSlave.instantiate, slaves.FmuSlave.close = timed_instantiate, timed_close
    try:
        yield spans
    finally:
        slaves.FmuSlave.instantiate, slaves.FmuSlave.close = instantiate, close


@contextlib.contextmanager
def loop_switch(python_loop: bool) -> Iterator[str]:
    """With python_loop, the compiled loop switched off (TOGGLE_COSIM_KERNEL=0) inside; yields
    the loop kind run.json must then report."""
    saved = os.environ.get("TOGGLE_COSIM_KERNEL")
    if python_loop:
        os.environ["TOGGLE_COSIM_KERNEL"] = "0"
    try:
        yield "python" if python_loop or system_loop.system_library() is None else "compiled"
    finally:
        if python_loop:
            if saved is None:
                os.environ.pop("TOGGLE_COSIM_KERNEL", None)
            else:
                os.environ["TOGGLE_COSIM_KERNEL"] = saved


def full_loop(plant, run, python_loop: bool = False) -> dict:
    """One simulate() (the pair in the execution): per-step loop cost and three real-time
    factors. python_loop: with the compiled loop switched off (TOGGLE_COSIM_KERNEL=0)."""
    with instance_spans(run.system.plant) as spans, loop_switch(python_loop) as expected:
        outcome = master.check_and_simulate(run, plant)
    if not outcome.complete:
        raise RuntimeError(f"{run.label}: {outcome.reason}")
    if outcome.record["loop"]["kind"] != expected:  # measure the loop we say we measure, or stop
        raise RuntimeError(f"{run.label}: expected the {expected} loop, ran {outcome.record['loop']}")
    steps = outcome.trace.data.shape[0] - 1
    simulated = steps * run.T_s
    return {
        "per_step": outcome.loop_seconds / steps,
        "rtf_loop": simulated / outcome.loop_seconds,
        "rtf_inst": simulated / spans[-1],
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
