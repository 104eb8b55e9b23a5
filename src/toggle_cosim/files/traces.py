"""Trace and run-record files: CSV in the FMI cross-check layout, and a JSON run record.

Every file is written to a temporary name in the same folder and renamed into place, so a
reader never sees a half-written file.
"""

from __future__ import annotations

import io
import json
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Trace:
    """Time series of one run: column names (first is "time") and an (n, m) array."""

    names: tuple[str, ...]
    data: np.ndarray

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.names.index(name)]

    @property
    def time(self) -> np.ndarray:
        return self.data[:, 0]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


FILE_MODE = 0o666 & ~_umask()  # what open() would give: mkstemp's files are private (0600)


def atomic_write(path: Path, write: Any, binary: bool = False) -> None:
    """Call `write(stream)` on a temporary file beside `path` (UTF-8 text, or bytes if `binary`),
    then rename it into place (its mode follows the umask, like any file the user creates)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        opened = os.fdopen(handle, "wb") if binary else os.fdopen(handle, "w", encoding="utf-8", newline="\n")
        with opened as stream:
            write(stream)
            stream.flush()
            os.fchmod(stream.fileno(), FILE_MODE)
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


CHUNK_ROWS = 20_000  # rows formatted at a time: memory stays bounded however long the trace


def recorded_rows(samples: int, every: int = 1) -> np.ndarray:
    """The samples a trace file keeps: every `every`-th one, and always the last."""
    kept = np.arange(0, samples, max(int(every), 1))
    if samples and kept[-1] != samples - 1:
        kept = np.append(kept, samples - 1)
    return kept


def write_csv(path: Path, trace: Trace, every: int = 1) -> None:
    """FMI cross-check CSV: a header of quoted names, "time" first, then one row per sample
    (every `every`-th sample and the last one: the scenario key record_every), in chunks; the
    rows are the bytes np.savetxt(fmt="%.17g", delimiter=",") writes (`csv_rows`)."""
    from toggle_cosim.files.csv_rows import format_rows_bytes

    def write(stream: Any) -> None:
        stream.write((",".join(f'"{name}"' for name in trace.names) + "\n").encode("utf-8"))
        if every <= 1:
            for start in range(0, trace.data.shape[0], CHUNK_ROWS):
                stream.write(format_rows_bytes(trace.data[start : start + CHUNK_ROWS]))
            return
        kept = recorded_rows(trace.data.shape[0], every)
        for start in range(0, kept.size, CHUNK_ROWS):
            stream.write(format_rows_bytes(trace.data[kept[start : start + CHUNK_ROWS]]))

    atomic_write(Path(path), write, binary=True)


def read_csv(path: Path) -> Trace:
    """Read a CSV written by `write_csv` (or any cross-check CSV with a header row): a regular
    file of at most `bounded_files.CSV_LIMIT` bytes. Raises ValueError (or InputFileError) naming it."""
    from toggle_cosim.files.bounded import CSV_LIMIT, read_text_bounded

    path = Path(path)
    text = read_text_bounded(path, CSV_LIMIT, "trace CSV")
    header, _, body = text.partition("\n")
    names = tuple(name.strip().strip('"') for name in header.strip().split(","))
    if not body.strip():
        return Trace(names, np.empty((0, len(names))))
    data = np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2)
    if data.shape[1] != len(names):
        raise ValueError(f"{path}: {len(names)} names in the header but {data.shape[1]} columns")
    return Trace(names, data)


def write_json(path: Path, record: dict[str, Any]) -> None:
    atomic_write(Path(path), lambda stream: json.dump(record, stream, indent=2, sort_keys=False, default=str))


def select(trace: Trace, names: Sequence[str]) -> Trace:
    return Trace(tuple(names), trace.data[:, [trace.names.index(n) for n in names]])
