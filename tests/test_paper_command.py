"""`toggle-cosim paper`: its figures are drawn by a child process beside the runs; the command
still writes every file whole, reports each figure, and an interrupt leaves no partial file
and no figure process behind."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from process_events import wait_until

pytestmark = pytest.mark.slow  # the paper's runs and figures as a command

ROOT = Path(__file__).resolve().parents[1]
PAPER = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")


def _paper(plant_fmu: Path, out: Path) -> list[str]:
    return [
        sys.executable,
        "-m",
        "toggle_cosim.cli",
        "paper",
        "--skip-build",
        "--fmu",
        str(plant_fmu),
        "--out",
        str(out),
    ]


def test_paper_writes_runs_figures_and_summary(plant_fmu: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = subprocess.run(_paper(plant_fmu, out), cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    for name in PAPER:
        figure = out / name / "figure.png"
        assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"wrote {figure}" in result.stdout
        for variant in ("friction", "no_friction"):
            assert (out / name / variant / "trace.csv").is_file()
    assert (out / "friction_models").is_dir() and "| run |" in (out / "summary.md").read_text()
    assert not [p for p in out.rglob("*") if "partial" in p.name]


def test_an_interrupt_leaves_no_partial_file_and_no_figure_process(shim_fmu: Path, tmp_path: Path) -> None:
    """SIGINT once Fig. 4's runs are written (its figure handed to the worker) and Fig. 5's runs
    (F_E = 100 N) hold in fmi2DoStep at 0.05 s behind the fault shim, so the command is under way
    whatever the machine's speed: exit 130, no traceback, no process and no partial file left."""
    from fault_plants import fault_environment

    from toggle_cosim.plant.contract import check_plant

    psutil = pytest.importorskip("psutil")
    out = tmp_path / "out"
    marks = tmp_path / "held"
    references = check_plant(shim_fmu).references
    env = fault_environment("", 0.05, references, 100.0, hold=tmp_path / "never", mark=marks)
    process = subprocess.Popen(
        _paper(shim_fmu, out), cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    fig4 = [out / "fig4_nominal" / variant / "run.json" for variant in ("friction", "no_friction")]

    def ready() -> bool:
        return (marks.exists() and all(p.exists() for p in fig4)) or process.poll() is not None

    try:
        wait_until(ready, "Fig. 4's runs written and Fig. 5's held")
        children = psutil.Process(process.pid).children(recursive=True)
        figures = [c for c in children if "toggle_cosim.analysis.figure_worker" in " ".join(c.cmdline())]
        assert figures and all(c.is_running() for c in figures)
        process.send_signal(signal.SIGINT)
        _, stderr = process.communicate(timeout=60)  # hang guard: the held runs end only by the interrupt
    finally:
        process.kill()
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr
    gone, alive = psutil.wait_procs([c for c in children if c.is_running()], timeout=60)
    assert not alive, f"left running: {[c.cmdline() for c in alive]}"
    assert not [p for p in out.rglob("*") if "partial" in p.name]
    for trace in out.rglob("trace.csv"):  # every file there is whole: each run.json beside its trace
        assert (trace.parent / "run.json").is_file()
