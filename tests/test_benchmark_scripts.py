"""The benchmark scripts run in the suite in their quick modes, so none can silently rot:
chattering.py and sampling_table.py over fewer points, paper_suite.py once (it times
`toggle-cosim paper --skip-build` through timing.py), sweep_tables.py on the shipped sweeps cut
down to a few cases. (bench.py --quick: test_bench.py; the scripts/ are run by the README's
examples and by the test command itself.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.slow  # each benchmark script in its quick mode

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS = ROOT / "benchmarks"


def _script(name: str, *arguments: str, cwd: Path = ROOT) -> str:
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / name), *arguments],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, f"{name}: exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    return result.stdout


def test_chattering_quick_holds_the_integral_law_below_10_A_per_s(plant_fmu: Path) -> None:
    output = _script("chattering.py", "--fmu", str(plant_fmu), "--quick")
    lines = dict(line.split(": ", 1) for line in output.strip().splitlines())
    assert set(lines) == {"paper", "integral"}
    integral = float(lines["integral"].split("total variation of i_q* ")[1].split(" A/s")[0])
    assert 0.0 < integral <= 10.0  # the docs' bound on the integral law's chattering (measured ≤ 2.72 A/s)


def test_sampling_table_quick_passes_the_unchanged_plant_and_fails_the_perturbed(plant_fmu: Path) -> None:
    rows = [line for line in _script("sampling_table.py", str(plant_fmu), "--quick").splitlines() if line[2:3] != "-"]
    table = {row.split("|")[1].strip(): [cell.strip() for cell in row.split("|")[2:-1]] for row in rows[1:]}
    assert rows[0].count("|") == 5  # model, result ×1, result ×10, reference ×10
    assert table["unchanged"] == ["pass", "pass", "pass"]
    assert all(cell.startswith("FAIL") for cell in table["mu 0.2 -> 0.25"] + table["gain C +5 %"])


def test_paper_suite_times_the_paper_command_once(plant_fmu: Path) -> None:
    output = _script("paper_suite.py", "--repeat", "1", "--fmu", str(plant_fmu))
    assert "[1] 13 runs: start -> last file" in output


@pytest.fixture(scope="module")
def small_sweeps(plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The two sweeps sweep_tables.py reads, cut down to F_E in {0, 150} N and m_B = 4.43 kg."""
    folder = tmp_path_factory.mktemp("sweeps")
    for name in ("sweep_law_FE_mB", "sweep_friction_models"):
        document = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text(encoding="utf-8"))
        document["base"] = str(ROOT / "scenarios" / document["base"])
        document["axes"]["plant.F_E"] = {"values": [0, 150]}
        document["axes"]["plant.m_B"] = {"values": [4.43]}
        path = folder / f"{name}.yaml"
        path.write_text(yaml.safe_dump(document), encoding="utf-8")
        command = [Path(sys.executable).parent / "toggle-cosim", "sweep", str(path), "--fmu", str(plant_fmu)]
        result = subprocess.run(
            [*map(str, command), "--out", str(folder / "out" / name), "--workers", "2", "--quiet"],
            capture_output=True,
            text=True,
            timeout=600,
            check=False,
        )
        assert result.returncode == 0, result.stderr
    return folder / "out"


def test_sweep_tables_prints_both_tables(small_sweeps: Path) -> None:
    output = _script("sweep_tables.py", "--sweeps", str(small_sweeps))
    law, friction = output.split("sweep_friction_models:")
    law_rows = [line for line in law.splitlines() if line.startswith("| 0 |") or line.startswith("| 150 |")]
    assert len(law_rows) == 4  # F_E 0 and 150 N, each under both laws
    friction_rows = [
        line for line in friction.splitlines() if line.startswith("| integral") or line.startswith("| paper")
    ]
    assert len(friction_rows) == 6 and all("| 2/2 |" in row for row in friction_rows)  # 2 laws x 3 models, all ok
