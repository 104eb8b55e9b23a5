"""The sweep's output folder as a store of finished cases: each finished row is written at once
to `OUTPUT/parts/<case_id>.parquet` (temporary name, then rename), so a crash or a kill loses no
finished case and a re-run finds the cases already done; at the end (and on Ctrl-C) the rows are
consolidated into `OUTPUT/results.parquet` (atomically), one row per case, and the consolidated
part files are removed."""

from __future__ import annotations

import contextlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from toggle_cosim.experiments.sweep_spec import METRICS, Sweep
from toggle_cosim.files.outputs import replacing

RESULTS_FILE = "results.parquet"
PARTS_DIR = "parts"


def _arrow_schema(sweep: Sweep) -> Any:
    import pyarrow as pa

    pa.enable_signal_handlers(False)  # its own SIGINT handler would bypass ours (exit -2, not 130)

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
    import pyarrow as pa

    columns = {}
    for f in schema:
        kind = str(f.type)
        columns[f.name] = pa.array([_coerce(r.get(f.name), kind) for r in rows], type=f.type)
    return pa.table(columns, schema=schema)


def _atomic_parquet(table: Any, path: Path) -> None:
    from toggle_cosim.files.naming import naming

    with naming(path):  # a full disk names the table it could not write
        _write_parquet(table, path)


def _write_parquet(table: Any, path: Path) -> None:
    import pyarrow.parquet as pq

    with replacing(path) as temporary:  # a unique temporary name, synced and renamed into place
        pq.write_table(table, str(temporary))


def _read_rows(path: Path) -> list[dict[str, Any]]:
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()


class ResultStore:
    """The sweep's output folder: one part file per finished case, consolidated into results.parquet."""

    def __init__(self, sweep: Sweep) -> None:
        self.sweep = sweep
        self.folder = sweep.output
        self.parts = self.folder / PARTS_DIR
        self.results = self.folder / RESULTS_FILE
        self.schema = _arrow_schema(sweep)
        self.wanted = {c.case_id for c in sweep.cases}
        self.rows: dict[str, dict[str, Any]] = {}  # finished cases of this sweep, by id
        self.unreadable: list[str] = []

    def load(self) -> None:
        """Read what earlier runs finished (results.parquet, then part files, newer wins)."""
        self.parts.mkdir(parents=True, exist_ok=True)
        for stale in self.parts.glob(".*.partial"):
            stale.unlink(missing_ok=True)
        for stale in self.folder.glob(".*.partial"):
            stale.unlink(missing_ok=True)
        sources = ([self.results] if self.results.is_file() else []) + sorted(self.parts.glob("*.parquet"))
        for source in sources:
            try:
                rows = _read_rows(source)
            except Exception as error:  # noqa: BLE001 - a torn file from a foreign writer: redo its cases
                self.unreadable.append(f"{source.name} ({type(error).__name__})")
                continue
            for row in rows:
                if row.get("case_id") in self.wanted:
                    self.rows[row["case_id"]] = row

    def add(self, row: dict[str, Any]) -> None:
        """Record a finished case at once: its own part file, written atomically."""
        self.rows[row["case_id"]] = row
        _atomic_parquet(_table([row], self.schema), self.parts / f"{row['case_id']}.parquet")

    def consolidate(self) -> Path:
        """results.parquet = this sweep's finished cases, in case order; then drop the part files it
        holds. Rows of cases that are not in this sweep (an earlier version of the file) stay as parts."""
        import pyarrow.parquet as pq

        order = {c.case_id: c for c in self.sweep.cases}
        rows = []
        for identifier, case in order.items():
            if identifier in self.rows:
                row = dict(self.rows[identifier])
                row["case"] = case.index  # the index in this version of the sweep file
                rows.append(row)
        if self.results.is_file():  # keep foreign rows of an earlier results table as part files
            with contextlib.suppress(Exception):
                old = pq.read_table(self.results)
                ids = old.column("case_id").to_pylist()
                for k, identifier in enumerate(ids):
                    target = self.parts / f"{identifier}.parquet"
                    if identifier not in self.wanted and not target.exists():
                        _atomic_parquet(old.slice(k, 1), target)
        _atomic_parquet(_table(rows, self.schema), self.results)
        for identifier in self.rows:
            (self.parts / f"{identifier}.parquet").unlink(missing_ok=True)
        with contextlib.suppress(OSError):
            self.parts.rmdir()  # only when empty: no empty folder is left behind
        return self.results


def read_results(path: Path) -> Any:
    """A sweep's results table as a pandas DataFrame (give results.parquet or its folder)."""
    import pandas as pd
    import pyarrow as pa

    pa.enable_signal_handlers(False)
    path = Path(path)
    return pd.read_parquet(path / RESULTS_FILE if path.is_dir() else path)
