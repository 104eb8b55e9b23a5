"""FMI-LS-REF: files packed into an FMU without touching its other members, validated by an
independent validator (xmlschema, which pyssp-standard uses, against the schemas as published),
and the FMU verified against what it carries: a model we do not ship (a Van der Pol oscillator,
built with our build) and our plant with the shipped scenarios' evidence."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
import xmlschema
from click.testing import CliRunner
from lxml import etree

from toggle_cosim.cli import main
from toggle_cosim.files.traces import Trace, write_csv
from toggle_cosim.fmi_ls_ref.manifest import MANIFEST, LsRefError
from toggle_cosim.fmi_ls_ref.verify import verify_fmu

DATA = Path(__file__).parent / "data" / "lsref"
SCHEMAS = Path(__file__).resolve().parent.parent / "src" / "toggle_cosim" / "fmi_ls_ref" / "schemas"
ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def van_der_pol(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The Van der Pol FMU as our build writes it for a user (FMI 2.0, Co-Simulation), and a
    reference of x0 and x1 over its default experiment, from FMPy."""
    from toggle_cosim.fmu_export import build_fmu

    folder = tmp_path_factory.mktemp("vdp")
    fmu = build_fmu(DATA / "VanDerPol.mo", "VanDerPol", folder / "VanDerPol.fmu", interfaces="cs").fmu.path
    result = fmpy.simulate_fmu(str(fmu), output=["x0", "x1"])
    reference = folder / "VanDerPol_ref.csv"
    write_csv(reference, Trace(("time", "x0", "x1"), np.column_stack([result[n] for n in ("time", "x0", "x1")])))
    return fmu, reference


def _pack(fmu: Path, reference: Path, out: Path, *extra: str) -> Path:
    result = CliRunner().invoke(main, ["pack", str(fmu), "--reference", str(reference), "--out", str(out), *extra])
    assert result.exit_code == 0, result.output
    return out


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def test_packing_copies_every_member_byte_for_byte_and_the_fmu_stays_valid(van_der_pol, tmp_path: Path) -> None:
    fmu, reference = van_der_pol
    packed = _pack(fmu, reference, tmp_path / "packed.fmu")
    before, after = _members(fmu), _members(packed)
    assert {name: after[name] for name in before} == before  # binaries/, modelDescription.xml, sources/
    assert any(name.startswith("binaries/") for name in before)
    assert set(after) - set(before) == {
        MANIFEST,
        "extra/org.fmi-standard.fmi-ls-ref/metadata/fmu.srmd",
        "extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/experiment.xml",
        "extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/reference.csv",
    }
    assert fmpy.validation.validate_fmu(str(packed)) == []


def test_the_manifest_and_experiment_validate_with_xmlschema(van_der_pol, tmp_path: Path) -> None:
    """xmlschema (pyssp-standard's validator), not lxml, against the published schemas."""
    fmu, reference = van_der_pol
    members = _members(_pack(fmu, reference, tmp_path / "packed.fmu"))
    manifest = tmp_path / "fmi-ls-manifest.xml"
    manifest.write_bytes(members[MANIFEST])
    xmlschema.XMLSchema10(str(SCHEMAS / "fmi3LayeredStandardReferenceManifest.xsd")).validate(str(manifest))
    experiment = tmp_path / "experiment.xml"
    experiment.write_bytes(members["extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/experiment.xml"])
    from toggle_cosim.fmi_ls_ref.experiments import schema_text

    standard = tmp_path / "maHarmonizedSpecificationExperiments.xsd"  # as loaded: its import read as an include
    standard.write_bytes(schema_text())
    shutil.copy(SCHEMAS / "fmi3Annotation.xsd", tmp_path)
    xmlschema.XMLSchema10(str(standard)).validate(str(experiment))
    root = etree.fromstring(members["extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/experiment.xml"])
    assert root.tag == "Experiments" and root.find("Experiment/TransientSimulation") is not None
    assert root.find("Experiment/References").get("source") == "reference.csv"


