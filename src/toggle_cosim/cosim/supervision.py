"""Supervised runs: every co-simulation's plant runs in a child process, under a time limit.

    parent: trace buffer (a file-backed shared map) -> fork -> wait for the child's answer, its
            exit, the time limit or an interrupt -> the outcome, whatever happened
    child:  master.simulate writing straight into the shared buffer -> its outcome (without the
            trace) back through a pipe -> _exit

A segfault, abort, endless loop or huge allocation (the child's address space may grow by
TOGGLE_COSIM_PLANT_MEMORY, default 4 GiB) in the plant's native code ends the child,
not the command: the parent keeps the trace up to the last sample the child recorded (it is in
the shared buffer), writes the run as `failed` with the reason (the signal's name, "time limit
30 s exceeded", the exit status) and goes on with the next run. SIGINT/SIGTERM in the parent
kill the child at once (a plant stuck in C cannot ignore SIGKILL) and the run is `interrupted`.
The child dies with its parent (PR_SET_PDEATHSIG), and the FMU's unzipped copy lives in the
run's own temporary folder, which the parent removes on every path.

The trace buffer is a file in that folder that never has a name (O_TMPFILE), mapped shared (the
map, and the child's copy of it, outlive the descriptor), so a long run's trace lives in the
page cache backed by disk, not in memory, and nothing of it is left on disk whatever ends the
command. The folder's name carries the supervising process's id: a command killed by SIGKILL
cannot remove its folders (the unzipped FMU), so each command removes those of supervising
processes that no longer exist before it starts its own (`remove_stale_folders`).
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import gc
import io
import math
import mmap
import os
import pickle
import select
import shutil
import signal
import sys
import tempfile
import time as clock
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from toggle_cosim import interrupts
from toggle_cosim.cosim import master
from toggle_cosim.cosim import outcome as outcomes
from toggle_cosim.files.traces import Trace
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.runs.definition import Run

PLANT_MEMORY_DEFAULT = 4 << 30  # bytes a plant may allocate beyond the process as forked
TIME_LIMIT_FLOOR_S = 30.0  # the default wall-clock limit is max(30 s, 20 x t_end)
TIME_LIMIT_PER_SIMULATED_S = 20.0
_PR_SET_PDEATHSIG = 1
FOLDER_PREFIX = "toggle-cosim-run-"  # then the supervising process's id, "-", a random part


def remove_stale_folders(scratch: Path | None = None) -> list[Path]:
    """Remove the run folders of supervising processes that no longer exist (killed by SIGKILL:
    nothing else leaves one) in `scratch` (default: the temporary directory), if they are ours;
    the folders removed. A folder whose process may still live is left alone."""
    folder = Path(scratch) if scratch is not None else Path(tempfile.gettempdir())
    removed = []
    try:
        candidates = list(folder.glob(f"{FOLDER_PREFIX}*-*"))
    except OSError:
        return removed
    for path in candidates:
        pid_text = path.name[len(FOLDER_PREFIX) :].split("-", 1)[0]
        if not pid_text.isdigit() or int(pid_text) == os.getpid():
            continue
        try:
            if path.lstat().st_uid != os.getuid() or not path.is_dir():
                continue
            os.kill(int(pid_text), 0)
            continue  # that process exists (perhaps another command running now): leave it
        except ProcessLookupError:
            pass
        except (OSError, ValueError):
            continue  # not ours to judge (no permission to signal it, an odd name)
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path)
    return removed


def default_time_limit(t_end: float) -> float:
    """The wall-clock limit of a run that names none: max(30 s, 20 s per simulated second)."""
    return max(TIME_LIMIT_FLOOR_S, TIME_LIMIT_PER_SIMULATED_S * t_end)


def time_limit_of(run: Run, override: float | None = None) -> float:
    """--time-limit, else the scenario's time_limit key, else the default from t_end."""
    if override is not None:
        return float(override)
    own = run.resolved.get("time_limit")
    return float(own) if own is not None else default_time_limit(run.t_end)


def seconds_text(value: float) -> str:
    return f"{value:.0f} s" if value >= 10 else f"{value:.3g} s"


def die_with_parent(parent: int) -> None:
    with contextlib.suppress(Exception):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def plant_memory_limit() -> int:
    """TOGGLE_COSIM_PLANT_MEMORY (bytes, or with a K/M/G suffix), default 4 GiB."""
    text = os.environ.get("TOGGLE_COSIM_PLANT_MEMORY", "").strip().upper()
    if not text:
        return PLANT_MEMORY_DEFAULT
    scale = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}.get(text[-1], 1)
    try:
        return int(float(text.rstrip("KMG")) * scale)
    except ValueError:
        return PLANT_MEMORY_DEFAULT


