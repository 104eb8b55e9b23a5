"""A system's stepping plan (`system.plan.Plan`) run in C: one loop over a component table and a
connection table, for any number of FMUs (FMI 2.0 and 3.0 Co-Simulation) and native controllers
(the built-in law, tracking included, and python-control systems: `system_natives`).

`SystemLoop` makes the tables from the plan and each component's C calls (`CFunctions`, e.g.
`fmi_pointers.fmu_functions` of an fmpy slave: its outputs' value references in the plan's
`output_names[c]` order, its fed inputs' in `input_names[c]` order) and runs samples k0 .. k_end - 1
as the plan's docstring says (cosim/execution/system_skeleton.c): per component one setReal for its early
inputs and one getReal for its outputs (then one getter call per recorded output of another type,
`CFunctions.reads`), then one setReal for its late inputs and a doStep each.
Each sample's row goes into the caller's preallocated trace: column 0 t_k = k T_s, column 1 + i
the value of the slot plan.record[i]. An input fed through a unit conversion gets factor · value
+ offset with Python's bits (compiled without contraction); an identity connection copies.
Instantiation, parameters and initialisation are the caller's (`cosim.execution.algorithm`): the loop only
steps instances that are ready.

A native controller's entry holds the law's parameters or the system's matrices and what its
`ControllerSlave` held; the C samples it as that slave does, with the law generated from
`control.laws` and the LTI sums of `control.lti` (`control.law_c`: the source the controller
FMU compiles too), so the trace has the Python execution's bits. Where the Python might raise or a value
is not finite, the loop hands the sample back (HAND_BACK, before any doStep of it) and
`give_back()` returns the slaves what they held at that sample's start.

A component run in Python (a user's Python controller, any slave without C calls:
`system_python.PythonComponent`) is called back once a sample, at its early turn
(`system_python.Callbacks`): the slave is given the calls the Python execution gives it, in their
order and with the same values, so only that component costs Python time. What it raises stops the loop at that sample
(RAISED) and `run` raises it, as the Python execution would.

`compiled_system` makes the loop for a plan's slaves (`cosim.execution.slaves`): an FMU's `c_functions()`,
a native controller, and every other component run in Python through the callback; or says in a
line why there is none (no compiled library).

A status other than OK or Warning stops the loop at that call; `failure()` names the component,
the function, its status and the sample (`ComponentCallError`, one line).

The library is compiled once per machine and cached as the master's other compiled loop is
(`native`: private cache, checked by hash; `TOGGLE_COSIM_KERNEL=0` switches it off and
`system_library_reason()` says why there is none).
"""

from __future__ import annotations

import ctypes
import functools
import os
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import NamedTuple

import numpy as np

from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.control.translate import ctypes_struct
from toggle_cosim.cosim.execution.fmi_pointers import CFunctions
from toggle_cosim.cosim.execution.guard import FiniteGuard, refusal
from toggle_cosim.cosim.execution.slaves import ControllerSlave, SlaveError
from toggle_cosim.cosim.execution.system_natives import NativeController, native_controller
from toggle_cosim.cosim.execution.system_python import Callbacks, PythonComponent, Turns, turns_of
from toggle_cosim.native import KERNEL_FLAGS, load_library_from
from toggle_cosim.system.plan import Plan

__all__ = [
    "ComponentCallError",
    "DONE",
    "FMI_FAILED",
    "HAND_BACK",
    "NOT_FINITE",
    "RAISED",
    "SystemLoop",
    "compiled_system",
    "system_library",
    "system_library_reason",
]

DONE, HAND_BACK, FMI_FAILED, RAISED, NOT_FINITE = 0, 1, 2, 3, 4  # system_run's return codes (system_skeleton.c)
_CALLS = {1: "get", 2: "set", 3: "step"}
_CALLS_STEP = 3  # _CALLS's doStep: system_t's fault of a failed doStep
_TYPED = 4  # fault 4 + i: the component's typed read i (`fmi_pointers.TypedRead`)

