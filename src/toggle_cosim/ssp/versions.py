"""What SSP 2.0 adds to SSP 1.0, as toggle-cosim reads and writes it (docs/ssp.md, "SSP 2.0").

SSP 2.0 keeps SSP 1.0's namespaces, and every 1.0 document is a valid 2.0 document; a document
says its version in its `version` attribute (`checks.VERSIONS`), and is checked against that
version's schemas. What 2.0 adds:

* the FMI 3 number types, for connectors and parameter values: `Float64` and `Float32` are Real,
  `Int8` ... `UInt64` are Integer (`family`); `String`, `Enumeration` and `Binary` values, which
  our master cannot pass, are refused where they would be used, naming the type;
* arrays (`Dimension`, or a value attribute holding a list), clocks (a `Clock` connector, or a
  connector associated with a clock) and Scheduled Execution components: refused, one line each
  naming the construct, the element and the file (`refuse_array`, `refuse_clocks`, and the
  reader's check of a component's implementation);
* `MetaData` and `Signature` elements: kept as they are written (`MetaData`, `Signature`,
  `metadata_of`, `signatures_of`), reported in run.json and readable from Python; nothing reads
  them to decide what runs, and none is required.

The writer's types: SSP 1.0 documents say Real, Integer, Boolean; SSP 2.0 documents say what
OMSimulator writes, Float64, Int32 (FMI 2.0's Integer is 32-bit) and Boolean (`written_type`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from lxml import etree

from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import Element, SspError
from toggle_cosim.system.interfaces import REAL_TYPES

__all__ = [
    "FAMILIES",
    "MetaData",
    "Signature",
    "family",
    "metadata_of",
    "refuse_array",
    "refuse_clocks",
    "signatures_of",
    "type_element",
    "written_type",
]

NS = layout.NAMESPACES
INTEGERS = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
# each type element of SSP 1.0 and 2.0 (connectors, parameter values; FMI 2.0 and 3.0 variable
# types have the same names) -> the kind of value it is
FAMILIES = {
    **dict.fromkeys(REAL_TYPES, "Real"),
    **dict.fromkeys(INTEGERS, "Integer"),
    "Boolean": "Boolean",
    "String": "String",
    "Enumeration": "Enumeration",
    "Binary": "Binary",
    "Clock": "Clock",
}
_WRITTEN = {
    "1.0": {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean"},
    "2.0": {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"},
}


def family(type_name: str | None) -> str | None:
    """The kind of value a type element (or an FMU variable type) holds: Real, Integer, Boolean,
    String, Enumeration, Binary or Clock; None for a name that is no type."""
    return FAMILIES.get(type_name) if type_name is not None else None


def written_type(kind: str, version: str) -> str:
    """The type element that a value of `kind` (Real, Integer, Boolean) is written as in an SSP
    document of `version`."""
    return _WRITTEN[version][kind]


def type_element(parent: Element) -> Element | None:
    """The type element (ssc:Real, ssc:Float64, ..., ssv:Float64, ...) among `parent`'s children:
    a child in the SSP common or parameter-values namespace whose name is a type."""
    namespaces = (layout.SSC_NS, layout.SSV_NS)
    for child in parent:
        if not isinstance(child.tag, str):
            continue
        name = etree.QName(child)
        if name.namespace in namespaces and name.localname in FAMILIES:
            return child
    return None


def refuse_array(element: Element, what: str, where: str) -> None:
    """SspError if the connector or parameter `element` is an array (SSP 2.0: `Dimension`
    children); `what` names it ("component 'plant''s connector 'x_B'")."""
    if element.find("ssc:Dimension", NS) is not None:
        raise SspError(
            f"{where}: {what} is an array (ssc:Dimension; our master connects and sets scalars only: "
            "give one scalar per value)"
        )


def refuse_clocks(connector: Element, what: str, where: str) -> None:
    """SspError if the connector is a clock (`ssc:Clock` as its type) or is associated with one
    (`ssd:Clock`): SSP 2.0 clocks, which our master does not run."""
    typed = type_element(connector)
    if typed is not None and etree.QName(typed).localname == "Clock":
        raise SspError(
            f"{where}: {what} is a Clock connector (SSP 2.0 clocks are not supported: our master steps at "
            "fixed communication points; remove it)"
        )
    clock = connector.find("ssd:Clock", NS)
    if clock is not None:
        raise SspError(
            f"{where}: {what} is associated with the clock {clock.get('name')!r} (ssd:Clock; SSP 2.0 clocks "
            "are not supported: our master steps at fixed communication points; remove it)"
        )


@dataclass(frozen=True)
class Signature:
    """An SSP 2.0 Signature element as written: its role (authenticity, suitability), MIME type,
    source (None: inline) and inline content (the XML text of its Content, None without)."""

    role: str
    type: str
    source: str | None
    content: str | None

    def record(self) -> dict[str, Any]:
        """What run.json says about it (the content's size, not the content)."""
        return {"role": self.role, "type": self.type, "source": self.source, "content_bytes": _size(self.content)}


@dataclass(frozen=True)
class MetaData:
    """An SSP 2.0 MetaData element as written: its kind (general, quality), MIME type, source
    (None: inline), inline content (the XML text of its Content element, None without) and the
    signatures it carries."""

    kind: str
    type: str
    source: str | None
    content: str | None
    signatures: tuple[Signature, ...] = ()

    def record(self) -> dict[str, Any]:
        """What run.json says about it (the content's size, not the content)."""
        return {
            "kind": self.kind,
            "type": self.type,
            "source": self.source,
            "content_bytes": _size(self.content),
            "signatures": [signature.record() for signature in self.signatures],
        }


def _size(content: str | None) -> int | None:
    return None if content is None else len(content.encode())


def _content(element: Element) -> str | None:
    content = element.find("ssc:Content", NS)
    if content is None:
        return None
    inner = "".join(etree.tostring(child, encoding="unicode") for child in content)
    return (content.text or "") + inner


def signatures_of(owner: Element) -> tuple[Signature, ...]:
    """The ssc:Signature children of `owner` (a root SSD, a component, a MetaData), in order."""
    return tuple(
        Signature(found.get("role", ""), found.get("type", ""), found.get("source"), _content(found))
        for found in owner.iterfind("ssc:Signature", NS)
    )


def metadata_of(owner: Element) -> tuple[MetaData, ...]:
    """The ssc:MetaData children of `owner` (a root SSD, a component), in order, each with its
    signatures."""
    return tuple(
        MetaData(
            found.get("kind", ""), found.get("type", ""), found.get("source"), _content(found), signatures_of(found)
        )
        for found in owner.iterfind("ssc:MetaData", NS)
    )
