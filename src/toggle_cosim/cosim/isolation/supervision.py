"""Supervised runs: every co-simulation's plant runs in a child process, under a time limit.

    parent: trace buffer (a file-backed shared map) -> fork -> wait for the child's answer, its
            exit, the time limit or an interrupt -> the outcome, whatever happened
    child:  master.simulate writing straight into the shared buffer -> its outcome (without the
            trace) back through a pipe -> _exit

A segfault, abort, endless loop or huge allocation (the child's address space may grow by
TOGGLE_COSIM_PLANT_MEMORY, default 4 GiB: `limits`) in the plant's native code ends the child,
not the command: the parent keeps the trace up to the last sample the child recorded (it is in
the shared buffer), writes the run as `failed` with the reason (the signal's name, "time limit
30 s exceeded", the exit status) and goes on with the next run. SIGINT/SIGTERM in the parent
kill the child at once (a plant stuck in C cannot ignore SIGKILL) and the run is `interrupted`.
The child dies with its parent (PR_SET_PDEATHSIG), and the FMU's unzipped copy lives in the
run's own temporary folder, which the parent removes on every path. Processes the plant starts
end with the run (`process_tree`: the child leads its own group, adopts orphans and runs the
plant in a grandchild it keeps, so even a crashed plant's daemons are found; the tree is killed
when the plant ends or the run reaches its limit), and the parent never waits on the pipe
alone, which a helper forked without exec holds open.

The trace buffer is a file in that folder that never has a name (O_TMPFILE), mapped shared (the
map, and the child's copy of it, outlive the descriptor), so a long run's trace lives in the
page cache backed by disk, not in memory, and nothing of it is left on disk whatever ends the
command. Its blocks are allocated before the fork (no SIGBUS on a full disk: the run fails
alone, naming the folder), and the map's descriptor goes with its last view
(`RunOutcome.detached` once the run's files are written). The folder's name carries the
supervising process's id: a command killed by SIGKILL cannot remove its folders (the unzipped
FMU), so each command removes those of supervising processes that no longer exist before it
starts its own (`remove_stale_folders`).
"""

from __future__ import annotations

import contextlib
import faulthandler
import functools
import gc
import math
import mmap
import os
import pickle
import shutil
import struct
import sys
import tempfile
import time as clock
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from toggle_cosim import interrupts, limits, process_tree
from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import Controller, ControllerError
from toggle_cosim.cosim import master
from toggle_cosim.cosim import outcome as outcomes
from toggle_cosim.cosim.checked import CheckedRun, SystemError_, built, check_run, component_names
from toggle_cosim.cosim.controllers import controller_record, user_controller
from toggle_cosim.cosim.figures import run_figures
from toggle_cosim.cosim.isolation.exit_reasons import (
    building_reason,
    component_reason,
    component_words,
    controller_words,
    ended_cleanly,
    exit_reason,
    in_controller_reason,
    stopped_in_controller,
)
from toggle_cosim.files.traces import Trace
from toggle_cosim.messages import bounded_text, error_text
from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.relay import OutputRelay
from toggle_cosim.runs.definition import Run

TIME_LIMIT_FLOOR_S = 30.0  # the default wall-clock limit is max(30 s, 20 x t_end)
TIME_LIMIT_PER_SIMULATED_S = 20.0
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


@contextlib.contextmanager
def in_process_folder(scratch: Path | None = None) -> Iterator[Path]:
    """For a run in this process (`simulate(supervised=False)`, TOGGLE_COSIM_SUPERVISE=0): a run
    folder named as a supervised run's (so that, if a plant's crash ends this process, the next
    command's `remove_stale_folders` removes it), where the FMUs are unzipped while the block runs
    (`tempfile.tempdir`, restored after), removed when it ends."""
    remove_stale_folders(scratch)
    folder = Path(tempfile.mkdtemp(prefix=f"{FOLDER_PREFIX}{os.getpid()}-", dir=scratch))
    previous = tempfile.tempdir
    tempfile.tempdir = str(folder)
    try:
        yield folder
    finally:
        tempfile.tempdir = previous
        shutil.rmtree(folder, ignore_errors=True)


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