# The C structs' fields, in their order in system_skeleton.c.
_COMPONENT_POINTERS = (
    "get",
    "set",
    "step",
    "component",
    "out_vr",
    "early_vr",
    "late_vr",
    "early_slot",
    "late_slot",
    "scratch",
    "typed_get",
    "typed_vr",
    "typed_kind",
    "typed_slot",
)
_COMPONENT_LONGS = ("fmi3", "n_out", "out0", "n_early", "n_late", "id", "n_typed")
_COMPONENT_AFTER = ("native", "python")  # pointers after the longs
_COMPONENT_LAST = ("pending", "guard")  # longs after them
_NATIVE_LONGS = ("kind", "n_in", "n_held", "n_state", "i_q", "i_qd", "m")
_NATIVE_POINTERS = ("early_pos", "late_pos", "mem", "saved", "state", "ref", "a", "b", "c", "d")
_NATIVE_DOUBLES = ("target", "origin")
_SYSTEM_POINTERS = ("components", "buffer", "source", "factor", "offset", "signals", "trace", "record", "rows")
_SYSTEM_LONGS = ("n_components", "n_signals", "n_record", "n", "k", "failed", "fault", "status", "no_prior")
_SYSTEM_DOUBLES = ("T_s",)
_SYSTEM_AFTER = ("calling", "answered", "guarded")  # pointers after T_s


class ComponentCallError(RuntimeError):
    """An FMI call of a component that returned a status other than OK or Warning: which
    component (its name), which function, the status and the sample's time."""

    def __init__(self, component: str, function: str, status: int, t: float) -> None:
        super().__init__(f"component {component}: {function} returned status {status} at t = {t:.6g} s")
        self.component, self.function, self.status, self.t = component, function, status, t


def _struct(name: str, *groups: tuple[Sequence[str], type]) -> type[ctypes.Structure]:
    """The ctypes mirror of one of system_skeleton.c's structs: its groups of fields in order,
    each (names, ctypes type)."""
    return type(name, (ctypes.Structure,), {"_fields_": [(field, kind) for names, kind in groups for field in names]})


@functools.cache
def _component_struct() -> type[ctypes.Structure]:
    return _struct(
        "_Component",
        (_COMPONENT_POINTERS, ctypes.c_void_p),
        (_COMPONENT_LONGS, ctypes.c_long),
        (_COMPONENT_AFTER, ctypes.c_void_p),
        (_COMPONENT_LAST, ctypes.c_long),
    )


@functools.cache
def _native_struct() -> type[ctypes.Structure]:
    return _struct(
        "_Native",
        (_NATIVE_LONGS, ctypes.c_long),
        (_NATIVE_POINTERS, ctypes.c_void_p),
        (_NATIVE_DOUBLES, ctypes.c_double),
        (("law",), ctypes_struct(LawParameters)),  # law_t, as control/law_c.py writes it (`translate.c_struct`)
    )


@functools.cache
def _system_struct() -> type[ctypes.Structure]:
    return _struct(
        "_System",
        (_SYSTEM_POINTERS, ctypes.c_void_p),
        (_SYSTEM_LONGS, ctypes.c_long),
        (_SYSTEM_DOUBLES, ctypes.c_double),
        (_SYSTEM_AFTER, ctypes.c_void_p),
    )


def _skeleton() -> Path:
    return Path(str(resources.files("toggle_cosim.cosim.execution").joinpath("system_skeleton.c")))


@functools.cache
def system_source() -> str:
    """The C source of the system loop: the generated law and the LTI sums (`control.law_c`, the
    one source the controller FMU compiles too), then system_skeleton.c."""
    from toggle_cosim.control import law_c

    return "\n".join([law_c.law_source(), law_c.lti_source(), _skeleton().read_text(encoding="utf-8")])


