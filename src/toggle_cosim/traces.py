"""Trace and run-record files: CSV in the FMI cross-check layout, and a JSON run record.

Every file is written to a temporary name in the same folder and renamed into place, so a
reader never sees a half-written file.
"""

from __future__ import annotations

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


def atomic_write(path: Path, write: Any) -> None:
    """Call `write(stream)` on a temporary file beside `path`, then rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        with os.fdopen(handle, "w", encoding="utf-8", newline="\n") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_csv(path: Path, trace: Trace) -> None:
    """FMI cross-check CSV: a header of quoted names, "time" first, then one row per sample."""

    def write(stream: Any) -> None:
        stream.write(",".join(f'"{name}"' for name in trace.names) + "\n")
        np.savetxt(stream, trace.data, delimiter=",", fmt="%.17g")

    atomic_write(Path(path), write)


def read_csv(path: Path) -> Trace:
    """Read a CSV written by `write_csv` (or any cross-check CSV with a header row)."""
    path = Path(path)
    with path.open(encoding="utf-8") as stream:
        header = stream.readline()
    names = tuple(name.strip().strip('"') for name in header.strip().split(","))
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    if data.shape[1] != len(names):
        raise ValueError(f"{path}: {len(names)} names in the header but {data.shape[1]} columns")
    return Trace(names, data)


def write_json(path: Path, record: dict[str, Any]) -> None:
    atomic_write(Path(path), lambda stream: json.dump(record, stream, indent=2, sort_keys=False, default=str))


def select(trace: Trace, names: Sequence[str]) -> Trace:
    return Trace(tuple(names), trace.data[:, [trace.names.index(n) for n in names]])