def limit_memory() -> None:
    """The child's address space may grow by plant_memory_limit(): a plant that allocates without
    end gets NULL from malloc instead of taking the machine's memory."""
    with contextlib.suppress(Exception):
        import resource

        with open("/proc/self/statm") as stream:
            current = int(stream.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        wanted = current + plant_memory_limit()
        if hard != resource.RLIM_INFINITY:
            wanted = min(wanted, hard)
        resource.setrlimit(resource.RLIMIT_AS, (wanted, hard))


def warm_up() -> None:
    """Work each child would repeat, done once in the parent before forking: the run record's
    versions, the compiled loop, and the modules a child would otherwise import each time
    (`resource` for its memory limit, `urllib.parse` for the FMU's resource URI that fmpy
    makes, the solver statistics' reader): about 9 ms a child."""
    import resource  # noqa: F401
    import urllib.parse  # noqa: F401

    import toggle_cosim.plant.solver_statistics  # noqa: F401

    outcomes.installed_versions()
    with contextlib.suppress(Exception):
        from toggle_cosim.cosim.compiled_loop import kernel_library

        kernel_library()


def fork_child(child: Callable[[int], None], known: Callable[[int], None]) -> None:
    """Fork a plant process: the parent's warm-up done and its streams flushed first, the fork
    inside `starting_children`. `known(pid)` runs in the parent before an interrupt can act (so
    whoever stops the child knows it); `child(parent_pid)` runs in the child and never returns."""
    warm_up()
    sys.stdout.flush()
    sys.stderr.flush()
    parent = os.getpid()
    with warnings.catch_warnings(), interrupts.starting_children():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads (pytest, Dask)
        pid = os.fork()
        if pid == 0:  # the child never leaves this block
            try:
                child(parent)
            finally:
                os._exit(4)
        known(pid)


def _child(
    run: Run,
    plant: PlantInterface,
    buffer: np.ndarray,
    progress_slot: np.ndarray | None,
    workdir: Path,
    write_fd: int,
    parent: int,
    capture_log: bool,
) -> None:
    """The child's whole life: run, send the outcome (no trace) back, exit without cleanup."""
    code = 0
    try:
        gc.disable()  # a collection would touch, and so copy, the whole inherited heap; the child lives briefly
        faulthandler.disable()  # a plant's crash is reported by the parent, not dumped here
        interrupts.as_child()  # the parent decides about interrupts
        die_with_parent(parent)
        limit_memory()
        tempfile.tempdir = str(workdir)  # the FMU's unzipped copy goes into the run's folder
        log = None
        if capture_log:
            log = io.StringIO()
            sys.stdout = log

        def progress(fraction: float) -> None:
            progress_slot[0] = fraction

        outcome = master.simulate(run, plant, progress if progress_slot is not None else None, buffer=buffer)
        answer = (
            "outcome",
            outcome.complete,
            outcome.reason,
            outcome.wall_seconds,
            outcome.loop_seconds,
            outcome.summary,
            outcome.record,
            outcome.interrupted,
            log.getvalue() if log else "",
        )
    except BaseException as error:  # noqa: BLE001 - everything goes back to the parent
        answer = ("error", " ".join(f"{type(error).__name__}: {error}".split()))
        code = 3
    try:
        data = pickle.dumps(answer)
        view = memoryview(data)
        while view:
            view = view[os.write(write_fd, view) :]
        sys.stdout.flush()
        sys.__stdout__.flush()
        sys.stderr.flush()
    except BaseException:  # noqa: BLE001
        code = 4
    os._exit(code)


def rows_recorded(buffer: np.ndarray) -> int:
    """Samples the child finished: the leading rows whose last column (written last) is set."""
    if buffer.shape[0] == 0:
        return 0
    unset = np.flatnonzero(np.isnan(buffer[:, -1]))
    return int(unset[0]) if unset.size else buffer.shape[0]


def _map_buffer(folder: Path, rows: int, columns: int) -> tuple[mmap.mmap, np.ndarray]:
    """A shared map of rows x columns doubles, NaN-filled, backed by a file in `folder` that has
    no name: O_TMPFILE on Linux (TemporaryFile falls back to create-and-unlink elsewhere), so no
    moment exists at which a kill could leave it behind."""
    size = max(rows * columns * 8, 8)
    with tempfile.TemporaryFile(dir=folder) as stream:
        stream.truncate(size)
        mapped = mmap.mmap(stream.fileno(), size, mmap.MAP_SHARED, mmap.PROT_READ | mmap.PROT_WRITE)
    array = np.frombuffer(mapped, dtype=np.float64, count=rows * columns).reshape(rows, columns)
    array.fill(np.nan)
    return mapped, array


class SupervisedRun:
    """One run in its own child process, from fork to outcome, driven by the caller's loop:

        child = SupervisedRun(run, plant, ...)
        child.start()                             # maps the trace buffer and forks
        while not child.done: select on child.watched() until child.deadline, then
            child.service(ready)                  # reads the answer, notices the exit, the limit
        child.outcome()                           # the RunOutcome, whatever happened

    `stop()` kills a child that is still running (an interrupt) and `close()` releases its
    descriptors and folder; both are safe to call at any moment and more than once. Several
    children may run at once (`supervised_batch`), each under its own deadline."""

    def __init__(
        self,
        run: Run,
        plant: PlantInterface,
        *,
        time_limit: float | None = None,
        scratch: Path | None = None,
        capture_log: bool = False,
        with_progress: bool = False,
    ) -> None:
        self.run = run
        self.plant = plant
        self.limit = time_limit_of(run, time_limit)
        self.started = clock.perf_counter()
        self.names = master.trace_names(plant)
        self.pid = -1
        self.status: int | None = None
        self.reason: str | None = None
        self.interrupted = False
        self.done = False
        self._read_fd = self._pidfd = -1
        self._chunks: list[bytes] = []
        self._watch: list[int] = []
        self.buffer = np.full((0, len(self.names)), np.nan)
        self.progress_slot: np.ndarray | None = None
        self.deadline = math.inf
        self._capture_log = capture_log
        self._with_progress = with_progress
        self._workdir = Path(tempfile.mkdtemp(prefix=f"{FOLDER_PREFIX}{os.getpid()}-", dir=scratch))

    def start(self) -> None:
        """Map the trace buffer and fork the child; its deadline runs from here."""
        try:
            self._fork()
        except BaseException:
            self.stop()
            raise

    def _fork(self) -> None:
        _, self.buffer = _map_buffer(self._workdir, self.run.steps + 1, len(self.names))
        if self._with_progress:
            self.progress_slot = np.frombuffer(mmap.mmap(-1, 8), dtype=np.float64)
        read_fd, write_fd = os.pipe()
        self._read_fd = read_fd

        def child(parent: int) -> None:
            os.close(read_fd)
            _child(
                self.run,
                self.plant,
                self.buffer,
                self.progress_slot,
                self._workdir,
                write_fd,
                parent,
                self._capture_log,
            )

        try:
            fork_child(child, lambda pid: setattr(self, "pid", pid))
        finally:
            os.close(write_fd)
        self.deadline = clock.monotonic() + self.limit
        try:
            self._pidfd = os.pidfd_open(self.pid)
        except (AttributeError, OSError):
            self._pidfd = -1
        self._watch = [self._read_fd] + ([self._pidfd] if self._pidfd >= 0 else [])

    def watched(self) -> list[int]:
        """The descriptors to select on: the answer pipe, and the child's pidfd where there is one."""
        return [] if self.done else list(self._watch)

    @property
    def polls(self) -> bool:
        """True without a pidfd: the caller must call service() now and then (every 0.1 s)."""
        return self._pidfd < 0

    def progress(self) -> float:
        return float(self.progress_slot[0]) if self.progress_slot is not None else 0.0

    def service(self, ready: set[int] | list[int]) -> bool:
        """Read what the child wrote, notice its exit or the passing of its deadline; True once done."""
        if self.done:
            return True
        if clock.monotonic() >= self.deadline:
            self.reason = f"time limit {seconds_text(self.limit)} exceeded"
            self._kill()
            return True
        if self._read_fd in ready and self._read_fd in self._watch:
            chunk = os.read(self._read_fd, 1 << 16)
            if chunk:
                self._chunks.append(chunk)
            else:
                self._watch.remove(self._read_fd)
        if self._pidfd in ready or self._pidfd < 0:
            finished, got = os.waitpid(self.pid, os.WNOHANG)
            if finished:
                self.status = got
                while self._read_fd in self._watch and (chunk := os.read(self._read_fd, 1 << 16)):
                    self._chunks.append(chunk)  # what the child wrote before select saw its exit
                self.done = True
        return self.done

    def _kill(self) -> None:
        if self.pid > 0 and self.status is None:
            with contextlib.suppress(OSError):
                os.kill(self.pid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                _, self.status = os.waitpid(self.pid, 0)
        self.done = True

    def stop(self, reason: str = "interrupted (SIGINT or SIGTERM)") -> None:
        """Kill the child if it still runs: the run becomes interrupted with `reason`."""
        if not self.done:
            self.interrupted = True
            self.reason = reason
        self._kill()

    def close(self) -> None:
        for fd in (self._read_fd, self._pidfd):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._read_fd = self._pidfd = -1
        shutil.rmtree(self._workdir, ignore_errors=True)  # the map outlives its file

    def outcome(self) -> outcomes.RunOutcome:
        """The run's outcome (call once done, after close()): the child's, or failed/interrupted
        with the reason and the trace up to the last sample the child recorded."""
        run, plant = self.run, self.plant
        answer = _answer(self._chunks)
        rows = rows_recorded(self.buffer)
        trace = Trace(self.names, self.buffer[:rows])
        wall = clock.perf_counter() - self.started
        reason = self.reason
        if answer is not None and answer[0] == "outcome" and reason is None:
            _, complete, child_reason, _, loop_s, summary, record, child_interrupted, log = answer
            if log:
                sys.stdout.write(log)
            record["wall_time_s"] = wall
            # the trace is a view of the map, which it keeps alive
            return outcomes.RunOutcome(
                run, trace, complete, child_reason, wall, loop_s, summary, record, child_interrupted
            )
        if reason is None:
            reason = self._exit_reason(answer)
        at = f" at t = {max(rows - 1, 0) * run.T_s:.6g} s" if rows else " before the first sample"
        reason = f"{reason}{at}"
        status_word = "interrupted" if self.interrupted else "failed"
        record = outcomes.run_record(run, plant, status_word, reason, rows, wall, wall)
        return outcomes.RunOutcome(run, trace, False, reason, wall, wall, None, record, self.interrupted)

    def _exit_reason(self, answer: tuple | None) -> str:
        if answer is not None and answer[0] == "error":
            return f"the plant could not be run: {answer[1]}"
        return exit_reason(self.status)


def exit_reason(status: int | None) -> str:
    """Why a plant process ended without answering, from its wait status."""
    if status is not None and os.WIFSIGNALED(status):
        number = os.WTERMSIG(status)
        name = signal.Signals(number).name if number in set(signal.Signals) else f"signal {number}"
        return f"the plant process was killed by {name}"
    if status is not None:
        return f"the plant process exited with status {os.waitstatus_to_exitcode(status)} before the run ended"
    return "the plant process ended without an answer"


def wait_for(children: list[SupervisedRun], poll: float | None = None) -> None:
    """Block until one of `children` (not yet done) has news or reaches its deadline, and
    service them all. `poll` caps the wait (progress display)."""
    active = [child for child in children if not child.done]
    if not active:
        return
    wait = max(0.0, min(child.deadline for child in active) - clock.monotonic())
    if poll is not None or any(child.polls for child in active):
        wait = min(wait, poll if poll is not None else 0.1)
    ready, _, _ = select.select([fd for child in active for fd in child.watched()], [], [], wait)
    for child in active:
        child.service(ready)


def simulate_supervised(
    run: Run,
    plant: PlantInterface,
    *,
    time_limit: float | None = None,
    progress: Callable[[float], None] | None = None,
    scratch: Path | None = None,
    capture_log: bool = False,
) -> outcomes.RunOutcome:
    """`master.simulate` in a supervised child process; never raises for anything the plant does.

    An interrupt (KeyboardInterrupt) during the run kills the child and returns the run as
    interrupted (`outcome.interrupted`); the caller stops after writing it."""
    child = SupervisedRun(
        run, plant, time_limit=time_limit, scratch=scratch, capture_log=capture_log, with_progress=progress is not None
    )
    try:
        child.start()
        while not child.done:
            wait_for([child], 0.1 if progress is not None else None)
            if progress is not None:
                progress(child.progress())
    except KeyboardInterrupt:
        pass  # stopped below: the run comes back as interrupted
    finally:
        child.stop()  # kills a child still running (an interrupt); nothing once it is done
        child.close()
    return child.outcome()


def _answer(chunks: list[bytes]) -> tuple | None:
    if not chunks:
        return None
    try:
        answer = pickle.loads(b"".join(chunks))
    except Exception:  # noqa: BLE001 - a child that died while writing
        return None
    return answer if isinstance(answer, tuple) and answer else None
