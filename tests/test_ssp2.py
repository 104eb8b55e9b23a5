"""SSP 2.0 read and written (`toggle_cosim.ssp`, docs/ssp.md "SSP 2.0").

Every shipped scenario written both ways (`ssp` and `ssp --ssp-version 2.0`): each SSD and .ssv
says its version and validates against that version's vendored schemas, the 2.0 documents with
Float64 connectors and values; run in our master with the controller FMU, both give the same
trace arrays bit for bit. An SSD written by hand in OMSimulator's style (version 2.0, Float64
connectors, a system-level .ssv; `tests/ssp_documents/omsimulator_2.0/`) runs exactly as its
1.0 twin. Each construct of SSP 2.0 our master cannot run (clocks, arrays, Scheduled Execution,
String/Enumeration/Binary values and connections) is refused in one line naming it, exit 2,
nothing written. MetaData and Signature are passed through: kept as written, in run.json and
from Python. pyssp-standard, an independent reader (its own schema copies, validated as XML
Schema 1.1 by xmlschema), reads our 2.0 output.
"""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from lxml import etree

from toggle_cosim.cli import main
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.files.traces import read_csv as read_trace_csv
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import SspError, schema
from toggle_cosim.ssp.reader import open_ssp, read_ssp
from toggle_cosim.ssp.writer import write_ssp

