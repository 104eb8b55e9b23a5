"""The plant contract as a Markdown table, generated from contract.yaml (`plant.contract`).

The table stands between the markers BEGIN and END in docs/plant-contract.md;
`tests/test_contract.py` checks that each equals what this module generates, and

    python -m toggle_cosim.plant.contract_table docs/plant-contract.md

writes it there again after a change of contract.yaml.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from toggle_cosim.plant.contract import CONTRACT, DIMENSIONLESS, ContractVariable

BEGIN = "<!-- plant contract table: generated from src/toggle_cosim/plant/contract.yaml, do not edit -->"
END = "<!-- end of the plant contract table -->"


def _tier(variable: ContractVariable) -> str:
    if variable.required:
        return "**required**"
    if variable.required_for:
        return "optional; required for objective " + ", ".join(f"`{name}`" for name in variable.required_for)
    return "optional"


def _unit(variable: ContractVariable) -> str:
    if variable.unit is None:
        return "—"
    return "1 (none needed)" if variable.unit == DIMENSIONLESS else variable.unit


def markdown_table(contract: Sequence[ContractVariable] = CONTRACT) -> str:
    """One row per contract variable, in the contract's order."""
    lines = ["| name | causality | type | unit | tier | meaning |", "|---|---|---|---|---|---|"]
    for v in contract:
        meaning = v.meaning.replace("|", "\\|")
        lines.append(f"| `{v.name}` | {v.causality} | {v.type} | {_unit(v)} | {_tier(v)} | {meaning} |")
    return "\n".join(lines) + "\n"


def replace_table(text: str, table: str | None = None) -> str:
    """`text` with the part between BEGIN and END replaced by the generated table."""
    start, end = text.index(BEGIN) + len(BEGIN), text.index(END)
    return f"{text[:start]}\n{table or markdown_table()}{text[end:]}"


def main(paths: Sequence[str]) -> None:
    for path in map(Path, paths):
        path.write_text(replace_table(path.read_text(encoding="utf-8")), encoding="utf-8")


if __name__ == "__main__":
    main(sys.argv[1:])
