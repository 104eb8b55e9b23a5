"""Modelica unit strings -> SI base-unit exponents, for the FMI <UnitDefinitions>.

Grammar (Modelica Language Specification 3.6, section 19.1, simplified to what models use):
a unit is `factor` or `numerator/denominator`; a product is factors joined by `.`; a factor is
a symbol with an optional integer exponent (`m2`, `s-1`). "1" is dimensionless.
"""

from __future__ import annotations

import re

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_SYMBOLS: dict[str, dict[str, int]] = {
    "kg": {"kg": 1},
    "g": {"kg": 1},
    "m": {"m": 1},
    "s": {"s": 1},
    "A": {"A": 1},
    "K": {"K": 1},
    "mol": {"mol": 1},
    "cd": {"cd": 1},
    "rad": {"rad": 1},
    "deg": {"rad": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "J": {"kg": 1, "m": 2, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3},
    "Pa": {"kg": 1, "m": -1, "s": -2},
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},
    "Ohm": {"kg": 1, "m": 2, "s": -3, "A": -2},
    "H": {"kg": 1, "m": 2, "s": -2, "A": -2},
    "T": {"kg": 1, "s": -2, "A": -1},
    "Wb": {"kg": 1, "m": 2, "s": -2, "A": -1},
    "Hz": {"s": -1},
}
_FACTOR = re.compile(r"^([A-Za-z]+)(-?\d+)?$")


class UnitError(ValueError):
    """A unit string this module cannot read."""


def _product(text: str) -> dict[str, int]:
    exponents: dict[str, int] = {}
    if text == "1":
        return exponents
    for factor in text.split("."):
        match = _FACTOR.match(factor)
        if match is None or match.group(1) not in _SYMBOLS:
            raise UnitError(f"unknown unit factor {factor!r}")
        power = int(match.group(2) or 1)
        for base, exponent in _SYMBOLS[match.group(1)].items():
            exponents[base] = exponents.get(base, 0) + exponent * power
    return exponents


def base_exponents(unit: str) -> dict[str, int]:
    """The SI base-unit exponents of `unit`, zeros dropped (e.g. "N/A" -> kg 1, m 1, s -2, A -1)."""
    parts = unit.split("/")
    if len(parts) > 2 or not all(parts):
        raise UnitError(f"cannot read unit {unit!r}")
    exponents = _product(parts[0])
    if len(parts) == 2:
        for base, exponent in _product(parts[1]).items():
            exponents[base] = exponents.get(base, 0) - exponent
    return {base: exponents[base] for base in BASE if exponents.get(base, 0) != 0}
