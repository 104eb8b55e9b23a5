"""A provenance record: an SRMD file (SSP Traceability's `SimulationResourceMetaData`, schema
vendored in `schemas/`) naming by SHA3-256 every file that shaped a result, and the tools that
made it.

The record is one `srmd:SimulationResourceMetaData` element: its `data` and `checksum` name the
result it describes (a run's trace.csv), `generationTool` and `generationDateAndTime` who wrote it
and when. Its content is `stc:Classification` elements, the schema's keyword-value form:

* one of type `org.toggle-cosim.resource` per file used (`Resource`): `xlink:href` its URI,
  relative to the record's folder, and entries `role` (what the run used it as), `kind` (STC's
  resource kind), `checksumType` (SHA3-256), `checksum` and, when known, `generationTool`;
* one of type `org.toggle-cosim.tools`: each tool's version (python, toggle-cosim, fmpy, ...);
* one of type `org.toggle-cosim.settings`: what a repeat needs besides the files (e.g. the
  scenario's variant), keyword-value pairs.

`write_record` writes through `files.outputs` (a temporary name, then renamed; an existing file
replaced only if it is a record). `read_record` reads within a bound, refuses a DOCTYPE, checks the
schema and every URI (relative, no scheme, no query), and returns the `Record`; `verify_record`
names each file that is missing or changed. A bad record is a `RecordError`, one line naming it.
"""

from __future__ import annotations

import functools
import os
import posixpath
import re
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote, urlsplit

from lxml import etree

from toggle_cosim.files.bounded import InputFileError, MiB, file_problem, read_bounded
from toggle_cosim.files.checksums import file_sha3_256
from toggle_cosim.files.outputs import SRMD, SRMD_NAMESPACE, write_file
from toggle_cosim.files.xml_reading import XmlKind, XmlRefused, read_xml
from toggle_cosim.files.xml_schema import first_problem

SRMD_NS = SRMD_NAMESPACE
STC_NS = "http://ssp-standard.org/SSPTraceability1/SSPTraceabilityCommon"
XLINK_NS = "http://www.w3.org/1999/xlink"
NAMESPACES = {"srmd": SRMD_NS, "stc": STC_NS, "xlink": XLINK_NS}

SRMD_VERSION = "1.0.0"  # the SRMD format version, as the schema's documentation gives it for this release
CHECKSUM_TYPE = "SHA3-256"
RECORD_LIMIT = 4 * MiB  # a record names tens of files in a few kB
RECORD_FILE = XmlKind("a record", "give a run's record")

RESOURCE = "org.toggle-cosim.resource"
TOOLS = "org.toggle-cosim.tools"
SETTINGS = "org.toggle-cosim.settings"

# STC's resource kinds (ResourceType/@kind): what a file is in the simulation process
KINDS = (
    "document",
    "requirement",
    "specification",
    "model",
    "parameter",
    "system",
    "testcase",
    "result",
    "method",
    "rationale",
    "report",
    "request",
    "delivery",
    "executable",
    "configuration",
)

_SHA3_HEX = re.compile(r"^[0-9a-f]{64}$")


class RecordError(Exception):
    """A record that cannot be used; str() is the one-line reason, naming the record and the fix."""


@dataclass(frozen=True)
class Resource:
    """One file named by a record: `uri` relative to the record's folder ('/'-separated,
    percent-encoded), its SHA3-256 `checksum` (hex), `kind` (one of STC's KINDS), `role` (what the
    run used it as: "plant", "scenario", "input-table", ...) and the tool that made it, if known."""

    uri: str
    checksum: str
    kind: str
    role: str
    generation_tool: str | None = None


