"""Run an SSP archive in other co-simulation masters and return their traces (a test helper).

Each `run_in_*` takes the path of an `.ssp` archive, the name of the parameter set to apply (the
`name` of an `.ssv` ParameterSet bound in the SSD, or None), the communication step T_s [s] and
the end time t_end [s], and returns a pandas DataFrame with a column `time` and one column
`<component>.<variable>` per Real input, output and parameter the master reports (FMPy: per
connector), one row per communication
point on the master's own time grid (row k holds the values at t_k). What each master does with
the SSP, measured with a stand-in controller in tests/test_other_masters.py and written up in
docs/other-masters.md:

- libcosim (libcosimpy 0.0.6, `CosimExecution.from_ssp_file`): a Jacobi master. It reads the
  *unpacked* SSP (the folder: its SystemStructure.ssd; or the path of another root SSD, a
  variant), applies the parameter bindings of the components (not the system's), and of those
  only the first binding of each component (libcosimc creates the execution with the parameter
  set named ""; its loader fills that set with each component's first binding). To apply the
  set asked for in an SSD that stacks several, `run_in_libcosim` removes the other bindings from
  the unpacked SSD; `ssd=` names the root SSD to load instead.
  The step is an integer number of nanoseconds; t_k = k T_s exactly in integer nanoseconds.
- ecos (ecospy 0.7.2, `EcosSimulation(ssp_path=...)`): a Jacobi master that loads the archive's
  SystemStructure.ssd only and applies a parameter set only when it is named in `init` (a set
  bound in SystemStructure.ssd), and silently applies nothing for a name it does not know (so
  `run_in_ecos` checks the name first). Its time accumulates t + T_s.
- FMPy 0.3.32 (`fmpy.ssp.simulate_ssp`): a Jacobi master whose connections start at 0.0 (the
  controller's first sample sees x_B = 0 and the plant's first step gets iq_ref = 0) and that
  ignores the SSD's parameter bindings: `run_in_fmpy` passes the named set explicitly, with the
  component prefixes simulate_ssp expects. FMPy labels the values after the step from t_k with
  t_k; the DataFrame labels them t_{k+1}.
"""

from __future__ import annotations

import shutil
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import pandas as pd
from lxml import etree

SSD = "SystemStructure.ssd"
NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
}
NANOSECOND = 1e-9


@dataclass(frozen=True)
class Binding:
    """One ParameterBinding of an SSD: where it sits and the parameter set it applies."""

    element: str  # the component's name, or "" for the system
    set_name: str  # the ParameterSet's name attribute
    values: dict[str, float]  # parameter name (as written in the set) -> value


def steps(T_s: float, t_end: float) -> int:
    """The number of communication steps from 0 to t_end (t_end a multiple of T_s)."""
    n = round(t_end / T_s)
    if n < 1 or abs(n * T_s - t_end) > 1e-9 * t_end:
        raise ValueError(f"t_end = {t_end} s is not a positive multiple of T_s = {T_s} s")
    return n


def _ssd_root(ssp_path: Path) -> etree._Element:
    with zipfile.ZipFile(ssp_path) as archive:
        return etree.fromstring(archive.read(SSD))


def _parameter_set(node: etree._Element) -> tuple[str, dict[str, float]]:
    values = {}
    for parameter in node.iterfind("ssv:Parameters/ssv:Parameter", NS):
        real = parameter.find("ssv:Real", NS)
        if real is not None:
            values[parameter.get("name")] = float(real.get("value"))
    return node.get("name", ""), values


def bindings(ssp_path: Path) -> list[Binding]:
    """Every ParameterBinding of the SSD's system and components, in document order."""
    root = _ssd_root(ssp_path)
    found = []
    with zipfile.ZipFile(ssp_path) as archive:
        for binding in root.iterfind(".//ssd:ParameterBinding", NS):
            element = binding.getparent().getparent()
            owner = element.get("name", "") if element.tag == f"{{{NS['ssd']}}}Component" else ""
            source = binding.get("source")
            if source is not None:
                node = etree.fromstring(archive.read(source))
            else:
                node = binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
            name, values = _parameter_set(node)
            found.append(Binding(owner, name, values))
    return found


def _check_set(ssp_path: Path, parameter_set: str | None) -> list[Binding]:
    found = [b for b in bindings(ssp_path) if b.set_name == parameter_set]
    if parameter_set is not None and not found:
        known = sorted({b.set_name for b in bindings(ssp_path)})
        raise ValueError(f"{ssp_path}: no parameter set named {parameter_set!r} (it has {known})")
    return found


