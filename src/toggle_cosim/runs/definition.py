"""What one co-simulation is: the plant's and the controller's settings and the run that joins them.

A `Run` is one scenario with one variant applied (experiments/scenario.py builds them from YAML);
the plant (plant/settings.py) reads what to set on the FMU from it, the co-simulation
(cosim/) steps it, and the experiments (sweeps, references) make and compare many of them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any, Literal

from toggle_cosim.control.trajectory import ProfileSpec
from toggle_cosim.physics.parameters import ControllerGains
from toggle_cosim.signals.definitions import Signal
from toggle_cosim.system.model import Wiring

COUPLINGS = ("gauss-seidel", "jacobi")  # Run.coupling: how the master couples plant and controller


@dataclass(frozen=True)
class PlantSettings:
    """What the master sets on the plant FMU before initialisation (and holds as inputs)."""

    F_E: float | Signal = 0.0  # N: a number (constant) or a signal in time (`signals`), applied at every sample
    m_B: float = 4.43
    mu: float = 0.2
    current_loop: Literal["first_order", "ideal"] = "first_order"
    friction_model: Literal["paper", "dissipative", "stick_slip"] = "paper"
    mu_s: float | None = None  # static coefficient (stick_slip); None: the same as mu
    K: float | None = None
    # Plausibility limits (`cosim.plausibility`). The paper gives no rating for its motor: 10 A is
    # assumed (the integral law's i_max; 2x the largest command of the shipped cases, 4.95 A).
    rated_current: float = 10.0  # A
    working_range: tuple[float, float] | None = None  # m, slider B; None: the linkage's (scenario)
    parameters: Mapping[str, float | bool] = field(default_factory=dict)
    # The plant FMU's other inputs by name (a user's plant: a disturbance, a temperature), each a
    # number or a signal, applied at every sample as F_E is; recorded after the diagnostics
    inputs: Mapping[str, float | Signal] = field(default_factory=dict)
    # Explicit (name, value) settings in order, e.g. an SSP's parameter set (`ssp.reader`): the
    # master sets exactly these instead of the ones it derives from the fields above
    fmu_values: tuple[tuple[str, float | bool | int], ...] | None = None


@dataclass(frozen=True)
class ErrorSignal:
    """What a python-control system reads: the plant output `output` (y) and its reference r, the
    run's stroke.trajectory or else `target` (None: stroke.x_target for x_B, θ1* of eq. (26) for
    theta1); a one-input system acts on e = r − y, a two-input one on [r, y]."""

    output: str
    target: float | None = None


@dataclass(frozen=True)
class ControllerSettings:
    """The built-in controller's settings, or (python) the user's controller factory
    "module:callable" with its keyword parameters, or (fmu) a controller FMU with its
    parameters (`cosim.controllers`)."""

    objective: Literal["x_B", "theta1"] = "x_B"
    gains: ControllerGains = field(default_factory=ControllerGains)
    nominal_m_B: float = 4.43
    law: Literal["paper", "integral"] = "paper"
    C_I: float = 16.0  # 1/s, the integral law's surface slope (unused by the paper's law)
    K_I: float = 64.0  # 1/s², the integral law's gain: C_I = 2λ, K_I = λ², λ = 8/s (unused by the paper's law)
    i_max: float = 10.0  # A, the integral law's current limit (unused by the paper's law)
    python: str | None = None  # "module:callable", the user's controller factory; None: the built-in law
    parameters: Mapping[str, Any] = field(default_factory=dict)  # the factory's keyword arguments
    error: ErrorSignal | None = None  # python-control systems: the error they act on
    command: Literal["iq_ref"] = "iq_ref"  # python-control systems: the plant input they drive
    discretise: str | None = None  # python-control systems: sample a continuous one at T_s by this method
    fmu: Path | None = None  # a controller FMU (resolved from the scenario's folder); None: not an FMU


@dataclass(frozen=True)
class Run:
    """One co-simulation: a scenario with one variant applied."""

    scenario: str
    variant: str | None
    source: Path | None
    description: str
    fmu: Path | None
    t_end: float
    T_s: float
    x_start: float
    x_target: float
    plant: PlantSettings
    controller: ControllerSettings
    resolved: Mapping[str, Any]
    # how the master couples plant and controller (`cosim.master`): gauss-seidel, the command of
    # sample k drives the plant over [t_k, t_k+1]; jacobi, the command of sample k - 1 does
    coupling: Literal["gauss-seidel", "jacobi"] = "gauss-seidel"
    # the profile the built-in law tracks from x_start to x_target (stroke.trajectory); None: the
    # constant target x_target
    trajectory: ProfileSpec | None = None
    # the parts around the plant and controller, the connections and what to record (`system`);
    # the default is the plain pair, which the master runs with the pair's trace and run.json
    system: Wiring = field(default_factory=Wiring)

    @property
    def x_final(self) -> float:
        """Where the reference ends: x_target, or x_start after a cycle."""
        return self.x_start if self.trajectory is not None and self.trajectory.kind == "cycle" else self.x_target

    @property
    def label(self) -> str:
        return self.scenario if self.variant is None else f"{self.scenario}/{self.variant}"

    @property
    def folder(self) -> PurePosixPath:
        """Where `toggle-cosim run` writes this run's files under OUT (`results_folder`)."""
        return results_folder(self)

    @property
    def steps(self) -> int:
        return int(round(self.t_end / self.T_s))


SSP_FOLDER_TAG = "_ssp"  # OUT/<archive>_ssp/<set>/: an SSP's runs


def results_folder(run: Run) -> PurePosixPath:
    """The folder, relative to the output folder, of a run's trace.csv and run.json: one per
    source and setting, so that no run replaces another's results.

    * a scenario file's run as the file says it: <scenario>/<variant>
    * an SSP's run: <the archive's name without .ssp>_ssp/<set>
    * a run whose coupling is not the one its file gives (`--coupling`): _<coupling> after the
      first part, e.g. fig4_nominal_jacobi/friction
    """
    source = Path(run.source) if run.source is not None else None
    top = f"{source.stem}{SSP_FOLDER_TAG}" if source is not None and source.suffix.lower() == ".ssp" else run.scenario
    if run.coupling != run.resolved.get("coupling", "gauss-seidel"):
        top += f"_{run.coupling}"
    return PurePosixPath(top) / (run.variant or "run")
