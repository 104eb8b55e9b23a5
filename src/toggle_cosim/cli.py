"""Command line: `toggle-cosim build | run | plot | paper`.

The only module that knows about files, exit codes and progress display. Exit status:
0 success, 1 a run or comparison failed, 2 bad input (nothing is written then), 130 interrupted.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from toggle_cosim import interrupts

if __name__ == "__main__" or Path(sys.argv[0]).name == "toggle-cosim":
    interrupts.install_for_start_up()  # before the heavy imports: an interrupt at start-up exits 130 too

import click  # noqa: E402

from toggle_cosim import __version__  # noqa: E402

DEFAULT_SOURCE = Path("modelica/ToggleLSM")
DEFAULT_MODEL = "ToggleLSM.Plant"
DEFAULT_FMU = Path("fmus/ToggleLSM.fmu")
DEFAULT_OUT = Path("out")
DEFAULT_REFERENCES = Path("scenarios/references")
PAPER_SCENARIOS = ("fig4_nominal", "fig5_external_force", "fig6_mass_variation")
# What `toggle-cosim build` writes when no --model is given: every shipped plant.
DEFAULT_BUILDS = (
    (DEFAULT_MODEL, DEFAULT_FMU),
    ("ToggleLSM.PlantNoGravity", Path("fmus/ToggleLSM_NoGravity.fmu")),
)
SHIPPED_SCENARIOS = (*PAPER_SCENARIOS, "swap_no_gravity", "integral_load", "friction_models")


class InputError(click.ClickException):
    """Bad input: one line on stderr, exit status 2."""

    exit_code = 2

    def show(self, file=None) -> None:  # noqa: ANN001 - click's signature
        click.echo(f"error: {self.message}", err=True)


class RunFailed(click.ClickException):
    exit_code = 1

    def show(self, file=None) -> None:  # noqa: ANN001
        click.echo(f"failed: {self.message}", err=True)


class _Commands(click.Group):
    """The command group, with one exit-status policy: 0 success, 1 a run or comparison failed,
    2 bad input (one line), 130 interrupted (SIGINT or SIGTERM, at any moment; no traceback)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):  # noqa: ANN001, ANN201
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        old_handlers = interrupts.install()
        try:
            try:
                result = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
            except SystemExit:
                interrupts.ignore()  # done: a signal during the interpreter's teardown changes nothing
                raise
            interrupts.ignore()
        except (KeyboardInterrupt, click.exceptions.Abort):
            interrupts.ignore()
            click.echo("interrupted (exit 130): finished runs are kept; run the command again for the rest", err=True)
            interrupts.exit_interrupted()
        except click.UsageError as error:  # one line, like every other bad input
            interrupts.ignore()  # the work is over: from here the process only ends
            command = error.ctx.command_path if error.ctx is not None else "toggle-cosim"
            click.echo(f"error: {' '.join(error.format_message().split())} (see '{command} --help')", err=True)
            sys.exit(2)
        except click.ClickException as error:
            interrupts.ignore()  # the work is over: from here the process only ends
            error.show()
            sys.exit(error.exit_code)
        except click.exceptions.Exit as error:
            interrupts.ignore()  # the work is over: from here the process only ends
            sys.exit(error.exit_code)
        except SystemExit:
            raise
        except OSError as error:  # a file system problem found late (e.g. a disk that filled up): one line
            interrupts.ignore()  # the work is over: from here the process only ends
            if interrupts.is_interrupt(error):
                interrupts.exit_interrupted()
            where = f"{error.filename}: " if error.filename else ""
            click.echo(
                f"error: {where}{error.strerror or error} (check the path, its permissions and free space)", err=True
            )
            sys.exit(2)
        except BaseException as error:
            interrupts.ignore()
            if not interrupts.is_interrupt(error):  # e.g. a SystemError from a C call the signal landed in
                raise
            click.echo("interrupted (exit 130): finished runs are kept; run the command again for the rest", err=True)
            interrupts.exit_interrupted()
        finally:
            if not interrupts.running_as_program():
                interrupts.restore(old_handlers)  # in-process (tests): give the caller its handlers back
        sys.exit(result if isinstance(result, int) else 0)


@click.group(cls=_Commands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="toggle-cosim")
def main() -> None:
    """Co-simulation of the PMLSM-driven toggle mechanism (Fung, Wu and Chen 2001)."""