def system_inputs() -> list[Path]:
    """The files the library is built from: the law's and the LTI sums' (`control.law_c`), the
    skeleton, this module (its struct mirror), `system_natives` (the native kinds) and
    `system_python` (the callback's signature and turns)."""
    from toggle_cosim.control.law_c import law_inputs

    here = Path(__file__)
    return [*law_inputs(), _skeleton(), here, here.with_name("system_natives.py"), here.with_name("system_python.py")]


_library: ctypes.CDLL | None = None
_library_reason: str | None = None


def system_library() -> ctypes.CDLL | None:
    """The system loop's library (built and cached on first use), or None; `system_library_reason()` says why not."""
    global _library, _library_reason
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return None
    if _library is None and _library_reason is None:
        try:
            library = load_library_from(system_inputs(), system_source, "system-loop", KERNEL_FLAGS, ("-lm",))
            library.system_run.argtypes = [ctypes.POINTER(_system_struct()), ctypes.c_long]
            library.system_run.restype = ctypes.c_int
            _library = library
        except Exception as error:  # noqa: BLE001 - no library: the Python execution runs instead
            _library_reason = str(error)
    return _library


def system_library_reason() -> str | None:
    """Why the system loop is not available (None when it is)."""
    if os.environ.get("TOGGLE_COSIM_KERNEL", "1") == "0":
        return "disabled by TOGGLE_COSIM_KERNEL=0"
    system_library()
    return _library_reason


def _longs(values: Sequence[int]) -> ctypes.Array:
    return (ctypes.c_long * max(len(values), 1))(*values)


class _NativeSlot(NamedTuple):
    """A native controller in the loop: its component's index, itself, its native_t and the
    arrays that native_t points to: its memory (dirty, held, row, next state), the memory's copy
    at the sample's start (`saved`) and its committed state."""

    c: int
    native: NativeController
    entry: ctypes.Structure
    memory: ctypes.Array
    saved: ctypes.Array
    state: ctypes.Array


def _native_entry(
    native: NativeController, early: Sequence[int], late: Sequence[int], n_out: int, keep: list[object]
) -> tuple[ctypes.Structure, list[ctypes.Array]]:
    """system_skeleton.c's native_t of a native controller, its memory filled from what its slave
    held (`NativeController.start`), and the arrays it points into (its early and late
    positions, memory, saved memory, state, ...); everything it points into goes into `keep`."""
    start = native.start
    n_held, n_in, n_state = len(start.held), len(start.row), native.n_state
    if n_held != n_out:
        raise ValueError(f"a native controller of {n_held} outputs in a plan that gives it {n_out}")
    memory = [1.0 if start.dirty else 0.0, *start.held, *start.row, *native.state_values(start.next)]
    size = len(memory)
    entry = _native_struct()()
    arrays: list[ctypes.Array] = [
        _longs(early),
        _longs(late),
        (ctypes.c_double * size)(*memory),
        (ctypes.c_double * size)(*memory),
        (ctypes.c_double * max(n_state, 1))(*native.state_values(start.state)),
    ]
    entry.kind, entry.n_in, entry.n_held, entry.n_state = native.kind, n_in, n_held, n_state
    entry.i_q, entry.i_qd = native.reads[0], native.reads[-1]
    entry.early_pos, entry.late_pos, entry.mem, entry.saved, entry.state = (ctypes.addressof(a) for a in arrays)
    if native.reference is not None:
        entry.ref = native.reference.ctypes.data
    if native.lti is not None:
        m = native.lti
        matrices = (
            (ctypes.c_double * max(m.n * m.n, 1))(*(value for row in m.A for value in row)),
            (ctypes.c_double * max(m.n * m.m, 1))(*(value for row in m.B for value in row)),
            (ctypes.c_double * max(m.n, 1))(*m.C),
            (ctypes.c_double * m.m)(*m.D),
        )
        arrays += matrices
        entry.a, entry.b, entry.c, entry.d = (ctypes.addressof(a) for a in matrices)
        entry.m, entry.target, entry.origin = m.m, native.target, native.origin
    if native.law is not None:
        law = native.law
        entry.law = type(entry.law)(*(float(getattr(law, name)) for name in LawParameters.__dataclass_fields__))
    keep += [entry, arrays, native.reference]
    return entry, arrays


