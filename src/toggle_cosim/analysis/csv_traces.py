"""Reading trace CSVs strictly: the FMI cross-check layout that FMPy's result CSVs also follow.

A trace is a header of quoted names, "time" first, then one row per sample with time strictly
increasing. Every defect raises `CompareInputError`, whose message is one line naming the file,
the problem and the fix (the command turns it into `error: ...` and exit status 2).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from toggle_cosim.files.traces import Trace

__all__ = ["CompareInputError", "check_finite", "check_trace", "read_trace"]


class CompareInputError(Exception):
    """Bad input to a comparison; the message is one line: file, problem, fix."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


def float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def read_trace(path: Path | str) -> Trace:
    """Read a cross-check CSV strictly; any defect raises CompareInputError naming the file and the fix.
    A value may be `nan` or `inf` (as a run records it), but not its time; `check_finite` refuses
    such a value in a variable that is compared."""
    path = Path(path)
    if not path.exists():
        raise CompareInputError(f"{path}: no such file; check the path (traces are written by `toggle-cosim run`)")
    if path.is_dir():
        raise CompareInputError(f"{path}: is a directory, not a CSV file; give the trace's .csv file")
    from toggle_cosim.files.bounded import CSV_LIMIT, InputFileError, read_bounded

    try:
        raw = read_bounded(path, CSV_LIMIT, "trace CSV")  # a regular file, at most CSV_LIMIT bytes
    except InputFileError as error:
        raise CompareInputError(str(error)) from error
    if b"\x00" in raw:
        raise CompareInputError(
            f'{path}: is a binary file, not a CSV; give a CSV with a header of quoted names, "time" first'
        )
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        bad = raw[error.start]
        raise CompareInputError(
            f"{path}: is not UTF-8 text (byte 0x{bad:02x} at offset {error.start}); re-save it as UTF-8"
        ) from error

    reader = csv.reader(io.StringIO(text, newline=""), skipinitialspace=True)
    rows: list[list[str]] = []
    lines: list[int] = []
    try:
        for row in reader:
            if not row or all(not cell.strip() for cell in row):
                continue  # blank line
            rows.append([cell.strip() for cell in row])
            lines.append(reader.line_num)
    except csv.Error as error:
        raise CompareInputError(
            f"{path}: is not a valid CSV (line {reader.line_num}: {error}); fix the quoting"
        ) from error

    if not rows:
        raise CompareInputError(
            f'{path}: is empty; a trace needs a header of quoted names ("time" first) and one row per sample'
        )
    names = tuple(rows[0])
    if len(names) == 1:
        separator = next((s for s in (";", "\t", "|") if s in names[0]), None)
        if separator is not None:
            raise CompareInputError(
                f"{path}: is separated by {separator!r}, not commas; the cross-check layout uses commas"
            )
        raise CompareInputError(
            f'{path}: has a single column ({names[0][:40]!r}), so it is not a trace CSV; expected "time" and variables'
        )
    if all(float_or_none(name) is not None for name in names):
        raise CompareInputError(
            f'{path}: has no header (line {lines[0]} is numbers); add a first line of quoted names, "time" first'
        )
    empty = [i + 1 for i, name in enumerate(names) if not name]
    if empty:
        raise CompareInputError(f"{path}: header column {empty[0]} has no name; name every column")
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise CompareInputError(f"{path}: column {name!r} appears twice in the header; keep one")
        seen.add(name)
    if names[0] != "time":
        if "time" in names:
            raise CompareInputError(f'{path}: "time" is column {names.index("time") + 1}; it must be the first column')
        near = next((n for n in names if n.lower() == "time"), None)
        if near is not None:
            raise CompareInputError(f'{path}: no "time" column (found {near!r}); rename it to "time", lowercase')
        shown = ",".join(names[:4]) + (",..." if len(names) > 4 else "")
        raise CompareInputError(f'{path}: no "time" column (header is {shown}); the first column must be "time"')

    body = rows[1:]
    if not body:
        raise CompareInputError(f"{path}: has a header but no data rows (empty trace); write at least two samples")
    for row, line in zip(body, lines[1:], strict=True):
        if len(row) != len(names):
            raise CompareInputError(
                f"{path}: line {line} has {len(row)} values but the header has {len(names)} columns; "
                "every row needs one value per column"
            )
    try:
        data = np.array(body, dtype=float)
    except ValueError:
        data = None
    if data is None or not np.all(np.isfinite(data[:, 0])):
        for row, line in zip(body, lines[1:], strict=True):
            for name, cell in zip(names, row, strict=True):
                if float_or_none(cell) is None:
                    raise CompareInputError(
                        f"{path}: line {line}, column {name!r}: {cell[:30]!r} is not a number; "
                        "write plain numbers (booleans as 0 and 1)"
                    )
            if not math.isfinite(float(row[0])):
                raise CompareInputError(
                    f"{path}: line {line}: time {row[0]!r} is not finite; every sample needs a finite time"
                )
    assert data is not None
    if data.shape[0] < 2:
        raise CompareInputError(f"{path}: has a single sample; a trace needs at least two to span a time interval")
    steps = np.diff(data[:, 0])
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise CompareInputError(
            f"{path}: time is not strictly increasing at line {lines[1 + i]} "
            f"(t = {data[i, 0]:.17g} after {data[i - 1, 0]:.17g}); drop repeated or out-of-order rows"
        )
    return Trace(names, data)


def check_finite(trace: Trace, names: Sequence[str], label: str) -> None:
    """The columns `names` hold finite values only: a funnel cannot hold NaN or an infinity. A
    trace may hold them in its other columns (a run records a NaN as a value), which are not
    compared; CompareInputError names the first sample, its time and the variable."""
    data = np.asarray(trace.data)[:, [trace.names.index(name) for name in names]]
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        row, column = (int(k) for k in bad[0])
        raise CompareInputError(
            f"{label}: sample {row + 1} (t = {float(trace.data[row, 0]):.6g} s), variable {names[column]!r} is "
            f"{float(data[row, column])!r}, not finite: a compared variable must be finite (the run diverged or "
            "recorded NaN there); fix the run, or leave that variable out of the reference"
        )


def check_trace(trace: Trace, label: str) -> None:
    """The checks of `read_trace` for a Trace built in memory."""
    data = np.asarray(trace.data)
    if data.ndim != 2 or data.shape[1] != len(trace.names):
        raise CompareInputError(f"{label}: data has shape {data.shape} but there are {len(trace.names)} names")
    if not trace.names or trace.names[0] != "time":
        raise CompareInputError(f'{label}: the first column must be "time", not {trace.names[:1]}')
    if len(set(trace.names)) != len(trace.names):
        raise CompareInputError(f"{label}: column names repeat; keep one of each")
    if data.shape[0] < 2:
        raise CompareInputError(f"{label}: has {data.shape[0]} samples (empty trace); need at least two")
    if not np.all(np.isfinite(data[:, 0])):
        row = int(np.flatnonzero(~np.isfinite(data[:, 0]))[0])
        raise CompareInputError(f"{label}: row {row + 1}: time {data[row, 0]!r} is not finite")
    steps = np.diff(data[:, 0])
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise CompareInputError(f"{label}: time is not strictly increasing at row {i + 1} (t = {data[i, 0]:.17g})")
