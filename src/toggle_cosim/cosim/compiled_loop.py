"""The master's co-simulation loop in C: read outputs, controller, set inputs, doStep, record.

A step in Python (read outputs, controller, set inputs, doStep, record) costs several times
the FMU's own doStep, most of it the controller's nominal model. `CompiledLoop` runs whole
stretches of the loop in C: it calls the FMU's functions through their pointers, evaluates the
control law and writes each sample into the master's preallocated trace. The controller is one
of three kinds: the generated law; a controller FMU (`ControllerCalls`), whose functions the
loop calls through their pointers in the order `fmu_controller.FmuController.step` calls them
(its doStep from the previous sample, deferred to this one; its inputs set from the row; its
command and diagnostics read); or a discrete LTI system (`LtiCalls`, a python-control system
adapted by `control.lti`: one input, the error, or two, the reference and the measurement), whose
matrices the loop multiplies in the order `control.lti.lti_step` sums in. Each way the trace has the Python loop's bits.

Nothing of the law is written twice. The C source is assembled here from
* `control.law_c`, the one source of the law in C every loop compiles: the struct `law_t`,
  generated from the fields of `control.parameters.LawParameters`, the functions of
  `control.nominal` and `control.laws`, translated from their Python by `control.translate`
  (same operations, same order; compiled without contraction or reassociation, so the C gives
  the Python's bits), and `lti_sums`, the LTI system's sums in `control.lti`'s order;
* `control/loop_skeleton.c`, the generic FMI calling loop (no physics, no law).
The ctypes mirror of the loop's struct is built from the same field lists.

A sample where the Python raises or might raise (a domain error, a division by zero), or
where an output is not finite, is handed back to the Python loop before anything of it is
sent to the FMU. An FMI error status is reported with the function's name and status, and
the master raises the same exception the Python path raises: for the controller FMU, at the
sample and call where the Python loop raises it (the sample not recorded), as for a command
that is not finite.

The Python loop uses the same library for the plant's part of its samples (`PlantExchange`:
set, doStep and the next sample's get in one call), so a controller in Python pays one ctypes
call per sample for the plant, not three.

The library is compiled once per machine with the C compiler the FMU build uses and kept in
the user's private cache by a hash of the generated source (``$XDG_CACHE_HOME/toggle-cosim`` or
``~/.cache/toggle-cosim``; ``TOGGLE_COSIM_CACHE`` overrides; see `native` for the checks made
before it is loaded). Without a C compiler, without a usable cache folder, or with
``TOGGLE_COSIM_KERNEL=0``, the master runs the Python loop and says why in run.json.
"""

from __future__ import annotations

import ctypes
import functools
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from fmpy.fmi1 import FMICallException

from toggle_cosim.control.lti import LtiMatrices, LtiState
from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.native import CachedLibrary, cached_library_from, load_library_from

if TYPE_CHECKING:
    from toggle_cosim.cosim.session import CFunctions

KERNEL_FLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math", "-fno-builtin")

_FMU_POINTERS = ("get", "set", "step", "component", "out_vr", "in_vr")
_POINTERS = (
    "data",
    "load",
    "ref",
    "plant_in",
    "ctrl_cols",
    "ctrl_in",
    "ctrl_out",
    "lti_a",
    "lti_b",
    "lti_c",
    "lti_d",
    "lti_x",
    "lti_xn",
    "rows",
)
_LONGS = (
    *("n_out", "ncols", "i_q", "i_qd", "col_u", "n", "n_load", "col_x", "k", "fault", "status", "no_prior"),
    *("kind", "ctrl_n_in", "ctrl_n_out", "ctrl_due", "lti_n", "lti_m", "lti_col"),
)
_DOUBLES = ("T_s", "z", "ctrl_t", "lti_target", "lti_origin")
CTRL_LAW, CTRL_FMU, CTRL_LTI = 0, 1, 2  # the controller kinds of the skeleton


