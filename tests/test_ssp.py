"""The study as an SSP 1.0 archive (`toggle_cosim.ssp`, docs/ssp.md).

Written for every shipped non-sweep scenario, the SSD and each .ssv validate against the vendored
SSP 1.0 schemas (lxml, the library the writer and reader use; it is a dependency anyway) and are
read by FMPy's own SSP reader, which validates them against FMPy's copies of the schemas. The
.ssv values are the master's plant settings and the built-in law's parameters bit for bit; a
parameter set read back runs the plant as the scenario does, bit for bit. Each bad input is one
line, exit 2, nothing written. Run in our master through the controller FMU ToggleVSC, each
parameter set gives the scenario variant's trace bit for bit.
"""

from __future__ import annotations

import dataclasses
import re
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
from toggle_cosim.controller_fmu import build_controller_fmu
from toggle_cosim.cosim.controllers import builtin_controller
from toggle_cosim.cosim.master import plant_settings, simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import SspError, schema_problem
from toggle_cosim.ssp.reader import open_ssp, read_ssp, read_ssp_sets
from toggle_cosim.ssp.writer import controller_values, write_ssp

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = sorted(p for p in (ROOT / "scenarios").glob("*.yaml") if not p.name.startswith("sweep_"))
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
def test_every_shipped_scenario_gives_an_ssp_valid_against_the_ssp_schemas(
    scenario: Path, plant_fmu: Path, controller_fmu: Path, tmp_path: Path
) -> None:
    """The SSD and every .ssv validate (vendored schemas, and FMPy's reader with its copies);
    the components, connections, bindings and experiment are those of docs/ssp.md."""
    from fmpy.ssp.ssd import read_ssd, read_ssv

    path = write_ssp(scenario, tmp_path / "study.ssp", plant_fmu, controller_fmu)
    runs = load_scenario(scenario)
    members = _members(path)
    sets = [layout.set_name(run.variant) for run in runs]
    ssvs = [layout.ssv_member(name, component) for name in sets for component in (layout.PLANT, layout.CONTROLLER)]
    assert sorted(members) == sorted([layout.SSD_MEMBER, "resources/ToggleLSM.fmu", "resources/ToggleVSC.fmu", *ssvs])
    ssd = etree.fromstring(members[layout.SSD_MEMBER])
    assert schema_problem(ssd, "ssd") is None
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
    for component in ssd.iterfind("ssd:System/ssd:Elements/ssd:Component", NS):
        assert component.get("type") == "application/x-fmu-sharedlibrary"
        bound = [b.get("source") for b in component.iterfind("ssd:ParameterBindings/ssd:ParameterBinding", NS)]
        assert bound == [layout.ssv_member(name, component.get("name")) for name in sets]  # default first
        for connector in component.iterfind("ssd:Connectors/ssd:Connector", NS):
            unit = connector.find("ssc:Real", NS).get("unit")
            assert unit == {**UNITS, "F_E": "N"}[connector.get("name")]
    assert ssd.find("ssd:System/ssd:Connectors", NS) is None  # no system-level connectors
    units = {u.get("name"): dict(u.find("ssc:BaseUnit", NS).attrib) for u in ssd.iterfind("ssd:Units/ssc:Unit", NS)}
    assert (
        units["m/s"] == {"m": "1", "s": "-1"} and units["rad/s"] == {"s": "-1", "rad": "1"} and units["A"] == {"A": "1"}
    )
    experiment = ssd.find("ssd:DefaultExperiment", NS)
    assert float(experiment.get("startTime")) == 0.0 and float(experiment.get("stopTime")) == runs[0].t_end
    ours = ssd.find(f"ssd:Annotations/ssc:Annotation[@type='{layout.ANNOTATION_TYPE}']", NS)
    assert float(ours[0].get("T_s")) == runs[0].T_s
    assert [entry.get("label") for entry in ours[0]] == [run.label for run in runs]


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


