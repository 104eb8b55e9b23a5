"""Command line: `toggle-cosim build | run | plot | paper`.

The only module that knows about files, exit codes and progress display. Exit status:
0 success, 1 a run or comparison failed, 2 bad input (nothing is written then).
"""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import click

from toggle_cosim import __version__

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


def _terminate_as_interrupt(signum: int, frame: object) -> None:
    """SIGTERM ends a run the way Ctrl-C does: the run in progress is written as incomplete."""
    raise KeyboardInterrupt(f"signal {signum}")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="toggle-cosim")
def main() -> None:
    """Co-simulation of the PMLSM-driven toggle mechanism (Fung, Wu and Chen 2001)."""
    if threading.current_thread() is threading.main_thread():  # signal handlers live in the main thread
        signal.signal(signal.SIGTERM, _terminate_as_interrupt)


def project_root() -> Path:
    """The project this command runs in: the nearest folder up from here with a pyproject.toml."""
    here = Path.cwd().resolve()
    for folder in (here, *here.parents):
        if (folder / "pyproject.toml").is_file():
            return folder
    return here


def _inside_project(path: Path, what: str, option: str) -> Path:
    """`path`, resolved, if it lies inside the project; else a one-line refusal."""
    root = project_root()
    resolved = path.resolve()
    if not resolved.is_relative_to(root):
        raise InputError(f"{path}: the {what} lies outside the project {root}; the build only reads and writes "
                         f"inside it (give a path under it with {option})")
    return resolved


def _build(source: Path, model: str, output: Path, fmi_version: str = "2.0", interfaces: str = "both") -> None:
    from toggle_cosim.fmu_export import FMUBuildError, ModelCompileError, build_fmu

    source = _inside_project(source, "Modelica source", "--source")
    output = _inside_project(output, "FMU output", "--output")
    if output.suffix != ".fmu":
        raise InputError(f"{output}: an FMU file name must end in .fmu (fix --output)")
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
@click.option("--source", type=click.Path(path_type=Path), default=DEFAULT_SOURCE, show_default=True,
              help="Modelica package directory (or a .mo file).")
@click.option("--model", default=None, help=f"Class to compile (default: every shipped plant, {DEFAULT_MODEL} first).")
@click.option("--output", "-o", type=click.Path(path_type=Path), default=None,
              help=f"FMU file to write (default: {DEFAULT_FMU} for {DEFAULT_MODEL}).")
@click.option("--fmi-version", type=click.Choice(["2.0", "3.0"]), default="2.0", show_default=True,
              help="FMI version of the FMU(s); 3.0 FMUs get a '3' after their default file name.")
@click.option("--interfaces", type=click.Choice(["both", "cs", "me"]), default="both", show_default=True,
              help="Interface types the FMU offers: Co-Simulation and Model Exchange in one FMU, or one of them.")
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
    from toggle_cosim.plant import ContractError, check_plant
    from toggle_cosim.friction import friction_settings
    from toggle_cosim.scenario import ScenarioError, load_scenario

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
            except ContractError as error:
                raise InputError(str(error)) from error
    pairs = [(run, plants[(fmu if fmu is not None else run.fmu).resolve()]) for run in runs]
    for run, plant in pairs:  # a friction model the plant cannot run is refused before anything runs
        try:
            friction_settings(run.plant.friction_model, run.plant.mu, run.plant.mu_s, plant.references, plant.path)
        except ValueError as error:
            raise InputError(f"{error} (scenario {run.source}, run {run.label})") from error
    return pairs


def _write_outcome(outcome, out: Path) -> Path:  # noqa: ANN001
    from toggle_cosim.traces import write_csv, write_json

    folder = out / outcome.run.scenario / (outcome.run.variant or "run")
    write_csv(folder / "trace.csv", outcome.trace)
    write_json(folder / "run.json", outcome.record)
    return folder


def _execute(pairs, out: Path, quiet: bool) -> list:  # noqa: ANN001
    from toggle_cosim.master import simulate

    outcomes = []
    for number, (run, plant) in enumerate(pairs, start=1):
        label = f"[{number}/{len(pairs)}] {run.label}"
        if quiet or not sys.stderr.isatty():
            outcome = simulate(run, plant)
        else:
            with click.progressbar(length=1000, label=label, file=sys.stderr) as bar:
                done = [0]

                def progress(fraction: float, bar=bar, done=done) -> None:  # noqa: ANN001
                    step = int(fraction * 1000) - done[0]
                    if step > 0:
                        bar.update(step)
                        done[0] += step

                outcome = simulate(run, plant, progress)
        folder = _write_outcome(outcome, out)
        s = outcome.summary
        status = "complete" if outcome.complete else f"INCOMPLETE ({outcome.reason})"
        detail = (
            f"final error {s.final_error_m * 1e3:+.4f} mm, peak |i_q*| {s.peak_iq_ref_A:.1f} A, "
            f"T_h {s.hitting_time_s:.4f} s" if s else "no summary"
        )
        click.echo(f"{label}: {status}; {detail}; RTF {outcome.record['real_time_factor']:.0f}; -> {folder}")
        outcomes.append(outcome)
        if outcome.interrupted:
            click.echo(f"interrupted: {label} written as incomplete; {len(pairs) - number} run(s) not started", err=True)
            sys.exit(130)
    return outcomes


