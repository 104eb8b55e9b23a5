"""A sweep from start to end: check the plant once, run the cases not done yet on the chosen
backend, record each as it finishes, then write the table, the heat maps and `sweep.json`.

    from toggle_cosim.experiments.sweep_run import run_sweep
    run_sweep(Path("scenarios/sweep_FE_mB.yaml"), output=Path("out/sweeps/sweep_FE_mB"))

Exit status of `run_sweep`: 0 every case ok, 1 some case failed (or a Dask cluster lost some: they
are "not run", and a re-run does them), 2 bad input (one `error: ...` line on stderr, nothing
run), 130 interrupted (finished cases are kept; run again to finish)."""

from __future__ import annotations

import contextlib
import copy
import os
import platform
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toggle_cosim import interrupts
from toggle_cosim.analysis.sweep_heatmaps import write_heatmaps
from toggle_cosim.cosim.run_provenance import UsedFile
from toggle_cosim.experiments.scenario import runs_from_document
from toggle_cosim.experiments.study_provenance import write_study_record
from toggle_cosim.experiments.sweep_exec import connect, execute
from toggle_cosim.experiments.sweep_spec import Sweep, SweepError, load_sweep, split_key
from toggle_cosim.experiments.sweep_store import RESULTS_FILE, TRACES_DIR, ResultStore, batch_rows
from toggle_cosim.experiments.sweep_worker import PEAK_RSS_KEY, CheckedCase, case_columns, checked_case, peak_rss_mb
from toggle_cosim.files.outputs import folder_lock

MANIFEST_FILE = "sweep.json"
KEPT_CHECKS_BYTES = 64 << 20  # the cases checked before the sweep starts, kept for their hosts (pickled), at most
MIN_ADDRESS_SPACE = 2 << 30  # bytes: pandas, pyarrow and matplotlib with their threads map about 1.6 GB
EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130


@dataclass
class SweepResult:
    total: int
    skipped: int  # finished by an earlier run
    ran: int = 0  # finished by this run
    done: int = 0  # cases in the final table
    failed: int = 0  # failed cases in the final table
    interrupted: bool = False
    lost: int = 0  # cases a Dask cluster lost (not run)
    lost_reason: str = ""
    wall_seconds: float = 0.0
    started_at: float | None = None  # the Unix time the cases started running
    worker_peak_rss_mb: float = 0.0  # the largest peak RSS a worker reported
    results: Path | None = None
    figures: list[Path] = field(default_factory=list)

    @property
    def rate(self) -> float:
        return self.ran / self.wall_seconds if self.wall_seconds > 0 else 0.0


@contextlib.contextmanager
def _exclusive(folder: Path) -> Iterator[None]:
    """One sweep at a time per output folder (a lock on the folder itself: no lock file)."""
    with folder_lock(folder) as locked:
        if not locked:
            raise SweepError(
                f"{folder}: another sweep is writing to this folder (wait for it or choose another output:)"
            )
        yield


