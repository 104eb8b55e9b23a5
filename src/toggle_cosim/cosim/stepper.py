"""Steppers: what runs samples k .. stop - 1 of the loop (read outputs, control, record, set
inputs, doStep). Every stepper writes into the same `Recorder` and shares one `LoopState`, so
one can take over from another at any sample.

* `PythonStepper`: the loop in Python over the `PlantSession` and the `VSCController`.
* `CompiledStepper`: the same loop in C (`compiled_loop`, generated from `control.laws`),
  stopping at every sample a step hook wants to see.
* `HandOver`: the compiled stepper while it can, then, from a sample the C hands back (non-
  finite outputs, a law that raises there), the Python stepper. It says which loop ran, and why.

A failed doStep raises `StepFailed` (sample k recorded, its step not made), which the
checkpoint policy (`retry`) may retry; any other FMI failure raises fmpy's FMICallException.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Protocol

from fmpy.fmi1 import FMICallException

from toggle_cosim.control.controller import ControllerState, VSCController
from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.cosim.compiled_loop import FMI_FAILED, HAND_BACK, CompiledLoop, kernel_library, kernel_reason
from toggle_cosim.cosim.recorder import Recorder, StepHook
from toggle_cosim.cosim.session import PlantSession

PHASES = {"reaching": 0.0, "sliding": 1.0}


class StepFailed(Exception):
    """doStep failed at sample k (after sample k was recorded)."""

    def __init__(self, k: int, error: FMICallException) -> None:
        super().__init__(str(error))
        self.k, self.error = k, error


@dataclass
class LoopState:
    """What the steppers share: the controller's state, the law's state z at the next sample,
    and why the run ended early (non-finite outputs), if it did."""

    controller: ControllerState | None = None
    z: float = 0.0
    reason: str | None = None


class Stepper(Protocol):
    def advance(self, k: int, stop: int) -> int:
        """Samples k .. stop - 1; the next sample, or -1 when the run ended (state.reason says why)."""
        ...


@dataclass
class Timing:
    """The sampling of a run: n + 1 samples 0 .. n, T_s apart; F_E the constant load input."""

    n: int
    T_s: float
    F_E: float


class PythonStepper:
    def __init__(
        self,
        session: PlantSession,
        controller: VSCController,
        recorder: Recorder,
        timing: Timing,
        state: LoopState,
        hooks: Sequence[StepHook] = (),
    ) -> None:
        self.session, self.controller, self.recorder = session, controller, recorder
        self.timing, self.state, self.hooks = timing, state, tuple(hooks)

    def advance(self, k0: int, k_end: int, read_first: bool = True) -> int:
        """As Stepper.advance; with read_first False the outputs of sample k0 are in the trace
        already (read by the compiled loop before it handed the sample back)."""
        rec, st = self.recorder, self.state
        data, n_out, i_x, i_v, col_u = rec.data, rec.n_out, rec.i_x, rec.i_v, rec.col_u
        T_s, n, F_E = self.timing.T_s, self.timing.n, self.timing.F_E
        read_outputs, write_inputs, do_step = self.session.read_outputs, self.session.write_inputs, self.session.do_step
        control_step, isfinite, hooks = self.controller.step, math.isfinite, self.hooks
        state, z = st.controller, st.z
        try:
            for k in range(k0, k_end):
                t = k * T_s
                row = data[k]
                row[0] = t
                if read_first or k != k0:
                    read_outputs(row[1 : 1 + n_out])
                x_B, v_B = row[i_x], row[i_v]
                if not (isfinite(x_B) and isfinite(v_B)):
                    st.reason = f"plant outputs became non-finite at t = {t:.6g} s"
                    return -1
                if state is None:
                    state = self.controller.start(t, (x_B, v_B))
                    z = state.z
                elif state.z != z:
                    state = replace(state, z=z)
                u, control = control_step(state, t, x_B, v_B)
                z = control.z
                row[col_u : col_u + 5] = (u, F_E, control.S, PHASES[control.phase], control.e)
                rec.rows = k + 1
                if k == n:
                    return k + 1
                write_inputs((u, F_E))
                try:
                    do_step(t, T_s)
                except FMICallException as error:
                    raise StepFailed(k, error) from None
                for hook in hooks:
                    if k % hook.every == 0:
                        hook(k)
            return k_end
        finally:
            st.controller, st.z = state, z


class CompiledStepper:
    """The loop in C over a `CompiledLoop`; `handed_back` is set when the C hands a sample back."""

    def __init__(
        self,
        loop: CompiledLoop,
        session: PlantSession,
        recorder: Recorder,
        timing: Timing,
        state: LoopState,
        hooks: Sequence[StepHook] = (),
    ) -> None:
        self.loop, self.recorder, self.timing, self.state = loop, recorder, timing, state
        self.names = session.function_names
        self.hooks = tuple(hooks)
        self.every = min((hook.every for hook in self.hooks), default=0)
        self.handed_back = False

    @classmethod
    def build(
        cls,
        session: PlantSession,
        recorder: Recorder,
        timing: Timing,
        state: LoopState,
        law: LawParameters,
        hooks: Sequence[StepHook] = (),
    ) -> CompiledStepper | str:
        """The compiled stepper from the current sample on, or why there is none."""
        library = kernel_library()
        functions = session.c_functions()
        if library is None or functions is None:
            return kernel_reason() or "the FMU's C functions are not reachable"
        loop = CompiledLoop(
            library,
            functions,
            recorder.data,
            recorder.n_out,
            recorder.i_x,
            recorder.i_v,
            recorder.col_u,
            timing.n,
            timing.T_s,
            timing.F_E,
            law,
            state.z,
        )
        return cls(loop, session, recorder, timing, state, hooks)

    def advance(self, k: int, stop: int) -> int:
        loop, rec, n, every = self.loop, self.recorder, self.timing.n, self.every
        while k < stop:
            # in C: up to the next sample a hook wants to see, or to the end of the stretch
            end = stop if not every else min(k + (every - k % every) % every + 1, stop)
            code, k = loop.run(k, end)
            if code == FMI_FAILED:  # reading sample k failed, or setting/stepping after recording it
                rec.rows = k if loop.fault_function == self.names.get else k + 1
                error = FMICallException(function=loop.fault_function, status=loop.fault_status)
                if loop.fault_function == self.names.step:
                    raise StepFailed(k, error)
                raise error
            rec.rows = k
            self.state.z = loop.z
            if code == HAND_BACK:
                self.handed_back = True
                return k
            for hook in self.hooks:
                if k - 1 < n and (k - 1) % hook.every == 0:
                    hook(k - 1)
        return k


class HandOver:
    """The compiled stepper, if there is one, then the Python stepper from a handed-back sample."""

    def __init__(self, python: PythonStepper, compiled: CompiledStepper | str) -> None:
        """`compiled`: the compiled stepper, or why there is none (`CompiledStepper.build`)."""
        self.python = python
        self.compiled = compiled if isinstance(compiled, CompiledStepper) else None
        self.loop: dict[str, Any] = (
            {"kind": "compiled", "reason": "generated from control.laws; C compiler available"}
            if self.compiled
            else {"kind": "python", "reason": compiled}
        )

    def advance(self, k: int, stop: int) -> int:
        if self.compiled is None:
            return self.python.advance(k, stop) if 0 < k < stop else k
        k = self.compiled.advance(k, stop)
        if not self.compiled.handed_back:
            return k
        self.compiled = None
        self.loop = {
            "kind": "compiled, then python",
            "reason": f"the compiled loop handed sample {k} (t = {k * self.python.timing.T_s:.6g} s) back to "
            "Python (non-finite outputs, or the law raises there)",
        }
        return self.python.advance(k, stop, read_first=False) if k <= self.python.timing.n else k
