"""Verify an FMU against what it carries (FMI-LS-REF): its manifest's files present and matching
their checksums, every file its SRMD (`metadata.py`) names matching too, then every carried
experiment run and funnel-compared with its reference (`analysis.compare`, as `toggle-cosim
references` compares).

An experiment with a carried scenario, in an FMU that meets our plant contract, runs through our
co-simulation master (the scenario's controller closes the loop); any other runs with FMPy's
`simulate_fmu` (Co-Simulation if offered, else Model Exchange): its start, stop, output
interval and tolerance, start values from the carried SSV, inputs from the carried CSV stimuli.
A `result` the manifest lists that no experiment names is held against the FMU's default
experiment (how the Reference FMUs carry their reference results).
"""

from __future__ import annotations

import functools
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from toggle_cosim.analysis.compare import (
    DEFAULT_TOLERANCE,
    ComparisonResult,
    Tolerance,
    compare_traces,
    load_tolerances,
)
from toggle_cosim.analysis.csv_traces import CompareInputError, read_trace
from toggle_cosim.files.bounded import MiB
from toggle_cosim.files.traces import Trace
from toggle_cosim.fmi_ls_ref.experiments import MIME, Experiment, read_experiments
from toggle_cosim.fmi_ls_ref.manifest import LsRefError, check_members, read_manifest, read_member
from toggle_cosim.fmi_ls_ref.metadata import check_record
from toggle_cosim.fmi_ls_ref.pack import open_fmu
from toggle_cosim.ssp.checks import SspError, parse_xml, schema_problem

CARRIED_LIMIT = 64 * MiB  # one carried CSV, SSV or scenario
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
SSV_TYPES = {"Real": float, "Integer": int, "Boolean": lambda text: text.strip().lower() in {"true", "1"}}


@dataclass(frozen=True)
class ExperimentCheck:
    """One carried experiment, run and compared: its name, the run's trace, the reference, the
    comparison, and how it ran ("master" or "fmpy")."""

    label: str
    trace: Trace
    reference: Trace
    comparison: ComparisonResult
    runner: str

    @property
    def passed(self) -> bool:
        return self.comparison.passed


@dataclass(frozen=True)
class Verification:
    """An FMU verified against what it carries.

    Attributes:
        fmu: the FMU file.
        checks: one `ExperimentCheck` per carried experiment, in the manifest's order.
        skipped: the sources of carried experiment files of a format we do not run, and the experiments
            (document#name) that are not transient simulations or name no CSV References, with why.
        passed: every experiment's variables inside their funnels.
        failures: one line per variable outside its funnel, naming the experiment and variable.

    Example:
        >>> check = tc.verify_fmu("fmus/ToggleLSM.fmu")  # doctest: +SKIP
        >>> [(c.label, c.passed) for c in check.checks]  # doctest: +SKIP
    """

    fmu: Path
    checks: tuple[ExperimentCheck, ...]
    skipped: tuple[str, ...] = ()  # carried experiments we do not run: by source, or document#name (why)

    @property
    def passed(self) -> bool:
        return all(check.passed for check in self.checks)

    @property
    def failures(self) -> list[str]:
        return [
            f"{check.label}: {v.name} off by {v.max_error:.3g} at t = {v.time_of_max_error:.4g} s"
            for check in self.checks
            for v in check.comparison.variables
            if not v.passed
        ]


def _extract(archive: zipfile.ZipFile, member: str, folder: Path, where: str) -> Path:
    """A carried member written into `folder` under its own base name (for the bounded readers)."""
    data = read_member(archive, member, where, CARRIED_LIMIT)
    path = folder / member.replace("/", "__")
    path.write_bytes(data)
    return path


