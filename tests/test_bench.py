"""The benchmark runs in the suite, so it cannot go stale: `benchmarks/bench.py --quick` must
finish, measure the loop it says it measures (the compiled loop when there is a C compiler),
time the compiled loop's C build, measure the sweeps (local workers, a Dask cluster of its own,
a many-case sweep as a command), and report every target it checks."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from toggle_cosim.cosim import compiled_loop

ROOT = Path(__file__).resolve().parent.parent


def test_bench_quick_runs_and_measures_the_compiled_loop(plant_fmu: Path, tmp_path: Path) -> None:
    figures_file = tmp_path / "bench.json"
    result = subprocess.run(
        [
            sys.executable,
            str(ROOT / "benchmarks" / "bench.py"),
            "--quick",
            "--skip-build",
            "--fmu",
            str(plant_fmu),
            "--json",
            str(figures_file),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    figures = json.loads(figures_file.read_text())
    if compiled_loop.kernel_available():
        assert figures["loop"] == "compiled"
        assert figures["kernel_compile_s"] > 0
    else:
        assert figures["loop"] == "python" and figures["loop_reason"]
    for key in ("ratio_loop_over_ctypes", "paper_rtf", "six_runs"):
        assert key in figures, key
    if "controller_fmu" in figures:  # measured wherever there is a C compiler
        assert 0 < figures["controller_fmu"]["ns_per_step"] < 1e6
        assert "controller FMU <= 0.5 us per step" in result.stdout
    assert len(figures["paper_rtf"]) == 6
    assert 0 < figures["linearize"]["seconds"] < 1.0 and figures["linearize"]["relative_error"] < 1e-6
    for target in (
        "full loop <= 1.5 x FMU alone",
        "each paper run's loop",
        "six runs together",
        "sweep >= 0.8 x simulate() on the same workers",
        "Dask cluster >= 0.8 x the pool",
        "1000 cases: parent peak RSS <= 500 MB",
        "linearize at one point < 1 s",
    ):
        assert target in result.stdout, target
    sweeps = figures["sweeps"]
    assert all(sweeps[key] > 0 for key in ("sweep1", "sweep2", "sim1", "sim2", "dask", "pool2"))
    assert figures["big_sweep"]["exit"] == 0 and figures["big_sweep"]["done_in_table"] == 1000
