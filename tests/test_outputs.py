"""Outputs never harm what lies at their paths (`files.outputs`): a file is written to a unique
temporary name in its folder and renamed; a symbolic link, folder, FIFO or socket at the
destination is refused in one line and left as it was (the file a link points to is untouched);
character devices and /dev/stdout, /dev/stderr are written through, never replaced; no module
makes a temporary or lock name of its own; the sweep lock is a lock on the folder itself."""

from __future__ import annotations

import json
import os
import re
import socket
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from toggle_cosim.files.outputs import (
    FILE_MODE,
    OutputError,
    OutputKind,
    check_destination,
    fitting_name,
    folder_lock,
    replacing,
    write_file,
)
from toggle_cosim.files.traces import Trace, read_csv, write_csv, write_json

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src" / "toggle_cosim"


def _victim(tmp_path: Path) -> Path:
    """A file elsewhere that a planted link points to."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(exist_ok=True)
    victim = elsewhere / "precious.txt"
    victim.write_text("keep me\n")
    return victim


def _device(tmp_path: Path, name: str, minor: int) -> Path:
    """A character device of our own in tmp_path (1, minor: 3 null, 7 full), not the machine's."""
    path = tmp_path / name
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, minor))
        fd = os.open(path, os.O_WRONLY)
        os.close(fd)
    except OSError as error:
        pytest.skip(f"cannot make a character device here ({error.strerror})")
    return path


# ------------------------------------------------------------------------------- the helper

ANY = OutputKind("any file (these tests are not about the kind)", lambda path: True)


def test_a_new_file_is_written_whole_with_the_usual_mode_and_nothing_else(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "out.txt"
    write_file(target, lambda stream: stream.write("one\ntwo\n"), kind=ANY)
    assert target.read_text() == "one\ntwo\n"
    assert stat.S_IMODE(target.stat().st_mode) == FILE_MODE
    assert sorted(p.name for p in target.parent.iterdir()) == ["out.txt"]
    write_file(target, lambda stream: stream.write(b"\x00\x01"), binary=True, kind=ANY)  # replaces a regular file
    assert target.read_bytes() == b"\x00\x01"


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    target.write_text("old\n")

    def fail(stream):  # noqa: ANN001
        stream.write("half")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError):
        write_file(target, fail, kind=ANY)
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


@pytest.mark.parametrize("kind", ["link to a file", "dangling link", "link to a folder", "folder", "fifo", "socket"])
def test_a_destination_that_is_not_a_regular_file_is_refused_and_left_alone(tmp_path: Path, kind: str) -> None:
    victim = _victim(tmp_path)
    target = tmp_path / "out" / "junit.xml"
    target.parent.mkdir()
    if kind == "link to a file":
        target.symlink_to(victim)
    elif kind == "dangling link":
        target.symlink_to(tmp_path / "elsewhere" / "not-yet")
    elif kind == "link to a folder":
        target.symlink_to(victim.parent, target_is_directory=True)
    elif kind == "folder":
        target.mkdir()
    elif kind == "fifo":
        os.mkfifo(target)
    else:
        server = socket.socket(socket.AF_UNIX)
        server.bind(str(target))
        server.close()
    before = os.lstat(target)
    with pytest.raises(OutputError) as caught:
        write_file(target, lambda stream: stream.write("<xml/>"), what="JUnit report", kind=ANY)
    message = str(caught.value)
    assert message.startswith(f"{target}: is ") and "give another file name for the JUnit report" in message
    assert "\n" not in message
    after = os.lstat(target)
    assert (after.st_ino, stat.S_IFMT(after.st_mode)) == (before.st_ino, stat.S_IFMT(before.st_mode))
    assert victim.read_text() == "keep me\n"
    assert not (tmp_path / "elsewhere" / "not-yet").exists()
    assert sorted(p.name for p in target.parent.iterdir()) == ["junit.xml"]  # no temporary left


