"""A thin, allocation-free wrapper over an FMI 2.0 or 3.0 Co-Simulation FMU for the master loop.

fmpy's `FMU2Slave.getReal([..])` builds ctypes arrays on every call, and each of its `fmi2*`
methods goes through a Python `_call` that looks the function up, optionally logs, and checks
the status. Here the value-reference arrays and value buffers are built once, and each call
goes straight to the FMU's C function (the ctypes function fmpy loaded, with its argument
types), checking the status as fmpy does: anything worse than a warning raises fmpy's
`FMICallException` naming the function.

The master can also run whole stretches of its loop in C over this wrapper: see
`toggle_cosim.compiled_loop`.
"""

from __future__ import annotations

import ctypes
import shutil
from pathlib import Path

import numpy as np
from fmpy import extract
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from toggle_cosim.compiled_loop import CompiledLoop, kernel_library
from toggle_cosim.control.parameters import LawParameters
from toggle_cosim.plant import PlantInterface

_WARNING = 1  # fmi2Warning == fmi3Warning: a status above it is a failure, as fmpy's _call says


class PlantFMU:
    """One instance of a plant FMU: set parameters, initialise, then read/write/step."""

    def __init__(self, plant: PlantInterface, instance_name: str, outputs: list[str], inputs: list[str]) -> None:
        self.plant = plant
        self._unzipped = Path(extract(str(plant.path)))
        md = plant.model_description
        self.is_fmi3 = plant.fmi_version.startswith("3")
        kwargs = dict(unzipDirectory=str(self._unzipped), modelIdentifier=plant.model_identifier, instanceName=instance_name)
        try:
            if self.is_fmi3:
                # fmpy passes the instantiationToken of FMI 3.0 under the name guid
                self.fmu = FMU3Slave(guid=md.instantiationToken, **kwargs)
            else:
                self.fmu = FMU2Slave(guid=md.guid, **kwargs)
        except BaseException:
            shutil.rmtree(self._unzipped, ignore_errors=True)
            raise
        self._instantiated = False
        ref = plant.references
        self._out_vr = (ctypes.c_uint32 * len(outputs))(*(ref[n] for n in outputs))
        self._out_val = (ctypes.c_double * len(outputs))()
        self._out_view = np.frombuffer(self._out_val, dtype=np.float64)
        self._n_out = len(outputs)
        self._in_vr = (ctypes.c_uint32 * len(inputs))(*(ref[n] for n in inputs))
        self._in_val = (ctypes.c_double * len(inputs))()
        self._n_in = len(inputs)
        prefix = "fmi3" if self.is_fmi3 else "fmi2"
        self._get_name = f"{prefix}GetFloat64" if self.is_fmi3 else "fmi2GetReal"
        self._set_name = f"{prefix}SetFloat64" if self.is_fmi3 else "fmi2SetReal"
        self._step_name = f"{prefix}DoStep"
        self._get = self._c_function(self._get_name)
        self._set = self._c_function(self._set_name)
        self._step = self._c_function(self._step_name)
        if self.is_fmi3:  # doStep's output arguments, built once
            self._event = ctypes.c_bool()
            self._terminate = ctypes.c_bool()
            self._early = ctypes.c_bool()
            self._last_time = ctypes.c_double()
            self._step_outputs = (ctypes.byref(self._event), ctypes.byref(self._terminate),
                                  ctypes.byref(self._early), ctypes.byref(self._last_time))
        self._component = None
        self._saved = None  # the checkpoint, an fmi2FMUstate / fmi3FMUState

    def _c_function(self, name: str):  # noqa: ANN202 - a ctypes function pointer
        """The FMU's C function as fmpy loaded it (argument and result types set), or the
        fmpy method of that name if this fmpy keeps them elsewhere."""
        found = getattr(self.fmu, "_functions", {}).get(name)
        return found if found is not None else getattr(self.fmu, name)

    # -- life cycle ---------------------------------------------------------------------------
    def instantiate(self, start: float, stop: float) -> None:
        if self.is_fmi3:
            self.fmu.instantiate(visible=False, loggingOn=False)
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

    def close(self) -> None:
        """Terminate and free the instance, whatever state it is in, and delete the unzipped copy."""
        try:
            if self._instantiated:
                try:
                    self.fmu.terminate()
                except Exception:  # noqa: BLE001 - an FMU in error state may refuse terminate
                    pass
                self.fmu.freeInstance()
                self._instantiated = False
                self._component = None
        finally:
            shutil.rmtree(self._unzipped, ignore_errors=True)

    # -- the hot path -------------------------------------------------------------------------
    def read_outputs(self, into: np.ndarray) -> None:
        """Copy the outputs (in the order given at construction) into `into`."""
        if self.is_fmi3:
            status = self._get(self._component, self._out_vr, self._n_out, self._out_val, self._n_out)
        else:
            status = self._get(self._component, self._out_vr, self._n_out, self._out_val)
        if status is not None and status > _WARNING:
            raise FMICallException(function=self._get_name, status=status)
        into[:] = self._out_view

    def write_inputs(self, values: tuple[float, ...]) -> None:
        buffer = self._in_val
        for k, v in enumerate(values):
            buffer[k] = v
        if self.is_fmi3:
            status = self._set(self._component, self._in_vr, self._n_in, buffer, self._n_in)
        else:
            status = self._set(self._component, self._in_vr, self._n_in, buffer)
        if status is not None and status > _WARNING:
            raise FMICallException(function=self._set_name, status=status)

    def do_step(self, t: float, h: float) -> None:
        if self.is_fmi3:
            status = self._step(self._component, t, h, True, *self._step_outputs)
        else:
            status = self._step(self._component, t, h, 1)
        if status is not None and status > _WARNING:
            raise FMICallException(function=self._step_name, status=status)

    # -- the compiled loop --------------------------------------------------------------------
    def compiled_loop(self, data: np.ndarray, n_out: int, i_x: int, i_v: int, col_u: int, n: int,
                      T_s: float, F_E: float, law: LawParameters, z: float = 0.0) -> CompiledLoop | None:
        """The loop in C over this instance, or None when it cannot be had (no compiler, the
        FMU's C functions not reachable, TOGGLE_COSIM_KERNEL=0). See `CompiledLoop`."""
        library = kernel_library()
        functions = getattr(self.fmu, "_functions", {})
        names = (self._get_name, self._set_name, self._step_name)
        if library is None or self._component is None or any(name not in functions for name in names):
            return None
        return CompiledLoop(library, self, [functions[name] for name in names], data, n_out, i_x, i_v, col_u,
                            n, T_s, F_E, law, z)
