"""Trace and run-record files: CSV in the FMI cross-check layout, and a JSON run record.

Every file is written through `files.outputs` (a unique temporary name in the same folder,
renamed into place), so a reader never sees a half-written file.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.files.outputs import CSV, JSON, write_file


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


CHUNK_ROWS = 20_000  # rows formatted at a time: memory stays bounded however long the trace
ROW_FORMAT = "%.17g"  # 17 significant digits: every float64 reads back exactly


def recorded_rows(samples: int, every: int = 1) -> np.ndarray:
    """The samples a trace file keeps: every `every`-th one, and always the last."""
    kept = np.arange(0, samples, max(int(every), 1))
    if samples and kept[-1] != samples - 1:
        kept = np.append(kept, samples - 1)
    return kept


def write_csv(path: Path, trace: Trace, every: int = 1) -> None:
    """FMI cross-check CSV: a header of quoted names, "time" first, then one row per sample
    (every `every`-th sample and the last one: the scenario key record_every), written by
    numpy's `savetxt` with 17 significant digits (`ROW_FORMAT`), which read back as the very
    same float64 values, in chunks of CHUNK_ROWS rows."""

    def write(stream: Any) -> None:
        stream.write(",".join(f'"{name}"' for name in trace.names) + "\n")
        kept = None if every <= 1 else recorded_rows(trace.data.shape[0], every)
        rows = trace.data.shape[0] if kept is None else kept.size
        for start in range(0, rows, CHUNK_ROWS):
            chunk = (
                trace.data[start : start + CHUNK_ROWS] if kept is None else trace.data[kept[start : start + CHUNK_ROWS]]
            )
            np.savetxt(stream, chunk, fmt=ROW_FORMAT, delimiter=",")

    write_file(Path(path), write, kind=CSV)


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
    write_file(Path(path), lambda stream: json.dump(record, stream, indent=2, sort_keys=False, default=str), kind=JSON)


def select(trace: Trace, names: Sequence[str]) -> Trace:
    return Trace(tuple(names), trace.data[:, [trace.names.index(n) for n in names]])
