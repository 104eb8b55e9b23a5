"""A finished run as the Python API returns it: the trace with its units, the status, the run
record (what run.json holds) and the figures of merit.

    result = tc.simulate(run, fmu)
    result.status             # "complete", "failed" or "interrupted"
    result.reason             # why it failed (None when complete)
    result.summary            # RunSummary: final error [m], peak |i_q*| [A], T_h [s], ...
    df = result.to_dataframe()     # indexed by time [s]; df.attrs["units"] = {column: unit}
    result.plot(["x_B", "iq_ref"])  # a matplotlib Figure, one panel per variable
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from toggle_cosim.cosim.outcome import RunOutcome
from toggle_cosim.cosim.summary import RunSummary
from toggle_cosim.files.traces import Trace
from toggle_cosim.runs.definition import Run

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.figure import Figure

__all__ = ["Result", "RunInterrupted", "Status"]

Status = Literal["complete", "failed", "interrupted"]


@dataclass(frozen=True)
class Result:
    """One run's result.

    Attributes:
        run: the run that was simulated (scenario, variant, settings).
        trace: the samples: `trace.names` (time first, then the plant's outputs, then the
            controller's columns iq_ref, F_E, S, phase, e) and `trace.data` (samples x columns),
            one row per controller sample T_s from t = 0; a failed run's trace ends at its last
            recorded sample.
        status: "complete", "failed" (the plant failed or crashed, or the time limit passed:
            `reason` says which and when) or "interrupted".
        reason: why the run did not complete; None when it did.
        summary: the figures of merit (`RunSummary`: final error x_B* − x_B [m], settling time
            [s], overshoot [%], peak |i_q*| [A], the hitting time T_h of eq. (21) [s], S(t0) of
            eq. (21), E_in and E_fric at t_end [J], the VSC metrics: total variation of i_q* per
            second, sign changes of S per second while sliding, the measured reaching time and its
            ratio to T_h, ...); None when the run ended before its
            second sample.
        record: the run record, what `toggle-cosim run` writes to run.json (the resolved
            scenario, the FMU's path and SHA-256, the loop that ran, wall time, solver counts).
        units: {column: unit} from the plant FMU's modelDescription and the controller (`units`).

    Example:
        ```python
        result = tc.simulate(tc.load_scenario("scenarios/fig4_nominal.yaml")["friction"], tc.plant_fmu())
        if not result.ok:
            print(result.status, result.reason)
        df = result.to_dataframe()             # indexed by time [s]
        df["x_B"].plot()                       # df.attrs["units"]["x_B"] == "m"
        result.write("out/mine/friction")      # trace.csv and run.json, as `toggle-cosim run` writes them
        ```
    """

    run: Run
    trace: Trace
    status: Status
    reason: str | None
    summary: RunSummary | None
    record: Mapping[str, Any]
    units: Mapping[str, str]

    @classmethod
    def from_outcome(cls, outcome: RunOutcome, units: Mapping[str, str]) -> Result:
        status: Status = "complete" if outcome.complete else "interrupted" if outcome.interrupted else "failed"
        return cls(outcome.run, outcome.trace, status, outcome.reason, outcome.summary, outcome.record, dict(units))

    @property
    def ok(self) -> bool:
        """True when the run completed (`assert result.ok, result.reason`)."""
        return self.status == "complete"

    @property
    def label(self) -> str:
        """scenario/variant, as the command line names the run."""
        return self.run.label

    def __repr__(self) -> str:
        why = f", reason={self.reason!r}" if self.reason else ""
        return f"Result({self.label!r}, status={self.status!r}, samples={self.trace.data.shape[0]}{why})"

    def to_dataframe(self, *, multiindex: bool = False) -> pd.DataFrame:
        """The trace as a pandas DataFrame indexed by time [s], one column per variable.

        The units are in `df.attrs["units"]` ({column: unit}, "time" included). With
        `multiindex=True` the columns are a two-level MultiIndex (variable, unit) instead, so
        they show in the printed table; a column without a known unit has unit ""."""
        import pandas as pd

        names = self.trace.names
        frame = pd.DataFrame(self.trace.data[:, 1:].copy(), columns=list(names[1:]))
        frame.index = pd.Index(self.trace.data[:, 0].copy(), name=names[0])
        if multiindex:
            frame.columns = pd.MultiIndex.from_tuples(
                [(name, self.units.get(name, "")) for name in names[1:]], names=["variable", "unit"]
            )
        frame.attrs["units"] = {name: self.units[name] for name in names if name in self.units}
        frame.attrs["run"] = self.label
        return frame

    def plot(
        self,
        vars: Sequence[str] | str | None = None,  # noqa: A002 - the name the command line's --vars has
        reference: Any = None,
        *,
        out: str | Path | None = None,
    ) -> Figure:
        """This run's `vars` (default: every column), one panel each, around `reference`'s
        funnel band when one is given (a trace file, `Result` or `Trace`): `tc.plot(self, ...)`."""
        from toggle_cosim.api.plotting import plot

        return plot(self, vars, reference, title=self.label, out=out)

    def write(self, folder: str | Path) -> Path:
        """Write trace.csv and run.json into `folder` as `toggle-cosim run` writes them into
        OUT/<scenario>/<variant>/ (every `record_every`-th sample in the CSV); `folder`."""
        from toggle_cosim.files.traces import write_csv, write_json

        folder = Path(folder)
        write_csv(folder / "trace.csv", self.trace, every=int(self.run.resolved.get("record_every", 1)))
        write_json(folder / "run.json", dict(self.record))
        return folder


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by an interrupt (Ctrl-C, the notebook's stop button, SIGTERM): the partial
    result is in `.result` (status "interrupted")."""

    def __init__(self, result: Result) -> None:
        super().__init__(f"{result.label}: {result.reason}")
        self.result = result
