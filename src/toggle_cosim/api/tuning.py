"""`tune`: a controller's parameters tuned for the worst case (or the mean) of a robustness map.

    result = tc.tune("scenarios/tune_integral.yaml", output="out/tune/integral")
    result.best["parameters"], result.best["figures"]["worst_settling_time"]
    result.history                                       # the trial history (a DataFrame)

It runs as `toggle-cosim tune` runs it (`experiments.tune_run`): the map of the starting
controller and the trials on the sweep engine (a local pool or a Dask cluster), the study kept
in the output folder (calling again with the same output resumes it), then the best trial as a
scenario file, its map re-run by the sweep engine, the trial history and the figures.
"""

from __future__ import annotations

import warnings
from pathlib import Path

from toggle_cosim.experiments.sweep_spec import SweepError
from toggle_cosim.experiments.tune_run import HISTORY_FILE, TuneResult, execute_tuning
from toggle_cosim.experiments.tune_spec import TuneError, load_tuning

__all__ = ["TuneError", "TuneResult", "tune"]


def _warn(line: str) -> None:
    """The sweep engine's log: its warnings as Python warnings; its progress lines are left out."""
    if line.startswith("warning: "):
        warnings.warn(line.removeprefix("warning: "), stacklevel=3)


def tune(
    path: str | Path,
    *,
    fmu: str | Path | None = None,
    output: str | Path | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    trials: int | None = None,
    case_timeout: float | None = None,
    progress: bool = False,
) -> TuneResult:
    """Run the tuning file `path` (docs/designing.md, "Tuning over a map") and return what it found:
    `start` and `best` (each with "parameters", "objectives", "feasible", "violations" and
    "figures": worst_<metric> and mean_<metric> over the map), `rerun` (the tuned map run again by
    the sweep engine, "equal" when its objectives are the best trial's), `trials`, `files`.

    Args:
        fmu: the plant FMU (default: the sweep's or its base scenario's fmu: key).
        output: the output folder (default: the file's output: key, else out/tune/<name>).
        workers: local pool size (default: all cores); scheduler: a Dask scheduler's address.
        trials: the optimiser's trial budget (default: the file's optimiser.trials); a study
            already in `output` goes on to this many.
        case_timeout: wall-clock limit per case in s.
        progress: a progress bar on stderr.

    `result.history` is the trial history (OUTPUT/trials.csv) as a DataFrame.

    Raises:
        TuneError: one line naming the file, the key and the fix; nothing has run.
        KeyboardInterrupt: interrupted; the finished trials are kept (call again to go on).
    """
    try:
        tuning = load_tuning(Path(path), Path(output) if output is not None else None)
        result = execute_tuning(
            tuning, Path(fmu) if fmu is not None else None, scheduler, workers, progress, _warn, case_timeout, trials
        )
    except (TuneError, SweepError) as error:
        raise TuneError(" ".join(str(error).split())) from None
    if result.interrupted:
        raise KeyboardInterrupt(f"tune {tuning.name}: {result.trials} trials done; call again to go on")
    import pandas as pd

    result.history = pd.read_csv(result.output / HISTORY_FILE)
    return result
