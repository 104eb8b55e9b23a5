"""SIGINT and SIGTERM as one kind of event, an interrupt, that never lands in the middle of a write.

`install()` makes both signals raise KeyboardInterrupt in the main thread. Inside
`deferred()` (writing a result file, recording a finished sweep case) an interrupt is noted and
raised when the block ends, so a file is either whole or not there. The command line turns
KeyboardInterrupt into exit status 130 (`cli`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

EXIT_INTERRUPTED = 130
_depth = 0
_pending: int | None = None
_starting = False  # the program is still importing: nothing is written yet, so exit at once
_program = False  # running as the toggle-cosim program (not imported by a test or a notebook)


def _handler(signum: int, frame: object) -> None:
    global _pending
    if _starting:
        os.write(2, b"interrupted (exit 130) while starting; nothing was written\n")
        os._exit(EXIT_INTERRUPTED)
    if _depth > 0:
        _pending = signum
        return
    raise KeyboardInterrupt(signal.Signals(signum).name)


def install_for_start_up() -> None:
    """For the program itself, before its heavy imports: an interrupt while it starts exits 130
    at once (no traceback from the middle of an import). `install()` ends this mode."""
    global _starting, _program
    _program = True
    if threading.current_thread() is threading.main_thread():
        _starting = True
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, _handler)


_default_unraisable = sys.unraisablehook


def _unraisable(info: object) -> None:
    """An interrupt that landed in a callback (a weakref callback during an import, a __del__)
    cannot propagate from there: send the signal again, to land in ordinary code."""
    error = getattr(info, "exc_value", None)
    if isinstance(error, KeyboardInterrupt) and threading.current_thread() is threading.main_thread():
        name = str(error) if str(error) in ("SIGINT", "SIGTERM") else "SIGINT"
        signal.raise_signal(getattr(signal, name))
        return
    _default_unraisable(info)  # type: ignore[arg-type]


def install() -> dict[int, object]:
    """SIGINT and SIGTERM raise KeyboardInterrupt (main thread only); returns the old handlers."""
    global _starting
    if threading.current_thread() is not threading.main_thread():
        return {}
    if _program:
        sys.unraisablehook = _unraisable
    _starting = False
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
    if not _program:  # imported (a test, a notebook): the caller's handlers come back afterwards
        return
    if threading.current_thread() is threading.main_thread():
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, signal.SIG_IGN)
    threading.excepthook = lambda args: None


def running_as_program() -> bool:
    return _program


def is_interrupt(error: BaseException) -> bool:
    """Whether `error` is an interrupt, or an error that one caused: a KeyboardInterrupt raised
    inside a C function that then returned normally comes back as a SystemError "from" it."""
    seen = 0
    while error is not None and seen < 20:
        if isinstance(error, KeyboardInterrupt):
            return True
        error = error.__cause__ or error.__context__
        seen += 1
    return False


def exit_interrupted() -> None:
    """End the program with status 130. As the program itself: os._exit after flushing, because
    CPython re-raises SIGINT at exit (status -2, not 130) when a KeyboardInterrupt once passed
    through C code that ran Python (an import, say), even though it was caught later. Imported
    (tests, notebooks): SystemExit(130)."""
    if _program:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(EXIT_INTERRUPTED)
    sys.exit(EXIT_INTERRUPTED)


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
