"""Plant faults and interruptions: the master stops cleanly, frees the FMU, keeps the trace up to
the fault (marked failed, with the reason), and first retries a failed step from a saved
state where the FMU can save it. Result files are never left truncated."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from fault_plants import fault_environment
from process_events import wait_until

from toggle_cosim.cosim import master
from toggle_cosim.cosim.execution.slaves import FmuSlave
from toggle_cosim.experiments.scenario import runs_from_document
from toggle_cosim.files.traces import read_csv
from toggle_cosim.fmu_export import build_fmu
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
FAULT_MODEL = """within ToggleLSM;
model PlantWithFault "Test only: the plant, with a derivative that is not finite after t_fault"
  extends Plant;
  parameter Real t_fault(unit = "s") = 0.2 "Time after which the model has no finite derivative";
  Real clock(start = 0.0, fixed = true) "Integrates 1/sqrt(t_fault - time), NaN past t_fault";
equation
  der(clock) = 1 / sqrt(t_fault - time);
end PlantWithFault;
"""


@pytest.fixture(scope="module")
def fault_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fault-injecting plant built from a variant of the Modelica source (a copy of the package
    with one more class), so the fault travels the same build and shell as the real plant."""
    folder = tmp_path_factory.mktemp("faulty")
    package = folder / "ToggleLSM"
    shutil.copytree(ROOT / "modelica" / "ToggleLSM", package)
    (package / "PlantWithFault.mo").write_text(FAULT_MODEL)
    return build_fmu(package, "ToggleLSM.PlantWithFault", folder / "Faulty.fmu").fmu.path


def _nominal(**plant: object):
    document = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    document.pop("variants")
    document["t_end"] = 0.5
    document["plant"].update(plant)
    return runs_from_document(document)[0]


