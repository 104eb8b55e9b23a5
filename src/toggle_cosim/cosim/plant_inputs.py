"""What a run sets on its plant: the parameters before initialisation (`plant_settings`) and
the inputs besides the command at every sample (`other_inputs`, `input_samples`). The
execution (`systems`) takes them from here for every run, the plain pair's included."""

from __future__ import annotations

import numpy as np

from toggle_cosim.plant.contract import PlantInterface
from toggle_cosim.plant.friction import friction_settings
from toggle_cosim.runs.definition import Run
from toggle_cosim.signals.definitions import as_signal, sample

__all__ = ["input_samples", "other_inputs", "plant_settings"]


def plant_settings(run: Run, plant: PlantInterface) -> list[tuple[str, float | bool]]:
    """The plant parameters a run sets before initialisation, in order: run.plant.fmu_values if
    given (an SSP's parameter set), else those the scenario's settings give."""
    if run.plant.fmu_values is not None:
        return list(run.plant.fmu_values)
    settings: list[tuple[str, float | bool]] = [("m_B", run.plant.m_B), ("mu", run.plant.mu)]
    available = plant.references
    if "x_B0" in available:
        settings.append(("x_B0", run.x_start))
    if "idealCurrentLoop" in available:
        settings.append(("idealCurrentLoop", run.plant.current_loop == "ideal"))
    elif run.plant.current_loop == "ideal":
        raise ValueError(
            f"{plant.path}: the plant has no parameter idealCurrentLoop, so plant.current_loop: ideal cannot be set"
        )
    if run.plant.K is not None:
        settings.append(("K", run.plant.K))
    settings += friction_settings(run.plant.friction_model, run.plant.mu, run.plant.mu_s, available, plant.path)
    for name, value in run.plant.parameters.items():
        if name not in available:
            raise ValueError(f"key plant.parameters.{name}: the plant FMU has no variable {name!r}")
        settings.append((name, value))
    return settings


def other_inputs(run: Run) -> tuple[str, ...]:
    """The plant inputs a run sets besides iq_ref and F_E (`plant.inputs`), in the scenario's order."""
    return tuple(run.plant.inputs)


def input_samples(run: Run, n: int) -> np.ndarray:
    """What each sample k = 0 .. n sends besides the command: F_E, then the plant's other inputs
    (`other_inputs`), each sampled once from its signal at t_k = k·T_s (`signals`): an (n + 1, m)
    float64 array in C order. A number gives n + 1 copies of it, so a constant run keeps its bits."""
    signals = [run.plant.F_E, *run.plant.inputs.values()]
    columns = [sample(as_signal(signal), n, run.T_s) for signal in signals]
    return np.ascontiguousarray(np.column_stack(columns), dtype=np.float64)
