"""The study as an SSP 1.0 archive (`toggle_cosim.ssp`, docs/ssp.md).

Written for every shipped non-sweep scenario, each variant is a root SSD (SystemStructure.ssd the
first) binding exactly one parameter set per component; every root SSD and .ssv validates against
the vendored SSP 1.0 schemas (lxml, the library the writer and reader use; it is a dependency
anyway) and SystemStructure.ssd is read by FMPy's own SSP reader, which validates it against
FMPy's copies of the schemas. The .ssv values are the master's plant settings and the built-in
law's parameters bit for bit; a variant read back runs the plant as the scenario does, bit for
bit, with the values of its .ssv (not of any annotation). Each bad input, the red-team cases of
issue 29 included, is one line, exit 2, nothing written. Run in our master through the controller
FMU ToggleVSC, each variant gives the scenario variant's trace bit for bit, and so does a
hand-written SSD (other component names, connections in another order, inline values).
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from lxml import etree

from toggle_cosim.cli import main
from toggle_cosim.cosim.controllers import builtin_controller
from toggle_cosim.cosim.master import check_and_simulate, plant_settings
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import SspError, schema_problem
from toggle_cosim.ssp.reader import open_ssp, open_ssp_variants, read_ssp
from toggle_cosim.ssp.writer import controller_values, write_ssp

ROOT = Path(__file__).resolve().parent.parent
# an SSP's parameter set holds one value per input: the scenarios whose load varies in time are refused
VARYING = ("step_load", "measured_load")
TRACKING = ("press_cycle",)  # a reference trajectory: refused too (the SSP's controller FMU regulates to a constant)
SCENARIOS = sorted(
    p
    for p in (ROOT / "scenarios").glob("*.yaml")
    if not p.name.startswith(("sweep_", "tune_")) and p.stem not in VARYING + TRACKING
)
NS = layout.NAMESPACES
UNITS = {"x_B": "m", "v_B": "m/s", "theta1": "rad", "omega1": "rad/s", "iq_ref": "A"}


def _with_units(fmu: Path, units: dict[str, str]) -> None:
    """Give the FMU's variables these units (PythonFMU writes none), in place."""
    with zipfile.ZipFile(fmu) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    text = members["modelDescription.xml"].decode()
    for name, unit in units.items():
        text = re.sub(rf'(<ScalarVariable name="{name}"[^>]*>\s*<Real)( unit="[^"]*")?', rf'\1 unit="{unit}"', text)
    members["modelDescription.xml"] = text.encode()
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for member, data in members.items():
            archive.writestr(member, data)


@pytest.fixture(scope="module")
def controller_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A stand-in for ToggleVSC (tests/models/ssp_controller): its variables, units on the signals."""
    folder = tmp_path_factory.mktemp("controller")
    script = ROOT / "tests" / "models" / "ssp_controller" / "ToggleVSC.py"
    command = [str(Path(sys.executable).parent / "pythonfmu"), "build", "-f", str(script), "-d", str(folder)]
    built = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert built.returncode == 0, built.stderr
    _with_units(folder / "ToggleVSC.fmu", UNITS)
    return folder / "ToggleVSC.fmu"


@pytest.fixture(scope="module")
def fig5_ssp(plant_fmu: Path, controller_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_ssp(
        ROOT / "scenarios" / "fig5_external_force.yaml",
        tmp_path_factory.mktemp("ssp") / "fig5.ssp",
        plant_fmu,
        controller_fmu,
    )


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def _rewrite(source: Path, target: Path, change) -> Path:  # noqa: ANN001 - change(members) edits the dict
    members = _members(source)
    change(members)
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return target


def _values(data: bytes) -> list[tuple[str, str, str]]:
    root = etree.fromstring(data)
    return [
        (p.get("name"), etree.QName(p[0]).localname, p[0].get("value"))
        for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS)
    ]


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda p: p.stem)
def test_every_shipped_scenario_gives_one_valid_root_ssd_per_variant(
    scenario: Path, plant_fmu: Path, controller_fmu: Path, tmp_path: Path
) -> None:
    """One root SSD per variant (SSP 1.0.1 section 3): SystemStructure.ssd the first, <variant>.ssd
    the others, each named after its variant (unique), each valid SSP 1.0 and binding exactly one
    .ssv per component, that variant's (section 5: all bindings apply, so one each is the only
    layout every master reads alike); FMPy's reader reads and validates the default."""
    from fmpy.ssp.ssd import read_ssd, read_ssv

    path = write_ssp(scenario, tmp_path / "study.ssp", plant_fmu, controller_fmu)
    runs = load_scenario(scenario)
    members = _members(path)
    sets = [layout.set_name(run.variant) for run in runs]
    roots = [layout.SSD_MEMBER, *(f"{name}.ssd" for name in sets[1:])]
    ssvs = [layout.ssv_member(name, component) for name in sets for component in (layout.PLANT, layout.CONTROLLER)]
    assert sorted(members) == sorted([*roots, "resources/ToggleLSM.fmu", "resources/ToggleVSC.fmu", *ssvs])
    for member in ssvs:
        assert schema_problem(etree.fromstring(members[member]), "ssv") is None
        assert read_ssv(str(path), member, validate=True).name == member.split("/")[1].split(".")[0]
    described = read_ssd(str(path), validate=True)
    assert {c.name: c.source for c in described.system.elements} == {
        "plant": "resources/ToggleLSM.fmu",
        "controller": "resources/ToggleVSC.fmu",
    }
    wires = {(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in described.system.connections}
    signals = ("x_B", "v_B", "theta1", "omega1")
    assert wires == {("plant", s, "controller", s) for s in signals} | {("controller", "iq_ref", "plant", "iq_ref")}
    for root, name, run in zip(roots, sets, runs, strict=True):
        ssd = etree.fromstring(members[root])
        assert schema_problem(ssd, "ssd") is None
        assert ssd.get("name") == name and ssd.find("ssd:System", NS).get("name") == run.scenario
        for component in ssd.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
            assert component.get("type") == "application/x-fmu-sharedlibrary"
            bound = [b.get("source") for b in component.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS)]
            assert bound == [layout.ssv_member(name, component.get("name"))]  # one binding, this variant's
            for connector in component.iterfind("ssd:Connectors/ssd:Connector", NS):
                unit = connector.find("ssc:Real", NS).get("unit")
                assert unit == {**UNITS, "F_E": "N"}[connector.get("name")]
        assert ssd.find("ssd:System/ssd:Connectors", NS) is None  # no system-level connectors
        assert ssd.find("ssd:System/ssd:ParameterBindings", NS) is None  # nor system-level bindings
        units = {u.get("name"): dict(u.find("ssc:BaseUnit", NS).attrib) for u in ssd.iterfind("ssd:Units/ssc:Unit", NS)}
        assert units["m/s"] == {"m": "1", "s": "-1"} and units["rad/s"] == {"s": "-1", "rad": "1"}
        experiment = ssd.find("ssd:DefaultExperiment", NS)
        assert float(experiment.get("startTime")) == 0.0 and float(experiment.get("stopTime")) == run.t_end
        ours = ssd.find(f"ssd:Annotations/ssc:Annotation[@type='{layout.ANNOTATION_TYPE}']", NS)
        assert ours[0].get("name") == run.scenario and ours[0].get("variant") == run.variant  # describes only


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda p: p.stem)
def test_the_ssv_values_are_the_masters_settings_bit_for_bit(
    scenario: Path, plant_fmu: Path, controller_fmu: Path, tmp_path: Path
) -> None:
    """Plant: plant_settings(run, plant) then F_E; controller: law_parameters() without t0 and
    T_h. Each text is repr of the float, so it reads back with the same bits."""
    path = write_ssp(scenario, tmp_path / "study.ssp", plant_fmu, controller_fmu)
    members = _members(path)
    plant = check_plant(plant_fmu)
    for run in load_scenario(scenario):
        name = layout.set_name(run.variant)
        expected_plant = [*plant_settings(run, plant), ("F_E", run.plant.F_E)]
        written = _values(members[layout.ssv_member(name, layout.PLANT)])
        assert [n for n, _, _ in written] == [n for n, _ in expected_plant]
        for (_, kind, text), (_, value) in zip(written, expected_plant, strict=True):
            assert text == (("true" if value else "false") if kind == "Boolean" else repr(float(value)))
        law = builtin_controller(run).law_parameters()
        fields = [f.name for f in dataclasses.fields(law) if f.name not in ("t0", "T_h")]
        written = _values(members[layout.ssv_member(name, layout.CONTROLLER)])
        assert [(n, float(text)) for n, _, text in written] == [(f, getattr(law, f)) for f in fields]
        assert all(float(text) == getattr(law, n) and text == repr(getattr(law, n)) for n, _, text in written)