class SystemLoop:
    """Samples of a plan run in C (module docstring).

    Args:
        plan: the system's stepping plan.
        functions: per component in plan.order, its C calls: out_vr the value references of
            plan.output_names[c], in_vr those of plan.input_names[c], in those orders; or a
            native controller (`system_natives.NativeController`), run in C; or a component run
            in Python (`system_python.PythonComponent`), called back.
        signals: the run's (n + 1, len(plan.signals)) C-contiguous float64 signal table.
        trace: the (n + 1, 1 + len(plan.record)) C-contiguous float64 trace the rows go into.
        n: the last sample (t_n = n T_s is recorded, and no doStep is made from it).
        T_s: the communication step [s].
        library: the compiled library (None: `system_library()`; ValueError when there is none).
        rows: the trace's row count (one int64, `execution.row_count`), set to k + 1 as soon as row
            k is recorded; None: not counted in C.
        calling: an int64 array whose element 0 the loop sets, before each call of a component,
            to that component's entry of `ids` (per component in plan.order; default 1, 2, ...):
            a supervising process that shares it knows whose call ended the process.
        guard: the slots whose values must be finite (`guard`; None: none): a value that is not
            stops the loop with NOT_FINITE at that sample (`refusal()`).
    """

    def __init__(
        self,
        plan: Plan,
        functions: Sequence[CFunctions | NativeController | PythonComponent],
        signals: np.ndarray,
        trace: np.ndarray,
        n: int,
        T_s: float,
        library: ctypes.CDLL | None = None,
        rows: np.ndarray | None = None,
        calling: np.ndarray | None = None,
        ids: Sequence[int] | None = None,
        guard: FiniteGuard | None = None,
    ) -> None:
        library = library if library is not None else system_library()
        if library is None:
            raise ValueError(f"no compiled system loop: {system_library_reason()}")
        count = len(plan.order)
        if len(functions) != count:
            raise ValueError(f"the plan has {count} components, {len(functions)} C calls were given")
        m = len(plan.signals)
        if signals.dtype != np.float64 or not signals.flags.c_contiguous or signals.shape != (n + 1, m):
            raise ValueError(f"the signal table must be a C-contiguous float64 array of shape ({n + 1}, {m})")
        width = 1 + len(plan.record)
        if trace.dtype != np.float64 or not trace.flags.c_contiguous or trace.ndim != 2 or trace.shape[1] != width:
            raise ValueError(f"the trace must be a C-contiguous float64 array of {width} columns")
        if trace.shape[0] < n + 1:
            raise ValueError(f"the trace has {trace.shape[0]} rows, the run {n + 1}")
        if rows is not None and (rows.shape != (1,) or rows.dtype != np.int64 or not rows.flags.c_contiguous):
            raise ValueError("the row count must be one C-contiguous int64")
        self.plan, self.T_s, self.n = plan, float(T_s), n
        self._library = library
        table = (_component_struct() * count)()
        keep: list[object] = [functions, signals, trace, rows]
        natives: list[_NativeSlot] = []
        buffer = np.zeros(max(plan.size, 1), dtype=np.float64)
        guarded = np.zeros(max(plan.size, 1), dtype=np.int64 if ctypes.sizeof(ctypes.c_long) == 8 else np.int32)
        if guard is not None:
            guarded[sorted(guard.slots)] = 1
        turns: dict[int, Turns] = {}
        for c, (entry, calls) in enumerate(zip(table, functions, strict=True)):
            inputs, outputs = plan.inputs[c], plan.outputs[c]
            if outputs and outputs != tuple(range(outputs[0], outputs[0] + len(outputs))):
                raise ValueError(f"component {plan.order[c]}: its output slots are not contiguous")
            early = plan.early[c]
            late = plan.late[c]
            if isinstance(calls, NativeController):
                native, held = _native_entry(calls, early, late, len(outputs), keep)
                natives.append(_NativeSlot(c, calls, native, *held[2:5]))
                entry.native = ctypes.addressof(native)
                in_vr: Sequence[int] = (0,) * len(inputs)
                reads: Sequence = ()
            elif isinstance(calls, PythonComponent):
                in_vr, reads = (0,) * len(inputs), ()
            else:
                in_vr = (ctypes.c_uint32 * len(inputs)).from_address(calls.in_vr) if inputs else ()
                reads = calls.reads
                entry.get, entry.set, entry.step, entry.component = calls.get, calls.set, calls.step, calls.component
                entry.out_vr = calls.out_vr
                entry.fmi3 = 1 if calls.fmi3 else 0
            arrays = (
                (ctypes.c_uint32 * max(len(early), 1))(*(in_vr[i] for i in early)),
                (ctypes.c_uint32 * max(len(late), 1))(*(in_vr[i] for i in late)),
                _longs([inputs[i] for i in early]),
                _longs([inputs[i] for i in late]),
                (ctypes.c_double * max(len(inputs), 1))(),
                (ctypes.c_void_p * max(len(reads), 1))(*(read.address for read in reads)),
                (ctypes.c_uint32 * max(len(reads), 1))(*(read.vr for read in reads)),
                _longs([read.kind for read in reads]),
                _longs([outputs[read.position] for read in reads]),
            )
            keep.append(arrays)
            (
                entry.early_vr,
                entry.late_vr,
                entry.early_slot,
                entry.late_slot,
                entry.scratch,
                entry.typed_get,
                entry.typed_vr,
                entry.typed_kind,
                entry.typed_slot,
            ) = (ctypes.addressof(a) for a in arrays)
            entry.n_out, entry.out0 = len(outputs) - len(reads), outputs[0] if outputs else 0
            entry.n_typed = len(reads)
            entry.n_early, entry.n_late = len(early), len(late)
            entry.id = ids[c] if ids is not None else c + 1
            entry.guard = 1 if any(guarded[slot] for slot in (*inputs, *outputs)) else 0
            if isinstance(calls, PythonComponent):
                late_slots = [inputs[i] for i in late]
                turns[c] = turns_of(
                    calls.slave, early, late, late_slots, arrays[4], buffer, entry.out0, len(outputs), T_s
                )
        self._natives = tuple(natives)
        # per native controller, its slave's `changes` when it held what the C holds (`take_back`;
        # none once the loop runs again)
        self._synced = {slot.native.slave.name: slot.native.slave.changes for slot in natives}
        self._callbacks = Callbacks(turns, self.T_s) if turns else None
        if self._callbacks is not None:
            for c in turns:
                table[c].python = ctypes.cast(self._callbacks.function, ctypes.c_void_p)
        source = np.ascontiguousarray(plan.feed_source, dtype=np.int64)
        factor = np.ascontiguousarray(plan.feed_factor, dtype=np.float64)
        offset = np.ascontiguousarray(plan.feed_offset, dtype=np.float64)
        record = np.ascontiguousarray(plan.record, dtype=np.int64)
        if ctypes.sizeof(ctypes.c_long) != 8:  # the C tables are longs
            source, record = source.astype(np.int32), record.astype(np.int32)
        if calling is None:
            calling = np.zeros(1, dtype=np.int64)
        if calling.dtype != np.int64 or calling.size < 1:
            raise ValueError("calling must be an int64 array of at least one element")
        keep += [table, buffer, source, factor, offset, record, calling, guarded]
        s = _system_struct()()
        s.components, s.buffer = ctypes.addressof(table), buffer.ctypes.data
        s.source, s.factor, s.offset = source.ctypes.data, factor.ctypes.data, offset.ctypes.data
        s.signals, s.trace, s.record = signals.ctypes.data, trace.ctypes.data, record.ctypes.data
        s.rows = None if rows is None else rows.ctypes.data
        s.n_components, s.n_signals, s.n_record, s.n = count, m, len(plan.record), n
        s.T_s = self.T_s
        s.calling = calling.ctypes.data
        s.guarded = guarded.ctypes.data
        if self._callbacks is not None:
            s.answered = self._callbacks.answered.ctypes.data
        self._keep = keep  # everything the C side points into stays alive with the loop
        self._table, self._calling = table, calling
        self._functions = tuple(functions)
        self._state = s
        self._pointer = ctypes.pointer(s)
        self.buffer = buffer  # the sample's values, slot by slot (plan.slot)

    @property
    def no_set_state_prior_to_current_point(self) -> bool:
        """doStep's noSetFMUStatePriorToCurrentPoint, for every component (default False)."""
        return bool(self._state.no_prior)

    @no_set_state_prior_to_current_point.setter
    def no_set_state_prior_to_current_point(self, value: bool) -> None:
        self._state.no_prior = 1 if value else 0

    def run(self, k0: int, k_end: int) -> tuple[int, int]:
        """Samples k0 .. k_end - 1 (k_end <= n + 1): (DONE, k_end), (FMI_FAILED, k) with k the
        sample whose call failed (`failure()` names it), (NOT_FINITE, k) with k the sample whose
        guarded value was not finite (`refusal()`), or (HAND_BACK, k) with k the sample a
        native controller hands to the Python execution (`give_back()`; no doStep of it made).
        What a component run in Python raised at sample k is raised here (a SlaveError with its
        `k`), as the Python execution raises it."""
        if not 0 <= k0 <= k_end <= self.n + 1:
            raise ValueError(f"samples {k0} .. {k_end - 1} are not within 0 .. {self.n}")
        self._state.k = k0
        self._synced.clear()  # the C's memory moves on from what any slave holds
        callbacks = self._callbacks
        if callbacks is None:
            code = self._library.system_run(self._pointer, k_end)
        else:
            with callbacks.catching():
                code = self._library.system_run(self._pointer, k_end)
            if code == RAISED:
                for c in callbacks.turns:  # the run ends here, or goes on from a checkpoint put back
                    self._table[c].pending = 0
                callbacks.reraise(self.plan.order[int(self._state.failed)], int(self._state.k))
            self._finish(code)
        return code, int(self._state.k)

    def _finish(self, code: int) -> None:
        """The late inputs and doStep still to make of each component run in Python (`pending`),
        as the Python execution makes them before the loop's next call: of the sample before
        the one the loop stopped at, or of that sample when a doStep of it failed."""
        s = self._state
        k = int(s.k) if code == FMI_FAILED and int(s.fault) == _CALLS_STEP else int(s.k) - 1
        pending = [(c, turn) for c, turn in self._callbacks.turns.items() if self._table[c].pending]
        for c, _ in pending:  # none left for the loop's next call, whatever these raise
            self._table[c].pending = 0
        for c, turn in pending:
            self._calling[0] = self._table[c].id
            try:
                turn.finish(k)
            except SlaveError as error:
                error.k = k
                raise

    @property
    def native_names(self) -> tuple[str, ...]:
        """The components the loop runs natively (`system_natives`), in plan order."""
        return tuple(self.plan.order[slot.c] for slot in self._natives)

    @property
    def in_python(self) -> tuple[tuple[str, str], ...]:
        """The components the loop calls back into Python for (`system_python`), in plan order:
        (name, why it is not run in C)."""
        return tuple(
            (self.plan.order[c], f.why) for c, f in enumerate(self._functions) if isinstance(f, PythonComponent)
        )

    def give_back(self) -> None:
        """After HAND_BACK at sample k: each native controller's slave holds again what it held at
        the start of sample k, so the Python execution takes the run from that sample."""
        for slot in self._natives:
            native = slot.native
            native.slave.resume(native.given_back(slot.state[: native.n_state], slot.saved[:]))

    def take_back(self) -> None:
        """Between samples: each native controller's slave holds what the C holds now (so a
        checkpoint saves it, or the Python execution takes the next sample from it)."""
        for slot in self._natives:
            native = slot.native
            native.slave.resume(native.given_back(slot.state[: native.n_state], slot.memory[:]))
            self._synced[native.slave.name] = native.slave.changes

    def hand_over(self) -> None:
        """Between samples: the C holds what each native controller's slave holds now (a
        checkpoint put back, a sample the Python execution took); `take_back`'s inverse, bit for bit."""
        for slot in self._natives:
            native, memory, state = slot.native, slot.memory, slot.state
            if self._synced.get(native.slave.name) == native.slave.changes:  # it holds what the C holds
                continue
            held = native.slave.sample_state()
            values = [1.0 if held.dirty else 0.0, *held.held, *held.row, *native.state_values(held.next)]
            if len(values) != len(memory):
                raise ValueError(f"component {native.slave.name!r}: its state does not fit its native memory")
            memory[:] = values
            committed = native.state_values(held.state)
            state[: len(committed)] = committed

    def refusal(self) -> SlaveError:
        """The guard's error of the last `run` that returned NOT_FINITE (`guard.refusal`): the
        Python execution's, word for word."""
        s = self._state
        slot, k = int(s.fault), int(s.k)
        error = refusal(self.plan, int(s.failed), slot, float(self.buffer[slot]), k * self.T_s)
        error.k = k
        return error

    def failure(self) -> ComponentCallError:
        """The error of the failed call of the last `run` that returned FMI_FAILED."""
        s = self._state
        c, fault = int(s.failed), int(s.fault)
        names = self._functions[c].names
        if fault >= _TYPED:
            function = self._functions[c].reads[fault - _TYPED].name
        else:
            function = getattr(names, _CALLS[fault])
        return ComponentCallError(self.plan.order[c], function, int(s.status), int(s.k) * self.T_s)