def _real_variables(fmu: Path, causalities=("input", "output", "parameter")) -> list[tuple[str, int]]:
    """(name, value reference) of an FMU's Real variables of the given causalities."""
    import fmpy

    description = fmpy.read_model_description(fmu, validate=False)
    return [
        (v.name, v.valueReference)
        for v in description.modelVariables
        if v.type in ("Real", "Float64") and v.causality in causalities
    ]


def _components(ssp_dir: Path) -> dict[str, Path]:
    root = etree.parse(str(ssp_dir / SSD)).getroot()
    return {
        c.get("name"): ssp_dir / c.get("source") for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)
    }


@contextmanager
def unpacked(ssp_path: Path) -> Iterator[Path]:
    """The SSP archive unpacked into a temporary folder (refusing names that leave it)."""
    folder = Path(tempfile.mkdtemp(prefix="ssp-"))
    try:
        with zipfile.ZipFile(ssp_path) as archive:
            for name in archive.namelist():
                path = PurePosixPath(name)
                if path.is_absolute() or ".." in path.parts:
                    raise ValueError(f"{ssp_path}: unsafe member name {name!r}")
            archive.extractall(folder)
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _keep_only(ssp_dir: Path, parameter_set: str) -> None:
    """Leave in the unpacked SSD only the component bindings of the named set (libcosimc applies
    the first binding of each component and has no way to name a set)."""
    path = ssp_dir / SSD
    tree = etree.parse(str(path))
    for binding in list(tree.getroot().iterfind(".//ssd:Component/ssd:ParameterBindings/ssd:ParameterBinding", NS)):
        source = binding.get("source")
        node = (
            etree.parse(str(ssp_dir / source)).getroot()
            if source is not None
            else binding.find("ssd:ParameterValues/ssv:ParameterSet", NS)
        )
        if node.get("name") != parameter_set:
            binding.getparent().remove(binding)
    tree.write(str(path), xml_declaration=True, encoding="UTF-8")


def run_in_libcosim(
    ssp_path: Path, parameter_set: str | None, T_s: float, t_end: float, ssd: str | None = None
) -> pd.DataFrame:
    """Run the SSP in libcosim (libcosimpy) with a fixed step T_s to t_end; `ssd`: the root SSD
    (a variant) to load, by its member name (None: SystemStructure.ssd, the unpacked folder).

    Records every Real input, output and parameter of every component at t_0 ... t_n with a time-series
    observer (rows 0..n-1; libcosimpy 0.0.6's `time_series_real_samples` drops the last sample it
    holds, so row n comes from a last-value observer). `time` is libcosim's integer nanoseconds
    in seconds. parameter_set None: libcosim's own choice (each component's first binding).
    """
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    if ssd is None:
        _check_set(ssp_path, parameter_set)
    n = steps(T_s, t_end)
    step_ns = round(T_s / NANOSECOND)
    if abs(step_ns * NANOSECOND - T_s) > 1e-12 * T_s:
        raise ValueError(f"libcosim's step is whole nanoseconds: T_s = {T_s} s is not")
    log_output_level(CosimLogLevel.WARNING)
    with unpacked(ssp_path) as folder:
        if parameter_set is not None:
            _keep_only(folder, parameter_set)
        loaded = folder if ssd is None else folder / ssd
        if not loaded.exists():
            raise ValueError(f"{ssp_path}: no root SSD {ssd!r}")
        execution = CosimExecution.from_ssp_file(str(loaded), step_size=step_ns)
        index = {info.name.decode(): info.index for info in execution.slave_infos()}
        series = CosimObserver.create_time_series()
        last = CosimObserver.create_last_value()
        execution.add_observer(series)
        execution.add_observer(last)
        columns = []
        for component, fmu in _components(folder).items():
            for name, reference in _real_variables(fmu):
                series.start_time_series(index[component], reference, CosimVariableType.REAL)
                columns.append((f"{component}.{name}", index[component], reference))
        if not execution.simulate_until(n * step_ns):
            raise RuntimeError(f"libcosim stopped before t_end = {t_end} s")
        data: dict[str, list[float]] = {}
        for label, slave, reference in columns:
            times, step_numbers, values = series.time_series_real_samples(slave, reference, 0, n + 1)
            if list(step_numbers) != list(range(n)):
                raise RuntimeError(
                    f"libcosim's time series of {label} has steps {step_numbers[:3]}...{step_numbers[-3:]}"
                )
            data["time"] = [t / 1e9 for t in times] + [n * step_ns / 1e9]  # as libcosim converts its nanoseconds
            data[label] = list(values) + [last.last_real_values(slave, [reference])[0]]
        del execution
    return pd.DataFrame(data)


