"""The FMI-LS-REF manifest, `extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml`: one `Related`
element per carried file (its source URI, role, MIME type, description, labels), written valid
against the vendored schema (`schemas/`, BSD-2-Clause).

The layered standard has no checksum attribute, so each file's SHA3-256 travels in the element's
`Annotations` (type `org.toggle-cosim.checksum`, which the schema admits: an annotation's content
is free). `check_members` refuses a manifest that names a member the FMU lacks, or whose member
does not hash to the recorded checksum, in one line naming the file. Other tools' manifests need
not be schema-valid to be read (the Reference FMUs' omit the required description): only the
elements we use are required.
"""

from __future__ import annotations

import functools
import hashlib
import posixpath
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from urllib.parse import unquote, urlsplit

from lxml import etree

from toggle_cosim.files.bounded import MiB
from toggle_cosim.files.xml_reading import XmlKind, XmlRefused, read_xml
from toggle_cosim.files.xml_schema import first_problem
from toggle_cosim.ssp.checks import Element

FOLDER = "extra/org.fmi-standard.fmi-ls-ref"
MANIFEST = f"{FOLDER}/fmi-ls-manifest.xml"
LS_NS = "http://fmi-standard.org/fmi-ls-manifest"
LS_NAME = "org.fmi-standard.fmi-ls-ref"
LS_VERSION = "1.0.0-alpha.1"
LS_DESCRIPTION = "Layered Standard providing information on related files included in an FMU."
SCHEMA = "fmi3LayeredStandardReferenceManifest.xsd"

CHECKSUM_ANNOTATION = "org.toggle-cosim.checksum"
CHECKSUM_NS = "https://github.com/toggle-cosim/toggle-cosim/fmi-ls-ref"
CHECKSUM_ALGORITHM = "SHA3-256"

XML_LIMIT = 4 * MiB  # a manifest or experiment document: ours are a few kB

MANIFEST_FILE = XmlKind("an FMI-LS-REF manifest", "pack the FMU again (toggle-cosim pack)")


class LsRefError(Exception):
    """An FMU's carried files that cannot be used; str() is the one-line reason naming the file."""


@dataclass(frozen=True)
class Related:
    """One carried file. `source` is relative to the manifest's folder (as the standard resolves
    it); `sha3_256` is the hex digest of its bytes, None when the manifest records none."""

    source: str
    role: str
    type: str = "application/octet-stream"
    description: str = ""
    labels: tuple[str, ...] = ()
    sha3_256: str | None = None

    @property
    def member(self) -> str:
        return member_of(self.source)

    @property
    def main_role(self) -> str:
        return self.role.split("/", 1)[0]


def sha3_256(data: bytes) -> str:
    return hashlib.sha3_256(data).hexdigest()


def member_of(source: str) -> str:
    """The archive member a relative `source` URI names (resolved against the manifest's folder);
    ValueError for an absolute URI or one that leaves the archive."""
    parts = urlsplit(source)
    if parts.scheme or parts.netloc or parts.path.startswith("/") or parts.query or parts.fragment:
        raise ValueError(f"{source!r} is not a relative URI inside the FMU")
    member = posixpath.normpath(posixpath.join(FOLDER, unquote(parts.path)))
    if member.startswith("../") or member in {".", ".."} or not parts.path:
        raise ValueError(f"{source!r} points outside the FMU")
    return member


@functools.cache
def schema() -> etree.XMLSchema:
    """The FMI-LS-REF manifest schema, from the vendored copies (its imports resolved beside it)."""
    folder = resources.files("toggle_cosim.fmi_ls_ref") / "schemas"
    with resources.as_file(folder / SCHEMA) as path:
        return etree.XMLSchema(etree.parse(str(path)))


def schema_problem(root: Element) -> str | None:
    """None if `root` is a valid FMI-LS-REF manifest, else its first problem in one line."""
    return first_problem(schema(), root)


