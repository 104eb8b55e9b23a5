"""The paper's nine-panel figure of a scenario's results folder (`<folder>/<variant>/trace.csv`
and `run.json`), with every defect of the folder as one `ResultsError` line naming the file."""

from __future__ import annotations

import json
from pathlib import Path


class ResultsError(ValueError):
    """A results folder that cannot be drawn; str() is the one-line reason."""


def read_run_record(path: Path) -> dict:
    """A run.json: a regular file of at most JSON_LIMIT bytes holding a JSON object."""
    from toggle_cosim.files.bounded import JSON_LIMIT, read_text_bounded

    record = json.loads(read_text_bounded(path, JSON_LIMIT, "run record"))
    if not isinstance(record, dict):
        raise ValueError("run.json does not hold a JSON object")
    return record


def plot_results(folder: Path, output: Path | None) -> Path:
    """Draw the variants of `folder` overlaid into `output` (default `folder/figure.png`)."""
    from toggle_cosim.analysis.plots import nine_panel_figure
    from toggle_cosim.files.traces import read_csv

    runs = sorted(p for p in folder.iterdir() if (p / "trace.csv").is_file()) if folder.is_dir() else []
    if not runs:
        raise ResultsError(
            f"{folder}: no run results here (expected <variant>/trace.csv; run 'toggle-cosim run' first)"
        )
    needed = ("time", "x_B", "iq_ref")  # the other panels are drawn from the optional outputs present
    traces, target, title = {}, None, folder.name
    for run_dir in runs:
        try:
            trace = read_csv(run_dir / "trace.csv")
            record = read_run_record(run_dir / "run.json")
            target = float(record["resolved"]["stroke"]["x_target"])
            title = f"{record['scenario']}: {record.get('description', '')}"
        except (OSError, ValueError, KeyError, TypeError) as error:
            detail = f"missing key {error}" if isinstance(error, KeyError) else " ".join(str(error).split())
            raise ResultsError(
                f"{run_dir}: unreadable results ({detail}); run it again with 'toggle-cosim run'"
            ) from error
        missing = [name for name in needed if name not in trace.names]
        if missing:
            raise ResultsError(
                f"{run_dir / 'trace.csv'}: no column {missing[0]!r} (the figure needs {', '.join(needed)});"
                " run it again with 'toggle-cosim run'"
            )
        traces[run_dir.name] = trace
    try:
        return nine_panel_figure(traces, title, output or folder / "figure.png", target)
    except OSError as error:
        raise ResultsError(
            f"{output or folder / 'figure.png'}: cannot write the figure ({error.strerror or error})"
        ) from error
