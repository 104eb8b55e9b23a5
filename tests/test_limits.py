"""Every number given outside a scenario file (options, environment variables) is checked in
one place before any run: NaN, infinity, huge or negative values are one line, exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from toggle_cosim import limits
from toggle_cosim.cli import main

SCENARIO = {
    "name": "small",
    "t_end": 0.05,
    "T_s": 0.0005,
    "stroke": {"x_start": 0.2329, "x_target": 0.3199},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
}
BAD_SECONDS = ["nan", "inf", "-inf", "1e300", "1e10", "-1", "0", "abc", ""]


def _files(folder: Path) -> tuple[Path, Path]:
    scenario = folder / "s.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    sweep = folder / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": "s.yaml", "axes": {"plant.F_E": {"values": [0.0, 5.0]}}}))
    return scenario, sweep


def _one_line_exit_2(args: list[str], needle: str) -> None:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], result.output


@pytest.mark.parametrize("value", BAD_SECONDS)
def test_seconds_out_of_range_are_refused(value: str) -> None:
    with pytest.raises(limits.LimitError, match="give a number of seconds above 0"):
        limits.seconds(value, "--time-limit")


def test_seconds_in_range_are_taken() -> None:
    assert limits.seconds("2.5", "x") == 2.5 and limits.seconds(1e6, "x") == 1e6


@pytest.mark.parametrize("value", ["nan", "inf", "1e300", "1e10", "-1", "0"])
def test_every_time_option_is_checked(plant_fmu: Path, tmp_path: Path, value: str) -> None:
    scenario, sweep = _files(tmp_path)
    out = tmp_path / "out"
    for command in (
        ["run", str(scenario), "--fmu", str(plant_fmu), "--out", str(out), "--time-limit", value],
        ["references", str(scenario), "--fmu", str(plant_fmu), "--out", str(out), "--time-limit", value],
        ["sweep", str(sweep), "--fmu", str(plant_fmu), "--out", str(out), "--case-timeout", value],
    ):
        _one_line_exit_2(command, f"{command[-2]} {value}")
    assert not out.exists()


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("TOGGLE_COSIM_MAX_OUTPUT", "1e400"),
        ("TOGGLE_COSIM_MAX_OUTPUT", "nan"),
        ("TOGGLE_COSIM_MAX_OUTPUT", "-5"),
        ("TOGGLE_COSIM_MAX_OUTPUT", "lots"),
        ("TOGGLE_COSIM_PLANT_MEMORY", "-5G"),
        ("TOGGLE_COSIM_PLANT_MEMORY", "0"),
        ("TOGGLE_COSIM_PLANT_MEMORY", "infG"),
        ("TOGGLE_COSIM_PLANT_MEMORY", "12Q"),
        ("TOGGLE_COSIM_KERNEL", "yes"),
        ("TOGGLE_COSIM_SUPERVISE", "2"),
    ],
)
def test_every_environment_number_is_checked_before_any_run(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, value: str
) -> None:
    scenario, sweep = _files(tmp_path)
    monkeypatch.setenv(name, value)
    out = tmp_path / "out"
    _one_line_exit_2(["run", str(scenario), "--fmu", str(plant_fmu), "--out", str(out)], f"{name}={value!r}")
    _one_line_exit_2(["sweep", str(sweep), "--fmu", str(plant_fmu), "--out", str(out / "sw")], f"{name}={value!r}")
    assert not (out / "small").exists() and not list((out / "sw").glob("*.parquet"))


def test_sizes_take_suffixes_where_documented() -> None:
    assert limits.byte_size("128M", "X", suffixes=True) == 128 << 20
    assert limits.byte_size("2e9", "X") == 2_000_000_000
    with pytest.raises(limits.LimitError):
        limits.byte_size("128M", "X")  # TOGGLE_COSIM_MAX_OUTPUT is in bytes
