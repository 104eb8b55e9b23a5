"""An SSD's parameter bindings as the values each component gets (SSP 1.0.1, section 5,
ParameterBindings): every binding of a component applies, in document order, later ones taking
priority; then the system's bindings, whose names are hierarchical (`plant.mu`) and which take
priority over the components' own. A binding's values come from an .ssv member of the archive
(`source`, relative to the SSD at the archive's top level) or inline (ParameterValues); a
binding's `prefix` is prepended to its names.

An .ssv that many components bind is read and checked once per opened archive (`bindings_of`
keeps its values by member); a parameter set holds at most MAX_PARAMETERS parameters, and the
values bound in one SSD (every binding of every component and the system, counted as applied)
at most MAX_BOUND_VALUES (`BindingBudget`), so a small archive cannot make the reader apply
millions of values.

Refused, one SspError line each naming the SSD and the binding: a source outside the archive
or resolved against the component (`sourceBase="component"`), a type other than a parameter set,
a ParameterMapping, a value that is not a finite Real, an Integer or a Boolean (SSP 2.0's Float64
and Float32 are Real, Int8 ... UInt64 Integer; its String, Enumeration and Binary are refused),
an array (`Dimension`, or a value attribute that lists more than one value), inline values not
valid against the parameter-values schema of their version, and (checked by the reader against
the FMUs) a name that no component has.
"""

from __future__ import annotations

import math
import struct
import weakref
import zipfile
from dataclasses import dataclass
from pathlib import PurePosixPath

from lxml import etree

from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import Element, SspError, parse_member, schema_problem
from toggle_cosim.ssp.versions import family, refuse_array, type_element

__all__ = ["MAX_BOUND_VALUES", "MAX_PARAMETERS", "Binding", "BindingBudget", "Value", "bindings_of", "merged"]

NS = layout.NAMESPACES
SET_TYPE = "application/x-ssp-parameter-set"
Value = float | int | bool
MAX_PARAMETERS = 10_000  # parameters of one parameter set (ours have a few dozen)
MAX_BOUND_VALUES = 200_000  # values one SSD's bindings apply, over all its components and the system
Values = tuple[tuple[str, Value, str, str | None], ...]
# the values of each .ssv member read from an open archive, without prefix: parsed once however
# many components bind it (the archive object's lifetime; another archive is read afresh)
_READ: weakref.WeakKeyDictionary[zipfile.ZipFile, dict[str, tuple[str | None, Values]]] = weakref.WeakKeyDictionary()


@dataclass
class BindingBudget:
    """How many values an SSD's bindings have applied (MAX_BOUND_VALUES at most); `where` names it."""

    where: str
    spent: int = 0

    def spend(self, count: int) -> None:
        self.spent += count
        if self.spent > MAX_BOUND_VALUES:
            raise SspError(
                f"{self.where}: its parameter bindings apply more than {MAX_BOUND_VALUES} values over its components "
                "(refused; bind each component the values it needs)"
            )


@dataclass(frozen=True)
class Binding:
    """One ParameterBinding: the set's name, where it came from (an archive member, or `inline`),
    and its values as (name, value, kind, unit) with the binding's prefix applied; kind is the
    kind of value (Real, Integer, Boolean: `versions.family` of the SSV element, so SSP 2.0's
    Float64 is Real, Int32 Integer)."""

    set_name: str | None
    source: str
    values: tuple[tuple[str, Value, str, str | None], ...]


def _single(value: float) -> float:
    """`value` rounded to single precision (past its range: infinite, which is then refused)."""
    try:
        return struct.unpack("f", struct.pack("f", value))[0]
    except OverflowError:  # Python versions that refuse to pack it
        return math.copysign(math.inf, value)


def _value(element: Element, kind: str, name: str, where: str) -> Value:
    """The scalar value of a type element of `kind` (Real, Integer, Boolean); SSP 2.0's value
    attribute is a list, and more or fewer than one value is an array, refused."""
    text = element.get("value") or ""
    items = text.split()
    if len(items) != 1:
        raise SspError(
            f"{where}: parameter {name!r} has {len(items)} values ({text!r}: an array; our master sets scalars "
            "only: give one value)"
        )
    if kind == "Boolean":
        return items[0] in ("true", "1")
    if kind == "Integer":
        return int(items[0])
    value = float(items[0])
    if etree.QName(element).localname == "Float32" and math.isfinite(value):  # xs:float: the single-precision number
        value = _single(value)
    if not math.isfinite(value):
        raise SspError(f"{where}: {name} = {value!r} is not a finite number (give a finite value)")
    return value


