"""The sweep's output folder as a store of finished cases, written in batches.

Finished rows are gathered in memory and written together, every BATCH_ROWS rows (or
TOGGLE_COSIM_SWEEP_BATCH_ROWS) or BATCH_SECONDS seconds, whichever comes first, as one Parquet file `OUTPUT/parts/batch-*.parquet`
(temporary name, then rename): a crash or a kill loses at most the batch in flight, and a re-run
finds the cases already done (their ids, kept in memory; the rows themselves are not). At the
end (and on Ctrl-C) the batches and the earlier table are consolidated into
`OUTPUT/results.parquet` (atomically), one row per case in case order, by Arrow tables, and the
consolidated batches are removed. A part whose columns are not the sweep's (another version of
the sweep file, a foreign writer) or that cannot be read is reported and its cases run again.

With keep_traces each case's whole trace goes, batch by batch, into the Parquet dataset
`OUTPUT/traces/` (zstd-compressed, a `case_id` column then the trace's columns), read back with
`read_trace(OUTPUT, case_id)` or `pandas.read_parquet(OUTPUT / "traces", filters=[("case_id",
"==", ID)])`.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from toggle_cosim.experiments.sweep_spec import METRICS, Sweep, SweepError
from toggle_cosim.files.outputs import PARQUET, replacing

RESULTS_FILE = "results.parquet"
PARTS_DIR = "parts"
TRACES_DIR = "traces"
BATCH_ROWS = 500
BATCH_SECONDS = 2.0


def batch_rows() -> int:
    """Rows per batch: TOGGLE_COSIM_SWEEP_BATCH_ROWS (a positive whole number), else BATCH_ROWS."""
    text = os.environ.get("TOGGLE_COSIM_SWEEP_BATCH_ROWS", "").strip()
    if not text:
        return BATCH_ROWS
    if not text.isdigit() or int(text) < 1:
        raise ValueError(f"TOGGLE_COSIM_SWEEP_BATCH_ROWS={text!r}: give a positive whole number of rows")
    return int(text)


def _arrow() -> Any:
    import pyarrow as pa

    pa.enable_signal_handlers(False)  # its own SIGINT handler would bypass ours (exit -2, not 130)
    return pa


def _arrow_schema(sweep: Sweep) -> Any:
    pa = _arrow()
    types = {"float": pa.float64(), "bool": pa.bool_(), "string": pa.string()}
    fields = [pa.field("case", pa.int64()), pa.field("case_id", pa.string()), pa.field("variant", pa.string())]
    fields += [pa.field(c, types[sweep.parameter_types[c]]) for c in sweep.parameter_columns]
    fields += [pa.field("status", pa.string()), pa.field("reason", pa.string()), pa.field("warnings", pa.string())]
    fields += [pa.field(m, pa.float64()) for m in METRICS]
    fields += [
        pa.field("samples", pa.int64()),
        pa.field("wall_s", pa.float64()),
        pa.field("host", pa.string()),
        pa.field("fmu_sha256", pa.string()),
    ]
    return pa.schema(fields)


def _coerce(value: Any, kind: str) -> Any:
    if value is None:
        return None
    if kind == "string":
        return value if isinstance(value, str) else str(value)
    if kind == "bool":
        return bool(value)
    if kind in ("double", "float"):
        return float(value)
    if kind == "int64":
        return int(value)
    return value


def _table(rows: Sequence[Mapping[str, Any]], schema: Any) -> Any:
    pa = _arrow()
    columns = {}
    for f in schema:
        kind = str(f.type)
        columns[f.name] = pa.array([_coerce(r.get(f.name), kind) for r in rows], type=f.type)
    return pa.table(columns, schema=schema)


def _atomic_parquet(table: Any, path: Path, compression: str = "snappy") -> None:
    from toggle_cosim.files.naming import naming

    with naming(path):  # a full disk names the table it could not write
        _write_parquet(table, path, compression)


def _write_parquet(table: Any, path: Path, compression: str) -> None:
    import pyarrow.parquet as pq

    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path, kind=PARQUET) as temporary:  # a unique temporary name, synced and renamed into place
        pq.write_table(table, str(temporary), compression=compression)


def _batch_name(sequence: int) -> str:
    """Names that sort in the order they were written (newer rows win over older ones)."""
    return f"batch-{time.time_ns():020d}-{os.getpid()}-{sequence:06d}.parquet"


class ResultStore:
    """The sweep's output folder: finished cases in batch files, consolidated into results.parquet."""

    def __init__(
        self,
        sweep: Sweep,
        *,
        keep_traces: bool = False,
        trace_columns: Sequence[str] = (),
        batch_rows: int | None = None,
        batch_seconds: float = BATCH_SECONDS,
    ) -> None:
        self.sweep = sweep
        self.folder = sweep.output
        self.parts = self.folder / PARTS_DIR
        self.traces = self.folder / TRACES_DIR
        self.results = self.folder / RESULTS_FILE
        self.schema = _arrow_schema(sweep)
        self.wanted = {c.case_id for c in sweep.cases}
        self.done: dict[str, bool] = {}  # finished cases of this sweep: id -> ok
        self.other_fmu: set[str] = set()  # finished cases computed with another FMU
        self.unreadable: list[str] = []
        self.keep_traces = keep_traces
        self.trace_columns = list(trace_columns)
        self.batch_rows, self.batch_seconds = max(1, batch_rows or BATCH_ROWS), batch_seconds
        self._rows: list[dict[str, Any]] = []
        self._traces: list[tuple[str, np.ndarray]] = []
        self._last_flush = time.monotonic()
        self._sequence = 0
        self._sources: list[Path] = []  # files whose rows are in `done`

    # -- reading what earlier runs finished ------------------------------------------------------
    def _readable(self, source: Path) -> Any:
        """The table in `source` if it is one of this sweep's (its columns and types), else None."""
        import pyarrow.parquet as pq

        try:
            table = pq.read_table(source, use_threads=False)
        except Exception as error:  # noqa: BLE001 - a torn file from a foreign writer: redo its cases
            self.unreadable.append(f"{source.name} ({type(error).__name__})")
            return None
        if not table.schema.equals(self.schema, check_metadata=False):
            self.unreadable.append(f"{source.name} (columns of another sweep)")
            return None
        return table

    def _set_aside(self, source: Path) -> None:
        """An unreadable batch is renamed, not read again (its cases run again); the table is replaced."""
        if source != self.results:
            with contextlib.suppress(OSError):
                source.rename(source.with_name(source.name + ".unreadable"))

    def load(self, fmu_sha256: str | None = None) -> None:
        """Note what earlier runs finished (results.parquet, then the batches, newer wins)."""
        self.parts.mkdir(parents=True, exist_ok=True)
        for folder in (self.parts, self.folder, self.traces):
            for stale in folder.glob(".*.partial"):
                stale.unlink(missing_ok=True)
        sources = ([self.results] if self.results.is_file() else []) + sorted(self.parts.glob("*.parquet"))
        for source in sources:
            table = self._readable(source)
            if table is None:
                self._set_aside(source)
                continue
            self._sources.append(source)
            ids = table.column("case_id").to_pylist()
            statuses = table.column("status").to_pylist()
            shas = table.column("fmu_sha256").to_pylist()
            for identifier, status, sha in zip(ids, statuses, shas, strict=True):
                if identifier in self.wanted:
                    self.done[identifier] = status == "ok"
                    if fmu_sha256 is not None and sha not in (None, fmu_sha256):
                        self.other_fmu.add(identifier)
                    else:
                        self.other_fmu.discard(identifier)

    def forget_failed(self) -> None:
        """Failed cases count as not done (--retry-failed): they run again and their new rows win."""
        self.done = {k: ok for k, ok in self.done.items() if ok}

    def drop_traces(self, identifiers: Iterable[str]) -> None:
        """Remove the stored traces of cases about to run again (a case has one trace)."""
        import pyarrow.compute as pc
        import pyarrow.parquet as pq

        again = list(identifiers)
        if not again or not self.traces.is_dir():
            return
        values = _arrow().array(again, type=_arrow().string())
        for part in sorted(self.traces.glob("*.parquet")):
            try:
                table = pq.read_table(part, use_threads=False)
                keep = pc.invert(pc.is_in(table.column("case_id"), value_set=values))
            except Exception:  # noqa: BLE001 - an unreadable trace part helps no one
                part.unlink(missing_ok=True)
                continue
            if pc.all(keep).as_py():
                continue
            kept = table.filter(keep)
            if kept.num_rows:
                _atomic_parquet(kept, part, "zstd")
            else:
                part.unlink(missing_ok=True)

    def traced(self) -> set[str]:
        """The ids of the cases whose trace is stored in OUTPUT/traces/ (its case_id column only)."""
        import pyarrow.parquet as pq

        found: set[str] = set()
        if not self.traces.is_dir():
            return found
        for part in sorted(self.traces.glob("*.parquet")):
            try:
                column = pq.read_table(part, columns=["case_id"], use_threads=False).column("case_id")
            except Exception:  # noqa: BLE001 - an unreadable part stores no trace: its cases run again
                continue
            found.update(str(value) for value in column.unique().to_pylist())
        return found

    # -- recording -----------------------------------------------------------------------------
    def add(self, row: dict[str, Any], trace: np.ndarray | None = None) -> None:
        """Record a finished case; its batch is written once it is full or old enough."""
        self.done[row["case_id"]] = row.get("status") == "ok"
        self._rows.append(row)
        if self.keep_traces and trace is not None and len(trace):
            self._traces.append((row["case_id"], trace))
        if len(self._rows) >= self.batch_rows or time.monotonic() - self._last_flush >= self.batch_seconds:
            self.flush()

    @property
    def pending(self) -> int:
        """Rows recorded and not yet written."""
        return len(self._rows)

    def flush(self) -> None:
        """Write the rows (and traces) gathered since the last batch, each as one file."""
        self._last_flush = time.monotonic()
        if not self._rows:
            return
        self._sequence += 1
        name = _batch_name(self._sequence)
        if self._traces:
            _atomic_parquet(self._trace_table(self._traces), self.traces / name, "zstd")
        path = self.parts / name
        _atomic_parquet(_table(self._rows, self.schema), path)
        self._sources.append(path)
        self._rows, self._traces = [], []

    def _trace_table(self, traces: Sequence[tuple[str, np.ndarray]]) -> Any:
        pa = _arrow()
        data = np.concatenate([trace for _, trace in traces])
        ids = pa.DictionaryArray.from_arrays(
            pa.array(np.repeat(np.arange(len(traces), dtype=np.int32), [len(t) for _, t in traces])),
            pa.array([identifier for identifier, _ in traces], type=pa.string()),
        )
        columns = {"case_id": ids, **{name: data[:, k] for k, name in enumerate(self.trace_columns)}}
        return pa.table(columns)

    # -- the table -------------------------------------------------------------------------------
    def consolidate(self) -> Path:
        """results.parquet = this sweep's finished cases, in case order (the newest row of each);
        then drop the batches it holds. Rows of cases that are not in this sweep (an earlier version
        of the file) stay, in one part file."""
        self.flush()
        pa = _arrow()
        tables = []
        for source in self._sources:
            with contextlib.suppress(Exception):
                tables.append(_read(source))
        if tables:
            table = pa.concat_tables(tables)
        else:
            table = _table([], self.schema)
        ids = table.column("case_id").to_pylist()
        index = {c.case_id: c.index for c in self.sweep.cases}
        newest: dict[str, int] = {}
        foreign: dict[str, int] = {}
        for position, identifier in enumerate(ids):
            (newest if identifier in index else foreign)[identifier] = position
        del ids
        order = sorted(newest, key=index.__getitem__)
        mine = table.take(pa.array([newest[k] for k in order], type=pa.int64()))
        mine = mine.set_column(0, "case", pa.array([index[k] for k in order], type=pa.int64()))
        if foreign:
            _atomic_parquet(
                table.take(pa.array(sorted(foreign.values()), type=pa.int64())), self.parts / _batch_name(0)
            )
        _atomic_parquet(mine, self.results)
        for source in self._sources:
            if source != self.results:
                source.unlink(missing_ok=True)
        self._sources = [self.results]
        with contextlib.suppress(OSError):
            self.parts.rmdir()  # only when empty: no empty folder is left behind
        return self.results


