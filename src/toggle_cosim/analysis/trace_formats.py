"""Trace files from other tools: FMPy / FMI cross-check CSV, and Modelica MAT v4 result files.

* `.csv`: the FMI cross-check layout that FMPy's `write_csv` also writes (a header of quoted
  names, "time" first): `toggle_cosim.analysis.csv_traces.read_trace`.
* `.mat`: the result file layout of Dymola and OpenModelica (MATLAB v4 matrices `Aclass`,
  `name`, `description`, `dataInfo`, `data_1` for parameters, `data_2` for trajectories), read
  with BuildingsPy's output-file reader (`buildingspy.io.outputfile.Reader`, which wraps DyMat).
  Every variable becomes a column on the time grid of the trajectories (parameters of `data_1`
  are constant columns). A Modelica result repeats the time of an event (the values just before
  and just after it); one sample per time is kept, the one after the event, since a trace's time
  must increase strictly. The abscissa ("Time" in Dymola's files) becomes "time".
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from toggle_cosim.analysis.csv_traces import CompareInputError, read_trace
from toggle_cosim.files.traces import Trace

__all__ = ["read_any_trace", "read_mat_trace"]


def read_mat_trace(path: Path | str) -> Trace:
    """A Dymola/OpenModelica MAT v4 result file as a Trace (see the module text)."""
    from buildingspy.io.outputfile import Reader

    from toggle_cosim.files.bounded import file_problem

    path = Path(path)
    problem = file_problem(path)
    if problem:
        raise CompareInputError(f"{path}: {problem}; give the Modelica result .mat file")
    try:  # every variable's values too: dataInfo may point past data_1 or data_2
        with contextlib.redirect_stdout(io.StringIO()):
            reader = Reader(str(path), "dymola")
            names = [name for name in reader.varNames() if name.lower() != "time"]
            series = {name: reader.values(name) for name in names}
    except Exception as error:  # noqa: BLE001 - any defect of a foreign file is bad input
        detail = " ".join(str(error).split())[:120] or type(error).__name__
        raise CompareInputError(
            f"{path}: is not a Modelica result file in the MAT v4 layout ({detail}); write it with Dymola or "
            "OpenModelica (Aclass, name, description, dataInfo, data_1, data_2)"
        ) from error
    if not names:
        raise CompareInputError(f"{path}: holds no variables besides time; nothing to compare")
    longest = max(series.values(), key=lambda pair: pair[0].size)[0]
    time = np.asarray(longest, dtype=float)
    if time.size < 2 or not np.all(np.isfinite(time)):
        raise CompareInputError(f"{path}: its time column has fewer than two finite samples; a trace needs two")
    if np.any(np.diff(time) < 0):
        raise CompareInputError(f"{path}: time decreases in its trajectories; the file is damaged")
    keep = np.append(np.diff(time) > 0, True)  # the last of each run of equal times: after the event
    columns = [time[keep]]
    for name in names:
        t, y = (np.asarray(part, dtype=float) for part in series[name])
        if t.size == time.size:
            values = y[keep]
        else:  # a parameter (data_1, two samples) or a trajectory on another grid
            values = np.interp(time[keep], t[np.append(np.diff(t) > 0, True)], y[np.append(np.diff(t) > 0, True)])
        if not np.all(np.isfinite(values)):
            raise CompareInputError(f"{path}: variable {name!r} has non-finite values; the run diverged")
        columns.append(values)
    return Trace(("time", *names), np.column_stack(columns))


def read_any_trace(path: Path | str) -> Trace:
    """Read a trace by its file name: `.mat` as a Modelica result file, anything else as CSV."""
    path = Path(path)
    if path.suffix.lower() == ".mat":
        return read_mat_trace(path)
    return read_trace(path)
