"""Supervised runs under misbehaving plants (fault injection) and interrupts at any moment.

The plants come from `fault_plants`: the shipped FMU with a C shim in front of its binary that
segfaults, aborts, loops forever, allocates without end, answers NaN or returns Discard/Error
once the communication point reaches t_fault = 0.1 s, only in runs whose F_E is >= 50 N. Each
command also holds a run with F_E = 0 that must complete. For every fault the tests check the
exit status, the run record's status and reason, the length of the partial trace (samples 0 ..
t_fault: 201 at T_s = 0.5 ms), that no temporary folder is left and that the other run completed.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from click.testing import CliRunner
from fault_plants import SCENARIO, fault_environment, make_faulty_fmu
from process_events import program_running, wait_until

from toggle_cosim.cli import main
from toggle_cosim.experiments.sweep import run_sweep
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
T_FAULT = 0.1
ROWS_TO_FAULT = 201  # samples t = 0 .. 0.1 s at T_s = 0.5 ms, the last one before the faulty step
REASONS = {
    "segfault": "killed by SIGSEGV",
    "abort": "killed by SIGABRT",
    "loop": "time limit 2 s exceeded",
    "alloc": "killed by SIGABRT",  # malloc fails at the child's memory limit, the shim aborts
    "nan": "plant outputs became non-finite",
    "discard": "fmi2DoStep failed with status 2 (discard)",
    "error": "fmi2DoStep failed with status 3 (error)",
}


@pytest.fixture(scope="module")
def faulty_fmu(plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_faulty_fmu(plant_fmu, tmp_path_factory.mktemp("faulty") / "Faulty.fmu")


@pytest.fixture()
def fault(faulty_fmu: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path):
    """Set the shim's environment for one kind of fault; a private temporary folder to count leaks."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.setenv("TMPDIR", str(scratch))  # for the sweep's pool workers too
    references = check_plant(faulty_fmu).references

    def arm(kind: str) -> Path:
        for key, value in fault_environment(kind, T_FAULT, references, min_F_E=50.0).items():
            monkeypatch.setenv(key, value)
        return scratch

    return arm


LOOP_LIMIT_S = 2  # the time limit that ends a plant's endless loop; every other run keeps the default (30 s)


def _scenario(folder: Path, kind: str = "") -> Path:
    """SCENARIO; for the loop fault, its hit run limited to LOOP_LIMIT_S (nothing else ends it)."""
    document = yaml.safe_load(yaml.safe_dump(SCENARIO))
    if kind == "loop":
        document["variants"]["hit"]["time_limit"] = LOOP_LIMIT_S
    path = folder / "faulty.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(REASONS))
def test_run_survives_a_misbehaving_plant(kind: str, fault, faulty_fmu: Path, tmp_path: Path) -> None:
    scratch = fault(kind)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["run", str(_scenario(tmp_path, kind)), "--fmu", str(faulty_fmu), "--out", str(out), "-q"]
    )
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    hit = json.loads((out / "faulty" / "hit" / "run.json").read_text())
    assert hit["status"] == "failed" and REASONS[kind] in hit["reason"], hit["reason"]
    assert f"t = {T_FAULT:g}" in hit["reason"]
    trace = read_csv(out / "faulty" / "hit" / "trace.csv")
    assert trace.data.shape[0] == hit["samples"] == ROWS_TO_FAULT
    assert trace.time[-1] == pytest.approx(T_FAULT, abs=1e-12) and np.all(np.isfinite(trace.data))
    clean = json.loads((out / "faulty" / "clean" / "run.json").read_text())
    assert clean["status"] == "complete" and clean["samples"] == 601
    assert list(scratch.iterdir()) == []  # the runs' temporary folders (the unzipped FMU) are gone
    assert not list(out.rglob("*.partial"))


def test_the_paper_runs_stay_bit_identical_under_supervision(plant_fmu: Path, tmp_path: Path) -> None:
    """The supervised child writes the same numbers the unsupervised loop does."""
    from toggle_cosim.cosim.isolation.supervision import simulate_supervised
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import load_scenario

    plant = check_plant(plant_fmu)
    for run in load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml"):
        plain, supervised = check_and_simulate(run, plant), simulate_supervised(run, plant)
        assert supervised.complete and supervised.record["status"] == "complete"
        assert np.array_equal(plain.trace.data, supervised.trace.data)
        assert plain.summary == supervised.summary


