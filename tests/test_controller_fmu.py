"""The controller FMU ToggleVSC (controller_fmu): it validates, declares what the law reads and
produces with the units of LawParameters' metadata, gives the built-in law's bits sample for
sample through FMPy's FMI 2.0 and 3.0 slaves, keeps the sampling semantics of
docs/controller-fmu.md, round-trips its state and rebuilds from its own sources."""

from __future__ import annotations

import ctypes
import dataclasses
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi1 import FMICallException  # noqa: E402
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

from toggle_cosim.control.controller import VSCController  # noqa: E402
from toggle_cosim.control.parameters import STARTED as COMPUTED  # noqa: E402
from toggle_cosim.control.parameters import LawParameters  # noqa: E402
from toggle_cosim.controller_fmu import build_controller_fmu  # noqa: E402
from toggle_cosim.native import c_compiler  # noqa: E402

VERSIONS = ("2.0", "3.0")
T_S = 0.0005


@pytest.fixture(scope="module")
def fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("controller-fmu")
    return {v: build_controller_fmu(folder / f"ToggleVSC{'3' if v == '3.0' else ''}.fmu", v).path for v in VERSIONS}


class Controller:
    """One instance of the FMU through FMPy, with its log messages kept."""

    def __init__(self, path: Path, version: str, parameters: LawParameters | None = None, start: float = 0.0) -> None:
        self.md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.unzipped = extract(str(path))
        self.version = version
        self.messages: list[str] = []
        kind = FMU3Slave if version == "3.0" else FMU2Slave
        token = self.md.instantiationToken if version == "3.0" else self.md.guid
        self.fmu = kind(guid=token, unzipDirectory=self.unzipped, modelIdentifier="ToggleVSC", instanceName="vsc")
        if version == "3.0":
            self.fmu.instantiate(loggingOn=True, logMessage=self._log3)
            self.fmu.enterInitializationMode(startTime=start)
        else:
            self._logger = fmi2CallbackLoggerTYPE(self._log2)
            callbacks = fmi2CallbackFunctions()
            callbacks.logger = self._logger
            self.fmu.instantiate(callbacks=callbacks, loggingOn=True)
            self.fmu.setupExperiment(startTime=start)
            self.fmu.enterInitializationMode()
        if parameters is not None:
            self.set(
                **{
                    f.name: getattr(parameters, f.name)
                    for f in dataclasses.fields(LawParameters)
                    if f.name not in COMPUTED
                }
            )
        self.fmu.exitInitializationMode()

    def _log2(self, env, name, status, category, message) -> None:  # noqa: ANN001
        self.messages.append(message.decode())

    def _log3(self, env, status, category, message) -> None:  # noqa: ANN001
        self.messages.append(message.decode())

    def set(self, **values: float) -> None:
        refs = [self.vr[name] for name in values]
        if self.version == "3.0":
            self.fmu.setFloat64(refs, list(values.values()))
        else:
            self.fmu.setReal(refs, list(values.values()))

    def get(self, *names: str) -> list[float]:
        refs = [self.vr[name] for name in names]
        return self.fmu.getFloat64(refs) if self.version == "3.0" else self.fmu.getReal(refs)

    def step(self, t: float, h: float = T_S) -> None:
        self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

    def close(self) -> None:
        self.fmu.freeInstance()
        shutil.rmtree(self.unzipped, ignore_errors=True)


