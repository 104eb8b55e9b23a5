"""The SHA-256 of a file, read in blocks (an FMU, a trace), and its SHA3-256 (a provenance record's
checksum, as SSP traceability's SRMD names it)."""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from pathlib import Path


def file_sha256(path: Path) -> str:
    """The SHA-256 of the file at `path` (hashlib reads it in blocks)."""
    with Path(path).open("rb") as stream:
        return hashlib.file_digest(stream, "sha256").hexdigest()


def file_sha3_256(path: Path) -> str:
    """The SHA3-256 (FIPS 202) of the regular file at `path`, read in blocks; OSError if it is
    not one: opened without blocking, so a FIFO or a device is refused, never waited on."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(fd, "rb") as stream:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.EINVAL, "not a regular file (a FIFO, device or socket)", str(path))
        return hashlib.file_digest(stream, "sha3_256").hexdigest()


def bytes_sha256(data: bytes) -> str:
    """The SHA-256 of bytes already read (a file's, hashed as it was parsed: no second read)."""
    return hashlib.sha256(data).hexdigest()


__all__ = ["bytes_sha256", "file_sha3_256", "file_sha256"]
