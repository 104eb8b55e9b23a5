"""Before any run: can the plant's binary be loaded, and does it export the FMI functions?

The binary is loaded in a forked child (its library constructors might crash or hang), from a
copy of the FMU's whole binaries/<platform>/ folder (libraries shipped beside the binary
included) unzipped into a temporary folder that is removed afterwards; the child answers with the
missing symbols or the loader's error, and is killed after PROBE_SECONDS. A plant that fails is
bad input: one line, exit 2, before anything runs.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import shutil
import signal
import sys
import tempfile
import time
import warnings
import zipfile
from pathlib import Path

from toggle_cosim import interrupts, process_tree
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


def _platform_folder(plant: PlantInterface) -> str:
    return _binary_member(plant).rsplit("/", 1)[0] + "/"


def _extract_platform_folder(plant: PlantInterface, folder: Path) -> Path:
    """The FMU's whole binaries/<platform>/ folder (the binary and the libraries shipped beside
    it, as fmpy extracts them for a run) under `folder`; the binary's path there."""
    prefix = _platform_folder(plant)
    with zipfile.ZipFile(plant.path) as archive:  # names and sizes already checked by check_plant
        for info in archive.infolist():
            if info.filename.startswith(prefix) and not info.is_dir():
                archive.extract(info, folder)
    return folder / _binary_member(plant)


def _wait(pid: int, read_fd: int, deadline: float) -> tuple[bytes, bool]:
    """What the child wrote until it ended or the deadline passed (then False), never waiting
    on the pipe alone: a helper the binary started may hold it open."""
    answer = b""
    try:
        pidfd = os.pidfd_open(pid)
    except (AttributeError, OSError):
        pidfd = -1
    try:
        while True:
            if process_tree.has_ended(pid):
                ended = True
                break
            left = deadline - time.monotonic()
            if left <= 0:
                ended = False
                break
            watched = [read_fd] + ([pidfd] if pidfd >= 0 else [])
            ready = interrupts.select_readable(watched, min(left, 0.05 if pidfd < 0 else left))
            if read_fd in ready:
                answer += _read_available(read_fd)
    finally:
        if pidfd >= 0:
            os.close(pidfd)
    return answer, ended


def _read_available(read_fd: int) -> bytes:
    data = b""
    while True:
        try:
            chunk = os.read(read_fd, 4096)
        except BlockingIOError:
            return data
        if not chunk:
            return data
        data += chunk


def _answer(target: Path, wanted: tuple[str, ...], write_fd: int) -> None:
    code = 0
    try:
        os.write(write_fd, _load(target, wanted).encode()[:4000])
    except BaseException:  # noqa: BLE001
        code = 1
    os._exit(code)


def probe_binary(plant: PlantInterface) -> None:
    """Raise ProbeError if the plant's binary does not load or misses an FMI function it needs.
    The child leads its own process group, adopts orphans and loads the binary in a grandchild
    it keeps (`process_tree`): whatever the binary's constructors start ends with the probe,
    even when loading crashes."""
    wanted = FMI3 if plant.fmi_version.startswith("3") else FMI2
    folder = Path(tempfile.mkdtemp(prefix="toggle-cosim-probe-"))
    try:
        member = _binary_member(plant)
        target = _extract_platform_folder(plant, folder)
        read_fd, write_fd = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads (pytest, Dask)
            pid = os.fork()
        if pid == 0:  # the child: load (in a grandchild it keeps, `run_kept`), answer, leave
            try:
                process_tree.become_leader()
                os.close(read_fd)
            except BaseException:  # noqa: BLE001
                os._exit(1)
            process_tree.run_kept(lambda: _answer(target, wanted, write_fd))
        process_tree.adopt(pid)
        os.close(write_fd)
        os.set_blocking(read_fd, False)
        try:
            answer, ended = _wait(pid, read_fd, time.monotonic() + PROBE_SECONDS)
        finally:
            status = process_tree.finish(pid)
        try:
            answer += _read_available(read_fd)  # the child and its helpers are gone: nothing waits
        finally:
            os.close(read_fd)
        if not ended:
            raise ProbeError(
                f"{plant.path}: loading the binary {member} did not finish within {PROBE_SECONDS:.0f} s; rebuild the FMU"
            )
        if status is not None and os.WIFSIGNALED(status):
            raise ProbeError(
                f"{plant.path}: loading the binary {member} kills the process "
                f"({signal.Signals(os.WTERMSIG(status)).name}); rebuild the FMU"
            )
        if answer:
            raise ProbeError(f"{plant.path}: {answer.decode(errors='replace')} ({member}); rebuild the FMU")
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(folder)
