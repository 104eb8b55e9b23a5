"""A tuning from start to end (`toggle-cosim tune`, `tc.tune`).

1. The map of the starting controller: the tuning's map written as a sweep file
   (OUTPUT/start_sweep.yaml) and run by the sweep engine (`sweep_run.execute_sweep`, which checks
   the plant and the controller before any case), into OUTPUT/map_start/. Its score seeds the
   study when the starting values lie inside the bounds.
2. Trials in batches: an Optuna study (TPE, CMA-ES or random sampling) kept in OUTPUT/study.db
   (sqlite) asks `batch` points at a time; their cases (the map's, with the tuned keys set) run
   together on the sweep engine's backend (`sweep_exec.execute`: local plant hosts or a Dask
   cluster), and each trial's score (`tune_score`) is told back. An interrupted tuning leaves
   its batch's trials running in the study; the next call fails them and asks their points again.
3. The best feasible trial (one objective: the lowest; two: the Pareto front's lowest first
   objective) as a scenario file (OUTPUT/<name>_best.yaml), its map as a sweep file
   (OUTPUT/tuned_sweep.yaml) run by the sweep engine into OUTPUT/map_tuned/ (the tuned figures,
   re-run), the trial history (OUTPUT/trials.csv), a figure of both maps side by side and, with
   two objectives, the Pareto front (`analysis.tune_figures`), and OUTPUT/tune.json.
"""

from __future__ import annotations

import contextlib
import copy
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toggle_cosim import interrupts
from toggle_cosim.cosim.run_provenance import RECORD_NAME
from toggle_cosim.experiments.sweep_exec import connect, execute
from toggle_cosim.experiments.sweep_run import execute_sweep
from toggle_cosim.experiments.sweep_spec import SweepError, load_sweep
from toggle_cosim.experiments.tune_files import (
    TUNE_YAML,
    map_sweep,
    tuned_scenario,
    write_map_sweep,
    write_scenario,
)
from toggle_cosim.experiments.tune_score import Score, score, violations
from toggle_cosim.experiments.tune_spec import TuneError, Tuning
from toggle_cosim.experiments.tune_study import MANIFEST_FILE, fingerprint, open_study
from toggle_cosim.files.outputs import CSV, JSON, PNG, OutputError, check_destination, folder_lock
from toggle_cosim.provenance.srmd import SRMD

HISTORY_FILE = "trials.csv"
START_SWEEP, TUNED_SWEEP = "start_sweep.yaml", "tuned_sweep.yaml"
START_MAP, TUNED_MAP = "map_start", "map_tuned"
WAVES = (9, 3, 1)  # a trial's cases in three waves (`waves`)
_ORIGIN = "origin"  # a trial's user attribute: "start" (the starting values) or "optimiser"


@dataclass
class TuneResult:
    """What a tuning did and found (the figures are worst/mean per metric over the map)."""

    output: Path
    trials: int = 0  # trials of the optimiser finished in the study
    ran: int = 0  # trials finished by this call
    feasible: int = 0
    interrupted: bool = False
    wall_seconds: float = 0.0
    start: dict[str, Any] | None = None  # {"parameters", "objectives", "feasible", "figures"}
    best: dict[str, Any] | None = None  # the same for the best trial, and "trial"
    rerun: dict[str, Any] | None = None  # the tuned map re-run: "objectives", "feasible", "figures", "equal"
    files: list[Path] = field(default_factory=list)
    history: Any = None  # the trial history as a DataFrame (`tc.tune` reads OUTPUT/trials.csv into it)


def _distributions(tuning: Tuning) -> dict[str, Any]:
    from optuna.distributions import FloatDistribution

    return {p.key: FloatDistribution(p.low, p.high, log=p.log) for p in tuning.parameters}


