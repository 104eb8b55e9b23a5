"""The paper's nine-panel figure (Figs. 4-6) from run traces, friction and no friction overlaid."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

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


def nine_panel_figure(traces: Mapping[str, Trace], title: str, output: Path, target: float | None = None) -> Path:
    """Draw the nine panels for each labelled trace and save a PNG (atomically) to `output`."""
    # a fixed layout: matplotlib's constrained layout costs ~40 % of drawing this figure
    figure, axes = plt.subplots(3, 3, figsize=(14, 10.5))
    figure.subplots_adjust(left=0.055, right=0.99, bottom=0.05, top=0.93, wspace=0.22, hspace=0.33)
    for ax, (label, key, ylabel) in zip(axes.flat, PANELS, strict=True):
        drawn = False
        for number, (name, trace) in enumerate(traces.items()):
            style = _STYLES[number % len(_STYLES)]
            t = trace.time
            if key.isdigit():
                if f"N{key}" in trace.names:
                    ax.plot(t, trace.column(f"N{key}"), style, color="C0", label=f"normal force ({name})")
                    drawn = True
                if f"Ff{key}" in trace.names and trace.column(f"Ff{key}").any():
                    ax.plot(t, trace.column(f"Ff{key}"), style, color="C3", label=f"friction force ({name})")
            elif key in trace.names:
                ax.plot(t, trace.column(key), style, color=f"C{number}", label=name)
                drawn = True
        if not drawn:  # an optional output the plant does not have (plant contract)
            ax.text(0.5, 0.5, "not an output of this plant", ha="center", va="center", transform=ax.transAxes)
        if key == "x_B" and target is not None:
            ax.axhline(target, color="0.6", linewidth=0.8, label="target x_B*")
        ax.set_title(label)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
        # fixed corners: x_B and λ2 settle high after an early dip (lower right is free), the other
        # panels settle low after early peaks; loc="best" searches every vertex, ~25 % of the figure
        if drawn or key == "x_B":
            ax.legend(fontsize=7, loc="lower right" if key in ("x_B", "lambda2") else "upper right")
    figure.suptitle(title)
    output = Path(output)
    try:
        with replacing(output, "figure", kind=PNG) as temporary:  # a unique temporary name, renamed into place
            figure.savefig(temporary, dpi=110, format="png")
    finally:
        plt.close(figure)
    return output
