"""Experiment documents carried in an FMU (FMI-LS-REF role `experiment`): what to run and what to
hold it against, in the Modelica Association's Experiments Format (MA-HS-Experiments, MIME type
`application/x-ma-hs-experiments`; `schemas/maHarmonizedSpecificationExperiments.xsd`). Each
`Experiment` is a `TransientSimulation` (start and stop time, a step size: the output interval, and
a run's sample time) with an optional relative tolerance, an SSV parameter set (`Parameters`), a
CSV of stimuli (the FMU's inputs over time) and the CSV reference (`References`), by source
relative to the document. What the format has no element for goes into an FMI annotation of type
`org.toggle-cosim.experiment`: the funnel tolerances (YAML, as `toggle-cosim compare` reads
them) and, for our own plants, the scenario and variant that run it through the co-simulation
master. A reader that does not know the annotation runs the same experiment from the standard
elements alone.
"""

from __future__ import annotations

import functools
import math
import posixpath
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources

from lxml import etree

from toggle_cosim.files.xml_reading import XmlKind, XmlRefused, read_xml
from toggle_cosim.files.xml_schema import first_problem
from toggle_cosim.fmi_ls_ref.manifest import LsRefError
from toggle_cosim.ssp.checks import Element

MIME = "application/x-ma-hs-experiments"
SCHEMA = "maHarmonizedSpecificationExperiments.xsd"
ANNOTATION = "org.toggle-cosim.experiment"  # our files of an experiment the format has no element for
# The schema imports fmi3Annotation.xsd, which has no target namespace, from a schema without one:
# XML Schema 1.0 (libxml2, xmlschema) allows that only as an include, which is how it is loaded.
_IMPORT = b'<xs:import schemaLocation="fmi3Annotation.xsd" />'
_INCLUDE = b'<xs:include schemaLocation="fmi3Annotation.xsd"/>'

EXPERIMENTS_FILE = XmlKind("an experiments document", "write it again with toggle-cosim pack")


@dataclass(frozen=True)
class Experiment:
    """One experiment; the file fields are sources relative to the experiment document. A time
    the document leaves out is None (the FMU's default experiment gives it: `verify`)."""

    name: str
    start: float | None
    stop: float | None
    step: float | None
    reference: str
    tolerance: float | None = None
    parameters: str | None = None
    stimuli: str | None = None
    tolerances: str | None = None
    scenario: str | None = None
    variant: str | None = None


def schema_text() -> bytes:
    """The vendored schema as it is loaded (its import of the annotations read as an include)."""
    folder = resources.files("toggle_cosim.fmi_ls_ref") / "schemas"
    return (folder / SCHEMA).read_bytes().replace(_IMPORT, _INCLUDE)


@functools.cache
def schema() -> etree.XMLSchema:
    folder = resources.files("toggle_cosim.fmi_ls_ref") / "schemas"
    with resources.as_file(folder / SCHEMA) as path:
        return etree.XMLSchema(etree.fromstring(schema_text(), base_url=str(path)))


def _problem(root: Element) -> str | None:
    return first_problem(schema(), root)


def _number(value: float | None) -> str:
    return repr(float(value))


