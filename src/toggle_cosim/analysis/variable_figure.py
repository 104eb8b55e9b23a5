"""Chosen variables of any runs overlaid, one panel per variable, a legend entry per run; a
reference drawn with its funnel band (`toggle-cosim plot RUN... --vars ... --reference REF`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from toggle_cosim.analysis.compare import ComparisonResult, draw_funnel_band, draw_outside_points
from toggle_cosim.analysis.display_points import thin
from toggle_cosim.analysis.run_files import LoadedRun
from toggle_cosim.files.outputs import PNG, replacing
from toggle_cosim.files.traces import Trace

__all__ = ["ReferenceBand", "axis_label", "default_variables", "save_figure", "variables_figure"]

MAX_PANELS = 12  # without --vars a plant's columns are drawn up to this many


@dataclass(frozen=True)
class ReferenceBand:
    """A reference trace and its comparison with the first run (the funnel of each variable)."""

    label: str
    trace: Trace
    comparison: ComparisonResult


def axis_label(name: str, runs: Sequence[LoadedRun] | Sequence[Mapping[str, str]]) -> str:
    """`name [unit]` with the unit of the first run that knows it; `name` when none does."""
    for run in runs:
        units = run.units if isinstance(run, LoadedRun) else run
        if name in units:
            return f"{name} [{units[name]}]"
    return name


def _draw_band(ax, band: ReferenceBand, name: str) -> None:  # noqa: ANN001 - a matplotlib Axes
    if name not in band.trace.names:
        return
    ax.plot(*thin(band.trace.time, band.trace.column(name)), color="k", linewidth=1.0, label=band.label)
    try:
        variable = band.comparison[name]
    except KeyError:
        return
    envelope = variable.envelope
    if envelope is None:
        return
    draw_funnel_band(ax, variable, "0.5", 0.25)
    if np.any(envelope.error > 0):
        draw_outside_points(ax, envelope, "outside the funnel")


def variables_figure(
    runs: Sequence[LoadedRun], variables: Sequence[str], title: str = "", reference: ReferenceBand | None = None
) -> Figure:
    """`variables` of every run, one panel each, a colour per run (curves thinned for display,
    `display_points`); with `reference`, its curve and funnel band under the runs'."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    columns = 1 if len(variables) <= 3 else 2 if len(variables) <= 8 else 3
    rows = math.ceil(len(variables) / columns)
    figure = Figure(figsize=(6.5 * columns, 2.6 * rows + 0.9), layout="constrained")
    FigureCanvasAgg(figure)
    axes = np.atleast_1d(figure.subplots(rows, columns, sharex=True, squeeze=False)).ravel()
    for ax, name in zip(axes, variables, strict=False):
        if reference is not None:
            _draw_band(ax, reference, name)
        for number, run in enumerate(runs):
            if name in run.trace.names:
                ax.plot(*thin(run.trace.time, run.trace.column(name)), color=f"C{number % 10}", label=run.label)
        ax.set_ylabel(axis_label(name, runs))
        ax.set_title(name, fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for ax in axes[len(variables) :]:
        ax.set_visible(False)
    for ax in axes[max(len(variables) - columns, 0) : len(variables)]:
        ax.set_xlabel("time [s]")
        ax.tick_params(labelbottom=True)
    if title:
        figure.suptitle(title)
    return figure


def save_figure(figure: Figure, output: Path) -> Path:
    """Write `figure` as a PNG to `output` (a unique temporary name renamed into place)."""
    output = Path(output)
    with replacing(output, "figure", kind=PNG) as temporary:
        figure.savefig(temporary, dpi=100, format="png")
    return output


def default_variables(runs: Sequence[LoadedRun]) -> list[str]:
    """What to draw when no variables are named: the columns every run has, in the first run's
    order, at most MAX_PANELS of them."""
    shared = [name for name in runs[0].variables if all(name in run.variables for run in runs[1:])]
    return shared[:MAX_PANELS]
