"""A plant host: one child process that keeps a plant loaded and runs request after request,
supervised by its parent as a single run is (`supervision`).

    parent: shared trace buffer -> fork -> submit(request, time limit) -> service() until the
            answer, the child's death or the limit -> the next request (or a new host)
    child:  read a request from the pipe -> serve(request, buffer, count) -> answer back -> read again

The child keeps whatever `serve` keeps between requests (a sweep worker: the unzipped FMU, its
loaded binary, the compiled loop, an instance to reset): that is what a host is for. Each
request gets the whole trace buffer, NaN-filled by `serve` before it writes the request's
samples, and the shared row count (`supervision.shared_count`) its recorder counts them in, so
when the child dies (a segfault, an abort, SIGKILL from outside) or hangs past the request's
time limit, the parent still knows how far the request got (`rows_recorded`), and the
answer reports the child's end as the request's failure; the caller starts a new host for the
next request. The child dies with its parent, its address space may grow by
TOGGLE_COSIM_PLANT_MEMORY, and its temporary files live in its own folder (named like a
supervised run's, so `remove_stale_folders` removes it after a SIGKILL), removed by `close()`.
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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim import interrupts, process_tree
from toggle_cosim.cosim.isolation.exit_reasons import exit_reason
from toggle_cosim.cosim.isolation.supervision import (
    FOLDER_PREFIX,
    fork_child,
    limit_memory,
    rows_recorded,
    seconds_text,
    shared_count,
)
from toggle_cosim.messages import error_text
from toggle_cosim.relay import OutputRelay

_HEADER = struct.Struct("<Q")  # the length of the pickled message that follows
Serve = Callable[[Any, np.ndarray, np.ndarray], Any]  # (request, trace buffer, row count) -> answer, in the child


@dataclass(frozen=True)
class HostAnswer:
    """What became of a request: `value` (serve's answer) or `failure` (why the child ended or
    was ended) with `rows`, the samples the request had recorded in the trace buffer by then."""

    value: Any = None
    failure: str | None = None
    rows: int = 0


def _write_message(fd: int, message: Any) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _read_exactly(fd: int, size: int) -> bytes | None:
    chunks, left = [], size
    while left:
        chunk = os.read(fd, left)
        if not chunk:
            return None
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _serve_forever(serve: Serve, buffer: np.ndarray, count: np.ndarray, requests: int, answers: int) -> None:
    while (header := _read_exactly(requests, _HEADER.size)) is not None:
        body = _read_exactly(requests, _HEADER.unpack(header)[0])
        if body is None:
            return
        try:
            answer: tuple = ("answer", serve(pickle.loads(body), buffer, count))
        except Exception as error:  # noqa: BLE001 - the request's failure goes back to the parent
            answer = ("error", error_text(error))
        _write_message(answers, answer)
        sys.stdout.flush()
        if getattr(serve, "retired", False):  # it may not serve again (a plant that answered Fatal)
            return


def _host_child(
    serve: Serve, buffer: np.ndarray, count: np.ndarray, workdir: Path, requests: int, answers: int, parent: int
) -> None:
    """The child's whole life: lead its group, then serve requests in a grandchild it keeps
    (`process_tree.run_kept`: a plant or controller that kills its parent kills this keeper, not
    the command) until the parent closes the pipe; end as the grandchild ended."""
    try:
        faulthandler.disable()  # a plant's crash is reported by the parent, not dumped here
        interrupts.as_child()  # the parent decides about interrupts
        process_tree.become_leader()  # its own group, and the adoptive parent of its plant's orphans
        process_tree.die_with(parent)
    except BaseException:  # noqa: BLE001 - the parent sees the exit status
        os._exit(4)
    process_tree.run_kept(functools.partial(_host_work, serve, buffer, count, workdir, requests, answers))


def _host_work(serve: Serve, buffer: np.ndarray, count: np.ndarray, workdir: Path, requests: int, answers: int) -> None:
    """The grandchild: serve requests until the parent closes the pipe, exit without cleanup."""
    code = 0
    try:
        limit_memory()
        tempfile.tempdir = str(workdir)  # the FMU's unzipped copy goes into the host's folder
        gc.freeze()  # a collection never touches (and so copies) the heap inherited from the parent
        _serve_forever(serve, buffer, count, requests, answers)
    except BaseException:  # noqa: BLE001 - the parent sees the exit status
        code = 4
    with contextlib.suppress(BaseException):
        sys.stdout.flush()
        sys.stderr.flush()
    os._exit(code)  # the keeper then ends what the plant started


class PlantHost:
    """One host child, driven by the caller's loop (one request at a time):

        host = PlantHost(serve, rows, columns)
        host.start()
        host.submit(request, time_limit)     # False if the child is gone (start a new host)
        while host.busy: select on host.watched() until host.deadline, then
            answer = host.service(ready)     # a HostAnswer once the request is over
        host.close()                         # stops the child, removes its folder

    After a failure the child is gone (killed at the time limit, or dead): close this host and
    start another for the next request."""

    def __init__(self, serve: Serve, rows: int, columns: int, scratch: Path | None = None) -> None:
        self.serve = serve
        self.rows, self.columns = max(rows, 1), columns
        self.pid = -1
        self.busy = False
        self.deadline = math.inf
        self.limit = math.inf
        self._request_fd = self._answer_fd = self._pidfd = -1
        self._pending = bytearray()
        self._status: int | None = None
        self.relay: OutputRelay | None = None
        self._map = mmap.mmap(-1, self.rows * columns * 8)  # anonymous and shared with the child
        self.buffer = np.frombuffer(self._map, dtype=np.float64).reshape(self.rows, columns)
        self.buffer.fill(np.nan)
        self.count = shared_count()  # the samples the current request recorded, counted by its recorder
        self._workdir = Path(tempfile.mkdtemp(prefix=f"{FOLDER_PREFIX}{os.getpid()}-", dir=scratch))

    @property
    def alive(self) -> bool:
        return self.pid > 0 and self._status is None

    def start(self) -> None:
        """Fork the child (inside `starting_children`: an interrupt waits until its pid is known)."""
        request_read, request_write = os.pipe()
        answer_read, answer_write = os.pipe()
        self.relay = OutputRelay()  # the host's stdout and stderr, relayed after each request, capped

        def child(parent: int) -> None:
            os.close(request_write)
            os.close(answer_read)
            self.relay.in_child()
            _host_child(self.serve, self.buffer, self.count, self._workdir, request_read, answer_write, parent)

        try:
            fork_child(child, lambda pid: setattr(self, "pid", pid))
        finally:
            os.close(request_read)
            os.close(answer_write)
            self.relay.after_fork()
            self._request_fd, self._answer_fd = request_write, answer_read
        try:
            self._pidfd = os.pidfd_open(self.pid)
        except (AttributeError, OSError):
            self._pidfd = -1

    @property
    def polls(self) -> bool:
        """True without a pidfd: the caller must call service() now and then (every 0.1 s)."""
        return self._pidfd < 0

    def submit(self, request: Any, time_limit: float) -> bool:
        """Send a request; its time limit runs from now. False if the child is gone."""
        if not self.alive or self.busy:
            return False
        try:
            _write_message(self._request_fd, request)
        except OSError:  # BrokenPipeError: the child died while idle (killed from outside)
            self._reap(block=True)
            return False
        self.busy = True
        self.limit = time_limit
        self.deadline = clock.monotonic() + time_limit
        return True

    def watched(self) -> list[int]:
        """The descriptors to select on while busy: the answer pipe and the child's pidfd."""
        if not self.busy:
            return []
        relayed = self.relay.fds() if self.relay is not None else []
        return [self._answer_fd] + ([self._pidfd] if self._pidfd >= 0 else []) + relayed

    def service(self, ready: Sequence[int] | set[int]) -> HostAnswer | None:
        """Read what the child wrote, notice its death or the deadline; the answer once over."""
        if not self.busy:
            return None
        if self.relay is not None:
            self.relay.drain(ready)
        answer = self._service(ready)
        if answer is not None and self.relay is not None:
            self.relay.relay()  # what the request printed, capped (`relay`)
        return answer

    def _service(self, ready: Sequence[int] | set[int]) -> HostAnswer | None:
        if self._answer_fd in ready:
            chunk = os.read(self._answer_fd, 1 << 20)
            self._pending += chunk
            answer = self._complete_answer()
            if answer is not None:
                return answer
            if not chunk:  # the pipe closed without a whole answer: the child is ending
                self._reap(block=True)
                return self._failed(exit_reason(self._status))
        if self._pidfd in ready or self._pidfd < 0:
            if self._reap(block=False):
                while chunk := os.read(self._answer_fd, 1 << 20):  # what it wrote before select saw the exit
                    self._pending += chunk
                return self._complete_answer() or self._failed(exit_reason(self._status))
        if clock.monotonic() >= self.deadline:
            self.kill()
            return self._failed(f"time limit {seconds_text(self.limit)} exceeded")
        return None

    def _complete_answer(self) -> HostAnswer | None:
        if len(self._pending) < _HEADER.size:
            return None
        size = _HEADER.unpack_from(self._pending)[0]
        if len(self._pending) < _HEADER.size + size:
            return None
        kind, value = pickle.loads(bytes(self._pending[_HEADER.size : _HEADER.size + size]))
        del self._pending[: _HEADER.size + size]
        self.busy = False
        self.deadline = math.inf
        if kind == "error":
            return HostAnswer(failure=value, rows=rows_recorded(self.count, self.buffer))
        return HostAnswer(value=value)

    def _failed(self, reason: str) -> HostAnswer:
        self.busy = False
        self.deadline = math.inf
        return HostAnswer(failure=reason, rows=rows_recorded(self.count, self.buffer))

    def _reap(self, block: bool) -> bool:
        if self.pid <= 0 or self._status is not None:
            return True
        with contextlib.suppress(ChildProcessError):
            finished, status = os.waitpid(self.pid, 0 if block else os.WNOHANG)
            if not finished:
                return False
            self._status = status
        if self._status is None:
            self._status = 0
        return True

    def kill(self) -> None:
        """End the child now (the time limit, an interrupt): a plant stuck in C cannot ignore SIGKILL."""
        if self.alive:
            process_tree.end_tree(self.pid)  # the host, its group and whatever its plant started
            self._reap(block=True)

    def close(self) -> None:
        """Stop the child (it exits when its request pipe closes; killed if busy) and remove its folder."""
        if self.busy:
            self.kill()
        for fd in (self._request_fd, self._answer_fd, self._pidfd):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._request_fd = self._answer_fd = self._pidfd = -1
        if self.alive:  # idle: it reads end-of-file and exits; do not wait on a plant's destructors
            self.kill()
        if self.relay is not None:
            self.relay.close()
        shutil.rmtree(self._workdir, ignore_errors=True)


def wait_for_hosts(hosts: Sequence[PlantHost], poll: float | None = None) -> list[tuple[PlantHost, HostAnswer]]:
    """Block until a busy host has news or reaches its deadline (at most `poll` s); the answers."""
    busy = [host for host in hosts if host.busy]
    if not busy:
        return []
    wait = max(0.0, min(host.deadline for host in busy) - clock.monotonic())
    if poll is not None or any(host.polls for host in busy):
        wait = min(wait, poll if poll is not None else 0.1)
    ready = interrupts.select_readable([fd for host in busy for fd in host.watched()], wait)
    answers = []
    for host in busy:
        answer = host.service(ready)
        if answer is not None:
            answers.append((host, answer))
    return answers


__all__ = ["HostAnswer", "PlantHost", "wait_for_hosts"]
