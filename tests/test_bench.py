"""The benchmark runs in the suite, so it cannot go stale: `benchmarks/bench.py --quick` must
finish, measure the loop it says it measures (the compiled system loop when there is a C
compiler), time its C build, measure a python-control PID in the compiled loop and a Python
controller's own cost, measure the sweeps (local workers, a Dask cluster of its own, a many-case
sweep as a command, with the time to its first case), measure systems in the compiled system loop
against a plain C master, and report every target it checks."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from toggle_cosim.cosim.execution.system_loop import system_library

pytestmark = pytest.mark.slow  # the whole benchmark, --quick (about 1-2 min)

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
    if system_library() is not None:
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
    press_sweep = figures["press_sweep"]  # a sweep of the press system against simulate() of its cases
    assert press_sweep["cases"] == 16 and press_sweep["sweep"] > 0 and press_sweep["simulate"] > 0
    assert "a sweep of the press system >= 0.8 x simulate() of the same cases" in result.stdout
    assert 0 < figures["big_sweep"]["first_case_s"] < figures["big_sweep"]["wall_s"]
    assert "the first case starts within 5 s of the command" in result.stdout
    pid = figures["python_control_pid"]  # the example's PID in the compiled loop, beside the built-in law
    assert 0 < pid["compiled_s"] < pid["python_s"] and pid["ratio"] == pid["compiled_s"] / pid["builtin_s"]
    if system_library() is not None:
        assert "python-control controller in the compiled loop <= 1.2 x the built-in law" in result.stdout
    if "systems" in figures:  # the compiled system loop, measured wherever it and the C master compile
        for key in ("pair", "three"):
            system = figures["systems"][key]
            assert system["c_master"] > 0 and 0 < system["compiled"] < system["python"], system
            assert system["bit_for_bit"], key  # the plain C master's bits are the loop's
        assert "plant + controller-FMU system in the compiled loop <= 1.2 x a plain C master" in result.stdout
        assert "3-FMU system in the compiled loop <= 1.2 x its FMUs' own calls from C" in result.stdout
        press = figures["systems"]["press"]
        assert press["components"] == 4 and 0 < press["compiled"] < press["python"] and press["bit_for_bit"]
        assert "4-FMU press system in the compiled loop <= 1.2 x the sum of its FMUs' own calls from C" in result.stdout
        python = figures["systems"]["python_controller"]  # a Python controller in the press system, beside the pair
        assert python["bit_for_bit"] and 0 < python["system"] < python["python"] and python["pair"] > 0, python
        assert "a Python controller in the press system <= 1.2 x the pair's own loop before" in result.stdout
        assert "a Python controller in the pair <= 1.2 x the pair's own loop before" in result.stdout
        assert figures["systems"]["builtin_over_c_master"] > 0  # the built-in law against the plain C master
        assert "built-in law through the execution <= 1.05 x a plain C master" in result.stdout
    if "python_loop_overhead" in figures:  # measured wherever the C driver compiles
        overhead = figures["python_loop_overhead"]
        assert overhead["own_s"] == overhead["loop_s"] - overhead["plant_s"]  # against the C driver's plant share
        assert 0 < overhead["plant_s"] < overhead["loop_s"] and overhead["three_calls_s"] > 0
        assert "Python controller's own cost per sample" in result.stdout
