"""The FMI interface types an FMU can offer, and the `--interfaces` choice that picks them."""

from __future__ import annotations

CO_SIMULATION = "CoSimulation"
MODEL_EXCHANGE = "ModelExchange"

Interfaces = frozenset[str]

# `toggle-cosim build --interfaces` choices
CHOICES: dict[str, Interfaces] = {
    "both": frozenset({CO_SIMULATION, MODEL_EXCHANGE}),
    "cs": frozenset({CO_SIMULATION}),
    "me": frozenset({MODEL_EXCHANGE}),
}
# One FMU with both interfaces, as OpenModelica and Dymola export by default: a Co-Simulation
# importer (our master) and a Model Exchange importer (its own solver) take the same file.
DEFAULT = "both"


def c_mask(interfaces: Interfaces) -> str:
    """The MD_INTERFACES value for model.c (shell/md_model.h MD_INTERFACE_* bits)."""
    bits = [
        name
        for name, wanted in (("MD_INTERFACE_CS", CO_SIMULATION), ("MD_INTERFACE_ME", MODEL_EXCHANGE))
        if wanted in interfaces
    ]
    return " | ".join(bits)


def parse(choice: str | Interfaces) -> Interfaces:
    """`choice` as a set of interface types ("both", "cs", "me", or already a set)."""
    if isinstance(choice, frozenset):
        if not choice or not choice <= CHOICES["both"]:
            raise ValueError(f"unknown interface types {sorted(choice)}")
        return choice
    try:
        return CHOICES[choice]
    except KeyError:
        raise ValueError(f"unknown interfaces {choice!r} (choose from {', '.join(CHOICES)})") from None
