"""Checks before work: the recorded size, the output folder and the plant settings; the trace's
recording interval and the file modes of what is written."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from fault_plants import fault_environment

from toggle_cosim.cli import main
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
BASE = {
    "name": "small",
    "t_end": 0.2,
    "T_s": 0.0005,
    "stroke": {"x_start": 0.2329, "x_target": 0.3199},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
}


def _scenario(folder: Path, **changes) -> Path:
    document = {**BASE, **changes}
    path = folder / "s.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


def _bad_input(args: list[str]) -> str:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_a_run_too_big_to_record_is_refused_before_it_starts(tmp_path: Path, plant_fmu: Path) -> None:
    """t_end = 100 s at T_s = 1 us: 1e8 samples of 35 columns, about 84 GB of CSV."""
    out = tmp_path / "out"
    line = _bad_input(
        ["run", str(_scenario(tmp_path, t_end=100, T_s=1e-6)), "--fmu", str(plant_fmu), "--out", str(out)]
    )
    assert "100000000 steps x 35 columns" in line and "GB" in line and "2.00 GB output limit" in line
    assert "raise T_s" in line and not out.exists()


@pytest.mark.parametrize("case", ["file", "long", "nested-file"])
def test_unusable_output_folders_are_refused_before_any_run(tmp_path: Path, plant_fmu: Path, case: str) -> None:
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    out = {"file": blocker, "long": tmp_path / ("a" * 300), "nested-file": blocker / "sub"}[case]
    line = _bad_input(["run", str(_scenario(tmp_path)), "--fmu", str(plant_fmu), "--out", str(out)])
    assert {
        "file": "is an existing file",
        "long": "longer than the file system allows",
        "nested-file": "is an existing file",
    }[case] in line


@pytest.mark.parametrize(
    ("parameters", "needle"),
    [
        ({"no_such_thing": 1.0}, "has no variable 'no_such_thing'"),
        ({"solver.relTol": True}, "write a number"),
        ({"x_B": 0.3}, "not a parameter"),
    ],
)
def testplant_settings_are_checked_before_any_run(
    tmp_path: Path, plant_fmu: Path, parameters: dict, needle: str
) -> None:
    out = tmp_path / "out"
    plant = {**BASE["plant"], "parameters": parameters}
    line = _bad_input(["run", str(_scenario(tmp_path, plant=plant)), "--fmu", str(plant_fmu), "--out", str(out)])
    assert needle in line and not out.exists()


def test_record_every_thins_the_csv_and_keeps_the_last_sample(tmp_path: Path, plant_fmu: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["run", str(_scenario(tmp_path, record_every=7)), "--fmu", str(plant_fmu), "--out", str(out), "-q"]
    )
    assert result.exit_code == 0, result.output
    trace = read_csv(out / "small" / "run" / "trace.csv")
    record = json.loads((out / "small" / "run" / "run.json").read_text())
    assert record["samples"] == 401  # every sample ran and counts for the summary
    assert trace.data.shape[0] == len(range(0, 401, 7)) + 1  # 0, 7, ..., 399, and 400
    assert trace.time[-1] == pytest.approx(0.2) and trace.time[1] == pytest.approx(7 * 0.0005)


def test_written_files_follow_the_umask(tmp_path: Path, plant_fmu: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["run", str(_scenario(tmp_path)), "--fmu", str(plant_fmu), "--out", str(out), "-q"]
    )
    assert result.exit_code == 0, result.output
    mask = os.umask(0)
    os.umask(mask)
    for name in ("trace.csv", "run.json"):
        mode = stat.S_IMODE((out / "small" / "run" / name).stat().st_mode)
        assert mode == 0o666 & ~mask, (name, oct(mode))


def test_the_time_limit_key_ends_a_run_that_cannot_finish_as_failed_with_a_partial_summary(
    tmp_path: Path, shim_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The plant holds in fmi2DoStep from t = 0.05 s for good (the fault shim's hold, never
    released): time_limit: 1 stops the run, whatever the machine's speed, with the samples up
    to where it held (101 at most). The samples it recorded have their figures of merit, marked
    as a partial run's."""
    hold = fault_environment("", 0.05, check_plant(shim_fmu).references, hold=tmp_path / "never")
    for key, value in hold.items():
        monkeypatch.setenv(key, value)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["run", str(_scenario(tmp_path, time_limit=1)), "--fmu", str(shim_fmu), "--out", str(out), "-q"]
    )
    assert result.exit_code == 1, result.output
    record = json.loads((out / "small" / "run" / "run.json").read_text())
    assert record["status"] == "failed" and record["reason"].startswith("time limit 1 s exceeded at t = ")
    trace = read_csv(out / "small" / "run" / "trace.csv")
    assert 2 <= trace.data.shape[0] == record["samples"] <= 101
    assert record["summary"]["final_error_m"] == pytest.approx(0.3199 - trace.column("x_B")[-1])
    assert record["summary"]["peak_iq_ref_A"] == pytest.approx(abs(trace.column("iq_ref")).max())
    assert record["summary_partial"] is True