@pytest.mark.parametrize("version", VERSIONS)
def test_the_fmu_validates_and_declares_the_laws_variables(fmus: dict[str, Path], version: str) -> None:
    assert validate_fmu(str(fmus[version])) == []
    md = read_model_description(str(fmus[version]))
    assert md.modelName == "ToggleVSC" and md.coSimulation.modelIdentifier == "ToggleVSC"
    assert float(md.defaultExperiment.stepSize) == VSCController().T_s
    by_name = {v.name: v for v in md.modelVariables}
    expected = [f for f in dataclasses.fields(LawParameters) if f.name not in COMPUTED]
    assert [v.name for v in md.modelVariables if v.causality == "parameter"] == [f.name for f in expected]
    for f in expected:
        assert (by_name[f.name].unit or "") == f.metadata["unit"], f.name
        assert by_name[f.name].description == f.metadata["description"]
    assert "t0" not in by_name and "T_h" not in by_name
    defaults = VSCController().law_parameters()
    assert all(float(by_name[f.name].start) == getattr(defaults, f.name) for f in expected)
    assert [u.variable.name for u in md.outputs] == ["iq_ref", "S", "phase", "e", "z"]
    assert by_name["iq_ref"].unit == "A" and by_name["x_B"].unit == "m" and by_name["omega1"].unit == "rad/s"
    inputs = [by_name[n] for n in ("x_B", "v_B", "theta1", "omega1", "x_ref", "v_ref", "a_ref")]
    assert [by_name[n].unit for n in ("x_ref", "v_ref", "a_ref")] == ["m", "m/s", "m/s2"]
    for unknowns in (md.outputs, md.initialUnknowns):  # direct feedthrough: each output depends on the inputs
        assert [u.variable.name for u in unknowns] == ["iq_ref", "S", "phase", "e", "z"]
        for unknown in unknowns:
            assert {id(v) for v in unknown.dependencies} == {id(v) for v in inputs}
    assert {u.name for u in md.unitDefinitions} >= {"A", "m", "m/s", "rad", "rad/s", "s", "N/A", "kg", "kg.m2"}


CASES = [
    pytest.param(VSCController(), "x_B", id="paper-xB"),
    pytest.param(VSCController(objective="theta1"), "theta1", id="paper-theta1"),
    pytest.param(VSCController(law="integral", i_max=3.0), "x_B", id="integral-xB-clipped"),
    pytest.param(VSCController(law="integral", objective="theta1"), "theta1", id="integral-theta1"),
]


def _measurements(n: int, objective: str) -> list[dict[str, float]]:
    """A stroke from rest at 0.2329 m towards the target with a wobble: reaching, sliding and,
    with a small i_max, the integral law's clipping."""
    import math

    from toggle_cosim.physics.mechanism import theta1_from_xB
    from toggle_cosim.physics.parameters import MechanismParameters

    nominal = MechanismParameters(mu=0.0)
    rows = []
    for k in range(n):
        s = k / (n - 1)
        x = 0.2329 + 0.0875 * (3 * s * s - 2 * s**3) + 1e-4 * math.sin(40 * s)
        v = 0.0875 * 6 * (s - s * s) / (n * T_S) + 4e-3 * math.cos(40 * s)
        theta = theta1_from_xB(x, nominal)
        rows.append({"x_B": x, "v_B": v, "theta1": theta, "omega1": v * 9.0})
    return rows


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize(("controller", "objective"), CASES)
def test_the_fmu_gives_the_built_in_laws_bits(
    fmus: dict[str, Path], version: str, controller: VSCController, objective: str
) -> None:
    rows = _measurements(300, objective)
    fmu = Controller(fmus[version], version, controller.law_parameters())
    try:
        state = controller.start(0.0, rows[0])
        phases = set()
        clipped = 0
        for k, row in enumerate(rows):
            t = k * T_S
            out = controller.step(state, t, row)
            fmu.set(**row)
            got = fmu.get("iq_ref", "S", "phase", "e", "z")
            assert got == [out.command, *out.diagnostics, out.state.z], (k, got)
            phases.add(out.diagnostics[1])
            clipped += abs(out.command) == controller.i_max
            fmu.step(t)
            state = out.state
        assert phases == {0.0, 1.0} or controller.law == "integral"  # reaching then sliding (paper law)
        if controller.i_max == 3.0:
            assert clipped > 0  # the anti-windup was exercised
    finally:
        fmu.close()


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("law", ["paper", "integral"])
def test_the_fmu_tracks_a_trajectory_with_the_python_laws_bits(
    fmus: dict[str, Path], plant_fmu: Path, version: str, law: str
) -> None:
    """A trajectory run (an S-curve move of the paper's stroke, μ = 0.2) replayed through the FMU
    with tracking = 1: its inputs x_B, v_B from the run's trace and x_ref, v_ref, a_ref from the
    run's sampled reference; every sample's iq_ref, S, phase and e are the Python law's bits."""
    from toggle_cosim.cosim.controllers import builtin_controller
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import runs_from_document
    from toggle_cosim.plant.contract import check_plant

    document = {
        "name": "tracking",
        "t_end": 0.7,
        "T_s": T_S,
        "stroke": {
            "x_start": 0.2329,
            "x_target": 0.3199,
            "trajectory": {"kind": "scurve", "v_max": 0.2, "a_max": 2.0, "j_max": 40.0},
        },
        "plant": {"mu": 0.2, "friction_model": "stick_slip"},
        "controller": {"law": law},
    }
    run = runs_from_document(document)[0]
    controller = builtin_controller(run)
    outcome = check_and_simulate(run, check_plant(plant_fmu), controller=controller)
    assert outcome.complete
    trace = outcome.trace
    columns = [trace.column(name) for name in ("x_B", "v_B", "iq_ref", "S", "phase", "e")]
    parameters = controller.law_parameters()
    assert parameters.tracking == 1.0
    fmu = Controller(fmus[version], version, parameters)
    try:
        for k in range(len(trace.time)):
            x_B, v_B, *expected = (float(c[k]) for c in columns)
            x_ref, v_ref, a_ref = controller.reference.values[k]
            fmu.set(x_B=x_B, v_B=v_B, x_ref=x_ref, v_ref=v_ref, a_ref=a_ref)
            got = fmu.get("iq_ref", "S", "phase", "e")
            assert got == expected, (k, got, expected)
            fmu.step(k * T_S)
    finally:
        fmu.close()
    assert np.max(np.abs(trace.column("e"))) < 1e-4  # it tracked: |e| < 0.1 mm all along


