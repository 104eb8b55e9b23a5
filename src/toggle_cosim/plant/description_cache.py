"""fmpy's parsed modelDescription of an FMU, kept between commands.

fmpy parses a modelDescription.xml with lxml into its own objects: about 30 ms for our plant's
200 variables (lxml's import included), on every command that checks the plant, for a file that
rarely changes. The parsed object is kept in the cache of compiled helpers (`native.cache_folders`)
under the SHA-256 of the whole FMU file (which the contract check computes once, for the run
records too), fmpy's version and Python's; any change to the FMU makes a new key, and an entry
that cannot be read is parsed again. Reading one back costs about 4 ms.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import sys
import tempfile
from pathlib import Path
from typing import Any

FORMAT = 1  # raise when what is stored changes


def _key(sha256: str, fmpy_version: str) -> str:
    return hashlib.sha256(f"{sha256}\0{fmpy_version}\0{sys.version}\0{FORMAT}".encode()).hexdigest()[:32]


def read_description(path: Path, sha256: str) -> Any:
    """fmpy.read_model_description(path, validate=False) for the FMU file whose SHA-256 is
    `sha256`, from the cache when it was parsed before. Raises what fmpy raises for a description
    it cannot read."""
    import fmpy

    from toggle_cosim.native import cache_folders

    name = f"model-description-{_key(sha256, fmpy.__version__)}.pickle"
    for folder in cache_folders():
        try:
            with open(folder / name, "rb") as stream:
                return pickle.load(stream)
        except Exception:  # noqa: BLE001, S110 - missing, unreadable or stale: parse it
            continue
    description = fmpy.read_model_description(str(path), validate=False)
    _store(name, description)
    return description


def _store(name: str, description: Any) -> None:
    """Write the entry atomically into the first cache folder that takes it; nothing if none does."""
    from toggle_cosim.native import cache_folders

    try:
        data = pickle.dumps(description, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # noqa: BLE001 - an object fmpy made that does not pickle: no entry
        return
    for folder in cache_folders():
        try:
            folder.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(dir=folder, prefix=f".{name}.")
            with os.fdopen(handle, "wb") as stream:
                stream.write(data)
            os.replace(temporary, folder / name)
            return
        except OSError:
            continue


__all__ = ["read_description"]