def test_a_model_we_do_not_ship_verifies_and_a_perturbed_reference_fails_naming_the_variable(
    van_der_pol, tmp_path: Path
) -> None:
    fmu, reference = van_der_pol
    runner = CliRunner()
    good = _pack(fmu, reference, tmp_path / "good.fmu")
    passed = runner.invoke(main, ["verify", str(good), "--out", str(tmp_path / "good")])
    assert passed.exit_code == 0, passed.output
    assert "VanDerPol_ref: pass (fmpy)" in passed.output

    trace = np.loadtxt(reference, delimiter=",", skiprows=1)
    trace[200:260, 1] += 0.05  # x0 moved far beyond its funnel over 0.6 s
    perturbed = tmp_path / "perturbed.csv"
    write_csv(perturbed, Trace(("time", "x0", "x1"), trace))
    bad = _pack(fmu, perturbed, tmp_path / "bad.fmu", "--name", "vdp")
    failed = runner.invoke(main, ["verify", str(bad), "--out", str(tmp_path / "bad"), "--html"])
    assert failed.exit_code == 1, failed.output
    assert "vdp: x0 off by" in failed.output and "x1 off" not in failed.output
    junit = (tmp_path / "bad" / "junit.xml").read_text()
    assert 'name="x0"' in junit and "failure" in junit
    assert "x0" in (tmp_path / "bad" / "summary.md").read_text()
    assert (tmp_path / "bad" / "report.html").is_file()


def test_a_result_without_experiment_is_held_against_the_default_experiment(van_der_pol, tmp_path: Path) -> None:
    """As the Reference FMUs carry theirs: a `result` role alone."""
    from toggle_cosim.fmi_ls_ref.manifest import Related
    from toggle_cosim.fmi_ls_ref.pack import Attachment, pack

    fmu, reference = van_der_pol
    packed = pack(
        fmu,
        [Attachment(Related("VanDerPol_out.csv", "result", "text/csv"), reference.read_bytes())],
        tmp_path / "r.fmu",
    )
    verification = verify_fmu(packed)
    assert verification.passed and [c.label for c in verification.checks] == ["default_experiment/VanDerPol_out"]


def _rewritten(source: Path, target: Path, drop: str | None = None, change: str | None = None) -> Path:
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for info in old.infolist():
            data = old.read(info)
            if info.filename == drop:
                continue
            if info.filename == change:
                data = data.replace(b",", b";", 1)[:-3] + b"9\n"
            new.writestr(info, data)
    return target


