"""The SHA-256 of a file, read in blocks (an FMU, a trace)."""

from __future__ import annotations

import hashlib
from pathlib import Path


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with Path(path).open("rb") as stream:
        for chunk in iter(lambda: stream.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def bytes_sha256(data: bytes) -> str:
    """The SHA-256 of bytes already read (a file's, hashed as it was parsed: no second read)."""
    return hashlib.sha256(data).hexdigest()


__all__ = ["bytes_sha256", "file_sha256"]