ROOT = Path(__file__).resolve().parent.parent
HANDMADE = ROOT / "tests" / "ssp_documents" / "omsimulator_2.0"
NS = layout.NAMESPACES
VARYING_OR_TRACKING = ("step_load", "measured_load", "press_cycle")  # refused by `ssp` in any version
SCENARIOS = sorted(
    p
    for p in (ROOT / "scenarios").glob("*.yaml")
    if not p.name.startswith(("sweep_", "tune_")) and p.stem not in VARYING_OR_TRACKING
)


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def _zip(target: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return target


def _run(path: Path, out: Path, *extra: str) -> None:
    ran = CliRunner().invoke(main, ["run", str(path), "--out", str(out), "-q", *extra])
    assert ran.exit_code == 0, ran.output


def _same_traces(first: Path, second: Path) -> None:
    """The two trace.csv files hold the same columns and the same arrays, bit for bit."""
    a, b = read_trace_csv(first), read_trace_csv(second)
    assert a.names == b.names
    for column in a.names:
        assert np.array_equal(a.column(column), b.column(column)), column


# fig4_nominal in the fast set; every other shipped scenario is in the slow set (-m "not slow" leaves it out)
FAST_SCENARIO = "fig4_nominal"


@pytest.mark.parametrize(
    "scenario",
    [pytest.param(p, id=p.stem, marks=() if p.stem == FAST_SCENARIO else pytest.mark.slow) for p in SCENARIOS],
)
def test_both_versions_of_every_shipped_scenario_validate_and_run_bit_for_bit(
    scenario: Path, request: pytest.FixtureRequest, vsc_fmu: Path, tmp_path: Path
) -> None:
    """`ssp` writes SSP 1.0 by default and SSP 2.0 with --ssp-version 2.0: the same members, each
    SSD and .ssv saying its version and valid against that version's schemas (a 2.0 SSD, with its
    Float64 connectors, is no valid 1.0 document); 2.0 writes ssc:Float64 and ssv:Float64 where
    1.0 writes Real. Every variant of both runs in our master to the same trace arrays."""
    plant = request.getfixturevalue("no_gravity_fmu" if scenario.stem == "swap_no_gravity" else "plant_fmu")
    written = {}
    for version, extra in (("1.0", []), ("2.0", ["--ssp-version", "2.0"])):
        out = tmp_path / f"v{version}" / "study.ssp"
        out.parent.mkdir()
        args = ["ssp", str(scenario), "--plant", str(plant), "--controller", str(vsc_fmu), "--out", str(out)]
        ran = CliRunner().invoke(main, [*args, *extra])
        assert ran.exit_code == 0, ran.output
        written[version] = _members(out)
    assert sorted(written["1.0"]) == sorted(written["2.0"])
    for member, data in written["2.0"].items():
        if member.endswith((".ssd", ".ssv")):
            kind = member.rsplit(".", 1)[1]
            new, old = etree.fromstring(data), etree.fromstring(written["1.0"][member])
            assert (new.get("version"), old.get("version")) == ("2.0", "1.0")
            assert schema(kind, "2.0").validate(new), schema(kind, "2.0").error_log
            assert schema(kind, "1.0").validate(old), schema(kind, "1.0").error_log
            names = {etree.QName(e).localname for e in new.iter() if isinstance(e.tag, str)}
            assert "Real" not in names and "Float64" in names
    ssd = etree.fromstring(written["2.0"][layout.SSD_MEMBER])
    assert not schema("ssd", "1.0").validate(ssd)  # checked against its own version's schema only
    variants = [arg for run in load_scenario(scenario) for arg in ("--variant", layout.set_name(run.variant))]
    for version in written:
        _run(tmp_path / f"v{version}" / "study.ssp", tmp_path / f"out{version}", *variants)
    for run in load_scenario(scenario):
        folder = Path("study_ssp") / layout.set_name(run.variant)
        _same_traces(tmp_path / "out1.0" / folder / "trace.csv", tmp_path / "out2.0" / folder / "trace.csv")
        record = json.loads((tmp_path / "out2.0" / folder / "run.json").read_text())["resolved"]["ssp"]
        assert record["version"] == "2.0"


def _handmade(plant_fmu: Path, vsc_fmu: Path, edit=None) -> dict[str, bytes]:  # noqa: ANN001
    """The hand-written OMSimulator-style SSP 2.0 (its SSD and .ssv from the test documents, the
    two FMUs where its SSD says), with `edit(text) -> text` applied to every XML member."""
    members = {
        "SystemStructure.ssd": (HANDMADE / "SystemStructure.ssd").read_bytes(),
        "resources/toggle.ssv": (HANDMADE / "resources" / "toggle.ssv").read_bytes(),
    }
    if edit is not None:
        members = {name: edit(data.decode()).encode() for name, data in members.items()}
    members["resources/0001_mechanism.fmu"] = plant_fmu.read_bytes()
    members["resources/0002_vsc.fmu"] = vsc_fmu.read_bytes()
    return members


def _as_1_0(text: str) -> str:
    """The SSP 1.0 twin of a hand-written 2.0 document: version 1.0, Real for Float64."""
    text = text.replace('version="2.0"', 'version="1.0"')
    return re.sub(r"<(ss[cv]):Float64\b", r"<\1:Real", text)


def test_a_hand_written_omsimulator_style_2_0_ssd_runs_as_its_1_0_twin(
    plant_fmu: Path, vsc_fmu: Path, tmp_path: Path
) -> None:
    """The SSD in OMSimulator's style (version 2.0, Float64 connectors with geometry, a system
    -level binding of element.variable values, OMSimulator's annotations), written by hand,
    reads and runs; its 1.0 twin (version 1.0, Real) is valid SSP 1.0 and gives the same trace
    arrays bit for bit, and both runs set the same values."""
    twin = _handmade(plant_fmu, vsc_fmu, _as_1_0)
    assert schema("ssd", "1.0").validate(etree.fromstring(twin["SystemStructure.ssd"]))
    assert schema("ssv", "1.0").validate(etree.fromstring(twin["resources/toggle.ssv"]))
    _zip(tmp_path / "oms.ssp", _handmade(plant_fmu, vsc_fmu))
    _zip(tmp_path / "twin.ssp", twin)
    _run(tmp_path / "oms.ssp", tmp_path / "a")
    _run(tmp_path / "twin.ssp", tmp_path / "b")
    _same_traces(
        tmp_path / "a" / "oms_ssp" / "toggle" / "trace.csv", tmp_path / "b" / "twin_ssp" / "toggle" / "trace.csv"
    )
    records = [
        json.loads((tmp_path / out / f"{name}_ssp" / "toggle" / "run.json").read_text())["resolved"]["ssp"]
        for out, name in (("a", "oms"), ("b", "twin"))
    ]
    assert records[0]["components"] == records[1]["components"]
    plant = records[0]["components"]["plant"]
    assert plant["name"] == "mechanism" and plant["values"] == {
        "m_B": 4.43,
        "mu": 0.2,
        "idealCurrentLoop": False,
        "F_E": 100.0,
    }
    assert records[0]["version"] == "2.0" and "version" not in records[1]  # a 1.0 record is as it was


def _replace(old: str, new: str):  # noqa: ANN202
    def edit(text: str) -> str:
        return text.replace(old, new, 1)

    return edit


def _inline_vsc(parameters: str):  # noqa: ANN202
    """An inline SSP 2.0 parameter set of `parameters` bound to the component vsc (the SSD's last)."""

    def edit(text: str) -> str:
        if "<ssd:SystemStructureDescription" not in text:
            return text
        head, tail = text.rsplit("</ssd:Component>", 1)
        binding = (
            '<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="2.0" '
            f'name="inline"><ssv:Parameters>{parameters}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>'
            "</ssd:ParameterBinding></ssd:ParameterBindings>"
        )
        return f"{head}{binding}</ssd:Component>{tail}"

    return edit


MECHANISM_IQ = '<ssd:Connector\n            name="iq_ref"\n            kind="input">\n            <ssc:Float64 />'
MU = '<ssv:Float64\n        value="0.2" />'
# each construct of SSP 2.0 our master cannot run: the edit of the hand-written SSP, and what
# the one line says (after the file and the member)
REFUSED = {
    "a Clock connector": (
        _replace(MECHANISM_IQ, MECHANISM_IQ.replace("<ssc:Float64 />", "<ssc:Clock />")),
        "SystemStructure.ssd: component 'mechanism''s connector 'iq_ref' is a Clock connector (SSP 2.0 clocks",
    ),
    "a connector on a clock": (
        _replace(MECHANISM_IQ, MECHANISM_IQ + '<ssd:Clock name="tick" />'),
        "SystemStructure.ssd: component 'mechanism''s connector 'iq_ref' is associated with the clock 'tick'",
    ),
    "an array connector": (
        _replace(MECHANISM_IQ, MECHANISM_IQ + '<ssc:Dimension size="3" />'),
        "SystemStructure.ssd: component 'mechanism''s connector 'iq_ref' is an array (ssc:Dimension",
    ),
    "Scheduled Execution": (
        _replace('name="vsc"', 'name="vsc" implementation="ScheduledExecution"'),
        "SystemStructure.ssd: component 'vsc' asks for implementation 'ScheduledExecution' (SSP 2.0 Scheduled",
    ),
    "an array parameter": (
        _replace(MU, MU + '<ssc:Dimension size="1" />'),
        "resources/toggle.ssv: parameter 'mechanism.mu' is an array (ssc:Dimension",
    ),
    "a list of values": (
        _replace(MU, MU.replace('"0.2"', '"0.2 0.3"')),
        "resources/toggle.ssv: parameter 'mechanism.mu' has 2 values ('0.2 0.3': an array",
    ),
    "a Float32 past single precision": (
        _replace(MU, '<ssv:Float32 value="1e39" />'),
        "resources/toggle.ssv: mechanism.mu = inf is not a finite number",
    ),
    "a String value": (
        _replace(MU, '<ssv:String value="0.2" />'),
        "resources/toggle.ssv: parameter 'mechanism.mu' is given as String",
    ),
    "an Enumeration value": (
        _replace(MU, '<ssv:Enumeration value="low" />'),
        "resources/toggle.ssv: parameter 'mechanism.mu' is given as Enumeration",
    ),
    "a Binary value": (
        _replace(MU, '<ssv:Binary value="00ff" />'),
        "resources/toggle.ssv: parameter 'mechanism.mu' is given as Binary",
    ),
    "a Binary connection": (
        _replace(MECHANISM_IQ, MECHANISM_IQ.replace("Float64", "Binary")),
        "the connection vsc.iq_ref -> mechanism.iq_ref joins mechanism.iq_ref, a Binary connector",
    ),
    "a version we do not read": (
        _replace('version="2.0">\n  <ssd:System', 'version="3.0">\n  <ssd:System'),
        "SystemStructure.ssd: version '3.0' is not an SSP version toggle-cosim reads (1.0 or 2.0",
    ),
    "inline values their schema refuses": (
        _inline_vsc('<ssv:Parameter name="C"><ssv:Float64 value="zero" /></ssv:Parameter>'),
        "SystemStructure.ssd: the inline ParameterValues of Component 'vsc' are not valid (line",
    ),
    "a 2.0 document its schema refuses": (
        _replace(MU, MU.replace('"0.2"', '"zero"')),
        "resources/toggle.ssv: not valid SSP 2.0 (line",
    ),
}


@pytest.mark.parametrize("case", REFUSED, ids=list(REFUSED))
def test_what_our_master_cannot_run_is_refused_in_one_line(
    case: str, plant_fmu: Path, vsc_fmu: Path, tmp_path: Path
) -> None:
    """Each case: exit 2, one line naming the SSP, the member, the element and the construct, no
    traceback, nothing written under --out; the reader raises the same line."""
    edit, expected = REFUSED[case]
    bad = _zip(tmp_path / "bad.ssp", _handmade(plant_fmu, vsc_fmu, edit))
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(bad), "--out", str(out), "-q"])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.output, result.output
    assert lines[0].startswith(f"error: {bad}: ") and expected in lines[0], lines[0]
    assert not out.exists() or not any(out.iterdir())
    with pytest.raises(SspError, match=re.escape(expected)):
        read_ssp(bad)


