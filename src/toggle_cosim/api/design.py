"""`trim` and `linearize`: the plant's operating point at a slider position and its linear model
there, for designing a controller with python-control (docs/designing.md).

    point = tc.trim(run, x_B=0.28)                # slider B held at rest: states, i_q*, warnings
    model = tc.linearize(run, at=point)           # A, B, C, D, names, units, error estimate
    model.system                                  # a control.StateSpace (the extra [design])

The plant FMU is the run's (`plant.fmu` of its scenario), else the shipped plant
(`tc.plant_fmu()`); `fmu=` names another. It is checked against the plant contract first, as
`simulate` does.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Literal

from toggle_cosim.api.scenarios import Scenario
from toggle_cosim.design.linearize import LinearModel
from toggle_cosim.design.linearize import linearize as _linearize
from toggle_cosim.design.model_exchange import ModelExchangeError
from toggle_cosim.design.trim import OperatingPoint, TrimError
from toggle_cosim.design.trim import trim as _trim
from toggle_cosim.runs.definition import Run

__all__ = ["LinearModel", "ModelExchangeError", "OperatingPoint", "TrimError", "linearize", "trim"]


def _plant(run: Run, fmu: str | Path | None):  # noqa: ANN202 - a PlantInterface
    from toggle_cosim.api.project import plant_fmu
    from toggle_cosim.api.simulation import checked_plant

    return checked_plant(fmu if fmu is not None else run.fmu if run.fmu is not None else plant_fmu())


def _one_run(run: Run | Scenario) -> Run:
    if isinstance(run, Scenario):
        return run.run
    if not isinstance(run, Run):
        raise TypeError(
            f"trim and linearize need a Run (a scenario's variant: scenario[name]), not {type(run).__name__}"
        )
    return run


def trim(run: Run | Scenario, x_B: float, *, fmu: str | Path | None = None) -> OperatingPoint:
    """The operating point holding slider B at rest at x_B [m] under the run's F_E and m_B,
    friction-free (`OperatingPoint.warnings` says so when the run's mu > 0). Raises TrimError
    (one line) for an x_B outside the working range, ModelExchangeError for a plant FMU without
    FMI 2.0 Model Exchange or of another structure than the shipped plant's."""
    run = _one_run(run)
    return _trim(run, float(x_B), _plant(run, fmu))


def linearize(
    run: Run | Scenario,
    at: OperatingPoint | float,
    *,
    outputs: Sequence[str] = (),
    coordinates: Literal["manifold", "fmu"] = "manifold",
    fmu: str | Path | None = None,
) -> LinearModel:
    """The plant linearised about `at` (an `OperatingPoint` from `trim`, or a position x_B [m],
    trimmed first): inputs iq_ref and F_E; outputs x_B, v_B, theta1 and the recorded `outputs`
    asked for; states on the constraint manifold (theta1, omega1, i_lag) or, with
    coordinates="fmu", all the FMU's continuous states. `.system` is the control.StateSpace."""
    run = _one_run(run)
    plant = _plant(run, fmu if fmu is not None else at.fmu if isinstance(at, OperatingPoint) else None)
    point = at if isinstance(at, OperatingPoint) else _trim(run, float(at), plant)
    return _linearize(run, point, plant, outputs=tuple(outputs), coordinates=coordinates)
