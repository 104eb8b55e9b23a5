"""Every run folder holds a provenance record (provenance.srmd) naming by SHA3-256 the files that
shaped its trace; `toggle-cosim repeat RUN_FOLDER` checks them all first, runs again, and its
trace.csv is bit-identical to the recorded one. A changed file, a hostile record or an --out
that would replace the recorded run are refused in one line, exit 2, nothing written."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.provenance import srmd

ROOT = Path(__file__).resolve().parents[1]
FIG4 = ROOT / "scenarios" / "fig4_nominal.yaml"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory, plant_fmu: Path) -> Path:
    """A short fig4 run's folder (its record beside trace.csv and run.json), written once."""
    folder = tmp_path_factory.mktemp("recorded")
    document = yaml.safe_load(FIG4.read_text(encoding="utf-8"))
    document.update(t_end=0.02, fmu=str(plant_fmu))
    scenario = folder / "fig4.yaml"
    scenario.write_text(yaml.safe_dump(document), encoding="utf-8")
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(folder / "out"), "-q", "-j", "1"])
    assert result.exit_code == 0, result.output
    return folder / "out" / "fig4_nominal" / "friction"


def _copy(recorded: Path, tmp_path: Path) -> Path:
    """The recorded run, its scenario and its records copied under tmp_path (same relative
    places), so that a test may edit them; the plant FMU stays where it is."""
    top = recorded.parents[2]
    for path in top.rglob("*"):
        if path.is_file():
            target = tmp_path / path.relative_to(top)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(path.read_bytes())
    copied = tmp_path / recorded.relative_to(top)
    for record in tmp_path.rglob("provenance.srmd"):  # the plant's URI is relative: point it at the same FMU
        text = record.read_text(encoding="utf-8")
        plant = next(item for item in srmd.read_record(recorded / record.name).resources if item.role == "plant")
        if record.parent == copied:
            moved = srmd.uri_of(srmd.located(recorded / "provenance.srmd", plant.uri), copied)
            record.write_text(text.replace(f'xlink:href="{plant.uri}"', f'xlink:href="{moved}"'), encoding="utf-8")
    return copied


def test_a_run_folder_holds_a_valid_record_of_its_files(recorded: Path, plant_fmu: Path) -> None:
    """The record names the scenario and the plant by SHA3-256 and the trace as its data, with
    the tools' versions; all its checksums match the files."""
    record = srmd.read_record(recorded / "provenance.srmd")
    roles = {item.role: item for item in record.resources}
    assert set(roles) == {"scenario", "plant"}
    assert roles["plant"].checksum == hashlib.sha3_256(plant_fmu.read_bytes()).hexdigest()
    assert record.data is not None and record.data.uri == "trace.csv"
    assert record.data.checksum == hashlib.sha3_256((recorded / "trace.csv").read_bytes()).hexdigest()
    assert {"python", "toggle-cosim", "fmpy", "numpy"} <= dict(record.tools).keys()
    assert record.setting("variant") == "friction"
    assert srmd.verify_record(recorded / "provenance.srmd") == []


