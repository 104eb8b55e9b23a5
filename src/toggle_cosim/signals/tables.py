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
file is read through `files.bounded` (at most TABLE_LIMIT bytes) and hashed as read, so run.json
names the bytes that ran.
"""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path
from typing import Literal

from toggle_cosim.files.bounded import TABLE_LIMIT, InputFileError, read_bounded
from toggle_cosim.files.checksums import bytes_sha256
from toggle_cosim.signals.definitions import SignalError, Table, TableSource, check_table

TIME_UNIT = "s"
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
    in time (`definitions.check_table`); coverage of the run is checked by the scenario."""
    name = shown or str(path)
    try:
        raw = read_bounded(path, TABLE_LIMIT, "CSV table")
        text = raw.decode("utf-8-sig")
    except InputFileError as error:
        raise SignalError(str(error)) from None
    except UnicodeDecodeError as error:
        raise SignalError(f"{name}: not UTF-8 text (byte {error.start}); save the table as UTF-8") from None
    try:
        return _parse(text, raw, Path(path), interpolation, input_name, column, name)
    except SignalError as error:
        raise SignalError(f"{name}: {error}") from None


def _parse(
    text: str,
    raw: bytes,
    path: Path,
    interpolation: Literal["hold", "linear"],
    input_name: str,
    column: str | None,
    name: str,
) -> Table:
    try:
        lines = [(number, row) for number, row in enumerate(csv.reader(io.StringIO(text)), start=1) if row]
    except csv.Error as error:
        raise SignalError(f"not a CSV table ({error})") from None
    if not lines:
        raise SignalError(f"the file is empty (write a header such as 'time [s],{input_name}' and rows)")
    header = parse_header(lines[0][1])
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
    times, values, labels = [], [], []
    for number, row in lines[1:]:
        labels.append(f"line {number}")
        if len(row) != len(names):
            raise SignalError(f"line {number} has {len(row)} fields, the header {len(names)}")
        times.append(_number(row[0], number, "time"))
        values.append(_number(row[j], number, column))
    check_table(times, values, labels)
    source = TableSource(str(path), bytes_sha256(raw), column, header[j][1])
    return Table(tuple(times), tuple(values), interpolation, source)