def _sampler(tuning: Tuning, finished: int) -> Any:
    """The tuning's sampler, seeded with seed + the trials already in the study (a resumed study
    does not ask again the points it asked first)."""
    import optuna

    seed = tuning.seed + finished
    if tuning.sampler == "random":
        return optuna.samplers.RandomSampler(seed=seed)
    if tuning.sampler == "cmaes":
        start = {p.key: p.start for p in tuning.parameters if p.start is not None and p.low <= p.start <= p.high}
        x0 = start if len(start) == len(tuning.parameters) else None
        return optuna.samplers.CmaEsSampler(x0=x0, seed=seed, warn_independent_sampling=False)
    return optuna.samplers.TPESampler(
        seed=seed, multivariate=True, constant_liar=True, n_startup_trials=max(4, 2 * tuning.batch)
    )


def _check_outputs(tuning: Tuning, output: Path) -> None:
    """TuneError, before anything runs, when one of the files the tuning writes at the end could
    not be written there (a link, a folder, a file of another kind: `files.outputs`)."""
    files = [
        (MANIFEST_FILE, JSON),
        (RECORD_NAME, SRMD),
        (HISTORY_FILE, CSV),
        (START_SWEEP, TUNE_YAML),
        (TUNED_SWEEP, TUNE_YAML),
        (f"{tuning.name}_best.yaml", TUNE_YAML),
        ("maps.png", PNG),
        ("pareto.png", PNG),
    ]
    for name, kind in files:
        try:
            check_destination(output / name, "tuning's file", kind, fix="choose another --out (or move it away)")
        except OutputError as error:
            raise TuneError(str(error)) from None


def waves(cases: int) -> list[list[int]]:
    """The order a trial's cases run in: every WAVES[0]-th case of the map first, then the other
    every WAVES[1]-th, then the rest. A trial stops at the first wave after which a case has
    failed or broken a constraint: it is infeasible whatever the rest of the map gives."""
    seen: set[int] = set()
    result = []
    for stride in WAVES:
        wave = [k for k in range(0, cases, stride) if k not in seen]
        seen.update(wave)
        if wave:
            result.append(wave)
    return result


def _run_batch(
    tuning: Tuning, batches: list[list[Any]], run: Callable[[list[Any], Callable[..., None]], None]
) -> tuple[dict[str, dict[str, Any]], list[list[int] | None]]:
    """Run a batch of trials' cases wave by wave (`waves`), together, on the sweep engine (`run`):
    the rows by case_id, and each trial's case indices that ran (None: a Dask cluster lost some)."""
    rows: dict[str, dict[str, Any]] = {}

    def on_row(row: dict[str, Any], trace: Any = None) -> None:
        rows[row["case_id"]] = row

    ran: list[list[int] | None] = [[] for _ in batches]
    alive = list(range(len(batches)))
    for wave in waves(len(tuning.cases)):
        todo = {batches[i][k].case_id: batches[i][k] for i in alive for k in wave}
        run([case for key, case in todo.items() if key not in rows], on_row)
        still = []
        for i in alive:
            done = ran[i]
            if done is None or any(batches[i][k].case_id not in rows for k in wave):
                ran[i] = None  # a Dask cluster lost some of its cases: the trial is asked again
                continue
            done.extend(wave)
            if not _breaks(tuning, rows, batches[i], done):
                still.append(i)
        alive = still
    return rows, ran


def _breaks(tuning: Tuning, rows: dict[str, dict[str, Any]], cases: list[Any], indices: list[int]) -> bool:
    """Whether the cases `indices` of a trial (all with rows) already make it infeasible."""
    broken = violations(
        [rows[cases[k].case_id] for k in indices], [tuning.rated_currents[k] for k in indices], tuning.constraints
    )
    return any(broken.values())


def _attrs(result: Score) -> dict[str, Any]:
    return {
        "objectives": [None if math.isnan(v) else v for v in result.objectives],
        "feasible": result.feasible,
        "violations": result.violations,
        "figures": {k: (None if math.isnan(v) else v) for k, v in result.figures.items()},
    }


def _read_rows(table_path: Path) -> dict[str, dict[str, Any]]:
    from toggle_cosim.experiments.sweep_store import read_results

    table = read_results(table_path)
    table = table.astype(object).where(table.notna(), None)
    return {row["case_id"]: row for row in table.to_dict("records")}


