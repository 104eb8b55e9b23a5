"""A thin, allocation-free wrapper over an FMI 2.0 or 3.0 Co-Simulation FMU for the master loop.

fmpy's `FMU2Slave.getReal([..])` builds ctypes arrays on every call; in a loop of thousands of
steps that dominates. Here the value-reference arrays and value buffers are built once, and
each call goes straight to the FMU's C function.
"""

from __future__ import annotations

import ctypes
import shutil
from pathlib import Path

import numpy as np
from fmpy import extract
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

from toggle_cosim.plant import PlantInterface


class PlantFMU:
    """One instance of a plant FMU: set parameters, initialise, then read/write/step."""

    def __init__(self, plant: PlantInterface, instance_name: str, outputs: list[str], inputs: list[str]) -> None:
        self.plant = plant
        self._unzipped = Path(extract(str(plant.path)))
        md = plant.model_description
        self.is_fmi3 = plant.fmi_version.startswith("3")
        cls = FMU3Slave if self.is_fmi3 else FMU2Slave
        kwargs = dict(unzipDirectory=str(self._unzipped), modelIdentifier=plant.model_identifier, instanceName=instance_name)
        if self.is_fmi3:
            self.fmu = cls(instantiationToken=md.instantiationToken, **kwargs)
        else:
            self.fmu = cls(guid=md.guid, **kwargs)
        self._instantiated = False
        ref = plant.references
        self._out_vr = (ctypes.c_uint32 * len(outputs))(*(ref[n] for n in outputs))
        self._out_val = (ctypes.c_double * len(outputs))()
        self._out_view = np.frombuffer(self._out_val, dtype=np.float64)
        self._n_out = len(outputs)
        self._in_vr = (ctypes.c_uint32 * len(inputs))(*(ref[n] for n in inputs))
        self._in_val = (ctypes.c_double * len(inputs))()
        self._n_in = len(inputs)

    # -- life cycle ---------------------------------------------------------------------------
    def instantiate(self, start: float, stop: float) -> None:
        if self.is_fmi3:
            self.fmu.instantiate(visible=False, loggingOn=False)
        else:
            self.fmu.instantiate(visible=False, loggingOn=False)
            self.fmu.setupExperiment(startTime=start, stopTime=stop)
        self._instantiated = True
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
        finally:
            shutil.rmtree(self._unzipped, ignore_errors=True)

    # -- the hot path -------------------------------------------------------------------------
    def read_outputs(self, into: np.ndarray) -> None:
        """Copy the outputs (in the order given at construction) into `into`."""
        if self.is_fmi3:
            self.fmu.fmi3GetFloat64(self.fmu.component, self._out_vr, self._n_out, self._out_val, self._n_out)
        else:
            self.fmu.fmi2GetReal(self.fmu.component, self._out_vr, self._n_out, self._out_val)
        into[:] = self._out_view

    def write_inputs(self, values: tuple[float, ...]) -> None:
        for k, v in enumerate(values):
            self._in_val[k] = v
        if self.is_fmi3:
            self.fmu.fmi3SetFloat64(self.fmu.component, self._in_vr, self._n_in, self._in_val, self._n_in)
        else:
            self.fmu.fmi2SetReal(self.fmu.component, self._in_vr, self._n_in, self._in_val)

    def do_step(self, t: float, h: float) -> None:
        if self.is_fmi3:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        else:
            self.fmu.fmi2DoStep(self.fmu.component, t, h, 1)