def ssv_values(data: bytes, where: str) -> dict[str, float | int | bool]:
    """The values of an SSP 1.0 parameter set (SSV), by parameter name; LsRefError naming `where`."""
    try:
        root = parse_xml(data, where)
    except SspError as error:
        raise LsRefError(str(error)) from None
    problem = schema_problem(root, "ssv")
    if problem is not None:
        raise LsRefError(f"{where}: not a valid SSP 1.0 parameter set ({problem})")
    values: dict[str, float | int | bool] = {}
    for parameter in root.iterfind(f"{{{SSV_NS}}}Parameters/{{{SSV_NS}}}Parameter"):
        for kind, convert in SSV_TYPES.items():
            typed = parameter.find(f"{{{SSV_NS}}}{kind}")
            if typed is not None:
                values[parameter.get("name")] = convert(typed.get("value"))
    return values


def _structured(trace: Trace) -> np.ndarray:
    dtype = [(name, np.float64) for name in trace.names]
    return np.rec.fromarrays(trace.data.T, dtype=dtype)


def run_with_fmpy(
    fmu: Path, experiment: Experiment, parameters: dict, stimuli: Trace | None, outputs: list[str]
) -> Trace:
    """The experiment run by FMPy's `simulate_fmu`, the reference's variables recorded."""
    from fmpy import simulate_fmu

    description = _description(fmu)
    known = {variable.name for variable in description.modelVariables}
    missing = [name for name in outputs if name not in known]
    if missing:
        raise LsRefError(f"{fmu}: experiment {experiment.name!r}: the FMU has no variable {', '.join(missing)}")
    kind = "CoSimulation" if description.coSimulation is not None else "ModelExchange"
    try:
        result = simulate_fmu(
            str(fmu),
            start_time=experiment.start,
            stop_time=experiment.stop,
            output_interval=experiment.step,
            step_size=experiment.step if kind == "ModelExchange" else None,
            relative_tolerance=experiment.tolerance,
            start_values=parameters,
            input=None if stimuli is None else _structured(stimuli),
            output=outputs,
            fmi_type=kind,
        )
    except Exception as error:  # noqa: BLE001 - the FMU's own failure, reported in one line
        raise LsRefError(
            f"{fmu}: experiment {experiment.name!r} failed to run: {' '.join(str(error).split())}"
        ) from None
    names = ("time", *outputs)
    return Trace(names, np.column_stack([np.asarray(result[name], dtype=np.float64) for name in names]))


@dataclass
class OurPlant:
    """The FMU under verification as our plant, checked against the contract and its binary
    probed once for all its experiments (`check_plant`, `probe_binary`: both read the whole FMU)."""

    fmu: Path
    _plant: object = None
    _checked: bool = False
    _probed: bool = False

    def checked(self) -> object:
        """The checked `PlantInterface`, or None if the FMU does not meet our plant contract."""
        from toggle_cosim.plant.contract import ContractError, check_plant

        if not self._checked:
            try:
                self._plant = check_plant(self.fmu)
            except ContractError:
                self._plant = None
            self._checked = True
        return self._plant

    def probe(self) -> None:
        """Probe its binary (once: ProbeError as `probe_binary` raises it)."""
        from toggle_cosim.plant.probe import probe_binary

        if not self._probed:
            probe_binary(self._plant)
            self._probed = True


