"""One self-contained HTML page of runs, comparisons and sweeps, drawn with Plotly.

The page holds plotly.js itself (Plotly's own bundle, written once into the page), so it opens
offline from a CI artifact or a mail; it has no script of its own beyond one click handler (a
heat-map cell shows its case's trace, `SWEEP_CLICK`). Sections, each built by a pure function
from data already read:

* `overlay_section`: every run's variables overlaid, one variable at a time, chosen in a
  dropdown (Plotly's updatemenus), its unit on the axis;
* `comparison_section`: a run against its reference, variable by variable: the funnel band, the
  reference, the run and the samples outside the funnel marked, with the verdict table
  (every variable, the numbers unrounded by display);
* `sweep_section`: a sweep's figures of merit as heat maps over two axes (a dropdown per figure
  of merit), whose cells, when the sweep kept its traces, show that case's trace below;
* `failures_section`: the runs that failed or were interrupted, with their reasons (a run that
  failed before its first sample has nothing else to show);
* `records_section`: each run's record (settings, warnings, which loop ran and why, solver counts).

Every value from the user's files reaches the page through `page_text` (the page's text and
attributes, and every string Plotly draws) or `script_json` (the click handler's values): a name
is shown as written and never read as markup or script.

Curves are thinned for display (`display_points.thin`, at most DISPLAY_POINTS per curve, every
extreme kept); the numbers in tables are never thinned.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.analysis.compare import ComparisonResult, VariableResult
from toggle_cosim.analysis.display_points import DISPLAY_POINTS, thin
from toggle_cosim.analysis.page_text import page_text, script_json, separators_escaped
from toggle_cosim.analysis.run_files import LoadedRun
from toggle_cosim.analysis.sweep_heatmaps import axis_title, value_label
from toggle_cosim.files.outputs import HTML, write_file
from toggle_cosim.files.traces import Trace

__all__ = [
    "Comparison",
    "Section",
    "SweepCase",
    "comparison_section",
    "failures_section",
    "overlay_section",
    "records_section",
    "render",
    "shown_variables",
    "sweep_section",
    "write_report",
]

OVERLAY_POINTS = 1000  # points per curve of the runs overlaid (runs x variables curves in one page)
SWEEP_TRACE_POINTS = 800  # points per curve of a sweep case's trace (hundreds of cases in one page)
SWEEP_TRACE_VARIABLES = ("x_B", "iq_ref")  # what a clicked cell shows, where the trace has them
# The one script of the page: a click on a heat-map cell shows the trace of that cell's case
# (the traces are in the figure below it, hidden; each carries its case id in `meta`). Plotly's
# to_html puts it after the heat map's figure, {plot_id} being that figure's element id;
# {traces_id} is the element id of the figure of traces, {x_name} and {y_name} the axes' names
# (JavaScript strings written by `page_text.script_json`).
SWEEP_CLICK = """
(function () {
  var map = document.getElementById('{plot_id}');
  map.on('plotly_click', function (event) {
    var id = event.points[0].customdata;
    var box = document.getElementById('{traces_id}');
    if (!box || !id) { return; }
    var shown = box.data.map(function (curve) { return curve.meta === id; });
    var cell = {x_name} + ' = ' + event.points[0].x + ', ' + {y_name} + ' = ' + event.points[0].y;
    Plotly.update(box, {visible: shown}, {title: {text: cell + ' (case ' + id + ')'}});
  });
})();
"""


@dataclass(frozen=True)
class Section:
    """A part of the page: a heading, its HTML, and an anchor for the table of contents."""

    title: str
    body: str
    anchor: str


@dataclass(frozen=True)
class Comparison:
    """A run checked against its reference: the label, the comparison (with its funnels), the
    reference trace and the units of its variables."""

    label: str
    comparison: ComparisonResult
    reference: Trace
    units: Mapping[str, str]


@dataclass(frozen=True)
class SweepCase:
    """A sweep's table and, where kept, its cases' traces: `table` is the results DataFrame,
    `x`, `y` the two axes of the heat maps, `groups` the other axes (one set of maps per
    combination), `traces` {case_id: trace} (empty when the sweep kept none)."""

    name: str
    table: Any  # pandas.DataFrame
    x: str
    y: str
    groups: Sequence[str]
    metrics: Sequence[tuple[str, str, Callable[[np.ndarray], np.ndarray]]]
    traces: Mapping[str, Trace]


def _figure_html(figure: Any, div_id: str, post_script: str | None = None) -> str:
    """The figure's element and its script (Plotly's JSON, `<` and `>` escaped by Plotly, the
    line separators by `separators_escaped`); the strings in `figure` went through `page_text`."""
    return separators_escaped(
        figure.to_html(
            full_html=False,
            include_plotlyjs=False,
            div_id=div_id,
            post_script=post_script,
            config={"displaylogo": False, "responsive": True},
        )
    )


def _display(values: np.ndarray) -> np.ndarray:
    """Values sent to the browser: float32 (7 digits, half the bytes), never the tables' numbers."""
    return np.asarray(values, dtype=np.float32)


