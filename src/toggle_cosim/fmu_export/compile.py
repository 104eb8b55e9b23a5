"""Modelica source -> C: flatten, causalize and emit with the `modelica` package, then write
the tables and the two functions the generic FMI shell needs (see `shell/md_model.h`).

Nothing here knows the toggle mechanism: every variable, parameter, state and event comes
from the flat model. What the compiler (modelica==0.0.205) leaves to us, and this module
adds:

* top-level ``input`` variables are not bound in its C, so each becomes a parameter slot
  before causalization; the FMU writes an input into that slot;
* parameter bindings have no C code, so `md_parameters` recomputes the calculated parameters
  in dependency order from the independent ones;
* start values are written as C in `md_start`, so a start value that depends on a parameter
  (the initial angles of eq. (26)) follows the parameter set before initialisation.
"""

from __future__ import annotations

import dataclasses
import hashlib
import sys
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from modelica.ir import nodes as ir
from modelica.ir.flat import FlatModel, FlatVariable
from modelica.ir.flatten import FlattenError
from modelica.sim import CausalizationError, EmitError, causalize, flatten
from modelica.sim.cgen import unit
from modelica.sim.dialect import C
from modelica.sim.emit import Emitter, emit_expr, settings

from toggle_cosim.fmu_export.c_names import check_c_names
from toggle_cosim.fmu_export.experiment import Experiment, ExperimentError, experiment_of
from toggle_cosim.fmu_export.source import ModelSourceError, load_program
from toggle_cosim.fmu_export.structure import Dependencies, model_dependencies

Kind = Literal["parameter", "input", "calculated", "constant", "state", "computed"]
_SHELL_KIND = {
    "parameter": "MD_PARAMETER",
    "input": "MD_INPUT",
    "calculated": "MD_CALCULATED",
    "constant": "MD_CALCULATED",
    "state": "MD_COMPUTED",
    "computed": "MD_COMPUTED",
}


class ModelCompileError(Exception):
    """The model could not be compiled; the message says which stage failed and why."""


@dataclass(frozen=True)
class ModelVariable:
    """One variable of the compiled model, as the FMU exposes it."""

    name: str
    value_reference: int
    kind: Kind
    causality: str  # as the flat model declares it: "input", "output" or "none"
    base_type: str  # "Real" or "Boolean"
    unit: str
    description: str
    start: float | None  # a literal start (parameters, inputs, constants, literal state starts)
    obs_slot: int
    par_slot: int  # -1 unless the value lives in p
    discrete: bool = False  # assigned only in `when` clauses


@dataclass(frozen=True)
class GeneratedModel:
    """The C source of one model and what the modelDescription needs to describe it."""

    name: str
    description: str
    guid: str
    c_source: str
    variables: tuple[ModelVariable, ...]
    states: tuple[str, ...]
    derivatives: tuple[str, ...]
    event_count: int
    # ModelStructure dependencies by variable name (states, der_ variables and the model's
    # variables): see structure.py. Empty: unknown (the description then claims all).
    dependencies: Dependencies = Dependencies(continuous={}, initial={})
    experiment: Experiment = Experiment()  # from the `experiment` annotation

    def variable(self, name: str) -> ModelVariable:
        for variable in self.variables:
            if variable.name == name:
                return variable
        raise KeyError(name)


def _references(node: ir.Expr | None) -> set[str]:
    """Every variable name an expression reads."""
    found: set[str] = set()

    def visit(value: object) -> None:
        if isinstance(value, ir.Ref):
            found.add(".".join(str(part) for part in value.parts))
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            for field in dataclasses.fields(value):
                visit(getattr(value, field.name))
        elif isinstance(value, tuple):
            for item in value:
                visit(item)

    visit(node)
    return found


def _inputs_as_parameters(flat: FlatModel) -> tuple[FlatModel, frozenset[str]]:
    """Turn each top-level input into a tunable parameter slot (see the module docstring)."""
    inputs = frozenset(v.name for v in flat.variables if v.causality == "input")
    variables = tuple(
        dataclasses.replace(v, variability="parameter", causality="none", binding=None) if v.name in inputs else v
        for v in flat.variables
    )
    return dataclasses.replace(flat, variables=variables), inputs


def _c_number(value: float | bool) -> str:
    return repr(float(value))


