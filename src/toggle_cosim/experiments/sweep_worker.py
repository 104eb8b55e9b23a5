"""Sweep cases in a worker that keeps the plant loaded: a `CaseRunner` (in the sweep's process, or
in a Dask worker) drives a plant host (`cosim.isolation.plant_host`), a child process that unzips each FMU
and loads its binary once, then runs case after case on one instance of each component (the
plant, a controller FMU, a system's parts), kept by its FMU's SHA-256 and its name in the host's
pool (`cosim.execution.instance_pool`, `master.check_and_simulate(..., pool=)`) and reset between cases; after a
failed case the instances are freed and the next one gets new ones.
A case that crashes, aborts or hangs the host is a failed row with the reason (and how far it
got); the runner starts a new host for the next case. A case never sees what another left: the
same case gives the same numbers alone, first in a host, after a failed case or after a
complete one.

Each case is checked once, in the process that drives the host (`checked.check_run`, the
same check `master.check` makes: `check_case`), and sent to the host with the request,
pickled with its plant left out (`pack_checked`: the host has it); the host only instantiates
(from its pool) and steps what was checked (`check_and_simulate(..., checked=)`).

The host loads the FMU from a private copy (in its own folder, created 0700) of bytes whose
SHA-256 it has checked against the sweep's: a file changed, or swapped, after the sweep checked
it is never loaded. Every answer is a plain table row; nothing the case does raises here."""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import hashlib
import io
import os
import pickle
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from toggle_cosim.cosim.execution.instance_pool import InstancePool
from toggle_cosim.experiments.scenario import runs_from_document
from toggle_cosim.experiments.sweep_spec import METRICS, Case
from toggle_cosim.messages import bounded_text, error_text, said_in

if TYPE_CHECKING:
    from toggle_cosim.cosim.checked import CheckedRun

PEAK_RSS_KEY = "_peak_rss_mb"  # in a row from a worker: its peak RSS (not stored in the table)
RETIRED_KEY = "_host_retired"  # in a row from a plant host: its plant answered Fatal, the host has ended
COLUMNS_KEY = "_columns"  # in a request to a plant host: the case's trace columns, known to the runner
CHECKED_KEY = "_checked"  # in a request to a plant host: the case as the runner checked it (`pack_checked`)
LOG_LINES_KEPT, LOG_CHARS_KEPT = 2000, 2000  # what a case's captured FMU log keeps, at most
_capture = threading.local()
_workers = threading.local()  # a Dask worker thread's CaseRunner, kept from task to task
_plants: dict[str, Any] = {}  # SHA-256 -> the checked PlantInterface (this process)
_private: list[Path] = []  # this process's own folder for FMU copies (Dask workers)
_open_runners: list[Any] = []  # every CaseRunner of run_cases, closed when the process exits


class _ThreadLogTee:
    """sys.stdout stand-in: text printed by a thread that is capturing goes to its buffer (fmpy
    prints the FMU's log messages), everything else to the real stream. Safe with Dask threads."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        buffer = getattr(_capture, "buffer", None)
        if buffer is not None:
            if len(buffer) < LOG_LINES_KEPT:  # a case that prints without end keeps its first writes only
                buffer.append(text[:LOG_CHARS_KEPT])
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


def case_samples(payload: Mapping[str, Any]) -> int:
    """The samples of a case's trace: t = 0 .. t_end every T_s."""
    parameters = payload["parameters"]
    return int(round(parameters["t_end"] / parameters["T_s"])) + 1


def case_time_limit(payload: Mapping[str, Any], override: float | None = None) -> float:
    """--case-timeout, else the case's time_limit key, else the default from t_end (`supervision`)."""
    from toggle_cosim.cosim.isolation.supervision import default_time_limit

    if override is not None:
        return float(override)
    own = payload["document"].get("time_limit")
    return float(own) if own is not None else default_time_limit(payload["parameters"]["t_end"])


_columns: dict[tuple[str, str | None, str, tuple[str, ...]], tuple[str, ...]] = {}


SYSTEM_KEYS = ("components", "connections", "record")  # a scenario with any of them is a system


