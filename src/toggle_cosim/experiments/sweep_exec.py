"""Running sweep cases: a local process pool (all cores by default) or an existing Dask
distributed cluster (`scheduler="tcp://host:8786"`); no scheduling of our own. Each finished
case's row is handed to `on_row` in this process as it arrives."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from toggle_cosim import interrupts
from toggle_cosim.experiments.sweep_spec import Case, SweepError
from toggle_cosim.experiments.sweep_worker import crash_row, file_sha256_cached, run_case

_slot: int = -1


def _pool_init(slots: Any, counter: Any) -> None:
    """Pool worker start: Ctrl-C is the parent's to handle; take a slot to report the running case."""
    global _slots, _slot
    interrupts.as_child()
    with counter.get_lock():
        _slot = counter.value
        counter.value += 1
    _slots = slots


def _pool_task(
    case: Mapping[str, Any], fmu: str, fmu_sha256: str | None, time_limit: float | None = None
) -> dict[str, Any]:
    if _slots is not None and 0 <= _slot < len(_slots):
        _slots[_slot] = case["index"]
    try:
        return run_case(case, fmu, fmu_sha256, time_limit=time_limit)
    finally:
        if _slots is not None and 0 <= _slot < len(_slots):
            _slots[_slot] = -1


def _kill_workers(pool: ProcessPoolExecutor) -> None:
    """End the pool's workers now (an interrupt): their running cases' plants die with them."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        with contextlib.suppress(Exception):
            process.kill()


def _run_pool(
    cases: Sequence[Case],
    fmu: str,
    sha: str,
    workers: int,
    on_row: Callable[[dict[str, Any]], None],
    time_limit: float | None = None,
) -> None:
    """Local process pool. A worker process that dies (a crash inside the FMU) breaks the pool:
    the cases that were running then are re-run one at a time to find the one that crashes, which
    is recorded as failed; the others are resubmitted."""
    context = multiprocessing.get_context("spawn")
    pending = list(cases)
    isolate: list[Case] = []
    while pending or isolate:
        if isolate:
            batch, size = [isolate.pop(0)], 1
        else:
            batch, pending, size = pending, [], max(1, min(workers, len(pending)))
        slots = context.Array("q", [-1] * size, lock=False)
        counter = context.Value("i", 0)
        pool = ProcessPoolExecutor(
            max_workers=size, mp_context=context, initializer=_pool_init, initargs=(slots, counter)
        )
        broken: list[Case] = []
        running_at_break: set[int] = set()
        try:
            # submit() starts the workers: an interrupt inside it would leave a child half launched
            # (not yet known to the pool, so never killed) to fail on its own, with a traceback
            with interrupts.starting_children():
                futures = {pool.submit(_pool_task, case.payload(), fmu, sha, time_limit): case for case in batch}
            remaining = set(futures)
            while remaining:
                done, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for future in done:
                    try:
                        row = future.result()
                    except BrokenProcessPool:
                        if not running_at_break:
                            running_at_break = {int(i) for i in slots if i >= 0} or {-2}
                        broken.append(futures[future])
                        continue
                    except Exception as error:  # noqa: BLE001 - pickling and the like
                        row = crash_row(futures[future], sha, " ".join(f"{type(error).__name__}: {error}".split()))
                    on_row(row)
        except BaseException:
            _kill_workers(pool)
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
        if broken:
            if size == 1 and len(batch) == 1:
                on_row(crash_row(batch[0], sha, "the worker process died running this case (a crash in the FMU?)"))
                continue
            suspects = [c for c in broken if c.index in running_at_break] or broken
            isolate.extend(suspects)
            pending = [c for c in broken if c not in suspects] + pending


def connect(scheduler: str) -> Any:
    """A client of the Dask distributed cluster at `scheduler` (SweepError if it cannot be reached;
    the time allowed is dask's distributed.comm.timeouts.connect)."""
    try:
        from distributed import Client
    except ImportError as error:  # pragma: no cover - a declared dependency
        raise SweepError(f"--scheduler needs the 'distributed' package ({error})") from error
    try:
        return Client(scheduler, set_as_default=False)
    except Exception as error:  # noqa: BLE001 - OSError, TimeoutError, ValueError for a bad address
        raise SweepError(
            f"cannot connect to the Dask scheduler at {scheduler} ({' '.join(str(error).split())})"
        ) from error


def _run_dask(
    cases: Sequence[Case],
    fmu: str,
    sha: str,
    client: Any,
    on_row: Callable[[dict[str, Any]], None],
    time_limit: float | None = None,
) -> None:
    """An existing Dask distributed cluster: submit every case, collect as they complete. The FMU
    travels with the tasks: the workers need toggle-cosim installed, not the project's files."""
    from distributed import as_completed

    # the FMU's bytes go along (once per worker), for workers that do not share this file system
    fmu_data = client.scatter(Path(fmu).read_bytes(), broadcast=True, hash=False)
    futures = {}
    for case in cases:
        future = client.submit(
            run_case,
            case.payload(),
            fmu,
            sha,
            fmu_data,
            time_limit,
            key=f"toggle-cosim-case-{case.case_id}",
            pure=False,
        )
        futures[future] = case
    try:
        for future in as_completed(futures, loop=client.loop):
            case = futures[future]
            try:
                row = future.result()
            except Exception as error:  # noqa: BLE001 - KilledWorker, a lost connection, ...
                reason = " ".join(f"{type(error).__name__}: {error}".split())
                row = crash_row(case, sha, f"the Dask task failed: {reason}")
            on_row(row)
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel(list(futures))
        raise
    finally:
        with contextlib.suppress(Exception):
            client.cancel([fmu_data])


def execute(
    cases: Sequence[Case],
    fmu: Path,
    scheduler: str | None,
    workers: int | None,
    on_row: Callable[[dict[str, Any]], None],
    fmu_sha256: str | None = None,
    client: Any = None,
    time_limit: float | None = None,
) -> None:
    """Run `cases` on the chosen backend and call `on_row(row)` in this process as each finishes:
    the Dask cluster at `scheduler` (or an open `client` of one), else a local process pool of
    `workers` processes (default: all cores)."""
    if not cases:
        return
    fmu = Path(fmu).resolve()
    if fmu_sha256 is None:
        fmu_sha256 = file_sha256_cached(fmu)
    if client is not None:
        _run_dask(cases, str(fmu), fmu_sha256, client, on_row, time_limit)
    elif scheduler:
        own = connect(scheduler)
        try:
            _run_dask(cases, str(fmu), fmu_sha256, own, on_row, time_limit)
        finally:
            with contextlib.suppress(Exception):
                own.close()
    else:
        _run_pool(cases, str(fmu), fmu_sha256, workers or os.cpu_count() or 1, on_row, time_limit)