@pytest.mark.parametrize("binary", ["script", "no-symbols"])
def test_a_plant_binary_that_cannot_serve_is_bad_input(tmp_path: Path, plant_fmu: Path, binary: str) -> None:
    """A shell script as the binary, or a library without the fmi2 functions: one line, exit 2,
    nothing written (the binary is loaded in a throw-away child before any run)."""
    import shutil
    import subprocess
    import zipfile

    if binary == "script":
        data = b"#!/bin/sh\necho plant\n"
    else:
        compiler = shutil.which("cc") or shutil.which("gcc")
        if compiler is None:
            pytest.skip("no C compiler")
        (tmp_path / "empty.c").write_text("int not_an_fmu(void) { return 0; }\n")
        subprocess.run(
            [compiler, "-shared", "-fPIC", "-o", str(tmp_path / "empty.so"), str(tmp_path / "empty.c")], check=True
        )
        data = (tmp_path / "empty.so").read_bytes()
    fmu = tmp_path / "bad.fmu"
    with zipfile.ZipFile(plant_fmu) as source, zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as target:
        for info in source.infolist():
            is_binary = info.filename.startswith("binaries/linux64/")
            target.writestr(info.filename, data if is_binary else source.read(info))
    out = tmp_path / "out"
    line = _bad_input(["run", str(_scenario(tmp_path)), "--fmu", str(fmu), "--out", str(out)])
    assert ("cannot be loaded" if binary == "script" else "lacks fmi2Instantiate") in line and not out.exists()


@pytest.mark.parametrize("case", ["dangling", "loop", "dangling-parent"])
def test_output_folder_symlinks_that_lead_nowhere_are_refused_before_any_run(
    tmp_path: Path, plant_fmu: Path, case: str
) -> None:
    (tmp_path / "dangling").symlink_to(tmp_path / "nowhere")
    (tmp_path / "loop_a").symlink_to(tmp_path / "loop_b")
    (tmp_path / "loop_b").symlink_to(tmp_path / "loop_a")
    out = {"dangling": "dangling", "loop": "loop_a", "dangling-parent": "dangling/sub"}[case]
    line = _bad_input(["run", str(_scenario(tmp_path)), "--fmu", str(plant_fmu), "--out", str(tmp_path / out)])
    assert ("in a loop" if case == "loop" else "which does not exist") in line
    assert not (tmp_path / "nowhere").exists()


def test_two_scenario_files_with_one_name_are_refused_naming_both(tmp_path: Path, plant_fmu: Path) -> None:
    first = _scenario(tmp_path)
    (tmp_path / "other").mkdir()
    second = _scenario(tmp_path / "other", t_end=0.1)
    out = tmp_path / "out"
    line = _bad_input(["run", str(first), str(second), "--fmu", str(plant_fmu), "--out", str(out)])
    assert str(first) in line and str(second) in line and "'small'" in line and not out.exists()
    assert "given twice" in _bad_input(["run", str(first), str(first), "--fmu", str(plant_fmu), "--out", str(out)])


def _variants(folder: Path, count: int) -> Path:
    variants = {f"v{k:03d}": {"plant": {"F_E": float(k)}} for k in range(count)}
    return _scenario(folder, t_end=0.01, variants=variants)