def run_with_master(
    fmu: Path, scenario: Path, variant: str | None, name: str, plant_of: OurPlant | None = None
) -> Trace | None:
    """The experiment's scenario run through our master on `fmu` (in a supervised child, as
    `toggle-cosim run` runs it), if `fmu` meets our plant contract; None if it does not (then
    FMPy runs the experiment). A carried scenario is data only: one that names code or FMUs
    (controller.python, controller.fmu, components) is refused, so an FMU cannot make verify run
    a file it does not carry. `plant_of`: the FMU as our plant, kept for all its experiments."""
    from toggle_cosim.control.protocol import ControllerError
    from toggle_cosim.cosim.checked import SystemError_, check_run
    from toggle_cosim.cosim.isolation.supervision import remove_stale_folders, simulate_supervised
    from toggle_cosim.experiments.scenario import ScenarioError, load_scenario
    from toggle_cosim.plant.probe import ProbeError
    from toggle_cosim.plant.settings import SettingError, check_settings

    plant_of = plant_of if plant_of is not None else OurPlant(fmu)
    plant = plant_of.checked()
    if plant is None:
        return None
    try:
        runs = load_scenario(scenario)
    except ScenarioError as error:
        raise LsRefError(f"{fmu}: experiment {name!r}: its scenario is not valid: {error}") from None
    chosen = [run for run in runs if run.variant == variant]
    if not chosen:
        raise LsRefError(f"{fmu}: experiment {name!r}: its scenario has no variant {variant!r}")
    run = replace(chosen[0], fmu=fmu)
    if run.controller.python is not None or run.controller.fmu is not None or run.system.parts:
        raise LsRefError(
            f"{fmu}: experiment {name!r}: its scenario names code or FMUs beside it (controller.python, "
            f"controller.fmu or components), which verify does not run (refused)"
        )
    try:
        plant_of.probe()
        check_settings(run, plant)
        checked = check_run(run, plant)  # the run's one check: the supervised run uses it
    except (ProbeError, SettingError, ControllerError, SystemError_) as error:
        raise LsRefError(f"{fmu}: experiment {name!r}: {error}") from None
    remove_stale_folders()
    outcome = simulate_supervised(run, plant, checked=checked)
    if not outcome.complete:
        raise LsRefError(f"{fmu}: experiment {name!r} failed to run: {outcome.reason}")
    return outcome.trace


def _description(fmu: Path):  # noqa: ANN202 - FMPy's ModelDescription
    """The FMU's model description read by FMPy; LsRefError in one line if it cannot be read."""
    from fmpy import read_model_description

    try:
        return read_model_description(str(fmu))
    except Exception as error:  # noqa: BLE001 - any malformed description, in one line
        raise LsRefError(f"{fmu}: its modelDescription.xml cannot be read ({' '.join(str(error).split())})") from None


Times = tuple[float, float, float, float | None]  # start, stop, step, tolerance


def _default_times(fmu: Path) -> Times:
    """The FMU's default experiment (start, stop, step, tolerance), with 0, 1 and (stop - start) / 500
    where it gives none."""
    default = _description(fmu).defaultExperiment
    start = float(default.startTime) if default is not None and default.startTime is not None else 0.0
    stop = float(default.stopTime) if default is not None and default.stopTime is not None else 1.0
    step = default.stepSize if default is not None and default.stepSize is not None else (stop - start) / 500
    tolerance = float(default.tolerance) if default is not None and default.tolerance is not None else None
    return start, stop, float(step), tolerance


def _with_times(experiment: Experiment, fmu: Path, default: Callable[[], Times]) -> Experiment:
    """The experiment with the times its document leaves out taken from the FMU's default
    experiment (`default`, read once for all of an FMU's experiments)."""
    if None not in (experiment.start, experiment.stop, experiment.step):
        return experiment
    start_0, stop_0, step_0, _ = default()
    start = start_0 if experiment.start is None else experiment.start
    stop = stop_0 if experiment.stop is None else experiment.stop
    step = experiment.step
    if step is None:
        step = step_0 if experiment.stop is None and experiment.start is None else (stop - start) / 500
    if stop <= start:
        raise LsRefError(f"{fmu}: experiment {experiment.name!r} stops at {stop:g} s, not after its start {start:g} s")
    return replace(experiment, start=start, stop=stop, step=step)


