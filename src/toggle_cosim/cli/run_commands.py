"""`toggle-cosim run`, `plot` and `paper`: scenario files to traces, figures and the summary."""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import click

from toggle_cosim.cli.app import (
    DEFAULT_BUILDS,
    DEFAULT_FMU,
    DEFAULT_MODEL,
    DEFAULT_OUT,
    DEFAULT_SOURCE,
    PAPER_SCENARIOS,
    SHIPPED_SCENARIO_FOLDER,
    InputError,
    check_output,
    main,
    out_file_option,
    require,
)
from toggle_cosim.cli.build_command import build_plant
from toggle_cosim.cli.execution import JOBS_OPTION, TIME_LIMIT_OPTION, execute_runs, load_runs, raise_if_failed
from toggle_cosim.files.outputs import MARKDOWN, PNG
from toggle_cosim.runs.definition import COUPLINGS


@main.command()
@click.argument("scenarios", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option(
    "--fmu", type=click.Path(path_type=Path), default=None, help="Plant FMU (overrides the scenarios' fmu: key)."
)
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT, show_default=True, help="Output folder.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars.")
@click.option(
    "--coupling",
    type=click.Choice(COUPLINGS),
    default=None,
    help="gauss-seidel: the plant gets the command computed from its outputs at the same sample; jacobi: the "
    "previous sample's command (overrides the scenarios' coupling: key; default gauss-seidel).",
)
@click.option(
    "--variant",
    "variants",
    multiple=True,
    metavar="NAME",
    help="For an .ssp: run this variant, a root SSD named NAME (repeat for several; default: SystemStructure.ssd).",
)
@click.option("--parameter-set", "parameter_sets", multiple=True, hidden=True, help="Old name of --variant.")
@TIME_LIMIT_OPTION
@JOBS_OPTION
def run(
    scenarios: tuple[Path, ...],
    fmu: Path | None,
    out: Path,
    quiet: bool,
    coupling: str | None,
    variants: tuple[str, ...],
    parameter_sets: tuple[str, ...],
    time_limit: float | None,
    jobs: int | None,
) -> None:
    """Run scenario files (or SSP archives, .ssp); write trace.csv and run.json per run under
    OUT/<scenario>/<variant>/ (an SSP's under OUT/<archive>_ssp/<set>/; with a --coupling the
    scenario does not give, OUT/<scenario>_<coupling>/<variant>/)."""
    from toggle_cosim.cli.ssp_command import is_ssp, ssp_runs

    ssps = [path for path in scenarios if is_ssp(path)]
    variants = (*variants, *parameter_sets)  # --parameter-set: the old name (a variant is named after its set)
    if variants and not ssps:
        raise InputError("--variant chooses an SSP's variant (a root SSD): give an .ssp file with it")
    if fmu is not None and ssps:
        raise InputError(f"{ssps[0]}: --fmu does not apply to an SSP (its plant is inside it); run it without --fmu")
    with contextlib.ExitStack() as stack:  # an SSP's FMUs live in a folder removed after the runs
        built = ssp_runs(ssps, variants, stack)
        pairs = load_runs([path for path in scenarios if not is_ssp(path)], fmu, built, coupling)
        raise_if_failed(execute_runs(pairs, out, quiet, time_limit, jobs=jobs))


def _plot_scenario(folder: Path, output: Path | None) -> Path:
    from toggle_cosim.analysis.results_figure import ResultsError, plot_results

    try:
        return plot_results(folder, output)
    except ResultsError as error:
        raise InputError(str(error)) from error


