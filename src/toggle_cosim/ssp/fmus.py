"""What an SSP needs to know about its FMUs, from their modelDescription.xml: the variables by name,
their units and base units, and the checks that a component's parameters, connectors and
connections fit the FMU. Each failure is one SspError line naming the FMU and the fix."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toggle_cosim.controller_fmu.variables import REFERENCE_INPUTS
from toggle_cosim.plant.contract import declared_unit
from toggle_cosim.ssp import layout
from toggle_cosim.ssp.checks import SspError
from toggle_cosim.system.interfaces import SettableError, fmu_interface, settable_type
from toggle_cosim.system.model import Interface

__all__ = ["FmuVariables", "describe"]


@dataclass(frozen=True)
class FmuVariables:
    """An FMU's variables by name (FMPy's ScalarVariable objects) and its model description;
    `label` names the FMU in messages (its path, or the SSP and the member it came from)."""

    label: str
    model_description: Any
    variables: dict[str, Any]

    @classmethod
    def of(cls, label: str | Path, model_description: Any) -> FmuVariables:
        return cls(str(label), model_description, {v.name: v for v in model_description.modelVariables})

    def variable(self, name: str) -> Any:
        found = self.variables.get(name)
        if found is None:
            raise SspError(f"{self.label}: the FMU has no variable {name!r} (give an FMU that has it)")
        return found

    def unit(self, name: str) -> str | None:
        return declared_unit(self.variable(name)) or None

    def base_unit(self, unit: str) -> dict[str, float] | None:
        """The SI exponents (and factor, offset) the FMU's UnitDefinitions give `unit`, or None."""
        for definition in getattr(self.model_description, "unitDefinitions", None) or ():
            if definition.name == unit and definition.baseUnit is not None:
                base = definition.baseUnit
                names = ("kg", "m", "s", "A", "K", "mol", "cd", "rad", "factor", "offset")
                return {key: getattr(base, key) for key in names}
        return None

    def interface(self) -> Interface:
        """The FMU's connectors as the system sees them (`system.interfaces.fmu_interface`)."""
        return fmu_interface(self.model_description)

    def inputs(self) -> list[str]:
        """The FMU's inputs another FMU drives, in model-description order: all but the built-in
        law's reference inputs x_ref, v_ref, a_ref (`controller_fmu.variables.REFERENCE_INPUTS`),
        which an SSP leaves at their start values (the law's parameter tracking is 0 there)."""
        return [
            v.name
            for v in self.model_description.modelVariables
            if v.causality == "input" and v.name not in REFERENCE_INPUTS
        ]

    def value_type(self, name: str, value: object) -> str:
        """The SSV element of a parameter: the FMU variable's type (Real, Integer, Boolean),
        checked as every component's value is (`system.interfaces.settable_type`)."""
        try:
            return settable_type(self.variable(name), name, value)
        except SettableError as error:
            raise SspError(f"{self.label}: {error}") from None

    def check_parameters(self, values: Sequence[tuple[str, object]], component: str, source: str) -> None:
        """Every name of `values` (given by `source`) is a parameter or an input of the FMU, and
        its value of the variable's type (`system.interfaces.settable_type`)."""
        for name, value in values:
            try:
                settable_type(self.variables.get(name), name, value)
            except SettableError as error:
                raise SspError(
                    f"{self.label}: the {component} FMU: {error}, which {source} sets (give the {component} FMU "
                    "that has it, or fix the name or the value)"
                ) from None

    def check_controller(self, plant: FmuVariables) -> None:
        """The controller FMU fits the plant: Co-Simulation, an output iq_ref, and every input
        a plant output of the same name and unit."""
        if getattr(self.model_description, "coSimulation", None) is None:
            raise SspError(f"{self.label}: the controller FMU has no Co-Simulation interface (give a CS FMU)")
        command = self.variables.get(layout.COMMAND)
        if command is None or command.causality != "output":
            raise SspError(f"{self.label}: the controller FMU has no output {layout.COMMAND!r} (give ToggleVSC.fmu)")
        for name in self.inputs():
            source = plant.variables.get(name)
            if source is None or source.causality != "output":
                raise SspError(
                    f"{self.label}: the controller's input {name!r} is not an output of the plant {plant.label} "
                    "(give a plant with that output, or a controller that does not read it)"
                )
            if self.unit(name) and plant.unit(name) and self.unit(name) != plant.unit(name):
                raise SspError(
                    f"{self.label}: the controller's input {name!r} is in {self.unit(name)}, the plant's output in "
                    f"{plant.unit(name)} (give FMUs that agree on the unit)"
                )


def describe(path: Path, what: str = "controller", label: str | None = None) -> FmuVariables:
    """An FMU's variables, its archive checked first (`plant.archive`); SspError otherwise.
    `label` names it in messages (default: its path)."""
    import fmpy

    from toggle_cosim.plant.archive import ArchiveError, read_model_description

    path = Path(path)
    shown = label or str(path)
    if not path.is_file():
        raise SspError(f"{shown}: no {what} FMU there (build it with toggle-cosim build, or name it with --{what})")
    try:
        names, description = read_model_description(path)
    except (ArchiveError, OSError, ValueError) as error:
        raise SspError(f"{shown}: not a usable FMU ({error}); give the {what} FMU") from None
    if description is None:
        raise SspError(f"{shown}: not an FMU (no modelDescription.xml); give the {what} FMU")
    try:
        model_description = fmpy.read_model_description(str(path), validate=False)
    except Exception as error:  # noqa: BLE001 - a foreign file: any failure is the message
        raise SspError(f"{shown}: its modelDescription.xml cannot be read ({' '.join(str(error).split())})") from None
    return FmuVariables.of(shown, model_description)
