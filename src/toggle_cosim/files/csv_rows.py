"""The rows of a trace as CSV text, byte for byte what `np.savetxt(stream, data, fmt="%.17g",
delimiter=",")` writes, only faster.

Formatting 17 significant digits is the whole cost of writing a trace (about 1-2 us a value in
Python, 35 values a sample); np.savetxt adds a Python call per row on top. Here a small C
function (`csv_rows.c`) formats a whole block: the digits of the values a trace holds come exact
from 128-bit integer arithmetic (about 0.08 us a value), any other value from the C library's
`snprintf("%.17g")` (correctly rounded, like Python's: about 0.4 us). It is compiled once per
machine with the C compiler the FMU build uses and cached beside the compiled loop
(`~/.cache/toggle-cosim`, or `$TOGGLE_COSIM_CACHE`). NaN is written "nan" whatever its sign
bit, as Python writes it. Without a C compiler (or with TOGGLE_COSIM_FAST_CSV=0) one
format string per block is applied to the Python floats instead: the same bytes, a little faster
than np.savetxt. `tests/test_csv_rows.py` compares both with np.savetxt on random and awkward data.
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path
from typing import Any

from toggle_cosim.native import cached_library

FLAGS = ("-O2", "-shared", "-fPIC", "-std=c99")
SOURCE = (Path(__file__).parent / "csv_rows.c").read_text(encoding="utf-8")
BYTES_PER_VALUE = 32  # "-1.2345678901234567e-308," is 25

_library: Any = None
_reason: str | None = None


def _build() -> Path:
    """The formatter's library (cached: `native`)."""
    return cached_library(SOURCE, "csv-rows", FLAGS)


def _load() -> Any:
    global _library, _reason
    if _library is None and _reason is None:
        try:
            library = ctypes.CDLL(str(_build()))
            library.format_rows.argtypes = [
                ctypes.c_void_p,
                ctypes.c_long,
                ctypes.c_long,
                ctypes.c_void_p,
                ctypes.c_long,
            ]
            library.format_rows.restype = ctypes.c_long
            _library = library
        except Exception as error:  # noqa: BLE001 - the Python route gives the same bytes
            _reason = str(error)
    return _library


def format_rows_python(data: Any) -> str:
    """The rows as np.savetxt(fmt="%.17g", delimiter=",") writes them: one format per block."""
    rows, columns = data.shape
    if rows == 0:
        return ""
    return ((",".join(["%.17g"] * columns) + "\n") * rows) % tuple(data.ravel().tolist())


def format_rows_bytes(data: Any) -> bytes | memoryview:
    """The rows of a 2-D float64 array as np.savetxt(fmt="%.17g", delimiter=",") writes them,
    as ASCII bytes (with the C route a view of the buffer it wrote: no copy)."""
    import numpy as np

    library = None if os.environ.get("TOGGLE_COSIM_FAST_CSV", "1") == "0" else _load()
    if library is None or data.dtype != np.float64 or data.ndim != 2:
        return format_rows_python(data).encode("ascii")
    block = np.ascontiguousarray(data)
    rows, columns = block.shape
    if rows == 0 or columns == 0:
        return format_rows_python(data).encode("ascii")
    capacity = rows * columns * BYTES_PER_VALUE + 1
    buffer = np.empty(capacity, dtype=np.uint8)
    used = library.format_rows(block.ctypes.data, rows, columns, buffer.ctypes.data, capacity)
    if used < 0:  # cannot happen with 32 bytes a value; the Python route then
        return format_rows_python(data).encode("ascii")
    return memoryview(buffer)[:used]


def format_rows(data: Any) -> str:
    """The rows of a 2-D float64 array as np.savetxt(fmt="%.17g", delimiter=",") writes them."""
    return bytes(format_rows_bytes(data)).decode("ascii")