def experiments_xml(experiments: Sequence[Experiment], name: str, description: str | None = None) -> bytes:
    """The Experiments document `name` of `experiments`, checked against the schema (a failure is our bug)."""
    root = etree.Element("Experiments", name=name)
    if description:
        root.set("description", description)
    for experiment in experiments:
        element = etree.SubElement(root, "Experiment", name=experiment.name)
        if experiment.tolerance is not None:
            element.set("tolerance", _number(experiment.tolerance))
        times = etree.SubElement(element, "TransientSimulation")
        for attribute, value in (
            ("startTime", experiment.start),
            ("stopTime", experiment.stop),
            ("stepSize", experiment.step),
        ):
            if value is not None:
                times.set(attribute, _number(value))
        for tag, source in (
            ("Parameters", experiment.parameters),
            ("Stimuli", experiment.stimuli),
            ("References", experiment.reference),
        ):
            if source is not None:
                etree.SubElement(element, tag, source=source)
        if experiment.tolerances is not None or experiment.scenario is not None:
            ours = etree.SubElement(etree.SubElement(element, "Annotations"), "Annotation", type=ANNOTATION)
            if experiment.tolerances is not None:
                etree.SubElement(ours, "Tolerances", source=experiment.tolerances)
            if experiment.scenario is not None:
                scenario = etree.SubElement(ours, "Scenario", source=experiment.scenario)
                if experiment.variant is not None:
                    scenario.set("variant", experiment.variant)
    problem = _problem(root)
    if problem is not None:
        raise AssertionError(f"the experiment document we wrote is not valid ({problem})")
    etree.indent(root)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8") + b"\n"


def relative_to(document_source: str, source: str) -> str:
    """A source of the document, made relative to the manifest's folder (where the document is)."""
    folder = posixpath.dirname(document_source)
    return posixpath.normpath(posixpath.join(folder, source)) if folder else source


def _time(element: Element | None, attribute: str) -> float | None:
    value = None if element is None else element.get(attribute)
    return None if value is None else float(value)


def read_experiments(
    data: bytes, where: str, document_source: str = ""
) -> tuple[tuple[Experiment, ...], tuple[str, ...]]:
    """The transient experiments of a document that name References (sources made relative to the
    manifest's folder), and the names of those it has that cannot be verified (another analysis
    type, or no References), each with why; LsRefError naming `where` for a document that is not
    valid against the schema or runs backwards."""
    try:
        root = read_xml(data, where, EXPERIMENTS_FILE)
    except XmlRefused as error:
        raise LsRefError(str(error)) from None
    problem = _problem(root)
    if problem is not None:
        raise LsRefError(
            f"{where}: not a valid MA-HS-Experiments document ({problem}); write it again with toggle-cosim pack"
        )
    experiments, skipped = [], []
    for element in root.iterfind("Experiment"):
        name = element.get("name")
        times = element.find("TransientSimulation")
        references = element.find("References")
        if times is None:
            kind = next(iter(element)).tag
            skipped.append(f"{document_source}#{name} ({kind}: not a transient simulation)")
            continue
        if references is None or references.get("type", "text/csv") != "text/csv":
            why = "no References" if references is None else f"References of type {references.get('type')}"
            skipped.append(f"{document_source}#{name} ({why})")
            continue
        files = {}
        for tag in ("Parameters", "Stimuli"):
            child = element.find(tag)
            files[tag] = None if child is None else relative_to(document_source, child.get("source"))
        ours = element.find(f"Annotations/Annotation[@type='{ANNOTATION}']")
        tolerances = None if ours is None else ours.find("Tolerances")
        scenario = None if ours is None else ours.find("Scenario")
        tolerance = element.get("tolerance")
        experiment = Experiment(
            name,
            _time(times, "startTime"),
            _time(times, "stopTime"),
            _time(times, "stepSize"),
            relative_to(document_source, references.get("source")),
            None if tolerance is None else float(tolerance),
            files["Parameters"],
            files["Stimuli"],
            None if tolerances is None else relative_to(document_source, tolerances.get("source")),
            None if scenario is None else relative_to(document_source, scenario.get("source")),
            None if scenario is None else scenario.get("variant"),
        )
        given = [v for v in (experiment.start, experiment.stop, experiment.step) if v is not None]
        if not all(math.isfinite(v) for v in given) or (
            experiment.start is not None and experiment.stop is not None and experiment.stop <= experiment.start
        ):
            raise LsRefError(f"{where}: experiment {name!r} needs finite times with stopTime > startTime")
        if experiment.step is not None and experiment.step <= 0:
            raise LsRefError(f"{where}: experiment {name!r} needs a stepSize > 0")
        experiments.append(experiment)
    return tuple(experiments), tuple(skipped)
