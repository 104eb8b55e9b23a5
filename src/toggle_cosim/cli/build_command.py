"""`toggle-cosim build`: Modelica source to FMU (`fmu_export`), from any folder into any folder;
and the controller FMU ToggleVSC (`controller_fmu`), which needs only a C compiler."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from toggle_cosim import limits
from toggle_cosim.cli.app import (
    CONTROLLER_MODEL,
    DEFAULT_BUILDS,
    DEFAULT_CONTROLLER,
    DEFAULT_FMU,
    DEFAULT_MODEL,
    DEFAULT_REFERENCES,
    DEFAULT_SOURCE,
    InputError,
    check_output,
    main,
    out_file_option,
    require,
)
from toggle_cosim.files.outputs import FMU

if TYPE_CHECKING:
    from toggle_cosim.fmu_export import BuildReport

CONTROLLER = CONTROLLER_MODEL  # --model of the controller FMU (no Modelica source)

# The default file name's tag for an FMU that offers one interface only: the default FMU offers both.
INTERFACE_TAGS = {"both": "", "cs": "_CS", "me": "_ME"}


def _check_fmu_output(output: Path) -> None:
    check_output(output, "FMU (--out)", FMU)  # a link there is refused, not followed; only an FMU is replaced
    if output.suffix != ".fmu":
        raise InputError(f"{output}: an FMU file name must end in .fmu (fix --out)")


def build_plant(
    source: Path,
    model: str,
    output: Path,
    fmi_version: str = "2.0",
    interfaces: str = "both",
    attach: tuple[Path, ...] = (),
    references: Path = DEFAULT_REFERENCES,
) -> None:
    """Build the FMU, then carry in it (FMI-LS-REF) its Modelica source, the scenarios `attach`
    with their references from `references` and, for a shipped plant built from the shipped
    source, the shipped scenarios that run on it with their shipped references."""
    from toggle_cosim.fmu_export import FMUBuildError, ModelCompileError, build_fmu

    require("modelica")
    try:
        limits.check_environment()  # TOGGLE_COSIM_BUILD_CACHE among the on/off variables
    except limits.LimitError as error:
        raise InputError(str(error)) from None
    if not source.exists():
        raise InputError(f"{source}: no such Modelica package folder or .mo file (fix --source)")
    _check_fmu_output(output)
    for scenario in attach:
        if not scenario.is_file():
            raise InputError(f"{scenario}: no such scenario file (fix --attach)")
    try:
        report = build_fmu(source, model, output, fmi_version=fmi_version, interfaces=interfaces)
    except (ModelCompileError, FMUBuildError) as error:
        raise InputError(str(error).splitlines()[0]) from error
    carried = _carry_evidence(source, output, attach, references, _shipped_plant(source, model))
    click.echo(
        f"built {report.fmu.path} (FMI {report.fmu.fmi_version} {' + '.join(sorted(report.fmu.interfaces))}, "
        f"{report.fmu.size_bytes / 1024:.0f} KiB, GUID {report.fmu.guid}): "
        f"{report.variables} variables, {report.states} states, {report.event_indicators} event indicators; "
        f"{_timing(report)}; "
        f"carries {carried}"
    )


def _timing(report: BuildReport) -> str:
    """Where the FMU came from: compiled (and how long each step took) or copied from the build cache."""
    if report.from_cache:
        return "from the build cache"
    return f"compile {report.compile_seconds:.1f} s, C build and zip {report.package_seconds:.1f} s"


def _shipped_plant(source: Path, model: str) -> str | None:
    """The shipped file name (e.g. ToggleLSM.fmu) of a shipped plant built from the shipped source,
    whose scenarios name it in their fmu: key; None for any other build."""
    if model in dict(DEFAULT_BUILDS) and Path(source).resolve() == Path(DEFAULT_SOURCE).resolve():
        return dict(DEFAULT_BUILDS)[model].name
    return None


def _carry_evidence(source: Path, output: Path, attach: tuple[Path, ...], references: Path, shipped: str | None) -> str:
    """Pack the FMU's evidence into it (`fmi_ls_ref.evidence`); what it carries, in words. A
    scenario that cannot be carried removes the FMU just built (no half-made output)."""
    from toggle_cosim.experiments.shipped import SHIPPED_SCENARIO_FOLDER
    from toggle_cosim.fmi_ls_ref.evidence import model_attachments, scenario_attachments, shipped_scenarios_for
    from toggle_cosim.fmi_ls_ref.manifest import LsRefError
    from toggle_cosim.fmi_ls_ref.pack import pack

    try:
        attachments = model_attachments(source)
        scenarios = shipped_scenarios_for(shipped) if shipped else []
        for scenario in scenarios:
            attachments += scenario_attachments(scenario, Path(SHIPPED_SCENARIO_FOLDER) / "references", output)
        for scenario in attach:
            attachments += scenario_attachments(scenario, references, output)
        pack(output, attachments)
    except LsRefError as error:
        output.unlink(missing_ok=True)
        raise InputError(str(error)) from None
    count = len(scenarios) + len(attach)
    return (
        f"its Modelica source and {count} scenario{'s' if count != 1 else ''} with references (FMI-LS-REF; "
        f"{output.stat().st_size / 1024:.0f} KiB with them)"
    )


def build_controller(output: Path, fmi_version: str = "2.0") -> None:
    """The controller FMU ToggleVSC (FMI `fmi_version`, Co-Simulation) at `output`."""
    import time

    from toggle_cosim.controller_fmu import build_controller_fmu
    from toggle_cosim.fmu_export.packaging import FMUBuildError

    _check_fmu_output(output)
    started = time.perf_counter()
    try:
        built = build_controller_fmu(output, fmi_version)
    except FMUBuildError as error:
        raise InputError(str(error).splitlines()[0]) from error
    click.echo(
        f"built {built.path} (FMI {built.fmi_version} CoSimulation, {built.size_bytes / 1024:.0f} KiB, "
        f"GUID {built.token}): the VSC sampled every T_s, generated from control/laws.py; "
        f"C build and zip {time.perf_counter() - started:.1f} s"
    )


@main.command()
@click.option(
    "--source",
    type=click.Path(path_type=Path),
    default=DEFAULT_SOURCE,
    show_default="the shipped ToggleLSM package",
    help="Modelica package folder (or a .mo file), anywhere.",
)
@click.option(
    "--model",
    default=None,
    help=f"Class to compile (default: every shipped plant, {DEFAULT_MODEL} first, then the controller FMU "
    f"in FMI 2.0 and 3.0); {CONTROLLER} builds only the controller FMU (no Modelica needed).",
)
@out_file_option(f"FMU file to write (default: {DEFAULT_FMU} for {DEFAULT_MODEL}).")
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
    help="Interface types the FMU offers: Co-Simulation and Model Exchange in one FMU, or one of them "
    "(then the default file name ends in _CS or _ME).",
)
@click.option(
    "--attach",
    multiple=True,
    type=click.Path(path_type=Path),
    help="A scenario file to carry in the FMU with its references from --references (FMI-LS-REF; "
    "repeatable); toggle-cosim verify reruns them.",
)
@click.option(
    "--references",
    type=click.Path(path_type=Path),
    default=DEFAULT_REFERENCES,
    show_default=True,
    help="Folder of the --attach scenarios' stored references.",
)
def build(
    source: Path,
    model: str | None,
    output: Path | None,
    fmi_version: str,
    interfaces: str,
    attach: tuple[Path, ...],
    references: Path,
) -> None:
    """Compile the Modelica source into FMI 2.0 or 3.0 FMUs (Co-Simulation and/or Model Exchange);
    by default every shipped plant into ./fmus of the current folder, then the controller FMU
    (fmus/ToggleVSC.fmu, FMI 2.0, and fmus/ToggleVSC3.fmu, FMI 3.0). Each plant FMU carries its
    Modelica source and, a shipped plant, the shipped scenarios with their references (FMI-LS-REF)."""
    suffix = ("3" if fmi_version == "3.0" else "") + INTERFACE_TAGS[interfaces]
    if model is None and output is not None:
        model = DEFAULT_MODEL
    if model is None:
        for name, path in DEFAULT_BUILDS:
            target = path.with_name(f"{path.stem}{suffix}.fmu")
            build_plant(source, name, target, fmi_version, interfaces, attach, references)
        build_controller(DEFAULT_CONTROLLER, "2.0")
        build_controller(DEFAULT_CONTROLLER.with_name(f"{CONTROLLER}3.fmu"), "3.0")
        return
    if model == CONTROLLER:
        if attach:
            raise InputError(f"{CONTROLLER} carries no scenarios (--attach is for plant FMUs)")
        if interfaces == "me":
            raise InputError(f"{CONTROLLER} is a Co-Simulation FMU only (fix --interfaces: cs or both)")
        tag = "3" if fmi_version == "3.0" else ""
        build_controller(output or DEFAULT_CONTROLLER.with_name(f"{CONTROLLER}{tag}.fmu"), fmi_version)
        return
    default = dict(DEFAULT_BUILDS).get(model, Path("fmus") / f"{model.split('.')[-1]}.fmu")
    target = output or default.with_name(f"{default.stem}{suffix}.fmu")
    build_plant(source, model, target, fmi_version, interfaces, attach, references)
