"""An FMU unzipped once per process, however many components use it (`unzipped`).

A system may hold one FMU file many times (40 sensors of one model, in an SSP or a scenario's
`components:`). Each instance needs the FMU's files on disk, but not a copy of its own: the
instances of an FMU share its binary and resources (FMI 2.0, 2.0.3 and FMI 3.0: an FMU that may
be instantiated several times in one process does so from one loaded library). So the first
instance unzips the FMU (keyed by its SHA-256, the hash its check computed), the next ones use
that folder, and the last one to let go removes it: temporary disk for one copy, not N.

An FMU that says it can be instantiated only once per process
(`canBeInstantiatedOnlyOncePerProcess`) is unzipped for each instance as before: a second copy
of its library, loaded from another path, is what lets two of its instances run in one process.
A forked child never uses (or removes) a folder of its parent's.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmpy import extract

__all__ = ["release", "unzipped"]


@dataclass
class _Shared:
    folder: Path
    users: int
    pid: int


_SHARED: dict[str, _Shared] = {}  # by the FMU file's SHA-256


def _once_per_process(description: Any) -> bool:
    interface = getattr(description, "coSimulation", None)
    return bool(getattr(interface, "canBeInstantiatedOnlyOncePerProcess", False))


def unzipped(path: Path, sha256: str, description: Any) -> Path:
    """The folder of the FMU at `path` unzipped (its SHA-256 `sha256`, its model description
    `description`), shared with the other instances of that FMU in this process where it allows
    it; give it back with `release`."""
    if _once_per_process(description):
        return Path(extract(str(path)))
    shared = _SHARED.get(sha256)
    if shared is None or shared.pid != os.getpid() or not shared.folder.is_dir():
        shared = _SHARED[sha256] = _Shared(Path(extract(str(path))), 0, os.getpid())
    shared.users += 1
    return shared.folder


def release(folder: Path) -> None:
    """One user less of `folder` (from `unzipped`): removed when no instance uses it any more."""
    for sha256, shared in list(_SHARED.items()):
        if shared.folder == folder and shared.pid == os.getpid():
            shared.users -= 1
            if shared.users > 0:
                return
            del _SHARED[sha256]
            break
    shutil.rmtree(folder, ignore_errors=True)
