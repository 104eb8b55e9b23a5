"""Every loader under hostile input: scenario, sweep, tolerances, trace CSV, run.json and the FMU
archive. Random and mutated input ends in the loader's own one-line error or a result, never
another exception; alias bombs, deep nesting, FIFOs, devices and oversize files are refused
quickly, each naming its limit."""

from __future__ import annotations

import io
import os
import time
import zipfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toggle_cosim.analysis.compare import load_tolerances
from toggle_cosim.analysis.csv_traces import CompareInputError, read_trace
from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
from toggle_cosim.experiments.sweep import SweepError, load_sweep
from toggle_cosim.files import bounded as bounded_files
from toggle_cosim.files import yaml_loader
from toggle_cosim.files.bounded import InputFileError, read_bounded
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant import archive as fmu_archive
from toggle_cosim.plant.contract import ContractError, check_plant

ROOT = Path(__file__).resolve().parent.parent
FUZZ = settings(max_examples=40, deadline=2000, suppress_health_check=[HealthCheck.function_scoped_fixture])
YAMLISH = st.text(alphabet=st.sampled_from(list("ab:-[]{}&*!|>'\"#,.0123456789eE+ \n\t") + ["\x00", "é"]), max_size=200)


def _one_line(message: str) -> None:
    assert message and "\n" not in message and "\r" not in message


@FUZZ
@given(text=YAMLISH)
def test_yaml_loader_answers_with_a_value_or_one_line(text: str) -> None:
    try:
        yaml_loader.parse_yaml(text)
    except yaml_loader.YamlError as error:
        _one_line(str(error))


