"""SSPs of more than the plant + controller pair (`toggle_cosim.ssp`, docs/ssp.md "Systems").

A three-component study: the plant FMU, a stand-in controller FMU (tests/models/ssp_controller)
and a position sensor between them (tests/models/ssp_parts/Encoder.py: y = gain·x, in mm
where its FMU declares units), the controller reading the sensor's y as its x_B. Written with
`write_ssp` from a run whose `system` names the sensor and the connections, each root SSD
validates against the SSP 1.0 schemas (and FMPy's reader reads the default) and reads back as the same Wiring (parts, values,
connections and their factors). Unit conversions and LinearTransformations are read in the
standard's order (unit conversion, then the transformation); different dimensions and an
algebraic loop are refused in one line naming them. libcosim runs the exported system as our
Jacobi run does, and a scenario file's system runs from its SSP bit for bit as from the file. The
shipped press example (four components) as an SSP: bit for bit as its scenario, and libcosim
and Ecos agree with our Jacobi run to 1e-12 m.
"""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from lxml import etree

from toggle_cosim.cli import main
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import SspError, schema_problem
from toggle_cosim.ssp.reader import open_ssp
from toggle_cosim.ssp.writer import write_ssp
from toggle_cosim.system.model import Connection, Part, Port, Wiring

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "fig4_nominal.yaml"
NS = layout.NAMESPACES
T_END = 0.05  # s: 100 samples, enough for the plant to move and quick with PythonFMU parts
MM = '<UnitDefinitions><Unit name="mm"><BaseUnit m="1" factor="0.001"/></Unit></UnitDefinitions>'


def _pythonfmu(script: Path, folder: Path) -> Path:
    command = [str(Path(sys.executable).parent / "pythonfmu"), "build", "-f", str(script), "-d", str(folder)]
    built = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert built.returncode == 0, built.stderr
    return folder / f"{script.stem}.fmu"