def carried(archive: zipfile.ZipFile, fmu: Path) -> tuple[list[Experiment], list[str]]:
    """The experiments the FMU carries (its manifest's members checked first), and the sources of
    experiment files of other formats (not run)."""
    where = str(fmu)
    related = read_manifest(archive, where)
    if related is None:
        raise LsRefError(
            f"{fmu}: carries no FMI-LS-REF manifest (pack experiments and references with toggle-cosim pack)"
        )
    check_members(archive, related, where)
    check_record(archive, where)
    experiments: list[Experiment] = []
    skipped: list[str] = []
    default = functools.cache(lambda: _default_times(fmu))
    for entry in related:
        if entry.main_role != "experiment":
            continue
        if entry.type != MIME:
            skipped.append(entry.source)
            continue
        data = read_member(archive, entry.member, where)
        found, passed_over = read_experiments(data, f"{fmu}: {entry.member}", entry.source)
        experiments += [_with_times(experiment, fmu, default) for experiment in found]
        skipped += passed_over
    named = {experiment.reference for experiment in experiments}
    for entry in related:
        if entry.main_role == "result" and entry.source not in named and entry.source.lower().endswith(".csv"):
            start, stop, step, tolerance = default()
            name = f"default_experiment/{Path(entry.source).stem}"
            experiments.append(Experiment(name, start, stop, step, entry.source, tolerance))
    if not experiments and skipped:
        raise LsRefError(
            f"{fmu}: carries no experiment toggle-cosim can verify ({', '.join(skipped)}); "
            f"pack a reference with toggle-cosim pack"
        )
    if not experiments:
        raise LsRefError(f"{fmu}: its FMI-LS-REF manifest lists no experiment or result to verify")
    return experiments, skipped


def _carried_trace(path: Path, fmu: Path, source: str) -> Trace:
    """A carried CSV trace, read strictly (`read_trace`); LsRefError naming the FMU and the file."""
    try:
        return read_trace(path)
    except CompareInputError as error:
        raise LsRefError(str(error).replace(str(path), f"{fmu}: {source}")) from None


def _tolerances(path: Path | None) -> tuple[Tolerance, dict[str, Tolerance]]:
    if path is None:
        return DEFAULT_TOLERANCE, {}
    try:
        return load_tolerances(path)
    except (CompareInputError, ValueError) as error:
        raise LsRefError(str(error)) from None


def verify_fmu(fmu: Path, progress: Callable[[str], None] | None = None) -> Verification:
    """Run every experiment `fmu` carries and compare it with its reference. LsRefError (one
    line naming the file) for an FMU whose carried files are missing, altered or invalid."""
    from toggle_cosim.fmi_ls_ref.manifest import member_of

    fmu = Path(fmu)
    checks = []
    with open_fmu(fmu) as archive, tempfile.TemporaryDirectory(prefix="toggle-cosim-verify-") as scratch:
        experiments, skipped = carried(archive, fmu)
        folder = Path(scratch)

        ours = OurPlant(fmu)  # checked and probed once, for every experiment run by our master

        @functools.cache  # a member shared by several experiments (a scenario, its tolerances) is extracted once
        def file(source: str | None) -> Path | None:
            return None if source is None else _extract(archive, member_of(source), folder, str(fmu))

        for experiment in experiments:
            if progress is not None:
                progress(experiment.name)
            reference = _carried_trace(file(experiment.reference), fmu, experiment.reference)
            default, per_variable = _tolerances(file(experiment.tolerances))
            trace, runner = None, "fmpy"
            if experiment.scenario is not None:
                trace = run_with_master(fmu, file(experiment.scenario), experiment.variant, experiment.name, ours)
                runner = "master"
            if trace is None:
                runner = "fmpy"
                parameters = {}
                if experiment.parameters is not None:
                    parameters = ssv_values(file(experiment.parameters).read_bytes(), f"{fmu}: {experiment.parameters}")
                stimuli = None
                if experiment.stimuli is not None:
                    stimuli = _carried_trace(file(experiment.stimuli), fmu, experiment.stimuli)
                trace = run_with_fmpy(fmu, experiment, parameters, stimuli, list(reference.names[1:]))
            try:
                comparison = compare_traces(
                    trace,
                    reference,
                    per_variable,
                    default,
                    result_label=f"{experiment.name} run",
                    reference_label=f"{fmu}: {experiment.reference}",
                )
            except CompareInputError as error:
                raise LsRefError(str(error)) from None
            checks.append(ExperimentCheck(experiment.name, trace, reference, comparison, runner))
    return Verification(fmu, tuple(checks), tuple(skipped))