@dataclass(frozen=True)
class Record:
    """A provenance record: its `name`, the result it describes (`data`, a Resource whose role is
    "result"; None: none), the files that shaped it (`resources`), the tools' versions (`tools`,
    name and version pairs), what a repeat needs besides the files (`settings`, keyword-value
    pairs) and when it was made (`created`, ISO 8601 UTC)."""

    name: str
    resources: tuple[Resource, ...]
    tools: tuple[tuple[str, str], ...] = ()
    settings: tuple[tuple[str, str], ...] = ()
    data: Resource | None = None
    created: str = ""
    generation_tool: str = ""

    def setting(self, keyword: str) -> str | None:
        """The value of a setting, or None if the record has none of that name."""
        return dict(self.settings).get(keyword)


def now() -> str:
    """The time now, as a record's `created` (ISO 8601, UTC, whole seconds)."""
    return datetime.now(UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def uri_of(path: Path | str, folder: Path | str) -> str:
    """The URI of `path` relative to `folder` (the record's), '/'-separated and percent-encoded."""
    relative = Path(posixpath.relpath(Path(path).absolute().as_posix(), Path(folder).absolute().as_posix()))
    return quote(relative.as_posix(), safe="/")


def resource(
    path: Path | str, folder: Path | str, kind: str, role: str, generation_tool: str | None = None
) -> Resource:
    """The Resource of the file at `path` for a record in `folder`: its URI and SHA3-256 (OSError
    if it cannot be read or is not a regular file)."""
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r} is not one of STC's resource kinds ({', '.join(KINDS)})")
    return Resource(uri_of(path, folder), file_sha3_256(Path(path)), kind, role, generation_tool)


def check_uri(uri: str) -> str | None:
    """Why `uri` cannot name a file of a record (a scheme, a host, an absolute path, a query or
    fragment, a NUL or backslash, empty), or None for a relative path."""
    if not uri or "\\" in uri or "\x00" in unquote(uri):
        return "is empty or has a NUL or backslash"
    parts = urlsplit(uri)
    if parts.scheme or parts.netloc:
        return "has a scheme or host (a record names files by paths relative to itself)"
    if parts.query or parts.fragment or "?" in uri or "#" in uri:
        return "has a query or fragment"
    if uri.startswith("/"):
        return "is an absolute path (a record names files by paths relative to itself)"
    return None


def located(record_path: Path | str, uri: str) -> Path:
    """The path of the file `uri` names, relative to the folder of the record at `record_path`
    (RecordError if the URI is not a relative path: `check_uri`)."""
    problem = check_uri(uri)
    if problem is not None:
        raise RecordError(f"{record_path}: the file URI {uri!r} {problem}; write the record again")
    return Path(record_path).parent / unquote(uri)


# --- XML -----------------------------------------------------------------------------------------


def _q(prefix: str, name: str) -> str:
    return f"{{{NAMESPACES[prefix]}}}{name}"


def _entry(parent: Any, keyword: str, value: str) -> None:
    etree.SubElement(parent, _q("stc", "ClassificationEntry"), keyword=keyword).text = value


def to_xml(record: Record) -> bytes:
    """The record as an SRMD document (UTF-8, indented)."""
    root = etree.Element(_q("srmd", "SimulationResourceMetaData"), nsmap=NAMESPACES)
    root.set("version", SRMD_VERSION)
    root.set("name", record.name)
    if record.data is not None:
        root.set("data", record.data.uri)
        root.set("checksum", record.data.checksum)
        root.set("checksumType", CHECKSUM_TYPE)
    if record.generation_tool:
        root.set("generationTool", record.generation_tool)
    if record.created:
        root.set("generationDateAndTime", record.created)
    for item in record.resources:
        group = etree.SubElement(root, _q("stc", "Classification"), type=RESOURCE)
        group.set(_q("xlink", "type"), "simple")
        group.set(_q("xlink", "href"), item.uri)
        _entry(group, "role", item.role)
        _entry(group, "kind", item.kind)
        _entry(group, "checksumType", CHECKSUM_TYPE)
        _entry(group, "checksum", item.checksum)
        if item.generation_tool:
            _entry(group, "generationTool", item.generation_tool)
    for kind, pairs in ((TOOLS, record.tools), (SETTINGS, record.settings)):
        if pairs:
            group = etree.SubElement(root, _q("stc", "Classification"), type=kind)
            for keyword, value in pairs:
                _entry(group, keyword, value)
    etree.indent(root)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8")


