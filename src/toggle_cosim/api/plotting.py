"""`tc.plot` and `Result.plot`: chosen variables of any runs overlaid, one panel per variable,
optionally around a reference's funnel band, as `toggle-cosim plot RUN... --vars` draws them.

    fig = tc.plot([fig4, fig5], vars=["x_B", "iq_ref"], reference=tc.stored_reference(fig4.run))
    fig.savefig("x_B.png")                   # a matplotlib Figure (or out="x_B.png" writes it)
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from toggle_cosim.analysis.run_files import LoadedRun, check_variables, label_groups, load_runs
from toggle_cosim.files.traces import Trace

if TYPE_CHECKING:
    from matplotlib.figure import Figure

Result = Any  # api.result.Result: api.result imports this module (Result.plot), so not the other way round

__all__ = ["plot"]


def _is_result(value: object) -> bool:
    """A `Result` (told by its fields: api.result imports this module, not the other way round)."""
    return all(hasattr(value, name) for name in ("trace", "units", "record", "label"))


def _loaded(value: Result | str | Path) -> list[LoadedRun]:
    if _is_result(value):
        return [LoadedRun(value.label, value.trace, value.units, value.record)]
    if isinstance(value, (str, Path)):
        return load_runs([Path(value)])
    raise TypeError(f"give Results, results folders or trace files' paths, not {type(value).__name__}")


def _band(first: LoadedRun, reference: Result | Trace | str | Path, variables: Sequence[str]):  # noqa: ANN202
    from toggle_cosim.analysis.compare import DEFAULT_TOLERANCE, compare_traces
    from toggle_cosim.analysis.tolerance_files import tolerances_for_reference
    from toggle_cosim.analysis.trace_formats import read_any_trace
    from toggle_cosim.analysis.variable_figure import ReferenceBand

    if isinstance(reference, (str, Path)):
        trace, label = read_any_trace(Path(reference)), f"reference {Path(reference).name}"
        default, tolerances, _ = tolerances_for_reference(Path(reference), None)
    else:
        trace = reference.trace if _is_result(reference) else reference
        label = f"reference {reference.label}" if _is_result(reference) else "reference"
        default, tolerances = DEFAULT_TOLERANCE, {}
    shared = [name for name in variables if name in trace.names]
    comparison = compare_traces(
        first.trace,
        trace,
        {name: tolerance for name, tolerance in tolerances.items() if name in trace.names},
        default,
        shared,
        result_label=f"run {first.label}",
        reference_label=label,
    )
    return ReferenceBand(label, trace, comparison)


def plot(
    results: Result | str | Path | Sequence[Result | str | Path],
    vars: Sequence[str] | str | None = None,  # noqa: A002 - the name the command line's --vars has
    reference: Result | Trace | str | Path | None = None,
    *,
    labels: Sequence[str] | None = None,
    title: str = "",
    out: str | Path | None = None,
) -> Figure:
    """Overlay `vars` of every run in `results`, one panel per variable, a legend entry per run.

    Args:
        results: `Result`s, results folders (`toggle-cosim run`'s output) or trace files; runs
            of different scenarios and plants together.
        vars: variable names (or "x_B,iq_ref"); default: the variables every run has.
        reference: a reference (trace file, `Result` or `Trace`) drawn in black with its funnel
            band around the first run's variables (tolerance files by place for a file).
        labels: the legend's name of each item of `results`, in order (an item holding several
            runs names each `LABEL: scenario/variant`); default: each run's scenario/variant,
            and where that repeats, its folder's path without the leading parts they share.
        out: also write the figure as a PNG there.

    Raises:
        ValueError (ResultsError): a run lacks a variable (the message names the run and what
            it has); `labels` has not one label per item of `results`.
        CompareInputError: the reference cannot be compared with the first run.
    """
    from toggle_cosim.analysis.variable_figure import default_variables, save_figure, variables_figure

    items = [results] if isinstance(results, (str, Path)) or _is_result(results) else list(results)
    runs = label_groups([_loaded(item) for item in items], None if labels is None else list(labels))
    if not runs:
        raise ValueError("plot: no runs given")
    names = [n.strip() for n in vars.split(",")] if isinstance(vars, str) else list(vars or default_variables(runs))
    check_variables(runs, names)
    band = _band(runs[0], reference, names) if reference is not None else None
    figure = variables_figure(runs, names, title, band)
    if out is not None:
        save_figure(figure, Path(out))
    return figure
