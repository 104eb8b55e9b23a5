"""An FMU archive checked before anything is extracted or read from it.

Refused, each in one line naming the member: a name that is absolute, holds a backslash or a
drive letter, or climbs out with `..`; a member whose inflated size is over MEMBER_LIMIT, or
members over TOTAL_LIMIT together; more than MAX_MEMBERS members; a member whose compressed
data is corrupt (each member is inflated once, in bounded chunks, and its CRC checked); and a
modelDescription.xml over `bounded_files.MODEL_DESCRIPTION_LIMIT`.
"""

from __future__ import annotations

import re
import zipfile
import zlib
from pathlib import Path

from toggle_cosim.files.bounded import MODEL_DESCRIPTION_LIMIT, MiB

MEMBER_LIMIT = 256 * MiB
TOTAL_LIMIT = 512 * MiB
MAX_MEMBERS = 10_000


class ArchiveError(Exception):
    """The archive cannot be used; str() is the one-line reason (without the file name)."""


def _bad_name(name: str) -> str | None:
    if name.startswith("/") or re.match(r"^[A-Za-z]:", name):
        return "an absolute path"
    if "\\" in name:
        return "a backslash in its name"
    if ".." in name.split("/"):
        return "a '..' that leads out of the archive's folder"
    if "\x00" in name:
        return "a NUL character in its name"
    return None


def check_archive(archive: zipfile.ZipFile) -> None:
    """Check every member's name and size, then inflate each once to check its data."""
    members = archive.infolist()
    if len(members) > MAX_MEMBERS:
        raise ArchiveError(f"{len(members)} members, more than the {MAX_MEMBERS} allowed")
    total = 0
    for info in members:
        problem = _bad_name(info.filename)
        if problem:
            raise ArchiveError(f"member {info.filename!r} has {problem} (refused before extraction)")
        if info.file_size > MEMBER_LIMIT:
            raise ArchiveError(
                f"member {info.filename!r} inflates to {info.file_size} bytes, over the {MEMBER_LIMIT // MiB} MiB limit"
            )
        total += info.file_size
        if total > TOTAL_LIMIT:
            raise ArchiveError(f"the members inflate to more than {TOTAL_LIMIT // MiB} MiB together")
        if info.filename == "modelDescription.xml" and info.file_size > MODEL_DESCRIPTION_LIMIT:
            raise ArchiveError(
                f"modelDescription.xml inflates to {info.file_size} bytes, over the "
                f"{MODEL_DESCRIPTION_LIMIT // MiB} MiB limit"
            )
    for info in members:
        if info.is_dir():
            continue
        try:
            with archive.open(info) as stream:  # reads at most file_size bytes, checks the CRC at the end
                while stream.read(1 << 20):
                    pass
        except (
            zipfile.BadZipFile,
            zlib.error,
            EOFError,
            OSError,
            NotImplementedError,
            RuntimeError,
            ValueError,
        ) as error:
            raise ArchiveError(f"member {info.filename!r} is corrupt ({' '.join(str(error).split())})") from None


def read_model_description(path: Path) -> tuple[set[str], bytes | None]:
    """The member names and modelDescription.xml of a checked archive (None if it has none)."""
    with zipfile.ZipFile(path) as archive:
        check_archive(archive)
        names = set(archive.namelist())
        description = archive.read("modelDescription.xml") if "modelDescription.xml" in names else None
    return names, description
