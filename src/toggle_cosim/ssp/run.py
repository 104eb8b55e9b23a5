"""An SSP's parameter sets as runs of our master (`toggle-cosim run study.ssp`): the plant gets
exactly the set's plant values (`runs.definition.PlantSettings.fmu_values`, which
`cosim.master.plant_settings` returns as they are) and F_E as its input; the controller is the
SSP's controller FMU with the set's controller values (`controller_from_ssp`)."""

from __future__ import annotations

import dataclasses

from toggle_cosim.runs.definition import ControllerSettings, Run
from toggle_cosim.ssp.reader import SspStudy

__all__ = ["controller_from_ssp", "run_from_ssp"]


def controller_from_ssp(study: SspStudy) -> ControllerSettings:
    """The run's controller: the SSP's controller FMU, its parameters set from the parameter set
    (the scenario key controller: {fmu: PATH, parameters: {...}} as our master reads it)."""
    return dataclasses.replace(study.run.controller, fmu=study.controller_fmu, parameters=dict(study.controller_values))


def run_from_ssp(study: SspStudy) -> Run:
    """The run of one parameter set: plant values and F_E from the set (`study.run`), the
    controller FMU as its controller."""
    return dataclasses.replace(study.run, controller=controller_from_ssp(study))
