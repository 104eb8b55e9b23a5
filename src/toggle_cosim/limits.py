"""Every number a user gives outside a scenario file, checked in one place.

Options (`--time-limit`, `--case-timeout`: seconds) and environment variables
(`TOGGLE_COSIM_MAX_OUTPUT`: bytes; `TOGGLE_COSIM_PLANT_MEMORY` and `TOGGLE_COSIM_MAX_LOG`: bytes
with an optional K/M/G suffix) must be finite, positive and within a range that means something: NaN, infinity,
1e300 or a negative size are refused with one line naming the option or variable, the value
and what to give instead (exit 2, before any run). `check_environment()` reads all the
variables at once: the run commands call it before the first run, so a bad value is never
found late (in a plant's child process, where it would only fail that run).
"""

from __future__ import annotations

import math
import os

MAX_SECONDS = 1e6  # about 11.6 days: a wall-clock limit beyond it is a typing error
MAX_BYTES = 1 << 50  # 1 PiB
SIZE_SUFFIXES = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
DEFAULT_MAX_OUTPUT = 2_000_000_000  # bytes a run's trace buffer or CSV may take
DEFAULT_PLANT_MEMORY = 4 << 30  # bytes a plant may allocate beyond the process as forked
DEFAULT_MAX_LOG = 64 << 10  # bytes of a run's own printing (plant, controller) relayed to the console
FLAGS = (
    "TOGGLE_COSIM_KERNEL",
    "TOGGLE_COSIM_FAST_CSV",
    "TOGGLE_COSIM_SUPERVISE",
    "TOGGLE_COSIM_BUILD_CACHE",
)  # "0" or "1"


class LimitError(ValueError):
    """A number out of range or not a number; str() is the one-line reason."""


def seconds(value: object, name: str) -> float:
    """`value` as a number of seconds in (0, MAX_SECONDS]; LimitError naming `name` otherwise."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        number = math.nan
    if not (math.isfinite(number) and 0 < number <= MAX_SECONDS):
        raise LimitError(f"{name} {value}: give a number of seconds above 0 and at most {MAX_SECONDS:g}")
    return number


def byte_size(text: str, name: str, suffixes: bool = False) -> int:
    """`text` as a number of bytes in [1, MAX_BYTES] (with `suffixes`: K, M, G or T allowed)."""
    cleaned = text.strip().upper()
    scale = 1
    if suffixes and cleaned[-1:] in SIZE_SUFFIXES:
        scale, cleaned = SIZE_SUFFIXES[cleaned[-1]], cleaned[:-1]
    try:
        number = float(cleaned) * scale
    except ValueError:
        number = math.nan
    if not (math.isfinite(number) and 1 <= number <= MAX_BYTES):
        unit = "a number of bytes (optionally with K, M, G or T)" if suffixes else "a number of bytes"
        raise LimitError(f"{name}={text!r}: give {unit} from 1 to {MAX_BYTES:.3g}")
    return int(number)


def max_output() -> int:
    """TOGGLE_COSIM_MAX_OUTPUT (bytes), default DEFAULT_MAX_OUTPUT."""
    text = os.environ.get("TOGGLE_COSIM_MAX_OUTPUT", "")
    return byte_size(text, "TOGGLE_COSIM_MAX_OUTPUT") if text.strip() else DEFAULT_MAX_OUTPUT


def max_log() -> int:
    """TOGGLE_COSIM_MAX_LOG (bytes), default DEFAULT_MAX_LOG: what a run's child may print that
    the command relays (`relay`); the rest is counted and dropped."""
    text = os.environ.get("TOGGLE_COSIM_MAX_LOG", "")
    return byte_size(text, "TOGGLE_COSIM_MAX_LOG", suffixes=True) if text.strip() else DEFAULT_MAX_LOG


def plant_memory() -> int:
    """TOGGLE_COSIM_PLANT_MEMORY (bytes, or with a K/M/G/T suffix), default DEFAULT_PLANT_MEMORY."""
    text = os.environ.get("TOGGLE_COSIM_PLANT_MEMORY", "")
    return byte_size(text, "TOGGLE_COSIM_PLANT_MEMORY", suffixes=True) if text.strip() else DEFAULT_PLANT_MEMORY


def check_environment() -> None:
    """Every variable above and the on/off FLAGS ("0" or "1", or unset);
    LimitError for the first bad one."""
    max_output()
    max_log()
    plant_memory()
    for name in FLAGS:
        value = os.environ.get(name)
        if value is not None and value.strip() not in ("0", "1"):
            raise LimitError(f"{name}={value!r}: give 0 (off) or 1 (on), or leave it unset")


__all__ = [
    "LimitError",
    "byte_size",
    "check_environment",
    "max_log",
    "max_output",
    "plant_memory",
    "seconds",
]
