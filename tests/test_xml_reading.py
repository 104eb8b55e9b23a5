"""Every XML file a user may hand us is read within the same bounds (`files.xml_reading`): at
most 100,000 elements and 64 levels, no DOCTYPE and no entity, nothing fetched; the refusal is
one line naming the file in the words of its kind: an SSP file, an SRMD record, an FMI-LS-REF
manifest, an experiments document."""

from __future__ import annotations

import pytest

from toggle_cosim.files.xml_reading import MAX_DEPTH, MAX_ELEMENTS, XmlKind, XmlRefused, read_xml
from toggle_cosim.fmi_ls_ref.experiments import read_experiments
from toggle_cosim.fmi_ls_ref.manifest import LsRefError
from toggle_cosim.provenance.srmd import RecordError, from_xml
from toggle_cosim.ssp.checks import SspError, parse_xml

KIND = XmlKind("a test file", "write it again")
DEEP = b"<a>" * (MAX_DEPTH + 1) + b"</a>" * (MAX_DEPTH + 1)
ENTITY = b'<!DOCTYPE a [<!ENTITY e "x">]><a>&e;</a>'
BOMB = b'<!DOCTYPE a [<!ENTITY e "xxxxxxxxxx"><!ENTITY f "&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;">]><a>&f;&f;&f;</a>'


@pytest.mark.parametrize(
    ("data", "says"),
    [
        (
            b"<a>" * (MAX_DEPTH + 1) + b"</a>" * (MAX_DEPTH + 1),
            "XML nested deeper than 64 levels (refused; a test file is flatter)",
        ),
        (b"<a>" + b"<b/>" * MAX_ELEMENTS + b"</a>", "more than 100000 XML elements (refused; a test file is smaller)"),
        (b"<a><b></a>", "not well-formed XML ("),
        (ENTITY, "a DOCTYPE or entity reference (refused: a test file needs neither; remove it)"),
        (BOMB, "a DOCTYPE or entity reference"),
        (b'<!DOCTYPE a SYSTEM "http://example.org/a.dtd"><a/>', "a DOCTYPE or entity reference"),
    ],
)
def test_a_document_out_of_bounds_is_refused_in_one_line(data: bytes, says: str) -> None:
    with pytest.raises(XmlRefused) as refused:
        read_xml(data, "f.xml", KIND)
    line = str(refused.value)
    assert line.startswith("f.xml: ") and says in line and "\n" not in line
    if says.startswith("not well-formed"):
        assert line.endswith("; write it again")


def test_a_document_at_the_bounds_is_read() -> None:
    """64 levels and 100,000 elements exactly are within the bounds."""
    assert read_xml(b"<a>" * MAX_DEPTH + b"</a>" * MAX_DEPTH, "f.xml", KIND).tag == "a"
    root = read_xml(b"<a>" + b"<b/>" * (MAX_ELEMENTS - 1) + b"</a>", "f.xml", KIND)
    assert len(root) == MAX_ELEMENTS - 1


@pytest.mark.parametrize(
    ("read", "error", "words"),
    [
        (lambda data: parse_xml(data, "s.ssd"), SspError, "an SSP file"),
        (lambda data: from_xml(data, "provenance.srmd"), RecordError, "a record"),
        (lambda data: read_experiments(data, "e.xml"), LsRefError, "an experiments document"),
    ],
)
def test_each_reader_refuses_an_entity_and_deep_nesting_in_its_words(read, error, words: str) -> None:  # noqa: ANN001
    """The SSP reader, the SRMD record reader and the FMI-LS-REF experiments reader all read
    through the one bounded reader: an entity is refused before any schema check, and so is a
    document nested too deep, each naming its kind."""
    with pytest.raises(error) as refused:
        read(ENTITY)
    assert f"refused: {words} needs neither" in str(refused.value)
    with pytest.raises(error) as refused:
        read(b"<a>" * 70 + b"</a>" * 70)
    assert f"refused; {words} is flatter" in str(refused.value)
