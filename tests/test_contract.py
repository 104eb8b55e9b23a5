"""The plant contract file (`plant/contract.yaml`), the tables generated from it, and its tiers
on the shipped plant."""

from __future__ import annotations

from pathlib import Path

import pytest

from toggle_cosim.plant.contract import (
    CONTRACT,
    INPUTS,
    OUTPUTS,
    REQUIRED,
    load_contract,
    objective_requirements,
)
from toggle_cosim.plant.contract import check_plant as check
from toggle_cosim.plant.contract_table import BEGIN, END, markdown_table, replace_table

ROOT = Path(__file__).resolve().parent.parent
# The trace columns of the shipped plant before the contract had tiers: they must not move.
SHIPPED_COLUMNS = (
    "x_B v_B theta1 theta2 theta5 x_C i_q F_C lambda1 lambda2 N12 N23 N34 N25 N56 Ff12 Ff23 Ff34 Ff25 Ff56"
    " E_in E_fric E_load E_mech a_B omega1 v_C Phi1 Phi2"
).split()


@pytest.mark.parametrize("page", ["docs/plant-contract.md"])
def test_each_contract_table_is_the_generated_one(page: str) -> None:
    """The tables are generated from contract.yaml, never written by hand: regenerate them with
    `python -m toggle_cosim.plant.contract_table docs/plant-contract.md`."""
    text = (ROOT / page).read_text(encoding="utf-8")
    assert text.count(BEGIN) == 1 and text.count(END) == 1
    assert replace_table(text) == text, f"{page}: the contract table differs from contract.yaml's"
    assert markdown_table() in text


def test_the_tiers_of_the_contract() -> None:
    assert REQUIRED == ("iq_ref", "F_E", "x_B", "v_B", "m_B", "mu")
    assert INPUTS == ("iq_ref", "F_E")
    assert objective_requirements("theta1") == ("theta1", "omega1")
    assert objective_requirements("x_B") == ()
    assert OUTPUTS == tuple(SHIPPED_COLUMNS)
    assert len(markdown_table().splitlines()) == 2 + len(CONTRACT)


def test_a_broken_contract_file_is_refused() -> None:
    with pytest.raises(ValueError, match="variable 'x' has a causality, tier or type"):
        load_contract("variables:\n  x: {causality: output, type: Real, unit: m, tier: wanted, meaning: x}\n")


def test_the_shipped_plant_has_every_contract_variable(plant_fmu: Path) -> None:
    """Nothing absent, no warning: its trace keeps the columns (and so the values) it had."""
    plant = check(plant_fmu)
    assert plant.absent == () and plant.warnings == () and plant.contract_notes() == []
    assert plant.recorded_outputs == tuple(SHIPPED_COLUMNS)
    assert plant.contract_record() == {"absent": [], "warnings": []}
