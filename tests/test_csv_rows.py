"""The fast trace writer gives the bytes np.savetxt(fmt="%.17g", delimiter=",") gives: on random
data over the whole double range and on awkward values (signed zeros, subnormals, the extremes,
integer-valued floats, ties at the 18th digit, inf and NaN of either sign)."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest

from toggle_cosim.files import csv_rows
from toggle_cosim.files.traces import Trace, write_csv


def savetxt(data: np.ndarray) -> str:
    stream = io.StringIO()
    np.savetxt(stream, data, delimiter=",", fmt="%.17g")
    return stream.getvalue()


def awkward() -> np.ndarray:
    values = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.1,
        1 / 3,
        2.0**-25,
        2.0**-24,
        2.0**-1074,
        -(2.0**-1074),
        2.2250738585072014e-308,
        1.7976931348623157e308,
        -1.7976931348623157e308,
        1e16,
        1e17,
        9007199254740993.0,
        123456789012345678.0,
        1e-5,
        1e-4,
        0.0001,
        12345.0,
        -150.0,
        5e-324,
        1e300,
        1e-300,
        np.inf,
        -np.inf,
        np.nan,
        -np.nan,
        struct.unpack("<d", struct.pack("<Q", 0xFFF8000000000001))[0],
    ]
    values += [float(2.0**-k) for k in range(1, 80)] + [float(5.0**k) for k in range(1, 30)]
    values += [float(k) * 0.5 for k in range(-50, 50)]
    pad = (-len(values)) % 7
    return np.array(values + [0.0] * pad).reshape(-1, 7)


def random_data(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2**64, size=(400, 35), dtype=np.uint64)  # every bit pattern: any double
    data = bits.view(np.float64).copy()
    data[:100] = rng.normal(size=(100, 35)) * 10.0 ** rng.integers(-30, 30, size=(100, 35))
    data[100:150] = np.round(rng.normal(size=(50, 35)) * 1000)  # integer-valued
    return data


@pytest.mark.parametrize("route", ["c", "python"])
@pytest.mark.parametrize(
    "data",
    [awkward(), random_data(1), random_data(2), np.zeros((0, 35)), np.ones((1, 1))],
    ids=["awkward", "random1", "random2", "empty", "one"],
)
def test_the_rows_are_savetxts_bytes(route: str, data: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> None:
    if route == "python":
        monkeypatch.setenv("TOGGLE_COSIM_FAST_CSV", "0")
    elif csv_rows._load() is None:
        pytest.skip(f"no C route here: {csv_rows._reason}")
    assert csv_rows.format_rows(data) == savetxt(data)


def test_a_trace_file_is_the_same_as_before(tmp_path) -> None:
    """write_csv as it was (np.savetxt in chunks) against write_csv now, with record_every too."""
    data = random_data(3)[:, :5]
    trace = Trace(("time", "a", "b", "c", "d"), data)
    write_csv(tmp_path / "all.csv", trace)
    write_csv(tmp_path / "every5.csv", trace, every=5)
    header = '"time","a","b","c","d"\n'
    assert (tmp_path / "all.csv").read_text() == header + savetxt(data)
    kept = np.append(np.arange(0, 400, 5), 399)
    assert (tmp_path / "every5.csv").read_text() == header + savetxt(data[kept])


def exact_route_data(seed: int) -> np.ndarray:
    """Values where csv_rows.c computes the digits itself (1e-11 <= |v| < 1e17): uniform in the
    mantissa over every decade, decimal fractions, and dyadic numbers m 2^e, whose expansions
    end early, so the 18th digit is often an exact tie (5 followed by zeros) that must round to even."""
    rng = np.random.default_rng(seed)
    size = 100_000
    spread = rng.uniform(-1, 1, size) * 10.0 ** rng.integers(-11, 17, size)
    decimal = rng.integers(-(10**9), 10**9, size) / 10.0 ** rng.integers(0, 12, size)
    dyadic = np.ldexp(rng.integers(1, 2**53, size).astype(np.float64), rng.integers(-90, 4, size))
    ties = np.ldexp(rng.integers(1, 2**20, size).astype(np.float64) * 2 + 1, rng.integers(-60, -20, size))
    return np.concatenate([spread, decimal, dyadic, ties]).reshape(-1, 8)


def test_the_exact_route_gives_pythons_digits() -> None:
    """400,000 values in the range the C formatter computes with 128-bit integers: every one is
    written as Python's correctly rounded '%.17g' writes it (a digit off, a tie rounded away from
    even, or a wrong switch between fixed and exponent notation fails)."""
    if csv_rows._load() is None:
        pytest.skip(f"no C route here: {csv_rows._reason}")
    data = exact_route_data(4)
    expected = "".join(",".join("%.17g" % v for v in row) + "\n" for row in data.tolist())
    assert csv_rows.format_rows(data) == expected
