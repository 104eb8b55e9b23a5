"""Before any run: can the plant's binary be loaded, and does it export the FMI functions?

The binary is loaded in a forked child (its library constructors might crash or hang), from a
copy unzipped into a temporary folder that is removed afterwards; the child answers with the
missing symbols or the loader's error, and is killed after PROBE_SECONDS. A plant that fails is
bad input: one line, exit 2, before anything runs.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import shutil
import signal
import sys
import tempfile
import warnings
import zipfile
from pathlib import Path

from toggle_cosim.plant.contract import PlantInterface, platform_binary_folders

PROBE_SECONDS = 10.0
FMI2 = (
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2GetReal",
    "fmi2SetReal",
    "fmi2SetBoolean",
    "fmi2DoStep",
)
FMI3 = (
    "fmi3InstantiateCoSimulation",
    "fmi3FreeInstance",
    "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode",
    "fmi3Terminate",
    "fmi3GetFloat64",
    "fmi3SetFloat64",
    "fmi3SetBoolean",
    "fmi3DoStep",
)


class ProbeError(Exception):
    """The binary cannot serve as the plant; str() is the one-line reason (file first)."""


def _binary_member(plant: PlantInterface) -> str:
    folder2, folder3 = platform_binary_folders()
    folder = folder2 if plant.fmi_version.startswith("2") else folder3
    suffix = {"linux": ".so", "darwin": ".dylib", "win32": ".dll"}.get(sys.platform, ".so")
    return f"binaries/{folder}/{plant.model_identifier}{suffix}"


def _load(path: Path, wanted: tuple[str, ...]) -> str:
    try:
        library = ctypes.CDLL(str(path))
    except OSError as error:
        return f"the binary cannot be loaded ({' '.join(str(error).split())})"
    missing = [name for name in wanted if not hasattr(library, name)]
    return f"the binary lacks {', '.join(missing)}" if missing else ""


def probe_binary(plant: PlantInterface) -> None:
    """Raise ProbeError if the plant's binary does not load or misses an FMI function it needs."""
    wanted = FMI3 if plant.fmi_version.startswith("3") else FMI2
    folder = Path(tempfile.mkdtemp(prefix="toggle-cosim-probe-"))
    try:
        member = _binary_member(plant)
        with zipfile.ZipFile(plant.path) as archive:  # already checked by check_plant
            target = folder / Path(member).name
            target.write_bytes(archive.read(member))
        read_fd, write_fd = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads (pytest, Dask)
            pid = os.fork()
        if pid == 0:  # the child: load, answer, leave without cleanup
            code = 0
            try:
                os.close(read_fd)
                os.write(write_fd, _load(target, wanted).encode()[:4000])
            except BaseException:  # noqa: BLE001
                code = 1
            os._exit(code)
        os.close(write_fd)
        answer, status = b"", None
        try:
            ready, _, _ = select.select([read_fd], [], [], PROBE_SECONDS)
            if ready:
                while chunk := os.read(read_fd, 4096):
                    answer += chunk
            else:
                os.kill(pid, signal.SIGKILL)
        finally:
            os.close(read_fd)
            _, status = os.waitpid(pid, 0)
        if os.WIFSIGNALED(status):
            raise ProbeError(
                f"{plant.path}: loading the binary {member} kills the process "
                f"({signal.Signals(os.WTERMSIG(status)).name}); rebuild the FMU"
            )
        if answer:
            raise ProbeError(f"{plant.path}: {answer.decode(errors='replace')} ({member}); rebuild the FMU")
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(folder)