@FUZZ
@given(data=st.binary(max_size=300) | YAMLISH.map(str.encode))
def test_scenario_sweep_and_tolerance_loaders_fail_only_their_own_way(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "input.yaml"
    path.write_bytes(data)
    for load, error in ((load_scenario, ScenarioError), (load_sweep, SweepError), (load_tolerances, CompareInputError)):
        try:
            load(path)
        except error as found:
            _one_line(str(found))


@FUZZ
@given(
    data=st.binary(max_size=300)
    | st.text(alphabet=st.sampled_from(list('"time,x_B0.123e-\n\r ')), max_size=200).map(str.encode)
)
def test_trace_csv_readers_fail_only_their_own_way(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "trace.csv"
    path.write_bytes(data)
    try:
        read_trace(path)
    except CompareInputError as error:
        _one_line(str(error))
    try:
        read_csv(path)
    except ValueError:  # InputFileError is one; numpy's messages for a malformed table are others
        pass


@FUZZ
@given(
    data=st.binary(max_size=200) | st.sampled_from([b"{}", b"[]", b'{"resolved": 1}', b'{"scenario": "x"}', b"null"])
)
def test_plot_refuses_a_bad_run_json_in_one_line(tmp_path: Path, data: bytes) -> None:
    from click.testing import CliRunner

    from toggle_cosim.cli import main

    run = tmp_path / "results" / "case" / "variant"
    run.mkdir(parents=True, exist_ok=True)
    (run / "trace.csv").write_text('"time","x_B"\n0,0.2\n')
    (run / "run.json").write_bytes(data)
    result = CliRunner().invoke(main, ["plot", str(run.parent)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and len(result.output.strip().splitlines()) == 1
    assert not list(run.parent.glob("*.png"))


# ------------------------------------------------------------------------------- FMU archives

NAMES = st.sampled_from(
    [
        "modelDescription.xml",
        "/etc/passwd",
        "..\\evil.dll",
        "../outside.txt",
        "a/../../b",
        "C:/windows.dll",
        "binaries/linux64/x.so",
        "resources/ok.txt",
        "sources\\m.c",
    ]
)


@FUZZ
@given(
    names=st.lists(NAMES, min_size=1, max_size=4, unique=True), flip=st.integers(0, 2000), seed=st.binary(max_size=64)
)
def test_fmu_archives_are_refused_in_one_line(tmp_path: Path, names: list[str], flip: int, seed: bytes) -> None:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        for name in names:
            archive.writestr(name, seed * 50 or b"x")
    data = bytearray(buffer.getvalue())
    if flip < len(data) and flip % 3 == 0:
        data[flip] ^= 0x5A  # corrupt a byte somewhere: header, name or deflate data
    path = tmp_path / "plant.fmu"
    path.write_bytes(bytes(data))
    with pytest.raises(ContractError) as info:
        check_plant(path)
    _one_line(str(info.value))
    assert str(info.value).startswith(f"{path}:")


@pytest.mark.parametrize(
    ("name", "needle"), [("/abs.txt", "absolute"), ("a\\b.txt", "backslash"), ("x/../../up.txt", "'..'")]
)
def test_archive_names_refused_before_extraction(tmp_path: Path, name: str, needle: str) -> None:
    path = tmp_path / "plant.fmu"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("modelDescription.xml", "<fmiModelDescription fmiVersion='2.0'/>")
        archive.writestr(name, "x")
    with pytest.raises(ContractError, match=needle):
        check_plant(path)


def test_an_inflation_bomb_is_refused_by_its_declared_size(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """modelDescription.xml that inflates past its limit (lowered here to keep the test small)."""
    monkeypatch.setattr(fmu_archive, "MODEL_DESCRIPTION_LIMIT", 1 << 20)
    path = tmp_path / "plant.fmu"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("modelDescription.xml", b"<" + b" " * (3 << 20))
    started = time.perf_counter()
    with pytest.raises(ContractError, match="over the 1 MiB limit"):
        check_plant(path)
    assert time.perf_counter() - started < 2.0


def test_corrupt_deflate_data_is_refused(tmp_path: Path, plant_fmu: Path) -> None:
    data = bytearray(plant_fmu.read_bytes())
    with zipfile.ZipFile(plant_fmu) as archive:
        info = archive.getinfo("modelDescription.xml")
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    for k in range(start + 100, start + 140):
        data[k] ^= 0xFF
    path = tmp_path / "corrupt.fmu"
    path.write_bytes(bytes(data))
    with pytest.raises(ContractError, match="corrupt|damaged"):
        check_plant(path)


# ------------------------------------------------------------------------------- bounded files


def test_fifo_and_devices_are_refused_without_waiting(tmp_path: Path) -> None:
    fifo = tmp_path / "scenario.yaml"
    os.mkfifo(fifo)
    started = time.perf_counter()
    with pytest.raises(ScenarioError, match="not a regular file"):
        load_scenario(fifo)
    with pytest.raises(CompareInputError, match="not a regular file"):
        read_trace(Path("/dev/zero"))
    with pytest.raises(InputFileError, match="not a regular file"):
        read_bounded("/dev/zero", 10)
    assert time.perf_counter() - started < 1.0


def test_oversize_files_are_refused_naming_the_limit(tmp_path: Path) -> None:
    big = tmp_path / "big.yaml"
    big.write_bytes(b"# " + b"x" * bounded_files.YAML_LIMIT)
    with pytest.raises(ScenarioError, match="over the limit of 1 MiB"):
        load_scenario(big)
    with pytest.raises(CompareInputError, match="over the limit of 1 MiB"):
        load_tolerances(big)
    with pytest.raises(InputFileError, match="over the limit of 100 bytes"):
        read_bounded(big, 100)


# Refused, not expanded: a refusal takes well under a second (0.4 s for the deep file on a loaded
# machine); 168 million values (10 x 8^8) expanded and checked take minutes and gigabytes. The
# bound tells the two apart on any machine, however busy, where 1 s did not
EXPANDED_S = 30.0


@pytest.mark.parametrize("loader", [load_scenario, load_sweep, load_tolerances])
def test_alias_bombs_and_deep_nesting_are_refused_quickly(tmp_path: Path, loader) -> None:  # noqa: ANN001
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [
        f"a{k}: &a{k} [*a{k - 1}, *a{k - 1}, *a{k - 1}, *a{k - 1}, *a{k - 1}, *a{k - 1}, *a{k - 1}, *a{k - 1}]"
        for k in range(1, 9)
    ]
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(lines) + "\n")
    deep = tmp_path / "deep.yaml"
    deep.write_text("a: " + "[" * 5000 + "]" * 5000 + "\n")
    for path, needle in ((bomb, "values once its aliases are expanded"), (deep, "nested more than 32 levels")):
        started = time.perf_counter()
        with pytest.raises((ScenarioError, SweepError, CompareInputError), match=needle):
            loader(path)
        assert time.perf_counter() - started < EXPANDED_S


@pytest.mark.parametrize("loader", [load_scenario, load_sweep, load_tolerances])
def test_duplicate_keys_are_refused_by_every_loader(tmp_path: Path, loader) -> None:  # noqa: ANN001
    path = tmp_path / "dup.yaml"
    path.write_text("a: 1\nb: 2\na: 3\n")
    with pytest.raises((ScenarioError, SweepError, CompareInputError), match="duplicate key 'a'"):
        loader(path)


def test_tolerances_accept_yaml_1_2_numbers_and_refuse_nan(tmp_path: Path) -> None:
    path = tmp_path / "tol.yaml"
    path.write_text("default: {rtol: 5e-4}\n")
    default, _ = load_tolerances(path)
    assert default.rtol == 5e-4
    for bad in (".nan", ".inf", "!!int abc"):
        path.write_text(f"default: {{rtol: {bad}}}\n")
        with pytest.raises(CompareInputError):
            load_tolerances(path)


def test_a_scenario_fifo_does_not_hang_the_command(tmp_path: Path) -> None:
    """The CLI refuses a FIFO given as the scenario at once (no writer ever comes)."""
    import subprocess
    import sys

    fifo = tmp_path / "s.yaml"
    os.mkfifo(fifo)
    result = subprocess.run(
        [sys.executable, "-m", "toggle_cosim.cli", "run", str(fifo)], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2 and "not a regular file" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