def _run_map(
    tuning: Tuning, document: dict[str, Any], sweep_file: Path, folder: Path, fmu: Path | None, options: dict[str, Any]
) -> tuple[Score, Any, list[dict[str, Any]]]:
    """Write a map's sweep file and run it with the sweep engine: its score, its sweep, its rows."""
    write_map_sweep(
        sweep_file, document, f"written by toggle-cosim tune {tuning.path}\n  toggle-cosim sweep {sweep_file}"
    )
    sweep = load_sweep(sweep_file, folder)
    done = execute_sweep(sweep, fmu, **options)
    if done.interrupted:
        raise KeyboardInterrupt
    rows = _read_rows(done.results)
    missing = [c for c in sweep.cases if c.case_id not in rows]
    if missing:
        raise TuneError(f"{sweep_file}: {len(missing)} cases of the map were not run (a Dask cluster lost them)")
    ordered = [rows[c.case_id] for c in sweep.cases]
    return score(ordered, tuning.rated_currents, tuning.objectives, tuning.constraints), sweep, ordered


def execute_tuning(
    tuning: Tuning,
    fmu: Path | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
    case_timeout: float | None = None,
    trials: int | None = None,
) -> TuneResult:
    """Run the tuning (or go on with it: the study in OUTPUT is resumed) up to `trials` optimiser
    trials (default: the file's optimiser.trials), then write its files. TuneError: bad input."""
    say = log or (lambda text: print(text, file=sys.stderr, flush=True))
    output = tuning.output
    fresh = not output.exists()
    with folder_lock(output) as locked:
        if not locked:
            raise TuneError(f"{output}: another tuning is writing to this folder (wait for it or choose another --out)")
        try:
            return _execute(
                tuning, output, fmu, scheduler, workers, progress, say, case_timeout, trials or tuning.trials
            )
        except (TuneError, SweepError):
            if fresh:  # bad input found before any trial (the plant, a controller): nothing is left behind
                import shutil

                shutil.rmtree(output, ignore_errors=True)
            raise