def limit_memory() -> None:
    """The child's address space may grow by `limits.plant_memory()` (checked by the command
    before any run, `limits.check_environment`): a plant that allocates without
    end gets NULL from malloc instead of taking the machine's memory. A bad value raises (the
    run fails, naming the variable) rather than leaving the plant without a limit."""
    allowed = limits.plant_memory()
    with contextlib.suppress(Exception):
        import resource

        with open("/proc/self/statm") as stream:
            current = int(stream.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        wanted = current + allowed
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
        from toggle_cosim.cosim.execution.system_loop import system_library as kernel_library

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
        process_tree.adopt(pid)  # it leads its own group (the child does the same)
        known(pid)


def _child(parent: int, plant_process: Callable[[], None]) -> None:
    """The child's whole life: lead its own group and adopt orphans, then (`run_kept`) run the
    plant in a grandchild, end whatever the plant started once that has ended, and end as it
    did (a segfault in the plant is the child's segfault for the parent)."""
    try:
        gc.disable()  # a collection would touch, and so copy, the whole inherited heap; the child lives briefly
        faulthandler.disable()  # a plant's crash is reported by the parent, not dumped here
        interrupts.as_child()  # the parent decides about interrupts
        process_tree.become_leader()  # its own group, and the adoptive parent of its helpers' orphans
        process_tree.die_with(parent)
    except BaseException:  # noqa: BLE001
        os._exit(3)
    process_tree.run_kept(plant_process)


_FRAME = struct.Struct("<Q")  # the length of the pickled message that follows on the answer pipe


def _send(fd: int, message: tuple) -> None:
    data = pickle.dumps(message)
    view = memoryview(_FRAME.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _messages(chunks: list[bytes]) -> list[tuple]:
    """The whole messages the child sent, in order (a message cut short by its death is left out)."""
    data, found, at = b"".join(chunks), [], 0
    while at + _FRAME.size <= len(data):
        size = _FRAME.unpack_from(data, at)[0]
        if at + _FRAME.size + size > len(data):
            break
        try:
            message = pickle.loads(data[at + _FRAME.size : at + _FRAME.size + size])
        except Exception:  # noqa: BLE001 - a child that died while writing
            break
        if isinstance(message, tuple) and message:
            found.append(message)
        at += _FRAME.size + size
    return found


def _build_controller(checked: CheckedRun, buffer_fd: int, write_fd: int) -> tuple[CheckedRun, np.ndarray | None]:
    """In the child: the run's controller.python built (its module imported, its factory called)
    and what only that instance tells checked (its diagnostics, and with them the connections,
    the plan and the columns: `checked.built`); its trace columns and record sent to the parent
    ("columns"), and the trace buffer sized for them in the file the parent opened
    (`buffer_fd`). A controller that cannot be built raises ControllerError (the run is refused
    with the reason)."""
    run, plant = checked.run, checked.plant
    try:
        controller = user_controller(run, plant.recorded_outputs)
        checked = built(checked, controller)
    except ControllerError:
        raise
    except SystemError_ as error:
        raise ControllerError(str(error)) from None
    except BaseException as error:  # noqa: BLE001 - the user's code: SystemExit, KeyboardInterrupt included
        raise ControllerError(f"building the controller raised {error_text(error)}") from None
    names = checked.names
    size = (run.steps + 1) * len(names) * 8
    if size > limits.max_output():
        raise ControllerError(
            f"the controller's {len(checked.diagnostics)} diagnostics make the trace {run.steps + 1} samples x"
            f" {len(names)} columns, about {size / 1e9:.2f} GB, over the {limits.max_output() / 1e9:.2f} GB output"
            " limit (record fewer diagnostics, or raise TOGGLE_COSIM_MAX_OUTPUT)"
        )
    if buffer_fd < 0:  # a probe (`probe_columns`): the columns alone
        _send(write_fd, ("columns", names, controller_record(run, controller)))
        return checked, None
    size = max((run.steps + 1) * len(names) * 8, 8)
    os.ftruncate(buffer_fd, size)
    if hasattr(os, "posix_fallocate"):
        os.posix_fallocate(buffer_fd, 0, size)
    mapped = mmap.mmap(buffer_fd, size, mmap.MAP_SHARED, mmap.PROT_READ | mmap.PROT_WRITE)
    buffer = np.frombuffer(mapped, dtype=np.float64, count=(run.steps + 1) * len(names)).reshape(-1, len(names))
    buffer.fill(np.nan)
    _send(write_fd, ("columns", names, controller_record(run, controller)))
    return checked, buffer


def _plant_process(
    checked: CheckedRun,
    buffer: np.ndarray | None,
    progress_slot: np.ndarray | None,
    workdir: Path,
    write_fd: int,
    buffer_fd: int,
    count: np.ndarray,
    calling: np.ndarray | None = None,
) -> None:
    """The plant's process: build the user's controller.python where the parent checked the run
    without it (`_build_controller`), run what the parent checked (`master.simulate`: nothing is
    checked again), send the outcome (no trace) back, exit without cleanup. Its stdout and stderr
    are the parent's relay (`relay.OutputRelay`)."""
    code = 0
    try:
        limit_memory()
        tempfile.tempdir = str(workdir)  # the FMU's unzipped copy goes into the run's folder
        here = os.open(".", os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))  # restored after the user's code

        def progress(fraction: float) -> None:
            progress_slot[0] = fraction

        if checked.builds_controller:
            try:
                checked, buffer = _build_controller(checked, buffer_fd, write_fd)
            except ControllerError as error:
                _send(write_fd, ("refused", bounded_text(str(error))))
                os._exit(0)
            finally:
                with contextlib.suppress(OSError):
                    os.fchdir(here)  # a module that changed directory at import moves nothing of the run's
            if buffer is None:  # a probe: built and checked, nothing to run
                master.close_controller(checked.controller)
                _send(write_fd, ("probed",))
                os._exit(0)
        outcome = master.simulate(
            checked, progress if progress_slot is not None else None, buffer=buffer, count=count, calling=calling
        )
        if outcome.interrupted:  # SIGINT is ignored here: user code raised KeyboardInterrupt itself
            reason = "the run's code raised KeyboardInterrupt (not an interrupt of the command)"
            outcome.record.update(status="failed", reason=reason)
            answer = (
                "outcome",
                False,
                reason,
                outcome.wall_seconds,
                outcome.loop_seconds,
                outcome.summary,
                outcome.record,
                False,
            )
        else:
            answer = (
                "outcome",
                outcome.complete,
                outcome.reason,
                outcome.wall_seconds,
                outcome.loop_seconds,
                outcome.summary,
                outcome.record,
                outcome.interrupted,
            )
    except BaseException as error:  # noqa: BLE001 - everything goes back to the parent
        if isinstance(error, OSError) and error.filename is None:
            error.filename = str(workdir)  # e.g. no space to unzip the FMU: say where
        answer = ("error", error_text(error))
        code = 3
    try:
        _send(write_fd, answer)
        sys.stdout.flush()
        sys.__stdout__.flush()
        sys.stderr.flush()
    except BaseException:  # noqa: BLE001
        code = 4
    os._exit(code)  # the keeper (`_child`) then ends the helper processes the plant started


def shared_word(dtype: type = np.int64) -> np.ndarray:
    """One 8-byte number (0) in an anonymous shared map: what a child forked after it writes
    there, the parent reads (a row count, the component being called, the run's progress)."""
    return np.frombuffer(mmap.mmap(-1, 8), dtype=dtype)


def shared_count() -> np.ndarray:
    """A row count shared with the children forked after it (`shared_word`): the child's recorder
    counts each sample in it as it records it (`recorder.row_count`, the C loops too), so the
    parent knows how many rows a run recorded whatever ended it, without reading the values (a
    NaN a run recorded is a value, not the end of the data)."""
    return shared_word()


def rows_recorded(count: np.ndarray, buffer: np.ndarray) -> int:
    """The samples a child recorded in `buffer`: its count, within the buffer's rows."""
    return max(0, min(int(count[0]), buffer.shape[0]))


def _map_buffer(folder: Path, rows: int, columns: int) -> tuple[mmap.mmap, np.ndarray]:
    """A shared map of rows x columns doubles, NaN-filled, backed by a file in `folder` that has
    no name: O_TMPFILE on Linux (TemporaryFile falls back to create-and-unlink elsewhere), so no
    moment exists at which a kill could leave it behind. Its blocks are allocated before it is
    mapped (a full file system is an OSError here, not a SIGBUS when the run writes a sample);
    the map holds the file's only descriptor, released with the last view of the map."""
    size = max(rows * columns * 8, 8)
    with tempfile.TemporaryFile(dir=folder) as stream:
        stream.truncate(size)
        if hasattr(os, "posix_fallocate"):
            os.posix_fallocate(stream.fileno(), 0, size)
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
    children may run at once (`supervised_batch`), each under its own deadline.

    The run is checked here, in the parent, once (`checked.check_run`: the controller given, the
    scenario's built-in law or its controller FMU's contract, the parts, connections, units,
    plan and columns; no binary loaded, no code of the user's run), and the child inherits the
    result and only instantiates and steps it; a run refused there fails before any child starts.
    A controller.python is built in the child alone, under the run's time limit: the parent never
    runs the user's code. Its diagnostics are columns of the trace, so the child checks what that
    instance tells (`checked.built`), sizes the trace buffer (a file the parent opened before the
    fork, with no name) and sends the columns first; whatever ends the child before that (an
    exit, a crash, SystemExit, the time limit) fails the run as the controller's failure.

    The child's stdout and stderr are pipes the parent reads while it waits and relays, capped,
    once the run is over (`relay`)."""

    def __init__(
        self,
        run: Run,
        plant: PlantInterface,
        *,
        time_limit: float | None = None,
        scratch: Path | None = None,
        with_progress: bool = False,
        controller: Controller | None = None,
        probe: bool = False,
        checked: CheckedRun | None = None,
    ) -> None:
        self._probe = probe  # only build the user's controller and send its columns (`probe_columns`)
        self.run = run
        self.plant = plant
        self.limit = time_limit_of(run, time_limit)
        self.started = clock.perf_counter()
        self.refused: str | None = None  # why the controller or the system was refused
        self.reason: str | None = None
        # the one check of the run (`checked.check_run`), here, before the fork: the child inherits it
        self.checked: CheckedRun | None = checked  # given: checked by the caller, with `controller`
        try:
            if checked is None:
                self.checked = check_run(run, plant, controller)
        except (ControllerError, SystemError_) as error:
            self.refused = str(error)
        except ValueError as error:  # a plant setting the plant does not have: the run cannot start
            self.reason = f"the plant could not be run: {error_text(error)}"
        # a controller.python is built in the child (`_build_controller`): its columns come from there
        self.deferred = self.checked is not None and self.checked.builds_controller
        complete = self.checked is not None and self.checked.complete
        self.names = (
            self.checked.names
            if complete
            else master.trace_names(plant, VSCController.diagnostics, master.other_inputs(run))
        )
        self._buffer_fd = -1  # deferred: the trace buffer's file, sized by the child
        self._built: tuple | None = None  # deferred: the child's ("columns", names, controller record)
        self.relay: OutputRelay | None = None
        self.pid = -1
        self.status: int | None = None
        self.interrupted = False
        self.done = False
        self._read_fd = self._pidfd = -1
        self._chunks: list[bytes] = []
        self._watch: list[int] = []
        self.buffer = np.full((0, len(self.names)), np.nan)
        self.count = np.zeros(1, dtype=np.int64)  # the samples the child recorded (`shared_count`)
        self.progress_slot: np.ndarray | None = None
        # a system's run writes here which component it calls (`systems.execute`)
        self.calling: np.ndarray | None = None
        self.deadline = math.inf
        self._with_progress = with_progress
        self._scratch = Path(scratch) if scratch is not None else Path(tempfile.gettempdir())
        self._workdir: Path | None = None

    def start(self) -> None:
        """Make the run's folder, map the trace buffer and fork the child; its deadline runs from
        here. A run that cannot start (no scratch space, no descriptor left) is done at once and
        fails alone, with the reason."""
        if self.refused is not None or self.checked is None:
            self.done = True
            return
        try:
            self._fork()
        except OSError as error:
            self._kill()
            self.reason = self.reason or f"the run could not start: {error.strerror or error}"
            self.done = True
        except BaseException:
            self.stop()
            raise

    def _fork(self) -> None:
        try:
            self._workdir = Path(tempfile.mkdtemp(prefix=f"{FOLDER_PREFIX}{os.getpid()}-", dir=self._scratch))
            if self.deferred and not self._probe:
                self._buffer_fd = _unnamed_file(self._workdir)
            else:
                _, self.buffer = _map_buffer(self._workdir, self.run.steps + 1, len(self.names))
        except OSError as error:
            self.reason = (
                f"no scratch space for the run's trace buffer in {self._scratch} ({error.strerror or error}; "
                "free space there or set TMPDIR)"
            )
            raise
        if self._with_progress:
            self.progress_slot = shared_word(np.float64)
        self.count = shared_count()
        self.calling = shared_word()  # the component being called (a system's, the pair's in the execution)
        read_fd, write_fd = os.pipe()
        self._read_fd = read_fd
        self.relay = OutputRelay()

        def child(parent: int) -> None:
            os.close(read_fd)
            self.relay.in_child()
            plant_process = functools.partial(
                _plant_process,
                self.checked,
                None if self.deferred else self.buffer,
                self.progress_slot,
                self._workdir,
                write_fd,
                self._buffer_fd,
                self.count,
                self.calling,
            )
            _child(parent, plant_process)

        try:
            fork_child(child, lambda pid: setattr(self, "pid", pid))
        finally:
            os.close(write_fd)
            self.relay.after_fork()
        os.set_blocking(read_fd, False)  # a helper the plant forked may hold the pipe open: never wait on it
        self.deadline = clock.monotonic() + self.limit
        try:
            self._pidfd = os.pidfd_open(self.pid)
        except (AttributeError, OSError):
            self._pidfd = -1
        self._watch = [self._read_fd] + ([self._pidfd] if self._pidfd >= 0 else [])

    def watched(self) -> list[int]:
        """The descriptors to select on: the answer pipe, the child's pidfd where there is one, and
        the pipes of its stdout and stderr."""
        return [] if self.done else list(self._watch) + (self.relay.fds() if self.relay is not None else [])

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
        if self.relay is not None:
            self.relay.drain(ready)
        if self._read_fd in ready and self._read_fd in self._watch:
            self._drain()
        if (self._pidfd in ready or self._pidfd < 0) and process_tree.has_ended(self.pid):
            self.status = process_tree.finish(self.pid)  # its helpers end with it; then reaped
            self._drain()  # what the child wrote before select saw its exit
            self.done = True
        return self.done

    def _drain(self) -> None:
        """Read what the pipe holds now, without waiting (a helper may keep it open)."""
        while self._read_fd in self._watch:
            try:
                chunk = os.read(self._read_fd, 1 << 16)
            except BlockingIOError:
                return
            if not chunk:
                self._watch.remove(self._read_fd)
                return
            self._chunks.append(chunk)

    def _kill(self) -> None:
        if self.pid > 0 and self.status is None:
            with contextlib.suppress(OSError):
                self.status = process_tree.finish(self.pid)
        self.done = True

    def stop(self, reason: str = "interrupted (SIGINT or SIGTERM)") -> None:
        """Kill the child if it still runs: the run becomes interrupted with `reason`."""
        if not self.done:
            self.interrupted = True
            self.reason = reason
        self._kill()

    def close(self) -> None:
        self._drain()
        if self.deferred and self._buffer_fd >= 0:
            self._map_built()
        for fd in (self._read_fd, self._pidfd, self._buffer_fd):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._read_fd = self._pidfd = self._buffer_fd = -1
        if self.relay is not None:
            self.relay.drain()
            self.relay.close()
        if self._workdir is not None:
            shutil.rmtree(self._workdir, ignore_errors=True)  # the map outlives its file

    def messages(self) -> list[tuple]:
        """The whole messages the child sent so far, in order."""
        return _messages(self._chunks)

    def _map_built(self) -> None:
        """Deferred: the trace buffer the child sized, mapped here once its columns came."""
        built = next((message for message in self.messages() if message[0] == "columns"), None)
        if built is None or self._built is not None:
            return
        names = tuple(built[1])
        size = max((self.run.steps + 1) * len(names) * 8, 8)
        try:
            if os.fstat(self._buffer_fd).st_size < size:
                return
            mapped = mmap.mmap(self._buffer_fd, size, mmap.MAP_SHARED, mmap.PROT_READ | mmap.PROT_WRITE)
        except (OSError, ValueError):
            return
        self._built = built
        self.names = names
        count = (self.run.steps + 1) * len(names)
        self.buffer = np.frombuffer(mapped, dtype=np.float64, count=count).reshape(-1, len(names))

    def outcome(self) -> outcomes.RunOutcome:
        """The run's outcome (call once done, after close()): the child's, or failed/interrupted
        with the reason and the trace up to the last sample the child recorded. What the child
        printed is relayed first (capped)."""
        run, plant = self.run, self.plant
        if self.relay is not None:
            self.relay.relay()
        answer = _answer(self.messages())
        rows = rows_recorded(self.count, self.buffer)
        trace = Trace(self.names, self.buffer[:rows])
        wall = clock.perf_counter() - self.started
        reason = self.reason
        if self.refused is not None:
            return master.refused_outcome(run, plant, self.refused, self.started)
        if answer is not None and answer[0] == "refused" and reason is None:
            return master.refused_outcome(run, plant, answer[1], self.started)
        if answer is not None and answer[0] == "outcome" and answer[1] and reason is None:
            if not ended_cleanly(self.status):
                # its complete answer came, but then the process was killed (by the run's own code: a
                # controller that killed its parent) or exited with an error: the run fails
                reason = f"{exit_reason(self.status)} after the run's last sample"
        if answer is not None and answer[0] == "outcome" and reason is None:
            _, complete, child_reason, _, loop_s, summary, record, child_interrupted = answer
            record["wall_time_s"] = wall
            # the trace is a view of the map, which it keeps alive
            return outcomes.RunOutcome(
                run, trace, complete, child_reason, wall, loop_s, summary, record, child_interrupted
            )
        if self.deferred and self._built is None and not self.interrupted:
            # the child ended (or was ended) while it imported or built the user's controller
            reason = building_reason(run, reason, answer, self.status)
        else:
            if reason is None:
                reason = self._exit_reason(answer)
            at = f" at t = {max(rows - 1, 0) * run.T_s:.6g} s" if rows else " before the first sample"
            users = self.checked is not None and self.checked.runs_users_code
            in_controller = (
                users  # the built-in law neither crashes nor hangs: a stop there is the plant's
                and not self.interrupted
                and self.status is not None
                and stopped_in_controller(self.buffer, rows, len(plant.recorded_outputs), self.names, self.calling)
            )
            called = self._called()
            if called is not None and not self.interrupted:  # a system's component was being called
                reason = component_reason(reason, called, at, by_limit=self.reason is not None)
            elif in_controller:  # the plant's outputs of the next sample read, no command yet
                words = controller_words(run.controller.python, run.controller.fmu)
                reason = in_controller_reason(reason, words, rows * run.T_s, by_limit=self.reason is not None)
            else:
                reason = f"{reason}{at}"
        reason = bounded_text(reason)
        status_word = "interrupted" if self.interrupted else "failed"
        given = self.checked.controller if self.checked is not None else None
        if self._built is not None:
            controller = self._built[2]
        elif given is None:
            controller = None
        else:
            controller = controller_record(run, given)
        # the samples recorded before the end: their figures of merit, a partial summary
        summary, warnings = run_figures(run, trace, self._built[2] if self._built is not None else given)
        record = outcomes.run_record(
            run, plant, status_word, reason, rows, wall, wall, summary, warnings=warnings, controller=controller
        )
        return outcomes.RunOutcome(run, trace, False, reason, wall, wall, summary, record, self.interrupted)

    def _called(self) -> str | None:
        """The component of a system whose call was under way when its process ended, in words
        (`component_words`); None for a run with the pair's trace (`CheckedRun.pair`), or
        outside any call."""
        if self.calling is None or self.checked is None or self.checked.pair:
            return None
        number = int(self.calling[0])
        names = component_names(self.run.system)
        if not 1 <= number <= len(names):
            return None
        return component_words(self.run, self.plant.path, names[number - 1])

    def _exit_reason(self, answer: tuple | None) -> str:
        if answer is not None and answer[0] == "error":
            return f"the plant could not be run: {answer[1]}"
        return exit_reason(self.status)


def _unnamed_file(folder: Path) -> int:
    """A read-write file in `folder` that never has a name (O_TMPFILE; create-and-unlink
    elsewhere): the descriptor, which the child inherits."""
    with tempfile.TemporaryFile(dir=folder) as stream:
        return os.dup(stream.fileno())


def wait_for(children: list[SupervisedRun], poll: float | None = None) -> None:
    """Block until one of `children` (not yet done) has news or reaches its deadline, and
    service them all. `poll` caps the wait (progress display)."""
    active = [child for child in children if not child.done]
    if not active:
        return
    wait = max(0.0, min(child.deadline for child in active) - clock.monotonic())
    if poll is not None or any(child.polls for child in active):
        wait = min(wait, poll if poll is not None else 0.1)
    ready = interrupts.select_readable([fd for child in active for fd in child.watched()], wait)
    for child in active:
        child.service(ready)


def simulate_supervised(
    run: Run,
    plant: PlantInterface,
    *,
    time_limit: float | None = None,
    progress: Callable[[float], None] | None = None,
    scratch: Path | None = None,
    controller: Controller | None = None,
    checked: CheckedRun | None = None,
) -> outcomes.RunOutcome:
    """`master.check_and_simulate` supervised: the run checked here, simulated in a child process
    (`master.simulate`); never raises for anything the plant or the controller does.
    `controller`: as for `master.check` (the child inherits it); None:
    the run's own, built in the child. `checked`: the run as `checked.check_run` checked it with
    `controller`, by a caller that checked it before (None: checked here, before the fork).
    What the child prints is written to this process's sys.stdout and sys.stderr once the run
    is over, capped (`relay`).

    An interrupt (KeyboardInterrupt) during the run kills the child and returns the run as
    interrupted (`outcome.interrupted`); the caller stops after writing it."""
    child = SupervisedRun(
        run,
        plant,
        time_limit=time_limit,
        scratch=scratch,
        with_progress=progress is not None,
        controller=controller,
        checked=checked,
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


def probe_columns(
    run: Run, plant: PlantInterface, time_limit: float | None = None, checked: CheckedRun | None = None
) -> tuple[str, ...]:
    """The trace columns of `run`: the run's check's (`checked.check_run`), or with a
    controller.python, found by building and checking the controller in a supervised child
    (under the run's time limit, or `time_limit`), never in this process. `checked`: the run as a
    caller checked it before (None: checked here). Raises ControllerError with the one-line
    reason: the controller's own refusal, or what ended the child (an exit, a crash, the limit)."""
    child = SupervisedRun(run, plant, time_limit=time_limit, probe=True, checked=checked)
    if child.refused is not None or child.checked is None:
        raise ControllerError(child.refused or child.reason or "the run could not be checked")
    if not child.deferred:  # nothing of the user's to build: the parent's check knows the columns
        return child.names
    try:
        child.start()
        while not child.done:
            wait_for([child])
    finally:
        child.stop()
        child.close()
        if child.relay is not None:
            child.relay.relay()
    messages = child.messages()
    columns = next((message for message in messages if message[0] == "columns"), None)
    if columns is not None:
        return tuple(columns[1])
    refused = next((message for message in messages if message[0] == "refused"), None)
    if refused is not None:
        raise ControllerError(refused[1])
    reason = building_reason(run, child.reason, _answer(child.messages()), child.status)
    raise ControllerError(bounded_text(reason.removeprefix("controller: ")))


def _answer(messages: list[tuple]) -> tuple | None:
    """The child's last word: its outcome, error or refusal (None if it sent none whole)."""
    final = [message for message in messages if message[0] in ("outcome", "error", "refused")]
    return final[-1] if final else None
