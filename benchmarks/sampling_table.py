"""The verdict of the funnel comparison against the sampling ratio, for the unchanged and perturbed plant.

    .venv/bin/python benchmarks/sampling_table.py [fmus/ToggleLSM.fmu] [--quick]

Runs fig4_nominal/friction once unchanged and once per perturbation (mu 0.2 -> 0.25; one
controller gain +5 %), then compares each with the unchanged run, one of the two traces
decimated by 3, 7 and 10: "result ×k" = the result keeps every k-th sample against the
full-resolution reference, "reference ×k" = the reverse. Tolerances: scenarios/references.
Prints a Markdown table (pass / FAIL and the number of failing variables). `--quick` (for the
test suite): the ratios 1 and 10 only.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from toggle_cosim.analysis.compare import compare_traces
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.references import tolerances_for
from toggle_cosim.experiments.scenario import load_scenario
from toggle_cosim.files.traces import Trace
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.runs.definition import Run

ROOT = Path(__file__).resolve().parent.parent
RATIOS = (1, 3, 7, 10)


def decimated(trace: Trace, ratio: int, offset: int = 0) -> Trace:
    """Every `ratio`-th sample from `offset` on, always with the first and the last sample (the span)."""
    rows = sorted({0, *range(offset, trace.data.shape[0], ratio), trace.data.shape[0] - 1})
    return Trace(trace.names, trace.data[rows])


def nominal_run() -> Run:
    return next(r for r in load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml") if r.variant == "friction")


def perturbations(run: Run) -> dict[str, Run]:
    gains = run.controller.gains
    return {
        "mu 0.2 -> 0.25": dataclasses.replace(run, plant=dataclasses.replace(run.plant, mu=0.25)),
        "gain C +5 %": dataclasses.replace(
            run, controller=dataclasses.replace(run.controller, gains=dataclasses.replace(gains, C=gains.C * 1.05))
        ),
    }


def verdict(result: Trace, reference: Trace) -> tuple[bool, int]:
    default, per_variable = tolerances_for(ROOT / "scenarios" / "references", "fig4_nominal")
    comparison = compare_traces(result, reference, per_variable, default)
    return comparison.passed, len(comparison.failed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fmu", type=Path, nargs="?", default=ROOT / "fmus" / "ToggleLSM.fmu")
    parser.add_argument("--quick", action="store_true", help="the ratios 1 and 10 only")
    args = parser.parse_args()
    table(args.fmu, (1, 10) if args.quick else RATIOS)


def table(fmu: Path, ratios: tuple[int, ...]) -> None:
    plant = check_plant(fmu)
    run = nominal_run()
    nominal = check_and_simulate(run, plant).trace
    cases = {
        "unchanged": nominal,
        **{name: check_and_simulate(r, plant).trace for name, r in perturbations(run).items()},
    }
    header = ["model"] + [f"result ×{k}" for k in ratios] + [f"reference ×{k}" for k in ratios if k > 1]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for name, trace in cases.items():
        cells = []
        for k in ratios:
            passed, failed = verdict(decimated(trace, k), nominal)
            cells.append("pass" if passed else f"FAIL ({failed})")
        for k in ratios[1:]:
            passed, failed = verdict(trace, decimated(nominal, k))
            cells.append("pass" if passed else f"FAIL ({failed})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    assert np.all(np.isfinite(nominal.data))


if __name__ == "__main__":
    main()