def case_columns(
    payload: Mapping[str, Any], plant: Any, time_limit: float | None = None, checked: CheckedRun | None = None
) -> tuple[str, ...]:
    """The trace columns of a case: time, the plant's outputs, the inputs and its controller's
    diagnostics (the built-in law's, or those a controller.python factory's controller or a
    controller FMU declares: that controller built and checked in a supervised child,
    `supervision.probe_columns`, once per controller setting in this process, which never runs
    the user's code itself). `checked`: the case as `check_case` checked it (its columns, when
    the check knows them; else handed to the probe, which then checks nothing again). Raises
    ControllerError when the controller cannot be built."""
    from toggle_cosim.cosim.master import trace_names

    if COLUMNS_KEY in payload:
        return tuple(payload[COLUMNS_KEY])
    controller_doc = payload["document"].get("controller") or {}
    inputs = tuple((payload["document"].get("plant") or {}).get("inputs") or {})  # the plant's other inputs
    system = {key: payload["document"][key] for key in SYSTEM_KEYS if key in payload["document"]}
    if "python" not in controller_doc and "fmu" not in controller_doc and not system:
        return trace_names(plant, inputs=inputs)
    source = payload.get("source")  # a system's columns are its recorded ports (`CheckedRun.names`)
    key = (repr(controller_doc), repr(_system_shape(system)), source, plant.sha256, inputs)
    if key not in _columns:
        if checked is not None and checked.complete:
            _columns[key] = checked.names
        else:
            from toggle_cosim.cosim.isolation.supervision import probe_columns

            run = checked.run if checked is not None else _case_run(payload)
            _columns[key] = probe_columns(run, plant, case_time_limit(payload, time_limit), checked=checked)
    return _columns[key]


def _case_run(payload: Mapping[str, Any]) -> Any:
    """The case's run, read from its document (the base scenario's folder: where its
    controller.python and FMUs are found)."""
    source = payload.get("source")
    (run,) = runs_from_document(copy.deepcopy(payload["document"]), Path(source) if source else None)
    return run


def check_case(payload: Mapping[str, Any], plant: Any) -> CheckedRun:
    """The case checked as `master.check` checks a run (`checked.check_run`: its controller,
    without running the user's code, its parts, connections, units, plan and signal table;
    nothing loaded), in the process that drives its host. Raises what `check_run` raises."""
    from toggle_cosim.cosim.checked import check_run

    return check_run(_case_run(payload), plant)


@dataclasses.dataclass(frozen=True)
class CheckedCase:
    """A case checked for its plant host (`checked_case`): its trace columns and its check,
    pickled for the host (`pack_checked`; None: the check refused the case, and the host, checking
    it as `simulate` does, fails it with that refusal)."""

    names: tuple[str, ...]
    packed: bytes | None


def checked_case(
    payload: Mapping[str, Any], plant: Any, time_limit: float | None = None, checked: CheckedRun | None = None
) -> CheckedCase:
    """The case checked once (`check_case`, unless `checked` is given), its columns and the check
    packed for its host. Raises ControllerError when a controller.python cannot be built to tell
    its columns (`case_columns`)."""
    if checked is None:
        try:
            checked = check_case(payload, plant)
        except Exception:  # noqa: BLE001 - the case's refusal: its host reports it as the case's row
            checked = None
    names = case_columns(payload, plant, time_limit, checked)
    return CheckedCase(names, None if checked is None else pack_checked(checked, plant))


class _PlantOut(pickle.Pickler):
    """A pickler that writes the plant (`plant`, by identity) as a reference, not its contents."""

    def __init__(self, stream: io.BytesIO, plant: Any) -> None:
        super().__init__(stream, protocol=pickle.HIGHEST_PROTOCOL)
        self.plant = plant

    def persistent_id(self, obj: Any) -> str | None:
        return "plant" if obj is self.plant else None


class _PlantIn(pickle.Unpickler):
    """An unpickler that puts `plant` where `_PlantOut` wrote the reference."""

    def __init__(self, stream: io.BytesIO, plant: Any) -> None:
        super().__init__(stream)
        self.plant = plant

    def persistent_load(self, pid: Any) -> Any:
        if pid != "plant":
            raise pickle.UnpicklingError(f"unknown reference {pid!r}")
        return self.plant


def pack_checked(checked: CheckedRun, plant: Any) -> bytes:
    """`checked` pickled for the plant host, with `plant` (the checked plant both sides hold) left
    out: its model description would cost more to send than the rest of the run."""
    stream = io.BytesIO()
    _PlantOut(stream, plant).dump(checked)
    return stream.getvalue()


