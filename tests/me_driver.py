"""A small Model Exchange master for the tests: FMPy's FMI 2.0 model API integrated by FMPy's
CVODE wrapper (fmpy.sundials.CVodeSolver), stepped from communication point to
communication point like a Co-Simulation master, with inputs held over each step.

At every communication point the inputs may change, which is a discontinuity of the right-hand
side: the integrator is restarted there (as FMPy's own simulateME restarts after an event).
State events found by CVODE's root finder go through event mode and fmi2NewDiscreteStates.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from dataclasses import dataclass, field

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model
from fmpy.sundials import CVodeSolver


class _HeldInputs:
    """The inputs are set by the master at communication points and held: nothing to apply
    while CVODE evaluates the model inside a step."""

    def apply(self, time: float, **_: object) -> None:
        pass


@dataclass
class ModelExchangeRun:
    """One ME instance of an FMI 2.0 FMU, integrated by CVODE to the times asked for."""

    fmu: str
    start_values: Mapping[str, float] = field(default_factory=dict)
    relative_tolerance: float = 1e-10
    max_step: float = 1e-3

    def __post_init__(self) -> None:
        self.description = read_model_description(self.fmu)
        self.unzipped = extract(self.fmu)
        self.vr = {v.name: v.valueReference for v in self.description.modelVariables}
        self.model = FMU2Model(
            guid=self.description.guid,
            unzipDirectory=self.unzipped,
            modelIdentifier=self.description.modelExchange.modelIdentifier,
            instanceName="me-run",
        )
        self.model.instantiate()
        self.model.setupExperiment(startTime=0.0)
        self.model.enterInitializationMode()
        if self.start_values:
            self.set(self.start_values)
        self.model.exitInitializationMode()
        self._settle()
        self.time = 0.0
        self.solver = CVodeSolver(
            nx=self.description.numberOfContinuousStates,
            nz=self.description.numberOfEventIndicators,
            get_x=self.model.getContinuousStates,
            set_x=self.model.setContinuousStates,
            get_dx=self.model.getDerivatives,
            get_z=self.model.getEventIndicators,
            get_nominals=self.model.getNominalsOfContinuousStates,
            set_time=self.model.setTime,
            input=_HeldInputs(),
            startTime=0.0,
            maxStep=self.max_step,
            relativeTolerance=self.relative_tolerance,
            maxNumSteps=100000,
        )
        self.model.enterContinuousTimeMode()

    def _settle(self) -> None:
        needed = True
        while needed:
            needed, terminate, *_ = self.model.newDiscreteStates()
            assert not terminate

    def set(self, values: Mapping[str, float]) -> None:
        self.model.setReal([self.vr[name] for name in values], list(values.values()))

    def get(self, names: list[str]) -> list[float]:
        return self.model.getReal([self.vr[name] for name in names])

    def statistic(self, name: str) -> int:
        return self.model.getInteger([self.vr[name]])[0]

    def set_inputs(self, values: Mapping[str, float]) -> None:
        """New input values from now on: a discontinuity, so the integrator restarts here."""
        self.set(values)
        self.solver.reset(self.time)

    def advance(self, t_next: float) -> None:
        """Integrate to t_next, handling every state event on the way."""
        while self.time < t_next and abs(self.time - t_next) > 1e-12 * max(1.0, t_next):
            state_event, _, self.time = self.solver.step(self.time, t_next)
            self.model.setTime(self.time)
            step_event, terminate = self.model.completedIntegratorStep()
            assert not terminate
            if state_event or step_event:
                self.model.enterEventMode()
                self._settle()
                self.model.enterContinuousTimeMode()
                self.solver.reset(self.time)

    def close(self) -> None:
        self.model.terminate()
        self.model.freeInstance()
        del self.solver
        self.model.freeLibrary()
        shutil.rmtree(self.unzipped, ignore_errors=True)