def _read(path: Path) -> Any:
    import pyarrow.parquet as pq

    return pq.read_table(path, use_threads=False)


def read_results(path: Path, columns: Sequence[str] | None = None) -> Any:
    """A sweep's results table as a pandas DataFrame (give results.parquet or its folder);
    `columns` reads only those."""
    import pandas as pd

    _arrow()
    path = Path(path)
    return pd.read_parquet(path / RESULTS_FILE if path.is_dir() else path, columns=list(columns) if columns else None)


def read_trace(folder: Path | str, case_id: str) -> Any:
    """One case's whole trace from a sweep run with keep_traces, as a pandas DataFrame (time,
    the plant's outputs, the controller's columns).

    Raises SweepError (one line naming the folder and the fix) when the folder holds no traces
    (the sweep ran without --keep-traces) or none of the case `case_id`."""
    import pyarrow.dataset as ds

    _arrow()
    traces = Path(folder) / TRACES_DIR
    if not traces.is_dir() or not any(traces.glob("*.parquet")):
        raise SweepError(
            f"{folder}: no traces stored here; run the sweep again with --keep-traces (finished cases "
            "without a trace run again to store it)"
        )
    dataset = ds.dataset(traces, format="parquet")
    table = dataset.to_table(filter=ds.field("case_id") == case_id)
    if table.num_rows == 0:
        raise SweepError(
            f"{folder}: no trace of case {case_id!r} in {TRACES_DIR}/ (a case id of results.parquet's "
            "case_id column; a failed case may have none); run the sweep again with --keep-traces"
        )
    return table.drop_columns(["case_id"]).to_pandas()