METADATA = (
    '<ssc:MetaData kind="general" type="application/x-srmd+xml">'
    '<ssc:Content><srmd:SimulationResourceMetaData xmlns:srmd="urn:example:srmd" name="toggle"/></ssc:Content>'
    '<ssc:Signature role="authenticity" type="application/pkcs7-signature" source="resources/srmd.p7s"/>'
    "</ssc:MetaData>"
    '<ssc:MetaData kind="quality" type="text/plain" source="resources/quality.txt"/>'
    '<ssc:Signature role="suitability" type="text/plain"><ssc:Content>checked</ssc:Content></ssc:Signature>'
)


def test_metadata_and_signatures_are_passed_through(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """A root SSD's MetaData (inline content or a source) and Signature elements are kept as
    written, readable from Python and recorded in run.json (the content's size, not the content);
    their sources need not be in the archive (nothing reads them) and they change nothing that runs."""
    edit = _replace("</ssd:DefaultExperiment>", "</ssd:DefaultExperiment>" + METADATA)
    with_metadata = _zip(tmp_path / "meta.ssp", _handmade(plant_fmu, vsc_fmu, edit))
    with open_ssp(with_metadata) as study:
        assert study.version == "2.0"
        general, quality = study.metadata
        assert (general.kind, general.type, general.source) == ("general", "application/x-srmd+xml", None)
        assert "SimulationResourceMetaData" in general.content and 'name="toggle"' in general.content
        assert [(s.role, s.source) for s in general.signatures] == [("authenticity", "resources/srmd.p7s")]
        assert (quality.kind, quality.source, quality.content) == ("quality", "resources/quality.txt", None)
        assert [(s.role, s.content) for s in study.signatures] == [("suitability", "checked")]
    _run(with_metadata, tmp_path / "a")
    _run(_zip(tmp_path / "plain.ssp", _handmade(plant_fmu, vsc_fmu)), tmp_path / "b")
    record = json.loads((tmp_path / "a" / "meta_ssp" / "toggle" / "run.json").read_text())["resolved"]["ssp"]
    assert [entry["kind"] for entry in record["metadata"]] == ["general", "quality"]
    assert record["metadata"][0]["signatures"][0]["role"] == "authenticity"
    assert record["metadata"][0]["content_bytes"] > 0 and record["metadata"][1]["source"] == "resources/quality.txt"
    assert record["signatures"] == [{"role": "suitability", "type": "text/plain", "source": None, "content_bytes": 7}]
    _same_traces(
        tmp_path / "a" / "meta_ssp" / "toggle" / "trace.csv", tmp_path / "b" / "plain_ssp" / "toggle" / "trace.csv"
    )


def test_pyssp_standard_reads_our_2_0_ssp(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """pyssp-standard, an SSP library of its own (its schema copies, validated as XML Schema 1.1
    by xmlschema), reads the 2.0 SSD and .ssv files we write: version 2.0, the components, the
    connections, the stop time, every parameter with its Float64/Boolean type; both comply."""
    ssd_module = pytest.importorskip("pyssp_standard.ssd")
    ssv_module = pytest.importorskip("pyssp_standard.ssv")
    scenario = ROOT / "scenarios" / "fig5_external_force.yaml"
    path = write_ssp(scenario, tmp_path / "fig5.ssp", plant_fmu, vsc_fmu, version="2.0")
    with zipfile.ZipFile(path) as archive:
        archive.extractall(tmp_path / "unpacked")
    run = load_scenario(scenario)[0]
    with ssd_module.SSD(tmp_path / "unpacked" / layout.SSD_MEMBER) as ssd:
        ssd.__check_compliance__()
        assert (ssd.version, ssd.name) == ("2.0", "friction")
        assert [element.name for element in ssd.system.elements] == ["plant", "controller"]
        wires = {(c.start_element, c.start_connector, c.end_element, c.end_connector) for c in ssd.connections()}
        signals = ("x_B", "v_B", "theta1", "omega1")
        assert wires == {("plant", s, "controller", s) for s in signals} | {("controller", "iq_ref", "plant", "iq_ref")}
        assert ssd.default_experiment.stop_time == run.t_end
    for component in (layout.PLANT, layout.CONTROLLER):
        member = tmp_path / "unpacked" / layout.ssv_member("friction", component)
        ours = etree.parse(str(member)).getroot()
        with ssv_module.SSV(member) as ssv:
            ssv.__check_compliance__()
            assert (ssv.version, ssv.name) == ("2.0", "friction")
            theirs = [(p["name"], p["type_name"]) for p in ssv.parameters]
        expected = [
            (p.get("name"), etree.QName(p[0]).localname) for p in ours.iterfind("ssv:Parameters/ssv:Parameter", NS)
        ]
        assert theirs == expected and {kind for _, kind in theirs} <= {"Float64", "Boolean", "Int32"}


def test_ssp_version_is_checked_in_one_line(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """--ssp-version takes 1.0 or 2.0; anything else is one line, exit 2, and no file."""
    out = tmp_path / "study.ssp"
    scenario = ROOT / "scenarios" / "fig5_external_force.yaml"
    args = ["ssp", str(scenario), "--plant", str(plant_fmu), "--controller", str(vsc_fmu), "--out", str(out)]
    result = CliRunner().invoke(main, [*args, "--ssp-version", "2.1"])
    assert result.exit_code == 2, result.output
    assert result.output.strip() == (
        "error: SSP version '2.1' (--ssp-version): toggle-cosim writes SSP 1.0 or 2.0 (give one of them)"
    )
    assert not out.exists()


def test_a_2_0_ssd_carries_the_studys_srmd_in_its_metadata(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """Each 2.0 root SSD holds one MetaData (kind general, type application/x-srmd) whose inline
    content is a valid SRMD record naming, by archive path and SHA3-256, the FMUs and the
    variant's .ssv files it uses, with the scenario and the variant as settings; the reader keeps
    it. A 1.0 SSD has no MetaData (SSP 1.0 has no place for it)."""
    import hashlib

    from toggle_cosim.provenance import srmd

    scenario = ROOT / "scenarios" / "fig5_external_force.yaml"
    path = write_ssp(scenario, tmp_path / "fig5.ssp", plant_fmu, vsc_fmu, version="2.0")
    members = _members(path)
    for member, variant in ((layout.SSD_MEMBER, "friction"), ("no_friction.ssd", "no_friction")):
        ssd = etree.fromstring(members[member])
        (metadata,) = ssd.findall("ssc:MetaData", NS)
        assert (metadata.get("kind"), metadata.get("type"), metadata.get("source")) == (
            "general",
            "application/x-srmd",
            None,
        )
        (document,) = metadata.find("ssc:Content", NS)
        record = srmd.from_xml(etree.tostring(document), member)
        used = {r.uri: r for r in record.resources}
        expected = {
            "resources/ToggleLSM.fmu": ("model", "plant"),
            "resources/ToggleVSC.fmu": ("model", "controller"),
            layout.ssv_member(variant, "plant"): ("parameter", "plant parameters"),
            layout.ssv_member(variant, "controller"): ("parameter", "controller parameters"),
        }
        assert {uri: (r.kind, r.role) for uri, r in used.items()} == expected
        assert all(r.checksum == hashlib.sha3_256(members[uri]).hexdigest() for uri, r in used.items())
        assert record.setting("variant") == variant and record.setting("scenario") == scenario.name
        assert record.setting("scenario-sha3-256") == hashlib.sha3_256(scenario.read_bytes()).hexdigest()
        assert dict(record.tools)["toggle-cosim"] and record.generation_tool.startswith("toggle-cosim")
    with open_ssp(path) as study:
        assert [m.type for m in study.metadata] == ["application/x-srmd"]
        assert "SimulationResourceMetaData" in study.metadata[0].content
    old = _members(write_ssp(scenario, tmp_path / "fig5-1.0.ssp", plant_fmu, vsc_fmu))
    assert etree.fromstring(old[layout.SSD_MEMBER]).find("ssc:MetaData", NS) is None


def test_fmi3_number_types_are_read_as_real_and_integer(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """A Float32 value is the single-precision number it writes (mu = float32(0.2)); an Int8 value
    is an Integer, set on the Real variable frictionModel as any Integer value is (2 -> 2.0)."""
    edit = _both(
        _replace(MU, '<ssv:Float32 value="0.2" />'),
        _replace(
            "</ssv:Parameters>",
            '<ssv:Parameter name="mechanism.frictionModel"><ssv:Int8 value="2" /></ssv:Parameter></ssv:Parameters>',
        ),
    )
    with open_ssp(_zip(tmp_path / "types.ssp", _handmade(plant_fmu, vsc_fmu, edit))) as study:
        values = dict(study.plant_values)
    assert values["mu"] == float(np.float32(0.2)) != 0.2
    assert values["frictionModel"] == 2.0 and isinstance(values["frictionModel"], float)


def _both(*edits):  # noqa: ANN002, ANN202
    def edit(text: str) -> str:
        for one in edits:
            text = one(text)
        return text

    return edit
