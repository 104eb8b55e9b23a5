"""Heat maps of a sweep's figures of merit over two of its axes (matplotlib, Agg)."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from toggle_cosim import interrupts
from toggle_cosim.files.outputs import PNG, fitting_name, replacing

HEATMAP_DIR = "heatmaps"

PANELS = (
    ("final_error_m", "|final error| [mm]", lambda v: abs(v) * 1e3, "viridis"),
    ("settling_time_s", "settling time (2 %) [s]", lambda v: v, "viridis"),
    ("peak_iq_ref_A", "peak |i_q*| [A]", lambda v: v, "magma"),
    ("overshoot_percent", "overshoot [%]", lambda v: v, "viridis"),
    ("fric_share_start", "E_fric/E_in at 10 % stroke [%]", lambda v: v * 100, "cividis"),
    ("fric_share_end", "E_fric/E_in at t_end [%]", lambda v: v * 100, "cividis"),
)


# units of the scenario keys a sweep varies that are not a plant variable (`axis_title`)
KEY_UNITS = {"T_s": "s", "t_end": "s", "stroke.x_start": "m", "stroke.x_target": "m"}


def axis_title(key: str) -> str:
    """A sweep axis as the maps label it: `plant.F_E [N]`, the unit of a plant variable from the
    plant contract (`plant.contract.contract_unit`), of a few scenario keys from KEY_UNITS; the key
    alone where neither gives one (a gain, an FMU parameter by its own name)."""
    from toggle_cosim.plant.contract import contract_unit

    unit = KEY_UNITS.get(key) or (contract_unit(key.removeprefix("plant.")) if key.startswith("plant.") else None)
    return f"{key} [{unit}]" if unit else key


def constant_value(grid: Any) -> float | None:
    """The one value of a map whose finite cells are all equal (its colour bar would say
    nothing), else None."""
    import numpy as np

    finite = grid[np.isfinite(grid)]
    if finite.size and finite.min() == finite.max():
        return float(finite[0])
    return None


def value_label(value: Any) -> str:
    """A sweep value as the maps label it: a float to 4 significant digits."""
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", text).strip("_") or "all"


def heatmap_name(others: list[str], key: tuple[Any, ...]) -> str:
    """The file name of the heat map of one combination `key` of the other axes `others`:
    heatmap_AXIS=VALUE_....png, within the file system's limit (`fitting_name`: a long one is cut
    and ends with a hash; the figure's title and the PNG's Description say the whole)."""
    if not others:
        return "heatmap.png"
    tag = _slug("_".join(f"{k}={value_label(v)}" for k, v in zip(others, key, strict=True)))
    return fitting_name(f"heatmap_{tag}", ".png")


def _columns_needed(sweep: Any) -> list[str]:
    axes = [*sweep.axes, "variant"]
    return list(dict.fromkeys([*axes, "status", *(column for column, *_ in PANELS)]))


def write_heatmaps(
    table: Any, sweep: Any, warn: Callable[[str], None] | None = None
) -> list[Path]:  # sweep: experiments.sweep_spec.Sweep
    """One PNG per combination of the other axes: heat maps of the figures of merit over the two
    chosen axes. A failed case is a crossed cell; a run that never settles is a grey cell.

    `table` is the results DataFrame or the path of results.parquet: then only the columns the
    maps show are read (not the reasons, hosts, timings and other metrics of every case).
    Given `warn`, a heat map that cannot be drawn or written is said there (one line) and the
    others are still written; without it, the error is raised."""
    if sweep.heatmap is None:
        return []
    if isinstance(table, (str, Path)):
        import pandas as pd

        table = pd.read_parquet(table, columns=_columns_needed(sweep), use_threads=False)
    if table.empty:
        return []
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x, y = sweep.heatmap
    others = [k for k in sweep.axes if k not in (x, y)]
    if len(sweep.variants) > 1 and "variant" not in (x, y):
        others.insert(0, "variant")
    folder = sweep.output / HEATMAP_DIR
    written = []
    groups = table.groupby(others, sort=True, dropna=False) if others else [((), table)]
    for key, group in groups:
        key = key if isinstance(key, tuple) else (key,)
        tag = ", ".join(f"{k} = {value_label(v)}" for k, v in zip(others, key, strict=True))
        xs = sorted(group[x].dropna().unique(), key=lambda v: (isinstance(v, str), v))
        ys = sorted(group[y].dropna().unique(), key=lambda v: (isinstance(v, str), v))
        xi = {v: i for i, v in enumerate(xs)}
        yi = {v: i for i, v in enumerate(ys)}
        figure, axes = plt.subplots(2, 3, figsize=(16, 9), constrained_layout=True)
        annotate = len(xs) * len(ys) <= 100
        rows_i = np.array([yi[v] for v in group[y]], dtype=int)
        cols_j = np.array([xi[v] for v in group[x]], dtype=int)
        ok = (group["status"] == "ok").to_numpy()
        failed = np.zeros((len(ys), len(xs)), dtype=bool)
        failed[rows_i[~ok], cols_j[~ok]] = True
        for ax, (column, title, transform, cmap) in zip(axes.flat, PANELS, strict=True):
            grid = np.full((len(ys), len(xs)), np.nan)
            values = transform(group[column].to_numpy(dtype=float, na_value=np.nan))
            grid[rows_i[ok], cols_j[ok]] = values[ok]
            colormap = plt.get_cmap(cmap).with_extremes(bad="0.85")
            image = ax.imshow(
                np.ma.masked_invalid(grid), origin="lower", aspect="auto", cmap=colormap, interpolation="nearest"
            )
            constant = constant_value(grid)
            if constant is None:
                figure.colorbar(image, ax=ax, shrink=0.9)
            for i, j in zip(*np.nonzero(failed), strict=True):
                ax.text(j, i, "✗", ha="center", va="center", color="red", fontsize=9)
            if annotate:
                finite = grid[np.isfinite(grid)]
                middle = (finite.min() + finite.max()) / 2 if finite.size else 0
                for (i, j), value in np.ndenumerate(grid):
                    if np.isfinite(value):
                        ax.text(
                            j,
                            i,
                            f"{value:.3g}",
                            ha="center",
                            va="center",
                            fontsize=6,
                            color="white" if value < middle else "black",
                        )
                    elif not failed[i, j] and column == "settling_time_s":
                        ax.text(j, i, "n/s", ha="center", va="center", fontsize=6, color="0.3")
            step_x = max(1, len(xs) // 12)
            step_y = max(1, len(ys) // 12)
            ax.set_xticks(range(0, len(xs), step_x), [value_label(v) for v in xs[::step_x]], rotation=45, fontsize=8)
            ax.set_yticks(range(0, len(ys), step_y), [value_label(v) for v in ys[::step_y]], fontsize=8)
            ax.set_xlabel(axis_title(x))
            ax.set_ylabel(axis_title(y))
            ax.set_title(title if constant is None else f"{title}\nconstant: {constant:.4g}")
        n_failed = int((group["status"] != "ok").sum())
        figure.suptitle(
            f"{sweep.name}{': ' + tag if tag else ''}  ({len(group)} cases, {n_failed} failed ✗,"
            " grey: no value / never settled)"
        )
        path = folder / heatmap_name(others, key)
        metadata = {"Title": f"{sweep.name}: heat maps", "Description": tag or "all cases"}
        try:
            with replacing(path, "heat map", kind=PNG) as temporary:  # a unique temporary name, renamed into place
                figure.savefig(temporary, dpi=100, format="png", metadata=metadata)
        except Exception as error:
            if warn is None or interrupts.is_interrupt(error):
                raise
            warn(f"warning: {path}: heat map not written ({' '.join(str(error).split())})")
            continue
        finally:
            plt.close(figure)
        written.append(path)
    return written
