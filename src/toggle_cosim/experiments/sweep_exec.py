"""Running sweep cases: local workers (all cores by default) or an existing Dask distributed
cluster (`scheduler="tcp://host:8786"`). Each worker keeps the plant loaded and runs case after
case (`sweep_worker`); each finished case's row is handed to `on_row(row, trace)` in this
process as it arrives (`trace`: the case's samples with keep_traces, else None).

Local workers are plant hosts this process forks and supervises itself: a case that crashes,
aborts or hangs its host (or whose host is killed from outside) is a failed row, the host is
replaced, the other cases go on. On a Dask cluster the cases go in chunks, a few per worker
thread at a time; a chunk whose worker or scheduler is lost is not recorded (its cases are "not
run": a re-run does them), and `DaskLoss` says how many. Interrupts are noted and acted on here,
between polls, never raised inside Dask's or the standard library's waiting code."""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim import interrupts
from toggle_cosim.experiments.sweep_spec import Case, SweepError
from toggle_cosim.experiments.sweep_worker import CaseRunner, CheckedCase, case_samples, crash_row, run_cases

OnRow = Callable[[dict[str, Any], "np.ndarray | None"], None]
CONNECT_TIMEOUT_S = 20.0  # a scheduler that does not answer as Dask within this is not one
CHUNK_MAX = 32  # cases a Dask task runs at most
IN_FLIGHT_PER_THREAD = 3  # Dask tasks submitted ahead per worker thread
RESULT_TIMEOUT_S = 30.0


@dataclass
class DaskLoss:
    """Cases a Dask run could not finish because a worker or the scheduler went away."""

    cases: int = 0
    reasons: list[str] = field(default_factory=list)


def _run_pool(
    cases: Sequence[Case],
    plant: Any,
    sha: str,
    workers: int,
    on_row: OnRow,
    time_limit: float | None = None,
    keep_traces: bool = False,
    checked: Mapping[str, CheckedCase] | None = None,
) -> None:
    """Local plant hosts, `workers` of them, each fed the next case as soon as it is free, the
    case as the sweep checked it before (`checked`, by case id) or as its runner checks it."""
    from toggle_cosim.cosim.isolation.plant_host import wait_for_hosts

    rows = max((case_samples(c.payload()) for c in cases), default=1)
    runners = [
        CaseRunner(plant, sha, rows=rows, time_limit=time_limit, keep_traces=keep_traces)
        for _ in range(max(1, min(workers, len(cases))))
    ]
    queue: Iterator[Case] = iter(cases)
    try:
        while True:
            for runner in runners:
                if not runner.busy and (case := next(queue, None)) is not None:
                    runner.submit(case.payload(), (checked or {}).get(case.case_id))
            busy = {runner.host: runner for runner in runners if runner.busy}
            if not busy:
                return
            for host, answer in wait_for_hosts(list(busy)):
                row, trace = busy[host].service(answer)
                on_row(row, trace)
    finally:
        with interrupts.deferred():  # an interrupt: the hosts and their cases in flight end now, all of them
            for runner in runners:
                runner.close()


