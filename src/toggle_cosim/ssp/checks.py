"""What the SSP writer and reader both check: XML against the vendored SSP schemas of its
version (`schemas/`: SSP 1.0; `schemas/ssp2/`: SSP 2.0, whose namespaces are 1.0's; validated with
lxml, which FMPy's own SSP reader uses too; `VERSIONS`), XML read within bounds
(member size XML_LIMIT, then `files.xml_reading`'s bounds: no DOCTYPE, so no entities, and
nothing fetched), and the archive's safety (the FMU archive checks of `plant.archive`: member
names, sizes, members, corrupt data)."""

from __future__ import annotations

import functools
import zipfile
from importlib import resources
from pathlib import Path
from typing import Any, TypeAlias

from lxml import etree

from toggle_cosim.files.bounded import MiB
from toggle_cosim.files.xml_reading import XmlKind, XmlRefused, read_xml
from toggle_cosim.files.xml_schema import first_problem
from toggle_cosim.plant.archive import ArchiveError, check_archive

SCHEMAS = {
    "ssd": "SystemStructureDescription.xsd",
    "ssv": "SystemStructureParameterValues.xsd",
    "ssm": "SystemStructureParameterMapping.xsd",
    "ssb": "SystemStructureSignalDictionary.xsd",
}


# an SSP document's `version` -> the folder of its schemas (every 1.0 document is also valid 2.0,
# but each is checked against its own version's schemas; SSP 2.0 documents say "2.0")
VERSIONS = {"1.0": ("schemas",), "2.0": ("schemas", "ssp2")}
DEFAULT_VERSION = "1.0"  # what `toggle-cosim ssp` writes unless asked: the version libcosim and Ecos read

XML_LIMIT = 4 * MiB  # an SSD or .ssv: ours are a few kB
SSP_FILE = XmlKind("an SSP file", "fix or rewrite it")

Element: TypeAlias = Any  # an lxml element (lxml names its class privately)


class SspError(Exception):
    """An SSP (or a scenario for one) that cannot be used; str() is the one-line reason, naming
    the file and the fix."""


@functools.cache
def schema(kind: str, version: str = DEFAULT_VERSION) -> etree.XMLSchema:
    """The schema of a file kind ("ssd", "ssv", "ssm", "ssb") in an SSP version ("1.0", "2.0"),
    from the vendored copies."""
    folder = resources.files("toggle_cosim.ssp").joinpath(*VERSIONS[version])
    with resources.as_file(folder / SCHEMAS[kind]) as path:
        return etree.XMLSchema(etree.parse(str(path)))


def version_problem(root: Element) -> str | None:
    """None if `root` says an SSP version we read (`VERSIONS`), else why not, in words."""
    version = root.get("version")
    if version in VERSIONS:
        return None
    return f"version {version!r} is not an SSP version toggle-cosim reads ({' or '.join(VERSIONS)}; write it as one)"


def schema_problem(root: Element, kind: str) -> str | None:
    """None if `root` is valid against the SSP schema of `kind` in its own `version` (1.0 or
    2.0), else the first problem in one line."""
    if (problem := version_problem(root)) is not None:
        return problem
    return first_problem(schema(kind, root.get("version")), root)


def parse_xml(data: bytes, where: str) -> Element:
    """The root of the SSP XML document `data`, read within bounds (`files.xml_reading`);
    SspError naming `where` otherwise."""
    try:
        return read_xml(data, where, SSP_FILE)
    except XmlRefused as error:
        raise SspError(str(error)) from None


def parse_member(archive: zipfile.ZipFile, member: str, kind: str, where: str) -> Element:
    """The root of an XML member (at most XML_LIMIT bytes, `parse_xml`), checked against the SSP
    schema of its version (`schema_problem`); SspError naming `where` (the SSP file and the
    member) otherwise."""
    if archive.getinfo(member).file_size > XML_LIMIT:
        raise SspError(f"{where}: over the {XML_LIMIT // MiB} MiB an SSP's XML file may have here (refused)")
    with archive.open(member) as stream:
        data = stream.read(XML_LIMIT + 1)
    if len(data) > XML_LIMIT:
        raise SspError(f"{where}: over the {XML_LIMIT // MiB} MiB an SSP's XML file may have here (refused)")
    root = parse_xml(data, where)
    if (problem := version_problem(root)) is not None:
        raise SspError(f"{where}: {problem}")
    problem = schema_problem(root, kind)
    if problem is not None:
        raise SspError(f"{where}: not valid SSP {root.get('version')} ({problem}); fix it or write the SSP again")
    return root


def open_archive(path: Path) -> zipfile.ZipFile:
    """The SSP at `path` as a checked zip archive (`plant.archive.check_archive`); SspError if it
    is not a zip file or is unsafe."""
    try:
        archive = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise SspError(f"{path}: no such file (give the path of an .ssp archive)") from None
    except (zipfile.BadZipFile, OSError) as error:
        raise SspError(
            f"{path}: not an SSP archive ({error}); give a zip archive as toggle-cosim ssp writes it"
        ) from None
    try:
        check_archive(archive)
    except ArchiveError as error:
        archive.close()
        raise SspError(f"{path}: unsafe or corrupt archive: {error}; write the SSP again") from None
    return archive
