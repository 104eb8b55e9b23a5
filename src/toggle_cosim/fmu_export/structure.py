"""Which knowns each variable of a causalized model depends on: the `dependencies` of the
modelDescription's ModelStructure (FMI 2.0 sec. 2.2.8, FMI 3.0 "Model Structure").

Read off the schedule, as `modelica.ir.system.Mode.sparsity` reads the state Jacobian: the
blocks are sorted so that everything a block reads was computed before it, so one pass
gives, for every variable, the states and parameter slots (inputs among them) it reaches.
A simultaneous block gives each of its unknowns the union of what the whole block reads
(conservative: it may over-report, never under-report). Nothing is evaluated.

Two views come out of that one pass:

* continuous: the states and inputs a variable depends on while the model runs -- the
  dependencies of Outputs and Derivatives;
* initial: the inputs and independent parameters it depends on at initialisation, where a
  state stands for its start expression and a calculated parameter for its binding -- the
  dependencies of InitialUnknowns.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from modelica.ir import nodes as ir
from modelica.ir.rewrite import names
from modelica.ir.system import System


@dataclass(frozen=True)
class Dependencies:
    """Per variable name: the knowns it depends on (names), in the two views."""

    continuous: Mapping[str, frozenset[str]]
    initial: Mapping[str, frozenset[str]]


def _names(node: ir.Expr | None) -> frozenset[str]:
    return frozenset(names(node)) if node is not None else frozenset()


def model_dependencies(
    system: System,
    inputs: Iterable[str],
    independent: Iterable[str],
    start: Mapping[str, ir.Expr | None],
    bindings: Mapping[str, ir.Expr | None],
) -> Dependencies:
    """Dependencies of every variable of `system`.

    `inputs`: the top-level inputs (parameter slots in the causalized model);
    `independent`: the parameters a user sets (initial = exact); `start`: each state's start
    expression; `bindings`: each calculated parameter's binding.
    """
    inputs = frozenset(inputs)
    independent = frozenset(independent)
    parameters = {v.name for v in system.parameters}
    seeds = frozenset(system.states) | frozenset(parameters)
    reaches: dict[str, frozenset[str]] = {name: frozenset({name}) for name in seeds}

    def carried(node: ir.Expr | None) -> frozenset[str]:
        found: frozenset[str] = frozenset()
        for name in _names(node):
            found |= reaches.get(name, frozenset())
        return found

    for block in system.blocks:
        if block.assignment is not None:
            reaches[block.unknowns[0]] = carried(block.assignment)
            continue
        whole: frozenset[str] = frozenset()
        for equation in block.equations:
            whole |= carried(equation.lhs) | carried(equation.rhs)
        for _, value in block.torn:
            whole |= carried(value)
        for name in block.solved:
            reaches[name] = whole
    for name, expression in system.aliases.items():
        if name not in reaches:
            reaches[name] = carried(expression)

    states = frozenset(system.states)
    continuous = {name: found & (states | inputs) for name, found in reaches.items()}

    expanded: dict[str, frozenset[str]] = {}

    def at_start(name: str, trail: frozenset[str] = frozenset()) -> frozenset[str]:
        """The inputs and independent parameters `name` (a seed) stands for at the start."""
        if name in expanded:
            return expanded[name]
        if name in inputs or name in independent:
            return frozenset({name})
        if name in trail:  # a cycle cannot be in a valid model; stop rather than recurse
            return frozenset()
        source = start.get(name) if name in states else bindings.get(name)
        found: frozenset[str] = frozenset()
        for read in _names(source):
            if read in seeds:
                found |= at_start(read, trail | {name})
        expanded[name] = found
        return found

    initial: dict[str, frozenset[str]] = {}
    for name, found in reaches.items():
        result: frozenset[str] = frozenset()
        for seed in found:
            result |= at_start(seed)
        initial[name] = result
    return Dependencies(continuous=continuous, initial=initial)
