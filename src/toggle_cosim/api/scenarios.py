"""Scenarios from a file or a dict, as the runs they define, by variant name.

    fig4 = tc.load_scenario("scenarios/fig4_nominal.yaml")
    list(fig4)                 # ['friction', 'no_friction']: the variants
    run = fig4["friction"]     # a Run: one co-simulation
    short = fig4.updated({"t_end": 0.3})   # the same scenario with keys changed, validated again

A scenario without variants has one run, under the name "run" (the folder name `toggle-cosim run`
writes it to); `Scenario.run` is that run. A dict is validated exactly as a YAML file is: the
first problem is one `ScenarioError` line naming the key and what is allowed.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toggle_cosim.experiments.scenario import ScenarioError, merge_documents, read_scenario, runs_from_document
from toggle_cosim.runs.definition import Run

__all__ = ["Scenario", "ScenarioError", "load_scenario", "scenario", "variant_name"]

NO_VARIANT = "run"  # the name of the one run of a scenario without variants


def variant_name(run: Run) -> str:
    """The run's variant, or "run" for the one run of a scenario without variants."""
    return run.variant if run.variant is not None else NO_VARIANT


@dataclass(frozen=True, eq=False)
class Scenario(Mapping[str, Run]):
    """A validated scenario: its runs by variant name (a read-only mapping, in the file's order).

    Attributes:
        name: the scenario's `name:` key.
        source: the file it was read from (None for a dict); a relative `fmu:` key is relative to it.
        document: the scenario document as validated (a copy: changing it changes nothing here).
        runs: the runs, one per variant.
    """

    name: str
    source: Path | None
    document: Mapping[str, Any]
    runs: tuple[Run, ...]

    def __getitem__(self, variant: str) -> Run:
        for run in self.runs:
            if variant_name(run) == variant:
                return run
        raise KeyError(f"scenario {self.name} has no variant {variant!r} (it has: {', '.join(self)})")

    def __iter__(self) -> Iterator[str]:
        return (variant_name(run) for run in self.runs)

    def __len__(self) -> int:
        return len(self.runs)

    def __repr__(self) -> str:
        return f"Scenario({self.name!r}, variants={list(self)!r})"

    @property
    def run(self) -> Run:
        """The scenario's only run; a scenario with several variants names them in a ValueError."""
        if len(self.runs) != 1:
            raise ValueError(
                f"scenario {self.name} has {len(self.runs)} variants ({', '.join(self)}); choose one: scenario[name]"
            )
        return self.runs[0]

    def updated(self, changes: Mapping[str, Any]) -> Scenario:
        """This scenario with `changes` merged in key by key (nested mappings merged, as a variant
        is), validated again: e.g. `updated({"t_end": 0.3, "plant": {"F_E": 50.0}})`. A top-level
        key applies to every variant that does not set it itself (a variant's own keys win, as in
        the file); `{"variants": {"friction": {"plant": {"mu": 0.1}}}}` changes one variant."""
        if not isinstance(changes, Mapping):
            raise ScenarioError(f"changes must be a mapping of scenario keys, not {type(changes).__name__}")
        return _build(merge_documents(dict(self.document), _plain(changes)), self.source)


def _plain(value: Any) -> Any:
    """A deep copy with every mapping a dict (what the YAML loader gives), so the schema sees the
    same kinds of values whether they came from a file or from Python."""
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_plain(item) for item in value]
    return copy.deepcopy(value)


def _build(document: dict[str, Any], source: Path | None) -> Scenario:
    try:
        runs = runs_from_document(document, source)
    except ScenarioError as error:
        raise ScenarioError(f"{source}: {error}" if source is not None else str(error)) from None
    return Scenario(str(document["name"]), source, copy.deepcopy(document), tuple(runs))


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file (YAML).

    Args:
        path: the scenario file; its relative `fmu:` and controller paths are relative to it.

    Returns:
        The `Scenario`: its runs by variant name.

    Raises:
        ScenarioError: one line, 'FILE: problem and fix' (a missing or misspelt key, a value out
            of range, bad YAML).

    Example:
        ```python
        fig4 = tc.load_scenario("scenarios/fig4_nominal.yaml")
        list(fig4)                                           # ['friction', 'no_friction']
        short = fig4.updated({"t_end": 0.3})["friction"]     # a Run
        ```
    """
    path = Path(path)
    document, runs = read_scenario(path)
    return Scenario(str(document["name"]), path, copy.deepcopy(document), tuple(runs))


def scenario(document: Mapping[str, Any]) -> Scenario:
    """A scenario from a dict with the keys of a scenario file (name, t_end [s], T_s [s], stroke
    [m], plant, controller, variants, ...), validated exactly as a file is. Raises ScenarioError
    with one line naming the key and the fix. A relative `fmu:` is relative to the current folder."""
    if not isinstance(document, Mapping):
        raise ScenarioError(
            f"a scenario is a mapping of scenario keys (name, t_end, T_s, stroke, ...), not {type(document).__name__}"
        )
    return _build(_plain(document), None)