def run_in_ecos(ssp_path: Path, parameter_set: str | None, T_s: float, t_end: float) -> pd.DataFrame:
    """Run the SSP archive in ecos (ecospy) with a fixed step T_s to t_end.

    The set is applied by name in `init` (ecos applies nothing when none is named, and nothing,
    silently, for an unknown name: this refuses an unknown name first). Records every Real input,
    output and parameter of every component after `init` and after each step; `time` is ecos's own.
    """
    from ecospy import EcosLib, EcosSimulation

    _check_set(ssp_path, parameter_set)
    n = steps(T_s, t_end)
    EcosLib.set_log_level("warn")
    with unpacked(ssp_path) as folder:
        identifiers = [
            (f"{component}.{name}", f"{component}::{name}")
            for component, fmu in _components(folder).items()
            for name, _ in _real_variables(fmu)
        ]
    rows = []
    with EcosSimulation(ssp_path=str(ssp_path), step_size=T_s) as sim:
        if not sim.init(0.0, parameter_set):
            raise RuntimeError(f"ecos could not initialise {ssp_path}: {EcosLib.get_last_error()}")
        try:
            for k in range(n + 1):
                if k:
                    sim.step()
                rows.append([sim.get_time()] + [sim.get_real(identifier) for _, identifier in identifiers])
        finally:
            sim.terminate()
    return pd.DataFrame(rows, columns=["time"] + [label for label, _ in identifiers])


def explicit_parameter_set(ssp_path: Path, parameter_set: str):
    """The named set as the one fmpy ParameterSet simulate_ssp takes: component bindings' names
    get the component's prefix; the system's bindings are taken as written."""
    from fmpy.ssp.ssd import Parameter, ParameterSet

    parameters = [
        Parameter(name=f"{b.element}.{name}" if b.element else name, value=value)
        for b in _check_set(ssp_path, parameter_set)
        for name, value in b.values.items()
    ]
    return ParameterSet(name=parameter_set, parameters=parameters)


def unconnected_inputs(ssp_path: Path) -> list[str]:
    """Input connectors of components that no connection ends at."""
    root = _ssd_root(ssp_path)
    ends = {(c.get("endElement"), c.get("endConnector")) for c in root.iterfind(".//ssd:Connection", NS)}
    return [
        f"{component.get('name')}.{connector.get('name')}"
        for component in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)
        for connector in component.iterfind("ssd:Connectors/ssd:Connector", NS)
        if connector.get("kind") == "input" and (component.get("name"), connector.get("name")) not in ends
    ]


def run_in_fmpy(ssp_path: Path, parameter_set: str | None, T_s: float, t_end: float) -> pd.DataFrame:
    """Run the SSP archive in FMPy's `simulate_ssp` with a step T_s to t_end.

    The named set is passed explicitly (simulate_ssp drops the SSD's bindings). Refuses an SSD
    that declares an input connector no connection feeds: fmpy 0.3.32's `get_connections` then
    connects it to the source of the input listed before it (an F_E connector would be driven
    by iq_ref). Returns FMPy's rows, whose values are those after the step from the row's
    time: the DataFrame gets t_0 = 0 with NaN values (FMPy reports nothing at t_0) and labels
    FMPy's row t_k as t_k + T_s (FMPy's next time, accumulated as FMPy does).
    """
    from fmpy.ssp.simulation import simulate_ssp

    loose = unconnected_inputs(ssp_path)
    if loose:
        raise ValueError(
            f"{ssp_path}: FMPy's simulate_ssp would drive the unconnected input connectors {loose} "
            "from another connection; leave them out of the SSD's connectors"
        )
    explicit = None if parameter_set is None else explicit_parameter_set(ssp_path, parameter_set)
    result = simulate_ssp(str(ssp_path), start_time=0.0, stop_time=t_end, step_size=T_s, parameter_set=explicit)
    frame = pd.DataFrame({name: result[name] for name in result.dtype.names})
    frame["time"] = frame["time"] + T_s
    first = pd.DataFrame({name: [0.0 if name == "time" else float("nan")] for name in frame.columns})
    return pd.concat([first, frame], ignore_index=True)
