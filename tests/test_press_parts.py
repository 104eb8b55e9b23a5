"""The press example's parts (examples/press_system/): the sensor and the die load, each built
by our build from its Modelica file and checked on its own, without a master.

* PositionSensor: a first-order low-pass T_f dy/dt = u - y on position and velocity, the
  outputs read off the filter states. From rest at x0 with a constant input x0 + dx, the
  state is x0 + dx (1 - exp(-t / T_f)): after one time constant 1 - 1/e = 63.2 % of the step.
  Checked within 1e-6 relative of the step over five time constants (the FMU's integrator
  runs at relTol 1e-8; a filter with T_f off by 0.1 % misses by 2.6e-4 at t = T_f). The
  outputs do not move when an input is set without a step (no direct feedthrough), and the
  description says so.
* DieLoad: F = k_c max(x - x_c, 0), evaluated at once from the input (direct feedthrough,
  declared in ModelStructure), exact to 1e-12 relative: zero below the contact, the spring
  above.
"""

from __future__ import annotations

import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import PRESS_SYSTEM
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from toggle_cosim.fmu_export import build_fmu
from toggle_cosim.fmu_export.compile import compile_model
from toggle_cosim.fmu_export.interfaces import CO_SIMULATION, MODEL_EXCHANGE
from toggle_cosim.fmu_export.model_description import fmi2_model_description, fmi3_model_description

ROOT = Path(__file__).resolve().parent.parent
X0 = 0.2329  # the stroke's start, the sensor's default x0 [m]
X_END = 0.3199  # the stroke's end [m]


