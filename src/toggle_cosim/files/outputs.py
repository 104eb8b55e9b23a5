"""Writing the files a command produces without harming what lies at their paths: every output
(traces, run records, JUnit and Markdown reports, figures, FMUs, sweep tables) goes through here.

* A file is written to a temporary name that `tempfile.mkstemp` makes in the destination's
  folder (unique, created by this process: nothing planted under it is followed), then renamed
  over the destination. A reader sees the old file or the whole new one; a failed or
  interrupted write leaves nothing behind.
* A destination that exists and is not a regular file (a folder, a symbolic link, a FIFO, a
  socket, a block device) is refused with one line (`OutputError`, exit 2 in the CLI): a link
  is neither followed nor replaced.
* A regular file is replaced only when it is of the output's own kind (`OutputKind`: an FMU
  over an FMU, an SSP over an SSP, a PNG over a PNG, a CSV table over a CSV table, ...), told by
  its content, not its name, or when it is empty. Anything else (a scenario file, notes, an FMU
  where an SSP goes) is refused with one line naming the path, the kind and the fix: a re-run
  replaces its own results and nothing the user wrote.
* Written through, by design: the paths /dev/stdout and /dev/stderr (the command's own output
  streams, whatever they are connected to) and a character device named directly (/dev/null,
  a terminal), opened without creating or truncating anything and without following a link.
* A lock is taken on the folder itself (`folder_lock`): no lock file, so no fixed name to plant.
* A name built from the user's words (axis names and values) is kept within the file system's
  limit of NAME_MAX bytes per name (`fitting_name`): cut short and ended by a hash of the whole.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import re
import stat
import sys
import tempfile
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
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


SNIFF_BYTES = 65536  # how much of an existing file is read to tell its kind


@dataclass(frozen=True)
class OutputKind:
    """What an output is (`name`, as the messages say it) and how an existing file is told to
    be one (`recognize`, on its path: a bounded read of its content), so that a re-run may
    replace it."""

    name: str
    recognize: Callable[[Path], bool]


def _head(path: Path) -> bytes:
    try:
        with open(path, "rb") as stream:
            return stream.read(SNIFF_BYTES)
    except OSError:
        return b""


def _zip_with(member: str) -> Callable[[Path], bool]:
    def recognize(path: Path) -> bool:
        try:
            with zipfile.ZipFile(path) as archive:
                return member in archive.namelist()
        except (OSError, zipfile.BadZipFile, ValueError):
            return False

    return recognize


def _zip_of(suffix: str) -> Callable[[Path], bool]:
    def recognize(path: Path) -> bool:
        try:
            with zipfile.ZipFile(path) as archive:
                names = archive.namelist()
        except (OSError, zipfile.BadZipFile, ValueError):
            return False
        return bool(names) and all(name.endswith(suffix) for name in names)

    return recognize


def _starts(*signatures: bytes) -> Callable[[Path], bool]:
    return lambda path: _head(path).lstrip().startswith(signatures)


_CSV_NAME = re.compile(r'^"?[A-Za-z_][^",\s]*"?$')


def _csv_table(path: Path) -> bool:
    """A header line of two or more comma-separated column names (quoted or not)."""
    line = _head(path).split(b"\n", 1)[0].rstrip(b"\r")
    try:
        fields = line.decode("utf-8").split(",")
    except UnicodeDecodeError:
        return False
    return len(fields) >= 2 and all(_CSV_NAME.match(field.strip()) for field in fields)


def _markdown_summary(path: Path) -> bool:
    """A Markdown summary as this project writes them: a heading or a table row first, and a
    table (a `|---` row) in it."""
    head = _head(path)
    return head.startswith((b"# ", b"| ")) and any(line.startswith(b"|---") for line in head.splitlines())


FMU = OutputKind("an FMU (a zip archive with a modelDescription.xml)", _zip_with("modelDescription.xml"))
SSP = OutputKind("an SSP (a zip archive with a SystemStructure.ssd)", _zip_with("SystemStructure.ssd"))
PNG = OutputKind("a PNG image", _starts(b"\x89PNG\r\n\x1a\n"))
PARQUET = OutputKind("a Parquet table", _starts(b"PAR1"))
CSV = OutputKind("a CSV table (a header of column names)", _csv_table)
JSON = OutputKind("a JSON object", _starts(b"{"))
JUNIT = OutputKind("a JUnit XML report", lambda path: b"<testsuite" in _head(path))
MARKDOWN = OutputKind("a Markdown summary (a '# ' heading or a '| ' table row first, and a table)", _markdown_summary)
HTML = OutputKind("an HTML page", _starts(b"<!DOCTYPE html", b"<!doctype html", b"<html"))
NPZ = OutputKind("a NumPy .npz archive", _zip_of(".npy"))
MAT = OutputKind("a MATLAB .mat file (version 5)", _starts(b"MATLAB 5.0 MAT-file"))
INVARIANTS = OutputKind(
    "a reference's invariants file (an 'invariants:' mapping)",
    lambda path: any(line.startswith(b"invariants:") for line in _head(path).splitlines()),
)
SETTINGS = OutputKind(
    "a reference's settings file (StartTime, ... lines)", _starts(b"StartTime,", b"StopTime,", b"StepSize,")
)
SRMD_NAMESPACE = "http://ssp-standard.org/SSPTraceability1/SimulationResourceMetaData"  # SSP Traceability's SRMD
SRMD = OutputKind("a provenance record (an SRMD file)", lambda path: SRMD_NAMESPACE.encode() in _head(path))
SQLITE_HEADER = b"SQLite format 3\x00"  # the first 16 bytes of every SQLite 3 database
SQLITE = OutputKind("an SQLite database", lambda path: _head(path).startswith(SQLITE_HEADER))

NAME_MAX = 255  # bytes in one name of a path (Linux, macOS and Windows file systems)
_HASH_DIGITS = 12


def fitting_name(stem: str, suffix: str = "", limit: int = NAME_MAX) -> str:
    """`stem + suffix` when it fits in `limit` bytes (UTF-8); else the stem cut short and ended
    by `~` and 12 hex digits of its SHA-256, so that the name fits: the same stem always gives
    the same name, and two stems that differ give different names (the hash)."""
    name = stem + suffix
    if len(name.encode()) <= limit:
        return name
    tag = "~" + hashlib.sha256(stem.encode()).hexdigest()[:_HASH_DIGITS]
    room = limit - len(suffix.encode()) - len(tag)
    if room < 0:
        raise ValueError(f"a suffix of {len(suffix.encode())} bytes leaves no room in a name of {limit} bytes")
    cut = stem.encode()[:room].decode("utf-8", errors="ignore")  # never half a character
    return cut + tag + suffix


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
    (stat.S_ISCHR, "a character device"),
)


def _written_through(path: Path) -> bool:
    """True if `path` is one of STREAMS or a character device named directly."""
    if str(path) in STREAMS:
        return True
    try:
        return stat.S_ISCHR(os.lstat(path).st_mode)
    except OSError:
        return False


def check_destination(
    path: Path | str,
    what: str = "output",
    kind: OutputKind | None = None,
    *,
    through: bool = True,
    fix: str | None = None,
) -> None:
    """Raise OutputError if something that is not a regular file lies at `path` (a character
    device and /dev/stdout, /dev/stderr are written through, unless `through` is False: an output
    that is a file by nature, such as a database, refuses them too; see the module docstring),
    or, given the output's `kind`, a non-empty regular file that is not of that kind; `what`
    names the output in the message, and `fix` says what to do (default: give another file name)."""
    path = Path(path)
    other = fix or f"give another file name for the {what} (or move the file away)"  # a file of another kind
    fix = fix or f"give another file name for the {what}"
    if through and str(path) in STREAMS:
        return
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as error:  # e.g. a parent that is a file: the write will say it, naming the path
        if error.errno in (errno.ENOTDIR, errno.ELOOP, errno.ENAMETOOLONG):
            raise OutputError(path, f"cannot be written ({error.strerror}); {fix}") from error
        raise
    if through and stat.S_ISCHR(mode):
        return
    if stat.S_ISREG(mode):
        if kind is not None and os.lstat(path).st_size > 0 and not kind.recognize(path):
            raise OutputError(path, f"exists and is not {kind.name}, so it is not replaced; {other}")
        return
    shape = next((name for test, name in _KINDS if test(mode)), "something else")
    note = " (a link is not followed)" if stat.S_ISLNK(mode) else ""
    raise OutputError(path, f"is {shape}, not a regular file{note}; {fix}")


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
def replacing(path: Path | str, what: str = "output", *, kind: OutputKind) -> Iterator[Path]:
    """The name of a fresh, empty temporary file in `path`'s folder (made by mkstemp) for a
    writer that wants a file name (matplotlib, junitparser, pyarrow); when the block ends
    without an exception, the file gets the usual mode, is synced and renamed over `path`;
    otherwise it is removed. OutputError (naming `what`) before anything is written if `path` is
    not missing, empty or a regular file of the output's `kind`; for a path that is written
    through, the temporary file's bytes are copied there instead."""
    path = Path(path)
    check_destination(path, what, kind)
    through = _written_through(path)
    folder = Path(tempfile.gettempdir()) if through else path.parent
    folder.mkdir(parents=True, exist_ok=True)
    # mkstemp adds 8 letters and the suffix: the prefix is cut so that a name that fits gives one that fits
    prefix = f".{fitting_name(path.name, limit=NAME_MAX - 32)}."
    handle, name = tempfile.mkstemp(prefix=prefix, suffix=".partial", dir=folder)
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
        check_destination(path, what, kind)  # a link (or another file) put there meanwhile is refused, not replaced
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_file(
    path: Path | str, write: Callable[[IO[Any]], Any], binary: bool = False, what: str = "output", *, kind: OutputKind
) -> Path:
    """Call `write(stream)` on a stream whose bytes end at `path` as `replacing` says (UTF-8 text
    with "\\n" line ends, or bytes if `binary`), and return `path`."""
    path = Path(path)
    with replacing(path, what, kind=kind) as temporary:
        opened = open(temporary, "wb") if binary else open(temporary, "w", encoding="utf-8", newline="\n")  # noqa: SIM115
        with opened as stream:
            write(stream)
    return path


def write_text(path: Path | str, text: str, what: str = "output", *, kind: OutputKind) -> Path:
    """`write_file` of a whole text."""
    return write_file(path, lambda stream: stream.write(text), what=what, kind=kind)


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
    "CSV",
    "FILE_MODE",
    "FMU",
    "HTML",
    "INVARIANTS",
    "JSON",
    "JUNIT",
    "MARKDOWN",
    "MAT",
    "NAME_MAX",
    "NPZ",
    "PARQUET",
    "PNG",
    "SETTINGS",
    "SQLITE",
    "SRMD",
    "SRMD_NAMESPACE",
    "SQLITE_HEADER",
    "SSP",
    "STREAMS",
    "OutputError",
    "OutputKind",
    "check_destination",
    "fitting_name",
    "folder_lock",
    "replacing",
    "write_file",
    "write_text",
]