def test_a_parameter_set_reads_back_as_the_run_it_was_written_from(fig5_ssp: Path, plant_fmu: Path) -> None:
    plant = check_plant(plant_fmu)
    runs = load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml")
    default = read_ssp(fig5_ssp, folder=fig5_ssp.parent / "default")
    assert default.parameter_set == "friction" and default.parameter_sets == ("friction", "no_friction")
    every = read_ssp_sets(fig5_ssp, folder=fig5_ssp.parent / "every")
    assert [study.parameter_set for study in every] == ["friction", "no_friction"]
    assert len({study.plant_fmu for study in every}) == 1  # one copy of the FMUs for all sets
    for run in runs:
        with open_ssp(fig5_ssp, run.variant) as study:
            assert study.plant_values == tuple(plant_settings(run, plant))
            assert study.controller_values == controller_values(run)
            assert (study.F_E, study.t_end, study.T_s) == (run.plant.F_E, run.t_end, run.T_s)
            assert (study.run.label, study.run.x_start, study.run.x_target) == (run.label, run.x_start, run.x_target)
            assert study.run.plant.fmu_values == study.plant_values and study.run.source == fig5_ssp
            assert study.plant_fmu.is_file() and study.controller_fmu.is_file()
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
        from_ssp = simulate(study.run, check_plant(study.plant_fmu), controller=builtin_controller(study.run))
    from_yaml = simulate(run, plant)
    assert from_ssp.trace.names == from_yaml.trace.names
    assert np.array_equal(_trace(from_ssp), _trace(from_yaml))
    assert from_ssp.record["resolved"]["ssp"] == {"file": str(fig5_ssp), "parameter_set": "friction"}
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
        outcome = simulate(study.run, check_plant(study.plant_fmu), controller=builtin_controller(study.run))
    expected = simulate(no_friction, check_plant(plant_fmu))
    assert np.array_equal(_trace(outcome), _trace(expected))


# -- what other SSP masters make of the parameter sets ------------------------------------------------


def _ecospy():  # noqa: ANN202
    try:
        import ecospy
    except OSError as error:  # its native library needs Debian's libtbb12 (scripts/install-system-deps)
        pytest.skip(f"ecospy's native library cannot be loaded: {error}")
    return ecospy


def test_ecos_applies_each_named_parameter_set_to_both_components(fig5_ssp: Path) -> None:
    """Ecos reads the archive as it is and applies a set named at init to the plant and the
    controller alike (each component's own .ssv of that name); unnamed, it applies none."""
    ecospy = _ecospy()
    for name, mu in (("friction", 0.2), ("no_friction", 0.0)):
        with ecospy.EcosSimulation(ssp_path=str(fig5_ssp), step_size=0.0005) as sim:
            sim.init(parameter_set=name)
            assert (sim.get_real("plant::mu"), sim.get_real("plant::F_E")) == (mu, 100.0)
            assert (sim.get_real("controller::C"), sim.get_real("controller::target")) == (5.0, 0.3199)


