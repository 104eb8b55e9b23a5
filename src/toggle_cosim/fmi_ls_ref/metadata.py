"""The FMU's own SRMD (FMI-LS-REF role `meta-data`): one provenance record (`provenance.srmd`)
naming by SHA3-256 every file of the FMU, its binaries, modelDescription.xml and sources as well
as the files it carries, so that `verify` refuses an FMU any of whose files changed after packing,
in one line naming the file. URIs are relative to the record's folder, as SRMD resolves them.
"""

from __future__ import annotations

import posixpath
import zipfile
from collections.abc import Mapping
from urllib.parse import quote, unquote

from toggle_cosim import __version__
from toggle_cosim.fmi_ls_ref.manifest import FOLDER, MANIFEST, LsRefError, Related, read_member, sha3_256
from toggle_cosim.provenance.srmd import Record, RecordError, Resource, from_xml, now, valid_xml

RECORD = "metadata/fmu.srmd"  # its source, relative to the manifest's folder
RECORD_MEMBER = f"{FOLDER}/{RECORD}"
MIME = "application/x-srmd-meta-data"
# a carried file's STC resource kind, by its FMI-LS-REF main role
KIND_OF_ROLE = {
    "model": "model",
    "parameter": "parameter",
    "result": "result",
    "experiment": "testcase",
    "configuration": "configuration",
    "requirement": "requirement",
    "specification": "specification",
    "system": "system",
    "testcase": "testcase",
    "method": "method",
    "rationale": "rationale",
    "report": "report",
    "request": "request",
    "delivery": "delivery",
}


def _kind_and_role(member: str, carried: Mapping[str, str]) -> tuple[str, str]:
    if member in carried:
        role = carried[member]
        return KIND_OF_ROLE.get(role.split("/", 1)[0], "document"), role
    if member.startswith("binaries/"):
        return "executable", "binary"
    if member == "modelDescription.xml":
        return "model", "model-description"
    if member.startswith("sources/"):
        return "model", "source"
    return "document", "file"


def record_entry() -> Related:
    return Related(RECORD, "meta-data", MIME, "SRMD: the SHA3-256 of every file of the FMU")


def fmu_record(name: str, members: Mapping[str, bytes], carried: Mapping[str, str]) -> bytes:
    """The SRMD of the FMU `name` whose files are `members` (archive name: bytes; the manifest and
    the record itself left out), `carried` the LS-REF role of each carried member."""
    folder = posixpath.dirname(RECORD_MEMBER)
    resources = []
    for member, data in members.items():
        if member in (MANIFEST, RECORD_MEMBER) or member.endswith("/"):
            continue
        kind, role = _kind_and_role(member, carried)
        resources.append(Resource(quote(posixpath.relpath(member, folder), safe="/"), sha3_256(data), kind, role))
    record = Record(
        name=name,
        resources=tuple(resources),
        tools=(("toggle-cosim", __version__),),
        created=now(),
        generation_tool=f"toggle-cosim {__version__}",
    )
    return valid_xml(record)


def check_record(archive: zipfile.ZipFile, where: str) -> None:
    """The FMU's own SRMD, if it carries one: every file it names present and matching its
    SHA3-256; LsRefError naming the file otherwise."""
    if RECORD_MEMBER not in archive.namelist():
        return
    try:
        record = from_xml(read_member(archive, RECORD_MEMBER, where), f"{where}: {RECORD_MEMBER}")
    except RecordError as error:
        raise LsRefError(str(error)) from None
    folder = posixpath.dirname(RECORD_MEMBER)
    names = set(archive.namelist())
    for found in record.resources:
        member = posixpath.normpath(posixpath.join(folder, unquote(found.uri)))
        if member not in names:
            raise LsRefError(
                f"{where}: the FMU's SRMD ({RECORD_MEMBER}) names {member}, which the FMU does not contain "
                f"(the FMU was changed after packing; build or pack it again)"
            )
        if sha3_256(archive.read(member)) != found.checksum:
            raise LsRefError(
                f"{where}: {member} does not match its SHA3-256 checksum in the FMU's SRMD "
                f"(the file was changed after packing; build or pack it again)"
            )