def unpack_checked(data: bytes, plant: Any) -> CheckedRun:
    """The checked run `pack_checked` wrote, on `plant` (the host's: its private copy of the same
    FMU, by SHA-256), both as the run's plant and as its plant component's FMU."""
    return _PlantIn(io.BytesIO(data), plant).load()


def _system_shape(system: Mapping[str, Any]) -> dict[str, Any]:
    """A case's system keys without its components' values: what its trace columns depend on (its
    FMUs, connections and `record:`), so that a sweep over a component's parameter probes its
    columns once, not once a case."""
    components = system.get("components")
    if not isinstance(components, Mapping):
        return dict(system)
    return {
        **system,
        "components": {
            name: {k: v for k, v in part.items() if k != "parameters"} if isinstance(part, Mapping) else part
            for name, part in components.items()
        },
    }


def case_view(buffer: np.ndarray, rows: int, columns: int) -> np.ndarray | None:
    """The case's trace (rows x columns, C order) at the start of a host's buffer, or None when
    the buffer is too small for it."""
    if rows * columns > buffer.size:
        return None
    return buffer.reshape(-1)[: rows * columns].reshape(rows, columns)


def _empty_row(payload: Mapping[str, Any], fmu_sha256: str | None, reason: str | None = None) -> dict[str, Any]:
    return {
        "case": payload["index"],
        "case_id": payload["case_id"],
        "variant": payload["variant"],
        **payload["parameters"],
        "status": "failed",
        "reason": reason,
        "warnings": None,
        **dict.fromkeys(METRICS),
        "samples": None,
        "wall_s": None,
        "host": socket.gethostname(),
        "fmu_sha256": fmu_sha256,
    }


def crash_row(
    case: Case | Mapping[str, Any], fmu_sha256: str | None, reason: str, samples: int | None = None
) -> dict[str, Any]:
    """The row of a case whose worker could not report (a dead process, a time limit)."""
    row = _empty_row(case.payload() if isinstance(case, Case) else case, fmu_sha256, reason)
    row["samples"] = samples
    return row


def _private_folder() -> Path:
    """This process's own folder for FMU copies (mkdtemp: 0700, a fresh name no one else holds),
    named like a run folder so that `remove_stale_folders` removes it once the process is gone."""
    if not _private:
        import atexit
        import shutil

        from toggle_cosim.cosim.isolation.supervision import FOLDER_PREFIX

        folder = Path(tempfile.mkdtemp(prefix=f"{FOLDER_PREFIX}{os.getpid()}-"))
        atexit.register(shutil.rmtree, folder, True)
        _private.append(folder)
    return _private[0]


def _verified_bytes(path: Path, sha256: str) -> bytes:
    data = Path(path).read_bytes()
    found = hashlib.sha256(data).hexdigest()
    if found != sha256:
        raise ValueError(
            f"{path} has SHA-256 {found[:12]}, not the sweep's {sha256[:12]}: it changed after the sweep checked it"
        )
    return data


def _private_copy(data: bytes, folder: Path, name: str = "plant.fmu") -> Path:
    """`data` written to `folder`/`name`, readable by this user only (O_EXCL: never through a link)."""
    path = folder / name
    path.unlink(missing_ok=True)
    handle = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
    with os.fdopen(handle, "wb") as stream:
        stream.write(data)
    return path


def resolve_plant(fmu: str, sha256: str, data: bytes | None = None) -> Any:
    """The checked plant (a PlantInterface) of the sweep's FMU in this process: `fmu` if that file
    has the sweep's SHA-256, else `data` (the FMU's bytes the Dask backend sends along) checked
    against it and copied into this process's private folder. A different FMU at the same path
    (a stale build on another machine) is never used."""
    if sha256 in _plants:
        return _plants[sha256]
    from toggle_cosim.plant.contract import check_plant

    given = Path(fmu)
    try:
        _verified_bytes(given, sha256)
        path = given
    except (OSError, ValueError) as error:
        if data is None:
            detail = f"no file {given}" if isinstance(error, FileNotFoundError) else str(error)
            raise FileNotFoundError(
                f"the sweep's FMU (SHA-256 {sha256[:12]}) is not on this machine: {detail}"
            ) from None
        if hashlib.sha256(data).hexdigest() != sha256:
            raise ValueError(f"the FMU bytes received do not have the sweep's SHA-256 {sha256[:12]}") from None
        path = _private_copy(data, _private_folder(), f"plant-{sha256[:32]}.fmu")
    _plants[sha256] = dataclasses.replace(check_plant(path), sha256=sha256)
    return _plants[sha256]


