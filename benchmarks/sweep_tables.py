"""The sweep tables of docs/controllers.md and docs/friction-models.md, drawn from sweep
results: the worst case over m_B for each F_E and law (`scenarios/sweep_law_FE_mB.yaml`), and the summary per friction model
(`scenarios/sweep_friction_models.yaml`).

    toggle-cosim sweep scenarios/sweep_law_FE_mB.yaml
    toggle-cosim sweep scenarios/sweep_friction_models.yaml
    .venv/bin/python benchmarks/sweep_tables.py [--sweeps out/sweeps]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from toggle_cosim.experiments.sweep import read_results


def _settling(values) -> str:  # noqa: ANN001 - a pandas Series
    return "never" if values.isna().any() else f"{values.max():.3f}"


def law_table(table) -> str:  # noqa: ANN001 - a pandas DataFrame
    lines = [
        "| F_E [N] | law | max abs final error [mm] | settling (2 %) [s] | peak abs i_q* [A] |",
        "|---|---|---|---|---|",
    ]
    for (force, law), group in table.groupby(["plant.F_E", "controller.law"], sort=True):
        lines.append(
            f"| {force:g} | {law} | {group['final_error_m'].abs().max() * 1e3:.4f} | "
            f"{_settling(group['settling_time_s'])} | {group['peak_iq_ref_A'].max():.2f} |"
        )
    return "\n".join(lines)


def friction_table(table) -> str:  # noqa: ANN001
    """One row per control law and friction model (the law column only where the sweep has it)."""
    keys = [key for key in ("controller.law", "plant.friction_model") if key in table.columns]
    head = " | ".join({"controller.law": "law", "plant.friction_model": "friction model"}[key] for key in keys)
    lines = [
        f"| {head} | complete | abs final error [mm] | settles within 2 % | peak abs i_q* [A] | E_fric [J] |",
        "|" + "---|" * (len(keys) + 5),
    ]
    for values, group in table.groupby(keys, sort=True):
        values = values if isinstance(values, tuple) else (values,)
        ok = group[group["status"] == "ok"]
        error = ok["final_error_m"].abs() * 1e3
        settled = ok[ok["settling_time_s"].notna()]
        when = (
            f"F_E ≤ {settled['plant.F_E'].max():g} N"
            if len(settled) < len(group)
            else f"≤ {settled['settling_time_s'].max():.3f} s"
        )
        lines.append(
            f"| {' | '.join(str(v) for v in values)} | {len(ok)}/{len(group)} | "
            f"{error.min():.4f} … {error.max():.4f} | {len(settled)} of {len(group)} ({when}) | "
            f"{ok['peak_iq_ref_A'].min():.2f} … {ok['peak_iq_ref_A'].max():.2f} | "
            f"from {ok['E_fric_J'].min():.4f} |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=Path, default=Path("out/sweeps"), help="the sweeps' output folders")
    args = parser.parse_args()
    printed = 0
    for name, table_of in (("sweep_law_FE_mB", law_table), ("sweep_friction_models", friction_table)):
        results = args.sweeps / name / "results.parquet"
        if not results.is_file():
            print(f"{name}: no {results} (run 'toggle-cosim sweep scenarios/{name}.yaml' first)", file=sys.stderr)
            continue
        print(f"{name}:\n{table_of(read_results(results))}\n")
        printed += 1
    return 0 if printed else 2


if __name__ == "__main__":
    sys.exit(main())