def _count_frees(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    freed: list[int] = []
    original = FmuSlave.close

    def close(self: FmuSlave, reuse: bool = False) -> None:
        original(self, reuse)
        freed.append(1)

    monkeypatch.setattr(FmuSlave, "close", close)
    return freed


def test_an_fmu_fault_ends_the_run_cleanly_after_a_retry(fault_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The Modelica fault at t = 0.2 s: doStep returns an error, the master retries the step from
    its checkpoint in smaller steps (in vain), frees the FMU and keeps the trace up to 0.2 s."""
    freed = _count_frees(monkeypatch)
    outcome = master.check_and_simulate(_nominal(), check_plant(fault_fmu))
    assert not outcome.complete and freed == [1]
    assert "fmi2DoStep failed with status 3" in outcome.reason
    assert "Retried from the checkpoint" in outcome.reason
    time_column = outcome.trace.time
    assert time_column[-1] == pytest.approx(0.1995, abs=1e-9)  # the last sample before t_fault = 0.2 s
    assert np.all(np.isfinite(outcome.trace.data))
    assert outcome.record["status"] == "failed" and outcome.record["samples"] == len(time_column)


@pytest.mark.parametrize("status, retried", [(2, True), (3, True), (4, False)])
def test_each_error_status_of_a_step(
    plant_fmu: Path, monkeypatch: pytest.MonkeyPatch, status: int, retried: bool
) -> None:
    """A mock failure of one doStep at t = 0.1 s with Discard (2), Error (3) or Fatal (4): Discard
    and Error are retried from the saved state and the run completes with the same trace as an
    undisturbed run; Fatal is not retried and ends the run, trace kept up to the fault."""
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")  # the Python execution, whose do_step we can intercept
    plant = check_plant(plant_fmu)
    clean = master.check_and_simulate(_nominal(), plant)
    freed = _count_frees(monkeypatch)
    original = FmuSlave.do_step
    failed: list[float] = []

    def do_step(self: FmuSlave, t: float, h: float) -> None:
        if abs(t - 0.1) < 1e-12 and h == 0.0005 and not failed:
            failed.append(t)
            raise self.failure("fmi2DoStep", t, status)
        original(self, t, h)

    monkeypatch.setattr(FmuSlave, "do_step", do_step)
    outcome = master.check_and_simulate(_nominal(), plant)
    assert failed == [pytest.approx(0.1)] and freed == [1]
    if retried:
        assert outcome.complete, outcome.reason
        assert outcome.record["retries"] == [
            {
                "t": pytest.approx(0.1),
                "error": f"fmi2DoStep failed with status {status} "
                f"({['ok', 'warning', 'discard', 'error', 'fatal'][status]}).",
                "outcome": "passed",
            }
        ]
        assert np.max(np.abs(outcome.trace.column("x_B") - clean.trace.column("x_B"))) < 1e-9
    else:
        assert not outcome.complete and "status 4 (fatal)" in outcome.reason
        assert outcome.trace.time[-1] == pytest.approx(0.1)
        assert outcome.record["retries"] == []


def test_non_finite_outputs_end_the_run(plant_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The plant's outputs read at t = 0.15 s and after are NaN: the run ends there, the FMU
    freed, the trace kept up to the sample before."""
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")  # the Python execution, whose get we can intercept
    original = FmuSlave.get

    def get(self: FmuSlave, values: object, t: float) -> None:
        original(self, values, t)
        if t >= 0.15 - 1e-12:
            values[:] = [np.nan] * len(values)

    monkeypatch.setattr(FmuSlave, "get", get)
    freed = _count_frees(monkeypatch)
    outcome = master.check_and_simulate(_nominal(), check_plant(plant_fmu))
    assert not outcome.complete and freed == [1]
    assert outcome.reason == "plant outputs became non-finite at t = 0.15 s"
    assert len(outcome.trace.time) == 300 and np.all(np.isfinite(outcome.trace.data))


def test_sigterm_writes_a_complete_file_marked_interrupted(shim_fmu: Path, tmp_path: Path) -> None:
    """Killing a run with SIGTERM while it is under way (here held in fmi2DoStep at 0.05 s by the
    fault shim, which marks a file then): exit 130, the trace up to the signal is a whole CSV,
    and run.json says interrupted and why; no temporary file is left behind."""
    document = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    document.pop("variants")
    scenario = tmp_path / "long.yaml"
    scenario.write_text(yaml.safe_dump(document))
    out = tmp_path / "out"
    marks = tmp_path / "held"
    hold = fault_environment("", 0.05, check_plant(shim_fmu).references, hold=tmp_path / "never", mark=marks)
    env = {**hold, "TOGGLE_COSIM_KERNEL": "0"}  # the Python loop
    command = [sys.executable, "-m", "toggle_cosim.cli", "run", str(scenario), "--fmu", str(shim_fmu)]
    process = subprocess.Popen(
        [*command, "--out", str(out), "-q"], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        wait_until(lambda: marks.exists() or process.poll() is not None, "the run held at 0.05 s")
        process.send_signal(signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, (stdout, stderr)
    record = json.loads((out / "fig4_nominal" / "run" / "run.json").read_text())
    assert record["status"] == "interrupted" and record["reason"].startswith("interrupted")
    trace = read_csv(out / "fig4_nominal" / "run" / "trace.csv")
    assert trace.data.shape[0] == record["samples"] == 101  # t = 0 .. 0.05 s at T_s = 0.5 ms
    assert np.all(np.isfinite(trace.data))
    assert not list(out.rglob("*.partial"))


def test_sigkill_leaves_no_truncated_csv(plant_fmu: Path, tmp_path: Path) -> None:
    """SIGKILL cannot be caught: what is left is either nothing or whole files, never a
    truncated CSV under the final name (files are written under a temporary name first). The
    kill comes once the first trace is written, while the other runs are under way."""
    out = tmp_path / "out"
    runs = [
        str(ROOT / "scenarios" / f"{name}.yaml")
        for name in ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")
    ]
    process = subprocess.Popen(
        [sys.executable, "-m", "toggle_cosim.cli", "run", *runs, "--fmu", str(plant_fmu), "--out", str(out), "-q"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        wait_until(lambda: any(out.rglob("trace.csv")) or process.poll() is not None, "the first trace")
    finally:
        process.kill()
        process.wait(timeout=30)
    traces = list(out.rglob("trace.csv"))
    assert traces
    for csv in traces:
        trace = read_csv(csv)
        assert trace.data.shape[0] == 3001


def _faulty(plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str, time: float, end: float):
    """The shim plant (`fault_plants`) misbehaving as `kind` from `time` (s) to `end` (s)."""
    from fault_plants import fault_environment, make_faulty_fmu

    faulty = check_plant(make_faulty_fmu(plant_fmu, tmp_path / f"{kind}.fmu"))
    environment = fault_environment(kind, time, faulty.references)
    for name in ("TOGGLE_FAULT_KIND", "TOGGLE_FAULT_TIME", "TOGGLE_FAULT_MIN_FE", "TOGGLE_FAULT_FE_VR"):
        monkeypatch.setenv(name, environment[name])
    monkeypatch.setenv("TOGGLE_FAULT_END", repr(end))
    return faulty


def test_a_run_failing_after_retries_is_reported_at_the_step_that_failed_for_good(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A plant that chatters from t = 0.2 s (every full step discarded, a retry's substeps pass)
    and fails for good at t = 0.25 s: the steps from 0.2 s pass when retried, one by one, until
    the retry at 0.25 s fails. The run is reported failed at 0.25 s, where it failed, with the
    earlier retries noted, and keeps its trace up to that step's sample; the samples before the
    first retried step are the undisturbed run's."""
    faulty = _faulty(plant_fmu, tmp_path, monkeypatch, "chatter", 0.2, 0.25)
    outcome = master.check_and_simulate(_nominal(), faulty)
    retries = outcome.record["retries"]
    assert [entry["outcome"] for entry in retries] == ["passed"] * 100 + ["failed"]
    assert retries[0]["t"] == pytest.approx(0.2) and retries[-1]["t"] == pytest.approx(0.25)
    assert not outcome.complete and outcome.reason.startswith("plant FMU failed at t = 0.25 s: fmi2DoStep failed")
    assert "Retried from the checkpoint" in outcome.reason and "went on failing" not in outcome.reason
    assert outcome.reason.endswith(
        "(earlier, 100 of the plant's steps from t = 0.2 s to 0.2495 s failed and passed when retried from a checkpoint)"
    )
    assert outcome.trace.time[-1] == pytest.approx(0.25, abs=1e-12) and len(outcome.trace.time) == 501
    assert outcome.record["samples"] == 501 and np.all(np.isfinite(outcome.trace.data))
    assert any(w.startswith("100 of the plant's steps from t = 0.2 s") for w in outcome.record["warnings"])
    clean = master.check_and_simulate(_nominal(), check_plant(plant_fmu))  # before the first retry: the undisturbed run
    assert np.array_equal(outcome.trace.data[:401], clean.trace.data[:401])
    from toggle_cosim.cosim.isolation.supervision import simulate_supervised

    supervised = simulate_supervised(_nominal(), faulty)  # the parent counts the rows the child left set
    assert supervised.reason == outcome.reason and np.array_equal(supervised.trace.data, outcome.trace.data)


def test_a_plant_failure_says_what_the_fmu_logged_and_a_retry_that_passed_is_reported(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The step at t = 0.1 s fails once (the FMU logs an event iteration that did not converge)
    and passes when retried: run.json's retries and a warning say so, with the FMU's words. From
    t = 0.2 s every step fails with a logged Zeno message: the reason names t = 0.2 s, the status
    and the FMU's message, and the trace runs to 0.2 s."""
    from fault_plants import ZENO_LATER, ZENO_ONCE

    faulty = _faulty(plant_fmu, tmp_path, monkeypatch, "zeno", 0.1, 0.2)
    outcome = master.check_and_simulate(_nominal(), faulty)
    first = f"fmi2DoStep failed with status 3 (error): {ZENO_ONCE.format(0.1)}"
    assert outcome.record["retries"][0] == {"t": pytest.approx(0.1), "error": first, "outcome": "passed"}
    assert [entry["outcome"] for entry in outcome.record["retries"]] == ["passed", "failed"]
    assert outcome.reason.startswith(
        f"plant FMU failed at t = 0.2 s: fmi2DoStep failed with status 3 (error): {ZENO_LATER.format(0.2)}. Retried"
    )
    assert outcome.reason.count("Zeno") == 1  # the retry failed the same way: said once
    assert outcome.reason.endswith(
        "(earlier, the plant's step at t = 0.1 s failed and passed when retried from a checkpoint)"
    )
    assert outcome.record["warnings"][-1] == (
        f"The plant's step at t = 0.1 s failed and passed when retried from a checkpoint: {first}"
    )
    assert outcome.trace.time[-1] == pytest.approx(0.2, abs=1e-12) and outcome.record["samples"] == 401
    monkeypatch.setenv("TOGGLE_FAULT_END", "1e300")  # the one failure only: the run completes, its retry noted
    passed = master.check_and_simulate(_nominal(), faulty)
    assert passed.complete and passed.record["retries"] == [outcome.record["retries"][0]]
    assert passed.record["warnings"][-1] == outcome.record["warnings"][-1]


def test_the_pair_takes_the_callers_checkpoint_options(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`check_and_simulate(..., checkpoints=)` holds for the plain pair too: with checkpoints off,
    the one refused step at t = 0.1 s ends the run there (no retry), where the default retries
    it and completes."""
    from toggle_cosim.cosim.execution.system_retry import CheckpointOptions

    faulty = _faulty(plant_fmu, tmp_path, monkeypatch, "zeno", 0.1, 1e300)
    retried = master.check_and_simulate(_nominal(), faulty)
    assert retried.complete and [entry["outcome"] for entry in retried.record["retries"]] == ["passed"]
    off = master.check_and_simulate(_nominal(), faulty, checkpoints=CheckpointOptions(enabled=False))
    assert not off.complete and off.record["retries"] == []
    assert off.reason.startswith("plant FMU failed at t = 0.1 s: fmi2DoStep failed with status 3 (error)")
    assert off.trace.time[-1] == pytest.approx(0.1, abs=1e-12)
