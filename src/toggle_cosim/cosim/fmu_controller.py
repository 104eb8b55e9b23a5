"""A controller FMU (FMI 2.0 or 3.0 Co-Simulation) as one more controller of the protocol
(`control.protocol`): the scenario key ``controller: {fmu: PATH, parameters: {...}}``.

    start:  extract -> instantiate -> setupExperiment (0, t_end) -> parameters -> initialise
    step k: (k > 0: doStep(t_{k-1}, T_s)) -> set the inputs from the measurement -> get iq_ref
            and the diagnostics
    close:  terminate -> free the instance and the library -> remove the unzipped copy

The FMU is loaded by `start`, in the process that runs the loop (a supervised run's child), never
when the controller is built (the parent only reads what `plant.controller_contract` checked).
Sample k's doStep is made when sample k + 1 is asked for, so the FMU is never stepped past the
last sample (nor past stopTime = t_end); its time is the master's t_k = k T_s, so an FMU that
samples at its communication points sees the same times. The inputs are the plant's outputs of
the same name; the diagnostics are its outputs other than iq_ref, in model-description order.

The hot calls go straight to the FMU's C functions with value-reference and value arrays built
once (as `session` does for the plant). A status other than OK or Warning ends the run as a
controller failure (`ControllerFmuError`) whose reason holds the FMU's last log line (the FMU
is instantiated with logging on: some, PythonFMU's among them, log a failure's cause only then;
its messages of status OK are dropped).
After a fatal status the FMU is not called again, not even to free it (FMI 2.0, 2.1.3); its
unzipped copy is removed all the same. The master
calls `close` on every exit path; `start` after `close` loads the FMU again.
"""

from __future__ import annotations

import ctypes
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from fmpy import extract

from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.control.trajectory import SampledReference
from toggle_cosim.controller_fmu.variables import REFERENCE_INPUTS
from toggle_cosim.cosim.session import CFunctions, FunctionNames, bound_function
from toggle_cosim.plant.controller_contract import COMMAND, ControllerFmu
from toggle_cosim.plant.fmi_calls import (
    FATAL,
    FMU2SlaveChecked,
    FMU3SlaveChecked,
    failed,
    last_log_line,
    logger3,
    quiet,
    typed_setter,
)

__all__ = ["ControllerFmuError", "FmuController"]


class ControllerFmuError(Exception):
    """The controller FMU refused a call; str() names the call, the status and its last log line."""