@pytest.fixture(scope="module")
def press_parts3(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The two parts as FMI 3.0 Co-Simulation FMUs (the session fixture builds FMI 2.0)."""
    folder = tmp_path_factory.mktemp("press-parts3")
    return {
        name: build_fmu(PRESS_SYSTEM / f"{name}.mo", name, folder / f"{name}3.fmu", "3.0", "cs").fmu.path
        for name in ("PositionSensor", "DieLoad")
    }


def _fmu(press_parts, press_parts3, name: str, version: str) -> Path:
    return (press_parts if version == "2.0" else press_parts3)[name]


class _Live:
    """One instance of a part, initialised, for get/set without any step."""

    def __init__(self, path: Path, parameters: dict[str, float] | None = None) -> None:
        self.description = read_model_description(str(path))
        self.folder = extract(str(path))
        self.references = {v.name: v.valueReference for v in self.description.modelVariables}
        self.fmu = instantiate_fmu(self.folder, self.description, fmi_type="CoSimulation")
        version = self.description.fmiVersion
        if version == "2.0":
            self.fmu.setupExperiment(startTime=0.0)
        for name, value in (parameters or {}).items():
            self.set(name, value)
        if version == "2.0":
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def set(self, name: str, value: float) -> None:
        write = self.fmu.setReal if self.description.fmiVersion == "2.0" else self.fmu.setFloat64
        write([self.references[name]], [value])

    def get(self, name: str) -> float:
        read = self.fmu.getReal if self.description.fmiVersion == "2.0" else self.fmu.getFloat64
        return read([self.references[name]])[0]

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self.folder, ignore_errors=True)


def _dependencies(path: Path) -> dict[str, list[str]]:
    """Each output's declared dependencies, by name (fmpy reads FMI 2.0 and 3.0 alike)."""
    md = read_model_description(str(path))
    return {u.variable.name: sorted(v.name for v in u.dependencies) for u in md.outputs}


# ---------------------------------------------------------------------------------------
# PositionSensor
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("t_f", [2e-4, 1e-3], ids=["default", "slower"])
def test_sensor_step_response_is_the_first_order_lag(press_parts, press_parts3, version, t_f):
    """Position and velocity steps from rest: x0 + dx (1 - exp(-t/T_f)) and dv (1 - exp(-t/T_f)),
    63.2 % after one time constant, within 1e-6 of the step, stepped every T_f / 20."""
    dx, dv = 0.01, 0.5
    signal = np.array([(0.0, X0 + dx, dv), (1.0, X0 + dx, dv)], dtype=[("time", float), ("x", float), ("v", float)])
    start = {} if t_f == 2e-4 else {"T_f": t_f}  # the default must be 0.2 ms as declared
    result = simulate_fmu(
        str(_fmu(press_parts, press_parts3, "PositionSensor", version)),
        stop_time=5 * t_f,
        output_interval=t_f / 20,
        input=signal,
        start_values=start,
        output=["x_m", "v_m", "solver.events"],
    )
    t = result["time"]
    lag = 1.0 - np.exp(-t / t_f)
    assert np.max(np.abs((result["x_m"] - X0) / dx - lag)) < 1e-6
    assert np.max(np.abs(result["v_m"] / dv - lag)) < 1e-6
    (k,) = np.flatnonzero(np.isclose(t, t_f, rtol=0, atol=1e-15))
    assert (result["x_m"][k] - X0) / dx == pytest.approx(1 - math.exp(-1), rel=1e-6)
    assert result["v_m"][k] / dv == pytest.approx(1 - math.exp(-1), rel=1e-6)
    assert result["solver.events"][-1] == 0


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_sensor_outputs_do_not_follow_an_input_without_a_step(press_parts, press_parts3, version):
    """No direct feedthrough: outputs are the filter states, so setting x and v changes
    nothing until time advances; the description declares the states, not the inputs."""
    path = _fmu(press_parts, press_parts3, "PositionSensor", version)
    live = _Live(path, {"x0": 0.25, "v0": 0.1})
    try:
        assert (live.get("x_m"), live.get("v_m")) == (0.25, 0.1)
        live.set("x", 0.3)
        live.set("v", -2.0)
        assert (live.get("x_m"), live.get("v_m")) == (0.25, 0.1)
    finally:
        live.close()
    assert _dependencies(path) == {"x_m": ["x_f"], "v_m": ["v_f"]}


@pytest.mark.parametrize("resolution", [1e-4, 2.5e-6])
def test_sensor_quantises_the_position_to_its_resolution_without_events(press_parts, resolution):
    """x_m = resolution round(x_f / resolution) (half up) at every output, the filter itself
    untouched (v_m unquantised); no events; resolution 0 reports x_f bit for bit."""
    signal = np.array([(0.0, X0, 0.0), (1e-3, X_END, 0.4)], dtype=[("time", float), ("x", float), ("v", float)])
    common = {"stop_time": 1e-3, "output_interval": 1e-5, "input": signal}
    names = ["x_m", "x_f", "v_m", "v_f", "solver.events"]
    path = str(press_parts["PositionSensor"])
    plain = simulate_fmu(path, output=names, **common)
    quantised = simulate_fmu(path, start_values={"resolution": resolution}, output=names, **common)
    assert np.array_equal(plain["x_m"], plain["x_f"])
    assert np.array_equal(quantised["x_f"], plain["x_f"])  # the quantiser does not act on the filter
    assert np.array_equal(quantised["v_m"], plain["v_f"])
    assert np.array_equal(quantised["x_m"], resolution * np.floor(quantised["x_f"] / resolution + 0.5))
    assert np.max(np.abs(quantised["x_m"] - quantised["x_f"])) <= resolution / 2 * (1 + 1e-9)
    assert np.ptp(quantised["x_m"]) > 100 * resolution  # it moved over many counts
    assert quantised["solver.events"][-1] == 0


# ---------------------------------------------------------------------------------------
# DieLoad
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize(
    "parameters, x_c, k_c",
    [({}, 0.31, 1e4), ({"x_c": 0.3, "k_c": 5e4}, 0.3, 5e4)],
    ids=["defaults", "set"],
)
def test_die_load_is_zero_before_contact_and_a_spring_after(press_parts, press_parts3, version, parameters, x_c, k_c):
    """F = k_c max(x - x_c, 0), read right after setting x (no step: direct feedthrough),
    across the stroke and a little past it, exact to 1e-12 relative."""
    live = _Live(_fmu(press_parts, press_parts3, "DieLoad", version), parameters)
    try:
        for x in [*np.linspace(X0, X_END + 0.005, 89), x_c, np.nextafter(x_c, 1.0), x_c + 1e-9]:
            live.set("x", float(x))
            force = live.get("F")
            if x <= x_c:
                assert force == 0.0, x
            else:
                assert force == pytest.approx(k_c * (x - x_c), rel=1e-12, abs=0.0), x
    finally:
        live.close()


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_die_load_declares_its_direct_feedthrough(press_parts, press_parts3, version):
    assert _dependencies(_fmu(press_parts, press_parts3, "DieLoad", version)) == {"F": ["x"]}


# ---------------------------------------------------------------------------------------
# What both descriptions say
# ---------------------------------------------------------------------------------------

UNITS = {
    "PositionSensor": {
        "T_f": "s",
        "resolution": "m",
        "x0": "m",
        "v0": "m/s",
        "x": "m",
        "v": "m/s",
        "x_f": "m",
        "v_f": "m/s",
        "x_m": "m",
        "v_m": "m/s",
    },
    "DieLoad": {"x_c": "m", "k_c": "N/m", "x": "m", "F": "N"},
}


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("name", ["PositionSensor", "DieLoad"])
def test_parts_validate_and_declare_a_unit_on_every_variable(press_parts, press_parts3, version, name):
    path = _fmu(press_parts, press_parts3, name, version)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    model = {v.name: v for v in md.modelVariables if v.name in UNITS[name]}
    assert {n: v.unit for n, v in model.items()} == UNITS[name]
    assert set(UNITS[name].values()) <= {u.name for u in md.unitDefinitions}
    causality = {n: v.causality for n, v in model.items()}
    if name == "DieLoad":
        assert causality == {"x_c": "parameter", "k_c": "parameter", "x": "input", "F": "output"}
    else:
        assert [n for n, c in causality.items() if c == "input"] == ["x", "v"]
        assert [n for n, c in causality.items() if c == "output"] == ["x_m", "v_m"]


@pytest.mark.parametrize("writer", [fmi2_model_description, fmi3_model_description])
def test_an_output_that_is_a_state_is_one_initial_unknown(writer):
    """GuidedMass's x_B and v_B are outputs and states: each is listed once in InitialUnknowns
    (FMI 2.0 sec. 2.2.8 and 3.0 sec. 2.4.8: an ordered list of unknowns, each once), ascending."""
    model = compile_model(ROOT / "examples" / "modelica_plant" / "GuidedMass.mo", "GuidedMass")
    text = writer(model, "GuidedMass", "tests", frozenset({CO_SIMULATION, MODEL_EXCHANGE}))
    root = ET.fromstring(text)
    if writer is fmi2_model_description:
        keys = [int(u.get("index")) for u in root.iterfind("ModelStructure/InitialUnknowns/Unknown")]
    else:
        keys = [int(u.get("valueReference")) for u in root.iterfind("ModelStructure/InitialUnknown")]
    assert keys == sorted(set(keys))
    assert len(keys) == 4  # x_B, v_B and their derivatives