@main.command()
@click.argument("results", nargs=-1, required=True, type=click.Path(path_type=Path))
@out_file_option("PNG to write (default: RESULTS/figure.png; with --vars or --reference RESULTS/variables.png).")
@click.option(
    "--vars",
    "variables",
    default=None,
    metavar="NAMES",
    help="Variables to draw, comma-separated (x_B,iq_ref): every RESULTS overlaid, one panel each.",
)
@click.option(
    "--reference",
    type=click.Path(path_type=Path),
    default=None,
    help="A reference trace drawn with its funnel band (tolerance files by place, as compare).",
)
@click.option(
    "--label",
    "labels",
    multiple=True,
    metavar="NAME",
    help="The legend's name of each RESULTS, in order (repeat: one per RESULTS; implies --vars' overlay). "
    "Default: scenario/variant, and where that repeats, the run's folder.",
)
def plot(
    results: tuple[Path, ...],
    output: Path | None,
    variables: str | None,
    reference: Path | None,
    labels: tuple[str, ...],
) -> None:
    """Draw results folders or trace files: the paper's nine-panel figure per scenario folder (variants
    overlaid), or with --vars/--reference/--label every run overlaid variable by variable (any scenario or plant)."""
    from toggle_cosim.cli.report_command import is_paper_plant, parse_vars, plot_variables

    require("matplotlib")
    names = parse_vars(variables)
    if labels and len(labels) != len(results):
        raise InputError(
            f"--label given {len(labels)} time(s) for {len(results)} RESULTS; give one --label per RESULTS, in order"
        )
    if names is not None or reference is not None or labels:
        check_output(output, "figure (--out)", PNG)
        click.echo(f"wrote {plot_variables(results, names, reference, output, labels or None)}")
        return
    if output is not None and len(results) > 1:
        raise InputError("--out names one file, so give one RESULTS folder with it")
    check_output(output, "figure (--out)", PNG)
    for folder in results:
        if not folder.is_file() and is_paper_plant(folder):
            click.echo(f"wrote {_plot_scenario(folder, output)}")
        else:  # a plant of one's own, or a trace file: the variables it has
            click.echo(f"wrote {plot_variables([folder], None, None, output or _figure_path(folder))}")


def _figure_path(result: Path) -> Path:
    return (result if result.is_dir() else result.parent) / "figure.png"


@main.command()
@click.option(
    "--scenarios",
    type=click.Path(path_type=Path),
    default=SHIPPED_SCENARIO_FOLDER,
    show_default="the shipped scenarios",
    help="Folder with the paper's scenario files (their fmu: keys give way to --fmu).",
)
@click.option("--out", type=click.Path(path_type=Path), default=DEFAULT_OUT, show_default=True)
@click.option("--fmu", type=click.Path(path_type=Path), default=DEFAULT_FMU, show_default=True)
@click.option("--skip-build", is_flag=True, help="Use the existing FMU.")
@TIME_LIMIT_OPTION
@JOBS_OPTION
def paper(scenarios: Path, out: Path, fmu: Path, skip_build: bool, time_limit: float | None, jobs: int | None) -> None:
    """The main job: build the FMUs, run the paper's six runs (and, where SCENARIOS has it,
    friction_models.yaml's seven: 13 runs), write traces, figures and a summary."""
    from toggle_cosim.analysis.report import write_summary

    require("matplotlib", *(() if skip_build else ("modelica",)))
    check_output(out / "summary.md", "summary", MARKDOWN)

    started = time.perf_counter()
    if not skip_build:
        build_plant(DEFAULT_SOURCE, DEFAULT_MODEL, fmu)
        for name, path in DEFAULT_BUILDS[1:]:
            build_plant(DEFAULT_SOURCE, name, path)
    files = [scenarios / f"{name}.yaml" for name in PAPER_SCENARIOS]
    pairs = load_runs(files, fmu)
    from toggle_cosim.analysis.figure_worker import FigureWorkers

    # matplotlib loads and each figure is drawn beside the runs, two figures at a time where
    # there are two cores
    from toggle_cosim.cosim.isolation.supervised_batch import default_jobs

    figures = FigureWorkers(min(2, default_jobs(len(PAPER_SCENARIOS))))
    try:
        left: dict = {}
        for run, *_ in pairs:
            left[run.folder.parent] = left.get(run.folder.parent, 0) + 1

        def written(outcome) -> None:  # noqa: ANN001 - a scenario's figure once all its runs are written
            left[outcome.run.folder.parent] -= 1
            if left[outcome.run.folder.parent] == 0:
                figures.submit(out / outcome.run.folder.parent)

        outcomes = execute_runs(
            pairs, out, quiet=False, time_limit=time_limit, on_written=written, jobs=jobs, keep_traces=True
        )
        extra = scenarios / "friction_models.yaml"
        if extra.is_file():  # the claims re-checked under the dissipative and stick-slip models
            try:
                extra_pairs = load_runs([extra], fmu)
            except InputError as error:  # e.g. a plant without the friction models: the paper's runs stand
                click.echo(f"skipped {extra}: {error.message}", err=True)
                extra_pairs = []
            outcomes = [*outcomes, *execute_runs(extra_pairs, out, quiet=False, jobs=jobs, keep_traces=True)]
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
    raise_if_failed(outcomes)