def manifest_xml(related: Sequence[Related]) -> bytes:
    """The manifest listing `related`, checked against the schema (a failure is our bug)."""
    ls = f"{{{LS_NS}}}"
    root = etree.Element("fmiReferences", nsmap={"fmi-ls": LS_NS})
    root.set(f"{ls}fmi-ls-name", LS_NAME)
    root.set(f"{ls}fmi-ls-version", LS_VERSION)
    root.set(f"{ls}fmi-ls-description", LS_DESCRIPTION)
    for entry in related:
        element = etree.SubElement(root, "Related", type=entry.type, source=entry.source, role=entry.role)
        if entry.description:
            element.set("description", entry.description)
        for label in entry.labels:
            etree.SubElement(element, "Label", name=label)
        if entry.sha3_256 is not None:
            annotation = etree.SubElement(etree.SubElement(element, "Annotations"), "Annotation")
            annotation.set("type", CHECKSUM_ANNOTATION)
            etree.SubElement(
                annotation,
                f"{{{CHECKSUM_NS}}}Checksum",
                nsmap={"tc": CHECKSUM_NS},
                algorithm=CHECKSUM_ALGORITHM,
                value=entry.sha3_256,
            )
    problem = schema_problem(root)
    if problem is not None:
        raise AssertionError(f"the FMI-LS-REF manifest we wrote is not valid ({problem})")
    etree.indent(root)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8") + b"\n"


def read_member(archive: zipfile.ZipFile, member: str, where: str, limit: int = XML_LIMIT) -> bytes:
    """The bytes of `member` (at most `limit`); LsRefError naming `where` if it is absent or larger."""
    try:
        info = archive.getinfo(member)
    except KeyError:
        raise LsRefError(
            f"{where}: the FMI-LS-REF manifest names {member}, which the FMU does not contain "
            f"(add the file or remove its entry)"
        ) from None
    if info.file_size > limit:
        raise LsRefError(f"{where}: {member} is over the {limit // MiB} MiB a carried file may have here (refused)")
    return archive.read(info)


def _checksum(element: Element) -> str | None:
    for annotation in element.iterfind("Annotations/Annotation"):
        if annotation.get("type") != CHECKSUM_ANNOTATION:
            continue
        for checksum in annotation.iterfind(f"{{{CHECKSUM_NS}}}Checksum"):
            if checksum.get("algorithm", "").upper() == CHECKSUM_ALGORITHM:
                return (checksum.get("value") or "").strip().lower()
    return None


def read_manifest(archive: zipfile.ZipFile, where: str) -> tuple[Related, ...] | None:
    """The manifest's entries, in order; None if the FMU carries no manifest. LsRefError naming
    `where` for a manifest that is not XML, has another root, or an entry without source or role."""
    if MANIFEST not in archive.namelist():
        return None
    data = read_member(archive, MANIFEST, where)
    try:
        root = read_xml(data, f"{where}: {MANIFEST}", MANIFEST_FILE)
    except XmlRefused as error:
        raise LsRefError(str(error)) from None
    if etree.QName(root).localname != "fmiReferences":
        raise LsRefError(f"{where}: {MANIFEST} is not an FMI-LS-REF manifest (its root is not fmiReferences)")
    entries = []
    for element in root.iterfind("Related"):
        source, role = element.get("source"), element.get("role")
        if not source or not role:
            raise LsRefError(f"{where}: {MANIFEST} line {element.sourceline}: a Related element needs source and role")
        labels = tuple(label.get("name", "") for label in element.iterfind("Label"))
        entries.append(
            Related(
                source,
                role,
                element.get("type", "application/octet-stream"),
                element.get("description", ""),
                labels,
                _checksum(element),
            )
        )
    return tuple(entries)


def check_members(archive: zipfile.ZipFile, related: Sequence[Related], where: str) -> None:
    """Every entry with a relative source names a member the FMU contains, whose SHA3-256 matches
    the recorded one; LsRefError naming the file otherwise. Absolute URIs are not followed."""
    for entry in related:
        try:
            member = entry.member
        except ValueError as error:
            raise LsRefError(f"{where}: {MANIFEST}: the source {error} (refused; carry the file in the FMU)") from None
        if member not in archive.namelist():
            raise LsRefError(
                f"{where}: the FMI-LS-REF manifest names {member}, which the FMU does not contain "
                f"(add the file or remove its entry)"
            )
        if entry.sha3_256 is not None and sha3_256(archive.read(member)) != entry.sha3_256:
            raise LsRefError(
                f"{where}: {member} does not match its SHA3-256 checksum in the FMI-LS-REF manifest "
                f"(the file was changed after packing; pack it again)"
            )