@pytest.mark.parametrize(
    ("how", "expected"),
    [
        (
            "drop",
            "names extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/reference.csv, which the FMU does not contain",
        ),
        (
            "change",
            "extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/reference.csv does not match its SHA3-256",
        ),
    ],
)
def test_a_missing_or_altered_carried_file_is_refused_in_one_line(
    van_der_pol, tmp_path: Path, how: str, expected: str
) -> None:
    fmu, reference = van_der_pol
    packed = _pack(fmu, reference, tmp_path / "packed.fmu")
    member = "extra/org.fmi-standard.fmi-ls-ref/experiments/VanDerPol_ref/reference.csv"
    broken = _rewritten(packed, tmp_path / "broken.fmu", **{how: member})
    result = CliRunner().invoke(main, ["verify", str(broken), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert expected in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()
    with pytest.raises(LsRefError, match="SHA3-256|does not contain"):
        verify_fmu(broken)


def test_our_plant_carries_its_source_and_scenarios_and_verifies_through_the_master(
    plant_fmu: Path, tmp_path: Path
) -> None:
    """What build packs into a shipped plant: the SSVs validate with pyssp-standard, the
    binaries are unchanged, and each carried run passes against its reference."""
    from pyssp_standard.ssv import SSV

    from toggle_cosim.fmi_ls_ref.evidence import shipped_evidence
    from toggle_cosim.fmi_ls_ref.pack import pack

    fmu = shutil.copy(plant_fmu, tmp_path / "ToggleLSM.fmu")
    scenarios = [ROOT / "scenarios" / "fig4_nominal.yaml"]
    packed = pack(
        Path(fmu),
        shipped_evidence(ROOT / "modelica" / "ToggleLSM", scenarios, ROOT / "scenarios" / "references", Path(fmu)),
    )
    after = _members(packed)
    assert {name: after[name] for name in _members(plant_fmu)} == _members(plant_fmu)
    assert "extra/org.fmi-standard.fmi-ls-ref/model/ToggleLSM/Plant.mo" in after
    assert fmpy.validation.validate_fmu(str(packed)) == []
    for variant in ("friction", "no_friction"):
        ssv = tmp_path / f"{variant}.ssv"
        ssv.write_bytes(after[f"extra/org.fmi-standard.fmi-ls-ref/scenarios/fig4_nominal/{variant}.ssv"])
        SSV(ssv).__check_compliance__()  # raises on an invalid file
    verification = verify_fmu(packed)
    assert [(c.label, c.runner, c.passed) for c in verification.checks] == [
        ("fig4_nominal/friction", "master", True),
        ("fig4_nominal/no_friction", "master", True),
    ]


def test_a_scenario_that_needs_files_beside_it_is_not_packed(plant_fmu: Path, tmp_path: Path) -> None:
    fmu = shutil.copy(plant_fmu, tmp_path / "ToggleLSM.fmu")
    before = Path(fmu).read_bytes()
    result = CliRunner().invoke(main, ["pack", str(fmu), "--scenario", str(ROOT / "scenarios" / "measured_load.yaml")])
    assert result.exit_code == 2 and "needs files beside it" in result.output, result.output
    assert Path(fmu).read_bytes() == before


def test_the_fmus_srmd_names_every_file_and_validates_with_pyssp_standards_schema(van_der_pol, tmp_path: Path) -> None:
    """The SRMD (role meta-data) names every file of the FMU by SHA3-256; pyssp-standard's own
    SRMD schema (xmlschema, XSD 1.1) accepts it."""
    import hashlib

    import pyssp_standard

    from toggle_cosim.provenance.srmd import from_xml

    fmu, reference = van_der_pol
    members = _members(_pack(fmu, reference, tmp_path / "packed.fmu"))
    record_member = "extra/org.fmi-standard.fmi-ls-ref/metadata/fmu.srmd"
    path = tmp_path / "fmu.srmd"
    path.write_bytes(members[record_member])
    schema = Path(pyssp_standard.__file__).parent / "resources" / "SRMD11.xsd"
    xmlschema.XMLSchema11(str(schema)).validate(str(path))
    named = {
        r.uri.removeprefix("../../../").removeprefix("../"): r.checksum
        for r in from_xml(path.read_bytes(), "x").resources
    }
    expected = {n for n in members if n not in (MANIFEST, record_member)}
    assert {n.removeprefix("extra/org.fmi-standard.fmi-ls-ref/") for n in expected} == set(named)
    assert named["modelDescription.xml"] == hashlib.sha3_256(members["modelDescription.xml"]).hexdigest()
    assert 'role="meta-data"' in members[MANIFEST].decode()


def test_an_fmu_whose_model_description_changed_after_packing_is_refused(van_der_pol, tmp_path: Path) -> None:
    """The manifest lists only the carried files; the SRMD covers the FMU's own files too."""
    fmu, reference = van_der_pol
    packed = _pack(fmu, reference, tmp_path / "packed.fmu")
    broken = tmp_path / "broken.fmu"
    with zipfile.ZipFile(packed) as old, zipfile.ZipFile(broken, "w") as new:
        for info in old.infolist():
            data = old.read(info)
            if info.filename == "modelDescription.xml":
                data = data.replace(b'description="', b'description="changed ', 1)
            new.writestr(info, data)
    result = CliRunner().invoke(main, ["verify", str(broken), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert "modelDescription.xml does not match its SHA3-256 checksum in the FMU's SRMD" in result.output


def test_a_carried_scenario_that_names_code_is_refused_not_run(plant_fmu: Path, tmp_path: Path) -> None:
    """An FMU cannot make verify import a module: a carried scenario with controller.python is
    refused in one line before any run."""
    from toggle_cosim.fmi_ls_ref.experiments import MIME, Experiment, experiments_xml
    from toggle_cosim.fmi_ls_ref.manifest import Related
    from toggle_cosim.fmi_ls_ref.pack import Attachment, pack

    scenario = (ROOT / "scenarios" / "fig4_nominal.yaml").read_text()
    scenario += "\n# added\n"
    scenario = scenario.replace("controller:\n", 'controller:\n  python: "json:loads"\n', 1)
    reference = (ROOT / "scenarios" / "references" / "fig4_nominal" / "friction_ref.csv").read_bytes()
    experiment = Experiment("x", 0.0, 1.5, 0.0005, "ref.csv", None, None, None, None, "s.yaml", "friction")
    packed = pack(
        Path(shutil.copy(plant_fmu, tmp_path / "P.fmu")),
        [
            Attachment(Related("s.yaml", "configuration"), scenario.encode()),
            Attachment(Related("ref.csv", "result"), reference),
            Attachment(Related("e.xml", "experiment", MIME), experiments_xml([experiment], "x")),
        ],
    )
    result = CliRunner().invoke(main, ["verify", str(packed), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert "names code or FMUs beside it" in result.output and len(result.output.strip().splitlines()) == 1


def test_a_carried_parameter_set_is_applied_to_a_third_party_fmu(van_der_pol, tmp_path: Path) -> None:
    """The experiment's SSV sets mu = 2 before the run: its reference (made with mu = 2) passes,
    the same reference without the SSV fails."""
    fmu, _ = van_der_pol
    result = fmpy.simulate_fmu(str(fmu), output=["x0", "x1"], start_values={"mu": 2.0})
    reference = tmp_path / "mu2.csv"
    write_csv(reference, Trace(("time", "x0", "x1"), np.column_stack([result[n] for n in ("time", "x0", "x1")])))
    ssv = tmp_path / "mu2.ssv"
    ssv.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
        'version="1.0" name="mu2"><ssv:Parameters><ssv:Parameter name="mu"><ssv:Real value="2.0"/>'
        "</ssv:Parameter></ssv:Parameters></ssv:ParameterSet>\n"
    )
    applied = verify_fmu(_pack(fmu, reference, tmp_path / "with.fmu", "--parameters", str(ssv)))
    assert applied.passed, applied.failures
    assert not verify_fmu(_pack(fmu, reference, tmp_path / "without.fmu")).passed


def test_an_experiments_document_written_by_another_tool_runs_what_it_can_and_names_the_rest(
    van_der_pol, tmp_path: Path
) -> None:
    """An MA-HS-Experiments document as another tool writes it (no annotation of ours, a stop time
    but no start or step, another analysis type, an experiment without References): the transient
    one runs from the standard elements alone (its start and step from the FMU's default
    experiment) and passes; the others are listed as skipped, with why."""
    from toggle_cosim.fmi_ls_ref.experiments import MIME
    from toggle_cosim.fmi_ls_ref.manifest import Related
    from toggle_cosim.fmi_ls_ref.pack import Attachment, pack

    fmu, reference = van_der_pol
    stop = float(np.loadtxt(reference, delimiter=",", skiprows=1)[-1, 0])
    document = f"""<?xml version="1.0" encoding="UTF-8"?>
<Experiments name="Smoke tests" description="from another tool">
  <Experiment name="transient">
    <TransientSimulation stopTime="{stop!r}"/>
    <References source="../results/vdp_ref.csv"/>
  </Experiment>
  <Experiment name="operating point"><SteadyState/></Experiment>
  <Experiment name="no reference"><TransientSimulation stopTime="1"/></Experiment>
</Experiments>
""".encode()
    packed = pack(
        Path(shutil.copy(fmu, tmp_path / "V.fmu")),
        [
            Attachment(Related("results/vdp_ref.csv", "result", "text/csv"), reference.read_bytes()),
            Attachment(Related("experiments/smoke.exp", "experiment", MIME), document),
        ],
    )
    verification = verify_fmu(packed)
    assert [check.label for check in verification.checks] == ["transient"], verification.checks
    assert verification.passed, verification.failures
    assert verification.skipped == (
        "experiments/smoke.exp#operating point (SteadyState: not a transient simulation)",
        "experiments/smoke.exp#no reference (no References)",
    )


def test_an_experiments_document_that_is_not_valid_against_the_standard_is_refused(van_der_pol, tmp_path: Path) -> None:
    """The old layout (times on the Experiment, no TransientSimulation) is not MA-HS-Experiments:
    one line naming the member, exit 2."""
    from toggle_cosim.fmi_ls_ref.experiments import MIME
    from toggle_cosim.fmi_ls_ref.manifest import Related
    from toggle_cosim.fmi_ls_ref.pack import Attachment, pack

    fmu, reference = van_der_pol
    document = (
        b'<Experiments name="x"><Experiment name="a" startTime="0" stopTime="1">'
        b'<References source="r.csv"/></Experiment></Experiments>'
    )
    packed = pack(
        Path(shutil.copy(fmu, tmp_path / "V.fmu")),
        [
            Attachment(Related("r.csv", "result", "text/csv"), reference.read_bytes()),
            Attachment(Related("e.exp", "experiment", MIME), document),
        ],
    )
    result = CliRunner().invoke(main, ["verify", str(packed), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "e.exp: not a valid MA-HS-Experiments document" in lines[0], result.output
