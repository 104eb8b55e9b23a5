"""`simulate`: one run of a scenario against a plant FMU, from Python, with the command line's
checks and its crash guard.

    result = tc.simulate(tc.load_scenario("scenarios/fig4_nominal.yaml")["friction"], "fmus/ToggleLSM.fmu")

Supervised (the default), the run happens in a forked child process, as every run of
`toggle-cosim run` does (`cosim.isolation.supervision`): a plant that crashes (segfault, abort), hangs past
the time limit or allocates without end fails the run, with the reason, and the Python process
(a notebook's kernel) goes on. `supervised=False` runs it in this process: no fork, no time limit
and no crash guard. Both give the same trace, bit for bit.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path

from toggle_cosim.api.result import Result, RunInterrupted
from toggle_cosim.api.scenarios import Scenario
from toggle_cosim.api.units import trace_units
from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import Controller, ControllerError, check_controller
from toggle_cosim.cosim import master
from toggle_cosim.cosim.checked import CheckedRun
from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.experiments.scenario import ScenarioError
from toggle_cosim.plant.contract import ContractError, PlantInterface, check_plant
from toggle_cosim.runs.definition import COUPLINGS, Run

__all__ = ["checked_plant", "simulate"]

_checked: dict[tuple[Path, int, int], PlantInterface] = {}  # (path, size, mtime) -> the checked plant


def checked_plant(fmu: str | Path) -> PlantInterface:
    """The plant FMU checked against the interface contract and its binary probed (in a forked
    child), as `toggle-cosim run` does before any run; kept while the file is unchanged.
    Raises ContractError with one line naming the file and the problem."""
    from toggle_cosim.plant.probe import ProbeError, probe_binary

    path = Path(fmu).resolve()
    try:
        status = path.stat()
    except OSError:
        status = None
    key = (path, status.st_size, status.st_mtime_ns) if status is not None else None
    if key is not None and key in _checked:
        return _checked[key]
    plant = check_plant(path)
    try:
        probe_binary(plant)
    except ProbeError as error:
        raise ContractError(str(error)) from None
    if key is not None:
        _checked[key] = plant
    return plant


def _one_run(run: Run | Scenario) -> Run:
    if isinstance(run, Scenario):
        return run.run  # a ValueError naming the variants when there are several
    if not isinstance(run, Run):
        raise TypeError(f"simulate needs a Run (a scenario's variant: scenario[name]), not {type(run).__name__}")
    return run


def _checks(run: Run, plant: PlantInterface, own_controller: bool = True) -> CheckedRun | None:
    """What the command line checks before a run starts: the settings against the plant's
    variables, the run as the master checks it (`cosim.checked.check_run`: the controller, a
    user's without running its code, the parts, connections, units and order; nothing loaded;
    a python-control system's factory, controller.error given, built in a supervised child) and
    the size of the trace buffer (ScenarioError, one line). The checked run, which the run then
    uses as it is (None: a controller given, checked with it as the run starts)."""
    from toggle_cosim.cosim.checked import SystemError_, check_run
    from toggle_cosim.cosim.isolation.supervision import probe_columns
    from toggle_cosim.experiments.resources import ResourceError, check_runs
    from toggle_cosim.plant.settings import SettingError, check_settings

    checked = None
    try:
        check_settings(run, plant)
        if own_controller:  # the scenario's, not one given to simulate
            checked = check_run(run, plant)
            if checked.builds_controller and run.controller.error is not None:
                probe_columns(run, plant, checked=checked)  # a python-control system: built in a supervised child
        check_runs([(run, plant)], None)
    except (SettingError, ControllerError, SystemError_) as error:
        raise ScenarioError(f"{run.source or run.label}: {error}") from None
    except ResourceError as error:
        raise ScenarioError(f"{run.source or run.label}: {error.message}") from None
    return checked


def _adapted(controller: object, run: Run, plant: PlantInterface) -> Controller | None:
    """The controller given to simulate, a python-control system adapted as a scenario's is
    (`cosim.controllers.system_controller`: its reference the run's trajectory or target, the
    run's controller.error and controller.discretise); any other object as given. Raises
    ValueError for a system the run cannot take (a continuous-time one without discretise)."""
    from toggle_cosim.cosim.controllers import is_python_control_system, system_controller

    if not is_python_control_system(controller):
        return controller  # type: ignore[return-value]
    try:
        return system_controller(controller, run, plant.recorded_outputs)
    except ControllerError as error:
        raise ValueError(f"controller: {error}") from None


def _outcome(
    run: Run,
    plant: PlantInterface,
    supervised: bool,
    time_limit: float | None,
    progress: Callable[[float], None] | None,
    controller: Controller | None = None,
    checked: CheckedRun | None = None,
) -> RunOutcome:
    """The one place a run starts, supervised or in this process; `checked`: the run as
    `_checks` checked it (None: checked as it starts)."""
    if not supervised:
        from toggle_cosim.cosim.isolation.supervision import in_process_folder

        with in_process_folder():  # the unzipped FMUs: removed after, or by the next command after a crash
            return master.check_and_simulate(run, plant, progress, controller=controller, checked=checked)
    from toggle_cosim.cosim.isolation.supervision import remove_stale_folders, simulate_supervised

    remove_stale_folders()
    return simulate_supervised(
        run, plant, time_limit=time_limit, progress=progress, controller=controller, checked=checked
    )


def simulate(
    run: Run | Scenario,
    fmu: str | Path | None = None,
    *,
    supervised: bool = True,
    time_limit: float | None = None,
    progress: Callable[[float], None] | None = None,
    controller: Controller | object | None = None,
    coupling: str | None = None,
) -> Result:
    """Simulate one run (one variant of a scenario: `scenario["friction"]`; a scenario with one
    run may be given itself) against the plant FMU `fmu` (default: the scenario's `fmu:` key).

    The master samples the plant every T_s, runs the paper's two-phase VSC (eqs. (19)-(25)) on
    the measured x_B, v_B and holds i_q* until the next sample, as `toggle-cosim run` does.

    Args:
        run: a `Run` (`tc.load_scenario(path)["friction"]`), or a `Scenario` with one variant.
        fmu: the plant FMU's path (default: the run's `fmu:` key); it is checked against the
            plant contract and its binary probed once while the file is unchanged.
        supervised: run in a forked child (default): a plant crash or hang fails the run, not
            this process. False: in this process, without a time limit.
        time_limit: wall-clock limit of a supervised run in s (default: the scenario's
            time_limit key, else max(30 s, 20 x t_end)).
        progress: called with the fraction of the run done, every 1 %.
        controller: any object that meets the controller protocol (`toggle_cosim.control.protocol`:
            start, step, diagnostics) instead of the scenario's controller; it runs in the Python
            loop at every sample (docs/controllers.md). Or a python-control system
            (`control.StateSpace`/`TransferFunction`, dt = T_s; one input e = r − y, or two,
            [r − y0, y − y0]), adapted by `DiscreteSystemController` to read the run's
            controller.error output (default x_B) against its trajectory or target; it runs in
            the compiled loop.
        coupling: "gauss-seidel" (the plant gets the command computed from its outputs at the
            same sample) or "jacobi" (the previous sample's command); default: the scenario's
            coupling key, else gauss-seidel (docs/controllers.md, "Coupling").

    Returns:
        The `Result`, complete or failed (a plant failure is a result, not an exception).

    Raises:
        ScenarioError: a setting the plant cannot take, or a run too large to record.
        ContractError: the FMU is missing or does not meet the plant's interface contract.
        RunInterrupted: an interrupt (Ctrl-C, the notebook's stop button) stopped the run; the
            partial result is its `.result`.
        ValueError: a `coupling` or `time_limit` that is not one of the allowed values, or a
            python-control system the run cannot take (continuous-time without the scenario's
            controller.discretise, a dt other than T_s, other than one or two inputs).

    Example:
        ```python
        import toggle_cosim as tc

        fig4 = tc.load_scenario("scenarios/fig4_nominal.yaml")
        result = tc.simulate(fig4["friction"], tc.plant_fmu())
        print(result.status, result.summary.final_error_m)   # complete 6.4e-05
        jacobi = tc.simulate(fig4["friction"], "fmus/ToggleLSM.fmu", coupling="jacobi")
        ```
    """
    run = _one_run(run)
    if coupling is not None:
        if coupling not in COUPLINGS:
            raise ValueError(f"coupling: choose one of {', '.join(COUPLINGS)}, not {coupling!r}")
        run = dataclasses.replace(run, coupling=coupling)
    chosen = fmu if fmu is not None else run.fmu
    if chosen is None:
        raise ScenarioError(f"{run.source or run.label}: no fmu: key and no fmu argument (name the plant FMU)")
    if time_limit is not None and not time_limit > 0:
        raise ValueError(f"time_limit: give a positive number of seconds, not {time_limit!r}")
    plant = checked_plant(os.fspath(chosen))
    checked = _checks(run, plant, own_controller=controller is None)
    controller = _adapted(controller, run, plant)
    if controller is not None:
        try:
            check_controller(controller, plant.recorded_outputs)
        except ControllerError as error:
            raise ScenarioError(f"controller: {error}") from None
    outcome = _outcome(run, plant, supervised, time_limit, progress, controller, checked)
    units = trace_units(outcome.trace.names, plant, run.controller.objective)
    if isinstance(outcome.record.get("units"), dict):  # a system's run: its columns' own units
        units = dict(outcome.record["units"])
    elif (
        controller is not None or run.controller.python is not None or run.controller.fmu is not None
    ):  # e, S, phase: only the built-in law's units
        units = {name: unit for name, unit in units.items() if name not in VSCController.diagnostics}
    result = Result.from_outcome(outcome, units)
    if outcome.interrupted:
        raise RunInterrupted(result)
    return result
