"""Steppers: what runs samples k .. stop - 1 of the loop (read outputs, control, record, set
inputs, doStep). Every stepper writes into the same `Recorder` and shares one `LoopState`, so
one can take over from another at any sample.

* `PythonStepper`: the loop in Python over the `PlantSession` and any controller that meets
  the protocol (`control.protocol`). Where the compiled loop's library is there, the plant's
  set, doStep and the next sample's get are one C call per sample (`PlantExchange`: the same
  FMI calls with the same values, a failure raised as the session raises it); else, or when
  the session's own calls are replaced, the session's three calls.
* `CompiledStepper`: the same loop in C (`compiled_loop`, generated from `control.laws`),
  stopping at every sample a step hook wants to see. It runs the built-in law, calls a
  controller FMU's C functions in the order `FmuController.step` calls them, or runs a
  python-control system's matrices as `control.lti` does (`compiled_controller` says which, or
  why none). A controller FMU's failure in C raises
  the `ControllerFailed` the Python loop raises for it, at the same sample.
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

import numpy as np
from fmpy.fmi1 import FMICallException

from toggle_cosim import interrupts
from toggle_cosim.control.controller import ControllerState, VSCController
from toggle_cosim.control.lti import INPUTS, DiscreteSystemController, LtiState
from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.control.protocol import Controller, ControllerError, ControlStep, Measurement, checked_command
from toggle_cosim.control.trajectory import SampledReference
from toggle_cosim.cosim.compiled_loop import (
    COMMAND_REJECTED,
    CONTROLLER_FAILED,
    FMI_FAILED,
    HAND_BACK,
    CompiledLoop,
    ControllerCalls,
    LtiCalls,
    PlantExchange,
    kernel_library,
    kernel_reason,
)
from toggle_cosim.cosim.fmu_controller import FmuController
from toggle_cosim.cosim.recorder import Recorder, StepHook
from toggle_cosim.cosim.session import PlantSession
from toggle_cosim.messages import error_text


class StepFailed(Exception):
    """doStep failed at sample k (after sample k was recorded)."""

    def __init__(self, k: int, error: FMICallException) -> None:
        super().__init__(str(error))
        self.k, self.error = k, error


class ControllerFailed(Exception):
    """The controller raised, or returned something unusable, at a sample; str() says what."""


@dataclass
class LoopState:
    """What the steppers share: the controller's state at the next sample (None before the
    first), why the run ended early (non-finite outputs), if it did, and under jacobi coupling
    the command and diagnostics of the last sample, held for the next."""

    controller: Any = None
    reason: str | None = None
    held: tuple[float, tuple[float, ...]] | None = None


def _name(function: object) -> str:
    return getattr(function, "__qualname__", repr(function))


def _replaced(controller: object, reference: type, method: str) -> bool:
    """Whether the controller's `method` is not `reference`'s own (overridden by its class, absent,
    or set on the object)."""
    own = getattr(type(controller), method, None)
    return own is not getattr(reference, method) or method in getattr(controller, "__dict__", {})


def compiled_law(controller: object, state: object) -> LawParameters | str:
    """The law the compiled loop may run in place of `controller`, or why it may not.

    The compiled loop is the C translation of `VSCController.step`, so it runs only a controller
    whose start and step *are* those functions (a subclass that overrides either, or an object
    of another class with the same methods, runs in Python at every sample), with the built-in
    diagnostics and a state `VSCController.start` made."""
    only = "the compiled loop runs only the built-in law and controller FMUs"
    for method in ("step", "start"):
        if _replaced(controller, VSCController, method):
            own = getattr(type(controller), method, None)
            return (
                f"the controller's {method} is {_name(own)}, not the built-in law's {_name(getattr(VSCController, method))}: "
                + only
            )
    if getattr(controller, "diagnostics", None) != VSCController.diagnostics:
        return f"the controller's diagnostics are not the built-in law's: {only}"
    if not isinstance(state, ControllerState) or state.law is None:
        return f"the controller's state is not the built-in law's: {only}"
    return state.law


def compiled_controller(
    controller: object, state: object
) -> LawParameters | FmuController | DiscreteSystemController | str:
    """What the compiled loop may run in place of `controller`: the built-in law (`compiled_law`),
    a controller FMU whose C functions it can call (an `FmuController` whose step is
    `FmuController.step`, loaded), a python-control system's adapter whose start and step are
    `DiscreteSystemController`'s (with its diagnostics and a state its start made), or why none."""
    if isinstance(controller, DiscreteSystemController):
        for method in ("step", "start"):
            if _replaced(controller, DiscreteSystemController, method):
                own = getattr(type(controller), method, None)
                return (
                    f"the controller's {method} is {_name(own)}, not {_name(getattr(DiscreteSystemController, method))}: "
                    "the compiled loop runs only the latter's sums"
                )
        if controller.diagnostics != DiscreteSystemController.diagnostics:
            return "the controller's diagnostics are not DiscreteSystemController's: the compiled loop records only e"
        if not (isinstance(state, LtiState) and len(state.x) == controller.matrices.n):
            return "the controller's state is not an LtiState of its system's states"
        return controller
    if not isinstance(controller, FmuController):
        return compiled_law(controller, state)
    if _replaced(controller, FmuController, "step"):
        own = getattr(type(controller), "step", None)
        return (
            f"the controller's step is {_name(own)}, not {_name(FmuController.step)}: "
            "the compiled loop makes only the latter's calls"
        )
    if controller.c_functions() is None:
        return "the controller FMU's C functions are not reachable"
    return controller


