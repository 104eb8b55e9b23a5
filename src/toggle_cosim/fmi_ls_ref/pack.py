"""Files added to an existing FMU under `extra/org.fmi-standard.fmi-ls-ref/`, listed in its
manifest with their SHA3-256, with the FMU's SRMD over all its files (`metadata.py`), WITHOUT
touching any other member: every other member is copied
byte for byte (its data, name, date and compression as they were), so the binaries and
modelDescription.xml stay what they were. The FMU is replaced atomically (a temporary name,
then rename), or written to another file.
"""

from __future__ import annotations

import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from toggle_cosim.files.outputs import FMU, replacing
from toggle_cosim.fmi_ls_ref.manifest import (
    FOLDER,
    MANIFEST,
    LsRefError,
    Related,
    manifest_xml,
    read_manifest,
    sha3_256,
)
from toggle_cosim.plant.archive import ArchiveError, check_archive


@dataclass(frozen=True)
class Attachment:
    """A file to carry: its manifest entry (source relative to the manifest's folder) and bytes."""

    related: Related
    data: bytes


def open_fmu(path: Path) -> zipfile.ZipFile:
    """The FMU at `path` as a checked zip archive (`plant.archive.check_archive`); LsRefError
    naming the file if it is missing, not a zip, or unsafe."""
    try:
        archive = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise LsRefError(f"{path}: no such FMU (give the path of an .fmu file)") from None
    except (zipfile.BadZipFile, OSError) as error:
        raise LsRefError(f"{path}: not an FMU ({error}); give a zip archive with a modelDescription.xml") from None
    try:
        check_archive(archive)
    except ArchiveError as error:
        archive.close()
        raise LsRefError(f"{path}: unsafe or corrupt FMU: {error}") from None
    if "modelDescription.xml" not in archive.namelist():
        archive.close()
        raise LsRefError(f"{path}: not an FMU (no modelDescription.xml); give an FMU built by an FMI tool")
    return archive


def _own_member(related: Related) -> str:
    try:
        member = related.member
    except ValueError as error:
        raise LsRefError(f"cannot carry {related.source!r}: {error}") from None
    if not member.startswith(f"{FOLDER}/") or member == MANIFEST:
        raise LsRefError(f"cannot carry {related.source!r}: carried files go under {FOLDER}/ (choose another name)")
    return member


def pack(fmu: Path, attachments: Sequence[Attachment], output: Path | None = None) -> Path:
    """Add `attachments` to the FMU `fmu` (an existing entry of the same source is replaced),
    with the FMU's SRMD over all its files (`metadata`), and write it to `output` (default: `fmu`
    itself). Returns the path written."""
    from toggle_cosim.fmi_ls_ref.metadata import RECORD_MEMBER, fmu_record, record_entry

    fmu, output = Path(fmu), Path(output or fmu)
    members = {_own_member(a.related): a for a in attachments}
    if len(members) != len(attachments) or RECORD_MEMBER in members:
        raise LsRefError("two attached files have the same name in the FMU, or one is named as its SRMD; rename it")
    replaced = {*members, MANIFEST, RECORD_MEMBER}
    with open_fmu(fmu) as archive:
        kept = [e for e in (read_manifest(archive, str(fmu)) or ()) if _entry_member(e) not in replaced]
        entries = [*kept, *(replace(a.related, sha3_256=sha3_256(a.data)) for a in attachments)]
        contents = {info.filename: archive.read(info) for info in archive.infolist() if info.filename not in replaced}
        contents.update({member: attachment.data for member, attachment in members.items()})
        roles = {member: e.role for e in entries if (member := _entry_member(e)) is not None}
        record = fmu_record(fmu.stem, contents, roles)
        entries.append(replace(record_entry(), sha3_256=sha3_256(record)))
        with replacing(output, "FMU", kind=FMU) as partial, zipfile.ZipFile(partial, "w") as packed:
            for info in archive.infolist():
                if info.filename not in replaced:
                    packed.writestr(info, contents[info.filename], compress_type=info.compress_type)
            for member, attachment in members.items():
                packed.writestr(member, attachment.data, compress_type=zipfile.ZIP_DEFLATED)
            packed.writestr(RECORD_MEMBER, record, compress_type=zipfile.ZIP_DEFLATED)
            packed.writestr(MANIFEST, manifest_xml(entries), compress_type=zipfile.ZIP_DEFLATED)
    return output


def _entry_member(entry: Related) -> str | None:
    try:
        return entry.member
    except ValueError:
        return None
