"""Parameter sweeps: the public names, gathered from `toggle_cosim.experiments` (where each
concern has its own module). The command is `toggle-cosim sweep` (`cli`)."""

from toggle_cosim.analysis.sweep_heatmaps import write_heatmaps
from toggle_cosim.experiments.sweep_exec import execute
from toggle_cosim.experiments.sweep_run import SweepResult, execute_sweep, run_sweep
from toggle_cosim.experiments.sweep_spec import METRICS, Case, Sweep, SweepError, load_sweep
from toggle_cosim.experiments.sweep_store import ResultStore, read_results, read_trace
from toggle_cosim.experiments.sweep_worker import run_case

__all__ = [
    "SweepError",
    "Sweep",
    "Case",
    "SweepResult",
    "load_sweep",
    "run_case",
    "execute",
    "execute_sweep",
    "run_sweep",
    "read_results",
    "read_trace",
    "write_heatmaps",
    "ResultStore",
    "METRICS",
]
