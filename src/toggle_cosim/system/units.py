"""What a unit means and how a value moves between two units: the one definition that the
master (`cosim.systems`) and the SSP reader (`ssp.wiring`) both use.

A unit's meaning is its SI base-unit exponents, then the factor and offset of the FMI
`BaseUnit` (a value v in the unit is factor·v + offset in SI base units). It is read from the
FMU's UnitDefinitions; a unit they do not define is read by its symbols (`fmu_export.units`),
except one with a scaled symbol (`g`, `deg`), whose factor the symbols do not give: that one is
unknown unless defined.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

from toggle_cosim.fmu_export.units import UnitError, base_exponents

__all__ = ["BASE", "Meaning", "UnitDefinitionError", "conversion", "defined_meaning", "meaning", "unit_meaning"]

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
Meaning = tuple[float, ...]  # the SI exponents of BASE, then factor and offset
# unit symbols `fmu_export.units` reads as a base unit although they are a multiple of it (g is
# 0.001 kg, deg pi/180 rad): a unit written with one has no meaning here unless a Unit defines it
_SCALED = re.compile(r"(^|[./])(g|deg)(-?\d+)?(?=$|[./])")


class UnitDefinitionError(ValueError):
    """A unit defined with a factor of 0 or a number that is not finite; str() names the unit."""


def meaning(unit: str, exponents: Sequence[object], factor: object, offset: object) -> Meaning:
    """The meaning of a unit's definition (a FMU's UnitDefinitions, an SSD's Units): refused, as
    UnitDefinitionError, unless every number is finite and the factor is not 0 (a factor of 0
    would make every value 0, or a conversion into it divide by 0)."""
    try:
        values = (*(float(e) for e in exponents), float(factor), float(offset))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        values = (math.nan,)
    if not all(math.isfinite(v) for v in values) or values[-2] == 0.0:
        raise UnitDefinitionError(
            f"the unit {unit!r} is defined with factor {factor!r}, offset {offset!r} (a unit's factor is a finite "
            "number other than 0, its offset and exponents finite: fix its definition)"
        )
    return values


def defined_meaning(unit: str, description: Any) -> Meaning | None:
    """The meaning a model description's UnitDefinitions give `unit` (`meaning`: raises
    UnitDefinitionError for a factor of 0 or a number that is not finite), or None."""
    for definition in getattr(description, "unitDefinitions", None) or ():
        if definition.name == unit and definition.baseUnit is not None:
            base = definition.baseUnit
            return meaning(
                unit,
                [getattr(base, key, 0) or 0 for key in BASE],
                base.factor if base.factor is not None else 1.0,
                base.offset or 0.0,
            )
    return None


def unit_meaning(unit: str, description: Any = None) -> Meaning | None:
    """What `unit` means for an FMU (its model description; None: none): its UnitDefinitions,
    else its symbols (factor 1); None for a unit it cannot read or one with a scaled symbol."""
    found = defined_meaning(unit, description)
    if found is not None:
        return found
    if _SCALED.search(unit):
        return None
    try:
        exponents = base_exponents(unit)
    except UnitError:
        return None
    return (*(float(exponents.get(key, 0)) for key in BASE), 1.0, 0.0)


def conversion(start: Meaning, end: Meaning) -> tuple[float, float]:
    """(factor, offset) taking a value in unit `start` to unit `end` (of the same dimension):
    end = (f_s / f_e)·start + (o_s − o_e) / f_e."""
    (f_s, o_s), (f_e, o_e) = start[-2:], end[-2:]
    return f_s / f_e, (o_s - o_e) / f_e
