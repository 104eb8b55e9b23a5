"""The master's co-simulation loop in C: read outputs, controller, set inputs, doStep, record.

Even so, a step in Python (read outputs, controller, set inputs, doStep, record) costs several
times the FMU's own doStep, and most of that is the controller's nominal model (~3 us of
scalar Python per sample). `CompiledLoop` runs whole stretches of the loop in C: it calls the
FMU's functions through their pointers, evaluates the controller (the nominal model of
`mechanism.nominal_fG` / `nominal_fG_theta1` and the control law of `controller.VSCController.step`,
transcribed operation for operation, compiled without contraction or reassociation so that
every result is bit-identical to the Python) and writes each sample into the master's
preallocated trace. It never decides anything the Python would decide differently: a sample
with non-finite outputs, or one where the Python controller would raise or produce a
non-finite value (a domain error, a division by zero), is handed back to the Python loop
before anything of it is sent to the FMU. An FMI error status is reported with the function's
name and status, and the master raises the same exception the Python path raises.

The C source is compiled once per machine with the C compiler the FMU build uses and cached
(``$XDG_CACHE_HOME/toggle-cosim`` or ``~/.cache/toggle-cosim``; ``TOGGLE_COSIM_CACHE`` overrides).
Without a C compiler, or with ``TOGGLE_COSIM_KERNEL=0``, the master runs the Python loop.

The C source is `compiled_loop.c` beside this module.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import subprocess
import sys
import tempfile
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from toggle_cosim.fmu_export.package import FMUBuildError, find_c_compiler

if TYPE_CHECKING:
    from toggle_cosim.fmu_io import PlantFMU

KERNEL_SOURCE = resources.files("toggle_cosim").joinpath("compiled_loop.c").read_text(encoding="utf-8")

KERNEL_FLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin")

_LAW_FIELDS = ("target", "C", "Q", "P", "delta", "beta", "K_f", "t0", "T_h",
               "r1", "r3", "r4", "r5", "f", "h", "phi", "m3", "m5", "mB", "mC", "J2", "g")


class _Kernel(ctypes.Structure):
    _fields_ = [
        *((name, ctypes.c_void_p) for name in ("get", "set", "step", "component", "out_vr", "in_vr", "data")),
        *((name, ctypes.c_long) for name in ("fmi3", "n_out", "ncols", "i_x", "i_v", "col_u", "n", "objective",
                                             "k", "fault", "status")),
        *((name, ctypes.c_double) for name in ("T_s", "F_E", *_LAW_FIELDS)),
    ]


DONE, HAND_BACK, FMI_FAILED = 0, 1, 2

_library: ctypes.CDLL | None = None
_library_reason: str | None = None


def _cache_folder() -> Path:
    if os.environ.get("TOGGLE_COSIM_CACHE"):
        return Path(os.environ["TOGGLE_COSIM_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "toggle-cosim"


def _build_kernel() -> Path:
    try:
        compiler = find_c_compiler()
    except FMUBuildError as error:
        raise RuntimeError(str(error)) from error
    suffix = {"Windows": ".dll", "Darwin": ".dylib"}.get(platform.system(), ".so")
    key = hashlib.sha256("\0".join((KERNEL_SOURCE, *KERNEL_FLAGS, compiler,
                                    platform.machine(), sys.platform)).encode()).hexdigest()[:16]
    for folder in (_cache_folder(), Path(tempfile.gettempdir()) / f"toggle-cosim-{os.getuid() if hasattr(os, 'getuid') else 'user'}"):
        library = folder / f"loop-kernel-{key}{suffix}"
        if library.is_file():
            return library
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(dir=folder) as work:
                source = Path(work) / "kernel.c"
                source.write_text(KERNEL_SOURCE, encoding="utf-8")
                built = Path(work) / f"kernel{suffix}"
                result = subprocess.run([compiler, *KERNEL_FLAGS, "-o", str(built), str(source), "-lm"],
                                        capture_output=True, text=True, check=False)
                if result.returncode != 0:
                    raise RuntimeError(f"the C compiler failed: {result.stderr.strip()[:500]}")
                os.replace(built, library)  # atomic: a concurrent build just wins or loses the race
            return library
        except OSError:
            continue
    raise RuntimeError("no writable cache folder for the compiled loop")


def kernel_library() -> ctypes.CDLL | None:
    """The compiled loop (built and cached on first use), or None; `kernel_reason()` says why not."""
    global _library, _library_reason
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return None
    if _library is None and _library_reason is None:
        try:
            library = ctypes.CDLL(str(_build_kernel()))
            library.kernel_run.argtypes = [ctypes.POINTER(_Kernel), ctypes.c_long]
            library.kernel_run.restype = ctypes.c_int
            library.kernel_control.argtypes = [ctypes.POINTER(_Kernel), ctypes.c_double, ctypes.c_double,
                                               ctypes.c_double, ctypes.POINTER(ctypes.c_double)]
            library.kernel_control.restype = ctypes.c_int
            _library = library
        except Exception as error:  # noqa: BLE001 - no kernel: the Python loop runs instead
            _library_reason = str(error)
    return _library


def kernel_available() -> bool:
    return kernel_library() is not None


def kernel_reason() -> str | None:
    """Why the compiled loop is not used (None when it is)."""
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return "disabled by TOGGLE_COSIM_KERNEL=0"
    kernel_library()
    return _library_reason


class CompiledLoop:
    """Samples k .. k_end - 1 of the master loop in one C call (see the module docstring).

    `data` is the master's preallocated (n + 1, ncols) float64 trace: column 0 time, columns
    1 .. n_out the FMU outputs, col_u .. col_u + 4 (iq_ref, F_E, S, phase, e). `law` holds the
    controller: objective (0 x_B, 1 theta1), target (x_B* or theta1*), gains C Q P delta beta,
    K_f, t0 and T_h of the ControllerState, and the nominal mechanism r1 .. g.
    """

    def __init__(self, library: ctypes.CDLL, fmu: PlantFMU, functions: list, data: np.ndarray, n_out: int,
                 i_x: int, i_v: int, col_u: int, n: int, T_s: float, F_E: float, law: dict[str, float]) -> None:
        if data.dtype != np.float64 or not data.flags.c_contiguous or data.shape[0] < n + 1:
            raise ValueError("the trace must be a C-contiguous float64 array of n + 1 rows")
        self._library = library
        self._keep = (fmu, data, functions)  # everything the C side points into stays alive
        k = _Kernel()
        k.get, k.set, k.step = (ctypes.cast(f, ctypes.c_void_p).value for f in functions)
        k.component = fmu._component
        k.out_vr = ctypes.addressof(fmu._out_vr)
        k.in_vr = ctypes.addressof(fmu._in_vr)
        k.data = data.ctypes.data
        k.fmi3 = 1 if fmu.is_fmi3 else 0
        k.n_out, k.ncols, k.i_x, k.i_v, k.col_u, k.n = n_out, data.shape[1], i_x, i_v, col_u, n
        k.objective = int(law["objective"])
        k.T_s, k.F_E = float(T_s), float(F_E)
        for name in _LAW_FIELDS:
            setattr(k, name, float(law[name]))
        self._state = k
        self._pointer = ctypes.pointer(k)
        self._out = (ctypes.c_double * 4)()
        self.fault_function = None
        self.fault_status = 0
        self._names = (None, fmu._get_name, fmu._set_name, fmu._step_name)

    def control(self, t: float, x_B: float, v_B: float) -> tuple[float, float, float, float] | None:
        """(u, S, phase, e) of the compiled controller, or None where it defers to Python."""
        if self._library.kernel_control(self._pointer, t, x_B, v_B, self._out):
            return None
        return tuple(self._out)

    def run(self, k: int, k_end: int) -> tuple[int, int]:
        """Run samples k .. k_end - 1; returns (DONE | HAND_BACK | FMI_FAILED, next sample).
        On FMI_FAILED the sample is the failed one and fault_function/fault_status say what failed."""
        state = self._state
        state.k = k
        code = self._library.kernel_run(self._pointer, k_end)
        if code == FMI_FAILED:
            self.fault_function = self._names[state.fault]
            self.fault_status = int(state.status)
        return code, int(state.k)
