"""`sweep`: a parameter sweep from Python, its results table as a pandas DataFrame.

    table = tc.sweep("scenarios/sweep_FE_mB.yaml", fmu="fmus/ToggleLSM.fmu", output="out/sweeps/FE_mB")

The sweep runs as `toggle-cosim sweep` runs it (`experiments.sweep_run`): every case in its own
supervised process on a local pool (or a Dask cluster), each finished case recorded at once, so
calling it again with the same output folder runs only the cases not done yet; the table and the
heat maps are written to the output folder, and the table is returned.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING

from toggle_cosim.experiments.sweep import SweepError, execute_sweep, load_sweep, read_results

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["SweepError", "sweep"]


def _warn(line: str) -> None:
    """The sweep's log: its warnings (results computed with another FMU, unreadable part files)
    as Python warnings; its progress lines are left out."""
    if line.startswith("warning: "):
        warnings.warn(line.removeprefix("warning: "), stacklevel=3)


def sweep(
    path: str | Path,
    *,
    fmu: str | Path | None = None,
    output: str | Path | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    retry_failed: bool = False,
    case_timeout: float | None = None,
    progress: bool = False,
) -> pd.DataFrame:
    """Run the sweep file `path` (its base scenario's variants times its axes) and return the
    results table: one row per case with its parameters (plant.F_E [N], plant.m_B [kg],
    plant.mu, T_s [s], t_end [s] and the axes), status ("ok" or "failed") and reason, and the
    figures of merit (`RunSummary`: final_error_m, peak_iq_ref_A, hitting_time_s, ...).

    Args:
        path: the sweep file (YAML: base, axes or samples, output, heatmap; docs/sweeps.md).
        fmu: the plant FMU (default: the sweep's or its base scenario's fmu: key).
        output: the output folder (default: the sweep's output: key, else out/sweeps/<name>).
        workers: local pool size (default: all cores); scheduler: a Dask scheduler's address.
        retry_failed: run again the cases that failed last time.
        case_timeout: wall-clock limit per case in s.
        progress: a progress bar on stderr.

    Returns:
        The results table (a pandas DataFrame, one row per case in case order); its `attrs` hold
        "output" (the folder) and "heatmaps" (the figures written).

    Raises:
        SweepError: one line naming the file, the key and the fix; nothing has run.
        KeyboardInterrupt: interrupted; the finished cases are kept (call again to finish).

    Example:
        ```python
        table = tc.sweep("scenarios/sweep_FE_mB.yaml", fmu=tc.plant_fmu(), workers=2)
        ok = table[table.status == "ok"]
        ok.pivot_table("final_error_m", index="plant.F_E", columns="plant.m_B")
        ```
    """
    try:
        spec = load_sweep(Path(path), Path(output) if output is not None else None)
        done = execute_sweep(
            spec,
            Path(fmu) if fmu is not None else None,
            scheduler,
            workers,
            progress=progress,
            retry_failed=retry_failed,
            log=_warn,
            case_timeout=case_timeout,
        )
    except SweepError as error:
        raise SweepError(" ".join(str(error).split())) from None
    if done.interrupted:
        raise KeyboardInterrupt(f"sweep {spec.name}: {done.done} of {done.total} cases done; call again to finish")
    table = read_results(done.results)
    table.attrs["output"] = str(spec.output)
    table.attrs["heatmaps"] = [str(figure) for figure in done.figures]
    return table
