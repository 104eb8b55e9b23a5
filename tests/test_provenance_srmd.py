"""The SRMD provenance record (`toggle_cosim.provenance.srmd`): written valid against the
vendored SRMD schema, read back to the same Record, every changed or missing file named, and a
hostile record refused in one line."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest
from lxml import etree

from toggle_cosim.files.outputs import OutputError
from toggle_cosim.provenance import srmd


def _record(tmp_path: Path) -> tuple[Path, srmd.Record]:
    """A run folder with a trace, a scenario beside it, and the record of both."""
    (tmp_path / "my scenario.yaml").write_text("scenario: demo\n")
    run = tmp_path / "out" / "demo"
    run.mkdir(parents=True)
    (run / "trace.csv").write_text("t,x_B\n0,0.1\n")
    record = srmd.Record(
        name="demo",
        resources=(srmd.resource(tmp_path / "my scenario.yaml", run, "testcase", "scenario", "an editor"),),
        tools=(("python", "3.13.0"), ("toggle-cosim", "0.1.0")),
        settings=(("variant", "nominal"),),
        data=srmd.resource(run / "trace.csv", run, "result", "result"),
        created="2026-01-01T00:00:00Z",
        generation_tool="toggle-cosim 0.1.0",
    )
    path = run / "provenance.srmd"
    srmd.write_record(path, record)
    return path, record


def test_a_record_is_valid_srmd_and_reads_back_the_same(tmp_path: Path) -> None:
    """The file validates against SRMD.xsd (with STC and SSC), names the file by a URI relative to
    itself (percent-encoded) with its SHA3-256, and reads back to an equal Record."""
    path, record = _record(tmp_path)
    root = etree.parse(str(path)).getroot()
    assert srmd.schema_problem(root) is None
    assert root.get("checksumType") == "SHA3-256"
    assert record.resources[0].uri == "../../my%20scenario.yaml"
    assert record.resources[0].checksum == hashlib.sha3_256(b"scenario: demo\n").hexdigest()
    assert srmd.read_record(path) == record
    assert srmd.read_record(path).setting("variant") == "nominal"
    assert srmd.verify_record(path) == []


def test_the_schema_refuses_what_is_not_srmd(tmp_path: Path) -> None:
    """The vendored schema is really applied: a record without its required version is invalid."""
    path, _ = _record(tmp_path)
    root = etree.parse(str(path)).getroot()
    del root.attrib["version"]
    assert "version" in srmd.schema_problem(root)


def test_verify_names_each_changed_and_missing_file(tmp_path: Path) -> None:
    """An edited scenario and a deleted trace: one line each, naming the file."""
    path, _ = _record(tmp_path)
    (tmp_path / "my scenario.yaml").write_text("scenario: edited\n")
    (path.parent / "trace.csv").unlink()
    lines = srmd.verify_record(path)
    assert len(lines) == 2
    assert lines[0].startswith(f"{tmp_path / 'my scenario.yaml'}: changed since the record")
    assert lines[1].startswith(f"{path.parent / 'trace.csv'}: no such file")


def test_a_fifo_named_by_a_record_is_refused_not_waited_on(tmp_path: Path) -> None:
    """A file swapped for a FIFO is named as not a regular file (reading it would block)."""
    path, _ = _record(tmp_path)
    (tmp_path / "my scenario.yaml").unlink()
    os.mkfifo(tmp_path / "my scenario.yaml")
    (line,) = srmd.verify_record(path)
    assert "not a regular file" in line


def _hostile(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "hostile.srmd"
    path.write_text(text)
    return path


VALID_HEAD = (
    '<srmd:SimulationResourceMetaData xmlns:srmd="{srmd}" xmlns:stc="{stc}" xmlns:xlink="{xlink}" '
    'version="1.0.0" name="x">'.format(**srmd.NAMESPACES)
)


def _with_href(href: str) -> str:
    return (
        VALID_HEAD + f'<stc:Classification type="org.toggle-cosim.resource" xlink:href="{href}">'
        '<stc:ClassificationEntry keyword="role">scenario</stc:ClassificationEntry>'
        '<stc:ClassificationEntry keyword="kind">testcase</stc:ClassificationEntry>'
        f'<stc:ClassificationEntry keyword="checksum">{"0" * 64}</stc:ClassificationEntry>'
        "</stc:Classification></srmd:SimulationResourceMetaData>"
    )


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("scenario: not xml\n", "not well-formed XML"),
        ("<a>" * 65 + "</a>" * 65, "XML nested deeper than 64 levels (refused; a record is flatter)"),
        ('<?xml version="1.0"?><run/>', "not an SRMD record"),
        (
            '<!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
            + VALID_HEAD
            + "</srmd:SimulationResourceMetaData>",
            "DOCTYPE",
        ),
        (VALID_HEAD.replace(' version="1.0.0"', "") + "</srmd:SimulationResourceMetaData>", "not a valid SRMD record"),
        (_with_href("/etc/passwd"), "absolute path"),
        (_with_href("file:///etc/passwd"), "scheme or host"),
        (_with_href("https://example.org/plant.fmu"), "scheme or host"),
        (_with_href("a.yaml?x=1"), "query or fragment"),
        (_with_href("a%00.yaml"), "NUL"),
        (_with_href("a.yaml").replace("0" * 64, "abc"), "no SHA3-256 checksum"),
    ],
)
def test_a_hostile_record_is_refused_in_one_line(tmp_path: Path, text: str, says: str) -> None:
    """Not XML, another root, a DOCTYPE with an entity, invalid SRMD, a file named by an absolute
    path, a scheme, a query or a NUL, a checksum that is not SHA3-256: RecordError, one line
    naming the record; no file is read for it."""
    path = _hostile(tmp_path, text)
    with pytest.raises(srmd.RecordError) as caught:
        srmd.read_record(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and says in message and "\n" not in message


def test_a_record_too_large_or_not_a_file_is_refused(tmp_path: Path) -> None:
    """read_record reads within RECORD_LIMIT and only a regular file."""
    big = tmp_path / "big.srmd"
    big.write_bytes(b" " * (srmd.RECORD_LIMIT + 1))
    with pytest.raises(srmd.RecordError, match="over the limit"):
        srmd.read_record(big)
    with pytest.raises(srmd.RecordError, match="directory"):
        srmd.read_record(tmp_path)


def test_write_record_replaces_a_record_but_not_another_file(tmp_path: Path) -> None:
    """An earlier record is replaced; a file of another kind at the path is left alone."""
    path, record = _record(tmp_path)
    srmd.write_record(path, record)  # a re-run's record over the earlier one
    notes = tmp_path / "notes.srmd"
    notes.write_text("my notes\n")
    with pytest.raises(OutputError, match="is not a provenance record"):
        srmd.write_record(notes, record)
    assert notes.read_text() == "my notes\n"


def test_a_resource_kind_must_be_one_of_stc_kinds(tmp_path: Path) -> None:
    (tmp_path / "a").write_text("a")
    with pytest.raises(ValueError, match="STC's resource kinds"):
        srmd.resource(tmp_path / "a", tmp_path, "fmu", "plant")
