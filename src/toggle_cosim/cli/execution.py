"""What the run commands share: loading and checking runs before any starts, running them
supervised (several at once, `cosim.isolation.supervised_batch`) or in-process, writing each run's files
in order, the per-run line, and the --jobs and --time-limit options."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import click

from toggle_cosim import interrupts
from toggle_cosim.cli.app import InputError, RunFailed


def load_runs(  # noqa: ANN201
    scenarios: Sequence[Path],
    fmu: Path | None,
    built: Sequence = (),  # noqa: ANN001
    coupling: str | None = None,
):
    """The (run, plant, checked) triples of the scenario files and of the runs `built` already
    (an SSP's, with their own plant), each checked before any run starts (`checked`: the check,
    `cosim.checked.check_run`, that the run then uses: a run is checked once); `coupling`: each
    run's coupling instead of its own (--coupling)."""
    from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
    from toggle_cosim.plant.contract import ContractError, check_plant
    from toggle_cosim.plant.probe import ProbeError, probe_binary

    runs = []
    named: dict[str, Path] = {}  # scenario name -> the file that gave it: its runs' folder OUT/<name>/
    own = {id(run) for run in built}  # runs whose plant is their own: --fmu does not apply
    grouped: dict[Path, list] = {}
    for run in built:
        grouped.setdefault(run.source, []).append(run)
    sources = [(path, None) for path in scenarios] + list(grouped.items())
    for path, given in sources:
        try:
            loaded = load_scenario(path) if given is None else given
        except ScenarioError as error:
            raise InputError(str(error)) from error
        for name in dict.fromkeys(run.scenario for run in loaded):
            if name in named:
                both = "is given twice" if Path(named[name]).resolve() == Path(path).resolve() else f"and {path}"
                raise InputError(
                    f"{named[name]} {both}: both name the scenario {name!r}, so their runs would write the same "
                    f"folders; give each scenario file its own name: key (or the file once)"
                )
            named[name] = path
        runs.extend(loaded)
    plants = {}
    for run in runs:
        chosen = fmu if fmu is not None and id(run) not in own else run.fmu
        if chosen is None:
            raise InputError(f"{run.source}: no fmu: key and no --fmu option (name the plant FMU)")
        chosen = chosen.resolve()
        if chosen not in plants:
            try:
                plants[chosen] = check_plant(chosen)
                probe_binary(plants[chosen])
            except (ContractError, ProbeError) as error:
                raise InputError(str(error)) from error
            for note in plants[chosen].contract_notes():  # absent optional outputs, missing units
                click.echo(note, err=True)
    pairs = [
        (
            run if coupling is None else dataclasses.replace(run, coupling=coupling),
            plants[(fmu if fmu is not None and id(run) not in own else run.fmu).resolve()],
        )
        for run in runs
    ]
    from toggle_cosim.control.protocol import ControllerError
    from toggle_cosim.cosim.checked import SystemError_, check_run
    from toggle_cosim.cosim.isolation.supervision import probe_columns
    from toggle_cosim.plant.settings import SettingError, check_settings

    noted: set[str] = set()
    triples = []
    for run, plant in pairs:  # every name and value the run sets, and its controller, before any run starts
        try:
            check_settings(run, plant)
            # the run as the master checks it: the controller (a user's without running its code, which
            # runs in the run's child alone), the parts, connections, units and order; nothing loaded
            checked = check_run(run, plant)
            if checked.builds_controller and run.controller.error is not None:
                # a python-control system: built and checked in a supervised child, as a sweep's
                # controllers are, so a system the run cannot take (continuous-time, another dt,
                # other inputs) is refused before any run
                probe_columns(run, plant, checked=checked)
        except (SettingError, ControllerError, SystemError_) as error:
            raise InputError(f"{run.source or run.label}: {error}") from error
        fmu = getattr(checked.controller, "fmu", None)  # a controller FMU's contract, as checked
        for warning in getattr(fmu, "warnings", ()):  # a controller FMU's missing units, once per file
            if f"{fmu.path}: {warning}" not in noted:
                noted.add(f"{fmu.path}: {warning}")
                click.echo(f"{fmu.path}: warning: {warning}", err=True)
        triples.append((run, plant, checked))
    return triples


