"""A sweep's output folder read back for the HTML report: its table, the heat maps' axes, and
the kept traces (`html_report.SweepCase`)."""

from __future__ import annotations

import json
from pathlib import Path

from toggle_cosim.analysis.html_report import SweepCase
from toggle_cosim.analysis.sweep_heatmaps import PANELS
from toggle_cosim.files.traces import Trace

__all__ = ["SweepFolderError", "is_sweep_folder", "read_sweep_folder"]


class SweepFolderError(ValueError):
    """A sweep folder that cannot be reported; str() is the one-line reason naming the file."""


def is_sweep_folder(folder: Path) -> bool:
    """True for a folder `toggle-cosim sweep` wrote (results.parquet and sweep.json)."""
    from toggle_cosim.experiments.sweep_run import MANIFEST_FILE
    from toggle_cosim.experiments.sweep_store import RESULTS_FILE

    return (Path(folder) / RESULTS_FILE).is_file() and (Path(folder) / MANIFEST_FILE).is_file()


def _heatmap_axes(manifest: dict, axes: list[str]) -> tuple[str, str]:
    """The sweep file's heatmap: axes where it can still be read, else its first two axes."""
    from toggle_cosim.experiments.sweep_spec import SweepError, load_sweep

    source = manifest.get("sweep_file")
    if source and Path(source).is_file():
        try:
            chosen = load_sweep(Path(source)).heatmap
        except (SweepError, OSError, ValueError):
            chosen = None
        if chosen and all(axis in axes for axis in chosen):
            return chosen[0], chosen[1]
    if len(axes) < 2:
        raise SweepFolderError(f"{source}: a heat map needs two axes, the sweep has {len(axes)}")
    return axes[0], axes[1]


def _traces(folder: Path, columns: tuple[str, ...]) -> dict[str, Trace]:
    """{case_id: trace of time and `columns`} of the sweep's kept traces ({} when none were kept)."""
    from toggle_cosim.experiments.sweep_store import TRACES_DIR

    if not (folder / TRACES_DIR).is_dir():
        return {}
    import pyarrow.dataset as ds

    dataset = ds.dataset(folder / TRACES_DIR, format="parquet")
    wanted = ["case_id", "time", *(name for name in columns if name in dataset.schema.names)]
    frame = dataset.to_table(columns=wanted).to_pandas()
    names = tuple(wanted[1:])
    return {
        str(case): Trace(names, group[list(names)].to_numpy(dtype=float))
        for case, group in frame.groupby("case_id", sort=False)
    }


def read_sweep_folder(folder: Path, trace_columns: tuple[str, ...] = ("x_B", "iq_ref")) -> SweepCase:
    """The table, heat-map axes and kept traces of the sweep output `folder`. Raises
    SweepFolderError naming the file for a folder that cannot be read."""
    from toggle_cosim.experiments.sweep_run import MANIFEST_FILE
    from toggle_cosim.experiments.sweep_store import RESULTS_FILE, read_results
    from toggle_cosim.files.bounded import JSON_LIMIT, read_text_bounded

    folder = Path(folder)
    manifest_path = folder / MANIFEST_FILE
    try:
        manifest = json.loads(read_text_bounded(manifest_path, JSON_LIMIT, "sweep manifest"))
        axes = list(manifest["axes"])
        variants = list(manifest.get("variants") or [])
        table = read_results(folder / RESULTS_FILE)
    except (OSError, ValueError, KeyError, TypeError) as error:
        detail = f"missing key {error}" if isinstance(error, KeyError) else " ".join(str(error).split())
        raise SweepFolderError(f"{manifest_path}: unreadable sweep output ({detail}); run the sweep again") from error
    x, y = _heatmap_axes(manifest, axes)
    groups = [axis for axis in axes if axis not in (x, y)]
    if len(variants) > 1 and "variant" not in (x, y):
        groups.insert(0, "variant")
    missing = [column for column in (x, y, *groups, "status", "case_id") if column not in table.columns]
    if missing:
        raise SweepFolderError(f"{folder / RESULTS_FILE}: no column {missing[0]!r}; run the sweep again")
    metrics = [(column, title, transform) for column, title, transform, _ in PANELS if column in table.columns]
    traces = _traces(folder, trace_columns)
    return SweepCase(str(manifest.get("sweep", folder.name)), table, x, y, groups, metrics, traces)
