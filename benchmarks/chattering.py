"""Chattering of the control laws over the robustness map: the total variation of i_q* per
second, Σ|Δi_q*| / t_end, for each law at every point of scenarios/sweep_law_FE_mB.yaml's map
(F_E 0..150 N every 10 N by m_B 4.43..8.86 kg, 9 values, μ = 0.2). Prints the largest value
per law and where it occurs; docs/controllers.md holds the integral law to ≤ 10 A/s.

    .venv/bin/python benchmarks/chattering.py [--fmu fmus/ToggleLSM.fmu] [--quick]

`--quick` (for the test suite): the map's four corners only.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
FULL_MAP = (np.linspace(0.0, 150.0, 16), np.linspace(4.43, 8.86, 9))  # F_E [N], m_B [kg]


def total_variation_per_second(u: np.ndarray, t: np.ndarray) -> float:
    return float(np.sum(np.abs(np.diff(u))) / (t[-1] - t[0]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmu", type=Path, default=ROOT / "fmus" / "ToggleLSM.fmu")
    parser.add_argument("--quick", action="store_true", help="the four corners of the map only")
    args = parser.parse_args()
    forces, masses = (np.linspace(0.0, 150.0, 2), np.linspace(4.43, 8.86, 2)) if args.quick else FULL_MAP
    plant = check_plant(args.fmu)
    base = next(r for r in load_scenario(ROOT / "scenarios" / "integral_load.yaml") if r.variant == "friction")
    for law in ("paper", "integral"):
        worst, where = 0.0, None
        for F_E in forces:
            for m_B in masses:
                run = dataclasses.replace(
                    base,
                    plant=dataclasses.replace(base.plant, F_E=float(F_E), m_B=float(m_B)),
                    controller=dataclasses.replace(base.controller, law=law),
                )
                outcome = check_and_simulate(run, plant)
                tv = total_variation_per_second(outcome.trace.column("iq_ref"), outcome.trace.time)
                if tv > worst:
                    worst, where = tv, (float(F_E), float(m_B))
        print(
            f"{law}: largest total variation of i_q* {worst:.2f} A/s, at F_E = {where[0]:g} N, m_B = {where[1]:.4g} kg"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