def _write_outcome(outcome, out: Path, plant=None) -> tuple[Path, bool]:  # noqa: ANN001
    """Write the run's trace.csv, run.json and provenance record (`cosim.run_provenance`) into
    OUT/`Run.folder`; the folder, and whether an earlier run's files there were replaced."""
    from toggle_cosim.files.naming import naming
    from toggle_cosim.files.traces import write_csv, write_json

    folder = out / outcome.run.folder
    replaced = (folder / "run.json").is_file() or (folder / "trace.csv").is_file()
    with interrupts.deferred():  # the files whole, or an interrupt waits for them
        with naming(folder / "trace.csv"):  # a full disk names the file it could not write
            write_csv(folder / "trace.csv", outcome.trace, every=int(outcome.run.resolved.get("record_every", 1)))
        with naming(folder / "run.json"):
            write_json(folder / "run.json", outcome.record)
        _write_provenance(outcome, folder, plant)
    return folder, replaced


def _write_provenance(outcome, folder: Path, plant) -> None:  # noqa: ANN001
    """The run's provenance record in `folder`; a file that cannot be hashed (removed or changed
    into a FIFO meanwhile) gives a warning line and no record, never a failed run."""
    from toggle_cosim.cosim.run_provenance import RECORD_NAME, record_of, tools
    from toggle_cosim.files.naming import naming
    from toggle_cosim.provenance.srmd import write_record

    description = getattr(plant, "model_description", None)
    try:
        record = record_of(
            outcome.run,
            Path(outcome.record["fmu"]["path"]),
            folder,
            tools(),
            getattr(description, "generationTool", None),
        )
    except OSError as error:
        click.echo(f"{folder / RECORD_NAME}: warning: not written: {error.filename}: {error.strerror}", err=True)
        return
    with naming(folder / RECORD_NAME):
        write_record(folder / RECORD_NAME, record)


def check_folders(pairs, out: Path) -> None:  # noqa: ANN001
    """Before any run: no two runs write the same folder (`runs.definition.results_folder`: one
    per source and setting), and their trace.csv and run.json may be written there (the output
    rule of `files.outputs`: only a CSV table and a JSON object of an earlier run are replaced)."""
    from toggle_cosim.cli.app import check_output
    from toggle_cosim.cosim.run_provenance import RECORD_NAME
    from toggle_cosim.files.outputs import CSV, JSON
    from toggle_cosim.provenance.srmd import SRMD

    seen: dict = {}
    for run, *_ in pairs:
        if run.folder in seen:
            other = seen[run.folder]
            raise InputError(
                f"{other.source or other.label} and {run.source or run.label}: both runs would write "
                f"{Path(out) / run.folder}; run them into different --out folders"
            )
        seen[run.folder] = run
        folder = Path(out) / run.folder
        try:
            exists = folder.is_dir()
        except OSError:  # e.g. a name too long: check_runs reports the output folder in one line
            exists = False
        if exists:  # a folder that is not one (an output folder that is a file) is check_runs' to report
            check_output(folder / "trace.csv", "trace", CSV)
            check_output(folder / "run.json", "run record", JSON)
            check_output(folder / RECORD_NAME, "provenance record", SRMD)


def _status_text(outcome) -> str:  # noqa: ANN001
    if outcome.complete:
        count = len(outcome.warnings)
        return f"complete with {count} warning{'s' if count > 1 else ''}" if count else "complete"
    return f"{'INTERRUPTED' if outcome.interrupted else 'FAILED'} ({outcome.reason})"


