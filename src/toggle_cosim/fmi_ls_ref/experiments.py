"""Experiment documents carried in an FMU (FMI-LS-REF role `experiment`): what to run and what to
hold it against. The schema is our own (`schemas/toggleExperiments.xsd`): each `Experiment` has a
name, start and stop time, a step size (the output interval, and a run's sample time), an optional
relative tolerance, and carried files by source relative to the document's folder: an SSV
parameter set, a CSV of stimuli (the FMU's inputs over time), the CSV reference, funnel
tolerances (YAML as `toggle-cosim compare` reads them) and, for our own plants, the scenario that
runs it through the co-simulation master.
"""

from __future__ import annotations

import functools
import math
import posixpath
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources

from lxml import etree

from toggle_cosim.fmi_ls_ref.manifest import LsRefError
from toggle_cosim.ssp.checks import Element, SspError, parse_xml

NS = "https://github.com/toggle-cosim/toggle-cosim/experiments"
MIME = "application/x-toggle-cosim-experiments+xml"
SCHEMA = "toggleExperiments.xsd"
FILES = ("Parameters", "Stimuli", "Reference", "Tolerances")


@dataclass(frozen=True)
class Experiment:
    """One experiment; the file fields are sources relative to the experiment document."""

    name: str
    start: float
    stop: float
    step: float
    reference: str
    tolerance: float | None = None
    parameters: str | None = None
    stimuli: str | None = None
    tolerances: str | None = None
    scenario: str | None = None
    variant: str | None = None


@functools.cache
def schema() -> etree.XMLSchema:
    folder = resources.files("toggle_cosim.fmi_ls_ref") / "schemas"
    with resources.as_file(folder / SCHEMA) as path:
        return etree.XMLSchema(etree.parse(str(path)))


def _problem(root: Element) -> str | None:
    checker = schema()
    if checker.validate(root):
        return None
    entry = checker.error_log[0]
    return f"line {entry.line}: {' '.join(entry.message.split())}"


def experiments_xml(experiments: Sequence[Experiment]) -> bytes:
    """The document of `experiments`, checked against the schema (a failure is our bug)."""
    root = etree.Element(f"{{{NS}}}Experiments", nsmap={None: NS}, version="1.0")
    for experiment in experiments:
        element = etree.SubElement(
            root,
            f"{{{NS}}}Experiment",
            name=experiment.name,
            startTime=repr(float(experiment.start)),
            stopTime=repr(float(experiment.stop)),
            stepSize=repr(float(experiment.step)),
        )
        if experiment.tolerance is not None:
            element.set("tolerance", repr(float(experiment.tolerance)))
        for tag, source in zip(
            FILES, (experiment.parameters, experiment.stimuli, experiment.reference, experiment.tolerances), strict=True
        ):
            if source is not None:
                etree.SubElement(element, f"{{{NS}}}{tag}", source=source)
        if experiment.scenario is not None:
            scenario = etree.SubElement(element, f"{{{NS}}}Scenario", source=experiment.scenario)
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


def read_experiments(data: bytes, where: str, document_source: str = "") -> tuple[Experiment, ...]:
    """The experiments of a document (sources made relative to the manifest's folder); LsRefError
    naming `where` for a document that is not valid against the schema or runs backwards."""
    try:
        root = parse_xml(data, where)
    except SspError as error:
        raise LsRefError(str(error)) from None
    problem = _problem(root)
    if problem is not None:
        raise LsRefError(f"{where}: not a valid experiment document ({problem}); write it again with toggle-cosim pack")
    experiments = []
    for element in root.iterfind(f"{{{NS}}}Experiment"):
        files = {}
        for tag in (*FILES, "Scenario"):
            child = element.find(f"{{{NS}}}{tag}")
            files[tag] = None if child is None else relative_to(document_source, child.get("source"))
        scenario = element.find(f"{{{NS}}}Scenario")
        tolerance = element.get("tolerance")
        experiment = Experiment(
            element.get("name"),
            float(element.get("startTime")),
            float(element.get("stopTime")),
            float(element.get("stepSize")),
            files["Reference"],
            None if tolerance is None else float(tolerance),
            files["Parameters"],
            files["Stimuli"],
            files["Tolerances"],
            files["Scenario"],
            None if scenario is None else scenario.get("variant"),
        )
        if (
            not all(math.isfinite(v) for v in (experiment.start, experiment.stop))
            or experiment.stop <= experiment.start
        ):
            raise LsRefError(f"{where}: experiment {experiment.name!r} needs finite times with stopTime > startTime")
        experiments.append(experiment)
    return tuple(experiments)