def _start_function(
    system_parameters: tuple[FlatVariable, ...],
    states: tuple[str, ...],
    discrete: list[tuple[int, ir.Expr | None]],
    flat: FlatModel,
    nw: int,
) -> list[str]:
    """md_start: the start value of every state and discrete variable, as C over p."""
    symbols = {v.name: f"p[{slot}]" for slot, v in enumerate(system_parameters)}
    lines = [
        "void md_start(const double *p, double *y, double *w) {",
        f"    for (int i = 0; i < {nw}; ++i) {{ w[i] = 0.0; }}",
    ]
    for slot, name in enumerate(states):
        start = flat[name].start
        lines.append(f"    y[{slot}] = {emit_expr(start, symbols, dialect=C) if start is not None else '0.0'};")
    for w_slot, start in discrete:
        lines.append(f"    w[{w_slot}] = {emit_expr(start, symbols, dialect=C) if start is not None else '0.0'};")
    if len(lines) == 2:
        lines.append("    (void)p; (void)y;")
    lines.append("}")
    return lines


def _defaults_function(variables: list[ModelVariable]) -> list[str]:
    """p at the values the source declares, for every slot a user may set."""
    lines = ["void md_defaults(double *p) {"]
    for variable in variables:
        if variable.kind in ("parameter", "input") and variable.start is not None:
            lines.append(f"    p[{variable.par_slot}] = {_c_number(variable.start)};  /* {variable.name} */")
    if len(lines) == 1:
        lines.append("    (void)p;")
    lines.append("}")
    return lines


def _parameter_function(
    parameters: tuple[FlatVariable, ...], calculated: set[str], order: list[FlatVariable]
) -> list[str]:
    """md_parameters: every calculated parameter from its binding, in dependency order."""
    symbols = {v.name: f"p[{slot}]" for slot, v in enumerate(parameters)}
    slots = {v.name: slot for slot, v in enumerate(parameters)}
    lines = ["void md_parameters(double *p) {"]
    for variable in order:
        if variable.name in calculated and variable.binding is not None:
            lines.append(f"    p[{slots[variable.name]}] = {emit_expr(variable.binding, symbols, dialect=C)};")
    if len(lines) == 1:
        lines.append("    (void)p;")
    lines.append("}")
    return lines


def _nominal(variable: FlatVariable | None) -> float:
    """The state's `nominal` attribute if it is a positive literal, else 1.0 (FMI's default)."""
    nominal = getattr(variable, "nominal", None)
    if isinstance(nominal, (ir.RealLiteral, ir.IntLiteral)) and abs(float(nominal.value)) > 0:
        return abs(float(nominal.value))
    return 1.0


def is_guard(name: str) -> bool:
    """A guard of the model: a variable whose name's last component starts with `guard`
    (`mechanism.guardSlip`). The shell fails at an event after which a guard is not positive
    (shell/md_model.h): the model says so where its modes admit no consistent solution."""
    return name.rsplit(".", 1)[-1].startswith("guard")


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def compile_model(source: Path, model: str) -> GeneratedModel:
    """Compile class `model` (a dotted name) found in `source` (package directory or .mo file).
    ModelCompileError (one line first) for anything the model's text makes fail, an expression
    nested deeper than the compiler can follow included."""
    try:
        return _compile_model(source, model)
    except RecursionError:
        raise ModelCompileError(
            f"{source}: cannot compile {model}: an expression is nested too deeply for the compiler "
            f"(limit about {sys.getrecursionlimit() // 5} levels); split it with intermediate variables"
        ) from None