def _simulate(run, plant, time_limit: float | None, progress=None, checked=None):  # noqa: ANN001, ANN202
    """One run, supervised (`supervision`); TOGGLE_COSIM_SUPERVISE=0 runs it in this process
    instead (for the benchmark's comparison and for debugging: no time limit, no crash guard;
    the working directory is restored after it, whatever the plant did with it). `checked`: the
    run as `load_runs` checked it (None: checked now)."""
    if not _supervised():
        from toggle_cosim.cosim.isolation.supervision import in_process_folder
        from toggle_cosim.cosim.master import check_and_simulate

        here = os.open(".", os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        try:
            with in_process_folder():  # the unzipped FMUs: removed after, or by the next command after a crash
                return check_and_simulate(run, plant, progress, checked=checked)
        finally:  # a plant that changed directory must not move the relative paths that follow
            with contextlib.suppress(OSError):
                os.fchdir(here)
            os.close(here)
    from toggle_cosim.cosim.isolation.supervision import simulate_supervised

    return simulate_supervised(run, plant, time_limit=time_limit, progress=progress, checked=checked)


def _supervised() -> bool:
    return os.environ.get("TOGGLE_COSIM_SUPERVISE", "1") != "0"


def _jobs_for(jobs: int | None, runs: int) -> int:
    """--jobs, else one run per core (supervised runs only: in-process runs go one by one)."""
    if not _supervised():
        return 1
    if jobs is not None:
        return max(1, min(jobs, runs))
    from toggle_cosim.cosim.isolation.supervised_batch import default_jobs

    return default_jobs(runs)


def outcomes_of(pairs, out: Path | None, quiet: bool, time_limit: float | None, jobs: int | None):  # noqa: ANN001, ANN202
    """Each pair's outcome (a (run, plant) pair, or a triple of `load_runs` with its check), in
    order, once the checks before any run have passed (`check_runs`: the sizes, the output
    folder `out` if files are written there, the scratch space). Several
    at once (`supervised_batch`) with more than one job (--jobs, else one per core); one by one
    otherwise, with a progress bar per run on a terminal unless quiet."""
    from toggle_cosim.cosim.isolation.supervision import remove_stale_folders
    from toggle_cosim.experiments.resources import check_runs

    jobs = _jobs_for(jobs, len(pairs))
    remove_stale_folders()  # what commands killed by SIGKILL left, before the scratch space is counted
    check_runs(pairs, out, jobs)
    if jobs > 1:
        from toggle_cosim.cosim.isolation.supervised_batch import run_supervised

        yield from run_supervised(pairs, jobs=jobs, time_limit=time_limit)
        return
    for number, (run, plant, *checked) in enumerate(pairs, start=1):
        if quiet or not sys.stderr.isatty():
            yield _simulate(run, plant, time_limit, checked=next(iter(checked), None))
            continue
        with click.progressbar(length=1000, label=f"[{number}/{len(pairs)}] {run.label}", file=sys.stderr) as bar:
            done = [0]

            def progress(fraction: float, bar=bar, done=done) -> None:  # noqa: ANN001
                step = int(fraction * 1000) - done[0]
                if step > 0:
                    bar.update(step)
                    done[0] += step

            outcome = _simulate(run, plant, time_limit, progress, next(iter(checked), None))
        yield outcome


def execute_runs(  # noqa: ANN201
    pairs,  # noqa: ANN001
    out: Path,
    quiet: bool,
    time_limit: float | None = None,
    on_written=None,  # noqa: ANN001
    jobs=None,  # noqa: ANN001
    keep_traces: bool = False,
) -> list:
    """Run each (run, plant) pair supervised (up to `jobs` at once), write its files in order,
    print a line; `on_written(outcome)` after each run's files are written. The outcomes come
    back detached from their runs' buffers (`RunOutcome.detached`): with their traces in memory
    if `keep_traces`, else without them, so that any number of runs holds no descriptor or
    scratch space once written."""
    target = Path(out).absolute()  # before any plant runs: one that changes directory must not move it
    check_folders(pairs, out)
    plants = {run.folder: plant for run, plant, *_ in pairs}
    outcomes = []
    with contextlib.closing(outcomes_of(pairs, out, quiet, time_limit, jobs)) as results:
        for number, outcome in enumerate(results, start=1):
            label = f"[{number}/{len(pairs)}] {outcome.run.label}"
            written, replaced = _write_outcome(outcome, target, plants.get(outcome.run.folder))
            folder = Path(out) / written.relative_to(target)  # as the user named it
            s = outcome.summary
            detail = (
                f"final error {s.final_error_m * 1e3:+.4f} mm, peak |i_q*| {s.peak_iq_ref_A:.1f} A"
                + (f", T_h {s.hitting_time_s:.4f} s" if s.hitting_time_s is not None else "")
                if s and s.final_error_m is not None
                else "no summary"
            )
            click.echo(
                f"{label}: {_status_text(outcome)}; {detail}; RTF {outcome.record['real_time_factor']:.0f}; -> {folder}"
                + (" (replaced the earlier run's files there)" if replaced else "")
            )
            for warning in outcome.warnings:  # plausibility flags (`cosim.plausibility`)
                click.echo(f"{label}: warning: {warning}")
            if on_written is not None:
                on_written(outcome)
            outcome = outcome.detached(keep_traces)  # the buffer goes with the last view of it
            outcomes.append(outcome)
            if outcome.interrupted:
                click.echo(
                    f"interrupted: {label} written as interrupted; {len(pairs) - number} later run(s) not written",
                    err=True,
                )
                raise KeyboardInterrupt
    return outcomes


SUMMARY_RUNS = 5  # the failed runs the closing line names; each run's line and run.json say the rest


def raise_if_failed(outcomes) -> None:  # noqa: ANN001
    """RunFailed naming the failed runs (the first SUMMARY_RUNS, each reason bounded), if any."""
    from toggle_cosim.messages import bounded_text

    failed = [f"{o.run.label} ({bounded_text(o.reason or '', 200)})" for o in outcomes if not o.complete]
    if failed:
        more = f"; and {len(failed) - SUMMARY_RUNS} more (each run's line and run.json say why)"
        named = "; ".join(failed[:SUMMARY_RUNS]) + (more if len(failed) > SUMMARY_RUNS else "")
        raise RunFailed(f"{len(failed)} run(s) failed: {named}")


def report_options(default_out: Path) -> Callable:
    """--out (default `default_out`), --junit and --summary: where a check writes its reports."""

    def apply(command: Callable) -> Callable:
        for option in reversed(
            (
                click.option(
                    "--out",
                    type=click.Path(path_type=Path),
                    default=default_out,
                    show_default=True,
                    help="Folder for the reports: junit.xml, summary.md, plots of failing variables.",
                ),
                click.option(
                    "--junit",
                    type=click.Path(path_type=Path),
                    default=None,
                    help="JUnit XML report (default: OUT/junit.xml).",
                ),
                click.option(
                    "--summary",
                    type=click.Path(path_type=Path),
                    default=None,
                    help="Markdown summary (default: OUT/summary.md).",
                ),
            )
        ):
            command = option(command)
        return command

    return apply


JOBS_OPTION = click.option(
    "--jobs",
    "-j",
    type=click.IntRange(min=1),
    default=None,
    metavar="N",
    help="Runs at once, each in its own process (default: one per core). With more than one, progress "
    "is a line per run as it is written (in order), not a bar; the traces are the same.",
)


class Seconds(click.ParamType):
    """A wall-clock limit in seconds, checked by `limits.seconds` (finite, positive, bounded)."""

    name = "seconds"

    def convert(self, value, param, ctx):  # noqa: ANN001, ANN201 - click's signature
        from toggle_cosim import limits

        try:
            return limits.seconds(value, f"--{param.name.replace('_', '-')}" if param else "value")
        except limits.LimitError as error:
            self.fail(str(error), param, ctx)


TIME_LIMIT_OPTION = click.option(
    "--time-limit",
    type=Seconds(),
    default=None,
    metavar="SECONDS",
    help="Wall-clock limit per run (default: the scenario's time_limit key, else max(30 s, 20 x t_end)).",
)


# The options a sweep and a tuning share: how their cases run (`sweep`, `tune`).
SCHEDULER_OPTION = click.option(
    "--scheduler", default=None, metavar="ADDRESS", help="Dask distributed scheduler (default: a local process pool)."
)
WORKERS_OPTION = click.option("--workers", type=int, default=None, help="Local pool size (default: all cores).")
FMU_OPTION = click.option(
    "--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (overrides the fmu: keys)."
)
CASE_TIMEOUT_OPTION = click.option(
    "--case-timeout",
    type=Seconds(),
    default=None,
    metavar="SECONDS",
    help="Wall-clock limit per case (default: the time_limit key, else max(30 s, 20 x t_end)).",
)
QUIET_OPTION = click.option("--quiet", "-q", is_flag=True, help="No progress bar.")


def check_report_outputs(out: Path, junit: Path | None, summary: Path | None) -> None:
    """The reports' destinations (`report_options`) checked before any work: InputError (one line)
    for a JUnit or Markdown file that may not be written, or an --out that is not a folder."""
    from toggle_cosim.cli.app import check_output
    from toggle_cosim.files.outputs import JUNIT, MARKDOWN

    check_output(junit, "JUnit report", JUNIT)
    check_output(summary, "Markdown summary", MARKDOWN)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory; give a folder for the reports (--out)")
