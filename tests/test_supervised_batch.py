"""Several supervised runs at once (cosim/isolation/supervised_batch.py): the outcomes come back in the
order of the runs, with the bits of the in-process loop whatever the number of jobs; closing
the batch early kills the children still running and leaves no folder behind."""

from __future__ import annotations

import os
import tempfile
import uuid
from pathlib import Path

import numpy as np
import pytest
from process_events import wait_gone, wait_until

from toggle_cosim.cosim.isolation.supervised_batch import default_jobs, run_supervised
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
PAPER = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")


def _pairs(plant_fmu: Path) -> list:
    plant = check_plant(plant_fmu)
    return [(run, plant) for name in PAPER for run in load_scenario(ROOT / "scenarios" / f"{name}.yaml")]


@pytest.mark.slow
@pytest.mark.parametrize("jobs", [1, 2, 3])
def test_the_outcomes_are_in_order_and_bit_identical(plant_fmu: Path, jobs: int) -> None:
    pairs = _pairs(plant_fmu)
    outcomes = list(run_supervised(pairs, jobs=jobs))
    assert [o.run.label for o in outcomes] == [run.label for run, _ in pairs]
    for outcome, (run, plant) in zip(outcomes, pairs, strict=True):
        plain = check_and_simulate(run, plant)
        assert outcome.complete and outcome.record["status"] == "complete"
        assert np.array_equal(outcome.trace.data, plain.trace.data)
        assert outcome.summary == plain.summary


def test_closing_the_batch_early_kills_and_cleans_up(
    plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After the first outcome the caller stops: the run under way is killed (no process of it is
    left, not even a zombie) and every run's temporary folder is gone."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    pairs = _pairs(plant_fmu)
    before = set(_children())  # a resource tracker, say, left by an earlier test in this process
    batch = run_supervised(pairs, jobs=2)
    first = next(batch)
    assert first.complete
    children = [p for p in _children() if p not in before]
    assert children  # the next runs were started before the first was handed back (alive or not yet reaped)
    batch.close()  # kills and reaps them before it returns
    assert [p for p in children if Path(f"/proc/{p}").exists() and _parent(p) == os.getpid()] == []
    assert list(tmp_path.glob("toggle-cosim-run-*")) == []


@pytest.mark.parametrize("after", [1, 3])
def test_an_interrupt_after_a_run_ended_hands_it_back_and_still_stops_the_batch(
    plant_fmu: Path, monkeypatch: pytest.MonkeyPatch, after: int
) -> None:
    """An interrupt that lands while the batch waits, once the run it waits for has already ended
    (its child done, not yet handed back), must not end the batch as if the runs had run out: the
    ended runs come back whole, in order, and then the batch raises KeyboardInterrupt (or hands
    back the first unfinished run as interrupted). Before, the ended run came back complete and
    the batch stopped quietly: `run` with several scenarios exited 0 with later runs never run."""
    from toggle_cosim.cosim.isolation import supervised_batch

    real = supervised_batch.wait_for
    calls = {"n": 0}

    def interrupted_wait(children: list) -> None:  # the interrupt lands once every child waited on has ended
        calls["n"] += 1
        while not all(child.done for child in children):
            real([child for child in children if not child.done])
        if calls["n"] == after:
            raise KeyboardInterrupt("SIGINT")

    monkeypatch.setattr(supervised_batch, "wait_for", interrupted_wait)
    pairs = _pairs(plant_fmu)
    handed = []
    with pytest.raises(KeyboardInterrupt):
        for outcome in run_supervised(pairs, jobs=2):
            handed.append(outcome)
            if outcome.interrupted:
                raise KeyboardInterrupt  # as the command does on an interrupted run
    assert handed and all(o.complete for o in handed[:-1])  # the runs that had ended, whole
    assert handed[-1].complete or handed[-1].interrupted


def _parent(pid: str) -> int:
    try:
        return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return -1


def _children() -> list[str]:
    """This process's children: the pids in /proc whose parent it is."""
    return [p for p in os.listdir("/proc") if p.isdigit() and _parent(p) == os.getpid()]


def test_jobs_follow_the_cores_and_the_runs() -> None:
    cores = len(os.sched_getaffinity(0))
    assert default_jobs(1) == 1
    assert default_jobs(100) == cores


@pytest.mark.slow
def test_a_killed_commands_folders_are_removed_by_the_next(plant_fmu: Path, tmp_path: Path) -> None:
    """SIGKILL to a command leaves its runs' folders (nothing in it can run), but no trace buffer:
    that file is created without a name (O_TMPFILE), so no moment exists at which it is on disk.
    The next command removes the folders of supervising processes that no longer exist, and
    leaves those of a live one alone."""
    import signal
    import subprocess
    import sys

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    mark = f"TOGGLE_TEST_MARK_{uuid.uuid4().hex}"  # in the environment of the command and its children
    env = {**os.environ, "TMPDIR": str(scratch), "TOGGLE_COSIM_KERNEL": "0", mark: "1"}  # the Python loop: slower
    files = [str(ROOT / "scenarios" / f"{name}.yaml") for name in PAPER]
    command = [sys.executable, "-m", "toggle_cosim.cli", "run", *files, "--fmu", str(plant_fmu), "-q"]
    process = subprocess.Popen([*command, "--out", str(tmp_path / "a")], env=env, stdout=subprocess.DEVNULL)
    wait_until(lambda: list(scratch.glob("toggle-cosim-run-*")) or process.poll() is not None, "a run started")
    assert process.poll() is None, "the command ended before its runs"
    process.send_signal(signal.SIGKILL)
    process.wait()
    wait_gone(mark)  # the children die with their parent (and write nothing more)
    left = list(scratch.glob("toggle-cosim-run-*"))
    assert left and all(folder.name.startswith(f"toggle-cosim-run-{process.pid}-") for folder in left)
    # the folder holds at most the FMU's unzipped copy (a directory): the trace buffer never had a name
    assert [entry for folder in left for entry in folder.iterdir() if not entry.is_dir()] == []
    alive = scratch / f"toggle-cosim-run-{os.getpid()}-x"  # a live process's folder (this one's)
    alive.mkdir()
    done = subprocess.run([*command, "--out", str(tmp_path / "b")], env=env, capture_output=True, check=False)
    assert done.returncode == 0, done.stderr
    assert list(scratch.glob("toggle-cosim-run-*")) == [alive]
