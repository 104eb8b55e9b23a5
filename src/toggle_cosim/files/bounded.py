"""Reading an input file: it must be a regular file, and only so much of it is read.

Every file the tool reads (scenario, sweep, tolerances, trace CSV, input table, run.json) goes through
`read_bounded`, which opens without blocking (a FIFO or a device is refused, never waited on),
checks that it is a regular file, and reads at most its limit: a larger file is refused with a
message that names the limit. The limits are generous for real files and small against
`/dev/zero`, a FIFO, or a mistaken multi-gigabyte argument.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

MiB = 1 << 20
YAML_LIMIT = 1 * MiB  # scenario, sweep and tolerance files: a few KB in practice
JSON_LIMIT = 16 * MiB  # run.json
CSV_LIMIT = 1024 * MiB  # trace CSV files (a 2 GB output limit applies when writing them: resources)
TABLE_LIMIT = 64 * MiB  # an input's CSV table (time and value columns: a run of 100 s at 1 kHz is ~4 MB)
MODEL_DESCRIPTION_LIMIT = 16 * MiB  # modelDescription.xml inside an FMU (ours is ~0.5 MB)


class InputFileError(ValueError):
    """A file that cannot be read as input; str() is the one-line message, naming the file."""


def _size(limit: int) -> str:
    return f"{limit // MiB} MiB" if limit >= MiB else f"{limit} bytes"


def link_problem(path: Path | str) -> str | None:
    """What is wrong with `path` if it is a symbolic link that leads nowhere (dangling, or in a
    loop); None for anything else."""
    path = Path(path)
    if not path.is_symlink():
        return None
    try:
        os.stat(path)
    except OSError as error:
        if error.errno == errno.ELOOP:
            return "a symbolic link in a loop"
        return f"a symbolic link to {os.readlink(path)}, which does not exist"
    return None


def file_problem(path: Path | str) -> str | None:
    """Why `path` cannot be read as an input file (no such file, a link that leads nowhere, a
    directory, a device or FIFO), or None for a regular file (or a link to one)."""
    path = Path(path)
    link = link_problem(path)
    if link:
        return f"is {link}"
    try:
        info = os.stat(path)
    except FileNotFoundError:
        return "no such file"
    except OSError as error:
        return f"cannot be read ({error.strerror or error})"
    if stat.S_ISDIR(info.st_mode):
        return "is a directory"
    if not stat.S_ISREG(info.st_mode):
        return "is not a regular file (a FIFO, device or socket)"
    return None


def read_bounded(path: Path | str, limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file `path`, if it has at most `limit` of them."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputFileError(f"{path}: no such {what}") from None
    except IsADirectoryError:
        raise InputFileError(f"{path}: is a directory, not a {what}") from None
    except OSError as error:
        raise InputFileError(f"{path}: cannot read the {what} ({error.strerror or error})") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise InputFileError(f"{path}: is a directory, not a {what}")
        if not stat.S_ISREG(info.st_mode):
            raise InputFileError(f"{path}: is not a regular file (a FIFO, device or socket); give the {what} itself")
        if info.st_size > limit:
            raise InputFileError(f"{path}: the {what} is {info.st_size} bytes, over the limit of {_size(limit)} for it")
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, min(1 << 20, limit + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
            if total > limit:  # grew while being read
                raise InputFileError(f"{path}: the {what} is over the limit of {_size(limit)} for it")
        return b"".join(chunks)
    except OSError as error:
        raise InputFileError(f"{path}: cannot read the {what} ({error.strerror or error})") from None
    finally:
        os.close(fd)


def read_text_bounded(path: Path | str, limit: int, what: str = "file", encoding: str = "utf-8") -> str:
    raw = read_bounded(path, limit, what)
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as error:
        raise InputFileError(f"{path}: not UTF-8 text (byte {error.start}); save the {what} as UTF-8") from None