def test_a_variant_reads_back_as_the_run_it_was_written_from(fig5_ssp: Path, plant_fmu: Path) -> None:
    plant = check_plant(plant_fmu)
    runs = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")
    default = read_ssp(fig5_ssp, folder=fig5_ssp.parent / "default")
    assert (default.variant, default.member, default.variants) == (
        "friction",
        "SystemStructure.ssd",
        ("friction", "no_friction"),
    )
    with open_ssp_variants(fig5_ssp, ["friction", "no_friction.ssd"]) as every:
        assert [study.variant for study in every] == ["friction", "no_friction"]
        assert len({study.plant_fmu for study in every}) == 1  # one copy of the FMUs for all variants
    for run in runs:
        with open_ssp(fig5_ssp, run.variant) as study:
            assert study.plant_values == tuple(plant_settings(run, plant))
            assert study.controller_values == controller_values(run)
            assert (study.F_E, study.t_end, study.T_s) == (run.plant.F_E, run.t_end, run.T_s)
            assert (study.run.label, study.run.x_start, study.run.x_target) == (run.label, run.x_start, run.x_target)
            assert (study.run.plant.m_B, study.run.plant.mu, study.run.plant.friction_model) == (
                run.plant.m_B,
                run.plant.mu,
                run.plant.friction_model,
            )
            assert study.run.controller.gains == run.controller.gains
            assert study.run.plant.fmu_values == study.plant_values and study.run.source == fig5_ssp
            assert study.plant_fmu.is_file() and study.controller_fmu.is_file()
            record = study.run.resolved["ssp"]
            assert record["variant"] == run.variant and record["ssd"] == study.member
            plant_record = record["components"]["plant"]
            assert plant_record["source"] == "resources/ToggleLSM.fmu" and len(plant_record["sha256"]) == 64
            assert plant_record["values"] == {**dict(study.plant_values), "F_E": run.plant.F_E}
            assert record["components"]["controller"]["values"] == dict(controller_values(run))
        assert not study.plant_fmu.exists()  # the extracted FMUs go with the block


def _trace(outcome) -> np.ndarray:  # noqa: ANN001
    assert outcome.complete, outcome.reason
    return np.asarray(outcome.trace.data)


