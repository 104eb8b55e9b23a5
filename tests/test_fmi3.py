"""The plant built as an FMI 3.0 Co-Simulation FMU (shell/fmi3.c over the same solver core as
shell/fmi2.c), checked against the FMI standard as fmpy reads it and against the FMI 2.0 build.

What is checked: fmpy's validator finds no problem; the archive layout (binaries/<arch>-<os>,
sources/buildDescription.xml valid against the FMI 3.0 schema); every fmi3* function of
fmi3Functions.h is exported and nothing else of FMI; an open-loop run through FMU3Slave
agrees with the FMI 2.0 build (the `plant_fmu` fixture) driven identically to 1e-12 relative
(they share solver.c, so they agree bit for bit); FMU state get/set and serialise/deserialise
round trips are bit-exact; a wrong instantiationToken and other unsupported requests are
refused with a logged reason; the independent variable `time`; fmpy.simulate_fmu runs it.
"""

from __future__ import annotations

import ctypes
import math
import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow  # builds the FMI 3.0 plant and validates it

fmpy = pytest.importorskip("fmpy")

from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from fmpy.fmi3 import FMU3Slave, fmi3Boolean, fmi3Float64, fmi3FMUState, fmi3ValueReference  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
HEADERS = ROOT / "src" / "toggle_cosim" / "fmu_export" / "fmi_headers"  # vendored, BSD-2-Clause
SHELL = ROOT / "src" / "toggle_cosim" / "fmu_export" / "shell"

PARAMETERS = {"m_B": 8.86, "mu": 0.2, "idealCurrentLoop": False, "F_E": 50.0}
T_END, H = 0.3, 5e-4


def iq_ref(t: float) -> float:
    """Open loop: accelerate, brake, then a small hold current."""
    return 4.0 if t < 0.12 else (-2.5 if t < 0.24 else 0.5)


@pytest.fixture(scope="module")
def plant3_build(tmp_path_factory: pytest.TempPathFactory):
    from toggle_cosim.fmu_export import build_fmu

    output = tmp_path_factory.mktemp("fmu3") / "ToggleLSM3.fmu"
    return build_fmu(ROOT / "modelica" / "ToggleLSM", "ToggleLSM.Plant", output, fmi_version="3.0")


@pytest.fixture(scope="module")
def plant3_fmu(plant3_build) -> Path:
    return plant3_build.fmu.path


class Slave:
    """Either FMI version behind one small interface: names, not value references."""

    def __init__(self, path: Path, token: str | None = None, **instantiate_options) -> None:
        self.md = read_model_description(str(path))
        self.version = self.md.fmiVersion
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.dir = extract(str(path))
        self.log: list[tuple[int, str, str]] = []
        identifier = self.md.coSimulation.modelIdentifier
        if self.version == "3.0":
            self.fmu = FMU3Slave(
                guid=token or self.md.guid, unzipDirectory=self.dir, modelIdentifier=identifier, instanceName="test3"
            )

            def record(env, status, category, message):
                self.log.append((status, category.decode(), message.decode()))

            try:
                self.fmu.instantiate(logMessage=record, **instantiate_options)
            except Exception:
                self.fmu.freeLibrary()
                shutil.rmtree(self.dir, ignore_errors=True)
                raise
        else:
            self.fmu = FMU2Slave(
                guid=self.md.guid, unzipDirectory=self.dir, modelIdentifier=identifier, instanceName="test2"
            )
            self.fmu.instantiate()
        self.t = 0.0

    def vr(self, *names: str) -> list[int]:
        return [self.vars[n].valueReference for n in names]

    def start(self, **parameters: float | bool) -> Slave:
        if self.version == "2.0":
            self.fmu.setupExperiment(startTime=0.0)
        self.set(**parameters)
        if self.version == "3.0":
            self.fmu.enterInitializationMode(startTime=0.0)
        else:
            self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()
        return self

    def set(self, **values: float | bool) -> None:
        for name, value in values.items():
            boolean = self.vars[name].type == "Boolean"
            if self.version == "3.0":
                if boolean:
                    self.fmu.setBoolean(self.vr(name), [bool(value)])
                else:
                    self.fmu.setFloat64(self.vr(name), [float(value)])
            elif boolean:
                self.fmu.setBoolean(self.vr(name), [bool(value)])
            else:
                self.fmu.setReal(self.vr(name), [float(value)])

    def get(self, *names: str) -> list[float]:
        getter = self.fmu.getFloat64 if self.version == "3.0" else self.fmu.getReal
        return getter(self.vr(*names))

    def step(self, h: float):
        result = self.fmu.doStep(self.t, h)
        self.t += h
        return result

    def errors(self) -> str:
        return "\n".join(message for status, _, message in self.log if status >= 3)

    def close(self) -> None:
        self.fmu.terminate()
        self.free()

    def free(self) -> None:
        self.fmu.freeInstance()
        shutil.rmtree(self.dir, ignore_errors=True)


