"""An XML document read within bounds, for every XML file a user may hand us (SSP files,
FMI-LS-REF manifests and experiment documents, SRMD records): at most MAX_ELEMENTS elements and
MAX_DEPTH levels, no DOCTYPE (so no entity is ever defined or expanded), nothing fetched from
the network. A refusal is one line naming the file, in the words of the kind of file it is."""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import Any

from lxml import etree

__all__ = ["MAX_DEPTH", "MAX_ELEMENTS", "XmlKind", "XmlRefused", "read_xml"]

MAX_ELEMENTS = 100_000  # our largest documents have a few hundred
MAX_DEPTH = 64


class XmlRefused(ValueError):
    """A document that is not read: str() is the one-line reason, naming the file and the fix."""


@dataclass(frozen=True)
class XmlKind:
    """How a refusal names the kind of document: `name` as in "an SSP file is smaller", and `fix`,
    what to do about a document that is not well-formed XML."""

    name: str
    fix: str


def read_xml(data: bytes, where: str, kind: XmlKind) -> Any:
    """The root element (lxml) of the XML document `data`, read as the module docstring says;
    XmlRefused naming `where` otherwise."""
    counted = depth = 0
    events = etree.iterparse(
        io.BytesIO(data),
        events=("start", "end"),
        resolve_entities=False,
        no_network=True,
        huge_tree=False,
        load_dtd=False,
    )
    try:
        for event, _ in events:
            if event == "end":
                depth -= 1
                continue
            counted, depth = counted + 1, depth + 1
            if counted > MAX_ELEMENTS:
                raise XmlRefused(f"{where}: more than {MAX_ELEMENTS} XML elements (refused; {kind.name} is smaller)")
            if depth > MAX_DEPTH:
                raise XmlRefused(
                    f"{where}: XML nested deeper than {MAX_DEPTH} levels (refused; {kind.name} is flatter)"
                )
        root = events.root
    except etree.XMLSyntaxError as error:
        raise XmlRefused(f"{where}: not well-formed XML ({' '.join(str(error).split())}); {kind.fix}") from None
    if root.getroottree().docinfo.doctype or any(node.tag is etree.Entity for node in root.iter()):
        raise XmlRefused(f"{where}: a DOCTYPE or entity reference (refused: {kind.name} needs neither; remove it)")
    return root
