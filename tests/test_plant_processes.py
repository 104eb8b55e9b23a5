"""What a plant's native code does beyond the FMI calls: statuses the standard does not define,
log messages that are not UTF-8, helper processes it starts, libraries it ships beside its
binary. The plants are the shipped FMU behind the fault shim (`fault_plants`)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import uuid
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from fault_plants import SCENARIO, fault_environment, make_faulty_fmu
from process_events import marked, wait_gone, wait_until

from toggle_cosim import process_tree
from toggle_cosim.cli import main
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.plant.fmi_calls import failed, log_line
from toggle_cosim.plant.probe import probe_binary

T_FAULT = 0.1
ROWS_TO_FAULT = 201  # samples 0 .. 0.1 s at T_s = 0.5 ms


def _scenario(folder: Path, **changes: object) -> Path:
    path = folder / "faulty.yaml"
    path.write_text(yaml.safe_dump({**SCENARIO, **changes}, sort_keys=False))
    return path


def _arm(monkeypatch: pytest.MonkeyPatch, shim_fmu: Path, kind: str, **extra: str) -> None:
    references = check_plant(shim_fmu).references
    for key, value in {**fault_environment(kind, T_FAULT, references, min_F_E=50.0), **extra}.items():
        monkeypatch.setenv(key, value)


def test_only_ok_and_warning_are_success() -> None:
    assert [status for status in range(-3, 9) if not failed(status)] == [0, 1]


@pytest.mark.parametrize("loop", ["compiled", "python"])
@pytest.mark.parametrize("status", [-1, 5, 7])
def test_a_status_the_standard_does_not_define_fails_the_run(
    shim_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, status: int, loop: str
) -> None:
    """doStep answers -1, 5 (fmi2Pending, never asked for) or 7 at t = 0.1 s and does not step:
    the run fails there, in the compiled loop as in the Python loop; the clean run completes."""
    _arm(monkeypatch, shim_fmu, "status", TOGGLE_FAULT_STATUS=str(status))
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "1" if loop == "compiled" else "0")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(_scenario(tmp_path)), "--fmu", str(shim_fmu), "--out", str(out)])
    assert result.exit_code == 1, result.output
    hit = json.loads((out / "faulty" / "hit" / "run.json").read_text())
    assert hit["status"] == "failed"
    assert f"fmi2DoStep failed with status {status}" in hit["reason"] and "t = 0.1 s" in hit["reason"]
    assert hit["samples"] == ROWS_TO_FAULT == read_csv(out / "faulty" / "hit" / "trace.csv").data.shape[0]
    assert hit["loop"]["kind"] == ("compiled" if loop == "compiled" else "python")
    assert json.loads((out / "faulty" / "clean" / "run.json").read_text())["status"] == "complete"


def test_log_messages_in_any_bytes_and_status_are_printed(shim_fmu: Path, tmp_path: Path) -> None:
    """From t = 0.1 s every doStep logs invalid UTF-8 with status 9: each message is printed with
    the bytes replaced, the run completes, and nothing raises in the callback."""
    env = {**fault_environment("log", T_FAULT, check_plant(shim_fmu).references, 50.0), "TOGGLE_FAULT_STATUS": "9"}
    command = [sys.executable, "-m", "toggle_cosim.cli", "run", str(_scenario(tmp_path)), "--fmu", str(shim_fmu)]
    result = subprocess.run([*command, "--out", str(tmp_path / "out"), "-q"], env=env, capture_output=True, timeout=120)
    stdout, stderr = result.stdout.decode(), result.stderr.decode()
    assert result.returncode == 0, stderr
    assert "[STATUS 9] bad bytes \ufffd\ufffd\ufffd at 0.1 s" in stdout
    assert stdout.count("[STATUS 9]") == 400  # every step from 0.1 s to 0.3 s, hit run only
    assert "Traceback" not in stderr and "Exception ignored" not in stderr
    assert log_line(3, b"\xff ok") == "[ERROR] \ufffd ok" and log_line(-2, None) == "[STATUS -2] "


HELPER_SECONDS = "600"  # the helpers' own life: only a kill ends them within the waits below


@pytest.mark.parametrize(
    ("kind", "limit"),
    [  # each kind once in the fast set, the other pairings in the full suite
        ("fork", None),
        pytest.param("daemon", None, marks=pytest.mark.slow),
        pytest.param("fork", "0.3", marks=pytest.mark.slow),
        ("daemon", "0.3"),
        ("orphan", None),
    ],
)
def test_a_plants_helper_process_ends_with_its_run(
    shim_fmu: Path, tmp_path: Path, kind: str, limit: str | None
) -> None:
    """A helper forked in fmi2Instantiate (holding every descriptor), started by the library's
    constructor with system("sleep 600 &") (holding the command's stdout), or a daemon that
    leaves the plant's group and session before the plant segfaults: the command ends as soon
    as its runs do, its stdout closes (`| cat` would end), no helper is left, and with a time
    limit the run that cannot finish (held in fmi2DoStep from 0.1 s on) ends at it."""
    mark = f"TOGGLE_TEST_MARK_{uuid.uuid4().hex}"
    hold = tmp_path / "never-made" if limit else None  # no file: the held runs never finish
    env = {
        **fault_environment(kind, T_FAULT, check_plant(shim_fmu).references, hold=hold),
        "TOGGLE_FAULT_SLEEP": HELPER_SECONDS,
        mark: "1",
    }
    command = [sys.executable, "-m", "toggle_cosim.cli", "run", str(_scenario(tmp_path)), "--fmu", str(shim_fmu)]
    command += ["--out", str(tmp_path / "out"), "-q"] + (["--time-limit", limit] if limit else [])
    try:
        # reads to EOF: a helper (600 s) holding the output open would run into the timeout
        result = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
        assert result.returncode == (1 if limit or kind == "orphan" else 0), result.stderr
        if kind == "orphan":
            record = json.loads((tmp_path / "out" / "faulty" / "hit" / "run.json").read_text())
            assert "killed by SIGSEGV" in record["reason"]
        if limit:
            record = json.loads((tmp_path / "out" / "faulty" / "hit" / "run.json").read_text())
            assert record["reason"].startswith(f"time limit {limit} s exceeded")
        assert "Traceback" not in result.stderr
        wait_gone(mark)
    finally:
        for pid in marked(mark):
            os.kill(pid, 9)


def test_a_helper_in_its_own_session_is_ended_with_the_tree() -> None:
    """process_tree on its own: a child that leads its group and adopts orphans starts a
    grandchild that leaves the group (setsid) and is orphaned; end_tree ends it too."""
    read_fd, write_fd = os.pipe()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork with pytest's threads
        pid = os.fork()
    if pid == 0:
        process_tree.become_leader()
        helper = os.fork()
        if helper == 0:
            if os.fork() == 0:  # the daemon: own session, its parent gone
                os.setsid()
                os.write(write_fd, str(os.getpid()).encode() + b"\n")
                time.sleep(600)  # beyond the wait below: only the kill ends it in time
            os._exit(0)
        os.waitpid(helper, 0)
        time.sleep(30)
        os._exit(0)
    process_tree.adopt(pid)
    os.close(write_fd)
    daemon = int(os.read(read_fd, 64).split()[0])
    os.close(read_fd)
    # adopted by the child once its parent has exited
    wait_until(lambda: daemon in process_tree.descendants(pid), "the daemon adopted by the child")
    process_tree.finish(pid)
    wait_until(lambda: _ended(daemon), "the daemon killed with the tree")


def test_the_tree_is_walked_until_it_is_frozen(monkeypatch: pytest.MonkeyPatch) -> None:
    """A helper that forked a daemon and is exiting hands the daemon to the subreaper while a
    walk reads the lists (/proc/<pid>/task/*/children, read without the kernel's lock), so one
    walk can find nothing new and still miss the daemon. The walk goes on while a process
    found still runs (the exiting helper, state R): the daemon, found on the next walk once the
    helper is a zombie, is stopped and killed with the tree. (/proc is simulated: the race
    itself cannot be timed from a test.)"""
    keeper, helper, daemon = 10**9, 10**9 + 1, 10**9 + 2
    lists = [{helper}, {helper}]  # two walks with the daemon in flight, on neither list
    walked = []
    signals: dict[int, set[int]] = {}

    def walk(pid: int) -> set[int]:
        walked.append(pid)
        return lists[len(walked) - 1] if len(walked) <= len(lists) else {helper, daemon}

    def state(pid: int) -> str:  # the helper exits (R) until the daemon is moved; then a zombie
        return ("R" if len(walked) <= len(lists) else "Z") if pid == helper else "T"

    monkeypatch.setattr(process_tree, "descendants", walk)
    monkeypatch.setattr(process_tree, "_state", state)
    monkeypatch.setattr(process_tree, "_signal", lambda pids, number: signals.setdefault(number, set()).update(pids))
    process_tree.end_tree(keeper)
    assert signals[signal.SIGSTOP] == {helper, daemon}
    assert signals[signal.SIGKILL] == {keeper, helper, daemon}


def _ended(pid: int) -> bool:
    """True once `pid` has exited: gone, or a zombie (killed, waiting for init to reap it)."""
    try:
        return (Path(f"/proc/{pid}") / "stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def test_the_probe_ends_a_helper_its_binary_starts(shim_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mark = f"TOGGLE_TEST_MARK_{uuid.uuid4().hex}"
    monkeypatch.setenv("TOGGLE_FAULT_KIND", "daemon")
    monkeypatch.setenv("TOGGLE_FAULT_SLEEP", HELPER_SECONDS)
    monkeypatch.setenv(mark, "1")
    try:
        probe_binary(check_plant(shim_fmu))  # within PROBE_SECONDS, whatever the helper does
        wait_gone(mark)
    finally:
        for pid in marked(mark):
            os.kill(pid, 9)


@pytest.mark.slow
def test_a_library_shipped_beside_the_binary_is_found(plant_fmu: Path, tmp_path: Path) -> None:
    """The binary needs libtoggle_helper.so from its own folder (run path $ORIGIN): the probe
    loads it from the whole extracted platform folder, as the run does, and the run completes
    with the plant's trace."""
    fmu = make_faulty_fmu(plant_fmu, tmp_path / "WithLibrary.fmu", needs_library=True)
    plant = check_plant(fmu)
    probe_binary(plant)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(_scenario(tmp_path)), "--fmu", str(fmu), "--out", str(out)])
    assert result.exit_code == 0, result.output
    same = CliRunner().invoke(main, ["run", str(_scenario(tmp_path)), "--fmu", str(plant_fmu), "--out", str(out / "p")])
    assert same.exit_code == 0, same.output
    ours, theirs = (read_csv(folder / "faulty" / "hit" / "trace.csv").data for folder in (out, out / "p"))
    assert np.array_equal(ours, theirs)


def test_a_plant_that_changes_directory_does_not_move_the_output(shim_fmu: Path, tmp_path: Path) -> None:
    """Unsupervised (TOGGLE_COSIM_SUPERVISE=0: the plant runs in the command's own process), a
    plant that calls chdir in fmi2Instantiate: the relative --out still means the folder the
    command was started in."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {
        **fault_environment("chdir", T_FAULT, check_plant(shim_fmu).references),
        "TOGGLE_FAULT_DIR": str(elsewhere),
        "TOGGLE_COSIM_SUPERVISE": "0",
    }
    scenario = _scenario(tmp_path)
    command = [sys.executable, "-m", "toggle_cosim.cli", "run", scenario.name, "--fmu", str(shim_fmu), "--out", "out"]
    result = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert sorted(p.parent.name for p in (tmp_path / "out").glob("faulty/*/run.json")) == ["clean", "hit"]
    assert list(elsewhere.iterdir()) == []


def test_a_plant_failure_says_the_fmus_error_in_run_json_the_console_and_a_sweeps_table(
    shim_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every step from t = 0.1 s fails, the FMU logging a Zeno message as an error: run.json's
    reason, the console's line and a sweep's reason column name the status and the FMU's
    message, said once (the retry that failed the same way, and the sweep's captured log, do
    not repeat it)."""
    import pandas as pd
    from fault_plants import ZENO_LATER

    _arm(monkeypatch, shim_fmu, "zeno", TOGGLE_FAULT_END=repr(T_FAULT))
    said = f"fmi2DoStep failed with status 3 (error): {ZENO_LATER.format(T_FAULT)}"
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(_scenario(tmp_path)), "--fmu", str(shim_fmu), "--out", str(out)])
    assert result.exit_code == 1, result.output
    reason = json.loads((out / "faulty" / "hit" / "run.json").read_text())["reason"]
    assert reason.startswith(f"plant FMU failed at t = 0.1 s: {said}. Retried") and reason.count("Zeno") == 1
    assert f"FAILED ({reason}" in result.output
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        yaml.safe_dump({"base": "faulty.yaml", "variant": "clean", "axes": {"plant.F_E": {"values": [0, 60]}}})
    )
    result = CliRunner().invoke(main, ["sweep", str(sweep), "--fmu", str(shim_fmu), "--out", str(tmp_path / "sweep")])
    assert result.exit_code == 1, result.output
    table = pd.read_parquet(tmp_path / "sweep" / "results.parquet").set_index("plant.F_E")
    assert table.loc[60.0, "reason"] == reason and table.loc[0.0, "status"] == "ok"