class CaseServer:
    """The plant host's side (in the child): the plant loaded once, a case per request -> its row."""

    def __init__(self, plant: Any, fmu_sha256: str, calling: np.ndarray | None = None) -> None:
        self.plant = plant
        self.sha256 = fmu_sha256
        self.calling = calling  # shared with the sweep's side: which component a system's case calls
        self.loaded: Any = None  # the plant as the cases load it: from this host's private copy
        self.pool = InstancePool()  # every FMU component of a case, the plant's included, kept loaded
        self.retired = False  # the plant answered Fatal: this host serves no more (`plant_host`)

    def _loaded_plant(self) -> Any:
        """The plant the cases load (through the pool), made at the first case: the FMU's bytes
        checked against the sweep's SHA-256, copied into this host's own folder and loaded from
        there, so a file changed or swapped after the sweep checked it is never loaded."""
        if self.loaded is None:
            copy_path = _private_copy(
                _verified_bytes(self.plant.path, self.sha256), _private_folder(), f"host-{self.sha256[:32]}.fmu"
            )
            self.loaded = dataclasses.replace(self.plant, path=copy_path)
        return self.loaded

    def __call__(self, payload: Mapping[str, Any], buffer: np.ndarray, count: np.ndarray) -> dict[str, Any]:
        from toggle_cosim.cosim.master import check_and_simulate

        started = time.perf_counter()
        row = _empty_row(payload, self.sha256)
        count[0] = 0  # how far this case gets is what the parent reads if the host dies
        buffer.fill(np.nan)
        if self.calling is not None:
            self.calling[0] = 0
        try:
            with _captured_fmu_log() as log:
                view = None
                try:
                    plant = self._loaded_plant()
                    packed = payload.get(CHECKED_KEY)  # checked by the runner: nothing is checked here
                    checked = None if packed is None else unpack_checked(packed, plant)
                    # without it (a case its runner's check refused), the case as simulate checks it: the same refusal
                    run = checked.run if checked is not None else _case_run(payload)
                    view = case_view(buffer, run.steps + 1, len(case_columns(payload, self.plant)))
                    outcome = check_and_simulate(
                        run, plant, buffer=view, count=count, calling=self.calling, pool=self.pool, checked=checked
                    )
                except Exception as error:  # noqa: BLE001 - any failure is the case's result
                    outcome = None
                    row["reason"] = error_text(error)
            messages = [line.strip() for line in "".join(log).splitlines() if line.startswith(("[ERROR]", "[FATAL]"))]
            if outcome is not None:
                _fill_row(row, outcome)
                if view is not None:  # the samples written, as a supervised run counts them
                    from toggle_cosim.cosim.isolation.supervision import rows_recorded

                    row["samples"] = rows_recorded(count, view)
            if row["status"] == "failed" and row["reason"]:  # what the reason says already is not said twice
                messages = [m for m in messages if not said_in(m.split("] ", 1)[-1], row["reason"])]
            if row["status"] == "failed" and messages:
                row["reason"] = bounded_text(f"{row['reason']} [FMU log: {' | '.join(messages[:3])}]")
        except Exception as error:  # noqa: BLE001 - even a failure of the bookkeeping is a row
            row["status"] = "failed"
            row["reason"] = error_text(error)
        if self.pool.fatal:  # FMI: no further call to that binary
            self.retired = True
            row[RETIRED_KEY] = True
        row["wall_s"] = time.perf_counter() - started
        row[PEAK_RSS_KEY] = peak_rss_mb()
        return row