@dataclass(frozen=True)
class ControllerCalls:
    """A controller FMU as the compiled loop calls it (`fmu_controller.FmuController`): its
    functions, the trace columns of its inputs (in its input order; -1 - i: value i of the
    reference's row, the built-in law's x_ref, v_ref, a_ref), the number of its outputs
    (iq_ref, then the diagnostics), and the time of its last sample (None before the first),
    whose deferred doStep the loop makes at its next sample."""

    functions: CFunctions
    columns: tuple[int, ...]
    n_out: int
    t: float | None


@dataclass(frozen=True)
class LtiCalls:
    """A discrete LTI controller as the compiled loop runs it (`control.lti.DiscreteSystemController`):
    its matrices (one input e = r − y, or two, r − y0 and y − y0), the trace column of the output y
    it reads, the constant reference r (the loop reads the trajectory's q* instead when it is given
    one), and its state at the first sample the loop runs (x and y0)."""

    matrices: LtiMatrices
    column: int
    target: float
    state: LtiState


@functools.cache
def kernel_source() -> str:
    """The whole C source of the compiled loop: the generated law, the LTI sums, then the loop skeleton."""
    from toggle_cosim.control import law_c

    skeleton = resources.files("toggle_cosim.control").joinpath("loop_skeleton.c").read_text(encoding="utf-8")
    return "\n".join([law_c.law_source(), law_c.lti_source(), skeleton])


@functools.cache
def _law_struct() -> type[ctypes.Structure]:
    return type(
        "_Law",
        (ctypes.Structure,),
        {"_fields_": [(name, ctypes.c_double) for name in LawParameters.__dataclass_fields__]},
    )


@functools.cache
def _fmu_struct() -> type[ctypes.Structure]:
    return type(
        "_Fmu",
        (ctypes.Structure,),
        {"_fields_": [*((name, ctypes.c_void_p) for name in _FMU_POINTERS), ("fmi3", ctypes.c_long)]},
    )


@functools.cache
def _kernel_struct() -> type[ctypes.Structure]:
    return type(
        "_Kernel",
        (ctypes.Structure,),
        {
            "_fields_": [
                ("plant", _fmu_struct()),
                ("ctrl", _fmu_struct()),
                *((name, ctypes.c_void_p) for name in _POINTERS),
                *((name, ctypes.c_long) for name in _LONGS),
                *((name, ctypes.c_double) for name in _DOUBLES),
                ("law", _law_struct()),
            ]
        },
    )


DONE, HAND_BACK, FMI_FAILED, CONTROLLER_FAILED, COMMAND_REJECTED = 0, 1, 2, 3, 4

_library: ctypes.CDLL | None = None
_library_reason: str | None = None


def kernel_inputs() -> list[Path]:
    """The files kernel_source() is generated from: the law's and the LTI sums' (`control.law_c`),
    the loop skeleton, and this module."""
    from toggle_cosim.control.law_c import law_inputs

    skeleton = Path(str(resources.files("toggle_cosim.control").joinpath("loop_skeleton.c")))
    return [*law_inputs(), skeleton, Path(__file__)]


def _build_kernel() -> CachedLibrary:
    """The compiled loop's library, built from the generated source (cached: `native`; the
    source is generated only when one of kernel_inputs() changed)."""
    return cached_library_from(kernel_inputs(), kernel_source, "loop-kernel", KERNEL_FLAGS, ("-lm",))


def _load_kernel() -> ctypes.CDLL:
    """The compiled loop's library, loaded after its bytes are checked (`native.load_library_from`)."""
    return load_library_from(kernel_inputs(), kernel_source, "loop-kernel", KERNEL_FLAGS, ("-lm",))


