"""A tuning's figures (matplotlib, Agg): the map of the starting controller beside the tuned
one's, metric by metric on one colour scale, and the Pareto front of two objectives."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toggle_cosim.analysis.sweep_heatmaps import PANELS
from toggle_cosim.files.outputs import PNG, replacing

# the metrics of a tuning (tune_spec.METRICS) that the sweep heat maps draw: their panel
_PANEL_OF = {"settling_time": "settling_time_s", "final_error": "final_error_m", "peak_command": "peak_iq_ref_A"}
_PANEL_OF["overshoot"] = "overshoot_percent"
_EXTRA = {  # the others: column, title, transform
    "input_energy": ("E_in_J", "input energy E_in [J]", lambda v: v),
    "chattering": ("iq_total_variation_A_per_s", "total variation of i_q* [A/s]", lambda v: v),
    "S_sign_changes": ("S_sign_changes_per_s", "sign changes of S [1/s]", lambda v: v),
}


def _panel(metric: str) -> tuple[str, str, Any]:
    if metric in _PANEL_OF:
        column, title, transform, _ = next(p for p in PANELS if p[0] == _PANEL_OF[metric])
        return column, title, transform
    return _EXTRA[metric]


def _grid(table: Any, x: str, y: str, column: str, transform: Any) -> tuple[Any, list[Any], list[Any]]:
    import numpy as np

    xs = sorted(table[x].unique())
    ys = sorted(table[y].unique())
    grid = np.full((len(ys), len(xs)), np.nan)
    ok = table[table["status"] == "ok"]
    values = transform(ok[column].to_numpy(dtype=float, na_value=np.nan))
    for xv, yv, value in zip(ok[x], ok[y], values, strict=True):
        grid[ys.index(yv), xs.index(xv)] = value
    return grid, xs, ys


def write_maps_side_by_side(start: Path, tuned: Path, sweep: Any, metrics: list[str], path: Path, title: str) -> Path:
    """One row per metric (the objectives' first, then settling time, final error and peak
    current): the starting controller's map on the left, the tuned one's on the right, over the
    sweep's heat-map axes; grey: never settled or no value."""
    import matplotlib
    import numpy as np
    import pandas as pd

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x, y = sweep.heatmap
    rows = list(dict.fromkeys([*metrics, "settling_time", "final_error", "peak_command"]))
    tables = [pd.read_parquet(start), pd.read_parquet(tuned)]
    figure, axes = plt.subplots(len(rows), 2, figsize=(12, 3.2 * len(rows)), constrained_layout=True, squeeze=False)
    for r, metric in enumerate(rows):
        column, label, transform = _panel(metric)
        grids = [_grid(table, x, y, column, transform) for table in tables]
        finite = np.concatenate([g[np.isfinite(g)] for g, _, _ in grids])
        low, high = (finite.min(), finite.max()) if finite.size else (0.0, 1.0)
        for c, ((grid, xs, ys), name) in enumerate(zip(grids, ("start", "tuned"), strict=True)):
            ax = axes[r][c]
            colormap = plt.get_cmap("viridis").with_extremes(bad="0.85")
            image = ax.imshow(
                np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap=colormap, vmin=low, vmax=high
            )
            figure.colorbar(image, ax=ax, shrink=0.9)
            worst = np.nanmax(grid) if np.isfinite(grid).any() else float("nan")
            ax.set_title(f"{name}: {label}, worst {worst:.4g}")
            step_x, step_y = max(1, len(xs) // 8), max(1, len(ys) // 8)
            ax.set_xticks(range(0, len(xs), step_x), [f"{v:.4g}" for v in xs[::step_x]], fontsize=8)
            ax.set_yticks(range(0, len(ys), step_y), [f"{v:.4g}" for v in ys[::step_y]], fontsize=8)
            ax.set_xlabel(x)
            ax.set_ylabel(y)
    figure.suptitle(f"{title}: the starting controller (left) and the tuned one (right)")
    try:
        with replacing(path, "figure", kind=PNG) as temporary:
            figure.savefig(temporary, dpi=90, format="png")
    finally:
        plt.close(figure)
    return path


def write_pareto(history: Any, tuning: Any, path: Path) -> Path:
    """The feasible trials of a two-objective tuning, the Pareto front joined and marked, the
    infeasible ones grey (drawn at their true figures where they have them)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b = (o.label for o in tuning.objectives)
    done = history[history["state"] == "complete"]
    feasible = done[done["feasible"] == True]  # noqa: E712 - a column
    infeasible = done[done["feasible"] != True]  # noqa: E712
    front = feasible[feasible["pareto"] == True].sort_values(a)  # noqa: E712
    figure, ax = plt.subplots(figsize=(7, 5), constrained_layout=True)
    ax.scatter(infeasible[a], infeasible[b], color="0.75", s=12, label="infeasible")
    ax.scatter(feasible[a], feasible[b], color="C0", s=16, label="feasible")
    ax.plot(front[a], front[b], "o-", color="C3", label="Pareto front")
    ax.set_xlabel(a)
    ax.set_ylabel(b)
    ax.set_title(f"{tuning.name}: {len(done)} trials")
    ax.legend()
    try:
        with replacing(path, "figure", kind=PNG) as temporary:
            figure.savefig(temporary, dpi=100, format="png")
    finally:
        plt.close(figure)
    return path