def check_address_space() -> None:
    """Refuse, before any import that could fail half-way, an address-space limit (`ulimit -v`)
    too small for a sweep: under it pyarrow and matplotlib fail to load or hang."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):  # pragma: no cover - not POSIX
        return
    if soft != resource.RLIM_INFINITY and soft < MIN_ADDRESS_SPACE:
        raise SweepError(
            f"the address-space limit (ulimit -v) is {soft >> 20} MiB; a sweep needs at least "
            f"{MIN_ADDRESS_SPACE >> 20} MiB (pandas, pyarrow, matplotlib and their threads): raise it"
        )


def _resolve_plant(
    sweep: Sweep, fmu: Path | None, keep_traces: bool = False, case_timeout: float | None = None
) -> tuple[Path, Any, dict[str, CheckedCase]]:
    """The sweep's plant FMU, checked with its axes and cases before any case runs: its path, the
    checked plant, and the cases checked here (one per setting, `KEPT_CHECKS_BYTES` of them at
    most), by case id, for their hosts."""
    from toggle_cosim.plant.contract import ContractError, check_plant

    chosen = fmu if fmu is not None else sweep.fmu
    if chosen is None:
        raise SweepError(
            f"{sweep.path}: no fmu: key here or in the base scenario, and no --fmu option (name the plant FMU)"
        )
    chosen = Path(chosen).resolve()
    from toggle_cosim.plant.probe import ProbeError, probe_binary

    try:
        plant = check_plant(chosen)
        probe_binary(plant)
    except (ContractError, ProbeError) as error:
        raise SweepError(str(error)) from error
    for key in sweep.axes:
        path = split_key(key)
        if path[:2] == ["plant", "parameters"] and path[2] not in plant.references:
            raise SweepError(f"{sweep.path}: axis {key}: the plant FMU has no variable {path[2]!r}")
    firsts = {
        case.variant: case for case in reversed(sweep.cases)
    }.values()  # every case of a variant sets the same keys
    names = {name for case in firsts for name in (case.document.get("plant", {}).get("parameters") or {})}
    for name in sorted(names):
        if name not in plant.references:
            raise SweepError(f"{sweep.base}: key plant.parameters.{name}: the plant FMU has no variable {name!r}")
    from toggle_cosim.cosim.master import trace_names
    from toggle_cosim.experiments.resources import max_output
    from toggle_cosim.plant.settings import SettingError, check_settings

    if sweep.cases:  # each case's trace buffer (8 bytes a value while it runs) within the output limit
        biggest = max(sweep.cases, key=lambda c: c.parameters["t_end"] / c.parameters["T_s"])
        samples = int(round(biggest.parameters["t_end"] / biggest.parameters["T_s"])) + 1
        size = samples * len(trace_names(plant)) * 8
        if size > max_output():
            raise SweepError(
                f"{sweep.path}: case {biggest.index} would hold {samples} samples x {len(trace_names(plant))}"
                f" columns, about {size / 1e9:.2f} GB while it runs, over the {max_output() / 1e9:.2f} GB"
                " output limit; raise T_s or shorten t_end (or raise TOGGLE_COSIM_MAX_OUTPUT)"
            )
    if keep_traces and sweep.cases:  # every case's trace, stored
        columns = len(trace_names(plant))
        samples = sum(int(round(c.parameters["t_end"] / c.parameters["T_s"])) + 1 for c in sweep.cases)
        size = samples * columns * 8
        if size > max_output():
            raise SweepError(
                f"{sweep.path}: --keep-traces would store {len(sweep.cases)} traces, {samples} samples x {columns}"
                f" columns, about {size / 1e9:.2f} GB before compression, over the {max_output() / 1e9:.2f} GB"
                " output limit; sweep fewer cases, raise T_s, shorten t_end or raise TOGGLE_COSIM_MAX_OUTPUT"
            )
    from toggle_cosim.control.protocol import ControllerError
    from toggle_cosim.cosim.checked import SystemError_, check_run

    seen = set()
    kept: dict[str, CheckedCase] = {}  # case id -> the case checked, for its host
    kept_bytes = 0
    # the axes that change the plant (all but F_E and m_B) or the controller: a variant and their
    # values make one setting, checked before any case runs
    setting = [key for key in sweep.axes if _sets_plant_or_controller(key)]
    for case in sweep.cases:
        key = (case.variant, *((type(case.values[name]), case.values[name]) for name in setting))
        if key in seen:
            continue
        seen.add(key)
        (run,) = runs_from_document(copy.deepcopy(case.document), sweep.base)  # validated by load_sweep already
        try:
            check_settings(run, plant)
            # the case as the master checks it: its controller without running the user's code, its
            # parts, connections, units and order; nothing loaded. Kept for its host, which then
            # checks it no more (`execute`), within KEPT_CHECKS_BYTES
            checked = check_run(run, plant)
            # a controller.python's columns: built and checked once in a supervised child
            # (`supervision.probe_columns`), never in this process; kept for the cases
            prepared = checked_case(case.payload(), plant, case_timeout, checked)
            columns = prepared.names
            if kept_bytes + len(prepared.packed or b"") <= KEPT_CHECKS_BYTES:
                kept[case.case_id] = prepared
                kept_bytes += len(prepared.packed or b"")
            if keep_traces and run.plant.inputs:
                raise SweepError(
                    f"{sweep.path}: case {case.index}: --keep-traces stores one trace table with the built-in "
                    f"law's columns, and this case also records the plant inputs {', '.join(run.plant.inputs)} "
                    "(plant.inputs); sweep it without --keep-traces (its table row is kept)"
                )
            if not checked.pair:  # a system's kept traces: its recorded ports, the same in every case
                if keep_traces and columns != case_columns(sweep.cases[0].payload(), plant, case_timeout):
                    raise SweepError(
                        f"{sweep.path}: case {case.index}: --keep-traces stores one trace table, and this case "
                        f"records other columns than case 0 ({', '.join(columns[1:4])}, ...); sweep it without "
                        "--keep-traces (its table row is kept)"
                    )
            elif keep_traces and columns != trace_names(plant):
                raise SweepError(
                    f"{sweep.path}: case {case.index}: --keep-traces stores one trace table with the built-in "
                    "law's columns, and this case's controller records other diagnostics; sweep it without "
                    "--keep-traces (its table row is kept) or give the controller the diagnostics S, phase, e"
                )
        except (SettingError, ControllerError, SystemError_) as error:
            raise SweepError(f"{sweep.path}: case {case.index}: {error}") from error
    return chosen, plant, kept


def execute_sweep(
    sweep: Sweep,
    fmu: Path | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    retry_failed: bool = False,
    log: Callable[[str], None] | None = None,
    case_timeout: float | None = None,
    keep_traces: bool = False,
) -> SweepResult:
    """Run the cases of `sweep` that are not done yet, write the table and the heat maps (and,
    with `keep_traces`, every case's trace into OUTPUT/traces/)."""
    say = log or (lambda text: print(text, file=sys.stderr, flush=True))
    check_address_space()
    if workers is not None and workers < 1:
        raise SweepError(f"--workers {workers}: give at least 1")
    if scheduler and workers is not None:
        raise SweepError(
            "--workers sets the local pool's size; with --scheduler the Dask cluster's workers run the cases"
        )
    from toggle_cosim import limits

    try:
        if case_timeout is not None:
            limits.seconds(case_timeout, "--case-timeout")
        limits.check_environment()  # before any case: a bad number must not surface in a worker
    except limits.LimitError as error:
        raise SweepError(str(error)) from None
    try:
        rows_per_batch = batch_rows()
    except ValueError as error:
        raise SweepError(str(error)) from error
    fmu_path, plant, checked = _resolve_plant(sweep, fmu, keep_traces, case_timeout)
    from toggle_cosim.cosim.isolation.supervision import remove_stale_folders

    remove_stale_folders()  # the run folders commands killed by SIGKILL left in the temporary directory
    client = connect(scheduler) if scheduler else None  # before anything is written
    try:
        return _execute_sweep(
            sweep,
            fmu_path,
            plant,
            scheduler,
            client,
            workers,
            progress,
            retry_failed,
            say,
            case_timeout,
            keep_traces,
            rows_per_batch,
            checked,
        )
    finally:
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()


def _execute_sweep(
    sweep: Sweep,
    fmu_path: Path,
    plant: Any,
    scheduler: str | None,
    client: Any,
    workers: int | None,
    progress: bool,
    retry_failed: bool,
    say: Callable[[str], None],
    case_timeout: float | None = None,
    keep_traces: bool = False,
    rows_per_batch: int | None = None,
    checked: dict[str, CheckedCase] | None = None,
) -> SweepResult:
    from toggle_cosim.cosim.master import trace_names

    sha = plant.sha256
    with _exclusive(sweep.output):
        columns = case_columns(sweep.cases[0].payload(), plant) if sweep.cases else trace_names(plant)
        store = ResultStore(sweep, keep_traces=keep_traces, trace_columns=columns, batch_rows=rows_per_batch)
        store.load(sha)
        if store.unreadable:
            say(f"warning: unreadable result files, their cases run again: {', '.join(store.unreadable[:5])}")
        if retry_failed:
            store.forget_failed()
        untraced = set()
        if keep_traces:  # a finished case whose trace is not stored (an earlier run without --keep-traces) runs again
            traced = store.traced()
            untraced = {c for c, ok in store.done.items() if ok and c not in traced}
        todo = [c for c in sweep.cases if c.case_id not in store.done or c.case_id in untraced]
        if keep_traces:
            store.drop_traces(c.case_id for c in todo)
        result = SweepResult(total=len(sweep.cases), skipped=len(sweep.cases) - len(todo))
        other_fmu = len(store.other_fmu & store.done.keys())
        backend = (
            f"Dask scheduler {scheduler}" if scheduler else f"local process pool, {workers or os.cpu_count()} workers"
        )
        say(
            f"sweep {sweep.name}: {result.total} cases; skipped {result.skipped} already done; "
            f"running {len(todo)} on the {backend}"
        )
        if untraced:
            say(f"--keep-traces: {len(untraced)} finished cases have no stored trace; they run again to store it")
        if other_fmu:
            say(
                f"warning: {other_fmu} finished cases were computed with a different FMU; "
                f"delete {sweep.output} to recompute them with this one"
            )
        failed_now = 0
        bar = None
        if progress and todo:
            from tqdm import tqdm

            bar = tqdm(
                total=len(todo),
                file=sys.stderr,
                unit="case",
                dynamic_ncols=True,
                desc=sweep.name,
                mininterval=0.2 if sys.stderr.isatty() else 5.0,
            )
        run_started = time.perf_counter()
        result.started_at = time.time()

        def on_row(row: dict[str, Any], trace: Any = None) -> None:
            nonlocal failed_now
            result.worker_peak_rss_mb = max(result.worker_peak_rss_mb, row.pop(PEAK_RSS_KEY, 0.0) or 0.0)
            with interrupts.deferred():  # a batch file is whole or not there
                store.add(row, trace)
                result.ran += 1
            if row["status"] != "ok":
                failed_now += 1
            if bar is not None:
                rate = result.ran / max(time.perf_counter() - run_started, 1e-9)
                bar.set_postfix_str(f"done {result.ran}, failed {failed_now}, {rate:.1f} cases/s", refresh=False)
                bar.update(1)

        try:
            loss = execute(
                todo, fmu_path, scheduler, workers, on_row, sha, client, case_timeout, keep_traces, plant, checked
            )
            result.lost = loss.cases
            if loss.cases:
                result.lost_reason = loss.reasons[0] if loss.reasons else "unknown"
        except BaseException as error:
            if not interrupts.is_interrupt(error):
                raise
            result.interrupted = True
            interrupts.ignore()  # the sweep is ending: what follows is writing its table
        finally:
            result.wall_seconds = time.perf_counter() - run_started
            if bar is not None:
                bar.close()
            with interrupts.deferred():
                result.results = store.consolidate()
        result.done = len(store.done)
        result.failed = sum(1 for ok in store.done.values() if not ok)
        if not result.interrupted:  # matplotlib only when there is time for it
            try:
                result.figures = write_heatmaps(result.results, sweep, warn=say)
            except BaseException as error:
                if not interrupts.is_interrupt(error):
                    if not isinstance(error, Exception):
                        raise
                    # the table is whole and sweep.json is still written: a figure never loses the results
                    say(f"warning: {sweep.output}: heat maps not written ({' '.join(str(error).split())})")
                else:
                    result.interrupted = True  # the table is whole; the maps come with the next run
                    interrupts.ignore()
        try:
            with interrupts.deferred():
                _write_manifest(sweep, result, fmu_path, sha, scheduler, workers)
        except KeyboardInterrupt:  # it came while sweep.json was written: the run ends interrupted, and says so
            result.interrupted = True
            interrupts.ignore()
            _write_manifest(sweep, result, fmu_path, sha, scheduler, workers)
        with interrupts.deferred():
            write_study_record(
                sweep.output,
                sweep.name,
                (UsedFile(sweep.path, "testcase", "sweep"),),
                sweep.cases,
                sweep.base,
                fmu_path,
                result.results if result.results is not None and Path(result.results).is_file() else None,
                say,
            )
    return result


def _sets_plant_or_controller(key: str) -> bool:
    """Whether an axis key lies in the plant's settings other than F_E and m_B, or the controller's."""
    path = split_key(key)
    return path[0] == "controller" or (path[0] == "plant" and len(path) > 1 and path[1] not in ("F_E", "m_B"))


def _write_manifest(
    sweep: Sweep, result: SweepResult, fmu: Path, sha: str, scheduler: str | None, workers: int | None
) -> None:
    from toggle_cosim.files.traces import write_json

    write_json(
        sweep.output / MANIFEST_FILE,
        {
            "sweep": sweep.name,
            "sweep_file": str(sweep.path),
            "base": str(sweep.base),
            "mode": sweep.mode,
            "axes": sweep.axes,
            "variants": sweep.variants,
            "cases": result.total,
            "fmu": {"path": str(fmu), "sha256": sha},
            "last_run": {
                "skipped": result.skipped,
                "ran": result.ran,
                "failed_in_table": result.failed,
                "done_in_table": result.done,
                "interrupted": result.interrupted,
                "started_at_unix": result.started_at,
                "wall_s": result.wall_seconds,
                "cases_per_s": result.rate,
                "peak_rss_mb": {"sweep": peak_rss_mb(), "worker": result.worker_peak_rss_mb},
                "backend": f"dask:{scheduler}" if scheduler else f"pool:{workers or os.cpu_count()}",
                "host": platform.node(),
                "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            },
            "results": RESULTS_FILE,
            "traces": TRACES_DIR if (sweep.output / TRACES_DIR).is_dir() else None,
            "heatmaps": [str(p.relative_to(sweep.output)) for p in result.figures],
        },
    )


def run_sweep(
    sweep_path: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    fmu: Path | None = None,
    *,
    output: Path | None = None,
    retry_failed: bool = False,
    progress: bool = True,
    case_timeout: float | None = None,
    keep_traces: bool = False,
) -> int:
    """`toggle-cosim sweep SWEEP.yaml [--scheduler ADDRESS] [--workers N] [--fmu PATH] [--keep-traces]`.

    Exit status: 0 every case ok, 1 some case failed, 2 bad input (one `error: ...` line on
    stderr, nothing run), 130 interrupted (finished cases are kept; run again to finish)."""
    try:
        check_address_space()
        sweep = load_sweep(Path(sweep_path), output)
        result = execute_sweep(
            sweep,
            fmu,
            scheduler,
            workers,
            progress=progress,
            retry_failed=retry_failed,
            case_timeout=case_timeout,
            keep_traces=keep_traces,
        )
    except SweepError as error:
        print(f"error: {' '.join(str(error).split())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (MemoryError, ImportError) as error:  # a memory limit met while loading a library
        detail = " ".join(f"{type(error).__name__}: {error}".split())
        print(f"error: not enough memory for the sweep ({detail}); raise the memory limit", file=sys.stderr)
        return EXIT_BAD_INPUT
    ok = result.done - result.failed
    print(
        f"sweep {sweep.name}: ran {result.ran} cases in {result.wall_seconds:.1f} s ({result.rate:.1f} cases/s), "
        f"skipped {result.skipped} already done; table: {ok} ok, {result.failed} failed, "
        f"{result.total - result.done} not run, of {result.total} cases"
    )
    print(f"wrote {result.results}")
    for figure in result.figures:
        print(f"wrote {figure}")
    if result.lost and not result.interrupted:
        print(
            f"warning: the Dask cluster lost {result.lost} cases (a worker or the scheduler went away: "
            f"{result.lost_reason}); they are not run: run the same command again to run them",
            file=sys.stderr,
        )
    if result.interrupted:
        print(
            f"interrupted: {result.done} of {result.total} cases done; run the same command again to finish",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    return EXIT_FAILED if result.failed or result.lost else EXIT_OK
