"""An input's table from a CSV file: a header naming the columns (with units in brackets, if
given), then one row per time.

    time [s],F_E [N]
    0.0,0.0
    0.25,12.5
    ...

The first column is the time, in s (a unit other than s is refused). The value column is the one
the scenario names (`column:`), else the column named as the input, else the second of exactly
two. Its unit, if the header gives one, must be the input's unit in the plant FMU (checked
before the run: `plant.settings`); without one, the values are taken in the input's unit. The
file is read through `files.bounded` (at most TABLE_LIMIT bytes, TABLE_ROWS rows) and hashed as
read, so run.json names the bytes that ran. Its numbers are parsed into float64 arrays (numpy's
C parser; a file it does not take, row by row, which names the bad line): memory is 16 bytes a
row, never a Python object per cell.
"""

from __future__ import annotations

import csv
import functools
import io
import os
import re
import stat
import warnings
from array import array
from pathlib import Path
from typing import Literal

import numpy as np

from toggle_cosim.files.bounded import TABLE_LIMIT, InputFileError, read_bounded
from toggle_cosim.files.checksums import bytes_sha256
from toggle_cosim.signals.definitions import SignalError, Table, TableSource, check_table

TIME_UNIT = "s"
TABLE_ROWS = 4_000_000  # rows of an input's table (an hour at 1 kHz): 64 MB of numbers at most
_HEADER = re.compile(r"^\s*(?P<name>[^\[\]]*?)\s*(?:\[(?P<unit>[^\[\]]*)\])?\s*\Z")


def parse_header(cells: list[str]) -> list[tuple[str, str | None]]:
    """Each header cell as (name, unit or None): `F_E [N]` is ("F_E", "N"), `F_E` ("F_E", None)."""
    parsed = []
    for number, cell in enumerate(cells, start=1):
        match = _HEADER.match(cell)
        if match is None or not match["name"]:
            raise SignalError(f"header column {number} {cell!r} is not a name with an optional [unit]")
        unit = match["unit"].strip() if match["unit"] is not None else None
        parsed.append((match["name"], unit or None))
    return parsed


def _number(cell: str, line: int, name: str) -> float:
    try:
        return float(cell)
    except ValueError:
        raise SignalError(f"line {line}: {name} {cell.strip()!r} is not a number") from None


def read_table(
    path: Path,
    interpolation: Literal["hold", "linear"],
    input_name: str,
    column: str | None = None,
    shown: str | None = None,
) -> Table:
    """The table in the CSV file `path` for the input `input_name`; raise SignalError naming the
    file (as `shown`, default `path`) and the line. Rows must be finite and strictly increasing
    in time (`definitions.check_table`); coverage of the run is checked by the scenario. A file
    read again unchanged (its size, time and inode) gives the same Table, read once: the runs
    of a sweep share it."""
    try:
        status = os.stat(path)
    except OSError:
        status = None
    if status is None or not stat.S_ISREG(status.st_mode):  # read_bounded says what is wrong
        return _read_table(Path(path), interpolation, input_name, column, shown)
    key = (status.st_size, status.st_mtime_ns, status.st_ino, status.st_dev)
    return _read_unchanged(Path(path), key, interpolation, input_name, column, shown)


@functools.lru_cache(maxsize=4)  # a few tables of up to 64 MB each kept
def _read_unchanged(
    path: Path,
    key: tuple[int, ...],
    interpolation: Literal["hold", "linear"],
    input_name: str,
    column: str | None,
    shown: str | None,
) -> Table:
    return _read_table(path, interpolation, input_name, column, shown)


def _read_table(
    path: Path,
    interpolation: Literal["hold", "linear"],
    input_name: str,
    column: str | None,
    shown: str | None,
) -> Table:
    name = shown or str(path)
    try:
        raw = read_bounded(path, TABLE_LIMIT, "CSV table")
        if not raw.isascii():
            raw.decode("utf-8-sig")  # checked whole here, parsed as a stream below
    except InputFileError as error:
        raise SignalError(str(error)) from None
    except UnicodeDecodeError as error:
        raise SignalError(f"{name}: not UTF-8 text (byte {error.start}); save the table as UTF-8") from None
    try:
        return _parse(raw, Path(path), interpolation, input_name, column)
    except SignalError as error:
        raise SignalError(f"{name}: {error}") from None


