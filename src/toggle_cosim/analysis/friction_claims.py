"""The paper's claims re-checked under the three friction models (rows for out/summary.md).

Takes the six paper runs (eq. (17), `fig4/5/6 x friction/no_friction`) and the runs of
`scenarios/friction_models.yaml` (the same cases under `dissipative` and `stick_slip`), and
says, claim by claim, whether it holds under each model, with the numbers.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from toggle_cosim.cosim.outcome import RunOutcome

MODELS = ("paper", "dissipative", "stick_slip")
CASES = {"fig4_nominal": "nominal", "fig5_external_force": "external_force", "fig6_mass_variation": "mass_variation"}
JOINTS = ("12", "23", "34", "25", "56")
CLAIM_COLUMNS = ("E_in", "E_fric", *(f"N{j}" for j in JOINTS))  # optional outputs the claims read


def missing_columns(outcomes: Sequence[RunOutcome], columns: Sequence[str]) -> list[str]:
    """The `columns` some run's trace lacks (optional outputs its plant does not have)."""
    return [name for name in columns if any(name not in o.trace.names for o in outcomes)]


def _label(case: str, model: str) -> str:
    return f"{case}/friction" if model == "paper" else f"friction_models/{CASES[case]}_{model}"


def _late_mean(outcome: RunOutcome, column: str) -> float:
    t = outcome.trace
    return float(np.mean(t.column(column)[t.time >= t.time[-1] - 0.5]))


def _share_at_end(outcome: RunOutcome) -> float:
    s = outcome.summary
    return float(s.E_fric_J / s.E_in_J) if s is not None and s.E_in_J else float("nan")


def _claims_for(model: str, runs: Mapping[str, RunOutcome]) -> list[str]:
    """One cell per claim for `model`."""
    nominal, no_friction = runs[_label("fig4_nominal", model)], runs["fig4_nominal/no_friction"]
    diff = np.abs(nominal.trace.column("iq_ref") - no_friction.trace.column("iq_ref"))
    later = float(np.max(diff[nominal.trace.time >= 0.1]))
    peak = float(np.max(np.abs(no_friction.trace.column("iq_ref"))))
    hold = _late_mean(runs[_label("fig5_external_force", model)], "iq_ref")
    hold_nominal = _late_mean(nominal, "iq_ref")
    errors = {case: 1e3 * runs[_label(case, model)].summary.final_error_m for case in CASES}
    ratios = [
        float(
            np.max(runs[_label(case, model)].trace.column(f"N{j}"))
            / np.max(runs[f"{case}/no_friction"].trace.column(f"N{j}"))
        )
        for case in CASES
        for j in JOINTS
    ]
    start = [runs[_label(case, model)].summary.fric_share_start for case in CASES]
    end = [_share_at_end(runs[_label(case, model)]) for case in CASES]
    e_fric = [runs[_label(case, model)].trace.column("E_fric") for case in CASES]
    monotone = all(float(np.min(np.diff(e))) >= -1e-12 for e in e_fric)
    return [
        f"{'holds' if later < 0.05 * peak else 'fails'}: after 0.1 s at most {later:.3f} A apart (peak {peak:.2f} A)",
        f"{'holds' if hold > 10 * max(abs(hold_nominal), 1e-3) else 'fails'}: holding {hold:.2f} A at 100 N vs {hold_nominal:.3f} A",
        f"partly: final error {errors['fig4_nominal']:+.3f} / {errors['fig6_mass_variation']:+.3f} mm (nominal / 8.86 kg), "
        f"{errors['fig5_external_force']:+.2f} mm at 100 N",
        f"forces {'raised' if min(ratios) >= 1.0 else 'not always raised'} (peak ratio {min(ratios):.3f}-{max(ratios):.3f}); "
        f"energy share at 10 % stroke {100 * min(start):.1f}-{100 * max(start):.1f} % "
        f"({'holds' if min(start) > 0.5 else 'fails'}), over the run {100 * min(end):.0f}-{100 * max(end):.0f} % of the net "
        f"input; E_fric {'never decreases' if monotone else 'decreases at times'}",
    ]


def friction_claims(outcomes: Sequence[RunOutcome]) -> str:
    """Markdown: the four claims (rows) under the three friction models (columns)."""
    runs = {o.run.label: o for o in outcomes}
    needed = [f"{case}/no_friction" for case in CASES] + [_label(case, m) for case in CASES for m in MODELS]
    missing = [label for label in needed if label not in runs or not runs[label].complete]
    if missing:
        return f"## The claims under the friction models\n\nNot checked: runs missing or incomplete: {', '.join(missing)}\n"
    lacking = missing_columns([runs[label] for label in needed], CLAIM_COLUMNS)
    if lacking:
        return f"## The claims under the friction models\n\nNot checked: the plant has no output {', '.join(lacking)}\n"
    cells = {model: _claims_for(model, runs) for model in MODELS}
    claims = (
        "(1) i_q* almost the same with and without friction",
        "(2) much higher i_q* with F_E",
        "(3) robust to F_E and m_B",
        "(4) friction raises joint forces, takes > 1/2 of the input at the start",
    )
    lines = [
        "## The claims under the friction models (mu = 0.2; stick_slip with mu_s = 0.2)",
        "",
        "| claim | " + " | ".join(MODELS) + " |",
        "|---|---|---|---|",
    ]
    for row, claim in enumerate(claims):
        lines.append(f"| {claim} | " + " | ".join(cells[m][row] for m in MODELS) + " |")
    return "\n".join(lines) + "\n"