def _execute(
    tuning: Tuning,
    output: Path,
    fmu: Path | None,
    scheduler: str | None,
    workers: int | None,
    progress: bool,
    say: Callable[[str], None],
    case_timeout: float | None,
    budget: int,
) -> TuneResult:
    import optuna

    started = time.perf_counter()
    result = TuneResult(output=output)
    chosen = fmu if fmu is not None else tuning.sweep.fmu
    options = {"scheduler": scheduler, "workers": workers, "progress": False, "log": say, "case_timeout": case_timeout}
    _check_outputs(tuning, output)
    study = open_study(tuning, output)
    # 1. the starting controller's map, by the sweep engine (it checks the plant and the controller first)
    start_doc = map_sweep(tuning, output, f"{tuning.name}_start", chosen)
    start_score, start_sweep, _ = _run_map(tuning, start_doc, output / START_SWEEP, output / START_MAP, chosen, options)
    start_point = {p.key: p.start for p in tuning.parameters}
    result.start = {"parameters": start_point, **_attrs(start_score)}
    distributions = _distributions(tuning)
    if not study.trials and all(
        p.start is not None and p.low <= p.start <= p.high for p in tuning.parameters
    ):  # the starting values, as trial 0
        study.add_trial(
            optuna.trial.create_trial(
                params=start_point,
                distributions=distributions,
                values=start_score.told,
                user_attrs={_ORIGIN: "start", **_attrs(start_score)},
            )
        )
    # 2. the trials of an interrupted batch: failed, their points asked again first
    for stale in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        study.tell(stale.number, state=optuna.trial.TrialState.FAIL)
        study.enqueue_trial(stale.params)
    plant_path = Path(chosen).resolve()
    from toggle_cosim.plant.contract import check_plant

    plant = check_plant(plant_path)

    def optimiser_trials() -> int:
        states = (optuna.trial.TrialState.COMPLETE,)
        return sum(1 for t in study.get_trials(deepcopy=False, states=states) if t.user_attrs.get(_ORIGIN) != "start")

    done_before = optimiser_trials()
    bar = None
    if progress and done_before < budget:
        from tqdm import tqdm

        bar = tqdm(total=budget, initial=done_before, file=sys.stderr, unit="trial", dynamic_ncols=True)
        bar.set_description(tuning.name)
    sampler = _sampler(tuning, len(study.trials))
    study.sampler = sampler
    stalled = 0

    client = connect(scheduler) if scheduler else None  # one connection for every wave of every batch

    def run(cases: list[Any], on_row: Callable[[dict[str, Any], Any], None]) -> None:
        execute(cases, plant_path, None, workers, on_row, plant.sha256, client, case_timeout, plant=plant)

    try:
        while (done := optimiser_trials()) < budget and stalled < 3:
            asked = [study.ask(distributions) for _ in range(min(tuning.batch, budget - done))]
            for trial in asked:
                trial.set_user_attr(_ORIGIN, "optimiser")
            batches = [tuning.trial_cases(dict(trial.params)) for trial in asked]
            rows, ran = _run_batch(tuning, batches, run)
            progressed = False
            for index, (trial, cases) in enumerate(zip(asked, batches, strict=True)):
                indices = sorted(ran[index] or [])
                if not indices:  # a Dask cluster lost some of its cases: asked again later
                    study.tell(trial, state=optuna.trial.TrialState.FAIL)
                    study.enqueue_trial(trial.params)
                    continue
                trial_score = score(
                    [rows[cases[k].case_id] for k in indices],
                    [tuning.rated_currents[k] for k in indices],
                    tuning.objectives,
                    tuning.constraints,
                )
                for key, value in _attrs(trial_score).items():
                    trial.set_user_attr(key, value)
                study.tell(trial, trial_score.told)
                result.ran += 1
                progressed = True
                if bar is not None:
                    bar.update(1)
            stalled = 0 if progressed else stalled + 1
            if bar is not None:
                best = _best(study, tuning)
                if best is not None:
                    bar.set_postfix_str(
                        ", ".join(
                            f"{o.label} {v:.4g}"
                            for o, v in zip(tuning.objectives, best.user_attrs["objectives"], strict=True)
                        )
                    )
    except BaseException as error:
        if not interrupts.is_interrupt(error):
            raise
        result.interrupted = True
        interrupts.ignore()  # the tuning is ending: what follows is writing its history
    finally:
        if bar is not None:
            bar.close()
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()
    if stalled >= 3:
        say("warning: three batches in a row lost cases on the Dask cluster; stopped (run again to go on)")
    result.trials = optimiser_trials()
    result.wall_seconds = time.perf_counter() - started
    with interrupts.deferred():
        result.files.append(_write_history(study, tuning, output))
    best = _best(study, tuning)
    result.feasible = sum(1 for t in _complete(study) if t.user_attrs.get("feasible"))
    if best is not None:
        result.best = {
            "trial": best.number,
            "parameters": dict(best.params),
            **{k: best.user_attrs[k] for k in ("objectives", "feasible", "violations", "figures")},
        }
    if result.interrupted or best is None:
        _write_manifest(tuning, result, plant, say)
        return result
    # 3. the best trial as a scenario, its map re-run by the sweep engine, the figures
    scenario_path = output / f"{tuning.name}_best.yaml"
    result.files.append(
        write_scenario(
            scenario_path,
            tuned_scenario(tuning, dict(best.params), output),
            f"written by toggle-cosim tune {tuning.path} (trial {best.number})\n"
            f"  toggle-cosim run {scenario_path}\n  toggle-cosim sweep {output / TUNED_SWEEP}",
        )
    )
    tuned_doc = map_sweep(tuning, output, f"{tuning.name}_tuned", chosen, dict(best.params))
    try:
        rerun, _, _ = _run_map(tuning, tuned_doc, output / TUNED_SWEEP, output / TUNED_MAP, chosen, options)
    except BaseException as error:
        if not interrupts.is_interrupt(error):
            raise
        result.interrupted = True
        _write_manifest(tuning, result, plant, say)
        return result
    result.files.extend([output / TUNED_SWEEP, output / TUNED_MAP])
    result.rerun = {**_attrs(rerun), "equal": _attrs(rerun)["objectives"] == result.best["objectives"]}
    from toggle_cosim.analysis.tune_figures import write_maps_side_by_side, write_pareto

    figures: list[tuple[Path, Callable[[], Path]]] = []
    if start_sweep.heatmap is not None:  # a map over two axes (a one-axis sweep has no heat maps)
        maps = [o.metric for o in tuning.objectives]
        figures.append(
            (
                output / "maps.png",
                lambda: write_maps_side_by_side(
                    output / START_MAP / "results.parquet",
                    output / TUNED_MAP / "results.parquet",
                    start_sweep,
                    maps,
                    output / "maps.png",
                    tuning.name,
                ),
            )
        )
    if len(tuning.objectives) == 2:
        figures.append(
            (output / "pareto.png", lambda: write_pareto(_history(study, tuning), tuning, output / "pareto.png"))
        )
    with interrupts.deferred():
        for path, draw in figures:
            try:
                result.files.append(draw())
            except Exception as error:  # a figure never loses the tuning's results: tune.json is written
                say(f"warning: {path}: figure not written ({' '.join(str(error).split())})")
    _write_manifest(tuning, result, plant, say)
    return result