def project_root() -> Path:
    """The project this command runs in: the nearest folder up from here with a pyproject.toml."""
    here = Path.cwd().resolve()
    for folder in (here, *here.parents):
        if (folder / "pyproject.toml").is_file():
            return folder
    return here


def _project_of(source: Path) -> Path:
    """The project a Modelica source belongs to: the nearest folder up from it with a
    pyproject.toml (whatever the current folder is); a one-line refusal if there is none."""
    resolved = source.resolve()
    for folder in (resolved, *resolved.parents):
        if (folder / "pyproject.toml").is_file():
            return folder
    raise InputError(
        f"{source}: the Modelica source lies in no project (no pyproject.toml above it); "
        "the build only reads and writes inside a project"
    )


def _inside_project(path: Path, what: str, option: str, root: Path | None = None) -> Path:
    """`path`, resolved, if it lies inside the project; else a one-line refusal."""
    root = root or project_root()
    resolved = path.resolve()
    if not resolved.is_relative_to(root):
        raise InputError(
            f"{path}: the {what} lies outside the project {root}; the build only reads and writes "
            f"inside it (give a path under it with {option})"
        )
    return resolved


def _build(source: Path, model: str, output: Path, fmi_version: str = "2.0", interfaces: str = "both") -> None:
    from toggle_cosim.fmu_export import FMUBuildError, ModelCompileError, build_fmu

    root = _project_of(source)
    source = _inside_project(source, "Modelica source", "--source", root)
    output = _inside_project(output, "FMU output", "--out", root)
    if output.suffix != ".fmu":
        raise InputError(f"{output}: an FMU file name must end in .fmu (fix --out)")
    try:
        report = build_fmu(source, model, output, fmi_version=fmi_version, interfaces=interfaces)
    except (ModelCompileError, FMUBuildError) as error:
        raise InputError(str(error).splitlines()[0]) from error
    click.echo(
        f"built {report.fmu.path} (FMI {report.fmu.fmi_version} {' + '.join(sorted(report.fmu.interfaces))}, "
        f"{report.fmu.size_bytes / 1024:.0f} KiB, GUID {report.fmu.guid}): "
        f"{report.variables} variables, {report.states} states, {report.event_indicators} event indicators; "
        f"compile {report.compile_seconds:.1f} s, C build and zip {report.package_seconds:.1f} s"
    )


@main.command()
@click.option(
    "--source",
    type=click.Path(path_type=Path),
    default=DEFAULT_SOURCE,
    show_default=True,
    help="Modelica package directory (or a .mo file).",
)
@click.option("--model", default=None, help=f"Class to compile (default: every shipped plant, {DEFAULT_MODEL} first).")
@click.option(
    "--out",
    "-o",
    "output",
    type=click.Path(path_type=Path),
    default=None,
    help=f"FMU file to write (default: {DEFAULT_FMU} for {DEFAULT_MODEL}).",
)
@click.option(
    "--fmi-version",
    type=click.Choice(["2.0", "3.0"]),
    default="2.0",
    show_default=True,
    help="FMI version of the FMU(s); 3.0 FMUs get a '3' after their default file name.",
)
@click.option(
    "--interfaces",
    type=click.Choice(["both", "cs", "me"]),
    default="both",
    show_default=True,
    help="Interface types the FMU offers: Co-Simulation and Model Exchange in one FMU, or one of them.",
)
def build(source: Path, model: str | None, output: Path | None, fmi_version: str, interfaces: str) -> None:
    """Compile the Modelica source into FMI 2.0 or 3.0 FMUs (Co-Simulation and/or Model Exchange)."""
    suffix = "3" if fmi_version == "3.0" else ""
    if model is None and output is not None:
        model = DEFAULT_MODEL
    if model is None:
        for name, path in DEFAULT_BUILDS:
            _build(source, name, path.with_name(f"{path.stem}{suffix}.fmu"), fmi_version, interfaces)
        return
    default = dict(DEFAULT_BUILDS).get(model, Path("fmus") / f"{model.split('.')[-1]}.fmu")
    _build(source, model, output or default.with_name(f"{default.stem}{suffix}.fmu"), fmi_version, interfaces)


