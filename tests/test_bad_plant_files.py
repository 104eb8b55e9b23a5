"""A plant FMU that cannot be the plant is refused before anything runs: one line naming the
file and the problem, exit status 2, nothing written."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner

from toggle_cosim.cli import main
from toggle_cosim.plant.contract import ContractError, check_plant

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = ROOT / "scenarios" / "fig4_nominal.yaml"


def _rewrite(source: Path, target: Path, edit_description=None, drop=lambda name: False) -> Path:
    """Copy an FMU, optionally editing modelDescription.xml and dropping members."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            if drop(item.filename):
                continue
            data = old.read(item.filename)
            if item.filename == "modelDescription.xml" and edit_description is not None:
                data = edit_description(data.decode()).encode()
            new.writestr(item, data)
    return target


def _cases(plant_fmu: Path, folder: Path) -> dict[str, tuple[Path, str]]:
    not_zip = folder / "not_zip.fmu"
    not_zip.write_bytes(b"\x7fELF this is no archive")
    empty_zip = folder / "no_description.fmu"
    with zipfile.ZipFile(empty_zip, "w") as archive:
        archive.writestr("binaries/readme.txt", "nothing")
    return {
        "missing": (folder / "absent.fmu", "no such FMU file"),
        "not a zip": (not_zip, "not a zip archive"),
        "no modelDescription": (empty_zip, "no modelDescription.xml"),
        "FMI 1.0": (
            _rewrite(plant_fmu, folder / "fmi1.fmu", lambda xml: xml.replace('fmiVersion="2.0"', 'fmiVersion="1.0"')),
            "FMI version 1.0 is not supported",
        ),
        "no binary": (
            _rewrite(plant_fmu, folder / "nobinary.fmu", drop=lambda name: name.startswith("binaries/")),
            "no binary for this platform",
        ),
        "Model Exchange only": (
            _rewrite(
                plant_fmu,
                folder / "me.fmu",
                lambda xml: re.sub(r"<CoSimulation\b.*?</CoSimulation>\s*", "", xml, flags=re.S),
            ),
            "does not support Co-Simulation",
        ),
        "foreign": (
            _rewrite(plant_fmu, folder / "foreign.fmu", lambda xml: xml.replace('name="v_B"', 'name="v_slider"')),
            "missing contract variable 'v_B'",
        ),
        "wrong unit": (
            _rewrite(
                plant_fmu,
                folder / "unit.fmu",
                lambda xml: re.sub(r'(name="x_B".*?unit=")m(")', r"\1mm\2", xml, count=1, flags=re.S),
            ),
            "variable 'x_B' has unit 'mm'",
        ),
        "wrong causality": (
            _rewrite(
                plant_fmu,
                folder / "causality.fmu",
                lambda xml: re.sub(r'(name="F_E"[^>]*causality=")input(")', r"\1output\2", xml),
            ),
            "variable 'F_E' has causality",
        ),
    }


def test_each_bad_plant_is_refused_with_one_line(plant_fmu: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    for name, (path, expected) in _cases(plant_fmu, tmp_path).items():
        with pytest.raises(ContractError, match=re.escape(expected)):
            check_plant(path)
        out = tmp_path / f"out-{name.replace(' ', '_')}"
        result = runner.invoke(main, ["run", str(SCENARIO), "--fmu", str(path), "--out", str(out)])
        assert result.exit_code == 2, (name, result.output)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {path}"), (name, result.stderr)
        assert expected in lines[0]
        assert "Traceback" not in result.output
        assert not out.exists(), name
