"""The controller of a run: the scenario's built-in VSC, or the user's own, checked against the
controller protocol (`control.protocol`) before the run.

A scenario names a user's controller by a factory::

    controller:
      python: "my_controllers:make_pid"    # module:callable, beside the scenario file or on sys.path (`user_code`)
      parameters: {Kp: 40.0, Ki: 5.0}       # passed to the factory as keyword arguments
      error: {output: x_B}                  # python-control systems only: y = x_B, r = target (or stroke.trajectory)
      command: iq_ref                       # python-control systems only: the input the system drives
      discretise: tustin                    # python-control systems only: sample a continuous-time system at T_s

The factory is called as ``factory(context, **parameters)`` with a `ControllerContext` (T_s, the
stroke, the scenario's built-in controller, ...) and returns an object that meets the protocol,
or a python-control system (`control.StateSpace`/`TransferFunction` with dt = T_s, one input
e = r − y or two, [r − y0, y − y0]), which `system_controller` adapts (`control.lti`), as it adapts one
given to `tc.simulate`. Or it names a controller FMU::

    controller:
      fmu: controllers/MyLaw.fmu            # relative to the scenario file
      parameters: {K_p: 40.0}               # FMU parameters, set by name before initialisation

checked by `plant.controller_contract` and run as an FMU component of the execution
(`ControllerFmuPart`, `systems`); an FMU with the
built-in law's parameters (`controller_contract.LAW_PARAMETERS`) first gets the scenario's own
controller settings. Every failure is a `ControllerError` whose message names the key and
the fix; the run commands prefix the scenario file.

`user_controller` runs the user's code (imports the module, calls the factory): the run
commands call it only in the run's supervised child (`supervision`); `own_controller` (the
built-in law, a controller FMU with its binary not loaded) and `check_user_controller` run none
of it, and the run's check (`checked.check_run`) calls them before any run. `controller_for` is
either, as the run asks.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toggle_cosim import interrupts
from toggle_cosim.control import trajectory
from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.lti import INPUTS, DiscreteSystemController
from toggle_cosim.control.parameters import settable_values
from toggle_cosim.control.protocol import Controller, ControllerContext, ControllerError, check_controller
from toggle_cosim.control.trajectory import SampledReference
from toggle_cosim.controller_fmu.variables import REFERENCE_INPUTS
from toggle_cosim.cosim import user_code
from toggle_cosim.messages import bounded_text, error_text
from toggle_cosim.physics.mechanism import theta1_from_xB
from toggle_cosim.physics.motor import thrust_constant
from toggle_cosim.physics.parameters import MechanismParameters, MotorParameters
from toggle_cosim.plant.contract import ContractError
from toggle_cosim.plant.controller_contract import ControllerFmu, check_controller_fmu
from toggle_cosim.runs.definition import Run

__all__ = [
    "ControllerFmuPart",
    "builds_in_child",
    "builtin_controller",
    "check_user_controller",
    "controller_for",
    "controller_record",
    "fmu_settings",
    "is_python_control_system",
    "load_factory",
    "one_line",
    "own_controller",
    "run_reference",
    "system_controller",
    "user_controller",
]


def builtin_controller(run: Run) -> VSCController:
    """The scenario's built-in controller, with its own nominal model (never the plant's parameters),
    tracking the run's trajectory (stroke.trajectory, sampled on the run's grid) if it has one."""
    nominal = MechanismParameters(mB=run.controller.nominal_m_B, mu=0.0)
    return VSCController(
        gains=run.controller.gains,
        nominal=nominal,
        K_f=thrust_constant(MotorParameters()),
        target=run.x_target,
        objective=run.controller.objective,
        law=run.controller.law,
        C_I=run.controller.C_I,
        K_I=run.controller.K_I,
        i_max=run.controller.i_max,
        T_s=run.T_s,
        reference=run_reference(run),
    )


def run_reference(run: Run) -> SampledReference | None:
    """The run's stroke.trajectory sampled on its grid (what the built-in law and a python-control
    system track), or None for a constant target."""
    if run.trajectory is None:
        return None
    return SampledReference.of(trajectory.build(run.trajectory), run.steps, run.T_s)


def one_line(error: BaseException) -> str:
    """An exception as one bounded line: its type and message (`messages.error_text`)."""
    return error_text(error)


def load_factory(spec: str, folder: Path | None) -> Callable[..., Any]:
    """The callable named by "package.module:attribute": the module beside the scenario file in
    `folder` (imported from its file under a name of its own, `user_code`), else from sys.path.
    Runs the user's module: call it in the run's supervised child. Raises ControllerError naming
    key controller.python and the fix."""
    module_name, _, attribute = spec.partition(":")
    where = f"beside the scenario file ({folder}) or on sys.path (PYTHONPATH)" if folder else "on sys.path (PYTHONPATH)"
    found = user_code.locate(module_name, folder)
    try:
        module = user_code.import_module(found)
    except BaseException as error:  # noqa: BLE001 - the user's module: any failure (SystemExit too) is the message
        if not interrupts.raised_by_code(error):
            raise
        raise ControllerError(
            f"key controller.python: cannot import {module_name!r} ({one_line(error)}); put the module {where}"
        ) from None
    attr: Any = module
    for part in attribute.split("."):
        try:
            attr = getattr(attr, part)
        except AttributeError:
            raise ControllerError(
                f"key controller.python: module {module_name!r} has no {attribute!r} (name a factory in it as {module_name}:NAME)"
            ) from None
    if not callable(attr):
        raise ControllerError(
            f"key controller.python: {spec} is a {type(attr).__name__}, not a callable (name a factory function or class)"
        )
    return attr


def check_user_controller(run: Run, outputs: Sequence[str] = ()) -> ControllerFmu | None:
    """The checks of a run's user controller that run none of its code (the command makes them
    before any run): controller.python's module found (`user_code.locate`) and, beside the
    scenario file, owned by the user; controller.fmu's archive checked against the protocol,
    owned by the user, and controller.parameters that it has, of its types. The checked FMU
    (its warnings are the command's to print), or None. Raises ControllerError."""
    settings = run.controller
    if settings.python is not None:
        user_code.locate(settings.python.partition(":")[0], run.source.parent if run.source is not None else None)
        return None
    if settings.fmu is None:
        return None
    fmu = _checked_fmu(run, outputs)
    fmu_settings(run, fmu)
    return fmu


def _context(run: Run, outputs: Sequence[str]) -> ControllerContext:
    return ControllerContext(
        T_s=run.T_s,
        t_end=run.t_end,
        x_start=run.x_start,
        x_target=run.x_target,
        objective=run.controller.objective,
        label=run.label,
        outputs=tuple(outputs),
        builtin=builtin_controller(run),
    )


def _error_target(run: Run, output: str, given: float | None) -> float:
    """The target of a python-control system's error: given, or stroke.x_target for x_B and
    θ1* (eq. (26), the nominal geometry) for theta1."""
    if given is not None:
        return given
    if output == "x_B":
        return run.x_target
    if output == "theta1":
        return theta1_from_xB(run.x_target, MechanismParameters(mB=run.controller.nominal_m_B, mu=0.0))
    raise ControllerError(
        f"key controller.error.target: missing; the error acts on {output!r}, so give its target value"
        " (only x_B and theta1 have a default, from stroke.x_target)"
    )


def is_python_control_system(candidate: object) -> bool:
    """Whether `candidate` is a python-control system (an LTI object: StateSpace, TransferFunction)."""
    control = sys.modules.get("control")  # imported by whoever made such a system
    return control is not None and isinstance(candidate, control.LTI)


def system_controller(
    system: Any, run: Run, outputs: Sequence[str] = (), factory: str | None = None
) -> DiscreteSystemController:
    """The controller of a python-control `system` in `run` (`control.lti.DiscreteSystemController`):
    it reads the plant output controller.error.output (default: the objective's, x_B or theta1),
    its reference r is the run's stroke.trajectory or else controller.error.target (default
    `_error_target`), and a continuous-time system is sampled at T_s by controller.discretise.
    `factory`: the controller.python that returned the system (None: the user gave it). Raises
    ControllerError naming the key and the fix (the system's own problem under controller.python)."""
    settings = run.controller
    output = settings.error.output if settings.error is not None else settings.objective
    given = settings.error.target if settings.error is not None else None
    if outputs and output not in outputs:
        raise ControllerError(
            f"key controller.error.output: the plant has no output {output!r} (choose one of {', '.join(outputs)})"
        )
    reference = run_reference(run)
    if reference is not None and output != "x_B":
        raise ControllerError(
            f"key controller.error.output: stroke.trajectory is a profile of x_B, not of {output!r} (read x_B,"
            " or remove stroke.trajectory)"
        )
    try:
        return DiscreteSystemController(
            system,
            output,
            _error_target(run, output, given) if reference is None else run.x_target,
            run.T_s,
            reference=reference,
            discretise=settings.discretise,
        )
    except ValueError as error:
        if factory is None:  # a system given to simulate
            raise ControllerError(f"the python-control system is {error}") from None
        raise ControllerError(f"key controller.python: {factory} returned {error}") from None


def fmu_settings(run: Run, fmu: ControllerFmu) -> list[tuple[str, Any]]:
    """The parameters set on a controller FMU before initialisation, in order: for an FMU of the
    built-in law, the scenario's controller settings (`builtin_controller(run).law_parameters()`,
    by name, t0 and T_h excepted), then controller.parameters by name. Raises ControllerError
    for a parameter the FMU does not have, and for a T_s other than the run's on an FMU of the
    built-in law (it steps at its parameter T_s)."""
    settings: dict[str, Any] = {}
    if fmu.law_parameters:
        settings.update(
            (name, value)
            for name, value in settable_values(builtin_controller(run).law_parameters())
            if name in fmu.parameters  # an FMU built before the parameter tracking has none
        )
    for name, value in run.controller.parameters.items():
        if name not in fmu.parameters:
            known = ", ".join(fmu.parameters) or "none"
            raise ControllerError(
                f"key controller.parameters.{name}: the controller FMU {fmu.path.name} has no parameter {name!r}"
                f" (its parameters: {known})"
            )
        wanted = _value_kind(fmu.types.get(name, "Real"))
        if not _fits(wanted, value):
            raise ControllerError(
                f"key controller.parameters.{name}: the controller FMU {fmu.path.name}'s parameter {name!r} is of"
                f" type {fmu.types.get(name, 'Real')}, so give {wanted}, not {bounded_text(repr(value), 60)}"
            )
        if fmu.law_parameters and name == "T_s" and value != run.T_s:
            raise ControllerError(
                f"key controller.parameters.T_s: the controller FMU {fmu.path.name} steps at its parameter T_s, which"
                f" is the run's T_s = {run.T_s:g} s; {bounded_text(repr(value), 60)} would refuse every step (remove"
                " it, or set the scenario's T_s)"
            )
        settings[name] = value
    return list(settings.items())


_INTEGER_TYPES = ("Integer", "Int8", "Int16", "Int32", "Int64", "UInt8", "UInt16", "UInt32", "UInt64", "Enumeration")


def _value_kind(fmi_type: str) -> str:
    """What a scenario value for an FMU variable of `fmi_type` must be, in words."""
    if fmi_type == "Boolean":
        return "true or false"
    if fmi_type == "String":
        return "a string"
    return "an integer" if fmi_type in _INTEGER_TYPES else "a number"


def _fits(kind: str, value: object) -> bool:
    if kind == "true or false":
        return isinstance(value, bool)
    if kind == "a string":
        return isinstance(value, str)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return float(value).is_integer() if kind == "an integer" else True


def _checked_fmu(run: Run, outputs: Sequence[str]) -> ControllerFmu:
    """controller.fmu's archive checked against the protocol, the plant's outputs and T_s, and
    owned by the user running (`user_code.check_owned`); its binary is not loaded."""
    assert run.controller.fmu is not None
    if Path(run.controller.fmu).exists():  # a missing file: the contract check's message
        user_code.check_owned(Path(run.controller.fmu), "key controller.fmu")
    try:
        return check_controller_fmu(run.controller.fmu, outputs, run.T_s)
    except ContractError as error:
        raise ControllerError(f"key controller.fmu: {error}") from None


@dataclass(frozen=True)
class ControllerFmuPart:
    """A run's controller FMU as the execution runs it, an FMU component (`slaves.FmuSlave`): the
    checked archive (`fmu`; its binary is not loaded here), the values set on it before
    initialisation (`settings`) and the reference a tracking law follows (`reference`; None: its
    constant target). It names its diagnostics and measurements as the controller protocol does;
    the execution steps the FMU itself, so `start` and `step` are never called."""

    fmu: ControllerFmu
    settings: tuple[tuple[str, Any], ...]
    reference: SampledReference | None = None

    @property
    def diagnostics(self) -> tuple[str, ...]:
        return self.fmu.diagnostics

    @property
    def measured(self) -> tuple[str, ...]:
        """The plant outputs it reads: the FMU's inputs."""
        return self.fmu.inputs

    def start(self, t0: float, measurement: object) -> None:
        raise ControllerError(f"{self.fmu.path.name}: a controller FMU is stepped as an FMU component of the execution")

    def step(self, state: object, t: float, measurement: object) -> None:
        raise ControllerError(f"{self.fmu.path.name}: a controller FMU is stepped as an FMU component of the execution")


def _fmu_controller(run: Run, outputs: Sequence[str]) -> ControllerFmuPart:
    """The controller FMU of controller.fmu, checked, as the execution runs it (`ControllerFmuPart`)."""
    fmu = _checked_fmu(run, outputs)
    reference = None
    if run.trajectory is not None:
        if fmu.reference_inputs != REFERENCE_INPUTS or "tracking" not in fmu.parameters:
            raise ControllerError(
                f"key controller.fmu: {fmu.path.name} has no inputs {', '.join(REFERENCE_INPUTS)} and parameter"
                " tracking, so it cannot track stroke.trajectory (build the built-in law's FMU with toggle-cosim build,"
                " or remove stroke.trajectory)"
            )
        reference = builtin_controller(run).reference
    return ControllerFmuPart(fmu, tuple(fmu_settings(run, fmu)), reference)


def builds_in_child(run: Run) -> bool:
    """Whether the run's controller is built by calling the user's code (controller.python,
    without a controller.fmu, which wins): then it is built in the run's child, never where the
    run is checked."""
    return run.controller.python is not None and run.controller.fmu is None


def controller_for(run: Run, outputs: Sequence[str] = ()) -> Controller:
    """The controller of `run`: the built-in VSC or its controller FMU (`own_controller`), or what
    controller.python's factory returns (`user_controller`, a python-control system adapted),
    checked against the protocol; `outputs` are the plant's recorded outputs (the measurement's
    names, which diagnostics may not reuse). Raises ControllerError with the one-line reason."""
    return user_controller(run, outputs) if builds_in_child(run) else own_controller(run, outputs)


def own_controller(run: Run, outputs: Sequence[str] = ()) -> Controller:
    """The run's controller when it runs no code of the user's (no controller.python): the
    built-in VSC, or controller.fmu's `ControllerFmuPart` (its archive checked, its binary not
    loaded), checked against the protocol. Raises ControllerError with the one-line reason."""
    try:
        if run.controller.fmu is not None:
            return _checked(run, _fmu_controller(run, outputs), outputs)
        return _checked(run, builtin_controller(run), outputs)
    except ControllerError as error:  # the scenario's module names, as the scenario gave them
        raise ControllerError(user_code.shown(str(error))) from None


def user_controller(run: Run, outputs: Sequence[str] = ()) -> Controller:
    """What controller.python's factory returns (its module imported, the factory called: the
    user's code runs, in the run's child), a python-control system adapted (`system_controller`),
    checked against the protocol. Raises ControllerError with the one-line reason."""
    try:
        return _checked(run, _user_controller(run, outputs), outputs)
    except ControllerError as error:  # the scenario's module names, as the scenario gave them
        raise ControllerError(user_code.shown(str(error))) from None


def _user_controller(run: Run, outputs: Sequence[str]) -> Any:
    settings = run.controller
    assert settings.python is not None
    factory = load_factory(settings.python, run.source.parent if run.source is not None else None)
    try:
        controller = factory(_context(run, outputs), **dict(settings.parameters))
    except BaseException as error:  # noqa: BLE001 - the user's factory: any failure is the message
        if not interrupts.raised_by_code(error):
            raise
        names = ", ".join(settings.parameters) or "none"
        raise ControllerError(
            f"key controller.python: {settings.python} raised {one_line(error)} (called with the context and"
            f" controller.parameters: {names}; fix the factory or the parameters)"
        ) from None
    if is_python_control_system(controller):
        if settings.error is None:
            raise ControllerError(
                f"key controller.error: missing; {settings.python} returned a python-control system, so name the"
                " plant output it reads (error: {output: x_B})"
            )
        return system_controller(controller, run, outputs, settings.python)
    if settings.error is not None or settings.discretise is not None:
        key = "error" if settings.error is not None else "discretise"
        raise ControllerError(
            f"key controller.{key}: {settings.python} returned a controller, not a python-control system; the {key}"
            " is for python-control systems only (remove it: the controller reads the measurement itself)"
        )
    return controller


def _checked(run: Run, controller: Any, outputs: Sequence[str]) -> Controller:
    """`controller` checked against the protocol, a failure naming its key (controller.python, .fmu)."""
    settings = run.controller
    try:
        check_controller(controller, outputs)
    except ControllerError as error:
        key = "key controller.python: " if settings.python is not None else ""
        key = "key controller.fmu: " if settings.fmu is not None else key
        raise ControllerError(f"{key}{error}") from None
    return controller


def controller_record(run: Run, controller: object) -> dict[str, Any]:
    """What run.json says about the controller: the scenario's spec and the object's class."""
    kind = type(controller)
    record = {
        "python": run.controller.python,
        "parameters": dict(run.controller.parameters) if run.controller.python or run.controller.fmu else {},
        "class": f"{user_code.shown(kind.__module__)}.{kind.__qualname__}",
        "diagnostics": list(getattr(controller, "diagnostics", ())),
    }
    if isinstance(controller, DiscreteSystemController):  # a python-control system's adapter
        record["system"] = {
            "states": controller.matrices.n,
            "inputs": INPUTS[controller.matrices.m],
            "discretise": run.controller.discretise,
            "reference": "target" if controller.reference is None else "stroke.trajectory",
        }
    fmu = getattr(controller, "fmu", None)
    if run.controller.fmu is not None and isinstance(fmu, ControllerFmu):
        record["fmu"] = {
            "path": str(fmu.path),
            "sha256": fmu.sha256,
            "fmi_version": fmu.fmi_version,
            "model_name": fmu.model_description.modelName,
            "inputs": list(fmu.inputs),
            "law_parameters": fmu.law_parameters,
            "warnings": list(fmu.warnings),
        }
    return record