class _Schemas(etree.Resolver):
    """Resolves the schemas' imports to the vendored copies (nothing is fetched); STC.xsd is given
    with its one XSD 1.1 type, xs:dateTimeStamp, read as its XSD 1.0 base xs:dateTime (libxml2
    validates XSD 1.0; a record uses no element of that type)."""

    def __init__(self, folder: Path) -> None:
        super().__init__()
        self.folder = folder
        self.urls = {
            "https://www.w3.org/XML/2008/06/xlink.xsd": folder / "w3c" / "xlink.xsd",
            "http://www.w3.org/2001/xml.xsd": folder / "w3c" / "xml.xsd",
        }

    def resolve(self, url: str | None, public_id: str | None, context: Any) -> Any:  # noqa: ARG002
        if url in self.urls:
            return self.resolve_filename(str(self.urls[url]), context)
        if url and Path(url).name == "STC.xsd":
            text = (self.folder / "STC.xsd").read_text(encoding="utf-8").replace("xs:dateTimeStamp", "xs:dateTime")
            return self.resolve_string(text, context, base_url=str(self.folder / "STC.xsd"))
        return None


@functools.cache
def schema() -> etree.XMLSchema:
    """SRMD.xsd with what it imports, from the vendored copies (`schemas/README.md`)."""
    with resources.as_file(resources.files("toggle_cosim.provenance") / "schemas") as folder:
        parser = etree.XMLParser(no_network=True, resolve_entities=False, load_dtd=False)
        parser.resolvers.add(_Schemas(Path(folder)))
        return etree.XMLSchema(etree.parse(str(Path(folder) / "SRMD.xsd"), parser))


def schema_problem(root: Any) -> str | None:
    """None if `root` is a valid SRMD element, else the first problem in one line."""
    return first_problem(schema(), root)


def from_xml(data: bytes, where: str) -> Record:
    """The Record of an SRMD document; RecordError naming `where` if it cannot be read within
    bounds (`files.xml_reading`: well-formed, no DOCTYPE), is not valid SRMD, or names a file by
    anything but a relative path."""
    try:
        root = read_xml(data, where, RECORD_FILE)
    except XmlRefused as error:
        raise RecordError(str(error)) from None
    if root.tag != _q("srmd", "SimulationResourceMetaData"):
        raise RecordError(f"{where}: not an SRMD record (its root is {root.tag}); give a run's record")
    problem = schema_problem(root)
    if problem is not None:
        raise RecordError(f"{where}: not a valid SRMD record ({problem}); write the record again")
    resources_, tools, settings = [], [], []
    for group in root.findall("stc:Classification", NAMESPACES):
        entries = [
            (e.get("keyword"), (e.text or "").strip()) for e in group.findall("stc:ClassificationEntry", NAMESPACES)
        ]
        kind = group.get("type")
        if kind == RESOURCE:
            resources_.append(_resource(group.get(_q("xlink", "href")) or "", dict(entries), where))
        elif kind == TOOLS:
            tools.extend(entries)
        elif kind == SETTINGS:
            settings.extend(entries)
    data = None
    if root.get("data") is not None:
        data = _checked(Resource(root.get("data"), (root.get("checksum") or "").lower(), "result", "result"), where)
    return Record(
        name=root.get("name"),
        resources=tuple(resources_),
        tools=tuple(tools),
        settings=tuple(settings),
        data=data,
        created=root.get("generationDateAndTime") or "",
        generation_tool=root.get("generationTool") or "",
    )