def _load_runs(scenarios: Sequence[Path], fmu: Path | None):  # noqa: ANN202
    from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
    from toggle_cosim.plant.contract import ContractError, check_plant
    from toggle_cosim.plant.probe import ProbeError, probe_binary

    runs = []
    for path in scenarios:
        try:
            runs.extend(load_scenario(path))
        except ScenarioError as error:
            raise InputError(str(error)) from error
    plants = {}
    for run in runs:
        chosen = fmu if fmu is not None else run.fmu
        if chosen is None:
            raise InputError(f"{run.source}: no fmu: key and no --fmu option (name the plant FMU)")
        chosen = chosen.resolve()
        if chosen not in plants:
            try:
                plants[chosen] = check_plant(chosen)
                probe_binary(plants[chosen])
            except (ContractError, ProbeError) as error:
                raise InputError(str(error)) from error
    pairs = [(run, plants[(fmu if fmu is not None else run.fmu).resolve()]) for run in runs]
    from toggle_cosim.plant.settings import SettingError, check_settings

    for run, plant in pairs:  # every name and value the run sets, before any run starts
        try:
            check_settings(run, plant)
        except SettingError as error:
            raise InputError(f"{run.source or run.label}: {error}") from error
    return pairs


def _write_outcome(outcome, out: Path) -> Path:  # noqa: ANN001
    from toggle_cosim.files.traces import write_csv, write_json

    folder = out / outcome.run.scenario / (outcome.run.variant or "run")
    with interrupts.deferred():  # both files whole, or an interrupt waits for them
        write_csv(folder / "trace.csv", outcome.trace, every=int(outcome.run.resolved.get("record_every", 1)))
        write_json(folder / "run.json", outcome.record)
    return folder


def _status_text(outcome) -> str:  # noqa: ANN001
    if outcome.complete:
        return "complete"
    return f"{'INTERRUPTED' if outcome.interrupted else 'FAILED'} ({outcome.reason})"


def _simulate(run, plant, time_limit: float | None, progress=None, scratch: Path | None = None):  # noqa: ANN001, ANN202
    """One run, supervised (`supervision`); TOGGLE_COSIM_SUPERVISE=0 runs it in this process
    instead (for the benchmark's comparison and for debugging: no time limit, no crash guard)."""
    if not _supervised():
        from toggle_cosim.cosim.master import simulate

        return simulate(run, plant, progress)
    from toggle_cosim.cosim.supervision import simulate_supervised

    return simulate_supervised(run, plant, time_limit=time_limit, progress=progress, scratch=scratch)


def _supervised() -> bool:
    return os.environ.get("TOGGLE_COSIM_SUPERVISE", "1") != "0"


def _jobs(jobs: int | None, runs: int) -> int:
    """--jobs, else one run per core (supervised runs only: in-process runs go one by one)."""
    if not _supervised():
        return 1
    if jobs is not None:
        return max(1, min(jobs, runs))
    from toggle_cosim.cosim.supervised_batch import default_jobs

    return default_jobs(runs)


def _outcomes(pairs, quiet: bool, time_limit: float | None, jobs: int):  # noqa: ANN001, ANN202
    """Each pair's outcome, in order. Several at once (`supervised_batch`) when jobs > 1; one by
    one otherwise, with a progress bar per run on a terminal unless quiet."""
    if jobs > 1:
        from toggle_cosim.cosim.supervised_batch import run_supervised

        yield from run_supervised(pairs, jobs=jobs, time_limit=time_limit)
        return
    for number, (run, plant) in enumerate(pairs, start=1):
        if quiet or not sys.stderr.isatty():
            yield _simulate(run, plant, time_limit)
            continue
        with click.progressbar(length=1000, label=f"[{number}/{len(pairs)}] {run.label}", file=sys.stderr) as bar:
            done = [0]

            def progress(fraction: float, bar=bar, done=done) -> None:  # noqa: ANN001
                step = int(fraction * 1000) - done[0]
                if step > 0:
                    bar.update(step)
                    done[0] += step

            outcome = _simulate(run, plant, time_limit, progress)
        yield outcome


