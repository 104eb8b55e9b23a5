"""What a plant FMU carries as its evidence (FMI-LS-REF): the Modelica source it was built from
(role `model`), and per scenario the scenario file (`configuration`), an SSV per variant
(`parameter`, the plant's constant values as `toggle-cosim ssp` writes them; an input that
varies in time is the scenario's), the stored reference of each
variant (`result`), the funnel tolerances (`configuration`) and one experiment document
(`experiment/validation`) naming them all, so that `toggle-cosim verify` reruns each variant
through the master and holds it against its reference.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import yaml

from toggle_cosim.analysis.compare import Tolerance
from toggle_cosim.files.bounded import MiB
from toggle_cosim.fmi_ls_ref.experiments import MIME, Experiment, experiments_xml
from toggle_cosim.fmi_ls_ref.manifest import LsRefError, Related
from toggle_cosim.fmi_ls_ref.pack import Attachment
from toggle_cosim.fmu_export.build_cache import source_files

SOURCE_LIMIT = 16 * MiB  # one Modelica file
SCENARIO_FOLDER = "scenarios"
MODEL_FOLDER = "model"


def model_attachments(source: Path) -> list[Attachment]:
    """The Modelica source (a .mo file, or a package folder's .mo files and package.order files),
    under `model/`, role `model`."""
    source = Path(source)
    files = [  # the files a build of `source` reads (`build_cache.source_files`), named as in the source
        (path, path.name if path == source else f"{source.name}/{path.relative_to(source).as_posix()}")
        for path in source_files(source)
    ]
    attachments = []
    for path, name in files:
        if path.stat().st_size > SOURCE_LIMIT:
            raise LsRefError(f"{path}: over the {SOURCE_LIMIT // MiB} MiB a carried Modelica file may have (refused)")
        kind = "text/x-modelica" if path.suffix == ".mo" else "text/plain"
        attachments.append(
            Attachment(Related(f"{MODEL_FOLDER}/{name}", "model", kind, "Modelica source"), path.read_bytes())
        )
    return attachments


def _tolerances_yaml(default: Tolerance, per_variable: dict[str, Tolerance]) -> bytes:
    def entry(tolerance: Tolerance) -> dict[str, float]:
        return {"atol": tolerance.atol, "rtol": tolerance.rtol, "ttol": tolerance.ttol}

    document = {"default": entry(default), **{name: entry(t) for name, t in per_variable.items()}}
    return yaml.safe_dump(document, sort_keys=False).encode()


def _standalone(scenario: Path) -> None:
    """A carried scenario is run from the FMU alone: refuse one that needs files beside it."""
    from toggle_cosim.experiments.scenario import ScenarioError, load_scenario

    with tempfile.TemporaryDirectory(prefix="toggle-cosim-pack-") as scratch:
        copy = Path(scratch) / scenario.name
        shutil.copyfile(scenario, copy)
        try:
            load_scenario(copy)
        except ScenarioError as error:
            raise LsRefError(
                f"{scenario}: needs files beside it, which an FMU cannot carry with it ({error}); "
                f"attach scenarios that stand alone"
            ) from None


def scenario_attachments(scenario: Path, references: Path, plant_fmu: Path) -> list[Attachment]:
    """What carries `scenario` in the plant FMU `plant_fmu`: the scenario, an SSV, the stored
    reference (from the `references` folder, as `toggle-cosim references` stores them) of each
    variant, the tolerances and the experiment document. LsRefError naming the file otherwise."""
    from toggle_cosim.experiments.references import REFERENCE_RELTOL, reference_stem, tolerances_for
    from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
    from toggle_cosim.plant.contract import ContractError, check_plant
    from toggle_cosim.ssp import layout
    from toggle_cosim.ssp.checks import SspError
    from toggle_cosim.ssp.fmus import FmuVariables
    from toggle_cosim.ssp.writer import parameter_sets, ssv_text

    scenario = Path(scenario)
    try:
        runs = load_scenario(scenario)
    except ScenarioError as error:
        raise LsRefError(str(error)) from None
    _standalone(scenario)
    try:
        plant = check_plant(Path(plant_fmu))
        sets = parameter_sets(runs, plant)
    except (ContractError, SspError) as error:
        raise LsRefError(str(error)) from None
    variables = FmuVariables.of(plant.path, plant.model_description)
    name = runs[0].scenario
    folder = f"{SCENARIO_FOLDER}/{name}"
    default, per_variable = tolerances_for(references, name)
    attachments = [
        Attachment(
            Related(f"{folder}/{scenario.name}", "configuration", "application/yaml", f"toggle-cosim scenario {name}"),
            scenario.read_bytes(),
        ),
        Attachment(
            Related(f"{folder}/tolerances.yaml", "configuration", "application/yaml", "funnel tolerances"),
            _tolerances_yaml(default, per_variable),
        ),
    ]
    experiments = []
    for run, parameter_set in zip(runs, sets, strict=True):
        variant = layout.set_name(run.variant)
        reference = Path(str(reference_stem(references, run)) + "_ref.csv")
        if not reference.is_file():
            raise LsRefError(
                f"{reference}: no stored reference for {run.label} (store it with toggle-cosim references --update)"
            )
        constants = [(key, value) for key, value in parameter_set.plant if isinstance(value, int | float)]
        ssv = ssv_text(parameter_set.name, constants, variables)
        labels = (f"variant:{variant}",)
        attachments += [
            Attachment(
                Related(f"{folder}/{variant}.ssv", "parameter", "application/x-ssp-parameter-set", run.label, labels),
                ssv,
            ),
            Attachment(
                Related(f"{folder}/{variant}_ref.csv", "result", "text/csv", run.label, labels), reference.read_bytes()
            ),
        ]
        experiments.append(
            Experiment(
                run.label,
                0.0,
                run.t_end,
                run.T_s,
                f"{variant}_ref.csv",
                REFERENCE_RELTOL,
                f"{variant}.ssv",
                None,
                "tolerances.yaml",
                scenario.name,
                run.variant,
            )
        )
    document = Related(f"{folder}/experiments.xml", "experiment/validation", MIME, f"the runs of scenario {name}")
    attachments.append(Attachment(document, experiments_xml(experiments, name, f"the runs of scenario {name}")))
    return attachments


def shipped_evidence(source: Path, scenarios: Sequence[Path], references: Path, plant_fmu: Path) -> list[Attachment]:
    """The model source and the scenarios' evidence, for the plant FMU `plant_fmu`."""
    attachments = model_attachments(source)
    for scenario in scenarios:
        attachments += scenario_attachments(scenario, references, plant_fmu)
    return attachments


def shipped_scenarios_for(plant_file: str) -> list[Path]:
    """The shipped scenarios whose `fmu:` key names the plant file `plant_file` (e.g.
    ToggleLSM.fmu) and that stand alone (need no file beside them), in the shipped order."""
    from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
    from toggle_cosim.experiments.shipped import SHIPPED_SCENARIO_FOLDER, SHIPPED_SCENARIOS

    chosen = []
    for name in SHIPPED_SCENARIOS:
        path = Path(SHIPPED_SCENARIO_FOLDER) / f"{name}.yaml"
        try:
            runs = load_scenario(path)
            _standalone(path)
        except (ScenarioError, LsRefError):
            continue
        if runs and runs[0].fmu is not None and runs[0].fmu.name == plant_file:
            chosen.append(path)
    return chosen
