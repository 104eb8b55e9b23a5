"""The controller FMU's variables, generated from the law's one definition: the inputs the law
may read, the outputs it produces (the command and the diagnostics the master records), and its
parameters, every field of `control.parameters.LawParameters` but t0 and T_h (computed at the
first sample), with the unit, description and bounds of the field's metadata.

Value references: 0 the independent variable time (FMI 3.0 only), then the inputs, the outputs
and the parameters in the order listed here.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.parameters import STARTED, LawParameters
from toggle_cosim.physics.mechanism import theta1_from_xB
from toggle_cosim.physics.parameters import MechanismParameters

__all__ = [
    "CODES",
    "PAPER_X_START",
    "REFERENCE_INPUTS",
    "FmuVariable",
    "inputs",
    "markdown_table",
    "outputs",
    "parameters",
    "variables",
]

Causality = Literal["input", "output", "parameter"]

CODES = ("law", "objective", "tracking")  # parameters that are integer codes (0 or 1)
PAPER_X_START = 0.2329  # the paper's stroke start x_B(0) [m]: the inputs' start values


@dataclass(frozen=True)
class FmuVariable:
    """One Float64 (FMI 2.0: Real) variable of the controller FMU."""

    name: str
    value_reference: int
    causality: Causality
    unit: str
    description: str
    start: float | None = None
    minimum: float | None = None
    maximum: float | None = None
    code: bool = False


VR_TIME = 0
_INPUTS = (
    ("x_B", "m", "measured position of slider B (the x_B objective reads it)"),
    ("v_B", "m/s", "measured velocity of slider B (the x_B objective reads it)"),
    ("theta1", "rad", "measured lever angle theta1 (the theta1 objective reads it)"),
    ("omega1", "rad/s", "measured lever rate omega1 (the theta1 objective reads it)"),
    ("x_ref", "m", "reference position x_B*(t) of slider B (read when tracking = 1)"),
    ("v_ref", "m/s", "reference velocity dx_B*/dt (read when tracking = 1)"),
    ("a_ref", "m/s2", "reference acceleration d2x_B*/dt2, the feed-forward (read when tracking = 1)"),
)
REFERENCE_INPUTS = ("x_ref", "v_ref", "a_ref")  # the law's reference (q*, q̇*, q̈*), in this order
_OUTPUTS = (
    ("iq_ref", "A", "the command i_q* of eq. (25), held until the next sample"),
    ("S", "", "switching function S of the sample [m/s, or rad/s]"),
    ("phase", "", "0 reaching (eq. (23)), 1 sliding (eq. (24))"),
    ("e", "", "tracking error e = target - q (x_ref - x_B when tracking) [m, or rad]"),
    ("z", "", "the integral law's state z = integral of e dt at the next sample [m s, or rad s]"),
)


def input_starts() -> dict[str, float]:
    """The paper's first sample: at rest at x_B = 0.2329 m, θ1 by eq. (26) on the nominal mechanism."""
    return {
        "x_B": PAPER_X_START,
        "v_B": 0.0,
        "theta1": theta1_from_xB(PAPER_X_START, MechanismParameters(mu=0.0)),
        "omega1": 0.0,
        "x_ref": VSCController().target,
        "v_ref": 0.0,
        "a_ref": 0.0,
    }


def inputs() -> tuple[FmuVariable, ...]:
    starts = input_starts()
    return tuple(
        FmuVariable(name, VR_TIME + 1 + i, "input", unit, description, start=starts[name])
        for i, (name, unit, description) in enumerate(_INPUTS)
    )


def outputs() -> tuple[FmuVariable, ...]:
    first = VR_TIME + 1 + len(_INPUTS)
    return tuple(
        FmuVariable(name, first + i, "output", unit, description)
        for i, (name, unit, description) in enumerate(_OUTPUTS)
    )


def parameters(defaults: LawParameters | None = None) -> tuple[FmuVariable, ...]:
    """The parameters with the start values of `defaults` (the built-in controller's defaults:
    the paper's law on the x_B objective)."""
    values = defaults if defaults is not None else VSCController().law_parameters()
    first = VR_TIME + 1 + len(_INPUTS) + len(_OUTPUTS)
    fields = [f for f in dataclasses.fields(LawParameters) if f.name not in STARTED]
    return tuple(
        FmuVariable(
            f.name,
            first + i,
            "parameter",
            f.metadata["unit"],
            f.metadata["description"],
            start=float(getattr(values, f.name)),
            minimum=f.metadata["min"],
            maximum=f.metadata["max"],
            code=f.name in CODES,
        )
        for i, f in enumerate(fields)
    )


def variables() -> tuple[FmuVariable, ...]:
    """Every variable but time, in value-reference order."""
    return (*inputs(), *outputs(), *parameters())


def c_number(value: float | None, default: float) -> str:
    """A C double literal with the exact bits of `value` (repr round-trips), or `default`'s."""
    chosen = default if value is None else value
    if math.isinf(chosen):
        return "HUGE_VAL" if chosen > 0 else "(-HUGE_VAL)"
    return repr(float(chosen))


TABLE_BEGIN = "<!-- controller FMU variables: generated by toggle_cosim.controller_fmu.variables, do not edit -->"
TABLE_END = "<!-- end of the controller FMU variables -->"


def _escaped(text: str) -> str:
    """Markdown text with its asterisks (x_B*, i_q*) shown as written."""
    return text.replace("*", "\\*")


def markdown_table() -> str:
    """The variables as a Markdown table, one row each in value-reference order (docs/controller-fmu.md
    holds it between TABLE_BEGIN and TABLE_END; a test keeps it equal)."""
    lines = ["| name | value reference | causality | unit | start | description |", "|---|---|---|---|---|---|"]
    for v in variables():
        start = "" if v.start is None else f"{v.start:.10g}"
        lines.append(
            f"| `{v.name}` | {v.value_reference} | {v.causality} | {v.unit or '—'} | {start} | {_escaped(v.description)} |"
        )
    return "\n".join([TABLE_BEGIN, *lines, TABLE_END])