def test_libcosim_takes_the_default_set_and_t_s_from_the_ssp(fig5_ssp: Path, tmp_path: Path) -> None:
    """libcosim (an unpacked SSP, no step size given) steps at T_s from the DefaultExperiment's
    annotation and applies the default set, the first binding: friction (mu = 0.2, F_E = 100 N)."""
    pytest.importorskip("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimObserver import CosimObserver

    folder = tmp_path / "unpacked"
    with zipfile.ZipFile(fig5_ssp) as archive:
        archive.extractall(folder)
    execution = CosimExecution.from_ssp_file(str(folder))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    slaves = {info.name.decode(): info.index for info in execution.slave_infos()}

    def value(slave: str, name: str) -> float:
        reference = next(v.reference for v in execution.slave_variables(slaves[slave]) if v.name.decode() == name)
        return observer.last_real_values(slaves[slave], [reference])[0]

    execution.step(2)
    assert execution.status().current_time == 2 * 500_000  # ns: two steps of T_s = 0.5 ms
    assert (value("plant", "mu"), value("plant", "F_E"), value("controller", "C")) == (0.2, 100.0, 5.0)


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


def _ssd_edit(old: str, new: str):  # noqa: ANN202
    def change(members: dict[str, bytes]) -> None:
        text = members[layout.SSD_MEMBER].decode()
        assert old in text
        members[layout.SSD_MEMBER] = text.replace(old, new, 1).encode()

    return change


def _ssv_edit(stem: str, old: str, new: str):  # noqa: ANN202
    def change(members: dict[str, bytes]) -> None:
        member = f"resources/{stem}.ssv"
        text = members[member].decode()
        assert old in text
        members[member] = text.replace(old, new, 1).encode()

    return change


BAD_SSPS = {
    "not a zip": (lambda path, tmp: (tmp / "bad.ssp").write_text("hello") and tmp / "bad.ssp", "not an SSP archive"),
    "no SSD": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", lambda m: m.pop(layout.SSD_MEMBER)),
        "no SystemStructure.ssd in the archive",
    ),
    "not valid SSP 1.0": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", _ssd_edit('kind="output"', 'kind="outward"')),
        "SystemStructure.ssd: not valid SSP 1.0 (line",
    ),
    "missing FMU": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", lambda m: m.pop("resources/ToggleVSC.fmu")),
        "component 'controller''s FMU 'resources/ToggleVSC.fmu' is not in the archive",
    ),
    "connection to a missing connector": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", _ssd_edit('endConnector="omega1"', 'endConnector="omega9"')),
        "names the connector controller.omega9, which the component does not declare",
    ),
    "connection to a missing component": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", _ssd_edit('endElement="plant"', 'endElement="plant2"')),
        "names the component 'plant2', which does not exist (choose one of plant, controller)",
    ),
    "connector the FMU lacks": (
        lambda path, tmp: _rewrite(
            path,
            tmp / "bad.ssp",
            _ssd_edit('<ssd:Connector name="theta1" kind="output">', '<ssd:Connector name="theta7" kind="output">'),
        ),
        "component 'plant' declares the connector 'theta7', which its FMU ToggleLSM.fmu does not have",
    ),
    "unit mismatch": (
        lambda path, tmp: _rewrite(
            path,
            tmp / "bad.ssp",
            _ssd_edit(
                '<ssd:Connector name="x_B" kind="input">\n            <ssc:Real unit="m"/>',
                '<ssd:Connector name="x_B" kind="input">\n            <ssc:Real unit="m/s"/>',
            ),
        ),
        "the connection plant.x_B -> controller.x_B joins m to m/s",
    ),
    "a third component": (
        lambda path, tmp: _rewrite(
            path,
            tmp / "bad.ssp",
            _ssd_edit(
                "</ssd:Elements>", '<ssd:Component name="logger" source="resources/ToggleVSC.fmu"/></ssd:Elements>'
            ),
        ),
        "the component 'logger' besides plant and controller (our master runs those two only; remove it)",
    ),
    "an .ssv not valid": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", _ssv_edit("friction.plant", 'value="0.2"', 'value="low"')),
        "resources/friction.plant.ssv: not valid SSP 1.0 (line",
    ),
    "an .ssv setting a variable the FMU lacks": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", _ssv_edit("friction.plant", 'name="mu"', 'name="muu"')),
        "resources/ToggleLSM.fmu: the plant FMU has no variable 'muu', which resources/friction.plant.ssv sets",
    ),
    "a controller T_s that is not the experiment's": (
        lambda path, tmp: _rewrite(
            path,
            tmp / "bad.ssp",
            _ssv_edit(
                "friction.controller", '"T_s">\n      <ssv:Real value="0.0005"', '"T_s">\n      <ssv:Real value="0.001"'
            ),
        ),
        "parameter set 'friction' sets the controller's T_s = 0.001 s, the experiment's T_s is 0.0005 s",
    ),
    "a value that is not finite": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", _ssv_edit("friction.plant", 'value="0.2"', 'value="NaN"')),
        "resources/friction.plant.ssv: mu = nan is not a finite number (give a finite value)",
    ),
    "unsafe archive": (
        lambda path, tmp: _rewrite(path, tmp / "bad.ssp", lambda m: m.update({"../escape.txt": b"x"})),
        "unsafe or corrupt archive: member '../escape.txt' has a '..'",
    ),
}


@pytest.mark.parametrize("case", BAD_SSPS, ids=list(BAD_SSPS))
def test_a_bad_ssp_is_refused_in_one_line(case: str, fig5_ssp: Path, tmp_path: Path) -> None:
    make, expected = BAD_SSPS[case]
    bad = make(fig5_ssp, tmp_path)
    line = _run_ssp(bad, tmp_path / "out")
    assert line.startswith(f"error: {bad}") and expected in line, line
    with pytest.raises(SspError, match=re.escape(expected)):
        read_ssp(bad)


