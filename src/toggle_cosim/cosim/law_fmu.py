"""The built-in law as generated C, for a system: its controller FMU (`controller_fmu`, the C
generated from `control.laws` in the FMI shell, bit for bit the Python law) built once per
machine into the private cache (`native.cached_file`), so that a system whose controller is the
built-in law runs in the compiled system loop (`cosim.system_loop`).

`law_fmu()` gives the cached FMU (its bytes checked against the SHA-256 recorded when it was
built), or why there is none: `TOGGLE_COSIM_KERNEL=0`, no C compiler, no private cache folder,
or a build that failed. The system then runs the law in Python (`slaves.ControllerSlave`), with
the same values.
"""

from __future__ import annotations

import functools
import os
from importlib import resources
from pathlib import Path

from toggle_cosim.native import CachedLibrary, cached_file, verified_bytes

__all__ = ["law_fmu"]


def _inputs() -> list[Path]:
    """The files the controller FMU is generated from: its package (shell included) and the law's."""
    found = []
    for package in ("toggle_cosim.controller_fmu", "toggle_cosim.controller_fmu.shell", "toggle_cosim.control"):
        folder = resources.files(package)
        found += sorted(Path(str(item)) for item in folder.iterdir() if item.name.endswith((".py", ".c", ".h")))
    return found


@functools.cache
def _built() -> CachedLibrary | str:
    from toggle_cosim.controller_fmu import build_controller_fmu

    try:
        return cached_file(_inputs(), "law-fmu", ".fmu", lambda path: build_controller_fmu(path, "2.0"))
    except Exception as error:  # noqa: BLE001 - no FMU: the law runs in Python, run.json says why
        return f"the built-in law's FMU could not be built ({' '.join(str(error).split())[:200]})"


def law_fmu() -> Path | str:
    """The built-in law's controller FMU (FMI 2.0) from the private cache, or why there is none."""
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return "disabled by TOGGLE_COSIM_KERNEL=0"
    built = _built()
    if isinstance(built, str):
        return built
    if not verified_bytes(built):
        _built.cache_clear()
        return f"{built.path}: the cached FMU's bytes are not those recorded when it was built: not used"
    return built.path