def compiled_system(
    plan: Plan,
    slaves: Sequence[object],
    signals: np.ndarray,
    trace: np.ndarray,
    n: int,
    T_s: float,
    rows: np.ndarray | None = None,
    calling: np.ndarray | None = None,
    ids: Sequence[int] | None = None,
    guard: FiniteGuard | None = None,
) -> SystemLoop | str:
    """The compiled loop over `slaves` (in plan.order, instantiated and initialised): each with a
    `c_functions()` in the plan's order (as `cosim.execution.slaves.FmuSlave` has) called from C, a
    `ControllerSlave` whose controller runs natively in C (`system_natives`), every other one
    called back into Python (`system_python.PythonComponent`, its `why` the line saying why it
    is not in C); or why there is none (the library is missing). `rows`, `calling`, `ids`,
    `guard`: as for `SystemLoop`."""
    library = system_library()
    if library is None:
        return f"no compiled system loop: {system_library_reason()}"
    functions: list[CFunctions | NativeController | PythonComponent] = []
    for c, slave in enumerate(slaves):
        if isinstance(slave, ControllerSlave):
            native = native_controller(slave, plan.input_names[c], n, T_s)
            if isinstance(native, str):
                native = PythonComponent(slave, f"{type(slave.controller).__name__}: {native}")
            functions.append(native)
            continue
        make = getattr(slave, "c_functions", None)
        calls = make() if callable(make) else None
        if not isinstance(calls, CFunctions):
            calls = PythonComponent(slave, f"{type(slave).__name__}: it has no C calls")
        functions.append(calls)
    return SystemLoop(plan, functions, signals, trace, n, T_s, library, rows, calling, ids, guard)
