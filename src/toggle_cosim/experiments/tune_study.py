"""A tuning's study (OUTPUT/study.db, Optuna's SQLite storage), opened only when it is this
tuning's own: Optuna writes its tables into whatever database lies at the path, so the file is
checked first, and a study of another tuning is refused, not added to.

Refused, each with one line naming the path and the fix (`TuneError`; exit 2 from the command),
before Optuna opens anything:

* at OUTPUT/study.db, anything that is not a regular file: a symbolic link (never followed,
  wherever it leads), a folder, a FIFO, a socket, a device (`files.outputs.check_destination`);
* a file that is not an SQLite database (its first 16 bytes are not "SQLite format 3\\0"), or
  one SQLite cannot read (damaged: `PRAGMA quick_check`);
* an SQLite database that is not an Optuna study (other tables), or that holds the study of
  another tuning: a study of another name, or of this name made with other cases, tuned keys,
  bounds, objectives or constraints (`fingerprint`, kept in the study's user attributes);
* a folder whose tune.json was written by another tuning (its name or fingerprint differ).

An empty file or no file is a new study. The file is opened without following a link and held
open while Optuna opens the path; afterwards the path must still be that same file.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import sqlite3
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import quote

from toggle_cosim.experiments.tune_spec import TuneError, Tuning
from toggle_cosim.files.outputs import SQLITE, OutputError, check_destination

STUDY_FILE = "study.db"
MANIFEST_FILE = "tune.json"
FINGERPRINT_ATTR = "tuning"  # the study's user attribute that holds the tuning's fingerprint
OPTUNA_TABLES = frozenset({"studies", "study_user_attributes", "trials", "version_info"})
_FIX = "choose another --out (or delete the folder)"


def fingerprint(tuning: Tuning) -> str:
    """What a study's trials mean: the map's cases, the tuned keys and bounds, objectives, constraints."""
    content = {
        "cases": [c.case_id for c in tuning.cases],
        "parameters": [[p.key, p.low, p.high, p.log] for p in tuning.parameters],
        "objectives": [o.label for o in tuning.objectives],
        "constraints": tuning.constraints.__dict__,
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def _another(path: Path, what: str) -> TuneError:
    return TuneError(f"{path}: holds {what}; {_FIX}")


def _other_study(path: Path) -> TuneError:
    return _another(
        path,
        "a study of another tuning (its map, parameters, bounds, objectives or constraints differ)",
    )


def check_manifest(tuning: Tuning, output: Path) -> None:
    """TuneError if OUTPUT/tune.json says another tuning wrote the folder (another name or
    fingerprint). A missing or unreadable tune.json says nothing (it is replaced at the end, if
    it is a JSON file: `files.outputs`)."""
    from toggle_cosim.files.bounded import JSON_LIMIT, InputFileError, read_text_bounded

    path = output / MANIFEST_FILE
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return
        manifest = json.loads(read_text_bounded(path, JSON_LIMIT, "tuning manifest"))
    except (OSError, InputFileError, ValueError):
        return
    if not isinstance(manifest, dict):
        return
    name, mark = manifest.get("tuning"), manifest.get("fingerprint")
    if name is not None and name != tuning.name:
        raise TuneError(f"{path}: the folder holds the files of another tuning ({name!r}); {_FIX}")
    if mark is not None and mark != fingerprint(tuning):
        raise TuneError(
            f"{path}: the folder holds the files of another tuning (its map, parameters, bounds, objectives or"
            f" constraints differ); {_FIX}"
        )


def _study_problem(path: Path, tuning: Tuning) -> TuneError | None:
    """What keeps the SQLite database at `path` from being this tuning's study (no tables at all:
    a new study). It is only read; opened read-write (never created) so that SQLite may roll
    back the journal of a tuning killed while it wrote, as Optuna would."""
    uri = f"file:{quote(str(path))}?mode=rw"
    try:
        connection = sqlite3.connect(uri, uri=True)
    except sqlite3.Error as error:
        return TuneError(f"{path}: cannot be opened as an SQLite database ({error}); {_FIX}")
    try:
        check = connection.execute("PRAGMA quick_check").fetchone()
        if not check or check[0] != "ok":
            return TuneError(f"{path}: is a damaged SQLite database ({check[0] if check else 'no answer'}); {_FIX}")
        tables = {row[0] for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if not tables:
            return None
        if not OPTUNA_TABLES <= tables:
            shown = ", ".join(sorted(tables)[:5]) + (", ..." if len(tables) > 5 else "")
            return TuneError(f"{path}: is an SQLite database but not a tuning's study (its tables: {shown}); {_FIX}")
        names = [row[0] for row in connection.execute("SELECT study_name FROM studies ORDER BY study_id")]
        others = [name for name in names if name != tuning.name]
        if others:
            return _another(path, f"the study of another tuning ({others[0]!r})")
        marks = connection.execute(
            "SELECT a.value_json FROM study_user_attributes a JOIN studies s ON a.study_id = s.study_id"
            " WHERE s.study_name = ? AND a.key = ?",
            (tuning.name, FINGERPRINT_ATTR),
        ).fetchall()
        if any(json.loads(value) != fingerprint(tuning) for (value,) in marks):
            return _other_study(path)
        return None
    except (sqlite3.Error, ValueError) as error:
        return TuneError(f"{path}: is not a readable SQLite database ({' '.join(str(error).split())}); {_FIX}")
    finally:
        connection.close()


def _flags() -> int:
    return os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | os.O_CLOEXEC


@contextlib.contextmanager
def _held(path: Path) -> Iterator[os.stat_result]:
    """The regular file at `path` (created empty if missing), opened without following a link and
    held open (its inode cannot be reused meanwhile): yields its fstat."""
    try:
        fd = os.open(path, _flags(), 0o666)
    except OSError as error:
        problem = "is a symbolic link (a link is not followed)" if error.errno == errno.ELOOP else error.strerror
        raise TuneError(f"{path}: cannot be opened as the tuning's study ({problem}); {_FIX}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise TuneError(f"{path}: is not a regular file; {_FIX}")
        yield info
    finally:
        os.close(fd)


def _same_file(path: Path, held: os.stat_result) -> bool:
    try:
        now = os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(now.st_mode) and (now.st_dev, now.st_ino) == (held.st_dev, held.st_ino)


def open_study(tuning: Tuning, output: Path) -> Any:
    """The tuning's Optuna study in OUTPUT/study.db (created, or resumed when it is this
    tuning's): TuneError, before anything is written, for anything else (the module docstring)."""
    path = output / STUDY_FILE
    try:
        check_destination(path, "tuning's study", SQLITE, through=False, fix=_FIX)
    except OutputError as error:
        raise TuneError(str(error)) from None
    check_manifest(tuning, output)
    with _held(path) as held:
        if held.st_size > 0:
            problem = _study_problem(path, tuning)
            if problem is not None:
                raise problem
        study = _optuna_study(tuning, path)
        if not _same_file(path, held):
            raise TuneError(f"{path}: was replaced while it was opened (a link is not followed); {_FIX}")
    mark = study.user_attrs.get(FINGERPRINT_ATTR)
    if mark is None:
        study.set_user_attr(FINGERPRINT_ATTR, fingerprint(tuning))
    elif mark != fingerprint(tuning):  # checked above already; kept for a study changed meanwhile
        raise _other_study(path)
    return study


def _optuna_study(tuning: Tuning, path: Path) -> Any:
    import optuna
    import sqlalchemy.exc

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        return optuna.create_study(
            storage=f"sqlite:///{path.resolve()}",
            study_name=tuning.name,
            directions=["minimize"] * len(tuning.objectives),
            load_if_exists=True,
        )
    except (sqlalchemy.exc.SQLAlchemyError, sqlite3.Error, RuntimeError, ValueError) as error:
        # a schema of another Optuna version (RuntimeError), a study with other directions (ValueError)
        detail = " ".join(str(error).split())[:300]
        raise TuneError(f"{path}: cannot be opened as the tuning's study ({detail}); {_FIX}") from None


__all__ = ["MANIFEST_FILE", "STUDY_FILE", "check_manifest", "fingerprint", "open_study"]