def _resource(uri: str, entries: dict[str, str], where: str) -> Resource:
    if entries.get("checksumType", CHECKSUM_TYPE) != CHECKSUM_TYPE:
        raise RecordError(f"{where}: {uri!r} has a checksum of type {entries['checksumType']!r}, not {CHECKSUM_TYPE}")
    found = Resource(
        uri,
        entries.get("checksum", "").lower(),
        entries.get("kind", ""),
        entries.get("role", ""),
        entries.get("generationTool"),
    )
    if found.kind not in KINDS or not found.role:
        raise RecordError(f"{where}: {uri!r} has no role or a kind that is not STC's; write the record again")
    return _checked(found, where)


def _checked(found: Resource, where: str) -> Resource:
    problem = check_uri(found.uri)
    if problem is not None:
        raise RecordError(f"{where}: the file URI {found.uri!r} {problem}; write the record again")
    if not _SHA3_HEX.match(found.checksum):
        raise RecordError(f"{where}: {found.uri!r} has no SHA3-256 checksum (64 hex digits); write the record again")
    return found


# --- files -----------------------------------------------------------------------------------------


def write_record(path: Path | str, record: Record) -> Path:
    """Write `record` to `path` (`files.outputs`: whole or not at all; an existing file replaced
    only if it is a record); the record is checked against the schema first (ValueError if not
    valid: a bug, not the user's)."""
    data = valid_xml(record)
    return write_file(path, lambda stream: stream.write(data), binary=True, what="provenance record", kind=SRMD)


def valid_xml(record: Record) -> bytes:
    """`record` as XML (`to_xml`), checked against the schema first: ValueError if it is not
    valid (a bug of the writer, not the user's)."""
    data = to_xml(record)
    problem = schema_problem(etree.fromstring(data))
    if problem is not None:
        raise ValueError(f"the record of {record.name!r} is not valid SRMD: {problem}")
    return data


def read_record(path: Path | str) -> Record:
    """The Record at `path` (read within RECORD_LIMIT, a regular file); RecordError naming it if it
    cannot be read or is not a valid record (`from_xml`)."""
    try:
        data = read_bounded(path, RECORD_LIMIT, "provenance record")
    except InputFileError as error:
        raise RecordError(str(error)) from None
    return from_xml(data, str(path))


def changed_files(path: Path | str, record: Record) -> list[str]:
    """One line per file of `record` (at `path`) that is missing, not a regular file, or whose
    SHA3-256 differs from the record's: the file's path and what is wrong. Empty if all match."""
    lines = []
    path = Path(path)
    for item in (*record.resources, *((record.data,) if record.data else ())):
        where = located(path, item.uri)
        target = Path(os.path.normpath(where))  # as the user would write it
        problem = file_problem(where)
        if problem is not None:
            lines.append(f"{target}: {problem} (the record {path} names it as the {item.role})")
            continue
        try:
            digest = file_sha3_256(where)
        except OSError as error:
            lines.append(f"{target}: cannot be read ({error.strerror or error}) (the record {path} names it)")
            continue
        if digest != item.checksum:
            lines.append(f"{target}: changed since the record {path} was written (the {item.role}; SHA3-256 differs)")
    return lines


def verify_record(path: Path | str) -> list[str]:
    """Read the record at `path` and check every file it names: one line per missing or changed
    file (`changed_files`), empty if all match. RecordError if the record itself is bad."""
    return changed_files(path, read_record(path))


__all__ = [
    "CHECKSUM_TYPE",
    "KINDS",
    "NAMESPACES",
    "RECORD_LIMIT",
    "SRMD",
    "SRMD_NS",
    "SRMD_VERSION",
    "Record",
    "RecordError",
    "Resource",
    "changed_files",
    "check_uri",
    "from_xml",
    "located",
    "now",
    "read_record",
    "resource",
    "schema_problem",
    "to_xml",
    "uri_of",
    "valid_xml",
    "verify_record",
    "write_record",
]
