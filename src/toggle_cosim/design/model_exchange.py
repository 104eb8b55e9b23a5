"""A plant FMU opened through its Model Exchange interface, for evaluating the model (not
integrating it): set the continuous states and the inputs, read the state derivatives and the
outputs. The FMU is instantiated, its parameters set as a run sets them, initialised (so the
states start consistent, at rest at `x_B0`) and left in continuous-time mode.

This is the one place the design functions (`design.trim`, `design.linearize`) touch an FMU;
everything they compute from it is in pure functions.
"""

from __future__ import annotations

import ctypes
import shutil
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from fmpy import extract
from fmpy.fmi2 import FMU2Model

from toggle_cosim.plant.contract import PlantInterface

__all__ = ["ModelExchangeError", "ModelExchangePlant", "StateInfo", "state_info", "variable_unit"]


class ModelExchangeError(Exception):
    """The plant FMU cannot be evaluated through Model Exchange; str() is the one-line reason."""


@dataclass(frozen=True)
class StateInfo:
    """The continuous states of a Model Exchange FMU, in the FMU's order (ModelStructure/Derivatives)."""

    names: tuple[str, ...]  # the state variables, e.g. mechanism.theta1
    units: tuple[str, ...]  # their units ("" when the description gives none)
    value_references: tuple[int, ...]


def variable_unit(variable: object) -> str:
    """A model variable's unit, from its own attribute or its declared type ("" when neither gives one)."""
    unit = getattr(variable, "unit", None)
    declared = getattr(variable, "declaredType", None)
    if not unit and declared is not None:
        unit = getattr(declared, "unit", None)
    return unit or ""


def state_info(plant: PlantInterface) -> StateInfo:
    """The FMU's continuous states, from the derivatives listed in its ModelStructure."""
    md = plant.model_description
    if md.modelExchange is None:
        raise ModelExchangeError(
            f"{plant.path}: the plant FMU offers no Model Exchange interface, which trim and linearize "
            "need (build it with --interfaces both, the default)"
        )
    if not md.fmiVersion.startswith("2"):
        raise ModelExchangeError(
            f"{plant.path}: trim and linearize read FMI 2.0 plants; this one is FMI {md.fmiVersion} "
            "(build it with --fmi-version 2.0, the default)"
        )
    states = [unknown.variable.derivative for unknown in md.derivatives]
    if not states or any(state is None for state in states):
        raise ModelExchangeError(f"{plant.path}: the model description lists no continuous states to linearise")
    return StateInfo(
        names=tuple(state.name for state in states),
        units=tuple(variable_unit(state) for state in states),
        value_references=tuple(state.valueReference for state in states),
    )


def _pointer(array: np.ndarray) -> object:
    """A C double* to the array's data (fmpy's FMU2Model passes it on to the FMU)."""
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class ModelExchangePlant:
    """One Model Exchange instance of an FMI 2.0 plant, set up and initialised, in
    continuous-time mode: `evaluate(x, inputs)` gives the state derivatives and outputs there."""

    def __init__(
        self, plant: PlantInterface, settings: Sequence[tuple[str, float | bool]], inputs: Sequence[str]
    ) -> None:
        self.plant = plant
        self.states = state_info(plant)
        md = plant.model_description
        self._refs = plant.references
        self._inputs = [self._refs[name] for name in inputs]
        self._unzipped = extract(str(plant.path))
        self._model = FMU2Model(
            guid=md.guid,
            unzipDirectory=self._unzipped,
            modelIdentifier=md.modelExchange.modelIdentifier,
            instanceName="toggle-cosim-design",
        )
        self._open = False
        try:
            self._model.instantiate()
            self._open = True
            self._model.setupExperiment(startTime=0.0)
            for name, value in settings:
                ref = self._refs[name]
                if isinstance(value, bool):
                    self._model.setBoolean([ref], [value])
                else:
                    self._model.setReal([ref], [float(value)])
            self._model.enterInitializationMode()
            self._model.exitInitializationMode()
            needed = True
            while needed:
                needed, terminate, *_ = self._model.newDiscreteStates()
                if terminate:
                    raise ModelExchangeError(f"{plant.path}: the plant asked to terminate at initialisation")
            self._model.enterContinuousTimeMode()
            self._model.setTime(0.0)
            self.nx = len(self.states.names)
            self._x = np.zeros(self.nx)
            self._dx = np.zeros(self.nx)
            self._model.getContinuousStates(_pointer(self._x), self.nx)
            self.initial_states = self._x.copy()
            nominals = np.zeros(self.nx)
            self._model.getNominalsOfContinuousStates(_pointer(nominals), self.nx)
            self.nominals: np.ndarray | None = nominals if np.all(np.isfinite(nominals) & (nominals > 0)) else None
        except Exception:
            self.close()
            raise

    def reference(self, name: str) -> int:
        return self._refs[name]

    def evaluate(self, x: np.ndarray, inputs: Sequence[float], outputs: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """The state derivatives and the outputs (value references `outputs`) at states `x` and inputs."""
        self._model.setReal(self._inputs, [float(u) for u in inputs])
        self._x[:] = x
        self._model.setContinuousStates(_pointer(self._x), self.nx)
        self._model.getDerivatives(_pointer(self._dx), self.nx)
        derivatives = self._dx.copy()
        values = np.array(self._model.getReal(list(outputs)), dtype=float) if outputs else np.empty(0)
        return derivatives, values

    def close(self) -> None:
        """Free the instance, its library and the unzipped copy (safe to call twice)."""
        model, self._model = getattr(self, "_model", None), None
        if model is not None:
            try:
                if self._open:
                    model.terminate()
                    model.freeInstance()
            finally:
                model.freeLibrary()
        shutil.rmtree(getattr(self, "_unzipped", ""), ignore_errors=True)

    def __enter__(self) -> ModelExchangePlant:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
