"""The contract of a controller FMU, and the check that an FMU meets it before a run.

A scenario may name a controller FMU (``controller: {fmu: PATH}``) in place of the built-in law;
the master runs it as an FMU component of the run's execution (`cosim.controllers.ControllerFmuPart`).
Before any run,
`check_controller_fmu` refuses in one line, naming the file and the fix, an FMU that:

* is not a safe, readable FMU archive, is not FMI 2.0 or 3.0, has no Co-Simulation interface or
  no binary for this platform (the plant's checks: `contract.read_fmu`);
* can only step at a fixed step of its own that is not T_s (an FMU of the built-in law steps at
  its parameter T_s, which the master sets to the run's: `cosim.controllers.fmu_settings`);
* has no output ``iq_ref`` (the command, Real/Float64 in A: a missing unit is a warning, as for
  plants), or an output that is not Real/Float64 (the others are its diagnostics);
* has an input that is not a recorded output of the plant, or whose unit differs from that
  output's (the plant contract's unit, `contract.yaml`; a missing unit is a warning). The
  inputs x_ref, v_ref, a_ref are the exception: the built-in law's reference trajectory
  (`controller_fmu.variables.REFERENCE_INPUTS`), read by the FMU only when its parameter
  tracking is 1; the master leaves them at their start values.

Parameters: any; those of `control.parameters.LawParameters` (but t0 and T_h) mark an FMU that
runs the built-in law (``law_parameters``), whose settings the scenario's controller keys give.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from toggle_cosim.control.parameters import settable
from toggle_cosim.control.protocol import COMMAND_COLUMNS
from toggle_cosim.controller_fmu.variables import REFERENCE_INPUTS
from toggle_cosim.plant.contract import CONTRACT, ContractError, declared_unit, read_fmu

__all__ = ["COMMAND", "ControllerFmu", "LAW_PARAMETERS", "check_controller_fmu"]

COMMAND = COMMAND_COLUMNS[0]  # the output the master sends to the plant
COMMAND_UNIT = next(v.unit for v in CONTRACT if v.name == COMMAND)  # the plant contract's unit for its input: A
REALS = ("Real", "Float64")
# the LawParameters fields a controller FMU of the built-in law takes as parameters (it computes
# t0 and T_h itself, at its first sample)
LAW_PARAMETERS = settable()
OPTIONAL_LAW_PARAMETERS = ("tracking",)  # an FMU of the built-in law built before the reference inputs lacks it
_UNITS = {v.name: v.unit for v in CONTRACT if v.causality == "output"}
_FIX = "see docs/controllers.md, 'A controller FMU'"


@dataclass(frozen=True)
class ControllerFmu:
    """A checked controller FMU: where it is, what it reads and gives, and its value references.

    Attributes:
        inputs: its inputs, in model-description order (each a plant output of the same name),
            but the reference inputs.
        reference_inputs: which of x_ref, v_ref, a_ref it has (the built-in law's reference).
        diagnostics: its outputs other than iq_ref, in model-description order.
        parameters: its variables of causality parameter, by name (value reference, type).
        law_parameters: it has every LawParameters parameter but t0 and T_h (the built-in law's).
        warnings: what the check accepted with a warning (a missing unit).
    """

    path: Path
    model_description: object
    fmi_version: str
    sha256: str
    inputs: tuple[str, ...]
    diagnostics: tuple[str, ...]
    references: dict[str, int]
    types: dict[str, str]
    parameters: tuple[str, ...]
    law_parameters: bool
    warnings: tuple[str, ...] = ()
    reference_inputs: tuple[str, ...] = ()

    @property
    def model_identifier(self) -> str:
        return self.model_description.coSimulation.modelIdentifier

    @property
    def token(self) -> str:
        """The FMU's guid (FMI 2.0) or instantiationToken (FMI 3.0)."""
        md = self.model_description
        return md.guid if self.fmi_version.startswith("2") else md.instantiationToken


def _unit_problem(path: Path, name: str, declared: str | None, wanted: str | None, what: str) -> str | None:
    """A warning if the unit is missing; raise ContractError if it differs from `wanted`."""
    if wanted is None:
        return None
    if declared is None:
        return f"no unit declared for {name} (taken as {wanted})"
    if declared != wanted:
        raise ContractError(f"{path}: {what} {name!r} has unit {declared!r}, it must be {wanted!r} ({_FIX})")
    return None


def check_controller_fmu(path: Path, outputs: Sequence[str], T_s: float | None = None) -> ControllerFmu:
    """Check the controller FMU at `path` against a plant whose recorded outputs are `outputs` and
    a sample time `T_s` [s]; raise ContractError naming the first problem (one line). Kept while
    the file is unchanged."""
    path = Path(path)
    try:
        status = path.stat()
        key = (status.st_size, status.st_mtime_ns)
    except OSError:
        key = None
    return _checked(path.resolve() if key else path, key, tuple(outputs), T_s)


def _check_step(path: Path, md: object, T_s: float) -> None:
    """ContractError when the FMU steps only at a fixed step of its own (it cannot handle a
    variable communication step, and its default experiment names that step) other than T_s."""
    fixed = not getattr(md.coSimulation, "canHandleVariableCommunicationStepSize", True)
    experiment = md.defaultExperiment
    own_step = float(experiment.stepSize) if experiment is not None and experiment.stepSize else None
    if fixed and own_step is not None and abs(own_step - T_s) > 1e-9 * T_s:
        raise ContractError(
            f"{path}: the controller FMU steps only at its own step {own_step:g} s, not T_s = {T_s:g} s"
            " (set T_s to its step, or rebuild it for T_s)"
        )


@functools.lru_cache(maxsize=32)
def _checked(path: Path, _key: object, outputs: tuple[str, ...], T_s: float | None) -> ControllerFmu:
    archive = read_fmu(path, missing="fix the path of key controller.fmu, relative to the scenario file")
    md = archive.model_description
    warnings: list[str] = []
    inputs, diagnostics, parameters, reference_inputs = [], [], [], []
    references: dict[str, int] = {}
    types: dict[str, str] = {}
    command = None
    for variable in md.modelVariables:
        references[variable.name] = variable.valueReference
        types[variable.name] = variable.type
        if variable.causality == "parameter":
            parameters.append(variable.name)
        elif variable.causality == "input" and variable.name in REFERENCE_INPUTS:
            reference_inputs.append(variable.name)
        elif variable.causality == "input":
            inputs.append(variable.name)
            if variable.name not in outputs:
                raise ContractError(
                    f"{path}: the controller FMU's input {variable.name!r} is not an output of the plant"
                    f" (the plant gives {', '.join(outputs)}; remove the input or use a plant that has it)"
                )
            if variable.type not in REALS:
                raise ContractError(
                    f"{path}: input {variable.name!r} has type {variable.type}, it must be Real/Float64"
                )
            warning = _unit_problem(path, variable.name, declared_unit(variable), _UNITS.get(variable.name), "input")
            if warning:
                warnings.append(warning)
        elif variable.causality == "output":
            if variable.type not in REALS:
                raise ContractError(
                    f"{path}: output {variable.name!r} has type {variable.type}; the master reads Real/Float64"
                    " outputs only (make it Real, or drop it)"
                )
            if variable.name == COMMAND:
                command = variable
            else:
                diagnostics.append(variable.name)
    if command is None:
        raise ContractError(f"{path}: the controller FMU has no output {COMMAND!r} (the command i_q* in A; {_FIX})")
    law_parameters = set(LAW_PARAMETERS) - set(OPTIONAL_LAW_PARAMETERS) <= set(parameters)
    if T_s is not None and not law_parameters:  # the built-in law's FMU steps at its parameter T_s, set to the run's
        _check_step(path, md, T_s)
    warning = _unit_problem(path, COMMAND, declared_unit(command), COMMAND_UNIT, "output")
    if warning:
        warnings.append(warning)
    return ControllerFmu(
        path=path,
        model_description=md,
        fmi_version=md.fmiVersion,
        sha256=archive.sha256,
        inputs=tuple(inputs),
        diagnostics=tuple(diagnostics),
        references=references,
        types=types,
        parameters=tuple(parameters),
        law_parameters=law_parameters,
        warnings=tuple(warnings),
        reference_inputs=tuple(reference_inputs),
    )
