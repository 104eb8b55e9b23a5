"""SIGINT and SIGTERM as one kind of event, an interrupt, that never lands in the middle of a write.

`install()` makes both signals raise KeyboardInterrupt in the main thread. Inside
`deferred()` (writing a result file, recording a finished sweep case) an interrupt is noted and
raised when the block ends, so a file is either whole or not there. The command line turns
KeyboardInterrupt into exit status 130 (`cli`).

A raised KeyboardInterrupt can still be lost: C code that calls Python and then clears whatever
it raised drops it (a sweep's lazy import of lxml, whose module set-up registers classes with
`abc`, did, and the sweep ran on to its held case). So an interrupt, once it arrived, stays
noted for the command (`raise_if_noted`): the command's waits raise it again before they block
(`select_readable`), and a command that ends without having acted on it ends as interrupted.

Child processes (plants, sweep workers, figure workers) are started inside
`starting_children()` and call `as_child()` first thing: Ctrl-C, which a terminal sends to the
whole process group, is the command's alone to act on, and cannot hit a child while it starts.

Python runs a signal's handler in the main thread, but the kernel may deliver the signal to any
thread that does not block it: to another thread (tqdm's monitor, pyarrow's pool) whenever the
main thread blocks it, as it does while it starts a child. That thread only notes the signal for
the main thread, which acts on it when it next runs Python: a main thread already waiting in
`select` would wait on, up to its timeout (a sweep case's time limit). So `install()` has every
signal's number written to a pipe as well (`signal.set_wakeup_fd`), and the waits of the
command's main thread select on it too (`select_readable`): they return at once, and the
handler runs.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import sys
import threading
import time
from collections.abc import Iterator, Sequence

EXIT_INTERRUPTED = 130
RESEND_DELAY_S = 0.002  # an interrupt lost in a callback is sent again after this
_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_depth = 0
_pending: int | None = None
_starting = False  # the program is still importing: nothing is written yet, so exit at once
_program = False  # running as the toggle-cosim program (not imported by a test or a notebook)
_in_hook = False  # inside _unraisable, where a raised interrupt would be dropped again
_lost = signal.SIGINT  # the interrupt _unraisable is sending again
_child = False  # a child process (`as_child`): SIGINT is ignored, so no KeyboardInterrupt is an interrupt
_wakeup: tuple[int, int] | None = None  # the pipe signals are written to (`install`), read end first
_noted: int | None = None  # the interrupt that arrived during the command, until it ends (`raise_if_noted`)
_WAKEUP_KEY = -2  # where `install` keeps the wakeup descriptor it replaced, among the old handlers


def raised_by_code(error: BaseException) -> bool:
    """True if `error`, caught around a user's code (a controller, its factory, its import), is
    that code's failure: any Exception, SystemExit, and a KeyboardInterrupt raised in a child
    process (where SIGINT is ignored: the code raised it itself). False for an interrupt of the
    command (KeyboardInterrupt in the command's own process) and GeneratorExit."""
    if isinstance(error, (Exception, SystemExit)):
        return True
    return isinstance(error, KeyboardInterrupt) and _child


def _handler(signum: int, frame: object) -> None:
    global _pending, _lost, _noted
    if _starting:
        os.write(2, b"interrupted (exit 130) while starting; nothing was written\n")
        os._exit(EXIT_INTERRUPTED)
    _noted = signum
    if _depth > 0:
        _pending = signum
        return
    if _in_hook:  # a signal while the hook runs: the hook's helper sends it once the hook is over
        _lost = signum
        return
    raise KeyboardInterrupt(signal.Signals(signum).name)


def install_for_start_up() -> None:
    """For the program itself, before its heavy imports: an interrupt while it starts exits 130
    at once (no traceback from the middle of an import). `install()` ends this mode."""
    global _starting, _program
    _program = True
    if threading.current_thread() is threading.main_thread():
        _starting = True
        for number in _SIGNALS:
            signal.signal(number, _handler)


_default_unraisable = sys.unraisablehook


def _unraisable(info: object) -> None:
    """An interrupt that landed in a callback (a weakref callback during an import, a __del__)
    cannot propagate from there: a helper thread sends the signal again once this hook has
    returned (and RESEND_DELAY_S later), to land in ordinary code. Raising it here, or sending
    it while the hook still runs (a busy machine can hold this thread for milliseconds), would
    only have it dropped again. Should it land in a callback again, the same happens again."""
    global _in_hook, _lost
    error = getattr(info, "exc_value", None)
    if isinstance(error, KeyboardInterrupt) and threading.current_thread() is threading.main_thread():
        _in_hook = True
        try:
            _lost = signal.SIGTERM if str(error) == "SIGTERM" else signal.SIGINT
            threading.Thread(target=_send_after_hook, name="toggle-cosim-interrupt", daemon=True).start()
        finally:
            _in_hook = False  # nothing between this and the return runs a signal handler
        return
    _default_unraisable(info)  # type: ignore[arg-type]


def _send_after_hook() -> None:
    while _in_hook:
        time.sleep(RESEND_DELAY_S / 4)
    time.sleep(RESEND_DELAY_S)
    os.kill(os.getpid(), _lost)


def install() -> dict[int, object]:
    """SIGINT and SIGTERM raise KeyboardInterrupt (main thread only); returns the old handlers.
    The start-up mode (`install_for_start_up`) ends last: an interrupt while this runs exits 130
    at once, as during the imports, rather than raising in the middle of it."""
    global _starting, _noted
    if threading.current_thread() is not threading.main_thread():
        return {}
    if _program:
        sys.unraisablehook = _unraisable
    _noted = None
    old = {}
    for number in _SIGNALS:
        old[number] = signal.signal(number, _handler)
    old[_WAKEUP_KEY] = signal.set_wakeup_fd(_wakeup_pipe()[1], warn_on_full_buffer=False)
    _starting = False
    return old


def restore(old: dict[int, object]) -> None:
    global _noted
    _noted = None
    for number, handler in old.items():
        if number == _WAKEUP_KEY:
            signal.set_wakeup_fd(handler)  # type: ignore[arg-type]
        else:
            signal.signal(number, handler)  # type: ignore[arg-type]


def _wakeup_pipe() -> tuple[int, int]:
    """The pipe every signal's number is written to (module docstring), made once per process."""
    global _wakeup
    if _wakeup is None:
        _wakeup = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
    return _wakeup


def select_readable(fds: Sequence[int], timeout: float) -> list[int]:
    """`select` for reading on `fds` for up to `timeout` s, returning early when a signal arrives
    in this process (module docstring), whichever thread the kernel gave it to; the handler then
    runs as this returns. An interrupt noted before (module docstring) is raised at once, outside
    `deferred()`. The descriptors among `fds` that are ready."""
    raise_if_noted()
    wakeup = _wakeup[0] if _wakeup is not None else -1
    ready, _, _ = select.select([*fds, wakeup] if wakeup >= 0 else list(fds), [], [], timeout)
    if wakeup >= 0 and wakeup in ready:
        with contextlib.suppress(OSError):
            while os.read(wakeup, 512):
                pass
    return [fd for fd in ready if fd != wakeup]


def raise_if_noted() -> None:
    """Raise KeyboardInterrupt if an interrupt arrived during the command, acted on or not (module
    docstring), outside `deferred()` (there it is raised when the block ends)."""
    if _noted is not None and _depth == 0:
        raise KeyboardInterrupt(signal.Signals(_noted).name)


def ignore() -> None:
    """From here on the process is ending: further signals change nothing (main thread only), and
    helper threads that fail while it ends (a process pool whose workers were killed) stay quiet.
    An interrupt noted before is no longer raised again (`raise_if_noted`)."""
    global _noted
    _noted = None
    if not _program:  # imported (a test, a notebook): the caller's handlers come back afterwards
        return
    if threading.current_thread() is threading.main_thread():
        for number in _SIGNALS:
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


@contextlib.contextmanager
def starting_children() -> Iterator[None]:
    """Start child processes inside this block. An interrupt arriving meanwhile is deferred as in
    `deferred()`, so no child is left half launched, unknown to whoever would stop it. SIGINT and
    SIGTERM are also blocked in this thread, and a child inherits that mask (through exec too):
    a Ctrl-C, which the terminal sends to the whole process group, cannot interrupt a child
    while it starts (a traceback from the middle of its imports). The child takes them over with
    `as_child()`; a signal that arrived before then is still pending and reaches it then."""
    with deferred():
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def as_child(on_terminate: object = signal.SIG_DFL) -> None:
    """The signals of a child process started by a toggle-cosim command: SIGINT is the parent's
    to handle (ignored here, a pending one discarded), SIGTERM does `on_terminate` (the parent
    stopping this child); then both are unblocked (`starting_children()` blocked them)."""
    global _child, _wakeup
    _child = True
    if _wakeup is not None:  # the parent's pipe: this process's signals are its own
        with contextlib.suppress(ValueError):  # set only from the main thread
            signal.set_wakeup_fd(-1)
        for fd in _wakeup:
            with contextlib.suppress(OSError):
                os.close(fd)
        _wakeup = None
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, on_terminate)  # type: ignore[arg-type]
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _SIGNALS)