def _label(name: str, units: Mapping[str, str]) -> str:
    return page_text(f"{name} [{units[name]}]" if name in units else name)


def _outside(name: str, units: Mapping[str, str]) -> str:
    return page_text(f"outside by [{units[name]}]" if name in units else "outside by")


def _dropdown(buttons: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [
        {
            "buttons": buttons,
            "direction": "down",
            "x": 0.0,
            "xanchor": "left",
            "y": 1.18,
            "yanchor": "top",
            "showactive": True,
            "name": "variable",
        }
    ]


_COLORS = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)


def overlay_section(runs: Sequence[LoadedRun], variables: Sequence[str] | None = None, title: str = "Runs") -> Section:
    """Every run's `variables` (default: every column any run has) overlaid, one variable shown
    at a time, chosen in the dropdown; a run lacking a variable has no curve for it, and a run
    with fewer than two samples (one that failed at its start) none at all: the note names it."""
    import plotly.graph_objects as go

    undrawn = [run.label for run in runs if not run.drawable]
    runs = [run for run in runs if run.drawable]
    names = list(variables or dict.fromkeys(name for run in runs for name in run.variables))
    units: dict[str, str] = {}
    for run in runs:
        for name, unit in run.units.items():
            units.setdefault(name, unit)
    figure = go.Figure()
    owner: list[str] = []
    for number, run in enumerate(runs):
        color = _COLORS[number % len(_COLORS)]
        for name in names:
            if name not in run.trace.names:
                continue
            t, y = thin(run.trace.time, run.trace.column(name), OVERLAY_POINTS)
            figure.add_trace(
                go.Scatter(
                    x=_display(t),
                    y=_display(y),
                    name=page_text(run.label),
                    legendgroup=run.label,
                    line={"color": color, "width": 1.5},
                    visible=name == names[0],
                    meta=name,
                    mode="lines",
                )
            )
            owner.append(name)
    buttons = [
        {
            "label": page_text(name),
            "method": "update",
            "args": [{"visible": [o == name for o in owner]}, {"yaxis.title.text": _label(name, units)}],
        }
        for name in names
    ]
    figure.update_layout(
        updatemenus=_dropdown(buttons),
        xaxis_title="time [s]",
        yaxis_title=_label(names[0], units) if names else "",
        height=560 + 22 * (len(runs) // 3),
        margin={"t": 90},
        legend={"title": {"text": "run"}, "orientation": "h", "y": -0.15, "yanchor": "top"},
        template="plotly_white",
    )
    note = f"<p>{len(runs)} run(s); choose the variable above the plot.</p>"
    if undrawn:
        note += f"<p>Not drawn (fewer than two samples): {page_text(', '.join(undrawn))}.</p>"
    return Section(title, note + _figure_html(figure, "runs-overlay"), "runs")


def failures_section(runs: Sequence[LoadedRun], title: str = "Runs that did not complete") -> Section:
    """A row per run whose record says it failed or was interrupted: its status, the reason its
    record gives and the samples its trace holds (none for a run that failed at its start)."""
    rows = "".join(
        f'<tr class="fail"><td>{page_text(run.label)}</td><td>{page_text(run.record.get("status"))}</td>'
        f"<td>{page_text(run.record.get('reason') or 'no reason recorded')}</td>"
        f"<td>{run.trace.data.shape[0]}</td></tr>"
        for run in runs
        if run.incomplete
    )
    head = "<tr><th>run</th><th>status</th><th>reason</th><th>samples in its trace</th></tr>"
    return Section(title, f'<table class="records">{head}{rows}</table>', "failures")


def shown_variables(comparison: ComparisonResult) -> list[VariableResult]:
    """The variables a comparison's figure draws: every failing one, else the first one compared
    (each variable's verdict is in the table; drawing every funnel of every run would make the
    page tens of megabytes)."""
    failing = [v for v in comparison.variables if not v.passed]
    return failing or list(comparison.variables[:1])


def _funnel_traces(variable: VariableResult, reference: Trace, visible: bool) -> list[tuple[int, Any]]:
    """(row, curve): the funnel's edges (filled between), the reference, the run and the
    samples outside the funnel above; the distance outside the funnel below."""
    import plotly.graph_objects as go

    envelope = variable.envelope
    assert envelope is not None, "compare_traces keeps every envelope"
    outside = np.flatnonzero(envelope.error > 0)
    if outside.size > DISPLAY_POINTS:  # the largest excursions, in time order
        outside = np.sort(outside[np.argsort(envelope.error[outside])[-DISPLAY_POINTS:]])
    band = f"funnel (±{variable.half_height:.3g}, ±{variable.half_width:.3g} s)"
    edge = {"color": "rgba(31,119,180,0.5)", "width": 0.8}

    def curve(t: np.ndarray, y: np.ndarray, thinned: bool = True, **style: Any) -> Any:
        if thinned:
            t, y = thin(t, y)
        return go.Scatter(x=_display(t), y=_display(y), visible=visible, meta=variable.name, **style)

    return [
        (1, curve(envelope.lower_time, envelope.lower, name=band, legendgroup="funnel", mode="lines", line=edge,
                  showlegend=False)),
        (1, curve(envelope.upper_time, envelope.upper, name=band, legendgroup="funnel", mode="lines", line=edge,
                  fill="tonexty", fillcolor="rgba(31,119,180,0.18)")),
        (1, curve(reference.time, reference.column(variable.name), name="reference", mode="lines",
                  line={"color": "black", "width": 1.2})),
        (1, curve(envelope.time, envelope.result, name="run", mode="lines",
                  line={"color": "#d62728", "width": 1.2, "dash": "dash"})),
        (1, curve(envelope.time[outside], envelope.result[outside], thinned=False, mode="markers",
                  name=f"outside the funnel ({int(np.count_nonzero(envelope.error > 0))} samples)",
                  marker={"color": "#d62728", "size": 5, "symbol": "x"})),
        (2, curve(envelope.time, envelope.error, name="distance outside the funnel", mode="lines",
                  line={"color": "#d62728", "width": 1.0}, fill="tozeroy")),
    ]  # fmt: skip


def _verdict_table(comparison: ComparisonResult, units: Mapping[str, str]) -> str:
    rows = []
    for v in comparison.variables:
        when = "" if v.time_of_max_error is None else repr(v.time_of_max_error)
        verdict = "PASS" if v.passed else "FAIL"
        rows.append(
            f'<tr class="{verdict.lower()}"><td>{page_text(v.name)}</td><td>{page_text(units.get(v.name, ""))}</td>'
            f"<td>{verdict}</td><td>{v.max_error!r}</td><td>{when}</td><td>{v.half_height!r}</td>"
            f"<td>{v.half_width!r}</td></tr>"
        )
    head = (
        "<tr><th>variable</th><th>unit</th><th>verdict</th><th>max error</th><th>at t [s]</th>"
        "<th>funnel half-height</th><th>half-width [s]</th></tr>"
    )
    return f'<table class="numbers">{head}{"".join(rows)}</table>'


def comparison_section(comparisons: Sequence[Comparison], title: str = "Comparisons with references") -> Section:
    """Each run against its reference: a figure of its failing variables (or its first variable
    when all pass; dropdown when several) and the verdict of every variable."""
    from plotly.subplots import make_subplots

    parts = []
    failed = sum(1 for c in comparisons if not c.comparison.passed)
    parts.append(f"<p>{len(comparisons)} run(s) compared, {failed} failing.</p>")
    for number, item in enumerate(comparisons):
        shown = shown_variables(item.comparison)
        figure = make_subplots(rows=2, cols=1, shared_xaxes=True, row_heights=(0.72, 0.28), vertical_spacing=0.06)
        owner: list[str] = []
        for index, variable in enumerate(shown):
            for row, curve in _funnel_traces(variable, item.reference, index == 0):
                figure.add_trace(curve, row=row, col=1)
                owner.append(variable.name)
        buttons = [
            {
                "label": page_text(f"{v.name} ({'PASS' if v.passed else 'FAIL'})"),
                "method": "update",
                "args": [
                    {"visible": [o == v.name for o in owner]},
                    {"yaxis.title.text": _label(v.name, item.units), "yaxis2.title.text": _outside(v.name, item.units)},
                ],
            }
            for v in shown
        ]
        first = shown[0] if shown else None
        figure.update_yaxes(title_text=_label(first.name, item.units) if first else "", row=1, col=1)
        figure.update_yaxes(title_text=_outside(first.name, item.units) if first else "", row=2, col=1)
        figure.update_xaxes(title_text="time [s]", row=2, col=1)
        figure.update_layout(
            updatemenus=_dropdown(buttons) if len(buttons) > 1 else [],
            height=580,
            margin={"t": 90 if len(buttons) > 1 else 50},
            template="plotly_white",
            title={"text": page_text(f"{item.label}: {'PASS' if item.comparison.passed else 'FAIL'}"), "x": 0.5},
        )
        verdict = "pass" if item.comparison.passed else "fail"
        parts.append(
            f'<h3 class="{verdict}" id="cmp-{number}">{page_text(item.label)}: {verdict.upper()}</h3>'
            + _figure_html(figure, f"comparison-{number}")
            + f"<details{' open' if not item.comparison.passed else ''}><summary>every variable</summary>"
            + _verdict_table(item.comparison, item.units)
            + "</details>"
        )
    return Section(title, "".join(parts), "comparisons")


def _grid_of(group: Any, x: str, y: str) -> tuple[list[Any], list[Any], np.ndarray, np.ndarray]:
    xs = sorted(group[x].dropna().unique(), key=lambda v: (isinstance(v, str), v))
    ys = sorted(group[y].dropna().unique(), key=lambda v: (isinstance(v, str), v))
    xi = {v: i for i, v in enumerate(xs)}
    yi = {v: i for i, v in enumerate(ys)}
    rows = np.array([yi[v] for v in group[y]], dtype=int)
    cols = np.array([xi[v] for v in group[x]], dtype=int)
    return xs, ys, rows, cols


def _with_unit(name: str) -> str:
    """A plant variable's axis title with its unit from the plant contract (`x_B [m]`)."""
    from toggle_cosim.plant.contract import contract_unit

    unit = contract_unit(name)
    return f"{name} [{unit}]" if unit else name


def _click_script(traces_id: str, x: str, y: str) -> str:
    """SWEEP_CLICK for the figure of traces `traces_id` and the axes `x`, `y`: the names as
    Plotly shows them (`page_text`) in script-safe literals (`script_json`)."""
    script = SWEEP_CLICK.replace("{traces_id}", traces_id)
    return script.replace("{x_name}", script_json(page_text(x))).replace("{y_name}", script_json(page_text(y)))


def _case_text(status: Any, reason: Any) -> str:
    """A cell's status as its hover text shows it: "ok", or "failed: <reason>"."""
    return page_text(f"{status}: {reason}" if status != "ok" and isinstance(reason, str) and reason else status)


def sweep_section(sweep: SweepCase, title: str = "Sweep") -> Section:
    """A heat map per combination of the other axes, the figure of merit chosen in a dropdown;
    failed cases are empty cells whose hover text names them with their reason. With kept traces,
    a click on a cell shows that case's trace in the figure below the map."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    table = sweep.table
    parts = [f"<p>{page_text(sweep.name)}: {len(table)} case(s), {int((table['status'] != 'ok').sum())} failed.</p>"]
    groups = table.groupby(list(sweep.groups), sort=True, dropna=False) if sweep.groups else [((), table)]
    for number, (key, group) in enumerate(groups):
        key = key if isinstance(key, tuple) else (key,)
        tag = page_text(", ".join(f"{k} = {value_label(v)}" for k, v in zip(sweep.groups, key, strict=True)))
        xs, ys, rows, cols = _grid_of(group, sweep.x, sweep.y)
        ok = (group["status"] == "ok").to_numpy()
        ids = np.full((len(ys), len(xs)), "", dtype=object)
        ids[rows, cols] = [page_text(case) for case in group["case_id"].astype(str)]
        reasons = group["reason"] if "reason" in group.columns else [None] * len(group)
        status = np.full((len(ys), len(xs)), "", dtype=object)
        status[rows, cols] = [_case_text(s, r) for s, r in zip(group["status"].astype(str), reasons, strict=True)]
        figure = go.Figure()
        for index, (column, label, transform) in enumerate(sweep.metrics):
            grid = np.full((len(ys), len(xs)), np.nan)
            values = transform(group[column].to_numpy(dtype=float, na_value=np.nan))
            grid[rows[ok], cols[ok]] = values[ok]
            figure.add_trace(
                go.Heatmap(
                    z=grid,
                    x=[page_text(value_label(v)) for v in xs],
                    y=[page_text(value_label(v)) for v in ys],
                    customdata=ids,
                    text=status,
                    colorscale="Viridis",
                    colorbar={"title": {"text": page_text(label)}},
                    meta=[page_text(sweep.x), page_text(sweep.y), page_text(label)],  # not read as template
                    hovertemplate="%{meta[0]} = %{x}<br>%{meta[1]} = %{y}<br>%{meta[2]}: %{z:.4g}"
                    "<br>status: %{text}<br>case %{customdata}<extra></extra>",
                    visible=index == 0,
                    name=page_text(label),
                )
            )
        buttons = [
            {
                "label": page_text(label),
                "method": "update",
                "args": [{"visible": [i == index for i in range(len(sweep.metrics))]}],
            }
            for index, (_, label, _) in enumerate(sweep.metrics)
        ]
        figure.update_layout(
            updatemenus=_dropdown(buttons),
            xaxis_title=page_text(axis_title(sweep.x)),
            yaxis_title=page_text(axis_title(sweep.y)),
            height=480,
            margin={"t": 90},
            template="plotly_white",
            title={"text": tag or page_text(sweep.name), "x": 0.5},
            xaxis={"type": "category"},
            yaxis={"type": "category"},
        )
        map_id, traces_id = f"sweep-map-{number}", f"sweep-trace-{number}"
        kept = [case for case in group["case_id"].astype(str) if case in sweep.traces]
        if not kept:
            parts.append(_figure_html(figure, map_id))
            continue
        shown = [name for name in SWEEP_TRACE_VARIABLES if name in sweep.traces[kept[0]].names]
        panel = make_subplots(rows=len(shown), cols=1, shared_xaxes=True, vertical_spacing=0.08)
        for case in kept:
            trace = sweep.traces[case]
            for row, name in enumerate(shown, start=1):
                if name in trace.names:
                    t, y = thin(trace.time, trace.column(name), SWEEP_TRACE_POINTS)
                    panel.add_trace(
                        go.Scatter(
                            x=_display(t),
                            y=_display(y),
                            name=page_text(name),
                            meta=page_text(case),
                            visible=case == kept[0],  # the first case's until a cell is clicked: no empty axes
                            mode="lines",
                            showlegend=False,
                            line={"width": 1.5},
                        ),  # fmt: skip
                        row=row,
                        col=1,
                    )
        for row, name in enumerate(shown, start=1):
            panel.update_yaxes(title_text=page_text(_with_unit(name)), row=row, col=1)
        panel.update_xaxes(title_text="time [s]", row=len(shown), col=1)
        panel.update_layout(
            height=180 + 200 * len(shown),
            template="plotly_white",
            title={"text": f"case {kept[0]}: click a cell of the map above to show its case's trace", "x": 0.5},
        )
        parts.append(
            _figure_html(figure, map_id, post_script=_click_script(traces_id, sweep.x, sweep.y))
            + _figure_html(panel, traces_id)
        )
    return Section(title, "".join(parts), "sweep")


def _controller(record: Mapping[str, Any]) -> str:
    """The controller's class (its last name) and the law it ran."""
    controller = record.get("controller") or {}
    law = ((record.get("resolved") or {}).get("controller") or {}).get("law")
    kind = str(controller.get("class", "")).rsplit(".", 1)[-1] if isinstance(controller, Mapping) else str(controller)
    return ", ".join(str(part) for part in (kind, f"law {law}" if law else "") if part)


_PATH_FIELDS = ("scenario file", "plant FMU")  # shown relative to the report's folder
_RECORD_FIELDS = (
    ("status", lambda r: r.get("status")),
    ("reason", lambda r: r.get("reason") or ""),
    ("scenario file", lambda r: r.get("scenario_file") or ""),
    ("plant FMU", lambda r: (r.get("fmu") or {}).get("path", "")),
    ("controller", lambda r: _controller(r)),
    ("coupling", lambda r: r.get("coupling") or ""),
    (
        "loop",
        lambda r: ": ".join(
            str(p) for p in ((r.get("loop") or {}).get("kind"), (r.get("loop") or {}).get("reason")) if p
        ),
    ),
    ("warnings", lambda r: "; ".join(map(str, r.get("warnings") or [])) or "none"),
    ("samples", lambda r: r.get("samples", "")),
    ("wall time [s]", lambda r: r.get("wall_time_s", "")),
)


def _cell(name: str, value: Any, folder: Path | None) -> str:
    """A record field as its table cell shows it: a number to 5 significant digits, a path
    relative to the report's `folder` (where the page is opened from)."""
    if isinstance(value, float):
        return f"{value:.5g}"
    if name in _PATH_FIELDS and value and folder is not None:
        return os.path.relpath(Path(str(value)).absolute(), Path(folder).absolute())
    return str(value)


def records_section(runs: Sequence[LoadedRun], title: str = "Run records", folder: Path | None = None) -> Section:
    """A row per run with its record's status, controller, coupling, loop (which ran, and why),
    warnings; the whole record (settings, solver statistics, versions) in a fold below. Numbers
    are shown to 5 significant digits and paths relative to `folder`, the report's."""
    head = "<tr><th>run</th>" + "".join(f"<th>{page_text(name)}</th>" for name, _ in _RECORD_FIELDS) + "</tr>"
    rows, folds = [], []
    for run in runs:
        record = dict(run.record)
        if not record:
            rows.append(f"<tr><td>{page_text(run.label)}</td><td colspan={len(_RECORD_FIELDS)}>no run record</td></tr>")
            continue
        warned = ' class="fail"' if run.incomplete else ' class="warn"' if record.get("warnings") else ""
        cells = "".join(f"<td>{page_text(_cell(name, read(record), folder))}</td>" for name, read in _RECORD_FIELDS)
        rows.append(f"<tr{warned}><td>{page_text(run.label)}</td>{cells}</tr>")
        folds.append(
            f"<details><summary>{page_text(run.label)}: the whole run.json</summary>"
            f"<pre>{page_text(json.dumps(record, indent=2, default=str))}</pre></details>"
        )
    body = f'<table class="records">{head}{"".join(rows)}</table>{"".join(folds)}'
    return Section(title, body, "records")


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1200px; color: #222; }
h1 { font-size: 1.5em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 1.6em; }
table { border-collapse: collapse; font-size: .85em; margin: .5em 0; }
td, th { border: 1px solid #ddd; padding: .2em .5em; text-align: left; vertical-align: top; }
table.numbers td:nth-child(n+4) { font-family: monospace; text-align: right; }
tr.fail td, h3.fail { color: #b00; } h3.pass { color: #060; } tr.warn { background: #fff6e0; }
table.records td { overflow-wrap: anywhere; max-width: 22em; }
pre { background: #f6f6f6; padding: .6em; overflow: auto; max-height: 30em; font-size: .8em; }
"""


def render(title: str, sections: Sequence[Section], note: str = "") -> str:
    """The whole page: plotly.js (Plotly's bundle, once), a table of contents, the sections."""
    from plotly.offline import get_plotlyjs

    contents = "".join(f'<li><a href="#{page_text(s.anchor)}">{page_text(s.title)}</a></li>' for s in sections)
    body = "".join(
        f'<section id="{page_text(s.anchor)}"><h2>{page_text(s.title)}</h2>{s.body}</section>' for s in sections
    )
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{page_text(title)}</title><style>{_STYLE}</style>"
        f'<script type="text/javascript">{get_plotlyjs()}</script></head>'
        f"<body><h1>{page_text(title)}</h1>{f'<p>{page_text(note)}</p>' if note else ''}<ul>{contents}</ul>{body}</body></html>\n"
    )


def write_report(path: Path | str, title: str, sections: Sequence[Section], note: str = "") -> Path:
    """Render the page and write it to `path` (a unique temporary name renamed into place;
    a link, folder or device at `path` is refused: `files.outputs`)."""
    text = render(title, [s for s in sections if s is not None], note)
    return write_file(Path(path), lambda stream: stream.write(text), what="HTML report", kind=HTML)