def _execute(pairs, out: Path, quiet: bool, time_limit: float | None = None, on_written=None, jobs=None) -> list:  # noqa: ANN001
    """Run each (run, plant) pair supervised (up to `jobs` at once), write its files in order,
    print a line; `on_written(outcome)` after each run's files are written."""
    from toggle_cosim.experiments.resources import check_runs

    jobs = _jobs(jobs, len(pairs))
    check_runs(pairs, out, jobs)
    outcomes = []
    with contextlib.closing(_outcomes(pairs, quiet, time_limit, jobs)) as results:
        for number, outcome in enumerate(results, start=1):
            label = f"[{number}/{len(pairs)}] {outcome.run.label}"
            folder = _write_outcome(outcome, out)
            s = outcome.summary
            detail = (
                f"final error {s.final_error_m * 1e3:+.4f} mm, peak |i_q*| {s.peak_iq_ref_A:.1f} A, "
                f"T_h {s.hitting_time_s:.4f} s"
                if s and s.final_error_m is not None
                else "no summary"
            )
            click.echo(
                f"{label}: {_status_text(outcome)}; {detail}; RTF {outcome.record['real_time_factor']:.0f}; -> {folder}"
            )
            outcomes.append(outcome)
            if on_written is not None:
                on_written(outcome)
            if outcome.interrupted:
                click.echo(
                    f"interrupted: {label} written as interrupted; {len(pairs) - number} later run(s) not written",
                    err=True,
                )
                raise KeyboardInterrupt
    return outcomes


def _failed(outcomes) -> None:  # noqa: ANN001
    failed = [f"{o.run.label} ({o.reason})" for o in outcomes if not o.complete]
    if failed:
        raise RunFailed(f"{len(failed)} run(s) failed: {'; '.join(failed)}")


_JOBS = click.option(
    "--jobs",
    "-j",
    type=click.IntRange(min=1),
    default=None,
    metavar="N",
    help="Runs at once, each in its own process (default: one per core). With more than one, progress "
    "is a line per run as it is written (in order), not a bar; the traces are the same.",
)

_TIME_LIMIT = click.option(
    "--time-limit",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    metavar="SECONDS",
    help="Wall-clock limit per run (default: the scenario's time_limit key, else max(30 s, 20 x t_end)).",
)


@main.command()
@click.argument("scenarios", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (overrides the scenarios' fmu: key)."
)
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT, show_default=True, help="Output folder.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars.")
@_TIME_LIMIT
@_JOBS
def run(
    scenarios: tuple[Path, ...], fmu: Path | None, out: Path, quiet: bool, time_limit: float | None, jobs: int | None
) -> None:
    """Run scenario files; write trace.csv and run.json per run under OUT/<scenario>/<variant>/."""
    pairs = _load_runs(scenarios, fmu)
    _failed(_execute(pairs, out, quiet, time_limit, jobs=jobs))


def _plot_scenario(folder: Path, output: Path | None) -> Path:
    from toggle_cosim.analysis.results_figure import ResultsError, plot_results

    try:
        return plot_results(folder, output)
    except ResultsError as error:
        raise InputError(str(error)) from error


@main.command()
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--out",
    "-o",
    "output",
    type=click.Path(path_type=Path),
    default=None,
    help="PNG to write (default: RESULTS/figure.png); only with one RESULTS folder.",
)
def plot(results: tuple[Path, ...], output: Path | None) -> None:
    """Draw the paper's nine-panel figure for each scenario results folder (variants overlaid)."""
    if output is not None and len(results) > 1:
        raise InputError("--out names one file, so give one RESULTS folder with it")
    for folder in results:
        click.echo(f"wrote {_plot_scenario(folder, output)}")