def _connect_timeout() -> float:
    """CONNECT_TIMEOUT_S, or dask's distributed.comm.timeouts.connect if that is shorter."""
    with contextlib.suppress(Exception):
        import dask
        from dask.utils import parse_timedelta

        return min(CONNECT_TIMEOUT_S, float(parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"))))
    return CONNECT_TIMEOUT_S


def connect(scheduler: str, timeout: float | None = None) -> Any:
    """A client of the Dask distributed cluster at `scheduler`; SweepError within about `timeout`
    seconds (`_connect_timeout`) if there is none: nothing listening, a service that is not Dask
    (an HTTP server), one that never answers. The connection is made on a helper thread and
    waited for here, so an interrupt meanwhile ends the command at once."""
    try:
        from distributed import Client
    except ImportError as error:
        raise SweepError(
            f"--scheduler needs the 'distributed' package ({' '.join(str(error).split())}); install toggle-cosim[sweep]"
        ) from error
    import threading

    timeout = _connect_timeout() if timeout is None else timeout

    outcome: dict[str, Any] = {}

    def attempt() -> None:
        try:
            outcome["client"] = Client(scheduler, set_as_default=False, timeout=f"{timeout}s")
        except BaseException as error:  # noqa: BLE001 - reported below
            outcome["error"] = error

    worker = threading.Thread(target=attempt, name="toggle-cosim-dask-connect", daemon=True)
    worker.start()
    deadline = time.monotonic() + timeout + 1
    while worker.is_alive() and time.monotonic() < deadline:
        worker.join(0.05)
    if "client" in outcome:
        return outcome["client"]
    error = outcome.get("error")
    if error is None:
        detail = f"no answer as a Dask scheduler within {timeout:.0f} s: is it one?"
    else:
        detail = " ".join(f"{type(error).__name__}: {error}".split())
        if isinstance(error, (TimeoutError, OSError)) and "timed out" in detail.lower():
            detail = f"no answer as a Dask scheduler within {timeout:.0f} s: is it one? ({detail})"
    raise SweepError(f"cannot connect to the Dask scheduler at {scheduler} ({detail})")


def _chunks(cases: Sequence[Case], threads: int) -> Iterator[list[Case]]:
    size = max(1, min(CHUNK_MAX, math.ceil(len(cases) / max(1, threads * 4))))
    for start in range(0, len(cases), size):
        yield list(cases[start : start + size])


def _threads(client: Any) -> int:
    with contextlib.suppress(Exception):
        return max(1, sum(client.nthreads().values()))
    return 1


def _run_dask(
    cases: Sequence[Case],
    fmu: str,
    sha: str,
    client: Any,
    on_row: OnRow,
    time_limit: float | None = None,
    keep_traces: bool = False,
) -> DaskLoss:
    """An existing Dask cluster: the cases in chunks, each run by a worker thread's plant host,
    a bounded number in flight. The FMU travels with the tasks (once per worker): the workers
    need toggle-cosim installed, not the project's files."""
    import logging

    loss = DaskLoss()
    threads = _threads(client)
    quiet = logging.getLogger("distributed.client")  # its reconnection errors: DaskLoss says what happened
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)
    with interrupts.deferred():
        fmu_data = client.scatter(Path(fmu).read_bytes(), broadcast=True, hash=False)
    chunks = _chunks(cases, threads)
    running: dict[Any, list[Case]] = {}
    serial = 0

    def submit_more() -> None:
        nonlocal serial
        while len(running) < threads * IN_FLIGHT_PER_THREAD and (chunk := next(chunks, None)) is not None:
            serial += 1
            with interrupts.deferred():
                future = client.submit(
                    run_cases,
                    [case.payload() for case in chunk],
                    fmu,
                    sha,
                    fmu_data,
                    time_limit,
                    keep_traces,
                    key=f"toggle-cosim-cases-{chunk[0].case_id}-{serial}",
                    pure=False,
                )
            running[future] = chunk

    reconnecting_since: float | None = None
    try:
        submit_more()
        while running:
            finished = [f for f in running if f.status in ("finished", "error", "cancelled")]
            if not finished:
                status = client.status
                if status != "running":  # the scheduler went away: Dask tries to reconnect for a while
                    reconnecting_since = reconnecting_since or time.monotonic()
                    if status != "connecting" or time.monotonic() - reconnecting_since > _connect_timeout():
                        raise _Lost(f"the client lost the scheduler (status {status})")
                else:
                    reconnecting_since = None
                time.sleep(0.02)  # our own wait: an interrupt lands here, never inside Dask
                continue
            for future in finished:
                chunk = running.pop(future)
                try:
                    with interrupts.deferred():
                        results = future.result(timeout=RESULT_TIMEOUT_S)
                except Exception as error:  # noqa: BLE001 - KilledWorker, CancelledError, a lost connection
                    reason = _one_line(error)
                    if not _is_loss(error):  # the task itself raised on a worker: its cases failed, for this reason
                        results = [(crash_row(case, sha, f"on a Dask worker: {reason}"), None) for case in chunk]
                    else:
                        loss.cases += len(chunk)
                        loss.reasons.append(reason)
                        continue
                for row, trace in results:
                    on_row(row, trace)
            submit_more()
    except _Lost as lost:
        loss.reasons.append(str(lost))
        loss.cases += sum(len(chunk) for chunk in running.values()) + sum(len(chunk) for chunk in chunks)
    finally:
        with contextlib.suppress(Exception), interrupts.deferred():
            client.cancel([*running, fmu_data])
        quiet.setLevel(level)
    return loss


class _Lost(Exception):
    pass


REASON_CHARACTERS = 2000  # a reason longer than this is cut, and says so


def _one_line(error: BaseException) -> str:
    """The error as one line, whole up to REASON_CHARACTERS (never cut mid-sentence unsaid)."""
    text = " ".join(f"{type(error).__name__}: {error}".split())
    return text if len(text) <= REASON_CHARACTERS else text[:REASON_CHARACTERS] + " [... cut]"


def _is_loss(error: BaseException) -> bool:
    """True for a worker or the scheduler gone (the cases did not run: a re-run does them), False
    for an exception the task raised (the cases failed, and a re-run would fail them again)."""
    import asyncio
    import concurrent.futures

    names = {cls.__name__ for cls in type(error).__mro__}
    return bool(names & {"KilledWorker", "CommClosedError", "CancelledError", "FutureCancelledError"}) or isinstance(
        error, (concurrent.futures.CancelledError, asyncio.CancelledError, TimeoutError, ConnectionError)
    )


def execute(
    cases: Sequence[Case],
    fmu: Path,
    scheduler: str | None,
    workers: int | None,
    on_row: OnRow,
    fmu_sha256: str | None = None,
    client: Any = None,
    time_limit: float | None = None,
    keep_traces: bool = False,
    plant: Any = None,
    checked: Mapping[str, CheckedCase] | None = None,
) -> DaskLoss:
    """Run `cases` on the chosen backend and call `on_row(row, trace)` in this process as each
    finishes: the Dask cluster at `scheduler` (or an open `client` of one), else `workers` local
    plant hosts (default: all cores). Each case is checked once, by the process that drives its
    host (here, or a Dask worker), or given checked (`checked`, by case id: local hosts only).
    The cases a Dask cluster lost (not run) come back."""
    if not cases:
        return DaskLoss()
    fmu = Path(fmu).resolve()
    if plant is None:
        from toggle_cosim.plant.contract import check_plant

        plant = check_plant(fmu)
    sha = fmu_sha256 or plant.sha256
    if client is not None:
        return _run_dask(cases, str(fmu), sha, client, on_row, time_limit, keep_traces)
    if scheduler:
        own = connect(scheduler)
        try:
            return _run_dask(cases, str(fmu), sha, own, on_row, time_limit, keep_traces)
        finally:
            with contextlib.suppress(Exception):
                own.close()
    _run_pool(cases, plant, sha, workers or os.cpu_count() or 1, on_row, time_limit, keep_traces, checked)
    return DaskLoss()
