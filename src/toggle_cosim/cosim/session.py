"""One instance of a plant FMU (FMI 2.0 or 3.0 Co-Simulation), with a public API for the master.

    instantiate -> set_value ... -> enter_initialization -> write_inputs -> exit_initialization
    -> (read_outputs, write_inputs, do_step)* -> close

fmpy's `FMU2Slave.getReal([..])` builds ctypes arrays on every call, and each of its `fmi2*`
methods goes through a Python `_call` that looks the function up, optionally logs, and checks
the status. Here the value-reference arrays and value buffers are built once, and the hot
calls go straight to the FMU's C functions (bound here from fmpy's loaded library `dll` with
their FMI prototypes). Any status but OK and Warning (`fmi_calls`: also values the standard does
not define) raises fmpy's `FMICallException` naming the function, in these calls and in every
other call fmpy makes for us; the FMU's log messages go through our logger (`fmi_calls`).

`c_functions()` hands the same pointers and buffers to the compiled loop (`compiled_loop`).

A session may serve run after run (a sweep worker keeps its plant loaded): `release(reuse=True)`
after a complete run terminates the instance and brings it back with fmi2Reset / fmi3Reset to
the state instantiation leaves, and the next `instantiate` only sets up the experiment; after a
failed run, or when the FMU refuses the reset, the instance is freed and the next `instantiate`
makes a new one from the binary already loaded. `close()` frees it and deletes the unzipped copy.
`no_set_state_prior_to_current_point` is the flag passed to every doStep; it stays False
(history kept) unless a checkpoint policy that never restores sets it True (`retry`).
"""

from __future__ import annotations

import ctypes
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import extract
from fmpy.fmi1 import FMICallException

from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.plant.fmi_calls import (
    FATAL,
    FMU2SlaveChecked,
    FMU3SlaveChecked,
    failed,
    last_error_message,
    last_log_line,
    logger3,
)

_VR, _DOUBLES = ctypes.POINTER(ctypes.c_uint32), ctypes.POINTER(ctypes.c_double)
_BOOL_OUT = ctypes.POINTER(ctypes.c_bool)
# The FMI prototypes of the three hot functions (fmi2FunctionTypes.h, fmi3FunctionTypes.h).
_PROTOTYPES = {
    "fmi2GetReal": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES),
    "fmi2SetReal": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES),
    "fmi2DoStep": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int),
    "fmi3GetFloat64": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES, ctypes.c_size_t),
    "fmi3SetFloat64": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, _VR, ctypes.c_size_t, _DOUBLES, ctypes.c_size_t),
    "fmi3DoStep": ctypes.CFUNCTYPE(
        ctypes.c_int,
        ctypes.c_void_p,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_bool,
        _BOOL_OUT,
        _BOOL_OUT,
        _BOOL_OUT,
        _DOUBLES,
    ),
}


def bound_function(dll: Any, name: str):  # noqa: ANN201 - a ctypes function pointer, or None
    """The FMU library's exported C function `name` (fmi2GetReal, fmi3DoStep, ...) with its FMI
    prototype, called directly (no fmpy wrapper), or None if the library does not export it."""
    try:
        return _PROTOTYPES[name]((name, dll))
    except (AttributeError, TypeError):
        return None


@dataclass(frozen=True)
class FunctionNames:
    """The FMI names of the hot functions, for error messages (fmi2GetReal / fmi3GetFloat64, ...)."""

    get: str
    set: str
    step: str


@dataclass(frozen=True)
class CFunctions:
    """What the compiled loop needs to call the FMU from C: addresses of the three functions,
    the instance, and the value-reference arrays (kept alive by `owner`)."""

    get: int
    set: int
    step: int
    component: int
    out_vr: int
    in_vr: int
    fmi3: bool
    names: FunctionNames
    owner: Any
    reads: tuple[Any, ...] = ()  # a system's typed reads after the Real outputs (`fmi_pointers.TypedRead`)

    @classmethod
    def of(
        cls,
        functions: tuple[Any, Any, Any],
        component: int,
        out_vr: Any,
        in_vr: Any,
        fmi3: bool,
        names: FunctionNames,
        holder: object = None,
    ) -> CFunctions:
        """From the bound (get, set, step) functions (`bound_function`), the instance and the
        value-reference arrays (ctypes arrays), all kept alive by the result (and `holder`, the
        object that owns them)."""
        get, set_, step = (ctypes.cast(f, ctypes.c_void_p).value for f in functions)
        return cls(
            get=get,
            set=set_,
            step=step,
            component=component,
            out_vr=ctypes.addressof(out_vr),
            in_vr=ctypes.addressof(in_vr),
            fmi3=fmi3,
            names=names,
            owner=(holder, functions, out_vr, in_vr),
        )