def _compile_model(source: Path, model: str) -> GeneratedModel:
    try:
        program = load_program(source)
    except ModelSourceError as error:
        raise ModelCompileError(str(error)) from error
    try:
        flat = flatten(program, model)
    except (FlattenError, KeyError, ValueError) as error:
        raise ModelCompileError(f"{source}: cannot flatten {model}: {error}") from error
    flat, inputs = _inputs_as_parameters(flat)
    try:
        system = causalize(flat)
    except CausalizationError as error:
        raise ModelCompileError(f"{source}: cannot causalize {model}: {error}") from error
    try:
        body = unit(system)
        values = settings(system)
    except EmitError as error:
        raise ModelCompileError(f"{source}: cannot emit C for {model}: {error}") from error

    emitter = Emitter(system)
    try:
        check_c_names({name: emitter.symbols[name] for name in emitter.observed}, body)
    except ValueError as error:
        raise ModelCompileError(f"{source}: cannot emit C for {model}: {error}") from error
    events = emitter.events()
    observed = emitter.observed
    parameters = system.parameters
    par_slots = {v.name: slot for slot, v in enumerate(parameters)}
    parameter_names = set(par_slots)
    calculated = {
        v.name
        for v in parameters
        if v.variability == "constant" or (v.name not in inputs and _references(v.binding) & parameter_names)
    }
    states = system.states
    flat_by_name = {v.name: v for v in flat.variables}
    nw = len(observed) + len(emitter.watched) + (1 if emitter.switching is not None else 0)

    variables: list[ModelVariable] = []
    for slot, name in enumerate(observed):
        info = flat_by_name.get(name)
        if info is None:  # a der_ variable the causalizer introduced
            continue
        if name in inputs:
            kind: Kind = "input"
        elif info.variability == "constant":
            kind = "constant"
        elif name in calculated:
            kind = "calculated"
        elif name in par_slots:
            kind = "parameter"
        elif name in states:
            kind = "state"
        else:
            kind = "computed"
        start: float | None = None
        if kind in ("parameter", "input", "constant"):
            start = float(values[name])
        elif kind == "state" and isinstance(info.start, (ir.RealLiteral, ir.IntLiteral)):
            start = float(info.start.value)
        variables.append(
            ModelVariable(
                name=name,
                value_reference=len(variables),
                kind=kind,
                causality="input" if name in inputs else info.causality,
                base_type="Boolean" if info.base_type == "Boolean" else "Real",
                unit=info.unit,
                description=info.comment,
                start=start,
                obs_slot=slot,
                par_slot=par_slots.get(name, -1),
                discrete=info.variability == "discrete",
            )
        )

    discrete = [(emitter.slots[name], flat_by_name[name].start) for name in emitter.remembered if name in flat_by_name]
    dependencies = model_dependencies(
        system,
        inputs=inputs,
        independent=[v.name for v in variables if v.kind == "parameter"],
        start={name: flat_by_name[name].start for name in states if name in flat_by_name},
        bindings={v.name: v.binding for v in parameters},
    )
    top = program.find(model)
    try:
        experiment = experiment_of(top, model)
    except ExperimentError as error:
        raise ModelCompileError(f"{source}: {error}") from error
    digest = hashlib.sha256(body.encode()).hexdigest()
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"toggle-cosim:{model}:{digest}")) + "}"
    n = len(variables)
    guards = [v for v in variables if is_guard(v.name) and v.kind == "computed"]
    tables = [
        "",
        "/* ---- Tables and start/parameter code written by toggle_cosim.fmu_export.compile ---- */",
        f"static const double md_direction_[{max(len(events), 1)}] = {{"
        + ", ".join(_c_number(e.trigger.direction) for e in events)
        + ("0.0" if not events else "")
        + "};",
        f"static const int md_latch_[{max(len(events), 1)}] = {{"
        + ", ".join(str(e.trigger.latch if e.trigger.latch is not None else -1) for e in events)
        + ("-1" if not events else "")
        + "};",
        f"static const int md_kind_[{n}] = {{" + ", ".join(_SHELL_KIND[v.kind] for v in variables) + "};",
        f"static const int md_obs_[{n}] = {{" + ", ".join(str(v.obs_slot) for v in variables) + "};",
        f"static const int md_par_[{n}] = {{" + ", ".join(str(v.par_slot) for v in variables) + "};",
        f"static const char *const md_names_[{n}] = {{" + ", ".join(_c_string(v.name) for v in variables) + "};",
        f"static const int md_guard_[{max(len(guards), 1)}] = {{"
        + (", ".join(str(v.obs_slot) for v in guards) or "-1")
        + "};",
        f"static const char *const md_guard_text_[{max(len(guards), 1)}] = {{"
        + (", ".join(_c_string(v.description or "inconsistent mode") for v in guards) or "0")
        + "};",
        f"static const double md_nominal_[{max(len(states), 1)}] = {{"
        + ", ".join(_c_number(_nominal(flat_by_name.get(name))) for name in states)
        + ("1.0" if not states else "")
        + "};",
        "/* the interface types modelDescription.xml offers: package.py defines MD_INTERFACES */",
        "#ifndef MD_INTERFACES",
        "#define MD_INTERFACES MD_INTERFACE_CS",
        "#endif",
        "const md_info MD_INFO = {",
        f"    {_c_string(model)}, {_c_string(guid)},",
        f"    {len(states)}, {len(parameters)}, {nw}, {len(observed)}, {len(events)},",
        "    md_direction_, md_latch_,",
        f"    {n}, md_kind_, md_obs_, md_par_, md_names_,",
        "    md_nominal_, MD_INTERFACES,",
        f"    {len(guards)}, md_guard_, md_guard_text_",
        "};",
        "",
        *_defaults_function(variables),
        "",
        *_parameter_function(parameters, calculated, emitter.ordered()),
        "",
        *_start_function(parameters, states, discrete, flat, nw),
        "",
    ]
    header = [
        f"/* {model}: generated by toggle_cosim.fmu_export from the Modelica source. Do not edit. */",
        '#include "md_model.h"',
    ]
    c_source = "\n".join(header) + "\n" + body + "\n".join(tables)
    return GeneratedModel(
        name=model,
        description=top.comment if top is not None else "",
        guid=guid,
        c_source=c_source,
        variables=tuple(variables),
        states=tuple(states),
        derivatives=tuple(system.derivative[s] for s in states),
        event_count=len(events),
        dependencies=dependencies,
        experiment=experiment,
    )
