"""The build cache (`fmu_export.build_cache`): an identical build is a copy of the FMU kept in the
user's private cache, not a compile; any change to what decides the FMU's bytes is a miss; a
cached file the private-cache rules refuse is not used; TOGGLE_COSIM_BUILD_CACHE=0 turns it off.

The cache is seeded from the session's built plant (no compile here): a build that would
compile meets a `compile_model` that raises `Compiled`, so each test sees which way it went."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim import limits
from toggle_cosim.fmu_export import build_cache, build_fmu
from toggle_cosim.fmu_export.interfaces import CHOICES

ROOT = Path(__file__).resolve().parent.parent
SOURCE = ROOT / "modelica" / "ToggleLSM"
MODEL = "ToggleLSM.Plant"


class Compiled(Exception):
    """Raised by the stand-in `compile_model`: the build went to the compiler."""


@pytest.fixture
def no_compiler(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """`compile_model` replaced by one that records its call and raises `Compiled`."""
    from toggle_cosim.fmu_export import compile as compile_module

    calls: list[str] = []

    def compile_model(source: Path, model: str) -> None:
        calls.append(model)
        raise Compiled(model)

    monkeypatch.setattr(compile_module, "compile_model", compile_model)
    return calls


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A private cache folder of this test's own, the build cache on."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("TOGGLE_COSIM_CACHE", str(folder))
    monkeypatch.delenv(build_cache.SWITCH, raising=False)
    return folder


def seed(plant_build, source: Path = SOURCE, fmi_version: str = "2.0", interfaces: str = "both") -> str:
    """Keep the session's plant FMU in the cache under the key of a build of `source` to
    ToggleLSM.fmu; the key."""
    key = build_cache.build_key(source, MODEL, "ToggleLSM", fmi_version, CHOICES[interfaces])
    facts = build_cache.CachedBuild(
        plant_build.fmu.guid, plant_build.variables, plant_build.states, plant_build.event_indicators
    )
    build_cache.keep(key, plant_build.fmu.path, facts)
    return key


def cached_fmu(folder: Path) -> Path:
    (found,) = folder.glob("fmu-*.fmu")
    return found


def short_trace(fmu: Path):
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import runs_from_document
    from toggle_cosim.plant.contract import check_plant

    document = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text(encoding="utf-8"))
    document.pop("variants")
    document["t_end"] = 0.02
    return check_and_simulate(runs_from_document(document)[0], check_plant(fmu)).trace


def test_a_second_identical_build_is_a_copy_from_the_cache_with_the_same_bytes_and_trace(
    plant_build, cache: Path, tmp_path: Path, no_compiler: list[str]
) -> None:
    """The same source, model, file name, FMI version and interfaces: the FMU is copied from the
    cache (the report says so, the compiler is not called), with the first build's bytes and
    report, and it runs a scenario to the first FMU's trace, bit for bit."""
    seed(plant_build)
    output = tmp_path / "again" / "ToggleLSM.fmu"
    output.parent.mkdir()
    report = build_fmu(SOURCE, MODEL, output)
    assert report.from_cache and no_compiler == []
    assert report.compile_seconds == 0.0
    assert output.read_bytes() == plant_build.fmu.path.read_bytes()
    assert report.fmu.path == output and report.fmu.size_bytes == output.stat().st_size
    assert (report.fmu.guid, report.variables, report.states, report.event_indicators) == (
        plant_build.fmu.guid,
        plant_build.variables,
        plant_build.states,
        plant_build.event_indicators,
    )
    first, copy = short_trace(plant_build.fmu.path), short_trace(output)
    assert first.names == copy.names and first.data.tobytes() == copy.data.tobytes()


def test_a_build_the_cache_has_not_seen_compiles(plant_build, cache: Path, tmp_path: Path, no_compiler) -> None:
    """One byte changed in a .mo file, another FMI version, another interface set, another
    model identifier (file name): each is another key and each build goes to the compiler."""
    source = tmp_path / "ToggleLSM"
    shutil.copytree(SOURCE, source)
    original = seed(plant_build, source)
    output = tmp_path / "ToggleLSM.fmu"
    assert build_fmu(source, MODEL, output).from_cache
    for fmi_version, interfaces, name in (
        ("3.0", "both", "ToggleLSM"),
        ("2.0", "cs", "ToggleLSM"),
        ("2.0", "both", "X"),
    ):
        with pytest.raises(Compiled):
            build_fmu(source, MODEL, tmp_path / f"{name}.fmu", fmi_version=fmi_version, interfaces=interfaces)
    package = source / "package.mo"
    package.write_bytes(package.read_bytes() + b" ")
    assert build_cache.build_key(source, MODEL, "ToggleLSM", "2.0", CHOICES["both"]) != original
    with pytest.raises(Compiled):
        build_fmu(source, MODEL, output)
    assert len(no_compiler) == 4


