"""The parsed modelDescription kept between commands is fmpy's own parse of the same FMU: read
back, it has the same identity and variables; another FMU file (another hash) is parsed
afresh, and a damaged entry is parsed again instead of being trusted."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from fmpy import read_model_description

from toggle_cosim.files.checksums import file_sha256
from toggle_cosim.plant import description_cache
from toggle_cosim.plant.contract import check_plant


def _signature(md) -> tuple:  # noqa: ANN001
    return (
        md.fmiVersion,
        md.guid,
        md.coSimulation.modelIdentifier,
        tuple((v.name, v.valueReference, v.causality, v.variability, v.start) for v in md.modelVariables),
    )


def test_an_entry_is_fmpys_parse_and_is_used(plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TOGGLE_COSIM_CACHE", str(tmp_path / "cache"))
    first = description_cache.read_description(plant_fmu, file_sha256(plant_fmu))
    entries = list((tmp_path / "cache").glob("model-description-*.pickle"))
    assert len(entries) == 1
    calls = []
    monkeypatch.setattr("fmpy.read_model_description", lambda *a, **k: calls.append(a))
    second = description_cache.read_description(plant_fmu, file_sha256(plant_fmu))
    assert calls == []  # read back, not parsed
    assert _signature(second) == _signature(first) == _signature(read_model_description(str(plant_fmu)))


def test_another_file_or_a_damaged_entry_is_parsed(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("TOGGLE_COSIM_CACHE", str(tmp_path / "cache"))
    description_cache.read_description(plant_fmu, file_sha256(plant_fmu))
    (entry,) = (tmp_path / "cache").glob("model-description-*.pickle")
    entry.write_bytes(b"not a pickle")
    again = description_cache.read_description(plant_fmu, file_sha256(plant_fmu))
    assert _signature(again)[1] == read_model_description(str(plant_fmu)).guid
    copy = tmp_path / "copy.fmu"
    shutil.copy(plant_fmu, copy)
    with copy.open("ab") as stream:  # the same description, another file: another key
        stream.write(b"\0")
    description_cache.read_description(copy, file_sha256(copy))
    assert len(list((tmp_path / "cache").glob("model-description-*.pickle"))) == 2


def test_the_plant_carries_its_fmus_hash_into_the_run_record(plant_fmu: Path) -> None:
    """check_plant hashes the FMU once; run.json names that hash (the file's own SHA-256)."""
    from toggle_cosim.cosim.outcome import run_record
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.plant.contract import check_plant

    plant = check_plant(plant_fmu)
    assert plant.sha256 == file_sha256(plant_fmu)
    run = load_scenario(Path(__file__).resolve().parent.parent / "scenarios" / "fig4_nominal.yaml")[0]
    assert run_record(run, plant, "complete", None, 0, 0.0, 0.0)["fmu"]["sha256"] == plant.sha256


def test_without_a_home_folder_the_plant_is_still_read(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """HOME unset and no passwd entry (Path.home() raises): the cache lives in the temporary
    directory only, and the FMU is read, not reported as an unreadable modelDescription.xml."""
    import tempfile

    from toggle_cosim.native import cache_folders

    def no_home() -> Path:
        raise RuntimeError("Could not determine home directory.")

    for name in ("HOME", "XDG_CACHE_HOME", "TOGGLE_COSIM_CACHE"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(Path, "home", staticmethod(no_home))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert cache_folders() == [tmp_path / f"toggle-cosim-{os.getuid()}"]
    plant = check_plant(plant_fmu)
    assert plant.model_identifier and "x_B" in plant.references