def test_character_devices_are_written_through_and_stay_devices(tmp_path: Path) -> None:
    null = _device(tmp_path, "null", 3)
    write_file(null, lambda stream: stream.write("discarded"), kind=ANY)
    assert stat.S_ISCHR(os.lstat(null).st_mode)
    full = _device(tmp_path, "full", 7)
    with pytest.raises(OutputError, match=r"full: cannot be written \(No space left on device\)"):
        write_file(full, lambda stream: stream.write("x" * 10), kind=ANY)
    assert stat.S_ISCHR(os.lstat(full).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full", "null"]


def test_a_link_to_a_device_is_refused_not_followed(tmp_path: Path) -> None:
    full = _device(tmp_path, "full", 7)
    link = tmp_path / "report.md"
    link.symlink_to(full)
    with pytest.raises(OutputError, match="symbolic link"):
        check_destination(link)
    assert link.is_symlink() and stat.S_ISCHR(os.lstat(full).st_mode)


def test_concurrent_writers_of_one_target_all_succeed(tmp_path: Path) -> None:
    """Unique temporary names: writers of the same file do not trip over each other's."""
    target = tmp_path / "figure.png"
    errors: list[BaseException] = []

    def writer(number: int) -> None:
        try:
            for _ in range(20):
                with replacing(target, kind=ANY) as temporary:
                    temporary.write_bytes(str(number).encode() * 1000)
                    time.sleep(0.001)
        except BaseException as error:  # noqa: BLE001
            errors.append(error)

    threads = [threading.Thread(target=writer, args=(n,)) for n in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    content = target.read_bytes()
    assert len(content) == 1000 and len(set(content)) == 1  # one writer's whole file
    assert [p.name for p in tmp_path.iterdir()] == ["figure.png"]


def test_the_folder_lock_is_exclusive_and_makes_no_file(tmp_path: Path) -> None:
    folder = tmp_path / "sweep"
    victim = _victim(tmp_path)
    folder.mkdir()
    (folder / ".lock").symlink_to(victim)  # what the old lock file would have truncated
    code = (
        "import sys; from toggle_cosim.files.outputs import folder_lock\n"
        "with folder_lock(sys.argv[1]) as locked: print(locked)"
    )
    with folder_lock(folder) as locked:
        assert locked
        other = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True, check=True)
        assert other.stdout.strip() == "False"
    other = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True, check=True)
    assert other.stdout.strip() == "True"
    assert victim.read_text() == "keep me\n"
    assert sorted(p.name for p in folder.iterdir()) == [".lock"]


def test_no_module_makes_a_temporary_or_lock_name_of_its_own() -> None:
    """Every temporary output name comes from `files.outputs` (mkstemp); a fixed name like
    `.x.partial` or `.lock` in a shared folder could be planted as a link."""
    found = []
    for path in SRC.rglob("*.py"):
        if path.name == "outputs.py" and path.parent.name == "files":
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            if "mkstemp(" in code or ".glob(" in code:  # a unique name's suffix; removing stale ones
                continue
            if re.search(r"""["'][^"']*\.(partial|lock)\b""", code) or 'with_name(f".{' in code:
                found.append(f"{path.relative_to(SRC)}:{number}: {line.strip()}")
    assert found == []


# ------------------------------------------------------------------------------- traces