def _complete(study: Any) -> list[Any]:
    import optuna

    return study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))


def _best(study: Any, tuning: Tuning) -> Any:
    """The best feasible trial: the lowest objective; with two, the lowest first objective of the
    Pareto front (which holds it)."""
    feasible = [t for t in _complete(study) if t.user_attrs.get("feasible")]
    if not feasible:
        return None
    return min(feasible, key=lambda t: (t.user_attrs["objectives"], t.number))


def pareto_front(points: list[tuple[float, float]]) -> list[bool]:
    """Which of `points` no other point dominates (lower or equal in both, lower in one)."""
    front = []
    for i, (a, b) in enumerate(points):
        dominated = any((c <= a and d <= b and (c < a or d < b)) for j, (c, d) in enumerate(points) if j != i)
        front.append(not dominated)
    return front


def _history(study: Any, tuning: Tuning) -> Any:
    """The trial history as a DataFrame: one row per trial with its state, origin, parameters,
    objectives, feasibility, violations and every metric's worst and mean over the map."""
    import pandas as pd

    records = []
    for trial in study.get_trials(deepcopy=False):
        attrs = trial.user_attrs
        record: dict[str, Any] = {
            "trial": trial.number,
            "state": trial.state.name.lower(),
            "origin": attrs.get(_ORIGIN, "optimiser"),
        }
        for p in tuning.parameters:
            record[p.key] = trial.params.get(p.key)
        for objective, value in zip(tuning.objectives, attrs.get("objectives") or [None] * 2, strict=False):
            record[objective.label] = value
        record["feasible"] = attrs.get("feasible")
        for name, count in (attrs.get("violations") or {}).items():
            record[f"violations_{name}"] = count
        record.update(attrs.get("figures") or {})
        record["duration_s"] = trial.duration.total_seconds() if trial.duration is not None else None
        records.append(record)
    table = pd.DataFrame.from_records(records)
    if len(tuning.objectives) == 2 and not table.empty:
        labels = [o.label for o in tuning.objectives]
        table["pareto"] = False
        mask = (table["state"] == "complete") & (table["feasible"] == True)  # noqa: E712 - a column
        chosen = table[mask]
        if not chosen.empty:
            front = pareto_front([tuple(map(float, r)) for r in chosen[labels].to_numpy()])
            table.loc[chosen.index, "pareto"] = front
    return table


def _write_history(study: Any, tuning: Tuning, output: Path) -> Path:
    from toggle_cosim.files.outputs import CSV, write_file

    table = _history(study, tuning)
    return write_file(
        output / HISTORY_FILE, lambda stream: table.to_csv(stream, index=False), what="trial history", kind=CSV
    )