def _sweep_file(folder: Path) -> Path:
    base = {k: v for k, v in SCENARIO.items() if k != "variants"}
    (folder / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    sweep = {"base": "base.yaml", "axes": {"plant.F_E": {"values": [0.0, 60.0, 10.0]}}, "output": "out"}
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(sweep, sort_keys=False))
    return path


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(REASONS))
def test_sweep_survives_a_misbehaving_plant(kind: str, fault, faulty_fmu: Path, tmp_path: Path) -> None:
    scratch = fault(kind)
    path = _sweep_file(tmp_path)
    timeout = LOOP_LIMIT_S if kind == "loop" else None  # nothing else ends the loop; the cases keep 30 s
    code = run_sweep(path, fmu=faulty_fmu, workers=1, progress=False, case_timeout=timeout)
    assert code == 1
    rows = {row["plant.F_E"]: row for row in pq.read_table(tmp_path / "out" / "results.parquet").to_pylist()}
    assert rows[60.0]["status"] == "failed" and REASONS[kind] in rows[60.0]["reason"]
    assert rows[60.0]["samples"] == ROWS_TO_FAULT
    assert rows[0.0]["status"] == rows[10.0]["status"] == "ok"  # the other cases went on
    assert list(scratch.iterdir()) == []


# ---------------------------------------------------------------------------------- interrupts


def _command(*args: str) -> list[str]:
    return [sys.executable, "-m", "toggle_cosim.cli", *args]


def _whole_files_only(out: Path) -> None:
    """Every result present is whole: trace.csv parses and has run.json's sample count, no
    partial file, no empty folder."""
    assert not list(out.rglob("*.partial")) and not list(out.rglob(".*.partial.*"))
    for folder in [p for p in out.rglob("*") if p.is_dir()]:
        assert any(folder.iterdir()), f"empty folder {folder}"
    for record_path in out.rglob("run.json"):
        record = json.loads(record_path.read_text())
        assert record["status"] in ("complete", "interrupted")
        trace = read_csv(record_path.parent / "trace.csv")
        assert trace.data.shape[0] == record["samples"]
        if record["status"] == "complete":
            assert record["samples"] == 3001


HOLD_F_E = 150.0  # N: above every paper run's F_E (at most 100 N): only the held runs meet the hold
SIGNAL_POINTS = 12