class FmuController:
    """A controller FMU run by our master (module docstring).

    Args:
        fmu: the checked FMU (`plant.controller_contract.check_controller_fmu`).
        settings: (name, value) set before initialisation, in order.
        T_s: the sample time [s]: every doStep is T_s long.
        t_end: the end of the run [s] (setupExperiment's stop time).
        instance_name: the FMU instance's name (its log lines are printed under it).
        reference: the trajectory the FMU tracks (the built-in law's FMU with tracking = 1): each
            sample also sets its inputs x_ref, v_ref, a_ref to the reference's row at t (the
            rows the compiled loop reads); None: they are left at their start values.
    """

    def __init__(
        self,
        fmu: ControllerFmu,
        settings: Sequence[tuple[str, Any]],
        T_s: float,
        t_end: float,
        instance_name: str = "controller",
        reference: SampledReference | None = None,
    ) -> None:
        self.fmu = fmu
        self.reference = reference
        self.settings = tuple(settings)
        self.T_s, self.t_end = float(T_s), float(t_end)
        self.instance_name = instance_name
        self.diagnostics: tuple[str, ...] = fmu.diagnostics
        self.measured: tuple[str, ...] = fmu.inputs  # the plant outputs it reads
        self._slave: Any = None
        self._unzipped: Path | None = None
        self._component: Any = None
        self._fatal = False  # the FMU returned fmi2Fatal / fmi3Fatal

    # -- life cycle ---------------------------------------------------------------------------
    @property
    def loaded(self) -> bool:
        """True from `start` to `close`: the FMU's copy is unzipped and its library loaded."""
        return self._unzipped is not None

    def _fail(self, function: str, status: object) -> ControllerFmuError:
        if status == FATAL:  # FMI: no further call to any instance of the FMU, not even to free it
            self._fatal = True
        line = last_log_line(self.instance_name)
        said = f"; it logged {' '.join(line.split())}" if line else " (it logged nothing)"
        return ControllerFmuError(f"{self.fmu.path.name}: {function} returned status {status}{said}")

    def _load(self) -> None:
        fmu = self.fmu
        is_fmi3 = fmu.fmi_version.startswith("3")
        self._unzipped = Path(extract(str(fmu.path)))
        kwargs = dict(
            unzipDirectory=str(self._unzipped),
            modelIdentifier=fmu.model_identifier,
            instanceName=self.instance_name,
            guid=fmu.token,  # fmpy passes FMI 3.0's instantiationToken as guid
        )
        slave = (FMU3SlaveChecked if is_fmi3 else FMU2SlaveChecked)(**kwargs)
        self._slave = slave
        last_log_line(self.instance_name, forget=True)
        quiet(self.instance_name)
        if is_fmi3:
            slave.instantiate(visible=False, loggingOn=True, logMessage=logger3(self.instance_name))
        else:
            slave.instantiate(visible=False, loggingOn=True)
        self._component = slave.component
        prefix = "fmi3" if is_fmi3 else "fmi2"
        self._names = (
            (f"{prefix}SetFloat64", f"{prefix}GetFloat64", f"{prefix}DoStep")
            if is_fmi3
            else ("fmi2SetReal", "fmi2GetReal", "fmi2DoStep")
        )
        self._set, self._get, self._step = (bound_function(slave.dll, name) for name in self._names)
        if None in (self._set, self._get, self._step):
            raise ControllerFmuError(f"{fmu.path.name}: the library does not export {', '.join(self._names)}")
        self._is_fmi3 = is_fmi3
        inputs, outputs = fmu.inputs, (COMMAND, *fmu.diagnostics)
        if self.reference is not None:  # then x_ref, v_ref, a_ref, from the reference
            inputs = (*inputs, *REFERENCE_INPUTS)
        self._in_vr = (ctypes.c_uint32 * len(inputs))(*(fmu.references[name] for name in inputs))
        self._in_val = (ctypes.c_double * len(inputs))()
        self._n_in = len(inputs)
        self._out_vr = (ctypes.c_uint32 * len(outputs))(*(fmu.references[name] for name in outputs))
        self._out_val = (ctypes.c_double * len(outputs))()
        self._n_out = len(outputs)
        if is_fmi3:  # doStep's output arguments, built once
            self._step_outputs = tuple(ctypes.byref(ctypes.c_bool()) for _ in range(3)) + (
                ctypes.byref(ctypes.c_double()),
            )

    def _call(self, function: str, call: Any) -> None:
        try:
            call()
        except Exception as error:  # noqa: BLE001 - fmpy's FMICallException, or a bad value
            raise self._fail(function, getattr(error, "status", type(error).__name__)) from None

    def _initialise(self) -> None:
        slave = self._slave
        if self._is_fmi3:
            for name, value in self.settings:
                self._set_value(name, value)
            self._call(
                "fmi3EnterInitializationMode", lambda: slave.enterInitializationMode(startTime=0.0, stopTime=self.t_end)
            )
        else:
            self._call("fmi2SetupExperiment", lambda: slave.setupExperiment(startTime=0.0, stopTime=self.t_end))
            for name, value in self.settings:
                self._set_value(name, value)
            self._call("fmi2EnterInitializationMode", slave.enterInitializationMode)
        self._call(f"{'fmi3' if self._is_fmi3 else 'fmi2'}ExitInitializationMode", slave.exitInitializationMode)

    def _set_value(self, name: str, value: Any) -> None:
        kind = self.fmu.types[name]
        found = typed_setter(self._slave, kind, value)
        if found is None:
            raise ControllerFmuError(f"{self.fmu.path.name}: parameter {name!r} is of type {kind}, which cannot be set")
        setter, value = found
        try:
            setter([self.fmu.references[name]], [value])
        except Exception as error:  # noqa: BLE001 - name the parameter and the value
            line = last_log_line(self.instance_name)
            said = f"; it logged {' '.join(line.split())}" if line else ""
            raise ControllerFmuError(
                f"{self.fmu.path.name}: setting parameter {name} = {value!r} failed ({error}){said}"
            ) from None

    def close(self) -> None:
        """Terminate and free the instance, whatever state it is in, unload the library and delete
        the unzipped copy (safe to call more than once, and before `start`)."""
        slave, self._slave = self._slave, None
        folder, self._unzipped = self._unzipped, None
        fatal, self._fatal = self._fatal, False
        try:
            if fatal:
                pass  # the instance and its library are left as they are (the run's process ends soon)
            elif slave is not None and self._component is not None:
                try:
                    slave.terminate()
                except Exception:  # noqa: BLE001, S110 - an FMU in error state may refuse terminate
                    pass
                slave.freeInstance()  # fmpy's: the instance freed, then the library unloaded
            elif slave is not None:
                slave.freeLibrary()
        except Exception:  # noqa: BLE001, S110 - freeing never fails the run's outcome
            pass
        finally:
            self._component = None
            if folder is not None:
                shutil.rmtree(folder, ignore_errors=True)
            last_log_line(self.instance_name, forget=True)
            quiet(self.instance_name, on=False)

    def failure(self, call: str, t: float, status: int) -> ControllerFmuError:
        """The error `step` raises when its call ("step", "set" or "get") returns `status` at
        the sample t (for "step": the sample the doStep starts from); the compiled loop raises it too."""
        function = self._names[("set", "get", "step").index(call)]
        return self._fail(f"{function} at t = {t:.6g} s", status)

    def c_functions(self) -> CFunctions | None:
        """What the compiled loop calls from C (its inputs and outputs in `measured` and
        (iq_ref, *diagnostics) order), or None when not loaded."""
        if self._component is None:
            return None
        names = FunctionNames(set=self._names[0], get=self._names[1], step=self._names[2])
        return CFunctions.of(
            (self._get, self._set, self._step), self._component, self._out_vr, self._in_vr, self._is_fmi3, names, self
        )

    # -- the protocol -------------------------------------------------------------------------
    def start(self, t0: float, measurement: Mapping[str, float]) -> float | None:
        """Load, instantiate and initialise the FMU (afresh if it was loaded); the state is the
        time of the previous sample (None before the first)."""
        if self.loaded:
            self.close()
        try:
            self._load()
            self._initialise()
        except BaseException:
            self.close()
            raise
        return None

    def step(self, state: float | None, t: float, measurement: Mapping[str, float]) -> ControlStep:
        """The FMU's command and diagnostics at the sample t: the previous sample's doStep (from
        `state` over T_s), the inputs set from `measurement`, the outputs read."""
        component, is_fmi3 = self._component, self._is_fmi3
        if state is not None:
            if is_fmi3:
                status = self._step(component, state, self.T_s, False, *self._step_outputs)
            else:
                status = self._step(component, state, self.T_s, 0)
            if failed(status):
                raise self.failure("step", state, status)
        values = self._in_val
        for j, name in enumerate(self.measured):
            values[j] = measurement[name]
        if self.reference is not None:
            j = len(self.measured)
            values[j], values[j + 1], values[j + 2] = self.reference.at(t)
        n_in, n_out, out = self._n_in, self._n_out, self._out_val
        if n_in:
            status = (
                self._set(component, self._in_vr, n_in, values, n_in)
                if is_fmi3
                else self._set(component, self._in_vr, n_in, values)
            )
            if failed(status):
                raise self.failure("set", t, status)
        status = (
            self._get(component, self._out_vr, n_out, out, n_out)
            if is_fmi3
            else self._get(component, self._out_vr, n_out, out)
        )
        if failed(status):
            raise self.failure("get", t, status)
        return ControlStep(out[0], tuple(out[1:n_out]), t)
