"""An OSError that names its file: a write that fails for a full disk (ENOSPC, EDQUOT, EIO) is
raised by `write()` or `fsync()` without a file name, and the one-line error would not say
which file could not be written."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def naming(path: Path | str) -> Iterator[None]:
    """Inside: an OSError without a file name (pyarrow's included) gets `path` as its file name."""
    try:
        yield
    except OSError as error:
        if error.filename is None:
            error.filename = str(path)
        raise


__all__ = ["naming"]