@main.command()
@click.option("--scenarios", type=click.Path(path_type=Path), default=Path("scenarios"), show_default=True)
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT, show_default=True)
@click.option("--fmu", type=click.Path(path_type=Path), default=DEFAULT_FMU, show_default=True)
@click.option("--skip-build", is_flag=True, help="Use the existing FMU.")
@_TIME_LIMIT
@_JOBS
def paper(scenarios: Path, out: Path, fmu: Path, skip_build: bool, time_limit: float | None, jobs: int | None) -> None:
    """The main job: build the FMU, run the paper's six runs, write traces, figures and a summary."""
    from toggle_cosim.analysis.report import write_summary

    started = time.perf_counter()
    if not skip_build:
        _build(DEFAULT_SOURCE, DEFAULT_MODEL, fmu)
        for name, path in DEFAULT_BUILDS[1:]:
            _build(DEFAULT_SOURCE, name, path)
    files = [scenarios / f"{name}.yaml" for name in PAPER_SCENARIOS]
    pairs = _load_runs(files, fmu)
    from toggle_cosim.analysis.figure_worker import FigureWorkers

    # matplotlib loads and each figure is drawn beside the runs, two figures at a time where
    # there are two cores
    from toggle_cosim.cosim.supervised_batch import default_jobs

    figures = FigureWorkers(min(2, default_jobs(len(PAPER_SCENARIOS))))
    try:
        left = {name: sum(1 for run, _ in pairs if run.scenario == name) for name in PAPER_SCENARIOS}

        def written(outcome) -> None:  # noqa: ANN001 - a scenario's figure once all its runs are written
            left[outcome.run.scenario] -= 1
            if left[outcome.run.scenario] == 0:
                figures.submit(out / outcome.run.scenario)

        outcomes = _execute(pairs, out, quiet=False, time_limit=time_limit, on_written=written, jobs=jobs)
        extra = scenarios / "friction_models.yaml"
        if extra.is_file():  # the claims re-checked under the dissipative and stick-slip models
            try:
                extra_pairs = _load_runs([extra], fmu)
            except InputError as error:  # e.g. a plant without the friction models: the paper's runs stand
                click.echo(f"skipped {extra}: {error.message}", err=True)
                extra_pairs = []
            outcomes = [*outcomes, *_execute(extra_pairs, out, quiet=False, jobs=jobs)]
        summary = write_summary(outcomes, out / "summary.md")
        lines = figures.results()
    except BaseException:
        figures.stop()
        raise
    for line in lines:
        if line.startswith("error: "):
            raise InputError(line.removeprefix("error: "))
        click.echo(line)
    click.echo(f"wrote {summary}; total {time.perf_counter() - started:.1f} s")
    _failed(outcomes)


@main.command()
@click.argument("result", type=click.Path(path_type=Path))
@click.argument("reference", type=click.Path(path_type=Path))
@click.option(
    "--tolerances",
    type=click.Path(path_type=Path),
    default=None,
    help="YAML: {variable: {atol, rtol, ttol}, default: {...}} (default: the tolerances.yaml files "
    "in the reference's folder and its parent).",
)
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    default=None,
    help="Folder for the envelopes and plots of failing variables.",
)
@click.option(
    "--junit",
    type=click.Path(path_type=Path),
    default=None,
    help="Write a JUnit XML report: one test case per variable.",
)
@click.option(
    "--summary", type=click.Path(path_type=Path), default=None, help="Write a Markdown table (for a CI job summary)."
)
@click.option(
    "--fail-on-solver-change", is_flag=True, help="A change of the stored solver statistics fails (default: a warning)."
)
def compare(
    result: Path,
    reference: Path,
    tolerances: Path | None,
    out: Path | None,
    junit: Path | None,
    summary: Path | None,
    fail_on_solver_change: bool,
) -> None:
    """Compare RESULT with REFERENCE (CSV or Modelica .mat traces) in a funnel; exit 0 pass, 1 fail, 2 bad input."""
    from toggle_cosim.analysis.compare_command import run_compare

    sys.exit(
        run_compare(
            result,
            reference,
            tolerances,
            out,
            junit=junit,
            summary=summary,
            fail_on_solver_change=fail_on_solver_change,
        )
    )


