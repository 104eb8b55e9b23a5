"""What a child process writes on its stdout and stderr, relayed by its parent with a cap.

A plant or a controller may print without end (671 MB in one case). A supervised child's file
descriptors 1 and 2 are pipes (`OutputRelay.in_child`); its parent reads them while it waits for
the child (`fds`, `drain`), keeps at most `limits.max_log()` bytes of each run
(TOGGLE_COSIM_MAX_LOG, default 64 KiB) and discards the rest, and once the run is over writes
what it kept, then one line saying how many bytes were dropped (`relay`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import TextIO

from toggle_cosim import limits


class OutputRelay:
    """The pipes of one child's stdout and stderr, from the parent's side; make it before the fork."""

    def __init__(self, cap: int | None = None) -> None:
        self.cap = limits.max_log() if cap is None else cap
        self._pipes = [os.pipe(), os.pipe()]  # (read, write) for stdout, stderr
        self._kept = [bytearray(), bytearray()]
        self.dropped = 0

    def in_child(self) -> None:
        """In the child, first thing: its stdout and stderr become the pipes' write ends, and its
        stdin /dev/null (a plant or controller never reads what the command's user types)."""
        sys.stdout.flush()
        sys.stderr.flush()
        with contextlib.suppress(OSError):
            null = os.open(os.devnull, os.O_RDONLY)
            os.dup2(null, 0)
            os.close(null)
        for target, (read, write) in zip((1, 2), self._pipes, strict=True):
            os.dup2(write, target)
            os.close(read)
            os.close(write)
        # Python's own streams too (the parent's may be a notebook's or a test runner's objects)
        sys.stdout = open(1, "w", encoding="utf-8", errors="replace", closefd=False, buffering=1)  # noqa: SIM115
        sys.stderr = open(2, "w", encoding="utf-8", errors="replace", closefd=False, buffering=1)  # noqa: SIM115

    def after_fork(self) -> None:
        """In the parent, after the fork: close the write ends and never block on the read ends."""
        for index, (read, write) in enumerate(self._pipes):
            with contextlib.suppress(OSError):
                os.close(write)
            self._pipes[index] = (read, -1)  # never closed again: its number may be another's by then
            os.set_blocking(read, False)

    def fds(self) -> list[int]:
        """The read ends still open (to select on)."""
        return [read for read, _ in self._pipes if read >= 0]

    def drain(self, ready: set[int] | list[int] | None = None) -> None:
        """Read what the pipes hold now (those in `ready`, or all), keeping up to the cap."""
        for index, (read, write) in enumerate(self._pipes):
            if read < 0 or (ready is not None and read not in ready):
                continue
            while True:
                try:
                    chunk = os.read(read, 1 << 16)
                except BlockingIOError:
                    break
                except OSError:
                    chunk = b""
                if not chunk:  # every writer has closed it
                    os.close(read)
                    self._pipes[index] = (-1, write)
                    break
                room = max(self.cap - len(self._kept[0]) - len(self._kept[1]), 0)
                self._kept[index] += chunk[:room]
                self.dropped += max(len(chunk) - room, 0)

    def relay(self, stdout: TextIO | None = None, stderr: TextIO | None = None) -> None:
        """Write what was kept to `stdout`/`stderr` (default: sys's), then the line about the rest."""
        self.drain()
        out, err = stdout or sys.stdout, stderr or sys.stderr
        for stream, kept in zip((out, err), self._kept, strict=True):
            if kept:
                text = kept.decode("utf-8", "replace")
                stream.write(text if text.endswith("\n") else text + "\n")
                kept.clear()
        if self.dropped:
            err.write(
                f"... {self.dropped} more bytes of the run's output (the plant's or the controller's own printing)"
                f" were dropped: each run's output is kept up to {self.cap} bytes (TOGGLE_COSIM_MAX_LOG)\n"
            )
            self.dropped = 0
        with contextlib.suppress(Exception):
            out.flush()
            err.flush()

    def close(self) -> None:
        """Close every end still open in this process."""
        for index, (read, write) in enumerate(self._pipes):
            for fd in (read, write):
                if fd >= 0:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self._pipes[index] = (-1, -1)


__all__ = ["OutputRelay"]