def test_a_parameter_set_that_does_not_exist_is_refused_naming_those_that_do(fig5_ssp: Path, tmp_path: Path) -> None:
    line = _run_ssp(fig5_ssp, tmp_path / "out", "--parameter-set", "heavy")
    assert line == (
        f"error: {fig5_ssp}: no parameter set 'heavy' (choose one of friction, no_friction with --parameter-set)"
    )
    before = set(Path(tempfile.gettempdir()).glob("toggle-cosim-ssp-*"))
    with pytest.raises(SspError, match="no parameter set 'heavy'"):
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
    assert "--fmu does not apply to an SSP" in _run_ssp(fig5_ssp, out, "--fmu", str(plant_fmu))
    result = CliRunner().invoke(
        main, ["run", str(ROOT / "scenarios" / "fig4_nominal.yaml"), "--parameter-set", "x", "--out", str(out)]
    )
    assert "--parameter-set chooses an SSP's parameter set" in _one_line(result, out)


# -- end to end: the controller FMU in our master --------------------------------------------------


@pytest.fixture(scope="module")
def toggle_vsc(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The real controller FMU (FMI 2.0), built once."""
    return build_controller_fmu(tmp_path_factory.mktemp("vsc") / "ToggleVSC.fmu").path


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda p: p.stem)
def test_running_the_ssp_gives_the_yaml_runs_trace_bit_for_bit(
    scenario: Path, request: pytest.FixtureRequest, toggle_vsc: Path, tmp_path: Path
) -> None:
    """Every shipped scenario file but the sweeps, written as an SSP and run in our master with the
    controller FMU: each parameter set gives its variant's trace bit for bit (the FMU's command,
    S, phase and e are the built-in law's C operations on the same measured values), plus the
    FMU's z column; run.json names the SSP and the set."""
    from toggle_cosim.files.traces import read_csv as read_trace_csv

    plant = request.getfixturevalue("no_gravity_fmu" if scenario.stem == "swap_no_gravity" else "plant_fmu")
    study = write_ssp(scenario, tmp_path / f"{scenario.stem}.ssp", plant, toggle_vsc)
    yaml_out, ssp_out = tmp_path / "yaml", tmp_path / "ssp"
    for args, out in (([str(scenario), "--fmu", str(plant)], yaml_out), ([str(study)], ssp_out)):
        ran = CliRunner().invoke(main, ["run", *args, "--out", str(out), "-q"])
        assert ran.exit_code == 0, ran.output
    for run in load_scenario(scenario):
        variant = run.variant or "run"
        folder, ssp_folder = Path(run.scenario) / variant, Path(f"{scenario.stem}_ssp") / variant
        expected, got = (
            read_trace_csv(yaml_out / folder / "trace.csv"),
            read_trace_csv(ssp_out / ssp_folder / "trace.csv"),
        )
        assert got.names == (*expected.names, "z")  # the FMU also reports the integral law's state
        for column in expected.names:
            assert np.array_equal(got.column(column), expected.column(column)), (run.label, column)
        record = (ssp_out / ssp_folder / "run.json").read_text()
        assert str(study) in record and f'"parameter_set": "{layout.set_name(run.variant)}"' in record


def test_a_named_parameter_set_runs_that_set_only(plant_fmu: Path, toggle_vsc: Path, tmp_path: Path) -> None:
    """--parameter-set NAME runs that set alone, with that set's values (no_friction: mu = 0)."""
    study = write_ssp(ROOT / "scenarios" / "fig4_nominal.yaml", tmp_path / "fig4.ssp", plant_fmu, toggle_vsc)
    ran = CliRunner().invoke(main, ["run", str(study), "--parameter-set", "no_friction", "--out", str(tmp_path), "-q"])
    assert ran.exit_code == 0, ran.output
    assert [p.name for p in (tmp_path / "fig4_ssp").iterdir()] == ["no_friction"]  # named for the archive
    record = (tmp_path / "fig4_ssp" / "no_friction" / "run.json").read_text()
    assert '"parameter_set": "no_friction"' in record and '"mu": 0.0' in record
