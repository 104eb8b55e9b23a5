"""The study's provenance in an SSP 2.0 root SSD: an SRMD record (SSP Traceability's
SimulationResourceMetaData, written by `provenance.srmd`) inline in an `ssc:MetaData` element of
kind "general" and type SRMD_TYPE.

The record names each archive member the variant's SSD uses, by its path in the archive (a URI
relative to the SSD, at the archive's top level) with its SHA3-256: the FMUs (kind "model", role
the component's name) and the variant's .ssv files (kind "parameter", role "<component>
parameters"); the tools' versions (`cosim.outcome.installed_versions`); and as settings the
scenario file's name and SHA3-256 and the variant. It has no creation time, so the same scenario
and FMUs, written with the same installation, give the same SSD. SSP 1.0 has no MetaData element: its SSDs carry none.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path

from lxml import etree

from toggle_cosim.files.checksums import file_sha3_256
from toggle_cosim.provenance import srmd
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import Element

__all__ = ["SRMD_TYPE", "metadata_element", "study_record"]

SRMD_TYPE = "application/x-srmd"  # the MetaData's MIME type: an SRMD document, inline


def study_record(
    scenario: Path,
    variant: str,
    fmus: Mapping[str, tuple[str, Path]],
    ssvs: Mapping[str, tuple[str, bytes]],
    tools: tuple[tuple[str, str], ...],
) -> srmd.Record:
    """The record of one variant's SSD: `fmus` maps each component to (its archive member, its
    FMU file), `ssvs` each component to (its .ssv member, its text); `tools` the tools' versions."""
    resources = [
        srmd.Resource(member, file_sha3_256(path), "model", component) for component, (member, path) in fmus.items()
    ]
    resources += [
        srmd.Resource(member, hashlib.sha3_256(text).hexdigest(), "parameter", f"{component} parameters")
        for component, (member, text) in ssvs.items()
    ]
    settings = (("scenario", Path(scenario).name), ("scenario-sha3-256", file_sha3_256(scenario)), ("variant", variant))
    version = dict(tools).get("toggle-cosim", "")
    return srmd.Record(
        name=variant,
        resources=tuple(resources),
        tools=tools,
        settings=settings,
        generation_tool=f"toggle-cosim {version}".strip(),
    )


def metadata_element(record: srmd.Record) -> Element:
    """The ssc:MetaData element holding `record` inline (checked against the SRMD schema: what
    we write is valid by construction, so a failure is our bug)."""
    document = etree.fromstring(srmd.to_xml(record))
    problem = srmd.schema_problem(document)
    if problem is not None:
        raise AssertionError(f"the study's SRMD written invalid ({problem})")
    metadata = etree.Element(f"{{{layout.SSC_NS}}}MetaData", kind="general", type=SRMD_TYPE)
    etree.SubElement(metadata, f"{{{layout.SSC_NS}}}Content").append(document)
    return metadata
