"""SIGINT and SIGTERM as one kind of event, an interrupt, that never lands in the middle of a write.

`install()` makes both signals raise KeyboardInterrupt in the main thread. Inside
`deferred()` (writing a result file, recording a finished sweep case) an interrupt is noted and
raised when the block ends, so a file is either whole or not there. The command line turns
KeyboardInterrupt into exit status 130 (`cli`).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

EXIT_INTERRUPTED = 130
_depth = 0
_pending: int | None = None


def _handler(signum: int, frame: object) -> None:
    global _pending
    if _depth > 0:
        _pending = signum
        return
    raise KeyboardInterrupt(signal.Signals(signum).name)


def install() -> dict[int, object]:
    """SIGINT and SIGTERM raise KeyboardInterrupt (main thread only); returns the old handlers."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    old = {}
    for number in (signal.SIGINT, signal.SIGTERM):
        old[number] = signal.signal(number, _handler)
    return old


def restore(old: dict[int, object]) -> None:
    for number, handler in old.items():
        signal.signal(number, handler)  # type: ignore[arg-type]


def ignore() -> None:
    """From here on the process is ending: further signals change nothing (main thread only), and
    helper threads that fail while it ends (a process pool whose workers were killed) stay quiet."""
    if threading.current_thread() is threading.main_thread():
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, signal.SIG_IGN)
    threading.excepthook = lambda args: None


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """An interrupt arriving inside the block is raised when the block ends (after its writes)."""
    global _depth, _pending
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if _depth == 0 and _pending is not None:
            signum, _pending = _pending, None
            raise KeyboardInterrupt(signal.Signals(signum).name)
