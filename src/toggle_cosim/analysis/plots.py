"""The paper's nine-panel figure (Figs. 4-6) from run traces, friction and no friction overlaid,
each panel with an inset of the first 50 ms, where the paper's transient is."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from toggle_cosim.files.outputs import PNG, replacing  # noqa: E402
from toggle_cosim.files.traces import Trace  # noqa: E402

PANELS = (
    ("(a) position of slider B", "x_B", "x_B [m]"),
    ("(b) control input i_q*", "iq_ref", "i_q* [A]"),
    ("(c) Lagrange multiplier λ1", "lambda1", "λ1 [N]"),
    ("(d) Lagrange multiplier λ2", "lambda2", "λ2 [N]"),
    ("(e) joint (2,3)", "23", "force [N]"),
    ("(f) joint (3,4)", "34", "force [N]"),
    ("(g) joint (2,5)", "25", "force [N]"),
    ("(h) joint (5,6)", "56", "force [N]"),
    ("(i) joint (1,2)", "12", "force [N]"),
)
_STYLES = ("-", "--", ":", "-.")


EARLY_S = 0.05  # the paper's transient: the inset of each panel shows t in [0, EARLY_S]
SETTLED_FROM = 0.3  # the part of the run (from this fraction of t_end on) where the curves have settled


def _free_side(ax, settled: list[np.ndarray]) -> tuple[str, tuple[float, float, float, float]]:  # noqa: ANN001 - an Axes
    """Where the settled curves leave room: ("upper" or "lower", the inset's rectangle in axes
    fractions), the inset left of the legend's corner on that side."""
    low, high = ax.get_ylim()
    values = np.concatenate(settled) if settled else np.array([low])
    span = (high - low) or 1.0
    bottom, top = (float(values.min()) - low) / span, (float(values.max()) - low) / span
    if 1.0 - top >= bottom:  # more room above the settled curves
        height = max(0.25, min(0.42, 1.0 - top - 0.12))
        return "upper", (0.15, 0.97 - height - 0.06, 0.4, height)
    height = max(0.25, min(0.42, bottom - 0.14))
    return "lower", (0.15, 0.1, 0.4, height)


def _identical_note(name: str, values: np.ndarray, drawn: dict[str, np.ndarray]) -> str:
    """`name`, or `name (identical to OTHER)` when an earlier curve of the panel has the same values."""
    for other, earlier in drawn.items():
        if earlier.shape == values.shape and np.array_equal(earlier, values):
            return f"{name} (identical to {other})"
    return name


def nine_panel_axes(traces: Mapping[str, Trace], title: str, target: float | None = None) -> Figure:
    """The nine panels for each labelled trace, each with an inset of the first EARLY_S seconds
    (where the paper's transient is); a curve equal to one drawn before it in its panel says so
    in the legend ("identical to ..."), since it hides under it."""
    # a fixed layout: matplotlib's constrained layout costs ~40 % of drawing this figure
    figure, axes = plt.subplots(3, 3, figsize=(14, 10.5))
    figure.subplots_adjust(left=0.055, right=0.99, bottom=0.05, top=0.93, wspace=0.22, hspace=0.33)
    for ax, (label, key, ylabel) in zip(axes.flat, PANELS, strict=True):
        curves: dict[str, np.ndarray] = {}  # label -> values, for the identical-curve note
        early_curves, settled = [], []
        for number, (name, trace) in enumerate(traces.items()):
            style = _STYLES[number % len(_STYLES)]
            t = trace.time
            early = t <= EARLY_S + 1e-12
            if key.isdigit():
                drawn_here = [(f"N{key}", "C0", "normal force"), (f"Ff{key}", "C3", "friction force")]
            else:
                drawn_here = [(key, f"C{number}", "")]
            for column, color, kind in drawn_here:
                if column not in trace.names or (column.startswith("Ff") and not trace.column(column).any()):
                    continue
                values = trace.column(column)
                tag = f"{kind} ({name})" if kind else name
                same = [other for other in curves if other.startswith(kind)] if kind else list(curves)
                legend = _identical_note(tag, values, {other: curves[other] for other in same})
                curves[tag] = values
                ax.plot(t, values, style, color=color, label=legend)
                early_curves.append((t[early], values[early], style, color))
                settled.append(values[t >= SETTLED_FROM * t[-1]])
        drawn = bool(curves) and any(not c.startswith("friction") for c in curves)
        if key == "x_B" and target is not None:
            ax.axhline(target, color="0.6", linewidth=0.8, label="target x_B*")
            settled.append(np.array([target]))
        side, rectangle = _free_side(ax, settled)
        if not drawn:  # an optional output the plant does not have (plant contract)
            ax.text(0.5, 0.5, "not an output of this plant", ha="center", va="center", transform=ax.transAxes)
        else:
            inset = ax.inset_axes(rectangle)
            for t_early, v_early, style, color in early_curves:
                inset.plot(t_early, v_early, style, color=color, linewidth=1.0)
            inset.set_xlim(0.0, EARLY_S)
            inset.set_title(f"first {EARLY_S * 1e3:.0f} ms", fontsize=7, pad=2)
            inset.tick_params(labelsize=6)
            inset.grid(True, alpha=0.3)
        ax.set_title(label)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        # the legend in the corner on the free side, right of the inset (loc="best" searches every
        # vertex, ~25 % of the figure)
        if drawn or key == "x_B":
            ax.legend(fontsize=7, loc=f"{side} right")
    figure.suptitle(title)
    return figure


def nine_panel_figure(traces: Mapping[str, Trace], title: str, output: Path, target: float | None = None) -> Path:
    """Draw the nine panels for each labelled trace (`nine_panel_axes`) and save a PNG
    (atomically) to `output`."""
    figure = nine_panel_axes(traces, title, target)
    output = Path(output)
    try:
        with replacing(output, "figure", kind=PNG) as temporary:  # a unique temporary name, renamed into place
            figure.savefig(temporary, dpi=110, format="png")
    finally:
        plt.close(figure)
    return output