@main.command()
@click.argument("scenarios", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (overrides the scenarios' fmu: key).")
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT, show_default=True, help="Output folder.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars.")
def run(scenarios: tuple[Path, ...], fmu: Path | None, out: Path, quiet: bool) -> None:
    """Run scenario files; write trace.csv and run.json per run under OUT/<scenario>/<variant>/."""
    pairs = _load_runs(scenarios, fmu)
    outcomes = _execute(pairs, out, quiet)
    failed = [o.run.label for o in outcomes if not o.complete]
    if failed:
        raise RunFailed(f"{len(failed)} run(s) incomplete: {', '.join(failed)}")


def _plot_scenario(folder: Path, output: Path | None) -> Path:
    from toggle_cosim.plots import nine_panel_figure
    from toggle_cosim.traces import read_csv

    runs = sorted(p for p in folder.iterdir() if (p / "trace.csv").is_file()) if folder.is_dir() else []
    if not runs:
        raise InputError(f"{folder}: no run results here (expected <variant>/trace.csv; run 'toggle-cosim run' first)")
    traces, target, title = {}, None, folder.name
    for run_dir in runs:
        try:
            traces[run_dir.name] = read_csv(run_dir / "trace.csv")
            record = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            raise InputError(f"{run_dir}: unreadable results ({error})") from error
        target = record["resolved"]["stroke"]["x_target"]
        title = f"{record['scenario']}: {record['description']}"
    return nine_panel_figure(traces, title, output or folder / "figure.png", target)


@main.command()
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--output", "-o", type=click.Path(path_type=Path), default=None,
              help="PNG to write (default: RESULTS/figure.png); only with one RESULTS folder.")
def plot(results: tuple[Path, ...], output: Path | None) -> None:
    """Draw the paper's nine-panel figure for each scenario results folder (variants overlaid)."""
    if output is not None and len(results) > 1:
        raise InputError("--output names one file, so give one RESULTS folder with it")
    for folder in results:
        click.echo(f"wrote {_plot_scenario(folder, output)}")


@main.command()
@click.option("--scenarios", type=click.Path(path_type=Path), default=Path("scenarios"), show_default=True)
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT, show_default=True)
@click.option("--fmu", type=click.Path(path_type=Path), default=DEFAULT_FMU, show_default=True)
@click.option("--skip-build", is_flag=True, help="Use the existing FMU.")
def paper(scenarios: Path, out: Path, fmu: Path, skip_build: bool) -> None:
    """The main job: build the FMU, run the paper's six runs, write traces, figures and a summary."""
    from toggle_cosim.report import write_summary

    started = time.perf_counter()
    if not skip_build:
        _build(DEFAULT_SOURCE, DEFAULT_MODEL, fmu)
        for name, path in DEFAULT_BUILDS[1:]:
            _build(DEFAULT_SOURCE, name, path)
    files = [scenarios / f"{name}.yaml" for name in PAPER_SCENARIOS]
    pairs = _load_runs(files, fmu)
    outcomes = _execute(pairs, out, quiet=False)
    for name in PAPER_SCENARIOS:
        click.echo(f"wrote {_plot_scenario(out / name, None)}")
    extra = scenarios / "friction_models.yaml"
    if extra.is_file():  # the claims re-checked under the dissipative and stick-slip models
        try:
            extra_pairs = _load_runs([extra], fmu)
        except InputError as error:  # e.g. a plant without the friction models: the paper's runs stand
            click.echo(f"skipped {extra}: {error.message}", err=True)
            extra_pairs = []
        outcomes = [*outcomes, *_execute(extra_pairs, out, quiet=False)]
    summary = write_summary(outcomes, out / "summary.md")
    click.echo(f"wrote {summary}; total {time.perf_counter() - started:.1f} s")
    failed = [o.run.label for o in outcomes if not o.complete]
    if failed:
        raise RunFailed(f"{len(failed)} run(s) incomplete: {', '.join(failed)}")


@main.command()
@click.argument("result", type=click.Path(path_type=Path))
@click.argument("reference", type=click.Path(path_type=Path))
@click.option("--tolerances", type=click.Path(path_type=Path), default=None,
              help="YAML: {variable: {atol, rtol, ttol}, default: {...}} (default: the tolerances.yaml files "
                   "in the reference's folder and its parent).")