def _patched(fmu: Path, target: Path, units: dict[str, str], definitions: str = "") -> Path:
    """A copy of the FMU whose variables have these units (PythonFMU writes none), with the
    UnitDefinitions given."""
    with zipfile.ZipFile(fmu) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    text = members["modelDescription.xml"].decode()
    for name, unit in units.items():
        text = re.sub(rf'(<ScalarVariable name="{name}"[^>]*>\s*<Real)', rf'\1 unit="{unit}"', text)
    if definitions:
        text = re.sub(r"(<CoSimulation[^>]*/>)", rf"\1{definitions}", text, count=1)
    members["modelDescription.xml"] = text.encode()
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for member, data in members.items():
            archive.writestr(member, data)
    return target


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The stand-in controller (units on its signals), the sensor bare (no units), the sensor
    declaring x in m and y in mm (with mm's definition), and the drive (in A)."""
    folder = tmp_path_factory.mktemp("parts")
    controller = _pythonfmu(ROOT / "tests" / "models" / "ssp_controller" / "ToggleVSC.py", folder / "c")
    encoder = _pythonfmu(ROOT / "tests" / "models" / "ssp_parts" / "Encoder.py", folder / "e")
    drive = _pythonfmu(ROOT / "tests" / "models" / "ssp_parts" / "Drive.py", folder / "d")
    units = {"x_B": "m", "v_B": "m/s", "theta1": "rad", "omega1": "rad/s", "iq_ref": "A"}
    return {
        "controller": _patched(controller, folder / "ToggleVSC.fmu", units),
        "bare": encoder,
        "mm": _patched(encoder, folder / "Encoder.fmu", {"x": "m", "y": "mm"}, MM),
        "drive": _patched(drive, folder / "Drive.fmu", {"iq_ref": "A", "i": "A"}),
    }


def _system(sensor: Path, gain: float, x_factor: float = 1.0, x_offset: float = 0.0) -> Wiring:
    """The sensor between plant.x_B and controller.x_B; the other signals as the pair wires them."""
    connections = [
        Connection(Port("plant", "x_B"), Port("sensor", "x")),
        Connection(Port("sensor", "y"), Port("controller", "x_B"), x_factor, x_offset),
        *(Connection(Port("plant", s), Port("controller", s)) for s in ("v_B", "theta1", "omega1")),
        Connection(Port("controller", "iq_ref"), Port("plant", "iq_ref")),
    ]
    return Wiring(parts=(Part("sensor", sensor, (("gain", gain),), "Encoder.fmu"),), connections=tuple(connections))


def _export(path: Path, plant_fmu: Path, controller: Path, system: Wiring, gains: tuple[float, ...] = ()) -> Path:
    """fig4's variants with this system (the sensor's gain per variant, if given), t_end = T_END."""
    runs = []
    for index, run in enumerate(load_scenario(SCENARIO)):
        own = system
        if gains:
            part = dataclasses.replace(system.parts[0], values=(("gain", gains[index]),))
            own = dataclasses.replace(system, parts=(part,))
        runs.append(dataclasses.replace(run, t_end=T_END, system=own))
    return write_ssp(SCENARIO, path, plant_fmu, controller, runs=runs)


def _edit(source: Path, target: Path, *changes: tuple[str, str]) -> Path:
    with zipfile.ZipFile(source) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    text = members[layout.SSD_MEMBER].decode()
    for old, new in changes:
        assert old in text, old
        text = text.replace(old, new, 1)
    members[layout.SSD_MEMBER] = text.encode()
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return target


def _connections(system: Wiring) -> list[tuple[str, str, float, float]]:
    return [(str(c.start), str(c.end), c.factor, c.offset) for c in system.connections]


def test_a_system_round_trips_through_an_ssp(fmus: dict[str, Path], plant_fmu: Path, tmp_path: Path) -> None:
    """Every component in every root SSD (one binding each, its variant's .ssv, the sensor's gain
    per variant), each SSD valid SSP 1.0; read back, each variant's system is the one written:
    parts (name, values), connections in order with their factor and offset. The sensor's y in
    mm to the controller's x_B in m is the master's own conversion (both FMUs declare their
    units): the SSD says it whole (a LinearTransformation of 0.001 with suppressUnitConversion)
    and it reads back as the identity connection written. A connection of its own, x 2.0 + 0.25,
    reads back with the same bits; the run's record names the part, its source, hash and values."""
    from fmpy.ssp.ssd import read_ssd

    written = _system(fmus["mm"], 1000.0)
    path = _export(tmp_path / "sys.ssp", plant_fmu, fmus["controller"], written, gains=(1000.0, 500.0))
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        ssds = {name: etree.fromstring(archive.read(name)) for name in names if name.endswith(".ssd")}
        assert "resources/Encoder.fmu" in names
        for name in names:
            if name.endswith(".ssv"):
                assert schema_problem(etree.fromstring(archive.read(name)), "ssv") is None
    assert sorted(ssds) == ["SystemStructure.ssd", "no_friction.ssd"]
    described = read_ssd(str(path), validate=True)  # FMPy's reader validates it against its own schemas
    assert [c.name for c in described.system.elements] == ["plant", "controller", "sensor"]
    for ssd in ssds.values():
        assert schema_problem(ssd, "ssd") is None
        components = ssd.findall("ssd:System/ssd:Elements/ssd:Component", NS)
        assert [c.get("name") for c in components] == ["plant", "controller", "sensor"]
        for component in components:
            bound = component.findall("ssd:ParameterBindings/ssd:ParameterBinding", NS)
            assert [b.get("source") for b in bound] == [layout.ssv_member(ssd.get("name"), component.get("name"))]
        wire = ssd.find("ssd:System/ssd:Connections/ssd:Connection[@startElement='sensor']", NS)
        assert wire.get("suppressUnitConversion") == "true"
        assert wire.find("ssc:LinearTransformation", NS).get("factor") == "0.001"
        sensor = next(c for c in components if c.get("name") == "sensor")
        units = {c.get("name"): c.find("ssc:Real", NS).get("unit") for c in sensor.iterfind("ssd:Connectors/*", NS)}
        assert units == {"x": "m", "y": "mm"}
    for variant, gain in (("friction", 1000.0), ("no_friction", 500.0)):
        with open_ssp(path, variant) as study:
            system = study.run.system
            assert (system.plant, system.controller) == ("plant", "controller")
            assert [(p.name, p.values, p.source) for p in system.parts] == [
                ("sensor", (("gain", gain),), "resources/Encoder.fmu")
            ]
            assert system.parts[0].fmu.is_file()
            assert system.connections == written.connections
            record = study.run.resolved["ssp"]["parts"][0]
            assert record["name"] == "sensor" and record["values"] == {"gain": gain} and len(record["sha256"]) == 64
    scaled = _system(fmus["bare"], 1.0, 2.0, 0.25)
    path = _export(tmp_path / "scaled.ssp", plant_fmu, fmus["controller"], scaled)
    with open_ssp(path) as study:
        assert study.run.system.connections == scaled.connections
        assert _connections(study.run.system)[1] == ("sensor.y", "controller.x_B", 2.0, 0.25)


@pytest.fixture(scope="module")
def bare_ssp(fmus: dict[str, Path], plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The system with the sensor that declares no units (its connectors carry none)."""
    return _export(
        tmp_path_factory.mktemp("bare") / "bare.ssp", plant_fmu, fmus["controller"], _system(fmus["bare"], 1.0)
    )


SENSOR_Y = '<ssd:Connector name="y" kind="output">\n            <ssc:Real/>'
UNITS = '<ssd:Units>\n    <ssc:Unit name="A">'
TO_X_B = 'startElement="sensor" startConnector="y" endElement="controller" endConnector="x_B"/>'


def _y_in(unit: str, definition: str = "") -> tuple[tuple[str, str], ...]:
    """The sensor's y connector in `unit` (the FMU declares none), with the SSD Unit given."""
    changes = [(SENSOR_Y, f'<ssd:Connector name="y" kind="output">\n<ssc:Real unit="{unit}"/>')]
    if definition:
        changes.append((UNITS, f'<ssd:Units>{definition}\n    <ssc:Unit name="A">'))
    return tuple(changes)


MM_UNIT = '<ssc:Unit name="mm"><ssc:BaseUnit m="1" factor="0.001"/></ssc:Unit>'


@pytest.mark.parametrize(
    ("case", "changes", "expected"),
    [
        ("mm to m: a unit conversion", _y_in("mm", MM_UNIT), (0.001, 0.0)),
        (
            "then a LinearTransformation",
            (
                *_y_in("mm", MM_UNIT),
                (TO_X_B, TO_X_B[:-2] + '><ssc:LinearTransformation factor="2" offset="0.1"/></ssd:Connection>'),
            ),
            (0.002, 0.1),
        ),
        (
            "a LinearTransformation instead (suppressUnitConversion)",
            (
                *_y_in("mm", MM_UNIT),
                (
                    TO_X_B,
                    TO_X_B[:-2] + ' suppressUnitConversion="true"><ssc:LinearTransformation factor="2" offset="0.1"/>'
                    "</ssd:Connection>",
                ),
            ),
            (2.0, 0.1),
        ),
        ("degrees Celsius to kelvin", (), None),
    ],
    ids=lambda value: value if isinstance(value, str) else "",
)
def test_unit_conversions_and_linear_transformations_are_read_in_the_standards_order(
    case: str, changes: tuple, expected: tuple[float, float] | None, bare_ssp: Path, tmp_path: Path
) -> None:
    """end = a·(unit-converted start) + b (the schema: the transformation applies to the value
    already in the target unit), or a·start + b with suppressUnitConversion. A unit with an
    offset: 20 degC is 293.15 K (factor 1, offset 273.15 from the units' base-unit offsets)."""
    if expected is None:  # both ends given units of the SSD's own with offsets
        celsius = '<ssc:Unit name="degC"><ssc:BaseUnit K="1" offset="273.15"/></ssc:Unit>'
        changes = (
            (SENSOR_Y, '<ssd:Connector name="y" kind="output">\n<ssc:Real unit="degC"/>'),
            (
                '<ssd:Connector name="x_B" kind="input">\n            <ssc:Real unit="m"/>',
                '<ssd:Connector name="x_B" kind="input">\n<ssc:Real unit="K"/>',
            ),
            (
                UNITS,
                f'<ssd:Units>{celsius}<ssc:Unit name="K"><ssc:BaseUnit K="1"/></ssc:Unit>\n    <ssc:Unit name="A">',
            ),
        )
        edited = _edit(bare_ssp, tmp_path / "c.ssp", *changes)
        with pytest.raises(
            SspError, match=re.escape("gives controller.x_B the unit 'K' (= 1 K), but its FMU's unit is")
        ):
            open_ssp(edited).__enter__()
        return
    edited = _edit(bare_ssp, tmp_path / "e.ssp", *changes)
    with open_ssp(edited) as study:
        got = _connections(study.run.system)[1]
        assert got[:2] == ("sensor.y", "controller.x_B")
        assert got[2:] == pytest.approx(expected, rel=1e-15, abs=0)


def test_a_part_with_an_input_iq_ref_is_told_from_the_plant_and_a_boolean_is_not_connected(
    fmus: dict[str, Path], plant_fmu: Path, tmp_path: Path
) -> None:
    """A drive between controller and plant has an input iq_ref as the plant has: the plant is the
    one with the plant contract's required variables, the drive a part. Connecting the drive's
    Boolean output is refused in one line naming it (connections join Real variables)."""
    signals = ("x_B", "v_B", "theta1", "omega1")
    system = Wiring(
        parts=(Part("drive", fmus["drive"], (("i_max", 8.0),)),),
        connections=(
            *(Connection(Port("plant", s), Port("controller", s)) for s in signals),
            Connection(Port("controller", "iq_ref"), Port("drive", "iq_ref")),
            Connection(Port("drive", "i"), Port("plant", "iq_ref")),
        ),
    )
    path = _export(tmp_path / "drive.ssp", plant_fmu, fmus["controller"], system)
    with open_ssp(path) as study:
        read = study.run.system
        assert (read.plant, read.controller, [p.name for p in read.parts]) == ("plant", "controller", ["drive"])
        assert read.parts[0].values == (("i_max", 8.0),) and read.connections == system.connections
    boolean = _edit(
        path,
        tmp_path / "boolean.ssp",
        (
            '<ssd:Connector name="i" kind="output">',
            '<ssd:Connector name="saturated" kind="output"><ssc:Boolean/></ssd:Connector>'
            '<ssd:Connector name="i" kind="output">',
        ),
        (
            "</ssd:Connections>",
            '<ssd:Connection startElement="drive" startConnector="saturated" endElement="plant" endConnector="F_E"/>'
            "</ssd:Connections>",
        ),
    )
    line = _one_line(boolean, tmp_path / "out")
    assert "the connection drive.saturated -> plant.F_E joins drive.saturated, a Boolean variable" in line


def _one_line(path: Path, out: Path) -> str:
    result = CliRunner().invoke(main, ["run", str(path), "--out", str(out), "-q"])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: SystemStructure.ssd: "), result.output
    assert not out.exists() or not any(out.iterdir())
    return lines[0]


def test_different_dimensions_and_an_algebraic_loop_are_refused_in_one_line(bare_ssp: Path, tmp_path: Path) -> None:
    """A connector in seconds feeding the controller's x_B in m: refused naming both units. The
    controller's command fed back into the sensor (whose y depends directly on x: PythonFMU
    declares no dependencies, so on every input): a cycle through four ports, named."""
    seconds = _edit(bare_ssp, tmp_path / "s.ssp", *_y_in("s"))
    line = _one_line(seconds, tmp_path / "out")
    assert "the connection sensor.y -> controller.x_B joins s to m, units of different dimensions" in line
    loop = _edit(
        bare_ssp,
        tmp_path / "loop.ssp",
        (
            'startElement="plant" startConnector="x_B" endElement="sensor"',
            'startElement="controller" startConnector="iq_ref" endElement="sensor"',
        ),
    )
    line = _one_line(loop, tmp_path / "out")
    cycle = re.search(r"an algebraic loop (\S+(?: -> \S+)+) \(", line)
    assert cycle, line
    ports = cycle.group(1).split(" -> ")
    assert ports[0] == ports[-1] and set(ports) == {"sensor.x", "sensor.y", "controller.x_B", "controller.iq_ref"}


def test_libcosim_runs_the_exported_system_as_our_jacobi_run_does(
    fmus: dict[str, Path], plant_fmu: Path, tmp_path: Path
) -> None:
    """libcosim loads the exported three-component SSD (mm to m said as a LinearTransformation
    with suppressUnitConversion, which it applies: its controller.x_B is the plant's x_B, two
    samples behind in its records) and steps it: the plant's x_B moves from x_start and equals
    our Jacobi run of the same SSP (`toggle-cosim run --coupling jacobi`) to 1e-12 m, the command
    to 1e-12 A; our run records the sensor and names the part in run.json."""
    pytest.importorskip("libcosimpy")
    import json

    from masters import run_in_libcosim

    from toggle_cosim.files.traces import read_csv

    path = _export(tmp_path / "sys.ssp", plant_fmu, fmus["controller"], _system(fmus["mm"], 1000.0))
    run = next(r for r in load_scenario(SCENARIO) if r.variant == "friction")
    frame = run_in_libcosim(path, None, run.T_s, T_END)
    x_B = frame["plant.x_B"].to_numpy()
    assert x_B[0] == pytest.approx(run.x_start, abs=1e-12)
    assert abs(x_B[-1] - run.x_start) > 1e-3
    assert frame["controller.x_B"].to_numpy()[2:] == pytest.approx(x_B[:-2], rel=1e-12)
    result = CliRunner().invoke(main, ["run", str(path), "--coupling", "jacobi", "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 0, result.output
    folder = tmp_path / "out" / "sys_ssp_jacobi" / "friction"
    trace = read_csv(folder / "trace.csv")
    assert len(trace.time) == len(x_B) and "sensor.y" in trace.names
    assert np.max(np.abs(trace.column("plant.x_B") - x_B)) < 1e-12
    assert np.max(np.abs(trace.column("controller.iq_ref") - frame["controller.iq_ref"].to_numpy())) < 1e-12
    record = json.loads((folder / "run.json").read_text())
    assert record["resolved"]["ssp"]["parts"][0]["name"] == "sensor"
    assert [c["name"] for c in record["system"]["components"]] == ["plant", "controller", "sensor"]


@pytest.mark.slow
def test_a_scenarios_system_and_its_ssp_give_one_trace_bit_for_bit(
    fmus: dict[str, Path], plant_fmu: Path, tmp_path: Path
) -> None:
    """A scenario file with `components:` (the sensor, mm) and `connections:`, written with
    `toggle-cosim ssp` and the real controller FMU ToggleVSC: both variants run from the SSP give
    the scenario's traces bit for bit on every column both have (the built-in law natively, the
    same law as an FMU; the sensor's mm converted to the controller's m by the master in both)."""
    from toggle_cosim.controller_fmu import build_controller_fmu
    from toggle_cosim.files.traces import read_csv

    vsc = build_controller_fmu(tmp_path / "vsc" / "ToggleVSC.fmu").path
    text = SCENARIO.read_text().replace("t_end: 1.5", f"t_end: {T_END}")
    text = re.sub(r"(?m)^fmu: .*$", f"fmu: {plant_fmu}", text)
    text += (
        f"components:\n  sensor:\n    fmu: {fmus['mm']}\n    parameters: {{gain: 1000.0}}\n"
        "connections:\n  - plant.x_B -> sensor.x\n  - sensor.y -> controller.x_B\n"
        "  - plant.v_B -> controller.v_B\n  - controller.iq_ref -> plant.iq_ref\n"
    )
    scenario = tmp_path / "sensed.yaml"
    scenario.write_text(text)
    ssp = tmp_path / "sensed.ssp"
    written = CliRunner().invoke(main, ["ssp", str(scenario), "--out", str(ssp), "--controller", str(vsc)])
    assert written.exit_code == 0, written.output
    for args, out in (
        ([str(scenario)], "yaml"),
        ([str(ssp), "--variant", "friction", "--variant", "no_friction"], "ssp"),
    ):
        ran = CliRunner().invoke(main, ["run", *args, "--out", str(tmp_path / out), "-q"])
        assert ran.exit_code == 0, ran.output
    for variant in ("friction", "no_friction"):
        expected = read_csv(tmp_path / "yaml" / "fig4_nominal" / variant / "trace.csv")
        got = read_csv(tmp_path / "ssp" / "sensed_ssp" / variant / "trace.csv")
        common = [name for name in expected.names if name in got.names]
        assert {"plant.x_B", "sensor.y", "controller.x_B", "controller.iq_ref"} <= set(common)
        for name in common:
            assert np.array_equal(got.column(name), expected.column(name)), (variant, name)
        assert abs(expected.column("plant.x_B")[-1] - expected.column("plant.x_B")[0]) > 1e-3


@pytest.fixture(scope="module")
def press(plant_fmu: Path, press_parts: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """examples/press_system/press.yaml (plant, controller, sensor, die: four components), its
    t_end cut to 0.5 s, written with `toggle-cosim ssp` and the real controller FMU (press.ssp),
    and also its integral variant alone (integral.ssp); run from the scenario (yaml/), from the
    SSP (ssp/) and from the SSP with --coupling jacobi (ssp/press_ssp_jacobi/). The folder."""
    from toggle_cosim.controller_fmu import build_controller_fmu

    folder = tmp_path_factory.mktemp("press")
    vsc = build_controller_fmu(folder / "vsc" / "ToggleVSC.fmu").path
    text = (ROOT / "examples" / "press_system" / "press.yaml").read_text()
    text = re.sub(r"(?m)^t_end: 2\.5 ", "t_end: 0.5 ", text)
    text = re.sub(r"(?m)^fmu: .*$", f"fmu: {plant_fmu}", text)
    for name in ("PositionSensor", "DieLoad"):
        text = text.replace(f"../../fmus/{name}.fmu", str(press_parts[name]))
    scenario = folder / "press.yaml"
    scenario.write_text(text)
    for out, extra in (("press.ssp", []), ("integral.ssp", ["--variant", "integral"])):
        written = CliRunner().invoke(
            main, ["ssp", str(scenario), "--out", str(folder / out), "--controller", str(vsc), *extra]
        )
        assert written.exit_code == 0, written.output
    variants = ["--variant", "paper", "--variant", "integral"]
    ssp = str(folder / "press.ssp")
    for args, out in (
        ([str(scenario)], "yaml"),
        ([ssp, *variants], "ssp"),
        ([ssp, *variants, "--coupling", "jacobi"], "ssp"),
    ):
        ran = CliRunner().invoke(main, ["run", *args, "--out", str(folder / out), "-q"])
        assert ran.exit_code == 0, ran.output
    return folder


@pytest.mark.slow
def test_the_press_example_as_an_ssp_runs_as_its_scenario_and_in_libcosim(press: Path) -> None:
    """Each variant of the press example run from its SSP gives the scenario's trace bit for bit
    on every column; libcosim, loading each variant's root SSD, gives our Jacobi run's x_B to
    1e-12 m and command to 1e-10 A."""
    from toggle_cosim.files.traces import read_csv

    for variant in ("paper", "integral"):
        expected = read_csv(press / "yaml" / "press_system" / variant / "trace.csv")
        got = read_csv(press / "ssp" / "press_ssp" / variant / "trace.csv")
        assert set(expected.names) <= set(got.names) and "die.F" in expected.names
        for name in expected.names:
            assert np.array_equal(got.column(name), expected.column(name)), (variant, name)
    pytest.importorskip("libcosimpy")
    from masters import run_in_libcosim

    for variant, member in (("paper", None), ("integral", "integral.ssd")):
        jacobi = read_csv(press / "ssp" / "press_ssp_jacobi" / variant / "trace.csv")
        frame = run_in_libcosim(press / "press.ssp", None, 0.0005, 0.5, ssd=member)
        assert np.max(np.abs(frame["plant.x_B"].to_numpy() - jacobi.column("plant.x_B"))) < 1e-12
        assert np.max(np.abs(frame["controller.iq_ref"].to_numpy() - jacobi.column("controller.iq_ref"))) < 1e-10


@pytest.mark.slow
def test_ecos_runs_the_press_example_by_its_set_names_as_our_jacobi_run_does(press: Path) -> None:
    """Ecos applies a parameter set named at init: paper from press.ssp (SystemStructure.ssd
    binds it), integral from the SSP of that variant alone (`toggle-cosim ssp --variant integral`);
    each gives our Jacobi run's x_B to 1e-12 m."""
    try:
        import ecospy  # noqa: F401
    except (ImportError, OSError) as error:  # its native library needs Debian's libtbb12
        pytest.skip(f"ecospy cannot be loaded: {error}")
    from masters import run_in_ecos

    from toggle_cosim.files.traces import read_csv

    for variant, archive in (("paper", "press.ssp"), ("integral", "integral.ssp")):
        jacobi = read_csv(press / "ssp" / "press_ssp_jacobi" / variant / "trace.csv")
        frame = run_in_ecos(press / archive, variant, 0.0005, 0.5)
        assert np.max(np.abs(frame["plant.x_B"].to_numpy() - jacobi.column("plant.x_B"))) < 1e-12
