"""`toggle-cosim pack` and `verify`: files carried inside an FMU (FMI-LS-REF), and the FMU run
against the references it carries (`fmi_ls_ref`; docs/verification.md)."""

from __future__ import annotations

import re
from pathlib import Path

import click

from toggle_cosim.cli.app import (
    DEFAULT_OUT,
    DEFAULT_REFERENCES,
    InputError,
    RunFailed,
    check_output,
    main,
    out_file_option,
    require,
)
from toggle_cosim.cli.execution import check_report_outputs, report_options
from toggle_cosim.cli.report_command import REPORT_FILE
from toggle_cosim.files.outputs import FMU, HTML

NAME = re.compile(r"[A-Za-z0-9_.-]{1,100}")
EXPERIMENT_FOLDER = "experiments"


def _read(path: Path, what: str, option: str) -> bytes:
    from toggle_cosim.files.bounded import InputFileError, read_bounded
    from toggle_cosim.fmi_ls_ref.verify import CARRIED_LIMIT

    try:
        return read_bounded(path, CARRIED_LIMIT, what)
    except InputFileError as error:
        raise InputError(f"{error} (fix {option})") from None


def _experiment_attachments(
    fmu: Path,
    reference: Path,
    name: str | None,
    stimuli: Path | None,
    parameters: Path | None,
    tolerances: Path | None,
    times: tuple[float | None, float | None, float | None, float | None],
) -> list:
    """A third party's experiment: its files under experiments/NAME/ and its document."""
    from fmpy import read_model_description

    from toggle_cosim.analysis.compare import load_tolerances
    from toggle_cosim.analysis.csv_traces import CompareInputError, read_trace
    from toggle_cosim.fmi_ls_ref.experiments import MIME, Experiment, experiments_xml
    from toggle_cosim.fmi_ls_ref.manifest import LsRefError, Related
    from toggle_cosim.fmi_ls_ref.pack import Attachment
    from toggle_cosim.fmi_ls_ref.verify import ssv_values

    name = name or reference.stem
    if not NAME.fullmatch(name):
        raise InputError(f"{name!r}: an experiment name is letters, digits, '_', '.' and '-' (fix --name)")
    try:
        read_trace(reference)
        if stimuli is not None:
            read_trace(stimuli)
        if tolerances is not None:
            load_tolerances(tolerances)
    except (CompareInputError, ValueError) as error:
        raise InputError(str(error)) from None
    if parameters is not None:
        try:
            ssv_values(_read(parameters, "SSV parameter set", "--parameters"), str(parameters))
        except LsRefError as error:
            raise InputError(f"{error} (fix --parameters)") from None
    try:
        default = read_model_description(str(fmu)).defaultExperiment
    except Exception as error:  # noqa: BLE001 - a broken FMU, in one line
        raise InputError(f"{fmu}: its modelDescription.xml cannot be read ({' '.join(str(error).split())})") from None

    def given(value: float | None, attribute: str) -> float | None:
        if value is not None:
            return value
        found = None if default is None else getattr(default, attribute)
        return None if found is None else float(found)

    start = given(times[0], "startTime") or 0.0
    stop, step, tolerance = given(times[1], "stopTime"), given(times[2], "stepSize"), given(times[3], "tolerance")
    if stop is None or step is None:
        raise InputError(f"{fmu}: has no default experiment with a stop time and step size (give --stop and --step)")
    if not stop > start or not step > 0:
        raise InputError(f"{fmu}: the experiment needs --stop > --start and --step > 0 (fix them)")
    folder = f"{EXPERIMENT_FOLDER}/{name}"
    files = {"reference": reference, "stimuli": stimuli, "parameters": parameters, "tolerances": tolerances}
    roles = {
        "reference": ("result", "text/csv"),
        "stimuli": ("other", "text/csv"),
        "parameters": ("parameter", "application/x-ssp-parameter-set"),
        "tolerances": ("configuration", "application/yaml"),
    }
    attachments, sources = [], {}
    for key, path in files.items():
        if path is None:
            sources[key] = None
            continue
        sources[key] = f"{key}{path.suffix}"
        role, kind = roles[key]
        data = _read(path, f"{key} file", f"--{key}")
        attachments.append(Attachment(Related(f"{folder}/{sources[key]}", role, kind, f"{name}: {key}"), data))
    experiment = Experiment(
        name,
        start,
        stop,
        step,
        sources["reference"],
        tolerance,
        sources["parameters"],
        sources["stimuli"],
        sources["tolerances"],
    )
    document = Related(f"{folder}/experiment.xml", "experiment/validation", MIME, f"experiment {name}")
    return [*attachments, Attachment(document, experiments_xml([experiment], name))]