@click.option("--out", type=click.Path(path_type=Path), default=None,
              help="Folder for the envelopes and plots of failing variables.")
@click.option("--junit", type=click.Path(path_type=Path), default=None,
              help="Write a JUnit XML report: one test case per variable.")
@click.option("--summary", type=click.Path(path_type=Path), default=None,
              help="Write a Markdown table (for a CI job summary).")
@click.option("--fail-on-solver-change", is_flag=True,
              help="A change of the stored solver statistics fails (default: a warning).")
def compare(result: Path, reference: Path, tolerances: Path | None, out: Path | None, junit: Path | None,
            summary: Path | None, fail_on_solver_change: bool) -> None:
    """Compare RESULT with REFERENCE (CSV or Modelica .mat traces) in a funnel; exit 0 pass, 1 fail, 2 bad input."""
    from toggle_cosim.compare import run_compare

    sys.exit(run_compare(result, reference, tolerances, out, junit=junit, summary=summary,
                         fail_on_solver_change=fail_on_solver_change))


@main.command()
@click.argument("scenarios", nargs=-1, type=click.Path(path_type=Path))
@click.option("--update", is_flag=True, help="Rewrite the stored references from fresh runs (review the diff!).")
@click.option("--folder", type=click.Path(path_type=Path), default=DEFAULT_REFERENCES, show_default=True)
@click.option("--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU for every scenario.")
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT / "references", show_default=True,
              help="Folder for the reports: junit.xml, summary.md, plots of failing variables.")
@click.option("--junit", type=click.Path(path_type=Path), default=None, help="JUnit XML report (default: OUT/junit.xml).")
@click.option("--summary", type=click.Path(path_type=Path), default=None,
              help="Markdown summary (default: OUT/summary.md).")
@click.option("--fail-on-solver-change", is_flag=True,
              help="A change of the stored solver statistics fails (default: a warning).")
def references(scenarios: tuple[Path, ...], update: bool, folder: Path, fmu: Path | None, out: Path,
               junit: Path | None, summary: Path | None, fail_on_solver_change: bool) -> None:
    """Check the shipped runs against their stored reference traces (or --update them)."""
    from toggle_cosim.analysis.reference_reports import write_reference_reports
    from toggle_cosim import references as refs
    from toggle_cosim.compare import CompareInputError, format_table
    from toggle_cosim.master import simulate

    for path, what in ((junit, "JUnit report"), (summary, "Markdown summary")):
        if path is not None and path.is_dir():
            raise InputError(f"{path}: is a directory; give a file name for the {what}")
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory; give a folder for the reports (--out)")
    files = list(scenarios) or [Path("scenarios") / f"{name}.yaml" for name in SHIPPED_SCENARIOS]
    pairs = _load_runs(files, fmu)
    failures: list[str] = []
    checks = []
    for run, plant in pairs:
        outcome = simulate(run, plant)
        if not outcome.complete:
            raise RunFailed(f"{run.label}: {outcome.reason}")
        if update:
            click.echo(f"{run.label}: wrote {refs.store(outcome, folder)}")
            continue
        try:
            checked = refs.check(outcome, folder)
        except (CompareInputError, ValueError) as error:
            raise InputError(str(error)) from error
        click.echo(f"{run.label}: {'pass' if checked.comparison.passed else 'FAIL'}")
        if not checked.comparison.passed:
            click.echo(format_table(checked.comparison))
        for line in checked.solver_changes:
            click.echo(f"{'FAIL' if fail_on_solver_change else 'warning'}: {line}")
        failures += checked.failures
        if fail_on_solver_change:
            failures += checked.solver_changes
        checks.append((checked, outcome.trace, refs.reference_stem(folder, run)))
    if not update:
        written = write_reference_reports(checks, out, junit or out / "junit.xml", summary or out / "summary.md",
                                          fail_on_solver_change)
        click.echo(f"reports: {', '.join(str(path) for path in written)}")
    if failures:
        raise RunFailed("; ".join(failures))


@main.command()
@click.argument("sweep_file", type=click.Path(path_type=Path))
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Dask distributed scheduler (default: a local process pool).")
@click.option("--workers", type=int, default=None, help="Local pool size (default: all cores).")
@click.option("--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (overrides the fmu: keys).")
@click.option("--retry-failed", is_flag=True, help="Run again the cases that failed last time.")
def sweep(sweep_file: Path, scheduler: str | None, workers: int | None, fmu: Path | None, retry_failed: bool) -> None:
    """Parameter sweep: one co-simulation per case -> results.parquet and heat maps (resumable)."""
    from toggle_cosim.sweep import run_sweep

    sys.exit(run_sweep(sweep_file, scheduler, workers, fmu, retry_failed=retry_failed))


if __name__ == "__main__":
    main()
