"""A tuning's study (OUTPUT/study.db) is opened only when it is this tuning's own: a link (to an
application's database, a text file, a folder), a FIFO, a file that is not an SQLite database, a
damaged one, a database that is not a study, and the study of another tuning are each refused
in one line (exit 2) before Optuna opens anything, and left exactly as they were. These refusals
come before any case runs, so no plant is needed."""

from __future__ import annotations

import json
import os
import sqlite3
from pathlib import Path

import optuna
import pytest
from click.testing import CliRunner
from test_tune import write_tuning

from toggle_cosim.cli import main

SQLITE_HEADER = b"SQLite format 3\x00"  # the first 16 bytes of every SQLite 3 database


def _tune(path: Path, out: Path) -> tuple[int, list[str]]:
    done = CliRunner().invoke(main, ["tune", str(path), "--out", str(out), "-q"])
    return done.exit_code, done.output.strip().splitlines()


def _snapshot(folder: Path) -> dict[str, tuple[str, bytes | str | None]]:
    """What lies in `folder`, without following links: each name's kind and content."""
    seen = {}
    for entry in sorted(os.scandir(folder), key=lambda e: e.name):
        if entry.is_symlink():
            seen[entry.name] = ("link", os.readlink(entry.path))
        elif entry.is_dir(follow_symlinks=False):
            seen[entry.name] = ("folder", None)
        elif entry.is_file(follow_symlinks=False):
            seen[entry.name] = ("file", Path(entry.path).read_bytes())
        else:
            seen[entry.name] = ("other", None)
    return seen


def _application_db(path: Path) -> Path:
    connection = sqlite3.connect(path)
    connection.execute("CREATE TABLE accounts (id INTEGER PRIMARY KEY, owner TEXT)")
    connection.execute("INSERT INTO accounts (owner) VALUES ('someone')")
    connection.commit()
    connection.close()
    return path


def _refused(tmp_path: Path) -> tuple[Path, Path]:
    """A tuning file and its output folder (made, empty)."""
    path = write_tuning(tmp_path / "files")
    out = tmp_path / "out"
    out.mkdir()
    return path, out


def _assert_one_line_refusal(code: int, lines: list[str], study: Path, words: str) -> None:
    assert code == 2, lines
    assert len(lines) == 1 and lines[0].startswith(f"error: {study}: "), lines
    assert words in lines[0] and "--out" in lines[0], lines


@pytest.mark.parametrize("target", ["application database", "text file", "folder"])
def test_a_link_at_study_db_is_refused_and_what_it_points_to_is_untouched(tmp_path: Path, target: str) -> None:
    path, out = _refused(tmp_path)
    victim = tmp_path / "victim"
    if target == "application database":
        _application_db(victim)
    elif target == "text file":
        victim.write_text("notes\n", encoding="utf-8")
    else:
        victim.mkdir()
    before = victim.read_bytes() if victim.is_file() else None
    (out / "study.db").symlink_to(victim)
    listing = _snapshot(out)
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "study.db", "symbolic link")
    assert _snapshot(out) == listing
    if before is not None:
        assert victim.read_bytes() == before
    else:
        assert list(victim.iterdir()) == []


def test_a_fifo_at_study_db_is_refused_without_waiting_on_it(tmp_path: Path) -> None:
    path, out = _refused(tmp_path)
    os.mkfifo(out / "study.db")
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "study.db", "is a FIFO")
    assert _snapshot(out) == {"study.db": ("other", None)}


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (b"my notes, not a database\n", "is not an SQLite database"),
        (SQLITE_HEADER + b"\xff" * 2000, "is not a readable SQLite database"),  # the header, then garbage
    ],
)
def test_a_file_that_is_not_a_readable_sqlite_database_is_refused_and_kept(
    tmp_path: Path, content: bytes, words: str
) -> None:
    path, out = _refused(tmp_path)
    (out / "study.db").write_bytes(content)
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "study.db", words)
    assert _snapshot(out) == {"study.db": ("file", content)}


def test_an_sqlite_database_that_is_not_a_study_is_refused_and_kept(tmp_path: Path) -> None:
    path, out = _refused(tmp_path)
    _application_db(out / "study.db")
    listing = _snapshot(out)
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "study.db", "not a tuning's study (its tables: accounts)")
    assert _snapshot(out) == listing


def test_the_study_of_another_tuning_is_refused_and_not_added_to(tmp_path: Path) -> None:
    """OUT/study.db holds the study a tuning named 'other' made: the tuning 'tiny' is refused,
    and the database still holds that one study only."""
    path, out = _refused(tmp_path)
    storage = f"sqlite:///{out / 'study.db'}"
    optuna.create_study(storage=storage, study_name="other").set_user_attr("tuning", "0123456789abcdef")
    listing = _snapshot(out)
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "study.db", "the study of another tuning ('other')")
    assert _snapshot(out) == listing
    assert optuna.study.get_all_study_names(storage) == ["other"]


def test_a_folder_whose_tune_json_is_another_tunings_is_refused(tmp_path: Path) -> None:
    """No study.db (deleted), but tune.json says the tuning 'other' wrote the folder."""
    path, out = _refused(tmp_path)
    (out / "tune.json").write_text(json.dumps({"tuning": "other", "fingerprint": "0"}), encoding="utf-8")
    listing = _snapshot(out)
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "tune.json", "another tuning ('other')")
    assert _snapshot(out) == listing


def test_a_file_the_tuning_writes_at_its_end_that_cannot_be_written_is_refused_first(tmp_path: Path) -> None:
    """A folder where maps.png goes: refused before any case runs (not after every trial)."""
    path, out = _refused(tmp_path)
    (out / "maps.png").mkdir()
    code, lines = _tune(path, out)
    _assert_one_line_refusal(code, lines, out / "maps.png", "is a folder")
    assert _snapshot(out) == {"maps.png": ("folder", None)}