@pytest.mark.slow
def test_finished_runs_hold_no_descriptor(tmp_path: Path, plant_fmu: Path) -> None:
    """Under `ulimit -n 20` a run of 40 variants writes all 40 (each finished run releases its
    trace buffer's descriptor) and leaves no run folder in TMPDIR."""
    import resource
    import subprocess
    import sys

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    out = tmp_path / "out"
    command = [sys.executable, "-m", "toggle_cosim.cli", "run", str(_variants(tmp_path, 40)), "--fmu", str(plant_fmu)]
    result = subprocess.run(
        [*command, "--out", str(out), "-q"],
        env={**os.environ, "TMPDIR": str(scratch)},
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_NOFILE, (20, 20)),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert len(list(out.glob("small/*/run.json"))) == 40
    assert list(scratch.iterdir()) == []


def test_a_run_without_scratch_space_fails_alone(
    tmp_path: Path, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The second run's trace buffer cannot get its blocks (ENOSPC): that run fails, naming the
    folder; the others complete; nothing is left in the scratch folder."""
    import errno
    import tempfile

    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    calls = []
    original = os.posix_fallocate

    def fallocate(fd: int, offset: int, length: int) -> None:
        calls.append(length)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        original(fd, offset, length)

    monkeypatch.setattr(os, "posix_fallocate", fallocate)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["run", str(_variants(tmp_path, 3)), "--fmu", str(plant_fmu), "--out", str(out), "-j", "1"]
    )
    assert result.exit_code == 1, result.output
    records = {p.parent.name: json.loads(p.read_text()) for p in out.glob("small/*/run.json")}
    assert [records[v]["status"] for v in ("v000", "v001", "v002")] == ["complete", "failed", "complete"]
    assert f"no scratch space for the run's trace buffer in {scratch}" in records["v001"]["reason"]
    assert list(scratch.iterdir()) == []


def _fill_the_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    """fsync of every file being written (a temporary `.partial` name) fails with ENOSPC."""
    import errno

    original = os.fsync

    def fsync(fd: int) -> None:
        if os.readlink(f"/proc/self/fd/{fd}").endswith(".partial"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        original(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def test_a_full_disk_names_the_file_it_could_not_write(
    tmp_path: Path, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """fsync of trace.csv fails with ENOSPC (as on a full disk): one line naming that file."""
    _fill_the_disk(monkeypatch)
    out = tmp_path / "out"
    line = _bad_input(["run", str(_scenario(tmp_path)), "--fmu", str(plant_fmu), "--out", str(out), "-j", "1"])
    assert f"{out / 'small' / 'run' / 'trace.csv'}: No space left on device" in line


def test_a_full_scratch_file_system_fails_runs_alone(tmp_path: Path, plant_fmu: Path) -> None:
    """A real 192 KiB tmpfs as TMPDIR (where this test may mount one): too small to unzip the
    FMU. No SIGBUS and no traceback: each run fails alone with a reason naming the folder in
    which it found no space, and nothing is left there."""
    import subprocess
    import sys

    small = tmp_path / "small"
    small.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=192k", "tmpfs", str(small)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        out = tmp_path / "out"
        command = [sys.executable, "-m", "toggle_cosim.cli", "run", str(_variants(tmp_path, 6))]
        result = subprocess.run(
            [*command, "--fmu", str(plant_fmu), "--out", str(out), "-q"],
            env={**os.environ, "TMPDIR": str(small)},
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert result.returncode == 1, result.stderr
        assert "Traceback" not in result.stderr
        records = [json.loads(p.read_text()) for p in out.glob("small/*/run.json")]
        assert len(records) == 6 and all(r["status"] == "failed" for r in records)
        assert all("No space left on device" in r["reason"] and str(small) in r["reason"] for r in records)
        assert list(small.iterdir()) == []
    finally:
        subprocess.run(["umount", str(small)], check=False)


def test_a_full_disk_in_a_sweep_names_the_table_it_could_not_write(
    tmp_path: Path, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _scenario(tmp_path, t_end=0.02)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": "s.yaml", "axes": {"plant.F_E": {"values": [0.0, 5.0]}}}))
    _fill_the_disk(monkeypatch)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        main, ["sweep", str(sweep), "--fmu", str(plant_fmu), "--out", str(out), "--workers", "1", "-q"]
    )
    assert result.exit_code == 2, result.output
    line = result.output.strip().splitlines()[-1]  # after the sweep's own header line
    assert line.startswith(f"error: {out}") and ".parquet: No space left on device" in line, result.output
    assert "Traceback" not in result.output