def peak_rss_mb() -> float:
    """This process's peak resident memory so far, in MB (not a table column: the manifest's)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _fill_row(row: dict[str, Any], outcome: Any) -> None:
    row["samples"] = outcome.trace.data.shape[0]
    if outcome.complete and outcome.summary is not None:
        row["status"] = "ok"
        summary = outcome.summary.as_dict()
        row.update({k: (None if v is None else float(v)) for k, v in summary.items()})
        E_in, E_fric = summary["E_in_J"], summary["E_fric_J"]
        row["fric_share_end"] = float(E_fric / E_in) if E_in and E_fric is not None else None
        row["warnings"] = "; ".join(outcome.warnings) or None  # plausibility flags (`cosim.plausibility`)
    else:
        row["reason"] = outcome.reason or "the run ended without a summary"


class CaseRunner:
    """A worker slot (the sweep's side): a plant host started when needed and replaced after a case
    that ends it, the case it runs, and that case's row once it is over (`service`)."""

    def __init__(
        self,
        plant: Any,
        fmu_sha256: str,
        *,
        rows: int = 1,
        time_limit: float | None = None,
        keep_traces: bool = False,
        scratch: Path | None = None,
    ) -> None:
        from toggle_cosim.cosim.master import trace_names

        self.plant = plant
        self.sha256 = fmu_sha256
        self.rows = rows
        self.columns = len(trace_names(plant))  # the built-in law's; a case with more gets a bigger host
        self.time_limit = time_limit
        self.keep_traces = keep_traces
        self.scratch = scratch
        self.host: Any = None
        self.calling: np.ndarray | None = None  # the host's word: which component a system's case calls
        self.payload: Mapping[str, Any] | None = None
        self.cases_run = 0  # by the current host
        self.hosts_started = 0

    @property
    def busy(self) -> bool:
        return self.payload is not None

    def _new_host(self, rows: int) -> Any:
        from toggle_cosim import interrupts
        from toggle_cosim.cosim.isolation.plant_host import PlantHost
        from toggle_cosim.cosim.isolation.supervision import shared_word

        self.close()
        self.calling = shared_word()  # shared with the host's child
        with interrupts.deferred():  # the host and its folder are known here before an interrupt acts
            server = CaseServer(self.plant, self.sha256, self.calling)
            self.host = PlantHost(server, max(rows, self.rows), self.columns, self.scratch)
            self.host.start()
        self.hosts_started += 1
        self.cases_run = 0
        return self.host

    def submit(self, payload: Mapping[str, Any], case: CheckedCase | None = None) -> None:
        """Start the case on this slot's host (a new one if there is none, it died idle, or its
        trace buffer is too small for this case); `case`: the case as the sweep checked it before
        (`checked_case`), else checked here, once."""
        rows = case_samples(payload)
        case = case if case is not None else checked_case(payload, self.plant, self.time_limit)
        names = case.names
        columns = len(names)
        limit = case_time_limit(payload, self.time_limit)
        request = {**payload, COLUMNS_KEY: names}  # the host never builds a controller to learn them
        if case.packed is not None:
            request[CHECKED_KEY] = case.packed  # nor checks the case again
        host = self.host
        small = host is not None and host.buffer.size < rows * columns
        if host is None or not host.alive or small or not host.submit(request, limit):
            self.columns = max(self.columns, columns)
            host = self._new_host(rows)
            if not host.submit(request, limit):
                raise RuntimeError("a new plant host died before its first case")
        self.payload = payload
        self.cases_run += 1

    def service(self, answer: Any) -> tuple[dict[str, Any], np.ndarray | None]:
        """The row (and, with keep_traces, the trace) of the case this slot ran, from the host's answer."""
        from toggle_cosim.cosim.isolation.exit_reasons import (
            controller_words,
            in_controller_reason,
            stopped_in_controller,
        )

        payload, self.payload = self.payload, None
        view = case_view(self.host.buffer, case_samples(payload), len(case_columns(payload, self.plant)))
        if answer.failure is None:
            row = answer.value
            trace = None
            if self.keep_traces and row.get("samples") and view is not None:
                trace = np.array(view[: row["samples"]])
            if row.pop(RETIRED_KEY, False):
                self.close()  # its plant answered Fatal and the host has ended: the next case gets a new one
            return row, trace
        rows = answer.rows  # the samples the case recorded, as its recorder counted them
        called = self._called(payload)
        self.close()  # a host that failed a case is gone (or dying): the next case gets a new one
        T_s = payload["parameters"]["T_s"]
        at = f" at t = {max(rows - 1, 0) * T_s:.6g} s" if rows else " before the first sample"
        if called is not None:  # a system's component was being called
            from toggle_cosim.cosim.isolation.exit_reasons import component_reason

            limited = answer.failure.startswith("time limit")
            return crash_row(payload, self.sha256, component_reason(answer.failure, called, at, limited), rows), None
        names = case_columns(payload, self.plant)
        controller = payload["document"].get("controller") or {}
        users = "python" in controller or "fmu" in controller  # the built-in law neither crashes nor hangs
        stopped = view is not None and stopped_in_controller(
            view, rows, len(self.plant.recorded_outputs), names, self.calling
        )
        if users and stopped:
            words = controller_words(controller.get("python"), controller.get("fmu"))
            limited = answer.failure.startswith("time limit")
            return crash_row(
                payload, self.sha256, in_controller_reason(answer.failure, words, rows * T_s, limited), rows
            ), None
        return crash_row(payload, self.sha256, f"{answer.failure}{at}", rows), None

    def _called(self, payload: Mapping[str, Any]) -> str | None:
        """The component a system's case was calling when its host ended, in words
        (`exit_reasons.component_words`); None for the plain pair (its controller is said in the
        pair's words, `exit_reasons.in_controller_reason`), or outside any call."""
        number = int(self.calling[0]) if self.calling is not None else 0
        if number <= 0:
            return None
        from toggle_cosim.cosim.isolation.exit_reasons import component_words
        from toggle_cosim.cosim.systems import component_names

        try:
            run = _case_run(payload)
        except Exception:  # noqa: BLE001 - a case that ran was read before: no words, the plain reason
            return None
        if run.system.is_pair:
            return None
        names = component_names(run.system)
        return component_words(run, self.plant.path, names[number - 1]) if number <= len(names) else None

    def close(self) -> None:
        """Stop the host and remove its folder; an interrupt meanwhile (say, one sent again after
        it was lost in a finalizer) waits until both are done."""
        from toggle_cosim import interrupts

        with interrupts.deferred():
            if self.host is not None:
                self.host.close()
                self.host = None


def run_cases(
    payloads: Sequence[Mapping[str, Any]],
    fmu: str,
    fmu_sha256: str,
    fmu_data: bytes | None = None,
    time_limit: float | None = None,
    keep_traces: bool = False,
) -> list[tuple[dict[str, Any], np.ndarray | None]]:
    """Run cases one after the other on this thread's plant host (kept from call to call: a Dask
    worker thread loads the plant once), each under its time limit; their rows (and traces)."""
    from toggle_cosim.cosim.isolation.plant_host import wait_for_hosts

    try:
        plant = resolve_plant(fmu, fmu_sha256, fmu_data)
    except Exception as error:  # noqa: BLE001 - the cases' result, not the worker's crash
        reason = " ".join(f"{type(error).__name__}: {error}".split())
        return [(crash_row(payload, fmu_sha256, reason), None) for payload in payloads]
    runner = getattr(_workers, "runner", None)
    key = (fmu_sha256, time_limit, keep_traces)
    if runner is None or getattr(_workers, "key", None) != key:
        if runner is not None:
            runner.close()
        runner = CaseRunner(plant, fmu_sha256, time_limit=time_limit, keep_traces=keep_traces)
        _workers.runner, _workers.key = runner, key
        if not _open_runners:
            import atexit

            atexit.register(_close_runners)
        _open_runners.append(runner)
    results = []
    for payload in payloads:
        try:
            runner.submit(payload)
        except Exception as error:  # noqa: BLE001 - e.g. its controller cannot be built here: the case fails
            results.append((crash_row(payload, fmu_sha256, " ".join(f"{type(error).__name__}: {error}".split())), None))
            continue
        while runner.busy:
            for _, answer in wait_for_hosts([runner.host]):
                results.append(runner.service(answer))
    return results


def _close_runners() -> None:
    for runner in _open_runners:
        with contextlib.suppress(Exception):
            runner.close()


def run_case(
    case: Mapping[str, Any],
    fmu: str,
    fmu_sha256: str,
    fmu_data: bytes | None = None,
    time_limit: float | None = None,
) -> dict[str, Any]:
    """Run one case (a payload of plain data) on the plant FMU at `fmu` (checked against
    `fmu_sha256`; `fmu_data`, the FMU's bytes, stand in where that file is missing or differs);
    return its table row. Never raises for a failure of the case: the row has status "failed"
    and the reason (a crash or hang of the plant, `time_limit` exceeded, ...)."""
    return run_cases([case], fmu, fmu_sha256, fmu_data, time_limit)[0][0]
