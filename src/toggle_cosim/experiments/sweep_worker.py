"""One sweep case in a worker process: run it supervised, capture the FMU's log, return a plain
table row. The worker takes plain data (the case payload and the FMU path) and never raises: an
FMU error, a diverging run or any exception is a row with status "failed" and the reason."""

from __future__ import annotations

import contextlib
import copy
import os
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from toggle_cosim.experiments.scenario import runs_from_document
from toggle_cosim.experiments.sweep_spec import METRICS, Case

_capture = threading.local()
_plant_cache: dict[tuple[str, int, int], Any] = {}
_sha_cache: dict[tuple[str, int, int], str] = {}


class _ThreadLogTee:
    """sys.stdout stand-in: text printed by a thread that is capturing goes to its buffer (fmpy
    prints the FMU's log messages), everything else to the real stream. Safe with Dask threads."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        buffer = getattr(_capture, "buffer", None)
        if buffer is not None:
            buffer.append(text)
            return len(text)
        return self._stream.write(text)

    def flush(self) -> None:
        if getattr(_capture, "buffer", None) is None and self._stream is not None:
            self._stream.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextlib.contextmanager
def _captured_fmu_log() -> Iterator[list[str]]:
    if not isinstance(sys.stdout, _ThreadLogTee):
        sys.stdout = _ThreadLogTee(sys.stdout)
    buffer: list[str] = []
    _capture.buffer = buffer
    try:
        yield buffer
    finally:
        _capture.buffer = None


def _file_key(path: Path) -> tuple[str, int, int]:
    stat = path.stat()
    return (str(path), stat.st_mtime_ns, stat.st_size)


def file_sha256_cached(path: Path) -> str:
    key = _file_key(path)
    if key not in _sha_cache:
        from toggle_cosim.files.checksums import file_sha256

        _sha_cache[key] = file_sha256(path)
    return _sha_cache[key]


def _plant(path: Path) -> Any:
    from toggle_cosim.plant.contract import check_plant

    key = _file_key(path)
    if key not in _plant_cache:
        _plant_cache[key] = check_plant(path)
    return _plant_cache[key]


def resolve_fmu(fmu: str, sha256: str | None, data: bytes | None = None) -> Path:
    """The FMU file this worker uses: `fmu` if it is there with the sweep's SHA-256, else a copy of
    `data` (the FMU's bytes, sent along by the Dask backend) in this machine's temporary folder.
    A different FMU at the same path (a stale build on another machine) is never used."""
    if sha256 is None:
        return Path(fmu)
    given = Path(fmu)
    found = None
    if given.is_file():
        found = file_sha256_cached(given)
        if found == sha256:
            return given
    if data is not None:
        cache = Path(tempfile.gettempdir()) / "toggle-cosim-fmus" / f"plant-{sha256[:32]}.fmu"
        if not (cache.is_file() and file_sha256_cached(cache) == sha256):
            cache.parent.mkdir(parents=True, exist_ok=True)
            handle, temporary = tempfile.mkstemp(prefix=".plant-", suffix=".partial", dir=cache.parent)
            with os.fdopen(handle, "wb") as stream:
                stream.write(data)
            os.replace(temporary, cache)
            if file_sha256_cached(cache) != sha256:
                raise ValueError(f"the FMU bytes received do not have the sweep's SHA-256 {sha256[:12]}")
        return cache
    detail = f"{given} has SHA-256 {found[:12]}" if found else f"no file {given}"
    raise FileNotFoundError(f"the sweep's FMU (SHA-256 {sha256[:12]}) is not on this machine: {detail}")


def run_case(
    case: Mapping[str, Any],
    fmu: str,
    fmu_sha256: str | None = None,
    fmu_data: bytes | None = None,
    time_limit: float | None = None,
) -> dict[str, Any]:
    """Run one case (a payload of plain data) on the plant FMU at `fmu` (checked against
    `fmu_sha256` if given; `fmu_data`, the FMU's bytes, stand in where that file is missing);
    return its table row.

    Never raises for a failure of the case: the row has status "failed" and the reason. The case
    runs supervised (`supervision`): a crash or hang of the plant, or `time_limit` (default: the
    case's time_limit key, else max(30 s, 20 x t_end)) exceeded, is a failed row."""
    from toggle_cosim.cosim.supervision import simulate_supervised

    started = time.perf_counter()
    row: dict[str, Any] = {
        "case": case["index"],
        "case_id": case["case_id"],
        "variant": case["variant"],
        **case["parameters"],
        "status": "failed",
        "reason": None,
        "warnings": None,
        **dict.fromkeys(METRICS),
        "samples": None,
        "wall_s": None,
        "host": socket.gethostname(),
        "fmu_sha256": fmu_sha256,
    }
    try:
        with _captured_fmu_log() as log:
            try:
                source = case.get("source")  # the base scenario: controller.python is imported from its folder
                (run,) = runs_from_document(copy.deepcopy(case["document"]), Path(source) if source else None)
                plant = _plant(resolve_fmu(fmu, fmu_sha256, fmu_data))
                outcome = simulate_supervised(run, plant, time_limit=time_limit, capture_log=True)
            except Exception as error:  # noqa: BLE001 - any failure is the case's result
                outcome = None
                row["reason"] = " ".join(f"{type(error).__name__}: {error}".split())
        messages = [line.strip() for line in "".join(log).splitlines() if line.startswith(("[ERROR]", "[FATAL]"))]
        if outcome is not None:
            row["samples"] = outcome.trace.data.shape[0]
            if outcome.complete and outcome.summary is not None:
                row["status"] = "ok"
                summary = outcome.summary.as_dict()
                row.update({k: (None if v is None else float(v)) for k, v in summary.items()})
                E_in, E_fric = summary["E_in_J"], summary["E_fric_J"]
                row["fric_share_end"] = float(E_fric / E_in) if E_in and E_fric is not None else None
                row["warnings"] = "; ".join(outcome.warnings) or None
            else:
                row["reason"] = outcome.reason or "the run ended without a summary"
        if row["status"] == "failed" and messages:
            row["reason"] = f"{row['reason']} [FMU log: {' | '.join(messages[:3])}]"
    except Exception as error:  # noqa: BLE001 - even a failure of the bookkeeping is a row
        row["status"] = "failed"
        row["reason"] = " ".join(f"{type(error).__name__}: {error}".split())
    row["wall_s"] = time.perf_counter() - started
    return row


def crash_row(case: Case, fmu_sha256: str | None, reason: str) -> dict[str, Any]:
    """The row of a case whose worker could not report (a dead process, a lost Dask task)."""
    return {
        "case": case.index,
        "case_id": case.case_id,
        "variant": case.variant,
        **case.parameters,
        "status": "failed",
        "reason": reason,
        "warnings": None,
        **dict.fromkeys(METRICS),
        "samples": None,
        "wall_s": None,
        "host": socket.gethostname(),
        "fmu_sha256": fmu_sha256,
    }