def _values(parameter_set: Element, prefix: str, where: str) -> Values:
    found = []
    for parameter in parameter_set.iterfind("ssv:Parameters/ssv:Parameter", NS):
        if len(found) == MAX_PARAMETERS:
            raise SspError(
                f"{where}: more than {MAX_PARAMETERS} parameters in one parameter set (refused; an SSP's set "
                "holds the parameters of its components)"
            )
        name = prefix + parameter.get("name")
        typed = type_element(parameter)
        written = etree.QName(typed).localname if typed is not None else "nothing"
        kind = family(written)
        if kind not in ("Real", "Integer", "Boolean"):
            raise SspError(
                f"{where}: parameter {name!r} is given as {written}; an SSP here sets Real (Float64, Float32), "
                "Integer (Int8 ... UInt64) and Boolean values"
            )
        refuse_array(parameter, f"parameter {name!r}", where)
        found.append((name, _value(typed, kind, name, where), kind, typed.get("unit")))
    return tuple(found)


def _member(source: str, archive: zipfile.ZipFile, where: str) -> str:
    path = PurePosixPath(source)
    member = str(path)
    if ":" in source.split("/", 1)[0] or path.is_absolute() or member not in archive.namelist():
        raise SspError(
            f"{where}: the parameter binding's source {source!r} is not a member of the archive "
            "(give the path of an .ssv inside it, relative to the SSD)"
        )
    return member


def _ssv(archive: zipfile.ZipFile, member: str, path: str) -> tuple[str | None, Values]:
    """The .ssv member's set name and values (no prefix), read and checked once per archive."""
    read = _READ.setdefault(archive, {})
    if member not in read:
        root = parse_member(archive, member, "ssv", f"{path}: {member}")
        read[member] = (root.get("name"), _values(root, "", f"{path}: {member}"))
    return read[member]


def bindings_of(
    owner: Element, archive: zipfile.ZipFile, path: str, where: str, budget: BindingBudget | None = None
) -> list[Binding]:
    """The bindings of a component or system element, in document order; `path` names the SSP
    in messages, `where` the SSD and the element; `budget` counts the values applied."""
    budget = budget if budget is not None else BindingBudget(where)
    found = []
    for binding in owner.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS):
        kind = binding.get("type", SET_TYPE)
        if kind != SET_TYPE:
            raise SspError(f"{where}: a parameter binding of type {kind!r} (only {SET_TYPE} is supported)")
        if binding.find("ssd:ParameterMapping", NS) is not None:
            raise SspError(f"{where}: a parameter binding with a ParameterMapping (not supported; rename in the .ssv)")
        if binding.get("sourceBase", "SSD") != "SSD":
            raise SspError(
                f'{where}: a parameter binding with sourceBase="component" (not supported; put the .ssv in the '
                "archive and give its path from the SSD)"
            )
        prefix = binding.get("prefix", "")
        source = binding.get("source")
        if source:
            member = _member(source, archive, where)
            set_name, values = _ssv(archive, member, path)
            budget.spend(len(values))
            if prefix:
                values = tuple((prefix + name, *rest) for name, *rest in values)
            found.append(Binding(set_name, member, values))
            continue
        inline = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
        if inline is None:
            raise SspError(f"{where}: a parameter binding with neither a source nor inline ParameterValues")
        problem = schema_problem(inline, "ssv")  # an SSP 2.0 SSD's schema leaves inline sets unchecked
        if problem is not None:
            owner_name = f"{etree.QName(owner).localname} {owner.get('name')!r}"
            raise SspError(f"{where}: the inline ParameterValues of {owner_name} are not valid ({problem}); fix them")
        values = _values(inline, prefix, f"{where} (inline values)")
        budget.spend(len(values))
        found.append(Binding(inline.get("name"), "inline", values))
    return found


def merged(bindings: list[Binding]) -> dict[str, tuple[Value, str, str | None]]:
    """The values the bindings give together: later bindings take priority (the standard's rule)."""
    values: dict[str, tuple[Value, str, str | None]] = {}
    for binding in bindings:
        for name, value, kind, unit in binding.values:
            values[name] = (value, kind, unit)
    return values