def test_trace_values_read_back_bit_for_bit(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    bits = rng.integers(0, 2**64, size=(300, 6), dtype=np.uint64).view(np.float64)
    awkward = np.array([0.1, -0.0, 5e-324, 1.7976931348623157e308, np.inf, -np.inf, 2.0**-1074, 1 / 3, 1e16 + 2])
    data = np.vstack([bits[np.isfinite(bits).all(axis=1)], np.resize(awkward, (3, 6))])
    data[:, 0] = np.arange(data.shape[0], dtype=float)
    path = tmp_path / "trace.csv"
    write_csv(path, Trace(tuple(f"c{i}" for i in range(6)), data))
    back = read_csv(path)
    assert back.names == tuple(f"c{i}" for i in range(6))
    assert np.array_equal(back.data.view(np.uint64), data.view(np.uint64))


def test_record_every_keeps_every_nth_sample_and_the_last(tmp_path: Path) -> None:
    data = np.arange(23 * 2, dtype=float).reshape(23, 2) / 7
    write_csv(tmp_path / "t.csv", Trace(("time", "x"), data), every=5)
    assert np.array_equal(read_csv(tmp_path / "t.csv").data, data[[0, 5, 10, 15, 20, 22]])


# ------------------------------------------------------------------------------- the commands


def _trace_pair(tmp_path: Path) -> tuple[Path, Path]:
    t = np.linspace(0.0, 1.0, 201)
    trace = Trace(("time", "x"), np.column_stack([t, np.sin(t)]))
    write_csv(tmp_path / "result.csv", trace)
    write_csv(tmp_path / "reference.csv", trace)
    return tmp_path / "result.csv", tmp_path / "reference.csv"


@pytest.mark.parametrize("option", ["--junit", "--summary"])
def test_compare_refuses_a_report_path_that_is_a_link_and_leaves_its_target(tmp_path: Path, option: str) -> None:
    from toggle_cosim.cli import main

    result_csv, reference_csv = _trace_pair(tmp_path)
    victim = _victim(tmp_path)
    link = tmp_path / "report"
    link.symlink_to(victim)
    run = CliRunner().invoke(main, ["compare", str(result_csv), str(reference_csv), option, str(link)])
    assert run.exit_code == 2, run.output
    assert f"error: {link}: is a symbolic link, not a regular file (a link is not followed)" in run.output
    assert link.is_symlink() and victim.read_text() == "keep me\n"


def test_compare_junit_to_a_full_device_fails_in_one_line_and_the_device_stays(tmp_path: Path) -> None:
    from toggle_cosim.cli import main

    result_csv, reference_csv = _trace_pair(tmp_path)
    full = _device(tmp_path, "full", 7)  # like /dev/full, made here
    run = CliRunner().invoke(main, ["compare", str(result_csv), str(reference_csv), "--junit", str(full)])
    assert run.exit_code == 2, run.output
    assert f"error: {full}: cannot be written (No space left on device)" in run.output
    assert stat.S_ISCHR(os.lstat(full).st_mode)


def test_build_refuses_a_linked_fmu_output_before_compiling(tmp_path: Path) -> None:
    from toggle_cosim.cli import main

    victim = _victim(tmp_path)
    link = ROOT / "fmus" / f"link-{os.getpid()}.fmu"
    link.parent.mkdir(exist_ok=True)
    link.symlink_to(victim)
    try:
        run = CliRunner().invoke(main, ["build", "--model", "ToggleLSM.Plant", "--out", str(link)])
        assert run.exit_code == 2, run.output
        assert (
            "is a symbolic link, not a regular file (a link is not followed); give another file name for the FMU"
            in run.output
        )
        assert link.is_symlink() and victim.read_text() == "keep me\n"
    finally:
        link.unlink()


def test_compare_writes_its_junit_report_to_stdout_by_design(tmp_path: Path) -> None:
    result_csv, reference_csv = _trace_pair(tmp_path)
    listing = tmp_path / "stdout.txt"
    with open(listing, "w") as stdout:
        done = subprocess.run(
            [sys.executable, "-m", "toggle_cosim.cli", "compare", str(result_csv), str(reference_csv)]
            + ["--junit", "/dev/stdout"],
            stdout=stdout,
            stderr=subprocess.PIPE,
            text=True,
            check=False,
        )
    assert done.returncode == 0, done.stderr
    text = listing.read_text()
    assert "<testsuites" in text and "PASS" in text.split("<?xml")[0]  # the table before it is kept
    assert text.rstrip().endswith("junit: /dev/stdout")


def _results_folder(tmp_path: Path) -> Path:
    """A scenario's results folder as `run` writes it, enough for `plot`."""
    from toggle_cosim.plant.contract import OUTPUTS

    names = ("time", "x_B", "iq_ref", "lambda1", "lambda2", *(n for n in OUTPUTS if n[:1] == "N" or n[:2] == "Ff"))
    t = np.linspace(0.0, 0.1, 11)
    run = tmp_path / "results" / "case" / "friction"
    run.mkdir(parents=True)
    write_csv(run / "trace.csv", Trace(names, np.column_stack([t] + [np.cos(t + k) for k in range(len(names) - 1)])))
    record = {"scenario": "case", "description": "d", "resolved": {"stroke": {"x_target": 0.3}}}
    (run / "run.json").write_text(json.dumps(record))
    return run.parent


def test_plot_ignores_a_planted_partial_name_and_refuses_a_linked_output(tmp_path: Path) -> None:
    from toggle_cosim.cli import main

    folder = _results_folder(tmp_path)
    victim = _victim(tmp_path)
    (folder / ".figure.partial.png").symlink_to(victim)  # the fixed name plot used to write through
    run = CliRunner().invoke(main, ["plot", str(folder)])
    assert run.exit_code == 0, run.output
    assert (folder / "figure.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert victim.read_text() == "keep me\n"
    link = tmp_path / "linked.png"
    link.symlink_to(victim)
    run = CliRunner().invoke(main, ["plot", str(folder), "-o", str(link)])
    assert run.exit_code == 2 and run.output.count("\n") == 1, run.output
    assert victim.read_text() == "keep me\n" and link.is_symlink()


# ------------------------------------------------------------------------------- only an output's own kind is replaced


def _zip(path: Path, member: str) -> Path:
    import zipfile

    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr(member, "<x/>")
    return path


def _kinds_and_files(tmp_path: Path) -> dict[str, tuple[object, Path]]:
    """One file of each kind, as the project writes it."""
    from toggle_cosim.files import outputs

    png = tmp_path / "f.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 16)
    parquet = tmp_path / "t.parquet"
    parquet.write_bytes(b"PAR1" + b"\0" * 16 + b"PAR1")
    trace = tmp_path / "trace.csv"
    write_csv(trace, Trace(("time", "x_B"), np.zeros((2, 2))))
    record = tmp_path / "run.json"
    write_json(record, {"scenario": "x"})
    junit = tmp_path / "r.xml"
    junit.write_text('<?xml version="1.0"?>\n<testsuites><testsuite name="x"/></testsuites>\n')
    summary = tmp_path / "s.md"
    summary.write_text("# Results of the paper's runs\n\n| run | status |\n|---|---|\n")
    settings = tmp_path / "x_ref.opt"
    settings.write_text("StartTime, 0.0\nStopTime, 1.0\n")
    npz = tmp_path / "model.npz"
    with open(npz, "wb") as stream:
        np.savez(stream, A=np.eye(2))
    mat = tmp_path / "model.mat"
    mat.write_bytes(b"MATLAB 5.0 MAT-file, Platform: posix".ljust(128, b" "))
    invariants = tmp_path / "x_ref_invariants.yaml"
    invariants.write_text("# held within a tolerance\ninvariants:\n  a: {value: 1.0}\n")
    html = tmp_path / "report.html"
    html.write_text('<!DOCTYPE html>\n<html lang="en"><head></head></html>\n')
    return {
        "html": (outputs.HTML, html),
        "fmu": (outputs.FMU, _zip(tmp_path / "p.fmu", "modelDescription.xml")),
        "ssp": (outputs.SSP, _zip(tmp_path / "s.ssp", "SystemStructure.ssd")),
        "png": (outputs.PNG, png),
        "parquet": (outputs.PARQUET, parquet),
        "csv": (outputs.CSV, trace),
        "json": (outputs.JSON, record),
        "junit": (outputs.JUNIT, junit),
        "markdown": (outputs.MARKDOWN, summary),
        "settings": (outputs.SETTINGS, settings),
        "npz": (outputs.NPZ, npz),
        "mat": (outputs.MAT, mat),
        "invariants": (outputs.INVARIANTS, invariants),
    }


def test_each_kind_replaces_its_own_kind_and_no_other(tmp_path: Path) -> None:
    """A re-run replaces what it wrote (its own kind, told by content), and every other kind,
    a scenario file and notes are refused in one line naming the path and the kind; an empty
    file holds nothing and may be replaced."""
    files = _kinds_and_files(tmp_path)
    scenario = tmp_path / "myscen.yaml"
    scenario.write_text("name: x\nt_end: 1\n")
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes, do not lose\n")
    empty = tmp_path / "empty"
    empty.touch()
    for name, (kind, own) in files.items():
        check_destination(own, name, kind)  # its own kind: replaced
        check_destination(empty, name, kind)
        for other_name, (_, other) in files.items():
            if other_name == name:
                continue
            before = other.read_bytes()
            with pytest.raises(OutputError) as caught:
                check_destination(other, name, kind)
            assert str(caught.value) == (
                f"{other}: exists and is not {kind.name}, so it is not replaced; give another file name for the "
                f"{name} (or move the file away)"
            ), (name, other_name)
            assert other.read_bytes() == before
        for foreign in (scenario, notes):
            with pytest.raises(OutputError, match="exists and is not"):
                check_destination(foreign, name, kind)


def test_a_file_put_at_the_destination_while_writing_is_not_replaced(tmp_path: Path) -> None:
    from toggle_cosim.files.outputs import PNG

    target = tmp_path / "figure.png"
    with pytest.raises(OutputError, match="exists and is not a PNG image"):
        with replacing(target, "figure", kind=PNG) as temporary:
            temporary.write_bytes(b"\x89PNG\r\n\x1a\nnew")
            target.write_text("notes written meanwhile\n")
    assert target.read_text() == "notes written meanwhile\n"
    assert [p.name for p in tmp_path.iterdir()] == ["figure.png"]  # no temporary left


@pytest.mark.parametrize("victim", ["myscen.yaml", "plant.fmu", "notes.txt"])
def test_ssp_refuses_to_write_over_a_file_that_is_not_an_ssp(tmp_path: Path, victim: str) -> None:
    """`ssp SCENARIO --out SCENARIO` used to replace the scenario with the archive."""
    from toggle_cosim.cli import main

    scenario = tmp_path / "myscen.yaml"
    scenario.write_text((ROOT / "scenarios" / "fig4_nominal.yaml").read_text(encoding="utf-8"))
    target = tmp_path / victim
    if victim == "plant.fmu":
        _zip(target, "modelDescription.xml")
    elif victim == "notes.txt":
        target.write_text("notes\n")
    before = target.read_bytes()
    run = CliRunner().invoke(main, ["ssp", str(scenario), "--out", str(target)])
    assert run.exit_code == 2, run.output
    assert run.output == (
        f"error: {target}: exists and is not an SSP (a zip archive with a SystemStructure.ssd), so it is not "
        "replaced; give another file name for the SSP (--out) (or move the file away)\n"
    )
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"myscen.yaml", victim})