@pytest.mark.parametrize("version", VERSIONS)
def test_sampling_semantics(fmus: dict[str, Path], version: str) -> None:
    controller = VSCController()
    fmu = Controller(fmus[version], version)
    try:
        fmu.set(x_B=0.25, v_B=0.0)
        first = fmu.get("iq_ref", "S")
        fmu.set(x_B=0.26, v_B=0.01)  # before the first doStep: the start follows the inputs
        state = controller.start(0.0, {"x_B": 0.26, "v_B": 0.01})
        expected = controller.step(state, 0.0, {"x_B": 0.26, "v_B": 0.01})
        assert fmu.get("iq_ref", "S") == [expected.command, expected.diagnostics[0]] != first
        fmu.step(0.0)
        assert fmu.get("iq_ref") == [expected.command]  # latched after doStep until an input is set
        fmu.set(x_B=0.27, v_B=0.02)
        after = controller.step(expected.state, T_S, {"x_B": 0.27, "v_B": 0.02})
        assert fmu.get("iq_ref") == [after.command]  # re-evaluated at t_1 with the first sample's T_h
        with pytest.raises(FMICallException):
            fmu.step(T_S, h=2 * T_S)
        assert any("h = 0.001" in m and "T_s = 0.0005" in m for m in fmu.messages)
        with pytest.raises(FMICallException):
            fmu.step(5 * T_S)
        assert any("not the FMU's time" in m for m in fmu.messages)
        fmu.step(T_S)  # refusals leave the instance as it was
        fmu.set(x_B=0.5)  # beyond the mechanism's reach: eq. (26) has no solution
        with pytest.raises(FMICallException):
            fmu.get("iq_ref")
        assert any("x_B = 0.5" in m and "t = 0.001" in m for m in fmu.messages)
    finally:
        fmu.close()


@pytest.mark.parametrize("version", VERSIONS)
def test_state_round_trips_give_the_same_continuation(fmus: dict[str, Path], version: str) -> None:
    controller = VSCController(law="integral")
    rows = _measurements(40, "x_B")
    fmu = Controller(fmus[version], version, controller.law_parameters())
    try:

        def run(ks: range) -> list[list[float]]:
            got = []
            for k in ks:
                fmu.set(**rows[k])
                got.append(fmu.get("iq_ref", "S", "phase", "e", "z"))
                fmu.step(k * T_S)
            return got

        run(range(10))
        if version == "3.0":
            state = fmu.fmu.getFMUState()
            blob = fmu.fmu.serializeFMUState(state)
        else:
            state = fmu.fmu.getFMUstate()
            blob = fmu.fmu.serializeFMUstate(state)
        reference = run(range(10, 40))
        if version == "3.0":
            fmu.fmu.setFMUState(state)
            assert run(range(10, 40)) == reference
            fmu.fmu.setFMUState(fmu.fmu.deserializeFMUState(blob))
        else:
            fmu.fmu.setFMUstate(state)
            assert run(range(10, 40)) == reference
            fmu.fmu.setFMUstate(fmu.fmu.deSerializeFMUstate(blob))
        assert run(range(10, 40)) == reference
    finally:
        fmu.close()