@main.command()
@click.argument("fmu", type=click.Path(path_type=Path))
@click.option(
    "--scenario",
    "scenarios",
    multiple=True,
    type=click.Path(path_type=Path),
    help="A scenario file to carry with its stored references from --folder (a plant FMU of ours; repeatable).",
)
@click.option("--folder", type=click.Path(path_type=Path), default=DEFAULT_REFERENCES, show_default=True)
@click.option(
    "--reference", type=click.Path(path_type=Path), default=None, help="A reference CSV to carry (time first)."
)
@click.option("--name", default=None, help="The experiment's name (default: the reference's file name).")
@click.option("--stimuli", type=click.Path(path_type=Path), default=None, help="CSV of the FMU's inputs over time.")
@click.option("--parameters", type=click.Path(path_type=Path), default=None, help="SSV parameter set to apply.")
@click.option("--tolerances", type=click.Path(path_type=Path), default=None, help="Funnel tolerances (YAML).")
@click.option("--start", type=float, default=None, help="Start time (default: the FMU's default experiment, else 0).")
@click.option("--stop", type=float, default=None, help="Stop time (default: the FMU's default experiment).")
@click.option("--step", type=float, default=None, help="Output interval (default: the FMU's default experiment).")
@click.option("--tolerance", type=float, default=None, help="Relative solver tolerance (default: the FMU's).")
@click.option(
    "--model-source", type=click.Path(path_type=Path), default=None, help="Modelica file or package folder to carry."
)
@out_file_option("FMU to write (default: FMU itself, replaced atomically).")
def pack(
    fmu: Path,
    scenarios: tuple[Path, ...],
    folder: Path,
    reference: Path | None,
    name: str | None,
    stimuli: Path | None,
    parameters: Path | None,
    tolerances: Path | None,
    start: float | None,
    stop: float | None,
    step: float | None,
    tolerance: float | None,
    model_source: Path | None,
    output: Path | None,
) -> None:
    """Carry experiments, references and sources inside FMU (FMI-LS-REF) without touching its other
    files: a reference CSV of any FMU (with its stimuli, parameters and times), scenarios with their
    stored references for a plant FMU of ours, the Modelica source."""
    from toggle_cosim.fmi_ls_ref.evidence import model_attachments, scenario_attachments
    from toggle_cosim.fmi_ls_ref.manifest import LsRefError
    from toggle_cosim.fmi_ls_ref.pack import open_fmu
    from toggle_cosim.fmi_ls_ref.pack import pack as pack_fmu

    target = output or fmu
    check_output(target, "FMU (--out)", FMU)
    if reference is None and (name or stimuli or parameters or tolerances or {start, stop, step, tolerance} - {None}):
        raise InputError("--name, --stimuli, --parameters, --tolerances and the times describe --reference: give it")
    if reference is None and not scenarios and model_source is None:
        raise InputError("nothing to pack: give --reference, --scenario or --model-source")
    try:
        open_fmu(fmu).close()
        attachments = []
        if model_source is not None:
            if not model_source.exists():
                raise InputError(f"{model_source}: no such Modelica file or package folder (fix --model-source)")
            attachments += model_attachments(model_source)
        for scenario in scenarios:
            attachments += scenario_attachments(scenario, folder, fmu)
        if reference is not None:
            attachments += _experiment_attachments(
                fmu, reference, name, stimuli, parameters, tolerances, (start, stop, step, tolerance)
            )
        written = pack_fmu(fmu, attachments, target)
    except LsRefError as error:
        raise InputError(str(error)) from None
    click.echo(f"packed {len(attachments)} files into {written}")


@main.command()
@click.argument("fmu", type=click.Path(path_type=Path))
@report_options(DEFAULT_OUT / "verify")
@click.option("--html", is_flag=True, help="Also write OUT/report.html: each experiment against its reference.")
def verify(fmu: Path, out: Path, junit: Path | None, summary: Path | None, html: bool) -> None:
    """Run the experiments FMU carries (FMI-LS-REF) and compare each with its carried reference in a
    funnel; exit 0 pass, 1 a variable left its funnel, 2 a bad FMU (a manifest naming a missing file,
    a checksum that does not match)."""
    from toggle_cosim.analysis.compare import format_table
    from toggle_cosim.fmi_ls_ref.manifest import LsRefError
    from toggle_cosim.fmi_ls_ref.reports import write_verification_html, write_verification_reports
    from toggle_cosim.fmi_ls_ref.verify import verify_fmu

    require("fmpy", "junitparser", "matplotlib", *(("plotly",) if html else ()))
    check_report_outputs(out, junit, summary)
    if html:
        check_output(out / REPORT_FILE, "HTML report", HTML)
    try:
        verification = verify_fmu(fmu)
    except LsRefError as error:
        raise InputError(str(error)) from None
    for source in verification.skipped:
        click.echo(f"note: {source}: an experiment file of a format toggle-cosim does not run (skipped)")
    for check in verification.checks:
        click.echo(f"{check.label}: {'pass' if check.passed else 'FAIL'} ({check.runner})")
        if not check.passed:
            click.echo(format_table(check.comparison))
    written = write_verification_reports(verification, out, junit or out / "junit.xml", summary or out / "summary.md")
    if html:
        written.append(write_verification_html(verification, out / REPORT_FILE))
    click.echo(f"reports: {', '.join(str(path) for path in written)}")
    if not verification.passed:
        raise RunFailed("; ".join(verification.failures))
