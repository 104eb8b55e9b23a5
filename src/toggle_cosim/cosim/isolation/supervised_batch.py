"""Several supervised runs at once: up to `jobs` children (`supervision.SupervisedRun`), each
under its own time limit, their outcomes handed back in the order of the runs.

The runs of a command are independent (each plant in its own process, with its own FMU copy
and trace buffer), so on a machine with several cores they overlap; their traces are the same
bytes as one after the other. An interrupt kills every child still running: the runs that had
ended before it are handed back whole, in order, then the first one that had not comes out as
interrupted and nothing after it, so the caller writes what finished, then that run, and stops.
An interrupt never ends the batch as if it had run out of runs: when every run had ended, it is
raised after the last one.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from pathlib import Path

from toggle_cosim.cosim.isolation.supervision import SupervisedRun, wait_for
from toggle_cosim.cosim.outcome import RunOutcome


def default_jobs(runs: int) -> int:
    """One child per core this process may use, and no more than there are runs."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, runs))


def run_supervised(
    pairs: Sequence[tuple],
    *,
    jobs: int,
    time_limit: float | None = None,
    scratch: Path | None = None,
) -> Iterator[RunOutcome]:
    """Run each (run, plant) pair in a supervised child, at most `jobs` at a time, and yield the
    outcomes in the order of `pairs`. A (run, plant, checked) triple gives the run as the caller
    checked it (`checked.check_run`), which the run then uses, checking nothing again.

    Close the generator (or exhaust it) to release the children: closing it early, or an
    interrupt while it waits, kills the ones still running and removes their folders."""
    children: list = [None] * len(pairs)  # SupervisedRun while started and not yet handed back
    started = handed = 0
    interrupted = False

    def fill() -> None:  # start runs until `jobs` are under way past the first not handed back
        nonlocal started
        while started < len(pairs) and started - handed < max(1, jobs):
            run, plant, *checked = pairs[started]
            children[started] = SupervisedRun(
                run, plant, time_limit=time_limit, scratch=scratch, checked=next(iter(checked), None)
            )
            started += 1
            children[started - 1].start()

    def take_head() -> RunOutcome:  # the first run not handed back, as it stands
        nonlocal handed
        head = children[handed]
        head.close()
        children[handed] = None
        handed += 1
        return head.outcome()

    try:
        while handed < len(pairs):
            try:
                if interrupted:
                    raise KeyboardInterrupt
                fill()
                while not children[handed].done:
                    wait_for([c for c in children[handed:started] if c is not None])
            except KeyboardInterrupt:
                if children[handed] is None:  # not started yet: nothing of it to write
                    raise
                children[handed].stop()
                outcome = take_head()
                if outcome.interrupted:
                    yield outcome
                    return
                interrupted = True  # it had ended before the interrupt: hand it back whole, then stop at the next
                yield outcome
                continue
            outcome = take_head()
            try:
                fill()  # the next run starts before the caller writes this one's files
            except KeyboardInterrupt:
                interrupted = True  # this run is whole: hand it back, then stop at the next
            yield outcome
        if interrupted:  # every run had ended: the interrupt still ends the command
            raise KeyboardInterrupt
    finally:
        for child in children:
            if child is not None:
                child.stop()
                child.close()


__all__ = ["default_jobs", "run_supervised"]