def test_an_ssp_run_sets_the_plant_as_the_scenario_does_bit_for_bit(fig5_ssp: Path, plant_fmu: Path) -> None:
    """The plant side of `run study.ssp`: the set's plant values and F_E, t_end and T_s from the
    SSP; with the built-in law as the controller the trace equals the YAML run's on every column;
    run.json's record names the SSP and the set."""
    plant = check_plant(plant_fmu)
    run = next(r for r in load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml") if r.variant == "friction")
    with open_ssp(fig5_ssp, "friction") as study:
        from_ssp = check_and_simulate(study.run, check_plant(study.plant_fmu), controller=builtin_controller(study.run))
    from_yaml = check_and_simulate(run, plant)
    assert from_ssp.trace.names == from_yaml.trace.names
    assert np.array_equal(_trace(from_ssp), _trace(from_yaml))
    assert from_ssp.record["resolved"]["ssp"]["variant"] == "friction"
    assert from_ssp.record["scenario_file"] == str(fig5_ssp)


def test_the_plant_values_come_from_the_ssv(fig5_ssp: Path, plant_fmu: Path, tmp_path: Path) -> None:
    """The friction set with its plant's mu edited to 0 runs as the no_friction variant does (and
    not as friction): the master sets the .ssv's values, not the scenario's."""
    member = layout.ssv_member("friction", layout.PLANT)

    def frictionless(members: dict[str, bytes]) -> None:
        text = members[member].decode()
        members[member] = re.sub(r'(name="mu">\s*<ssv:Real value=")0\.2"', r'\g<1>0.0"', text).encode()

    edited = _rewrite(fig5_ssp, tmp_path / "edited.ssp", frictionless)
    no_friction = next(
        r for r in load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml") if r.variant == "no_friction"
    )
    with open_ssp(edited, "friction") as study:
        assert dict(study.plant_values)["mu"] == 0.0
        assert study.run.plant.mu == 0.0  # the record says what ran
        assert study.run.resolved["ssp"]["components"]["plant"]["values"]["mu"] == 0.0
        outcome = check_and_simulate(study.run, check_plant(study.plant_fmu), controller=builtin_controller(study.run))
    expected = check_and_simulate(no_friction, check_plant(plant_fmu))
    assert np.array_equal(_trace(outcome), _trace(expected))


# -- what other SSP masters make of the parameter sets ------------------------------------------------


def _ecospy():  # noqa: ANN202
    try:
        import ecospy
    except OSError as error:  # its native library needs Debian's libtbb12 (scripts/install-system-deps)
        pytest.skip(f"ecospy's native library cannot be loaded: {error}")
    return ecospy


@pytest.mark.slow
def test_ecos_applies_a_set_only_when_named_and_bound_in_the_ssd_it_loads(
    fig5_ssp: Path, plant_fmu: Path, controller_fmu: Path, tmp_path: Path
) -> None:
    """Ecos loads SystemStructure.ssd and applies a set named at init to both components (each
    component's own .ssv of that name). The default variant's name applies it; the other
    variant's set is bound only in its own root SSD, so Ecos applies nothing for it (the FMU's
    start values: mu 0.2, F_E 0 N), as with no name; the SSP of that variant alone
    (`toggle-cosim ssp --variant no_friction`) applies it by its name."""
    ecospy = _ecospy()
    alone = write_ssp(
        ROOT / "scenarios" / "fig5_external_force.yaml",
        tmp_path / "alone.ssp",
        plant_fmu,
        controller_fmu,
        ["no_friction"],
    )
    for path, name, mu, F_E in (
        (fig5_ssp, "friction", 0.2, 100.0),
        (fig5_ssp, "no_friction", 0.2, 0.0),
        (fig5_ssp, None, 0.2, 0.0),
        (alone, "no_friction", 0.0, 100.0),
    ):
        with ecospy.EcosSimulation(ssp_path=str(path), step_size=0.0005) as sim:
            sim.init(parameter_set=name)
            assert (sim.get_real("plant::mu"), sim.get_real("plant::F_E")) == (mu, F_E), (path.name, name)
            if F_E:
                assert (sim.get_real("controller::C"), sim.get_real("controller::target")) == (5.0, 0.3199)


def test_libcosim_runs_the_root_ssd_it_is_pointed_at(fig5_ssp: Path, tmp_path: Path) -> None:
    """libcosim (an unpacked SSP, no step size given) steps at T_s from the DefaultExperiment's
    annotation and applies the bindings of the root SSD it loads: SystemStructure.ssd (the folder)
    is the default variant, friction (mu = 0.2, F_E = 100 N); no_friction.ssd is the other."""
    pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    folder = tmp_path / "unpacked"
    with zipfile.ZipFile(fig5_ssp) as archive:
        archive.extractall(folder)
    for given, mu in ((folder, 0.2), (folder / "no_friction.ssd", 0.0)):
        execution = CosimExecution.from_ssp_file(str(given))
        observer = CosimObserver.create_last_value()
        execution.add_observer(observer)
        slaves = {info.name.decode(): info.index for info in execution.slave_infos()}

        def value(slave: str, name: str, execution=execution, observer=observer, slaves=slaves) -> float:  # noqa: ANN001
            reference = next(v.reference for v in execution.slave_variables(slaves[slave]) if v.name.decode() == name)
            return observer.last_real_values(slaves[slave], [reference])[0]

        execution.step(2)
        assert execution.status().current_time == 2 * 500_000  # ns: two steps of T_s = 0.5 ms
        assert (value("plant", "mu"), value("plant", "F_E"), value("controller", "C")) == (mu, 100.0, 5.0)
        del execution


# -- bad input: one line, exit 2, nothing written ---------------------------------------------------


def _one_line(result, out: Path) -> str:  # noqa: ANN001
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    assert "Traceback" not in result.output
    assert not out.exists() or not any(out.iterdir())
    return lines[0]


def _run_ssp(path: Path, out: Path, *extra: str) -> str:
    return _one_line(CliRunner().invoke(main, ["run", str(path), "--out", str(out), "-q", *extra]), out)


def _ssd_edit(old: str, new: str, member: str = layout.SSD_MEMBER):  # noqa: ANN202
    def change(members: dict[str, bytes]) -> None:
        text = members[member].decode()
        assert old in text
        members[member] = text.replace(old, new, 1).encode()

    return change


def _ssv_edit(stem: str, old: str, new: str):  # noqa: ANN202
    return _ssd_edit(old, new, f"resources/{stem}.ssv")


def _twice(members: dict[str, bytes], name: str) -> None:
    """The SSD with its component `name` written twice."""
    text = members[layout.SSD_MEMBER].decode()
    start = text.index(f'<ssd:Component name="{name}"')
    end = text.index("</ssd:Component>", start) + len("</ssd:Component>")
    members[layout.SSD_MEMBER] = (text[:end] + text[start:end] + text[end:]).encode()


def _both(*changes):  # noqa: ANN002, ANN202
    def change(members: dict[str, bytes]) -> None:
        for one in changes:
            one(members)

    return change


CONTROLLER_IN = '<ssd:Connector name="{0}" kind="input">\n            <ssc:Real unit="{1}"/>'
WIRE = 'startElement="plant" startConnector="{0}" endElement="controller" endConnector="{0}"'
COMMAND_WIRE = 'startElement="controller" startConnector="iq_ref" endElement="plant" endConnector="iq_ref"'
# each case: the change to fig5's SSP, and what the one line says
BAD_SSPS = {
    "not a zip": (lambda m: None, "not an SSP archive"),
    "no SSD": (lambda m: m.pop(layout.SSD_MEMBER), "no SystemStructure.ssd in the archive"),
    "not valid SSP 1.0": (_ssd_edit('kind="output"', 'kind="outward"'), "SystemStructure.ssd: not valid SSP 1.0 (line"),
    "missing FMU": (
        lambda m: m.pop("resources/ToggleVSC.fmu"),
        "component 'controller''s FMU 'resources/ToggleVSC.fmu' is not in the archive",
    ),
    "a component member that is not a zip": (
        lambda m: m.update({"resources/ToggleVSC.fmu": b"not a zip"}),
        "resources/ToggleVSC.fmu: the component FMU is not a zip archive",
    ),
    "connection to a missing connector": (
        _ssd_edit('endConnector="omega1"', 'endConnector="omega9"'),
        "names the connector controller.omega9, which the component does not declare",
    ),
    "connection to a missing component": (
        _ssd_edit('endElement="plant"', 'endElement="plant2"'),
        "names the component 'plant2', which does not exist (choose one of plant, controller)",
    ),
    "connector the FMU lacks": (
        _ssd_edit('<ssd:Connector name="theta1" kind="output">', '<ssd:Connector name="theta7" kind="output">'),
        "component 'plant' declares the connector 'theta7', which its FMU ToggleLSM.fmu does not have",
    ),
    "a connector of the wrong kind": (
        _ssd_edit('<ssd:Connector name="x_B" kind="output">', '<ssd:Connector name="x_B" kind="input">'),
        "component 'plant' declares 'x_B' as a connector of kind input, but its FMU's variable has causality output",
    ),
    "x_B and v_B crossed, their units left out": (
        _both(
            _ssd_edit(WIRE.format("x_B"), WIRE.format("x_B").replace('endConnector="x_B"', 'endConnector="v_B"')),
            _ssd_edit(WIRE.format("v_B"), WIRE.format("v_B").replace('endConnector="v_B"', 'endConnector="x_B"')),
            _ssd_edit(CONTROLLER_IN.format("x_B", "m"), '<ssd:Connector name="x_B" kind="input">\n<ssc:Real/>'),
            _ssd_edit(CONTROLLER_IN.format("v_B", "m/s"), '<ssd:Connector name="v_B" kind="input">\n<ssc:Real/>'),
        ),
        "the connection plant.x_B -> controller.v_B joins m to m/s",
    ),
    "unit mismatch": (
        _ssd_edit(CONTROLLER_IN.format("x_B", "m"), CONTROLLER_IN.format("x_B", "m/s")),
        "the connection plant.x_B -> controller.x_B gives controller.x_B the unit 'm/s'",
    ),
    "controller.iq_ref to plant.F_E": (
        _ssd_edit(COMMAND_WIRE, COMMAND_WIRE.replace('endConnector="iq_ref"', 'endConnector="F_E"')),
        "the connection controller.iq_ref -> plant.F_E joins A to N",
    ),
    "an algebraic loop": (
        _ssd_edit(
            "</ssd:Connections>",
            '<ssd:Connection startElement="controller" startConnector="iq_ref" '
            'endElement="controller" endConnector="omega1"/></ssd:Connections>',
        ),
        "an algebraic loop controller.iq_ref -> controller.omega1 -> controller.iq_ref",
    ),
    "system-level connectors": (
        _ssd_edit(
            "<ssd:Elements>", '<ssd:Connectors><ssd:Connector name="F" kind="input"/></ssd:Connectors><ssd:Elements>'
        ),
        "the system has connectors of its own (not supported; connect the components)",
    ),
    "a Model Exchange component": (
        _ssd_edit('<ssd:Component name="plant"', '<ssd:Component implementation="ModelExchange" name="plant"'),
        "component 'plant' asks for implementation 'ModelExchange' (our master runs Co-Simulation only)",
    ),
    "a parameter mapping": (
        _ssd_edit(
            'source="resources/friction.plant.ssv"/>',
            'source="resources/friction.plant.ssv"><ssd:ParameterMapping source="resources/m.ssm"/></ssd:ParameterBinding>',
        ),
        "a parameter binding with a ParameterMapping (not supported; rename in the .ssv)",
    ),
    "a source inside the component": (
        _ssd_edit(
            'source="resources/friction.plant.ssv"/>', 'source="resources/friction.plant.ssv" sourceBase="component"/>'
        ),
        'a parameter binding with sourceBase="component" (not supported',
    ),
    "a source outside the archive": (
        _ssd_edit('source="resources/friction.plant.ssv"/>', 'source="file:///etc/passwd"/>'),
        "the parameter binding's source 'file:///etc/passwd' is not a member of the archive",
    ),
    "an SSP of an earlier toggle-cosim": (
        _ssd_edit(f'type="{layout.ANNOTATION_TYPE}"', f'type="{layout.OLD_ANNOTATION_TYPE}"'),
        "SystemStructure.ssd: written by an earlier toggle-cosim, with one binding per parameter set on each component",
    ),
    "a system-level binding naming no component": (
        _ssd_edit(
            "<ssd:Elements>",
            "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet "
            'version="1.0" name="x"><ssv:Parameters><ssv:Parameter name="mu"><ssv:Real value="0.5"/></ssv:Parameter>'
            "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
            "<ssd:Elements>",
        ),
        "the system's binding inline sets 'mu', which names no component's variable (write COMPONENT.VARIABLE",
    ),
    "an .ssv not valid": (
        _ssv_edit("friction.plant", 'value="0.2"', 'value="low"'),
        "resources/friction.plant.ssv: not valid SSP 1.0 (line",
    ),
    "an .ssv setting a variable the FMU lacks": (
        _ssv_edit("friction.plant", 'name="mu"', 'name="muu"'),
        "resources/ToggleLSM.fmu: the FMU has no variable 'muu', which",
    ),
    "a step size that is not the controller's T_s": (
        _ssd_edit('baseStepSize="0.0005"', 'baseStepSize="0.001"'),
        "the OSP annotation's baseStepSize 0.001 s is not the controller's T_s = 0.0005 s",
    ),
    "a value that is not finite": (
        _ssv_edit("friction.plant", 'value="0.2"', 'value="NaN"'),
        "resources/friction.plant.ssv: mu = nan is not a finite number (give a finite value)",
    ),
    "NaN to an Integer": (
        _ssv_edit("friction.plant", '<ssv:Real value="1.0"/>', '<ssv:Integer value="NaN"/>'),
        "resources/friction.plant.ssv: not valid SSP 1.0 (line",
    ),
    "stopTime INF": (
        _ssd_edit('stopTime="1.5"', 'stopTime="INF"'),
        "DefaultExperiment stopTime 'INF' is not a finite time",
    ),
    "an entity reference in annotation text": (
        lambda m: m.update(
            {
                layout.SSD_MEMBER: m[layout.SSD_MEMBER]
                .replace(b"?>\n", b'?>\n<!DOCTYPE x [<!ENTITY big "bigger">]>\n', 1)
                .replace(b'{"', b'&big;{"', 1)
            }
        ),
        "SystemStructure.ssd: a DOCTYPE or entity reference (refused",
    ),
    "two .ssv files with one set name": (
        _ssv_edit("no_friction.plant", 'name="no_friction"', 'name="friction"'),
        "resources/friction.plant.ssv and resources/no_friction.plant.ssv both hold the parameter set 'friction' of "
        "component 'plant'",
    ),
    "a variant name that climbs out": (
        _ssd_edit('name="no_friction" generationTool', 'name="../../../x" generationTool', "no_friction.ssd"),
        "no_friction.ssd: the name '../../../x' cannot name a results folder",
    ),
    "an absolute variant name": (
        _ssd_edit('name="friction" generationTool', 'name="/tmp/x" generationTool'),
        "SystemStructure.ssd: the name '/tmp/x' cannot name a results folder",
    ),
    "two variants of one name": (
        _ssd_edit('name="no_friction" generationTool', 'name="Friction" generationTool', "no_friction.ssd"),
        "no_friction.ssd: the variant name 'Friction' is also SystemStructure.ssd's",
    ),
    "m_B = 1e308": (
        _ssv_edit("friction.plant", '"m_B">\n      <ssv:Real value="4.43"', '"m_B">\n      <ssv:Real value="1e308"'),
        "key plant.m_B: 1e+308 is out of range (must be <= 1000) (read from the variant's parameter values",
    ),
    "m_B = 0": (
        _ssv_edit("friction.plant", '"m_B">\n      <ssv:Real value="4.43"', '"m_B">\n      <ssv:Real value="0.0"'),
        "key plant.m_B: 0.0 is out of range (must be > 0)",
    ),
    "frictionModel = 7": (
        _ssv_edit("friction.plant", '<ssv:Real value="1.0"/>', '<ssv:Real value="7.0"/>'),
        "frictionModel = 7.0 is not one of 1 (paper), 2 (dissipative), 3 (stick_slip)",
    ),
    "an XML bomb of parameters": (
        lambda m: m.update(
            {
                "resources/friction.plant.ssv": m["resources/friction.plant.ssv"].replace(
                    b"<ssv:Parameters>",
                    b"<ssv:Parameters>" + b'<ssv:Parameter name="mu"><ssv:Real value="0.2"/></ssv:Parameter>' * 60_000,
                    1,
                )
            }
        ),
        "resources/friction.plant.ssv: more than 100000 XML elements",
    ),
    "XML nested too deep": (
        _ssd_edit(
            "</ssd:Annotations>\n</ssd:SystemStructureDescription>",
            "<a>" * 70 + "</a>" * 70 + "</ssd:Annotations>\n</ssd:SystemStructureDescription>",
        ),
        "SystemStructure.ssd: XML nested deeper than 64 levels",
    ),
    "an oversized SSD": (
        lambda m: m.update({layout.SSD_MEMBER: m[layout.SSD_MEMBER] + b" " * (5 << 20)}),
        "SystemStructure.ssd: over the 4 MiB an SSP's XML file may have here",
    ),
    "unsafe archive": (
        lambda m: m.update({"../escape.txt": b"x"}),
        "unsafe or corrupt archive: member '../escape.txt' has a '..'",
    ),
    "a component name with a dot": (
        _ssd_edit('<ssd:Component name="controller"', '<ssd:Component name="ctl.r"'),
        "SystemStructure.ssd: component name 'ctl.r' is not a name the master can use (no dots",
    ),
    "two components of one name": (
        lambda m: _twice(m, "controller"),
        "SystemStructure.ssd: two components are named 'controller' (give each its own name)",
    ),
    **{
        f"an SSD unit of factor {factor}": (
            _ssd_edit('<ssc:BaseUnit m="1"/>', f'<ssc:BaseUnit m="1" factor="{factor}"/>'),
            f"SystemStructure.ssd: the unit 'm' is defined with factor '{factor}', offset 0 (a unit's factor is a "
            "finite number other than 0",
        )
        for factor in ("0", "NaN", "INF")
    },
}


@pytest.mark.parametrize("name", VARYING)
def test_a_load_that_varies_in_time_is_refused_in_one_line(name: str, tmp_path: Path) -> None:
    scenario = ROOT / "scenarios" / f"{name}.yaml"
    ran = CliRunner().invoke(main, ["ssp", str(scenario), "--out", str(tmp_path / "x.ssp")])
    assert ran.exit_code == 2 and not (tmp_path / "x.ssp").exists()
    kind = "step" if name == "step_load" else "table"
    assert ran.output.strip() == (
        f"error: {scenario}: key plant.F_E: the load is a {kind} in time, and an SSP's parameter set holds one value"
        " per input (give F_E a number, or run the scenario with toggle-cosim run)"
    )


def test_a_trajectory_is_refused_in_one_line(tmp_path: Path) -> None:
    scenario = ROOT / "scenarios" / "press_cycle.yaml"
    ran = CliRunner().invoke(main, ["ssp", str(scenario), "--out", str(tmp_path / "x.ssp")])
    assert ran.exit_code == 2 and not (tmp_path / "x.ssp").exists()
    assert ran.output.strip().startswith(f"error: {scenario}: key stroke.trajectory: an SSP's controller FMU regulates")
    assert "\n" not in ran.output.strip()


def _bad(case: str, fig5_ssp: Path, tmp_path: Path) -> Path:
    change, _ = BAD_SSPS[case]
    if case == "not a zip":
        (tmp_path / "bad.ssp").write_text("hello")
        return tmp_path / "bad.ssp"
    return _rewrite(fig5_ssp, tmp_path / "bad.ssp", change)


@pytest.mark.parametrize("case", BAD_SSPS, ids=list(BAD_SSPS))
def test_a_bad_ssp_is_refused_in_one_line(case: str, fig5_ssp: Path, tmp_path: Path) -> None:
    """Each case: exit 2, one line naming the SSP (and the member, the connection, the value), no
    traceback, nothing written under --out, and the same refusal from the reader itself."""
    bad = _bad(case, fig5_ssp, tmp_path)
    expected = BAD_SSPS[case][1]
    line = _run_ssp(bad, tmp_path / "out")
    assert line.startswith(f"error: {bad}") and expected in line, line
    with pytest.raises(SspError, match=re.escape(expected)):
        read_ssp(bad)


# Refused while the master ran only the plant + controller loop; read now as the system they
# describe (the master steps any system, `cosim.systems`): each case's change, and the Wiring's
# parts (names) and connections (start, end, factor, offset), None for the plain pair
PAIR = [("plant.x_B", "controller.x_B"), ("plant.v_B", "controller.v_B"), ("plant.theta1", "controller.theta1")]
PAIR += [("plant.omega1", "controller.omega1"), ("controller.iq_ref", "plant.iq_ref")]
NOW_SYSTEMS = {
    "no connections": (
        lambda m: m.update(
            {
                layout.SSD_MEMBER: re.sub(
                    rb"<ssd:Connections>.*</ssd:Connections>", b"", m[layout.SSD_MEMBER], flags=re.S
                )
            }
        ),
        (),
        [],
    ),
    # both connectors' unit m is redefined alike (0.001 m): each value leaves and reaches its FMU
    # in the FMU's own m, so the connection is the identity and this is the plain pair
    "a unit redefined by a factor 0.001": (
        _ssd_edit(
            '<ssc:Unit name="m">\n      <ssc:BaseUnit m="1"/>',
            '<ssc:Unit name="m">\n<ssc:BaseUnit m="1" factor="0.001"/>',
        ),
        (),
        None,
    ),
    "a scaling transformation": (
        _ssd_edit(
            f"{WIRE.format('x_B')}/>",
            f'{WIRE.format("x_B")}><ssc:LinearTransformation factor="1000"/></ssd:Connection>',
        ),
        (),
        [(*PAIR[0], 1000.0, 0.0), *((*wire, 1.0, 0.0) for wire in PAIR[1:])],
    ),
    "controller.S to plant.F_E": (
        _both(
            _ssd_edit(
                '<ssd:Connector name="iq_ref" kind="output">',
                '<ssd:Connector name="S" kind="output"/><ssd:Connector name="iq_ref" kind="output">',
            ),
            _ssd_edit(
                "</ssd:Connections>",
                '<ssd:Connection startElement="controller" startConnector="S" endElement="plant" endConnector="F_E"/>'
                "</ssd:Connections>",
            ),
        ),
        (),
        [*((*wire, 1.0, 0.0) for wire in PAIR), ("controller.S", "plant.F_E", 1.0, 0.0)],
    ),
    "a third component": (
        _ssd_edit("</ssd:Elements>", '<ssd:Component name="logger" source="resources/ToggleVSC.fmu"/></ssd:Elements>'),
        ("logger",),
        [(*wire, 1.0, 0.0) for wire in PAIR],
    ),
}


@pytest.mark.parametrize("case", NOW_SYSTEMS, ids=list(NOW_SYSTEMS))
def test_a_wiring_other_than_the_pair_is_read_as_the_system_it_describes(
    case: str, fig5_ssp: Path, tmp_path: Path
) -> None:
    """Cases once refused (the master ran the pair only): the run's system has the SSD's parts and
    every connection in document order, with the LinearTransformation's factor; the plain pair
    stays Wiring() so its runs stay the fixed loop's."""
    change, parts, connections = NOW_SYSTEMS[case]
    with open_ssp(_rewrite(fig5_ssp, tmp_path / "now.ssp", change)) as study:
        system = study.run.system
        assert tuple(part.name for part in system.parts) == parts
        if connections is None:
            assert system == dataclasses.replace(system.__class__()) and system.is_pair
        else:
            got = [(str(c.start), str(c.end), c.factor, c.offset) for c in system.connections]
            assert got == connections
            assert [p["name"] for p in study.run.resolved["ssp"]["parts"]] == list(parts)


def test_a_variant_that_does_not_exist_is_refused_naming_those_that_do(fig5_ssp: Path, tmp_path: Path) -> None:
    line = _run_ssp(fig5_ssp, tmp_path / "out", "--variant", "heavy")
    assert line == (
        f"error: {fig5_ssp}: no variant 'heavy' (choose one of friction, no_friction with --variant; the default is "
        "friction, SystemStructure.ssd)"
    )
    before = set(Path(tempfile.gettempdir()).glob("toggle-cosim-ssp-*"))
    with pytest.raises(SspError, match="no variant 'heavy'"):
        read_ssp(fig5_ssp, "heavy")
    assert set(Path(tempfile.gettempdir()).glob("toggle-cosim-ssp-*")) <= before  # its temporary copy is gone


def test_ssp_refuses_a_python_controller_and_a_sweep_in_one_line(controller_fmu: Path, tmp_path: Path) -> None:
    scenario = tmp_path / "python.yaml"
    scenario.write_text(
        (ROOT / "scenarios" / "fig4_nominal.yaml")
        .read_text()
        .replace("controller:\n", "controller:\n  python: m:f\n", 1)
    )
    out = tmp_path / "study.ssp"
    for given, expected in (
        (scenario, "key controller.python: an SSP's controller is an FMU"),
        (ROOT / "scenarios" / "sweep_FE_mB.yaml", "a sweep file cannot be written as an SSP"),
    ):
        result = CliRunner().invoke(
            main,
            ["ssp", str(given), "--out", str(out), "--plant", str(controller_fmu), "--controller", str(controller_fmu)],
        )
        line = _one_line(result, tmp_path / "none")
        assert line.startswith(f"error: {given}: ") and expected in line, line
        assert not out.exists()


def test_ssp_refuses_variants_that_differ_in_t_end(plant_fmu: Path, controller_fmu: Path, tmp_path: Path) -> None:
    scenario = tmp_path / "longer.yaml"
    text = (ROOT / "scenarios" / "fig4_nominal.yaml").read_text()
    scenario.write_text(text.replace("  no_friction:\n", "  no_friction:\n    t_end: 2.0\n", 1))
    out = tmp_path / "s.ssp"
    result = CliRunner().invoke(
        main,
        ["ssp", str(scenario), "--out", str(out), "--plant", str(plant_fmu), "--controller", str(controller_fmu)],
    )
    assert _one_line(result, tmp_path / "none") == (
        f"error: {scenario}: key t_end: the variants use 1.5, 2.0 s, and an SSP has one experiment for all its "
        "parameter sets (give every variant the same value, or split the scenario)"
    )
    assert not out.exists()


def test_ssp_gives_a_scenarios_errors_as_run_does(plant_fmu: Path, controller_fmu: Path, tmp_path: Path) -> None:
    scenario = tmp_path / "broken.yaml"
    scenario.write_text((ROOT / "scenarios" / "fig4_nominal.yaml").read_text().replace("t_end: 1.5", "t_end: -1"))
    as_run = CliRunner().invoke(main, ["run", str(scenario), "--fmu", str(plant_fmu), "--out", str(tmp_path / "o")])
    as_ssp = CliRunner().invoke(
        main,
        [
            "ssp",
            str(scenario),
            "--out",
            str(tmp_path / "s.ssp"),
            "--plant",
            str(plant_fmu),
            "--controller",
            str(controller_fmu),
        ],
    )
    assert _one_line(as_ssp, tmp_path / "none") == _one_line(as_run, tmp_path / "o")
    assert not (tmp_path / "s.ssp").exists()


def test_ssp_refuses_a_missing_controller_fmu_and_a_plant_it_cannot_feed(
    plant_fmu: Path, controller_fmu: Path, tmp_path: Path
) -> None:
    scenario, out = ROOT / "scenarios" / "fig4_nominal.yaml", tmp_path / "s.ssp"
    missing = tmp_path / "ToggleVSC.fmu"
    line = _one_line(
        CliRunner().invoke(
            main, ["ssp", str(scenario), "--out", str(out), "--plant", str(plant_fmu), "--controller", str(missing)]
        ),
        tmp_path / "none",
    )
    assert (
        line
        == f"error: {missing}: no controller FMU there (build it with toggle-cosim build, or name it with --controller)"
    )
    wrong = tmp_path / "wrong.fmu"
    _rewrite(controller_fmu, wrong, lambda m: None)
    _with_units(wrong, {"x_B": "mm"})
    line = _one_line(
        CliRunner().invoke(
            main, ["ssp", str(scenario), "--out", str(out), "--plant", str(plant_fmu), "--controller", str(wrong)]
        ),
        tmp_path / "none",
    )
    assert "the controller's input 'x_B' is in mm, the plant's output in m" in line
    assert not out.exists()


def test_ssp_finds_the_controller_beside_the_plant_from_any_working_folder(
    plant_fmu: Path, controller_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without --plant and --controller, `ssp` takes the plant by the scenario's fmu: key
    (relative to the scenario) and the controller ToggleVSC.fmu beside that plant, so it runs
    from another folder as from the study's; a missing one is named where it was looked for."""
    study = tmp_path / "study"
    (study / "scenarios").mkdir(parents=True)
    (study / "fmus").mkdir()
    shutil.copy(ROOT / "scenarios" / "fig4_nominal.yaml", study / "scenarios" / "fig4_nominal.yaml")
    shutil.copy(plant_fmu, study / "fmus" / "ToggleLSM.fmu")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    arguments = ["ssp", str(study / "scenarios" / "fig4_nominal.yaml"), "--out", "fig4.ssp"]
    line = _one_line(CliRunner().invoke(main, arguments), tmp_path / "none")
    beside_plant = study / "scenarios" / ".." / "fmus" / "ToggleVSC.fmu"  # the fmu: key's folder
    assert line.startswith(f"error: {beside_plant}: no controller FMU there"), line
    shutil.copy(controller_fmu, study / "fmus" / "ToggleVSC.fmu")
    result = CliRunner().invoke(main, arguments)
    assert result.exit_code == 0, result.output
    assert "resources/ToggleVSC.fmu" in _members(elsewhere / "fig4.ssp")


def test_an_ssp_is_written_whole_or_not_at_all(
    plant_fmu: Path, controller_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "study.ssp"
    with zipfile.ZipFile(out, "w") as old:  # an earlier SSP (only an SSP may be replaced)
        old.writestr(layout.SSD_MEMBER, "<the old file/>")
    before = out.read_bytes()

    def interrupted(*args, **kwargs) -> None:  # noqa: ANN002, ANN003
        raise KeyboardInterrupt

    monkeypatch.setattr(zipfile.ZipFile, "write", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_ssp(ROOT / "scenarios" / "fig4_nominal.yaml", out, plant_fmu, controller_fmu)
    assert out.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["study.ssp"]


def test_run_options_that_do_not_fit_an_ssp_are_refused(fig5_ssp: Path, plant_fmu: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert _run_ssp(fig5_ssp, out, str(fig5_ssp)) == (
        f"error: {fig5_ssp} is given twice: its runs would write the same folders (give it once)"
    )
    assert "--fmu does not apply to an SSP" in _run_ssp(fig5_ssp, out, "--fmu", str(plant_fmu))
    result = CliRunner().invoke(
        main, ["run", str(ROOT / "scenarios" / "fig4_nominal.yaml"), "--variant", "x", "--out", str(out)]
    )
    assert "--variant chooses an SSP's variant (a root SSD): give an .ssp file with it" in _one_line(result, out)


# -- end to end: the controller FMU in our master --------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda p: p.stem)
def test_running_the_ssp_gives_the_yaml_runs_trace_bit_for_bit(
    scenario: Path, request: pytest.FixtureRequest, vsc_fmu: Path, tmp_path: Path
) -> None:
    """Every shipped scenario file but the sweeps, written as an SSP and run in our master with the
    controller FMU, every variant named with --variant: each gives its variant's trace bit for bit
    (the FMU's command, S, phase and e are the built-in law's C operations on the same measured
    values), plus the FMU's z column; run.json names the SSP, the variant's root SSD and each
    component's source, SHA-256 and values. Without --variant the default alone runs."""
    import json

    from toggle_cosim.files.traces import read_csv as read_trace_csv

    plant = request.getfixturevalue("no_gravity_fmu" if scenario.stem == "swap_no_gravity" else "plant_fmu")
    study = write_ssp(scenario, tmp_path / f"{scenario.stem}.ssp", plant, vsc_fmu)
    runs = load_scenario(scenario)
    named = [arg for run in runs for arg in ("--variant", layout.set_name(run.variant))]
    yaml_out, ssp_out, default_out = tmp_path / "yaml", tmp_path / "ssp", tmp_path / "default"
    for args, out in (([str(scenario), "--fmu", str(plant)], yaml_out), ([str(study), *named], ssp_out)):
        ran = CliRunner().invoke(main, ["run", *args, "--out", str(out), "-q"])
        assert ran.exit_code == 0, ran.output
    for index, run in enumerate(runs):
        folder = Path(run.scenario) / (run.variant or "run")
        ssp_folder = Path(f"{scenario.stem}_ssp") / (run.variant or "run")  # an SSP's runs: named for the archive
        expected = read_trace_csv(yaml_out / folder / "trace.csv")
        got = read_trace_csv(ssp_out / ssp_folder / "trace.csv")
        assert got.names == (*expected.names, "z")  # the FMU also reports the integral law's state
        for column in expected.names:
            assert np.array_equal(got.column(column), expected.column(column)), (run.label, column)
        record = json.loads((ssp_out / ssp_folder / "run.json").read_text())["resolved"]["ssp"]
        assert record["file"] == str(study) and record["variant"] == layout.set_name(run.variant)
        assert record["ssd"] == layout.ssd_member(index, layout.set_name(run.variant))
        assert record["components"]["plant"]["values"]["F_E"] == run.plant.F_E
        assert record["components"]["controller"]["values"] == dict(controller_values(run))
    if len(runs) > 1:
        ran = CliRunner().invoke(main, ["run", str(study), "--out", str(default_out), "-q"])
        assert ran.exit_code == 0, ran.output
        assert [p.name for p in (default_out / f"{scenario.stem}_ssp").iterdir()] == [layout.set_name(runs[0].variant)]


@pytest.mark.slow
def test_a_named_variant_runs_that_variant_only(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """--variant NAME runs that root SSD alone, with its values (no_friction: mu = 0); the old
    option --parameter-set NAME is the same (a variant is named after its parameter set)."""
    study = write_ssp(ROOT / "scenarios" / "fig4_nominal.yaml", tmp_path / "fig4.ssp", plant_fmu, vsc_fmu)
    for option, out in (("--variant", tmp_path / "a"), ("--parameter-set", tmp_path / "b")):
        ran = CliRunner().invoke(main, ["run", str(study), option, "no_friction", "--out", str(out), "-q"])
        assert ran.exit_code == 0, ran.output
        assert [p.name for p in (out / "fig4_ssp").iterdir()] == ["no_friction"]  # named for the archive
        record = (out / "fig4_ssp" / "no_friction" / "run.json").read_text()
        assert '"ssd": "no_friction.ssd"' in record and '"mu": 0.0' in record


def _inline(values: list[tuple[str, str, str]], name: str) -> str:
    parameters = "".join(
        f'<ssv:Parameter name="{n}"><ssv:{kind} value="{text}"/></ssv:Parameter>' for n, kind, text in values
    )
    return (
        f'<ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="{name}">'
        f"<ssv:Parameters>{parameters}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>"
    )


@pytest.mark.slow
def test_a_hand_written_ssp_runs_as_the_standard_reads_it(plant_fmu: Path, vsc_fmu: Path, tmp_path: Path) -> None:
    """An SSP this project did not write: components named vsc and mechanism (the controller
    first), connections in another order, no Units, no annotations, parameter values inline. The
    mechanism's first binding sets mu = 0.5 and m_B = 9 kg, its second the variant's values: the
    later binding takes priority (mu back to the variant's); a system-level binding sets
    mechanism.m_B back to 4.43 kg, over the component's own (a higher level takes priority).
    It runs fig4's friction variant bit for bit, and its run.json records the values that ran."""
    import json

    from toggle_cosim.files.traces import read_csv as read_trace_csv

    scenario = ROOT / "scenarios" / "fig4_nominal.yaml"
    ours = _members(write_ssp(scenario, tmp_path / "ours.ssp", plant_fmu, vsc_fmu))
    plant_values = [v for v in _values(ours[layout.ssv_member("friction", "plant")]) if v[0] != "m_B"]
    m_B = next(v for v in _values(ours[layout.ssv_member("friction", "plant")]) if v[0] == "m_B")
    controller_values_ = _values(ours[layout.ssv_member("friction", "controller")])
    connectors = {
        "vsc": [("x_B", "input"), ("v_B", "input"), ("theta1", "input"), ("omega1", "input"), ("iq_ref", "output")],
        "mechanism": [
            ("x_B", "output"),
            ("v_B", "output"),
            ("theta1", "output"),
            ("omega1", "output"),
            ("iq_ref", "input"),
        ],
    }

    def component(name: str, source: str, bindings: str) -> str:
        declared = "".join(
            f'<ssd:Connector name="{n}" kind="{k}"><ssc:Real/></ssd:Connector>' for n, k in connectors[name]
        )
        return (
            f'<ssd:Component name="{name}" source="{source}"><ssd:Connectors>{declared}</ssd:Connectors>'
            f"<ssd:ParameterBindings>{bindings}</ssd:ParameterBindings></ssd:Component>"
        )

    wires = [("vsc", "iq_ref", "mechanism", "iq_ref")] + [
        ("mechanism", s, "vsc", s) for s in ("omega1", "theta1", "v_B", "x_B")
    ]
    ssd = (
        '<?xml version="1.0" encoding="UTF-8"?>'
        '<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
        'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
        'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="nominal">'
        '<ssd:System name="handmade"><ssd:ParameterBindings>'
        + _inline([("mechanism.m_B", "Real", m_B[2])], "system")
        + "</ssd:ParameterBindings><ssd:Elements>"
        + component("vsc", "resources/vsc.fmu", _inline(controller_values_, "nominal"))
        + component(
            "mechanism",
            "resources/plant.fmu",
            _inline([("mu", "Real", "0.5"), ("m_B", "Real", "9.0")], "first") + _inline(plant_values, "nominal"),
        )
        + "</ssd:Elements><ssd:Connections>"
        + "".join(
            f'<ssd:Connection startElement="{a}" startConnector="{b}" endElement="{c}" endConnector="{d}"/>'
            for a, b, c, d in wires
        )
        + '</ssd:Connections></ssd:System><ssd:DefaultExperiment stopTime="1.5"/></ssd:SystemStructureDescription>'
    )
    assert schema_problem(etree.fromstring(ssd.encode()), "ssd") is None
    handmade = tmp_path / "handmade.ssp"
    with zipfile.ZipFile(handmade, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        archive.write(plant_fmu, "resources/plant.fmu")
        archive.write(vsc_fmu, "resources/vsc.fmu")
    for args, out in (
        ([str(scenario), "--fmu", str(plant_fmu)], tmp_path / "yaml"),
        ([str(handmade)], tmp_path / "ssp"),
    ):
        ran = CliRunner().invoke(main, ["run", *args, "--out", str(out), "-q"])
        assert ran.exit_code == 0, ran.output
    expected = read_trace_csv(tmp_path / "yaml" / "fig4_nominal" / "friction" / "trace.csv")
    got = read_trace_csv(tmp_path / "ssp" / "handmade_ssp" / "nominal" / "trace.csv")
    for column in expected.names:
        assert np.array_equal(got.column(column), expected.column(column)), column
    record = json.loads((tmp_path / "ssp" / "handmade_ssp" / "nominal" / "run.json").read_text())
    ran_with = record["resolved"]["ssp"]["components"]["plant"]
    assert ran_with["name"] == "mechanism" and ran_with["values"]["mu"] == 0.2 and ran_with["values"]["m_B"] == 4.43


def test_ssp_variant_writes_the_variants_named_and_refuses_names_that_collide(
    plant_fmu: Path, controller_fmu: Path, tmp_path: Path
) -> None:
    """`ssp --variant NAME` writes that variant alone as SystemStructure.ssd (named after it); an
    unknown name, and two variants whose root SSDs would share a file (ignoring case, or a later
    variant named SystemStructure), are one line, exit 2, nothing written."""
    scenario, out = ROOT / "scenarios" / "fig4_nominal.yaml", tmp_path / "s.ssp"

    def ssp(given: Path, *extra: str):  # noqa: ANN202
        args = ["ssp", str(given), "--out", str(out), "--plant", str(plant_fmu), "--controller", str(controller_fmu)]
        return CliRunner().invoke(main, [*args, *extra])

    assert ssp(scenario, "--variant", "no_friction").exit_code == 0
    members = _members(out)
    assert sorted(m for m in members if m.endswith(".ssd")) == ["SystemStructure.ssd"]
    assert etree.fromstring(members["SystemStructure.ssd"]).get("name") == "no_friction"
    out.unlink()
    line = _one_line(ssp(scenario, "--variant", "heavy"), tmp_path / "none")
    assert line == f"error: {scenario}: no variant 'heavy' (choose one of friction, no_friction with --variant)"
    text = scenario.read_text()
    for renamed, expected in (
        (
            text.replace("  no_friction:\n", "  Friction:\n", 1).replace("  friction:\n", "  b: {}\n  friction:\n", 1),
            None,
        ),
        (text.replace("  no_friction:\n", "  SystemStructure:\n", 1), "would both be written as SystemStructure.ssd"),
    ):
        if expected is None:  # b, friction, Friction: friction.ssd and Friction.ssd
            expected = "'friction' and 'Friction' would both be written as Friction.ssd"
        bad = tmp_path / "bad.yaml"
        bad.write_text(renamed)
        line = _one_line(ssp(bad), tmp_path / "none")
        assert expected in line and "names are compared ignoring case" in line, line
        assert not out.exists()


def test_an_ssv_is_parsed_once_however_often_it_is_bound(
    fig5_ssp: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every variant's plant and controller bind an .ssv; the archive's checks and each variant's
    read use it again: each member is parsed (and schema-checked) once."""
    from toggle_cosim.ssp import bindings

    parsed: list[str] = []
    parse = bindings.parse_member

    def counted(archive, member, kind, where):  # noqa: ANN001, ANN202
        parsed.append(member)
        return parse(archive, member, kind, where)

    monkeypatch.setattr(bindings, "parse_member", counted)
    with open_ssp_variants(fig5_ssp, [None, "no_friction"]) as studies:
        assert len(studies) == 2
    assert parsed and sorted(parsed) == sorted(set(parsed))


@pytest.mark.parametrize(
    ("limit", "value", "message"),
    [
        ("MAX_PARAMETERS", 3, "more than 3 parameters in one parameter set (refused;"),
        ("MAX_BOUND_VALUES", 5, ": its parameter bindings apply more than 5 values over its components (refused;"),
    ],
)
def test_parameter_bindings_past_their_bounds_are_refused_in_one_line(
    fig5_ssp: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, limit: str, value: int, message: str
) -> None:
    from toggle_cosim.ssp import bindings

    monkeypatch.setattr(bindings, limit, value)
    line = _run_ssp(fig5_ssp, tmp_path / "out")
    assert line.startswith(f"error: {fig5_ssp}: ") and message in line, line


def test_a_variant_is_chosen_by_its_ssd_name_before_any_file_name(fig5_ssp: Path, tmp_path: Path) -> None:
    """no_friction.ssd renamed "SystemStructure": --variant SystemStructure is that SSD (a name),
    not SystemStructure.ssd (whose file stem it is); a member's whole file name still chooses it."""
    renamed = _rewrite(
        fig5_ssp,
        tmp_path / "renamed.ssp",
        _ssd_edit('name="no_friction"', 'name="SystemStructure"', member="no_friction.ssd"),
    )
    assert read_ssp(renamed, "SystemStructure").member == "no_friction.ssd"
    assert read_ssp(renamed, "SystemStructure.ssd").member == layout.SSD_MEMBER
    with pytest.raises(SspError, match="no variant 'no_friction'"):
        read_ssp(renamed, "no_friction")