def _text(raw: bytes, newline: str | None = "") -> io.TextIOWrapper:
    """The file's text as a stream over `raw` (no copy of the bytes, no whole decoded text)."""
    return io.TextIOWrapper(io.BytesIO(raw), encoding="utf-8-sig", newline=newline)


def _header(raw: bytes, input_name: str) -> tuple[list[tuple[str, str | None]], int, int]:
    """The header (`parse_header`) and how many records and physical lines it ends at."""
    reader = csv.reader(_text(raw))
    try:
        for record, row in enumerate(reader, start=1):
            if row:
                return parse_header(row), record, reader.line_num
    except csv.Error as error:
        raise SignalError(f"not a CSV table ({error})") from None
    raise SignalError(f"the file is empty (write a header such as 'time [s],{input_name}' and rows)")


def _parse(
    raw: bytes,
    path: Path,
    interpolation: Literal["hold", "linear"],
    input_name: str,
    column: str | None,
) -> Table:
    header, record, line = _header(raw, input_name)
    names = [n for n, _ in header]
    try:
        float(names[0])
    except ValueError:
        pass
    else:
        raise SignalError(f"line 1 is not a header (name the columns first, e.g. 'time [s],{input_name}')")
    if len(header) < 2 or names[0] != "time":
        raise SignalError(f"the header is {', '.join(names)}: the first column must be time, then the values")
    if header[0][1] not in (None, TIME_UNIT):
        raise SignalError(f"the time column's unit is {header[0][1]!r}; write times in s (time [s])")
    if len(set(names)) != len(names):
        raise SignalError(f"the header names a column twice ({', '.join(names)})")
    if column is None:
        column = input_name if input_name in names else names[1] if len(names) == 2 else None
        if column is None:
            raise SignalError(
                f"no column {input_name!r} among {', '.join(names[1:])} (name the column with the key column:)"
            )
    elif column not in names[1:]:
        raise SignalError(f"no column {column!r} (the value columns are: {', '.join(names[1:])})")
    j = names.index(column)
    columns = _fast_rows(raw, line, len(names), j)
    if columns is None:  # not plain numbers, or a bad row: read row by row, naming the line
        columns = _rows(raw, record, len(names), j, column)
    source = TableSource(str(path), bytes_sha256(raw), column, header[j][1])
    return Table(*columns, interpolation, source)


def _too_long() -> SignalError:
    return SignalError(
        f"more than {TABLE_ROWS} rows (the limit for an input's table; keep one row per change of the input, "
        "or split the run)"
    )


def _fast_rows(raw: bytes, skip: int, width: int, j: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The time and value columns read by numpy's C parser, 8 bytes a number: None where the
    rows are not `width` plain numbers each or fail `check_table` (the row-by-row reader then
    names the line). A table of more than TABLE_ROWS rows is refused after reading one more."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # no rows: the row-by-row reader says so
            data = np.loadtxt(
                _text(raw, newline=None),
                delimiter=",",
                comments=None,
                skiprows=skip,
                dtype=np.float64,
                ndmin=2,
                max_rows=TABLE_ROWS + 1,
            )
    except ValueError:
        return None
    if data.shape[0] > TABLE_ROWS:
        raise _too_long()
    if data.shape[1] != width:
        return None
    times, values = np.ascontiguousarray(data[:, 0]), np.ascontiguousarray(data[:, j])
    del data
    times.flags.writeable = values.flags.writeable = False  # the Table keeps these, no copy
    try:
        check_table(times, values)
    except SignalError:
        return None
    return times, values


def _rows(raw: bytes, header: int, width: int, j: int, column: str) -> tuple[np.ndarray, np.ndarray]:
    """The time and value columns read row by row after the header's record `header` (records
    counted as lines, blank ones included, as the messages name them), into float arrays."""
    times, values, lines = array("d"), array("d"), array("q")
    reader = csv.reader(_text(raw))
    try:
        for number, row in enumerate(reader, start=1):
            if number <= header or not row:
                continue
            if len(times) == TABLE_ROWS:
                raise _too_long()
            if len(row) != width:
                raise SignalError(f"line {number} has {len(row)} fields, the header {width}")
            times.append(_number(row[0], number, "time"))
            values.append(_number(row[j], number, column))
            lines.append(number)
    except csv.Error as error:
        raise SignalError(f"not a CSV table ({error})") from None
    t, v = np.frombuffer(times, dtype=np.float64), np.frombuffer(values, dtype=np.float64)
    check_table(t, v, lambda i: f"line {lines[i]}")
    return t, v
