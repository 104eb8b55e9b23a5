"""`toggle-cosim paper`: its figures are drawn by a child process beside the runs; the command
still writes every file whole, reports each figure, and an interrupt leaves no partial file
and no figure process behind."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

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


def test_an_interrupt_leaves_no_partial_file_and_no_figure_process(plant_fmu: Path, tmp_path: Path) -> None:
    psutil = pytest.importorskip("psutil")
    out = tmp_path / "out"
    process = subprocess.Popen(
        _paper(plant_fmu, out), cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not (out / "fig4_nominal" / "no_friction" / "run.json").exists():
        time.sleep(0.01)
    children = psutil.Process(process.pid).children(recursive=True)
    assert any("toggle_cosim.analysis.figure_worker" in " ".join(c.cmdline()) for c in children if c.is_running())
    time.sleep(0.3)  # the first figure is being drawn now
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=30)
    assert process.returncode == 130, stderr
    assert "Traceback" not in stderr
    gone, alive = psutil.wait_procs([c for c in children if c.is_running()], timeout=5)
    assert not alive, f"left running: {[c.cmdline() for c in alive]}"
    assert not [p for p in out.rglob("*") if "partial" in p.name]
    for trace in out.rglob("trace.csv"):  # every file there is whole: each run.json beside its trace
        assert (trace.parent / "run.json").is_file()