@main.command()
@click.argument("scenarios", nargs=-1, type=click.Path(path_type=Path))
@click.option("--update", is_flag=True, help="Rewrite the stored references from fresh runs (review the diff!).")
@click.option("--folder", type=click.Path(path_type=Path), default=DEFAULT_REFERENCES, show_default=True)
@click.option("--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU for every scenario.")
@click.option(
    "--out",
    type=click.Path(path_type=Path),
    default=DEFAULT_OUT / "references",
    show_default=True,
    help="Folder for the reports: junit.xml, summary.md, plots of failing variables.",
)
@click.option(
    "--junit", type=click.Path(path_type=Path), default=None, help="JUnit XML report (default: OUT/junit.xml)."
)
@click.option(
    "--summary", type=click.Path(path_type=Path), default=None, help="Markdown summary (default: OUT/summary.md)."
)
@click.option(
    "--fail-on-solver-change", is_flag=True, help="A change of the stored solver statistics fails (default: a warning)."
)
@_TIME_LIMIT
@_JOBS
def references(
    scenarios: tuple[Path, ...],
    update: bool,
    folder: Path,
    fmu: Path | None,
    out: Path,
    junit: Path | None,
    summary: Path | None,
    fail_on_solver_change: bool,
    time_limit: float | None,
    jobs: int | None,
) -> None:
    """Check the shipped runs against their stored reference traces (or --update them)."""
    from toggle_cosim.analysis.reference_reports import write_reference_reports
    from toggle_cosim.experiments import references as refs

    for path, what in ((junit, "JUnit report"), (summary, "Markdown summary")):
        if path is not None and path.is_dir():
            raise InputError(f"{path}: is a directory; give a file name for the {what}")
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory; give a folder for the reports (--out)")
    files = list(scenarios) or [Path("scenarios") / f"{name}.yaml" for name in SHIPPED_SCENARIOS]
    pairs = _load_runs(files, fmu)
    from toggle_cosim.experiments.resources import check_runs

    jobs = _jobs(jobs, len(pairs))
    check_runs(pairs, folder if update else None, jobs)
    failures: list[str] = []
    checks = []
    with contextlib.closing(_outcomes(pairs, True, time_limit, jobs)) as results:
        for outcome in results:
            failures += _check_reference(outcome, refs, folder, update, fail_on_solver_change, checks)
    if not update:
        written = write_reference_reports(
            checks, out, junit or out / "junit.xml", summary or out / "summary.md", fail_on_solver_change
        )
        click.echo(f"reports: {', '.join(str(path) for path in written)}")
    if failures:
        raise RunFailed("; ".join(failures))


def _check_reference(outcome, refs, folder: Path, update: bool, fail_on_solver_change: bool, checks: list) -> list[str]:  # noqa: ANN001
    """One run of `references`: store it (--update) or check it; the failures it adds."""
    from toggle_cosim.analysis.compare import CompareInputError, format_table

    run = outcome.run
    if outcome.interrupted:
        raise KeyboardInterrupt
    if not outcome.complete:  # the other runs go on; the command fails at the end
        click.echo(f"{run.label}: FAILED ({outcome.reason})")
        return [f"{run.label}: {outcome.reason}"]
    if update:
        click.echo(f"{run.label}: wrote {refs.store(outcome, folder)}")
        return []
    try:
        checked = refs.check(outcome, folder)
    except (CompareInputError, ValueError) as error:
        raise InputError(str(error)) from error
    click.echo(f"{run.label}: {'pass' if checked.comparison.passed else 'FAIL'}")
    if not checked.comparison.passed:
        click.echo(format_table(checked.comparison))
    for line in checked.solver_changes:
        click.echo(f"{'FAIL' if fail_on_solver_change else 'warning'}: {line}")
    checks.append((checked, outcome.trace, refs.reference_stem(folder, run)))
    return [*checked.failures, *(checked.solver_changes if fail_on_solver_change else [])]


@main.command()
@click.argument("sweep_file", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "-o",
    type=click.Path(path_type=Path),
    default=None,
    help="Output folder (default: the sweep file's output: key, else out/sweeps/<name> under the current folder).",
)
@click.option(
    "--scheduler", default=None, metavar="ADDRESS", help="Dask distributed scheduler (default: a local process pool)."
)
@click.option("--workers", type=int, default=None, help="Local pool size (default: all cores).")
@click.option("--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (overrides the fmu: keys).")
@click.option("--retry-failed", is_flag=True, help="Run again the cases that failed last time.")
@click.option(
    "--case-timeout",
    type=click.FloatRange(min=0, min_open=True),
    default=None,
    metavar="SECONDS",
    help="Wall-clock limit per case (default: the time_limit key, else max(30 s, 20 x t_end)).",
)
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
def sweep(
    sweep_file: Path,
    out: Path | None,
    scheduler: str | None,
    workers: int | None,
    fmu: Path | None,
    retry_failed: bool,
    case_timeout: float | None,
    quiet: bool,
) -> None:
    """Parameter sweep: one co-simulation per case -> results.parquet and heat maps (resumable)."""
    from toggle_cosim.experiments.sweep_run import run_sweep

    code = run_sweep(
        sweep_file,
        scheduler,
        workers,
        fmu,
        output=out,
        retry_failed=retry_failed,
        progress=not quiet,
        case_timeout=case_timeout,
    )
    if code == interrupts.EXIT_INTERRUPTED:
        interrupts.exit_interrupted()
    sys.exit(code)


if __name__ == "__main__":
    main()