@pytest.fixture()
def held(shim_fmu: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """The commands below run on the fault shim with no fault: runs with F_E >= 120 N hold in
    their first fmi2DoStep for good (the release file is never made), every other run is the
    plant's. A command with a held run cannot end before an interrupt ends it, whatever the
    machine's speed. The shim marks the file returned once a run holds."""
    marks = tmp_path / "held"
    hold = fault_environment("", 0.0, check_plant(shim_fmu).references, 120.0, hold=tmp_path / "never", mark=marks)
    for key, value in hold.items():
        monkeypatch.setenv(key, value)
    return marks


def _started(command: list[str]) -> subprocess.Popen[str]:
    """The command, once its own code runs (before that the interpreter alone would meet a signal)."""
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    wait_until(lambda: program_running(process.pid) or process.poll() is not None, "the command's own code")
    return process


def _until_held(command: list[str], marks: Path) -> float:
    """Seconds from the command's start to its held run holding (the span the signals are spread
    over); the command is then ended as `kill` would (it cleans up as for any SIGTERM)."""
    process = _started(command)
    started = time.monotonic()
    try:
        wait_until(lambda: marks.exists() or process.poll() is not None, "the held run")
        assert process.poll() is None, process.communicate()
        return time.monotonic() - started
    finally:
        _end(process, signal.SIGTERM)
        marks.unlink(missing_ok=True)


def _end(process: subprocess.Popen[str], number: int | None) -> tuple[int, str]:
    """Send `number` to the process (None: it was sent) and wait for it (hang guard: the held
    run ends only by the signal); its exit status and stderr."""
    if number is not None:
        process.send_signal(number)
    try:
        _, stderr = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        raise
    return process.returncode, stderr


def _interrupt(command: list[str], delay: float, number: int) -> tuple[int, str]:
    """Signal the command `delay` s after its own code started running: SIGINT as a terminal's
    Ctrl-C sends it, to the command's whole process group (its pool workers, figure and plant
    processes too, some of them still starting); SIGTERM as `kill` sends it, to the command
    alone. The command holds a run that never finishes: every moment is one before its end."""
    process = _started(command)
    time.sleep(delay)  # the moment to hit, not a wait for anything: each outcome must be the same
    if number == signal.SIGINT:
        os.killpg(process.pid, number)
        return _end(process, None)
    return _end(process, number)


def _signal_points(span: float) -> list[tuple[float, signal.Signals]]:
    """SIGNAL_POINTS moments spread from the command's start to its held run (`span`), SIGINT
    and SIGTERM in turn."""
    last = SIGNAL_POINTS - 1
    return [(span * k / last, signal.SIGINT if k % 2 == 0 else signal.SIGTERM) for k in range(SIGNAL_POINTS)]


@pytest.mark.slow
def test_interrupts_at_any_moment_of_a_multi_variant_run(shim_fmu: Path, tmp_path: Path, held: Path) -> None:
    """SIGINT/SIGTERM at 12 moments from start-up to the last of seven runs (that one holds until
    the command ends it): exit 130 every time, no traceback, whole files only, the interrupted
    run recorded as interrupted."""
    files = [
        str(ROOT / "scenarios" / f"{name}.yaml")
        for name in ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")
    ]
    last = {k: v for k, v in SCENARIO.items() if k != "variants"}
    last.update(name="held", plant={**SCENARIO["plant"], "F_E": HOLD_F_E}, time_limit=600)
    (tmp_path / "held.yaml").write_text(yaml.safe_dump(last, sort_keys=False))
    files.append(str(tmp_path / "held.yaml"))

    def command(out: str) -> list[str]:
        return _command("run", *files, "--fmu", str(shim_fmu), "--out", str(tmp_path / out), "-q")

    span = _until_held(command("calibration"), held)
    for number, (delay, which) in enumerate(_signal_points(span)):
        out = tmp_path / f"out{number}"
        code, stderr = _interrupt(command(out.name), delay, which)
        assert "Traceback" not in stderr, stderr
        assert code == 130, (delay, which, stderr)
        if out.exists():
            _whole_files_only(out)


@pytest.mark.slow
def test_interrupts_at_any_moment_of_a_sweep(
    shim_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, held: Path
) -> None:
    """The same over a sweep (start-up, workers starting, cases running and finishing; its last
    case holds until the command ends it): exit 130 every time, readable tables only, no
    traceback, no worker folder left in TMPDIR."""
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    base = {k: v for k, v in SCENARIO.items() if k != "variants"}
    base.update(t_end=1.0, time_limit=600)
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    axes = {"plant.F_E": {"values": [*np.linspace(0, 40, 11).tolist(), HOLD_F_E]}}

    def command(output: str) -> list[str]:
        path = tmp_path / f"{output}.yaml"
        path.write_text(yaml.safe_dump({"base": "base.yaml", "axes": axes, "output": output}, sort_keys=False))
        return _command("sweep", str(path), "--fmu", str(shim_fmu), "--workers", "2")

    span = _until_held(command("calibration"), held)
    for number, (delay, which) in enumerate(_signal_points(span)):
        code, stderr = _interrupt(command(f"out{number}"), delay, which)
        assert "Traceback" not in stderr, stderr
        assert code == 130, (delay, which, stderr)
        out = tmp_path / f"out{number}"
        assert not list(scratch.glob("toggle-cosim-run-*")), (delay, which)
        if out.exists():
            assert not list(out.rglob("*.partial"))
            for table in [*out.glob("results.parquet"), *out.glob("parts/*.parquet")]:
                pq.read_table(table)
            if (out / "sweep.json").exists():
                assert json.loads((out / "sweep.json").read_text())["last_run"]["interrupted"]