def outputs(md) -> list[str]:
    return [v.name for v in md.modelVariables if v.causality == "output" and v.type in ("Real", "Float64")]


def open_loop(slave: Slave, names: list[str], t_end: float = T_END, h: float = H) -> np.ndarray:
    rows = []
    for k in range(int(round(t_end / h))):
        slave.set(iq_ref=iq_ref(k * h))
        rows.append(slave.get(*names))
        slave.step(h)
    rows.append(slave.get(*names))
    return np.array(rows)


# ---------------------------------------------------------------------------------------
# The archive
# ---------------------------------------------------------------------------------------


def test_validates_with_fmpy(plant3_fmu: Path) -> None:
    assert validate_fmu(str(plant3_fmu)) == []


def test_archive_layout_and_descriptions(plant3_fmu: Path, plant3_build) -> None:
    """binaries/<arch>-<os>/<id>.so, the FMI 3.0 sources with a schema-valid
    buildDescription.xml, and the modelDescription essentials."""
    from lxml import etree

    from toggle_cosim.fmu_export.package import platform_tuple

    assert platform_tuple() == fmpy.platform_tuple
    with zipfile.ZipFile(plant3_fmu) as archive:
        names = set(archive.namelist())
        build_description = archive.read("sources/buildDescription.xml")
    assert f"binaries/{fmpy.platform_tuple}/ToggleLSM3{fmpy.sharedLibraryExtension}" in names
    assert {"sources/solver.c", "sources/fmi3.c", "sources/model.c", "sources/solver.h", "sources/md_model.h"} <= names
    assert "sources/fmi2.c" not in names
    schema = etree.XMLSchema(
        etree.parse(str(Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3BuildDescription.xsd"))
    )
    document = etree.fromstring(build_description)
    assert schema.validate(document), schema.error_log
    assert [f.get("name") for f in document.iter("SourceFile")] == ["solver.c", "instance.c", "fmi3.c", "model.c"]

    md = read_model_description(str(plant3_fmu))
    assert md.fmiVersion == "3.0"
    assert md.instantiationToken == plant3_build.fmu.guid
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate  # fmpy spells it so
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert not md.coSimulation.hasEventMode
    (independent,) = [v for v in md.modelVariables if v.causality == "independent"]
    # time comes after the model's variables and the three solver settings
    assert (independent.name, independent.type, independent.valueReference) == (
        "time",
        "Float64",
        plant3_build.variables + 3,
    )
    assert independent.start is None and independent.initial is None
    references = [v.valueReference for v in md.modelVariables]
    assert len(references) == len(set(references))
    n = plant3_build.variables  # the model's variables have the value references 0 .. n - 1
    settings = {v.name: v for v in md.modelVariables if v.name.startswith("solver.") and v.type == "Float64"}
    assert [v.valueReference for v in settings.values()] == [n, n + 1, n + 2]
    statistics = [v for v in md.modelVariables if v.type == "Int64"]
    # after the settings and time (n + 3): the integrator's statistics
    assert [(v.name, v.valueReference, v.causality, v.variability) for v in statistics] == [
        ("solver.steps", n + 4, "local", "discrete"),
        ("solver.rejectedSteps", n + 5, "local", "discrete"),
        ("solver.events", n + 6, "local", "discrete"),
    ]
    assert all(v.variability == "tunable" and v.causality == "parameter" for v in settings.values())
    kinds = {v.name: (v.type, v.causality, v.variability, v.initial) for v in md.modelVariables}
    assert kinds["m_B"] == ("Float64", "parameter", "fixed", "exact")
    assert kinds["idealCurrentLoop"] == ("Boolean", "parameter", "fixed", "exact")
    assert kinds["iq_ref"][:3] == ("Float64", "input", "continuous")
    assert kinds["motor.K_f"] == ("Float64", "calculatedParameter", "fixed", "calculated")
    assert kinds["motor.pi"] == ("Float64", "local", "constant", "exact")
    assert kinds["x_B"] == ("Float64", "output", "continuous", "calculated")
    assert [u.variable.name for u in md.outputs] == outputs(md)
    assert [c.name for c in md.logCategories] == ["logEvents", "logStatusWarning", "logStatusError", "logAll"]


def test_every_fmi3_function_is_exported_and_nothing_of_fmi2(plant3_fmu: Path) -> None:
    """FMI 3.0 sec. 2.5: all functions of fmi3Functions.h, also those of the interface types
    and capabilities the FMU does not support (fmpy resolves all of them at load time)."""
    header = (HEADERS / "fmi3Functions.h").read_text()
    declared = re.findall(r"^FMI3_Export\s+\w+TYPE\s+(fmi3\w+);", header, re.MULTILINE)
    assert len(declared) == 75
    unzipped = extract(str(plant3_fmu))
    try:
        library = Path(unzipped) / "binaries" / fmpy.platform_tuple / f"ToggleLSM3{fmpy.sharedLibraryExtension}"
        dll = ctypes.CDLL(str(library))
        missing = [name for name in declared if not hasattr(dll, name)]
        assert missing == []
        nm = shutil.which("nm")
        if nm:
            symbols = subprocess.run(
                [nm, "-D", "--defined-only", str(library)], capture_output=True, text=True, check=True
            ).stdout
            exported = {line.split()[-1] for line in symbols.splitlines() if " T " in line}
            assert exported == set(declared)
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)


def test_fmi3_shell_compiles_with_strict_flags(tmp_path: Path) -> None:
    from toggle_cosim.fmu_export.shell_settings import HEADER_NAME, settings_header

    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler")
    (tmp_path / HEADER_NAME).write_text(settings_header())  # as the build writes it
    result = subprocess.run(
        [
            cc,
            "-c",
            "-std=c99",
            "-pedantic",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-fPIC",
            "-O2",
            "-fvisibility=hidden",
            f"-I{HEADERS}",
            f"-I{SHELL}",
            f"-I{tmp_path}",
            str(SHELL / "fmi3.c"),
            "-o",
            str(tmp_path / "fmi3.o"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr


# ---------------------------------------------------------------------------------------
# The same numbers as the FMI 2.0 build
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("ideal", [False, True])
def test_open_loop_matches_the_fmi2_build(plant3_fmu: Path, plant_fmu: Path, ideal: bool) -> None:
    """Every output over a 0.3 s open-loop run with m_B, mu, idealCurrentLoop and a load set:
    FMI 3.0 and FMI 2.0 agree to 1e-12 relative (measured: bit for bit)."""
    parameters = {**PARAMETERS, "idealCurrentLoop": ideal}
    fmu3 = Slave(plant3_fmu).start(**parameters)
    names = outputs(fmu3.md)
    assert {"x_B", "lambda1", "N12", "E_in", "E_fric", "F_C", "i_q"} <= set(names)
    run3 = open_loop(fmu3, names)
    assert fmu3.fmu.getFloat64([time_value_reference_of(fmu3)]) == [pytest.approx(T_END, abs=1e-12)]
    fmu3.close()
    fmu2 = Slave(plant_fmu).start(**parameters)
    run2 = open_loop(fmu2, names)
    fmu2.close()

    assert np.all(np.isfinite(run3))
    x_B = run3[:, names.index("x_B")]
    assert x_B.max() - x_B[0] > 0.01  # the mechanism really moved
    scale = np.maximum(np.max(np.abs(run2), axis=0), 1e-300)
    relative = np.max(np.abs(run3 - run2), axis=0) / scale
    worst = names[int(np.argmax(relative))]
    assert relative.max() <= 1e-12, f"{worst}: {relative.max():.3g}"
    assert np.array_equal(run3, run2)  # same solver core, same operations: identical


def time_value_reference_of(slave: Slave) -> int:
    (vr,) = [v.valueReference for v in slave.md.modelVariables if v.causality == "independent"]
    return vr


def test_time_is_the_independent_variable(plant3_fmu: Path) -> None:
    fmu = Slave(plant3_fmu)
    vr = time_value_reference_of(fmu)
    assert fmu.fmu.getFloat64([vr]) == [0.0]  # in Instantiated
    fmu.fmu.enterInitializationMode(startTime=0.25, stopTime=0.26)
    fmu.fmu.exitInitializationMode()
    fmu.t = 0.25
    assert fmu.fmu.getFloat64([vr]) == [0.25]
    event, terminate, early, last = fmu.step(0.004)
    assert (event, terminate, early) == (False, False, False)
    assert last == 0.254
    assert fmu.fmu.getFloat64([vr]) == [0.254]
    with pytest.raises(FMICallException):
        fmu.fmu.setFloat64([vr], [0.0])
    assert "time is the independent variable" in fmu.errors()
    with pytest.raises(FMICallException):  # past the stop time
        fmu.step(0.01)
    assert "past the stopTime" in fmu.errors()
    assert fmu.fmu.getFloat64([vr]) == [0.254]
    fmu.close()


# ---------------------------------------------------------------------------------------
# FMU state
# ---------------------------------------------------------------------------------------


def test_fmu_state_round_trips_are_bit_exact(plant3_fmu: Path) -> None:
    """Get/set and serialise/deserialise: going back to t = 0.1 s and repeating the same
    steps reproduces every output bit for bit; the serialised bytes survive a round trip and
    are refused when damaged."""
    fmu = Slave(plant3_fmu).start(**PARAMETERS)
    names = outputs(fmu.md)
    for _ in range(200):
        fmu.set(iq_ref=3.0)
        fmu.step(H)
    t0 = fmu.t
    state = fmu.fmu.getFMUState()
    serialized = fmu.fmu.serializeFMUState(state)

    def rerun() -> np.ndarray:
        fmu.t = t0
        rows = []
        for k in range(200):
            fmu.set(iq_ref=-2.0 if k < 100 else 1.0)
            fmu.step(H)
            rows.append(fmu.get(*names))
        return np.array(rows)

    first = rerun()
    fmu.fmu.setFMUState(state)
    assert np.array_equal(rerun(), first)

    restored = fmi3FMUState()
    fmu.fmu.deserializeFMUState(serialized, restored)
    assert restored.value
    fmu.fmu.setFMUState(restored)
    assert fmu.fmu.serializeFMUState(fmu.fmu.getFMUState()) == serialized
    assert np.array_equal(rerun(), first)

    # a second instance of the same FMU takes the serialised state as well
    other = Slave(plant3_fmu)
    into = fmi3FMUState()
    other.fmu.deserializeFMUState(serialized, into)
    other.fmu.setFMUState(into)
    assert np.array_equal(rerun_on(other, t0, names), first)
    other.close()

    damaged = bytearray(serialized)
    damaged[len(damaged) // 2] ^= 0x01
    with pytest.raises(FMICallException):
        fmu.fmu.deserializeFMUState(bytes(damaged), fmi3FMUState())
    with pytest.raises(FMICallException):
        fmu.fmu.deserializeFMUState(serialized[:-8], fmi3FMUState())
    fmu.fmu.freeFMUState(state)
    fmu.fmu.freeFMUState(restored)
    assert not state.value and not restored.value
    fmu.close()


def rerun_on(slave: Slave, t0: float, names: list[str]) -> np.ndarray:
    slave.t = t0
    rows = []
    for k in range(200):
        slave.set(iq_ref=-2.0 if k < 100 else 1.0)
        slave.step(H)
        rows.append(slave.get(*names))
    return np.array(rows)


def test_reset_reproduces_the_first_run(plant3_fmu: Path) -> None:
    fmu = Slave(plant3_fmu).start(**PARAMETERS)
    names = ["x_B", "E_in", "lambda1"]
    first = open_loop(fmu, names, t_end=0.05)
    fmu.fmu.reset()
    fmu.t = 0.0
    assert fmu.get("m_B") == [4.43]  # back to the declared start value
    fmu.start(**PARAMETERS)
    assert np.array_equal(open_loop(fmu, names, t_end=0.05), first)
    fmu.close()


# ---------------------------------------------------------------------------------------
# Refusals
# ---------------------------------------------------------------------------------------


def test_wrong_instantiation_token_is_refused(plant3_fmu: Path) -> None:
    messages: list[str] = []
    md = read_model_description(str(plant3_fmu))
    unzipped = extract(str(plant3_fmu))
    fmu = FMU3Slave(
        guid="{00000000-0000-0000-0000-000000000000}",
        unzipDirectory=unzipped,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="wrong",
    )
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    assert any("instantiationToken {00000000-0000-0000-0000-000000000000} does not match" in m for m in messages)
    with pytest.raises(Exception, match="Failed to instantiate"):  # hasEventMode="false"
        fmu.guid = md.guid
        fmu.instantiate(
            eventModeUsed=True, logMessage=lambda env, status, category, message: messages.append(message.decode())
        )
    assert any("eventModeUsed = true" in m for m in messages)
    # the FMU offers Model Exchange too: the same check of the token there
    assert fmu.fmi3InstantiateModelExchange(b"me", b"{wrong}", None, False, False, None, fmu.logMessage) is None
    assert any("fmi3InstantiateModelExchange: instantiationToken {wrong} does not match" in m for m in messages)
    fmu.freeLibrary()
    shutil.rmtree(unzipped, ignore_errors=True)
    # earlyReturnAllowed is accepted (the FMU just never returns early)
    ok = Slave(plant3_fmu, earlyReturnAllowed=True).start()
    assert ok.step(1e-3)[2] is False
    ok.close()


def test_start_values_and_what_is_settable_when(plant3_fmu: Path) -> None:
    fmu = Slave(plant3_fmu)
    # Instantiated: start values, including calculated parameters evaluated from them
    assert fmu.get("m_B", "motor.K", "solver.relTol", "iq_ref") == [4.43, 350.0, 1e-8, 0.0]
    assert fmu.fmu.getBoolean(fmu.vr("idealCurrentLoop", "motor.idealCurrentLoop")) == [False, False]
    fmu.set(K=400.0, idealCurrentLoop=True)
    assert fmu.get("motor.K") == [400.0]
    assert fmu.fmu.getBoolean(fmu.vr("motor.idealCurrentLoop")) == [True]
    with pytest.raises(FMICallException):
        fmu.get("x_B")  # calculated in initialisation mode: no value yet
    assert "x_B has no value before fmi3EnterInitializationMode" in fmu.errors()
    fmu.start(**PARAMETERS)
    # Step Mode: inputs and tunable settings yes; fixed parameters, calculated, computed no
    fmu.set(iq_ref=2.0, **{"solver.maxStep": 1e-4})
    assert fmu.get("solver.maxStep", "iq_ref") == [1e-4, 2.0]
    refused = {"m_B": 5.0, "motor.K_f": 1.0, "x_B": 0.3, "motor.pi": 3.0, "F_E": math.nan, "solver.relTol": 0.5}
    for name, value in refused.items():
        with pytest.raises(FMICallException):
            fmu.set(**{name: value})
    errors = fmu.errors()
    assert "m_B is a fixed parameter" in errors
    assert "motor.K_f is not settable" in errors and "x_B is not settable" in errors
    assert "non-finite value nan for F_E" in errors and "solver.relTol = 0.5 is out of range" in errors
    with pytest.raises(FMICallException):
        fmu.fmu.setBoolean(fmu.vr("idealCurrentLoop"), [False])
    with pytest.raises(FMICallException):
        fmu.fmu.setBoolean(fmu.vr("solver.relTol"), [True])
    assert "solver.relTol is a Float64 variable" in fmu.errors()
    # nValues must equal nValueReferences: every variable is a scalar
    values = (fmi3Float64 * 2)()
    with pytest.raises(FMICallException):
        fmu.fmu.fmi3GetFloat64(fmu.fmu.component, (fmi3ValueReference * 1)(*fmu.vr("x_B")), 1, values, 2)
    assert "nValues = 2 but nValueReferences = 1" in fmu.errors()
    # no variables of other types; nothing of the other interface types or capabilities
    for call in (
        lambda: fmu.fmu.getInt32([0]),
        lambda: fmu.fmu.getString([0]),
        lambda: fmu.fmu.setUInt64([5], [1]),
        lambda: fmu.fmu.getFloat32([999]),
        fmu.fmu.enterEventMode,
        fmu.fmu.enterStepMode,
        lambda: fmu.fmu.getDirectionalDerivative([100], [5], [1.0]),
        lambda: fmu.fmu.getOutputDerivatives([100], [1]),
        lambda: fmu.fmu.fmi3EnterConfigurationMode(fmu.fmu.component),
        lambda: fmu.fmu.fmi3SetTime(fmu.fmu.component, 0.0),
        lambda: fmu.fmu.fmi3GetClock(fmu.fmu.component, (fmi3ValueReference * 1)(0), 1, (fmi3Boolean * 1)()),
    ):
        with pytest.raises(FMICallException):
            call()
    errors = fmu.errors()
    assert "x_B is not a Int32 variable" not in errors  # vr 0 is m_B
    assert "m_B is not a Int32 variable" in errors
    assert "unknown value reference 999" in errors
    assert "hasEventMode" in errors and "providesDirectionalDerivatives" in errors
    assert "maxOutputDerivativeOrder" in errors
    assert "fmi3SetTime: a Model Exchange function, but the instance is a Co-Simulation one" in errors
    assert fmu.fmu.getInt32([]) == []  # an empty request is fine
    # none of that damaged the instance
    fmu.step(1e-3)
    assert math.isfinite(fmu.get("x_B")[0])
    fmu.close()


def test_errors_are_logged_even_with_logging_off_and_debug_output_on_request(plant3_fmu: Path) -> None:
    fmu = Slave(plant3_fmu)  # loggingOn = False
    fmu.start(**PARAMETERS)
    fmu.set(iq_ref=4.0)
    fmu.step(2e-3)  # friction sign events at t = 0+ and t = 1.4 ms
    assert fmu.log == []  # nothing but errors when logging is off
    with pytest.raises(FMICallException):
        fmu.fmu.doStep(0.5, 1e-3)  # not the FMU's time
    (status, category, message) = fmu.log[-1]
    assert (status, category) == (3, "logStatusError")
    assert "currentCommunicationPoint 0.5 s is not the FMU's time" in message
    fmu.fmu.reset()
    fmu.fmu.setDebugLogging(True, ["logEvents"])
    fmu.t = 0.0
    fmu.start(**PARAMETERS)
    fmu.set(iq_ref=4.0)
    fmu.step(2e-3)
    events = [message for _, category, message in fmu.log if category == "logEvents"]
    assert len(events) >= 2 and all(m.startswith("event at t=") for m in events)
    assert all(category in ("logEvents", "logStatusError") for _, category, _ in fmu.log)
    fmu.fmu.setDebugLogging(True, ["logStatusWarning", "noSuchCategory"])  # fmi3Warning
    assert fmu.log[-1][:2] == (1, "logStatusWarning")
    assert 'unknown log category "noSuchCategory"' in fmu.log[-1][2]
    fmu.close()


def test_failed_step_leaves_an_error_state_that_reset_clears(plant3_fmu: Path) -> None:
    """x_B0 beyond the toggle position has no initial angles: an error status, not a crash;
    fmi3Reset brings the instance back."""
    fmu = Slave(plant3_fmu)
    fmu.set(x_B0=0.5)
    with pytest.raises(FMICallException):
        fmu.fmu.enterInitializationMode(startTime=0.0)
    with pytest.raises(FMICallException):
        fmu.fmu.exitInitializationMode()
    assert "not allowed after an error" in fmu.errors()
    fmu.fmu.reset()
    fmu.start(**PARAMETERS)
    fmu.step(1e-3)
    assert fmu.get("x_B")[0] > 0.2
    fmu.close()


# ---------------------------------------------------------------------------------------
# fmpy's own master
# ---------------------------------------------------------------------------------------


def test_simulate_fmu_runs_it_like_the_fmi2_build(plant3_fmu: Path, plant_fmu: Path) -> None:
    options = dict(
        stop_time=0.1,
        output_interval=1e-3,
        output=["x_B", "E_in", "lambda1"],
        start_values={"m_B": 8.86, "mu": 0.2, "idealCurrentLoop": True},
        input=np.array([(0.0, 4.0), (0.1, 4.0)], dtype=[("time", np.float64), ("iq_ref", np.float64)]),
    )
    result3 = fmpy.simulate_fmu(str(plant3_fmu), **options)
    result2 = fmpy.simulate_fmu(str(plant_fmu), **options)
    assert len(result3) == 101 and result3["time"][-1] == pytest.approx(0.1)
    assert result3["x_B"][-1] - result3["x_B"][0] > 0.005
    for name in ("time", "x_B", "E_in", "lambda1"):
        assert np.array_equal(result3[name], result2[name]), name


def test_fmi3_plant_under_the_master_matches_the_stored_reference(plant3_fmu: Path) -> None:
    """The FMI 3.0 build, run by the same master and controller as the FMI 2.0 one, stays in
    the funnel of the reference trace recorded with the FMI 2.0 build."""
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments import references
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.plant.contract import check_plant

    for run in load_scenario(ROOT / "scenarios" / "fig5_external_force.yaml"):
        outcome = check_and_simulate(run, check_plant(plant3_fmu))
        assert outcome.complete, outcome.reason
        assert outcome.record["fmu"]["fmi_version"] == "3.0"
        checked = references.check(outcome, ROOT / "scenarios" / "references")
        assert checked.comparison.passed, checked.failures


@pytest.mark.parametrize("kernel", ["1", "0"])
def test_record_reads_an_fmi3_plants_int64_and_boolean_with_their_getters(
    plant3_fmu: Path, plant_fmu: Path, kernel: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`record:` of the FMI 3.0 plant's Int64 solver.steps and Boolean idealCurrentLoop reads them
    by fmi3GetInt64 and fmi3GetBoolean (compiled and Python system loop): the FMI 2.0 plant's values,
    read by fmi2GetInteger and fmi2GetBoolean, the same solver's counts."""
    import dataclasses

    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.plant.contract import check_plant
    from toggle_cosim.system.model import Port, Wiring

    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", kernel)
    run = dataclasses.replace(load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0], t_end=0.02)
    chosen = tuple(Port("plant", name) for name in ("x_B", "solver.steps", "idealCurrentLoop"))
    run = dataclasses.replace(run, system=Wiring(record=chosen))
    traces = []
    for fmu in (plant3_fmu, plant_fmu):
        outcome = check_and_simulate(run, check_plant(fmu))
        assert outcome.complete, outcome.reason
        assert outcome.record["loop"]["kind"] == f"system, {'compiled' if kernel == '1' else 'python'}"
        traces.append(outcome.trace)
    steps = traces[0].column("plant.solver.steps")
    assert steps[0] == 0 and steps[-1] > 40 and np.all(np.diff(steps) > 0)
    assert np.all(traces[0].column("plant.idealCurrentLoop") == 0.0)
    for name in ("plant.x_B", "plant.solver.steps", "plant.idealCurrentLoop"):
        assert np.array_equal(traces[0].column(name), traces[1].column(name)), name