class Stepper(Protocol):
    def advance(self, k: int, stop: int) -> int:
        """Samples k .. stop - 1; the next sample, or -1 when the run ended (state.reason says why)."""
        ...


@dataclass
class Timing:
    """The sampling of a run: n + 1 samples 0 .. n, T_s apart; `load` the inputs besides the
    command that sample k sends, load[k] = (F_E, then the plant's other inputs): an (n + 1, m)
    float64 array, C order (`master.input_samples`)."""

    n: int
    T_s: float
    load: np.ndarray


class PythonStepper:
    """The loop in Python over any controller that meets the protocol (`control.protocol`).
    With `jacobi`, the plant gets, and row k records, the command and diagnostics of sample
    k - 1 (sample 0's at k = 0): jacobi coupling (`master`)."""

    def __init__(
        self,
        session: PlantSession,
        controller: Controller,
        recorder: Recorder,
        timing: Timing,
        state: LoopState,
        hooks: Sequence[StepHook] = (),
        jacobi: bool = False,
    ) -> None:
        self.session, self.controller, self.recorder = session, controller, recorder
        self.timing, self.state, self.hooks = timing, state, tuple(hooks)
        self.jacobi = jacobi
        self.load = timing.load.tolist()  # row k: what sample k sends besides the command, as Python floats
        self.index = {name: j for j, name in enumerate(recorder.names[1 : 1 + recorder.n_out], start=1)}
        self._exchange: PlantExchange | None | bool = False  # False: not looked for yet

    def exchange(self) -> PlantExchange | None:
        """The plant's part of a sample in one C call (`PlantExchange`), or None: no compiled loop
        library, the FMU's C functions not reachable, or a session whose read_outputs,
        write_inputs or do_step is not `PlantSession`'s own (then the loop calls those)."""
        if self._exchange is False:
            self._exchange = None
            session, library = self.session, kernel_library()
            if library is not None and isinstance(session, PlantSession):
                if not any(_replaced(session, PlantSession, m) for m in ("read_outputs", "write_inputs", "do_step")):
                    functions = session.c_functions()
                    if functions is not None:
                        rec, timing = self.recorder, self.timing
                        self._exchange = PlantExchange(
                            library, functions, rec.data, rec.n_out, rec.col_u, timing.n, timing.T_s, timing.load
                        )
        return self._exchange

    def _start(self, t: float, measurement: Measurement) -> Any:
        try:
            return self.controller.start(t, measurement)
        except BaseException as error:  # noqa: BLE001 - the user's code: its failure ends the run with the reason
            if not interrupts.raised_by_code(error):
                raise
            raise ControllerFailed(f"the controller's start raised at t = {t:.6g} s: {_error(error)}") from None

    def advance(self, k0: int, k_end: int, read_first: bool = True) -> int:
        """As Stepper.advance; with read_first False the outputs of sample k0 are in the trace
        already (read by the compiled loop before it handed the sample back)."""
        rec, st = self.recorder, self.state
        data, n_out, i_x, i_v, col_u = rec.data, rec.n_out, rec.i_x, rec.i_v, rec.col_u
        T_s, n, load = self.timing.T_s, self.timing.n, self.load
        col_x = rec.col_x
        others = col_x < len(rec.names)  # the plant has inputs besides iq_ref and F_E
        read_outputs, write_inputs, do_step = self.session.read_outputs, self.session.write_inputs, self.session.do_step
        control_step, isfinite, hooks, index = self.controller.step, math.isfinite, self.hooks, self.index
        jacobi = self.jacobi
        n_diagnostics = col_x - col_u - 2
        col_d = col_u + 2  # the first diagnostic's column
        outputs = data[:, 1 : 1 + n_out]  # row k's outputs: outputs[k], a view the session reads into
        state = st.controller
        exchange = self.exchange()
        if exchange is not None:
            exchange.no_set_state_prior_to_current_point = self.session.no_set_state_prior_to_current_point
            call, pointer, STEP = exchange.call, exchange.pointer, exchange.STEP
        ahead = False  # the outputs of sample k are in the trace already (read by the exchange)
        try:
            for k in range(k0, k_end):
                t = k * T_s
                row = data[k]
                row[0] = t
                if ahead:
                    ahead = False
                elif read_first or k != k0:
                    read_outputs(outputs[k])
                if not (isfinite(row[i_x]) and isfinite(row[i_v])):
                    st.reason = f"plant outputs became non-finite at t = {t:.6g} s"
                    return -1
                measurement = Measurement(index, row)
                if state is None:
                    state = self._start(t, measurement)
                try:
                    result = control_step(state, t, measurement)
                except BaseException as error:  # noqa: BLE001 - the user's code: its failure ends the run
                    if not interrupts.raised_by_code(error):
                        raise
                    raise step_raised(t, error) from None
                try:
                    u, diagnostics, state = checked_command(result, n_diagnostics, t)
                except ControllerError as error:
                    raise ControllerFailed(str(error)) from None
                if jacobi:  # the previous sample's outputs now, this sample's at the next
                    held = st.held if st.held is not None else (u, diagnostics)
                    st.held = (u, diagnostics)
                    u, diagnostics = held
                sent = load[k]  # F_E, then the other inputs
                row[col_u] = u
                row[col_u + 1] = sent[0]
                if n_diagnostics == 1:
                    row[col_d] = diagnostics[0]
                elif n_diagnostics:
                    row[col_d:col_x] = diagnostics
                if others:
                    row[col_x:] = sent[1:]
                rec.rows = k + 1
                if k == n:
                    return k + 1
                due = [hook for hook in hooks if k % hook.every == 0] if hooks else ()
                if exchange is None:
                    write_inputs((u, *sent))
                    try:
                        do_step(t, T_s)
                    except FMICallException as error:
                        raise StepFailed(k, error) from None
                else:  # sample k + 1's outputs read here too, unless a hook sees sample k first
                    ahead = not due and k + 1 < k_end
                    code = call(pointer, k, u, ahead)
                    if code:
                        if code == STEP:
                            raise StepFailed(k, exchange.failure(code))
                        raise exchange.failure(code)  # set: at sample k; get: of sample k + 1, as read there
                for hook in due:
                    hook(k)
            return k_end
        finally:
            st.controller = state