class PlantSession:
    """One instance of a plant FMU: set parameters, initialise, then read/write/step."""

    def __init__(self, plant: PlantInterface, instance_name: str, outputs: list[str], inputs: list[str]) -> None:
        self.plant = plant
        self.instance_name = instance_name
        self._unzipped = Path(extract(str(plant.path)))
        md = plant.model_description
        self.is_fmi3 = plant.fmi_version.startswith("3")
        kwargs = dict(
            unzipDirectory=str(self._unzipped), modelIdentifier=plant.model_identifier, instanceName=instance_name
        )
        try:
            if self.is_fmi3:
                # fmpy passes the instantiationToken of FMI 3.0 under the name guid
                self.fmu = FMU3SlaveChecked(guid=md.instantiationToken, **kwargs)
            else:
                self.fmu = FMU2SlaveChecked(guid=md.guid, **kwargs)
        except BaseException:
            shutil.rmtree(self._unzipped, ignore_errors=True)
            raise
        self._instantiated = False
        self._was_reset = False  # an instance kept by release(reuse=True), in the state instantiation leaves
        self.fatal = False  # the FMU answered Fatal to reset: FMI allows no further call to its binary
        ref = plant.references
        self._out_vr = (ctypes.c_uint32 * len(outputs))(*(ref[n] for n in outputs))
        self._out_val = (ctypes.c_double * len(outputs))()
        self._out_view = np.frombuffer(self._out_val, dtype=np.float64)
        self._n_out = len(outputs)
        self.inputs = tuple(inputs)  # the names write_inputs sets, in order
        self._in_vr = (ctypes.c_uint32 * len(inputs))(*(ref[n] for n in inputs))
        self._in_val = (ctypes.c_double * len(inputs))()
        self._n_in = len(inputs)
        prefix = "fmi3" if self.is_fmi3 else "fmi2"
        self.function_names = FunctionNames(
            get=f"{prefix}GetFloat64" if self.is_fmi3 else "fmi2GetReal",
            set=f"{prefix}SetFloat64" if self.is_fmi3 else "fmi2SetReal",
            step=f"{prefix}DoStep",
        )
        names = self.function_names
        self._get, self._set, self._step = (self._c_function(name) for name in (names.get, names.set, names.step))
        if self.is_fmi3:  # doStep's output arguments, built once
            self._event = ctypes.c_bool()
            self._terminate = ctypes.c_bool()
            self._early = ctypes.c_bool()
            self._last_time = ctypes.c_double()
            self._step_outputs = (
                ctypes.byref(self._event),
                ctypes.byref(self._terminate),
                ctypes.byref(self._early),
                ctypes.byref(self._last_time),
            )
        self._component = None
        self._saved = None  # the checkpoint, an fmi2FMUstate / fmi3FMUState
        # False: the FMU keeps its history (a checkpoint before the current point may be restored).
        self.no_set_state_prior_to_current_point = False

    def _c_function(self, name: str):  # noqa: ANN202 - a ctypes function pointer, or None
        """The FMU's exported C function `name` with its FMI prototype, or None if not exported."""
        return bound_function(self.fmu.dll, name)

    # -- life cycle ---------------------------------------------------------------------------
    @property
    def is_instantiated(self) -> bool:
        return self._instantiated

    def instantiate(self, start: float, stop: float) -> None:
        last_log_line(self.instance_name, forget=True)  # a failure's reason tells only this run's messages
        if self._was_reset:  # the instance kept by release(reuse=True)
            self._was_reset = False
            if not self.is_fmi3:
                self.fmu.setupExperiment(startTime=start, stopTime=stop)
            self._start, self._stop = start, stop
            return
        if self.is_fmi3:  # errors are logged with logging off too; kept under the instance's name
            self.fmu.instantiate(visible=False, loggingOn=False, logMessage=logger3(self.instance_name))
        else:
            self.fmu.instantiate(visible=False, loggingOn=False)
            self.fmu.setupExperiment(startTime=start, stopTime=stop)
        self._instantiated = True
        self._component = self.fmu.component
        self._start, self._stop = start, stop

    def enter_initialization(self) -> None:
        if self.is_fmi3:
            self.fmu.enterInitializationMode(startTime=self._start, stopTime=self._stop)
        else:
            self.fmu.enterInitializationMode()

    def exit_initialization(self) -> None:
        self.fmu.exitInitializationMode()

    def set_value(self, name: str, value: float | bool) -> None:
        vr = [self.plant.references[name]]
        kind = self.plant.types[name]
        if kind == "Boolean":
            self.fmu.setBoolean(vr, [bool(value)])
        elif kind in ("Real", "Float64"):
            self.fmu.setReal(vr, [float(value)]) if not self.is_fmi3 else self.fmu.setFloat64(vr, [float(value)])
        else:
            raise TypeError(f"variable {name!r} is of type {kind}; only Real/Float64 and Boolean can be set")

    # -- checkpoints (FMI "get/set FMU state") ------------------------------------------------
    @property
    def can_save_state(self) -> bool:
        return bool(self.plant.model_description.coSimulation.canGetAndSetFMUstate)

    def save_state(self) -> None:
        """Keep the FMU's whole state as the checkpoint (one state, updated in place)."""
        if self.is_fmi3:
            if self._saved is None:
                self._saved = self.fmu.getFMUState()
            else:
                self.fmu.fmi3GetFMUState(self._component, ctypes.byref(self._saved))
        elif self._saved is None:
            self._saved = self.fmu.getFMUstate()
        else:
            self.fmu.fmi2GetFMUstate(self._component, ctypes.byref(self._saved))

    def restore_state(self) -> None:
        """Put the FMU back to the checkpoint (also out of an error state)."""
        if self._saved is None:
            raise RuntimeError("no checkpoint to restore")
        if self.is_fmi3:
            self.fmu.setFMUState(self._saved)
        else:
            self.fmu.setFMUstate(self._saved)

    def release(self, reuse: bool = False, unload: bool = False) -> None:
        """End the run on this instance: with `reuse`, terminate and reset it for the next run;
        else (or if the FMU refuses either call) free it. The loaded binary stays, unless `unload`."""
        if not self._instantiated:
            if unload:
                self.fmu.freeLibrary()
            return
        if self._saved is not None:  # the checkpoint belongs to this run
            try:
                if self.is_fmi3:
                    self.fmu.freeFMUState(self._saved)
                else:
                    self.fmu.freeFMUstate(self._saved)
            except Exception:  # noqa: BLE001 - freeInstance releases it in any case
                reuse = False
            self._saved = None
        if reuse and not self._was_reset:
            try:
                self.fmu.terminate()
                self.fmu.reset()
                self._was_reset = True
                return
            except Exception as error:  # noqa: BLE001 - an FMU that cannot reset gets a new instance
                if getattr(error, "status", None) == FATAL:  # no call of any kind to this binary again
                    self.fatal = True
                    self._instantiated = False
                    self._component = None
                    return
        try:
            self.fmu.terminate()
        except Exception:  # noqa: BLE001 - an FMU in error state may refuse terminate
            pass
        self._was_reset = False
        self._instantiated = False
        component, self._component = self._component, None
        if unload:
            self.fmu.freeInstance()  # fmpy's: fmi2FreeInstance, then the binary is unloaded
        elif self.is_fmi3:
            self.fmu.fmi3FreeInstance(component)
        else:
            self.fmu.fmi2FreeInstance(component)

    def close(self) -> None:
        """Terminate and free the instance, whatever state it is in, and delete the unzipped copy
        (after a Fatal status nothing is called: the binary stays loaded until the process ends)."""
        try:
            if not self.fatal:
                self.release(reuse=False, unload=True)
        finally:
            shutil.rmtree(self._unzipped, ignore_errors=True)

    # -- the hot path -------------------------------------------------------------------------
    def read_outputs(self, into: np.ndarray) -> None:
        """Copy the outputs (in the order given at construction) into `into`."""
        if self.is_fmi3:
            status = self._get(self._component, self._out_vr, self._n_out, self._out_val, self._n_out)
        else:
            status = self._get(self._component, self._out_vr, self._n_out, self._out_val)
        if failed(status):
            raise FMICallException(function=self.function_names.get, status=status)
        into[:] = self._out_view

    def write_inputs(self, values: tuple[float, ...]) -> None:
        buffer = self._in_val
        for k, v in enumerate(values):
            buffer[k] = v
        if self.is_fmi3:
            status = self._set(self._component, self._in_vr, self._n_in, buffer, self._n_in)
        else:
            status = self._set(self._component, self._in_vr, self._n_in, buffer)
        if failed(status):
            raise FMICallException(function=self.function_names.set, status=status)

    def do_step(self, t: float, h: float) -> None:
        """One doStep from t over h, with `no_set_state_prior_to_current_point` as the flag."""
        keep = self.no_set_state_prior_to_current_point
        if self.is_fmi3:
            status = self._step(self._component, t, h, keep, *self._step_outputs)
        else:
            status = self._step(self._component, t, h, 1 if keep else 0)
        if failed(status):
            raise FMICallException(function=self.function_names.step, status=status)

    # -- for the compiled loop and the run record ---------------------------------------------
    def logged_error(self) -> str | None:
        """What the FMU last logged with a failing status since this was last asked (or since
        instantiation), on one line, or None: the cause of a failed call, for its reason."""
        return last_error_message(self.instance_name, forget=True)

    def c_functions(self) -> CFunctions | None:
        """The addresses the compiled loop calls, or None (not instantiated, or a function not exported)."""
        functions = (self._get, self._set, self._step)
        if self._component is None or any(f is None for f in functions):
            return None
        return CFunctions.of(
            functions, self._component, self._out_vr, self._in_vr, self.is_fmi3, self.function_names, self
        )

    def solver_statistics(self) -> dict[str, int] | str:
        """The plant solver's cumulative counts (toggle_cosim.plant.solver_statistics), read now."""
        from toggle_cosim.plant.solver_statistics import NOT_EXPOSED, read_solver_statistics

        if not self._instantiated:
            return NOT_EXPOSED
        try:
            return read_solver_statistics(self.fmu, self.plant.model_description)
        except Exception as error:  # noqa: BLE001 - a run's record never fails for its statistics
            return f"unreadable ({error})"