@pytest.mark.parametrize("planted", ["group-writable", "other bytes", "other record"])
def test_a_cached_fmu_the_private_cache_rules_refuse_is_not_used(
    plant_build, cache: Path, tmp_path: Path, no_compiler, planted: str
) -> None:
    """A cached FMU writable by the group, or whose bytes are not those its SHA-256 record
    names, is not copied: the build compiles."""
    seed(plant_build)
    fmu = cached_fmu(cache)
    if planted == "group-writable":
        os.chmod(fmu, 0o660)
    elif planted == "other bytes":
        data = bytearray(fmu.read_bytes())
        data[100] ^= 0xFF
        fmu.write_bytes(bytes(data))
    else:
        record = fmu.with_name(fmu.name + ".sha256")
        os.chmod(record, 0o600)
        record.write_text("0" * 64 + "\n", encoding="ascii")
    with pytest.raises(Compiled):
        build_fmu(SOURCE, MODEL, tmp_path / "ToggleLSM.fmu")
    assert not (tmp_path / "ToggleLSM.fmu").exists()


def test_the_build_cache_switched_off_compiles(
    plant_build, cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, no_compiler
) -> None:
    """TOGGLE_COSIM_BUILD_CACHE=0: the build compiles although the cache has it; any other
    value than 0 or 1 is refused with the other on/off variables."""
    seed(plant_build)
    monkeypatch.setenv(build_cache.SWITCH, "0")
    with pytest.raises(Compiled):
        build_fmu(SOURCE, MODEL, tmp_path / "ToggleLSM.fmu")
    monkeypatch.setenv(build_cache.SWITCH, "off")
    with pytest.raises(limits.LimitError, match="TOGGLE_COSIM_BUILD_CACHE='off': give 0"):
        limits.check_environment()


def test_an_unusable_cache_does_not_fail_a_build(
    plant_build, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, no_compiler
) -> None:
    """No usable cache folder (the configured one and the fallback both refused): the build
    goes on to the compiler, not to an error of the cache."""
    from toggle_cosim import native

    def no_folder() -> Path:
        raise native.CacheError("no usable cache folder")

    monkeypatch.setattr(build_cache, "cache_folder", no_folder)
    monkeypatch.delenv(build_cache.SWITCH, raising=False)
    with pytest.raises(Compiled):
        build_fmu(SOURCE, MODEL, tmp_path / "ToggleLSM.fmu")


def test_build_says_the_fmu_came_from_the_build_cache(
    plant_build, cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, no_compiler
) -> None:
    """`toggle-cosim build` of a build the cache has: its line says "from the build cache"
    instead of the compile seconds, and the FMU still carries its source (FMI-LS-REF)."""
    import zipfile

    from toggle_cosim.cli import main

    seed(plant_build)
    output = tmp_path / "ToggleLSM.fmu"
    result = CliRunner().invoke(main, ["build", "--source", str(SOURCE), "--model", MODEL, "--out", str(output)])
    assert result.exit_code == 0, result.output
    assert "from the build cache" in result.output and "compile " not in result.output
    assert no_compiler == []
    assert any(name.startswith("extra/") for name in zipfile.ZipFile(output).namelist())


def test_a_missing_source_gets_the_builds_own_error_with_the_cache_on(cache: Path, tmp_path: Path) -> None:
    """A source that is not there: the build's one-line ModelCompileError naming it, not an
    OSError from reading the source for the cache's key."""
    from toggle_cosim.fmu_export import ModelCompileError

    with pytest.raises(ModelCompileError, match="expected a Modelica package directory or a .mo file"):
        build_fmu(tmp_path / "Missing.mo", "Missing", tmp_path / "Missing.fmu")