def kernel_library() -> ctypes.CDLL | None:
    """The compiled loop (built and cached on first use), or None; `kernel_reason()` says why not."""
    global _library, _library_reason
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return None
    if _library is None and _library_reason is None:
        try:
            library = _load_kernel()
            kernel = _kernel_struct()
            library.kernel_run.argtypes = [ctypes.POINTER(kernel), ctypes.c_long]
            library.kernel_run.restype = ctypes.c_int
            library.kernel_control.argtypes = [
                ctypes.POINTER(kernel),
                *(ctypes.c_double,) * 7,
                ctypes.POINTER(ctypes.c_double),
            ]
            library.kernel_control.restype = ctypes.c_int
            library.plant_exchange.argtypes = [ctypes.POINTER(kernel), ctypes.c_long, ctypes.c_double, ctypes.c_int]
            library.plant_exchange.restype = ctypes.c_int
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
    1 .. n_out the FMU outputs, col_u .. col_u + 1 (iq_ref, F_E), then the diagnostics, then the
    plant's other inputs (its last m - 1 columns); `load` the (n + 1, m) float64 array of what
    sample k sends besides the command, load[k] = (F_E, the other inputs), recorded in its row. With
    `controller` None the controller is the generated law: it reads the columns i_q and i_qd
    (x_B and v_B, or theta1 and omega1 for the θ1 objective) and writes (S, phase, e); `law` is
    the controller's `LawParameters` (with t0 and T_h of its first sample), `z` the law's state
    at the first sample the loop runs, `reference` the law's (n + 1, 3) float64 reference
    (q*, q̇*, q̈*) per sample (`control.trajectory`; None: the constant law.target). With
    `controller` (a controller FMU's calls) the loop calls it instead, in the order
    `FmuController.step` does, and hands a sample whose columns i_q, i_qd (x_B, v_B) are not
    finite back before calling it; `law`, `z` and `reference` are unused. With an `LtiCalls` the
    loop runs that system (diagnostic e) on the reference q* of `reference` (None: its constant
    target), handing back a sample where i_q, i_qd, e, the command or the next state is not
    finite; `lti_state()` is its state. `rows` (one int64, the recorder's `count`), if given, is
    set to k + 1 as soon as row k is whole, so a supervising process knows how many rows a run
    that crashed in C recorded without reading their values.
    """

    def __init__(
        self,
        library: ctypes.CDLL,
        fmu: CFunctions,
        data: np.ndarray,
        n_out: int,
        i_q: int,
        i_qd: int,
        col_u: int,
        n: int,
        T_s: float,
        load: np.ndarray,
        law: LawParameters | None,
        z: float = 0.0,
        controller: ControllerCalls | LtiCalls | None = None,
        reference: np.ndarray | None = None,
        rows: np.ndarray | None = None,
    ) -> None:
        if rows is not None and (rows.shape != (1,) or rows.dtype != np.int64 or not rows.flags.c_contiguous):
            raise ValueError("the row count must be one C-contiguous int64")
        if data.dtype != np.float64 or not data.flags.c_contiguous or data.shape[0] < n + 1:
            raise ValueError("the trace must be a C-contiguous float64 array of n + 1 rows")
        if load.dtype != np.float64 or not load.flags.c_contiguous or load.ndim != 2 or load.shape[0] != n + 1:
            raise ValueError("the load must be a C-contiguous float64 array of n + 1 rows")
        if reference is not None and (
            reference.dtype != np.float64 or not reference.flags.c_contiguous or reference.shape != (n + 1, 3)
        ):
            raise ValueError("the reference must be a C-contiguous float64 array of n + 1 rows of 3")
        n_load = load.shape[1]
        if not 1 <= n_load <= data.shape[1] - col_u - 1:
            raise ValueError("the load needs F_E and a trace column for each other input")
        self._library = library
        k = _kernel_struct()()
        _point_at(k.plant, fmu)
        plant_in = (ctypes.c_double * (1 + n_load))()  # the plant's inputs: the command, then the load row
        k.data, k.load, k.plant_in = data.ctypes.data, load.ctypes.data, ctypes.addressof(plant_in)
        k.ref = None if reference is None else reference.ctypes.data
        k.rows = None if rows is None else rows.ctypes.data
        k.n_load, k.col_x = n_load, data.shape[1] - (n_load - 1)
        k.n_out, k.ncols, k.i_q, k.i_qd, k.col_u, k.n = n_out, data.shape[1], i_q, i_qd, col_u, n
        k.T_s, k.z = float(T_s), float(z)
        k.no_prior = 0  # the FMU keeps its history unless a policy that never restores says so
        if law is not None:
            for name in LawParameters.__dataclass_fields__:
                setattr(k.law, name, float(getattr(law, name)))
        buffers: tuple[object, ...] = ()
        k.kind = CTRL_LAW
        self._x: ctypes.Array[ctypes.c_double] | None = None
        if isinstance(controller, LtiCalls):
            m, size = controller.matrices, max(controller.matrices.n, 1)
            a = (ctypes.c_double * max(m.n * m.n, 1))(*(value for row in m.A for value in row))
            b = (ctypes.c_double * max(m.n * m.m, 1))(*(value for row in m.B for value in row))
            c, d = (ctypes.c_double * size)(*m.C), (ctypes.c_double * m.m)(*m.D)
            x, xn = (ctypes.c_double * size)(*controller.state.x), (ctypes.c_double * size)()
            buffers = (a, b, c, d, x, xn)
            k.lti_a, k.lti_b, k.lti_c, k.lti_d, k.lti_x, k.lti_xn = (ctypes.addressof(v) for v in buffers)
            k.kind, k.lti_n, k.lti_m, k.lti_col = CTRL_LTI, m.n, m.m, controller.column
            k.lti_target, k.lti_origin = controller.target, controller.state.origin
            self._x = x
        elif controller is not None:
            n_in = len(controller.columns)
            if data.shape[1] < col_u + 1 + controller.n_out:
                raise ValueError("the trace has fewer columns than the controller FMU's outputs")
            columns = (ctypes.c_long * max(n_in, 1))(*controller.columns)
            values, outputs = (ctypes.c_double * max(n_in, 1))(), (ctypes.c_double * controller.n_out)()
            buffers = (controller.functions, columns, values, outputs)
            _point_at(k.ctrl, controller.functions)
            k.kind, k.ctrl_n_in, k.ctrl_n_out = CTRL_FMU, n_in, controller.n_out
            k.ctrl_cols, k.ctrl_in, k.ctrl_out = (ctypes.addressof(b) for b in (columns, values, outputs))
            k.ctrl_due, k.ctrl_t = (0, 0.0) if controller.t is None else (1, float(controller.t))
            self._outputs = outputs
        self._keep = (
            fmu,
            data,
            load,
            reference,
            rows,
            plant_in,
            buffers,
        )  # everything the C side points into stays alive
        self._state = k
        self._pointer = ctypes.pointer(k)
        self._out = (ctypes.c_double * 5)()
        self.fault_function = None
        self.fault_status = 0
        self._names = (None, fmu.names.get, fmu.names.set, fmu.names.step, "get", "set", "step")

    @property
    def no_set_state_prior_to_current_point(self) -> bool:
        """The flag the C loop passes to every doStep (set by the checkpoint policy, `retry`)."""
        return bool(self._state.no_prior)

    @no_set_state_prior_to_current_point.setter
    def no_set_state_prior_to_current_point(self, value: bool) -> None:
        self._state.no_prior = 1 if value else 0

    @property
    def pointer(self) -> object:
        """The ctypes pointer to the loop's struct, for the library's functions."""
        return self._pointer

    @property
    def status(self) -> int:
        """The status field of the struct: the last failed FMI call's status."""
        return int(self._state.status)

    @property
    def z(self) -> float:
        """The law's state at the next sample."""
        return float(self._state.z)

    @property
    def controller_time(self) -> float:
        """The controller FMU's state: the time of its last sample, whose doStep is deferred."""
        return float(self._state.ctrl_t)

    def lti_state(self) -> LtiState:
        """The LTI controller's state at the next sample (`LtiCalls`)."""
        assert self._x is not None, "not an LTI controller"
        return LtiState(tuple(self._x[: self._state.lti_n]), float(self._state.lti_origin))

    def controller_outputs(self) -> tuple[float, ...]:
        """The controller FMU's outputs read at its last sample (iq_ref, then the diagnostics)."""
        return tuple(self._outputs)

    def control(
        self, t: float, q: float, qd: float, z: float = 0.0, reference: tuple[float, float, float] | None = None
    ) -> tuple[float, float, float, float, float] | None:
        """(u, S, phase, e, z_next) of the compiled law at the measured (q, qd) and the reference
        (q*, q̇*, q̈*) (None: law.target, 0, 0), or None where it defers to Python."""
        r, rd, rdd = (self._state.law.target, 0.0, 0.0) if reference is None else reference
        if self._library.kernel_control(self._pointer, t, q, qd, z, r, rd, rdd, self._out):
            return None
        return tuple(self._out)

    def run(self, k: int, k_end: int) -> tuple[int, int]:
        """Run samples k .. k_end - 1; returns (DONE | HAND_BACK | FMI_FAILED | CONTROLLER_FAILED
        | COMMAND_REJECTED, next sample). On a failure the sample is the failed one and
        fault_function/fault_status say what failed: the plant's FMI function name, or for
        CONTROLLER_FAILED the controller FMU's call ("get", "set" or "step")."""
        state = self._state
        state.k = k
        code = self._library.kernel_run(self._pointer, k_end)
        if code in (FMI_FAILED, CONTROLLER_FAILED):
            self.fault_function = self._names[state.fault]
            self.fault_status = int(state.status)
        return code, int(state.k)


class PlantExchange:
    """The plant's part of a sample of the Python loop in one C call (`plant_exchange` in the
    loop skeleton): set the inputs (the command, then the load row k), doStep from t_k over T_s,
    and optionally get the outputs of sample k + 1 into the trace row k + 1. The same FMI calls
    with the same values as `PlantSession.write_inputs`, `do_step` and `read_outputs`, so the
    trace has their bits; a failed call is reported as they report it (`failure`).

    `call` and `pointer` are pre-bound for the loop: ``call(pointer, k, u, read_next)`` returns
    0, or the failed call (GET, SET or STEP), whose status is then `status`."""

    GET, SET, STEP = 1, 2, 3

    def __init__(
        self,
        library: ctypes.CDLL,
        fmu: CFunctions,
        data: np.ndarray,
        n_out: int,
        col_u: int,
        n: int,
        T_s: float,
        load: np.ndarray,
    ) -> None:
        """`data`, `n_out`, `col_u`, `n`, `T_s`, `load`: as `CompiledLoop`'s (no law, no controller)."""
        self._loop = CompiledLoop(library, fmu, data, n_out, 0, 0, col_u, n, T_s, load, None)
        self.call = library.plant_exchange
        self.pointer = self._loop.pointer
        self.names = fmu.names

    @property
    def no_set_state_prior_to_current_point(self) -> bool:
        """The flag passed to every doStep (the session's, copied before each stretch)."""
        return self._loop.no_set_state_prior_to_current_point

    @no_set_state_prior_to_current_point.setter
    def no_set_state_prior_to_current_point(self, value: bool) -> None:
        self._loop.no_set_state_prior_to_current_point = value

    @property
    def status(self) -> int:
        """The status of the failed call."""
        return self._loop.status

    def failure(self, code: int) -> FMICallException:
        """The exception the session raises for the failed call `code` (named as it names it)."""
        names = self.names
        function = {self.GET: names.get, self.SET: names.set, self.STEP: names.step}[code]
        return FMICallException(function=function, status=self.status)


def _point_at(target: ctypes.Structure, functions: CFunctions) -> None:
    """Fill the skeleton's fmu_t from an FMU's C functions."""
    target.get, target.set, target.step = functions.get, functions.set, functions.step
    target.component, target.out_vr, target.in_vr = functions.component, functions.out_vr, functions.in_vr
    target.fmi3 = 1 if functions.fmi3 else 0