def test_the_fmu_rebuilds_from_its_sources(fmus: dict[str, Path], tmp_path: Path) -> None:
    """sources/ compiled with the C compiler alone (and the standard's headers) gives a binary
    that instantiates and computes the first sample's command."""
    from toggle_cosim.fmu_export.packaging import fmi_headers

    with zipfile.ZipFile(fmus["2.0"]) as archive:
        archive.extractall(tmp_path)
    sources = sorted((tmp_path / "sources").glob("*.c"))
    assert {p.name for p in sources} == {"vsc_law.c", "vsc_core.c", "vsc_fmi2.c"}
    binary = tmp_path / "rebuilt.so"
    subprocess.run(
        [
            c_compiler(),
            "-shared",
            "-fPIC",
            "-O2",
            "-ffp-contract=off",
            f"-I{fmi_headers()}",
            *map(str, sources),
            "-o",
            str(binary),
            "-lm",
        ],
        check=True,
    )
    library = ctypes.CDLL(str(binary))
    assert library.fmi2GetVersion and library.fmi2DoStep
    library.fmi2GetVersion.restype = ctypes.c_char_p
    assert library.fmi2GetVersion() == b"2.0"
    with zipfile.ZipFile(fmus["3.0"]) as archive:
        names = archive.namelist()
    assert "sources/buildDescription.xml" in names and "sources/vsc_fmi3.c" in names


def test_the_docs_variables_table_is_the_generated_one() -> None:
    """docs/controller-fmu.md holds the table `variables.markdown_table()` generates from
    LawParameters' metadata (rewrite it from there after a change)."""
    from toggle_cosim.controller_fmu.variables import TABLE_BEGIN, TABLE_END, markdown_table

    page = (Path(__file__).resolve().parents[1] / "docs" / "controller-fmu.md").read_text(encoding="utf-8")
    assert page[page.index(TABLE_BEGIN) : page.index(TABLE_END) + len(TABLE_END)] == markdown_table()


@pytest.mark.slow
def test_the_cli_builds_the_controller_fmu_without_modelica(tmp_path: Path) -> None:
    """`toggle-cosim build --model ToggleVSC` needs a C compiler only: it works in a process where
    importing the Modelica compiler fails, writes fmus/ToggleVSC.fmu (fmus/ToggleVSC3.fmu for
    FMI 3.0) and refuses a file name that is not an FMU's in one line, exit 2."""
    import sys

    program = "import sys; sys.modules['modelica'] = None\nfrom toggle_cosim.cli import main\nmain(sys.argv[1:])\n"

    def cli(*arguments: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-c", program, *arguments], cwd=tmp_path, capture_output=True, text=True, check=False
        )

    for arguments, name, version in (
        (["--model", "ToggleVSC"], "ToggleVSC.fmu", "2.0"),
        (["--model", "ToggleVSC", "--fmi-version", "3.0"], "ToggleVSC3.fmu", "3.0"),
    ):
        result = cli("build", *arguments)
        assert result.returncode == 0, result.stderr
        assert result.stdout.startswith(f"built fmus/{name} (FMI {version} CoSimulation")
        assert read_model_description(str(tmp_path / "fmus" / name)).fmiVersion == version
    refused = cli("build", "--model", "ToggleVSC", "--out", "notes.txt")
    assert refused.returncode == 2 and refused.stderr.strip().splitlines() == [
        "error: notes.txt: an FMU file name must end in .fmu (fix --out)"
    ]
    assert not (tmp_path / "notes.txt").exists()