def test_a_run_repeated_from_its_record_is_bit_identical(recorded: Path, tmp_path: Path) -> None:
    out = tmp_path / "again"
    result = CliRunner().invoke(main, ["repeat", str(recorded), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    repeated = out / "fig4_nominal" / "friction" / "trace.csv"
    assert repeated.read_bytes() == (recorded / "trace.csv").read_bytes()
    assert "bit-identical to the recorded trace" in result.output
    assert srmd.verify_record(repeated.parent / "provenance.srmd") == []


def test_a_run_whose_scenario_was_edited_is_refused(recorded: Path, tmp_path: Path) -> None:
    """One line naming the scenario; exit 2; nothing run or written."""
    folder = _copy(recorded, tmp_path / "copy")
    scenario = tmp_path / "copy" / "fig4.yaml"
    scenario.write_text(scenario.read_text(encoding="utf-8").replace("t_end: 0.02", "t_end: 0.03"), encoding="utf-8")
    out = tmp_path / "again"
    result = CliRunner().invoke(main, ["repeat", str(folder), "--out", str(out), "-q"])
    assert result.exit_code == 2
    (line,) = result.output.strip().splitlines()
    assert f"{scenario}: changed since the record" in line
    assert not out.exists()


def test_a_record_naming_a_file_the_run_does_not_use_is_refused(recorded: Path, tmp_path: Path) -> None:
    """A resource added to the record (with the right checksum of a file elsewhere) is refused:
    the record must name exactly the files the recorded run uses."""
    folder = _copy(recorded, tmp_path / "copy")
    stranger = tmp_path / "stranger.txt"
    stranger.write_text("not the run's\n")
    path = folder / "provenance.srmd"
    record = srmd.read_record(path)
    extra = srmd.resource(stranger, folder, "document", "notes")
    path.unlink()
    srmd.write_record(path, srmd.Record(**{**record.__dict__, "resources": (*record.resources, extra)}))
    out = tmp_path / "again"
    result = CliRunner().invoke(main, ["repeat", str(folder), "--out", str(out), "-q"])
    assert result.exit_code == 2
    (line,) = result.output.strip().splitlines()
    assert f"names {stranger}" in line and "does not use" in line
    assert not out.exists()


@pytest.mark.parametrize(
    ("content", "says"),
    [
        (b"not xml at all\n", "not well-formed XML"),
        (b'<?xml version="1.0"?><SimulationResourceMetaData/>', "not an SRMD record"),
    ],
)
def test_a_record_that_is_not_srmd_is_refused(tmp_path: Path, content: bytes, says: str) -> None:
    (tmp_path / "provenance.srmd").write_bytes(content)
    result = CliRunner().invoke(main, ["repeat", str(tmp_path), "--out", str(tmp_path / "again")])
    assert result.exit_code == 2
    (line,) = result.output.strip().splitlines()
    assert says in line and "provenance.srmd" in line
    assert not (tmp_path / "again").exists()


def test_a_repeat_into_the_recorded_runs_folder_is_refused(recorded: Path) -> None:
    """--out that would put the repeated run's files over the recorded ones: exit 2."""
    before = (recorded / "trace.csv").read_bytes()
    result = CliRunner().invoke(main, ["repeat", str(recorded), "--out", str(recorded.parents[1]), "-q"])
    assert result.exit_code == 2
    assert "the recorded run's folder" in result.output
    assert (recorded / "trace.csv").read_bytes() == before


def test_the_files_of_a_run_are_its_scenario_plant_tables_and_controller_module(tmp_path: Path) -> None:
    """files_used names an input table's CSV and a controller module beside the scenario, each once."""
    from toggle_cosim.cosim.run_provenance import files_used
    from toggle_cosim.experiments.scenario import load_scenario

    plant = tmp_path / "plant.fmu"
    (table,) = load_scenario(ROOT / "scenarios" / "measured_load.yaml")[:1]
    assert [(u.path.name, u.role) for u in files_used(table, plant)] == [
        ("measured_load.yaml", "scenario"),
        ("plant.fmu", "plant"),
        ("measured_load.csv", "input-table"),
    ]
    module = load_scenario(ROOT / "examples" / "controllers" / "user_controllers.yaml")[0]
    assert [(u.path.name, u.role) for u in files_used(module, plant)][-1] == ("my_controllers.py", "controller-module")


def test_an_edited_controller_module_is_refused(tmp_path: Path, plant_fmu: Path) -> None:
    """The user's controller module is in the record: edited after the run, the repeat names it."""
    examples = ROOT / "examples" / "controllers"
    document = yaml.safe_load((examples / "user_controllers.yaml").read_text(encoding="utf-8"))
    document.update(t_end=0.01, fmu=str(plant_fmu), variants={"pd": document["variants"]["pd"]})
    (tmp_path / "user_controllers.yaml").write_text(yaml.safe_dump(document), encoding="utf-8")
    module = tmp_path / "my_controllers.py"
    module.write_bytes((examples / "my_controllers.py").read_bytes())
    out = tmp_path / "out"
    ran = CliRunner().invoke(main, ["run", str(tmp_path / "user_controllers.yaml"), "--out", str(out), "-q"])
    assert ran.exit_code == 0, ran.output
    module.write_text(module.read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8")
    result = CliRunner().invoke(main, ["repeat", str(out / "user_controllers" / "pd"), "--out", str(tmp_path / "r")])
    assert result.exit_code == 2
    assert result.output.strip().splitlines() == [result.output.strip()]
    assert f"{module}: changed since the record" in result.output and "controller-module" in result.output


def test_a_run_from_an_ssp_is_recorded_by_its_archive_and_repeats_bit_identically(
    tmp_path: Path, plant_fmu: Path, vsc_fmu: Path
) -> None:
    """An SSP's run names the .ssp (its FMUs and parameter files are inside); repeated, its trace is
    the same bytes."""
    document = yaml.safe_load(FIG4.read_text(encoding="utf-8"))
    document.update(t_end=0.02, fmu=str(plant_fmu))
    scenario = tmp_path / "fig4.yaml"
    scenario.write_text(yaml.safe_dump(document), encoding="utf-8")
    archive = tmp_path / "fig4.ssp"
    made = CliRunner().invoke(main, ["ssp", str(scenario), "--out", str(archive), "--controller", str(vsc_fmu)])
    assert made.exit_code == 0, made.output
    out = tmp_path / "out"
    ran = CliRunner().invoke(main, ["run", str(archive), "--out", str(out), "-q", "-j", "1"])
    assert ran.exit_code == 0, ran.output
    (folder,) = {path.parent for path in out.rglob("provenance.srmd")}
    record = srmd.read_record(folder / "provenance.srmd")
    assert [item.role for item in record.resources] == ["ssp"]
    result = CliRunner().invoke(main, ["repeat", str(folder), "--out", str(tmp_path / "again"), "-q"])
    assert result.exit_code == 0, result.output
    repeated = tmp_path / "again" / folder.relative_to(out) / "trace.csv"
    assert repeated.read_bytes() == (folder / "trace.csv").read_bytes()


def test_a_file_of_another_kind_where_the_record_goes_is_refused_before_any_run(
    tmp_path: Path, plant_fmu: Path
) -> None:
    """A run's record replaces an earlier record only: notes at its path stop the command first."""
    document = yaml.safe_load(FIG4.read_text(encoding="utf-8"))
    document.update(t_end=0.02, fmu=str(plant_fmu))
    scenario = tmp_path / "fig4.yaml"
    scenario.write_text(yaml.safe_dump(document), encoding="utf-8")
    notes = tmp_path / "out" / "fig4_nominal" / "friction" / "provenance.srmd"
    notes.parent.mkdir(parents=True)
    notes.write_text("my notes\n")
    result = CliRunner().invoke(main, ["run", str(scenario), "--out", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 2
    assert f"{notes}: exists and is not a provenance record" in result.output
    assert notes.read_text() == "my notes\n" and not (notes.parent / "trace.csv").exists()
