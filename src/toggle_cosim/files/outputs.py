"""Writing the files a command produces without harming what lies at their paths: every output
(traces, run records, JUnit and Markdown reports, figures, FMUs, sweep tables) goes through here.

* A file is written to a temporary name that `tempfile.mkstemp` makes in the destination's
  folder (unique, created by this process: nothing planted under it is followed), then renamed
  over the destination. A reader sees the old file or the whole new one; a failed or
  interrupted write leaves nothing behind.
* A destination that exists and is not a regular file (a folder, a symbolic link, a FIFO, a
  socket, a block device) is refused with one line (`OutputError`, exit 2 in the CLI): a link
  is neither followed nor replaced.
* Written through, by design: the paths /dev/stdout and /dev/stderr (the command's own output
  streams, whatever they are connected to) and a character device named directly (/dev/null,
  a terminal), opened without creating or truncating anything and without following a link.
* A lock is taken on the folder itself (`folder_lock`): no lock file, so no fixed name to plant.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

# paths written through to the command's own streams, by design
STREAMS = {"/dev/stdout": 1, "/dev/stderr": 2}


class OutputError(OSError):
    """A destination that must not be written (one line naming the path and the fix), or a
    write through a device that failed."""

    def __init__(self, path: Path | str, problem: str) -> None:
        super().__init__(problem)
        self.filename = str(path)
        self.strerror = problem

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


FILE_MODE = 0o666 & ~_umask()  # what open() would give: mkstemp's files are private (0600)

_KINDS = (
    (stat.S_ISLNK, "a symbolic link"),
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISBLK, "a block device"),
)


def _written_through(path: Path) -> bool:
    """True if `path` is one of STREAMS or a character device named directly."""
    if str(path) in STREAMS:
        return True
    try:
        return stat.S_ISCHR(os.lstat(path).st_mode)
    except OSError:
        return False


def check_destination(path: Path | str, what: str = "output") -> None:
    """Raise OutputError if something that is not a regular file lies at `path` (a character
    device and /dev/stdout, /dev/stderr are written through; see the module docstring); `what`
    names the output in the message."""
    path = Path(path)
    if str(path) in STREAMS:
        return
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as error:  # e.g. a parent that is a file: the write will say it, naming the path
        if error.errno in (errno.ENOTDIR, errno.ELOOP, errno.ENAMETOOLONG):
            raise OutputError(
                path, f"cannot be written ({error.strerror}); give another file name for the {what}"
            ) from error
        raise
    if stat.S_ISREG(mode) or stat.S_ISCHR(mode):
        return
    kind = next((name for test, name in _KINDS if test(mode)), "something else")
    note = " (a link is not followed)" if stat.S_ISLNK(mode) else ""
    raise OutputError(path, f"is {kind}, not a regular file{note}; give another file name for the {what}")


@contextlib.contextmanager
def _through(path: Path, what: str) -> Iterator[int]:
    """A write descriptor on STREAMS[path] or on the character device at `path`."""
    if str(path) in STREAMS:
        sys.stdout.flush()
        sys.stderr.flush()
        yield STREAMS[str(path)]
        return
    fd = os.open(path, os.O_WRONLY | os.O_NOFOLLOW | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    try:
        if not stat.S_ISCHR(os.fstat(fd).st_mode):
            raise OutputError(path, f"changed while it was opened; give another file name for the {what}")
        yield fd
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes, path: Path, what: str) -> None:
    view = memoryview(data)
    try:
        while view:
            view = view[os.write(fd, view) :]
    except OSError as error:
        raise OutputError(
            path, f"cannot be written ({error.strerror}); give another file name for the {what}"
        ) from error


@contextlib.contextmanager
def replacing(path: Path | str, what: str = "output") -> Iterator[Path]:
    """The name of a fresh, empty temporary file in `path`'s folder (made by mkstemp) for a
    writer that wants a file name (matplotlib, junitparser, pyarrow); when the block ends
    without an exception, the file gets the usual mode, is synced and renamed over `path`;
    otherwise it is removed. OutputError (naming `what`) before anything is written if `path` is
    not a regular file or missing; for a path that is written through, the temporary file's
    bytes are copied there instead."""
    path = Path(path)
    check_destination(path, what)
    through = _written_through(path)
    folder = Path(tempfile.gettempdir()) if through else path.parent
    folder.mkdir(parents=True, exist_ok=True)
    handle, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=folder)
    temporary = Path(name)
    try:
        os.close(handle)
        yield temporary
        if through:
            with _through(path, what) as fd:
                _write_all(fd, temporary.read_bytes(), path, what)
            temporary.unlink()
            return
        with open(temporary, "rb+") as stream:
            os.fchmod(stream.fileno(), FILE_MODE)
            os.fsync(stream.fileno())
        check_destination(path, what)  # a link put there meanwhile is refused, not replaced
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_file(path: Path | str, write: Callable[[IO[Any]], Any], binary: bool = False, what: str = "output") -> Path:
    """Call `write(stream)` on a stream whose bytes end at `path` as `replacing` says (UTF-8 text
    with "\\n" line ends, or bytes if `binary`), and return `path`."""
    path = Path(path)
    with replacing(path, what) as temporary:
        opened = open(temporary, "wb") if binary else open(temporary, "w", encoding="utf-8", newline="\n")  # noqa: SIM115
        with opened as stream:
            write(stream)
    return path


def write_text(path: Path | str, text: str, what: str = "output") -> Path:
    """`write_file` of a whole text."""
    return write_file(path, lambda stream: stream.write(text), what=what)


@contextlib.contextmanager
def folder_lock(folder: Path | str) -> Iterator[bool]:
    """Hold an exclusive lock on `folder` itself (created if missing) while the block runs:
    yields True, or False at once when another process holds it. No lock file is made (so none
    can be planted); on a platform without flock the block runs unlocked (yields True)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield True
        return
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


__all__ = [
    "FILE_MODE",
    "STREAMS",
    "OutputError",
    "check_destination",
    "folder_lock",
    "replacing",
    "write_file",
    "write_text",
]