def _write_manifest(tuning: Tuning, result: TuneResult, plant: Any, say: Callable[[str], None]) -> None:
    """tune.json, and the tuning's provenance record (`study_provenance`): the tuning file, its
    sweep file, every file of its cases, the plant; its trial history as the data."""
    from toggle_cosim.cosim.run_provenance import UsedFile
    from toggle_cosim.experiments.study_provenance import write_study_record
    from toggle_cosim.files.traces import write_json

    sha = plant.sha256
    with interrupts.deferred():
        write_study_record(
            result.output,
            tuning.name,
            (UsedFile(tuning.path, "testcase", "tuning"), UsedFile(tuning.sweep.path, "testcase", "sweep")),
            tuning.cases,
            tuning.sweep.base,
            plant.path,
            result.output / HISTORY_FILE,
            say,
        )
        write_json(
            result.output / MANIFEST_FILE,
            {
                "tuning": tuning.name,
                "fingerprint": fingerprint(tuning),
                "tuning_file": str(tuning.path),
                "sweep_file": str(tuning.sweep.path),
                "cases": len(tuning.cases),
                "sampler": tuning.sampler,
                "objectives": [o.label for o in tuning.objectives],
                "constraints": copy.deepcopy(tuning.constraints.__dict__),
                "fmu_sha256": sha,
                "trials": result.trials,
                "ran": result.ran,
                "feasible": result.feasible,
                "interrupted": result.interrupted,
                "wall_s": result.wall_seconds,
                "start": result.start,
                "best": result.best,
                "rerun": result.rerun,
                "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            },
        )


def run_tuning(
    tuning_path: Path,
    *,
    output: Path | None = None,
    fmu: Path | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: bool = True,
    case_timeout: float | None = None,
    trials: int | None = None,
) -> int:
    """`toggle-cosim tune TUNE.yaml`. Exit status: 0 a feasible best found (its files written),
    1 no feasible trial, 2 bad input (one `error: ...` line), 130 interrupted (run again to go on)."""
    from toggle_cosim.experiments.sweep_run import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK
    from toggle_cosim.experiments.tune_spec import load_tuning

    try:
        tuning = load_tuning(Path(tuning_path), output)
        result = execute_tuning(tuning, fmu, scheduler, workers, progress, None, case_timeout, trials)
    except (TuneError, SweepError) as error:
        print(f"error: {' '.join(str(error).split())}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print(report(tuning, result))
    if result.interrupted:
        print(
            f"interrupted: {result.trials} of {trials or tuning.trials} trials done; run again to go on",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    return EXIT_OK if result.best is not None else EXIT_FAILED


def _figures_line(label: str, record: dict[str, Any] | None, tuning: Tuning) -> str:
    if record is None:
        return f"{label}: none"
    figures = record["figures"]
    cases = int(figures["cases"])
    parts = [
        f"settled {int(figures['settled'])}/{cases}",
        f"worst settling {figures['worst_settling_time']:.4g} s" if figures["worst_settling_time"] is not None else "",
        f"worst |final error| {figures['worst_final_error'] * 1e3:.4g} mm"
        if figures["worst_final_error"] is not None
        else "",
        f"peak |i_q*| {figures['worst_peak_command']:.4g} A" if figures["worst_peak_command"] is not None else "",
        "feasible"
        if record["feasible"]
        else "infeasible (" + ", ".join(f"{k} {v}" for k, v in record["violations"].items() if v) + ")",
    ]
    values = ", ".join(f"{k} = {v:.6g}" for k, v in record.get("parameters", {}).items() if v is not None)
    return f"{label}{' (' + values + ')' if values else ''}: " + ", ".join(p for p in parts if p)


def report(tuning: Tuning, result: TuneResult) -> str:
    """The lines `toggle-cosim tune` prints: the start, the best, the re-run, the files."""
    lines = [
        f"tune {tuning.name}: {result.trials} trials ({result.ran} run now, {result.feasible} feasible) over "
        f"{len(tuning.cases)} cases in {result.wall_seconds:.1f} s",
        _figures_line("start", result.start, tuning),
        _figures_line(f"best (trial {result.best['trial']})" if result.best else "best", result.best, tuning),
    ]
    if result.rerun is not None:
        verdict = "the same figures" if result.rerun["equal"] else "DIFFERENT figures"
        lines.append(_figures_line(f"re-run by the sweep engine ({verdict})", result.rerun, tuning))
    lines.extend(f"wrote {path}" for path in result.files)
    return "\n".join(lines)