def step_raised(t: float, error: BaseException) -> ControllerFailed:
    """The failure of a controller whose step raised `error` at the sample t."""
    return ControllerFailed(f"the controller's step raised at t = {t:.6g} s: {_error(error)}")


def _error(error: BaseException) -> str:
    return error_text(error, 300)  # with the sentence around it, within the reason's bound


class CompiledStepper:
    """The loop in C over a `CompiledLoop`; `handed_back` is set when the C hands a sample back.
    `controller`: the controller FMU the loop calls (None: the generated law)."""

    def __init__(
        self,
        loop: CompiledLoop,
        session: PlantSession,
        recorder: Recorder,
        timing: Timing,
        state: LoopState,
        hooks: Sequence[StepHook] = (),
        controller: FmuController | DiscreteSystemController | None = None,
    ) -> None:
        self.loop, self.recorder, self.timing, self.state = loop, recorder, timing, state
        self.names = session.function_names
        self.hooks = tuple(hooks)
        self.every = min((hook.every for hook in self.hooks), default=0)
        self.handed_back = False
        self.controller = controller
        if controller is None:
            self.reason = "the built-in law, generated from control.laws; C compiler available"
        elif isinstance(controller, DiscreteSystemController):
            self.reason = (
                f"the python-control system ({controller.matrices.n} states, inputs "
                f"{INPUTS[controller.matrices.m]}) as matrices in C, summed as control.lti sums them; C compiler available"
            )
        else:
            self.reason = (
                f"the controller FMU {controller.fmu.path.name}, called from C through its function pointers; "
                "C compiler available"
            )

    @classmethod
    def build(
        cls,
        session: PlantSession,
        recorder: Recorder,
        timing: Timing,
        state: LoopState,
        law: LawParameters | FmuController | DiscreteSystemController,
        measured: tuple[str, ...],
        hooks: Sequence[StepHook] = (),
        reference: SampledReference | None = None,
    ) -> CompiledStepper | str:
        """The compiled stepper from the current sample on, or why there is none. `law` is the
        built-in law to run, the controller FMU to call, or the python-control system's adapter
        (`compiled_controller`), `measured` the plant outputs it reads, `reference` the trajectory
        the built-in law tracks (its `VSCController.reference`; None: the constant target; a
        controller FMU's and a python-control system's are their own)."""
        if isinstance(law, (FmuController, DiscreteSystemController)):
            reference = law.reference
        if reference is not None and (reference.T_s != timing.T_s or reference.values.shape != (timing.n + 1, 3)):
            return "the law's reference is not sampled on the run's grid (T_s, t_end): the Python loop evaluates it"

        library = kernel_library()
        functions = session.c_functions()
        if library is None or functions is None:
            return kernel_reason() or "the FMU's C functions are not reachable"
        names = recorder.names
        controller: ControllerCalls | LtiCalls | None
        if isinstance(law, DiscreteSystemController):
            controller = LtiCalls(law.matrices, names.index(law.output), law.target, state.controller)
            i_q, i_qd, parameters, z = recorder.i_x, recorder.i_v, None, 0.0
        elif isinstance(law, FmuController):
            calls = law.c_functions()
            if calls is None:
                return "the controller FMU's C functions are not reachable"
            # the reference inputs x_ref, v_ref, a_ref: columns -1, -2, -3 (the reference's row k)
            feed = (-1, -2, -3) if reference is not None else ()
            controller = ControllerCalls(
                calls, (*(names.index(name) for name in measured), *feed), 1 + len(law.diagnostics), state.controller
            )
            i_q, i_qd, parameters, z = recorder.i_x, recorder.i_v, None, 0.0
        else:
            controller = None
            i_q, i_qd, parameters, z = names.index(measured[0]), names.index(measured[1]), law, state.controller.z
        loop = CompiledLoop(
            library,
            functions,
            recorder.data,
            recorder.n_out,
            i_q,
            i_qd,
            recorder.col_u,
            timing.n,
            timing.T_s,
            timing.load,
            parameters,
            z,
            controller,
            None if reference is None else reference.values,
            recorder.count,
        )
        return cls(loop, session, recorder, timing, state, hooks, law if controller is not None else None)

    def _sync(self) -> None:
        """The shared controller state from the C's: the law's integrator, the LTI system's
        state, or the controller FMU's last sample."""
        if isinstance(self.controller, DiscreteSystemController):
            self.state.controller = self.loop.lti_state()
            return
        if self.controller is not None:
            self.state.controller = self.loop.controller_time
            return
        controller = self.state.controller
        if self.loop.z != controller.z:
            self.state.controller = replace(controller, z=self.loop.z)

    def _controller_failed(self, code: int, k: int) -> ControllerFailed:
        """The failure the Python loop raises for the controller FMU at sample k (not recorded)."""
        t = k * self.timing.T_s
        if code == COMMAND_REJECTED:
            u, *diagnostics = self.loop.controller_outputs()
            try:
                checked_command(ControlStep(u, tuple(diagnostics), t), len(diagnostics), t)
            except ControllerError as error:
                return ControllerFailed(str(error))
            return ControllerFailed(f"the controller's command at t = {t:.6g} s was rejected by the compiled loop")
        call, status = self.loop.fault_function, self.loop.fault_status
        at = self.loop.controller_time if call == "step" else t
        return step_raised(t, self.controller.failure(call, at, status))

    def advance(self, k: int, stop: int) -> int:
        loop, rec, n, every = self.loop, self.recorder, self.timing.n, self.every
        while k < stop:
            # in C: up to the next sample a hook wants to see, or to the end of the stretch
            end = stop if not every else min(k + (every - k % every) % every + 1, stop)
            code, k = loop.run(k, end)
            if code == FMI_FAILED:  # reading sample k failed, or setting/stepping after recording it
                rec.rows = k if loop.fault_function == self.names.get else k + 1
                if self.controller is not None:  # sample k's controller call made: a retry goes on from it
                    self._sync()
                error = FMICallException(function=loop.fault_function, status=loop.fault_status)
                if loop.fault_function == self.names.step:
                    raise StepFailed(k, error)
                raise error
            rec.rows = k
            self._sync()
            if code in (CONTROLLER_FAILED, COMMAND_REJECTED):
                raise self._controller_failed(code, k)
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
            {"kind": "compiled", "reason": self.compiled.reason}
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