@pytest.mark.parametrize(
    ("command", "option"),
    [("compare", "--junit"), ("compare", "--summary"), ("references", "--junit"), ("references", "--summary")],
)
def test_reports_refuse_to_write_over_notes(tmp_path: Path, command: str, option: str) -> None:
    from toggle_cosim.cli import main

    result_csv, reference_csv = _trace_pair(tmp_path)
    notes = tmp_path / "notes.txt"
    notes.write_text("notes\n")
    arguments = (
        [str(result_csv), str(reference_csv)]
        if command == "compare"
        else [str(ROOT / "scenarios" / "fig4_nominal.yaml"), "--out", str(tmp_path / "reports")]
    )
    run = CliRunner().invoke(main, [command, *arguments, option, str(notes)])
    assert run.exit_code == 2, run.output
    assert f"{notes}: exists and is not a " in run.output and run.output.count("\n") == 1, run.output
    assert notes.read_text() == "notes\n"
    assert not (tmp_path / "reports").exists()


@pytest.mark.slow
def test_plot_refuses_to_write_over_notes_and_replaces_its_own_figure(tmp_path: Path) -> None:
    from toggle_cosim.cli import main

    folder = _results_folder(tmp_path)
    notes = tmp_path / "notes.txt"
    notes.write_text("notes\n")
    run = CliRunner().invoke(main, ["plot", str(folder), "-o", str(notes)])
    assert run.exit_code == 2 and "exists and is not a PNG image" in run.output, run.output
    assert notes.read_text() == "notes\n"
    for _ in range(2):  # the second run replaces the figure the first wrote
        run = CliRunner().invoke(main, ["plot", str(folder), "-o", str(tmp_path / "fig.png")])
        assert run.exit_code == 0, run.output


def test_a_long_name_is_cut_with_a_hash_of_the_whole_and_a_short_one_is_kept() -> None:
    assert fitting_name("heatmap_plant.mu=0.2", ".png") == "heatmap_plant.mu=0.2.png"
    long_a, long_b = "x" * 300 + "a", "x" * 300 + "b"
    named_a, named_b = fitting_name(long_a, ".png"), fitting_name(long_b, ".png")
    assert len(named_a.encode()) == 255 and named_a.endswith(".png") and named_a.startswith("x" * 200)
    assert named_a != named_b and named_a == fitting_name(long_a, ".png")
    assert len(fitting_name("é" * 200, ".png").encode()) <= 255  # never half a character
    fitting_name("é" * 200, ".png").encode().decode("utf-8")
