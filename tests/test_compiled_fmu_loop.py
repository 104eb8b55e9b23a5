"""The compiled system loop with a controller FMU (`controller: {fmu: PATH}`): the C calls the
controller FMU's functions in the order the Python execution does, so a run gives the Python
execution's outcome (`TOGGLE_COSIM_KERNEL=0`) bit for bit.

Behaviour checked: for the paper's fig4 and fig5 runs and the integral law, with the generated
ToggleVSC as an FMI 2.0 and an FMI 3.0 FMU, the compiled loop runs (run.json says so) and its
trace equals the Python execution's and the built-in law's in every column; a controller FMU
that fails (doStep, setting an input, reading the command: PythonFMU's Fatal; ToggleVSC's Error
for an x_B out of its nominal reach) ends the run with the Python execution's reason
("controller failed: ", the FMU's file, the call) and rows; a plant that fails (a step retried
from the checkpoint, non-finite outputs) gives the Python execution's trace, retries and
reason; progress hooks report the run's progress in both forms and an interrupt stops both at
the same row.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from python_fmus import build_python_fmu

from toggle_cosim.controller_fmu import build_controller_fmu
from toggle_cosim.cosim.execution.system_loop import system_library, system_library_reason
from toggle_cosim.cosim.master import RunOutcome, check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "scenarios"

FLAKY_LAW = '''
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real


class FlakyLaw(Fmi2Slave):
    """iq_ref = K_p (target - x_B) - K_d v_B; from t = fail_at on it fails in the call `mode`
    names: 1 doStep raises, 2 setting x_B raises, 3 reading iq_ref raises, 4 iq_ref is NaN."""

    author = "toggle-cosim tests"
    description = "a PD law on x_B that fails on purpose"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._x_B, self.v_B, self.time = 0.2329, 0.0, 0.0
        self.K_p, self.K_d, self.target, self.fail_at, self.mode = 55.0, 2.5, 0.3199, 1e9, 0
        self.register_variable(Real("x_B", causality=Fmi2Causality.input, getter=lambda: self._x_B, setter=self.set_x_B))
        self.register_variable(Real("v_B", causality=Fmi2Causality.input))
        for name in ("K_p", "K_d", "target", "fail_at"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Integer("mode", causality=Fmi2Causality.parameter, variability=Fmi2Variability.tunable))
        self.register_variable(Real("iq_ref", causality=Fmi2Causality.output, getter=self.command))
        self.register_variable(Real("e", causality=Fmi2Causality.output, getter=lambda: self.target - self._x_B))

    def failing(self, mode: int) -> bool:
        return self.mode == mode and self.time >= self.fail_at

    def set_x_B(self, value: float) -> None:
        if self.failing(2):
            raise RuntimeError(f"x_B refused at t = {self.time:.4f} s")
        self._x_B = value

    def command(self) -> float:
        if self.failing(3):
            raise RuntimeError(f"no command at t = {self.time:.4f} s")
        if self.failing(4):
            return float("nan")
        return self.K_p * (self.target - self._x_B) - self.K_d * self.v_B

    def do_step(self, current_time: float, step_size: float) -> bool:
        if self.mode == 1 and current_time >= self.fail_at:
            raise RuntimeError(f"the law gave up at t = {current_time:.4f} s")
        self.time = current_time + step_size
        return True
'''


@pytest.fixture(autouse=True)
def _needs_the_kernel() -> None:
    if system_library() is None:
        pytest.skip(f"no compiled loop: {system_library_reason()}")


@pytest.fixture(scope="module")
def toggle_vsc(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("toggle-vsc")
    return {v: Path(build_controller_fmu(folder / f"ToggleVSC{v[0]}.fmu", v).path) for v in ("2.0", "3.0")}


@pytest.fixture(scope="module")
def flaky_fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_python_fmu(FLAKY_LAW, tmp_path_factory.mktemp("flaky-fmu"), "FlakyLaw")


def _with_fmu(run, fmu: Path, **parameters: float):  # noqa: ANN001, ANN202 - a Run
    settings = dataclasses.replace(run.controller, fmu=fmu, parameters={**run.controller.parameters, **parameters})
    return dataclasses.replace(run, controller=settings)


def _both_loops(monkeypatch: pytest.MonkeyPatch, run, plant, **options) -> tuple[RunOutcome, RunOutcome]:  # noqa: ANN001
    """The run in the compiled loop, then in the Python execution (TOGGLE_COSIM_KERNEL=0)."""
    monkeypatch.delenv("TOGGLE_COSIM_KERNEL", raising=False)
    compiled = check_and_simulate(run, plant, **options)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    python = check_and_simulate(run, plant, **options)
    monkeypatch.delenv("TOGGLE_COSIM_KERNEL")
    assert python.record["loop"]["kind"] == "python"
    return compiled, python


def _same_outcome(compiled: RunOutcome, python: RunOutcome) -> None:
    assert compiled.reason == python.reason
    assert compiled.trace.names == python.trace.names
    assert compiled.trace.data.shape == python.trace.data.shape
    assert np.array_equal(compiled.trace.data, python.trace.data, equal_nan=True)
    assert compiled.record["retries"] == python.record["retries"]


@pytest.mark.parametrize("fmi_version", ["2.0", "3.0"])
def test_the_controller_fmu_runs_in_c_with_the_python_loops_bits(
    fmi_version: str, toggle_vsc: dict[str, Path], plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every run of fig4, fig5 and the integral law with ToggleVSC: the compiled loop ran, its
    trace is the Python execution's and the built-in law's, bit for bit."""
    plant, fmu = check_plant(plant_fmu), toggle_vsc[fmi_version]
    for name in ("fig4_nominal", "fig5_external_force", "integral_load"):
        for run in load_scenario(SCENARIOS / f"{name}.yaml"):
            compiled, python = _both_loops(monkeypatch, _with_fmu(run, fmu), plant)
            assert compiled.complete, (run.label, compiled.reason)
            loop = compiled.record["loop"]
            assert loop["kind"] == "compiled" and loop["reason"].endswith("in the compiled system loop"), loop
            _same_outcome(compiled, python)
            builtin = check_and_simulate(run, plant)
            assert builtin.record["loop"]["kind"] == "compiled"
            for column in builtin.trace.names:
                assert np.array_equal(builtin.trace.column(column), compiled.trace.column(column)), (run.label, column)
            assert compiled.trace.names[-1] == "z" and np.ptp(compiled.trace.column("iq_ref")) > 1.0


@pytest.mark.parametrize(
    ("mode", "said"),
    [
        (1, "FlakyLaw.fmu: fmi2DoStep at t = 0.05 s returned status 4; it logged [FATAL] "),
        (2, "FlakyLaw.fmu: fmi2SetReal at t = 0.05 s returned status 4; it logged [FATAL] "),
        (3, "FlakyLaw.fmu: fmi2GetReal at t = 0.05 s returned status 4; it logged [FATAL] "),
        (4, "the controller's command at t = 0.05 s is nan, not a finite float"),
    ],
    ids=["doStep", "set", "get", "nan"],
)
def test_a_failing_controller_fmu_gives_the_python_loops_reason_and_rows(
    mode: int, said: str, flaky_fmu: Path, plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each call of the controller FMU failing at t = 0.05 s: the same reason, naming the FMU and
    its call, with its log line, and the trace cut at the same row as in the Python execution (the doStep from 0.05 s
    fails at the next sample, which keeps sample 0.05 s; the others fail at 0.05 s itself)."""
    document = {
        "name": "flaky",
        "t_end": 0.1,
        "T_s": 0.0005,
        "fmu": str(plant_fmu),
        "stroke": {"x_start": 0.2329, "x_target": 0.3199},
        "controller": {"fmu": str(flaky_fmu), "parameters": {"fail_at": 0.05, "mode": mode}},
    }
    run = runs_from_document(document)[0]
    compiled, python = _both_loops(monkeypatch, run, check_plant(plant_fmu))
    assert compiled.record["loop"]["kind"] == "compiled" and compiled.record["status"] == "failed"
    assert compiled.reason.startswith("controller failed: ") and said in compiled.reason, compiled.reason
    assert len(compiled.trace.time) == (101 if mode == 1 else 100)
    _same_outcome(compiled, python)


def test_the_generated_fmus_error_for_an_x_B_out_of_reach(
    toggle_vsc: dict[str, Path], plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """ToggleVSC with a nominal mechanism that reaches only to x_B = 0.29 m (r1 + r3): its
    fmi2GetReal returns Error once the slider passes 0.29 m; the compiled loop stops there with
    the Python execution's reason (the FMU's log line naming x_B) and rows."""
    run = load_scenario(SCENARIOS / "fig4_nominal.yaml")[0]
    run = _with_fmu(run, toggle_vsc["2.0"], r3=0.29 - 0.1)
    compiled, python = _both_loops(monkeypatch, run, check_plant(plant_fmu))
    assert compiled.record["loop"]["kind"] == "compiled"
    assert "fmi2GetReal at t = " in compiled.reason and "returned status 3" in compiled.reason
    assert "out of the nominal mechanism's reach" in compiled.reason
    x_B = compiled.trace.column("x_B")
    assert 100 < len(x_B) < run.steps and x_B[-1] <= 0.29  # cut before the sample out of reach
    _same_outcome(compiled, python)


@pytest.mark.parametrize(
    "kind",
    ["chatter", "nan"],
)
def test_a_failing_plant_with_a_controller_fmu_gives_the_python_loops_outcome(
    kind: str, toggle_vsc: dict[str, Path], plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The plant's steps discarded from 0.1 s (retried from the checkpoint, the run goes on) to
    0.15 s (the retry fails too), or its outputs NaN from 0.1 s (the sample handed back to
    C): the same trace, retries and reason as the Python execution; with the retries the
    controller FMU's deferred doStep goes on from the retried sample."""
    from fault_plants import fault_environment, make_faulty_fmu

    faulty = check_plant(make_faulty_fmu(plant_fmu, tmp_path / "Faulty.fmu"))
    environment = fault_environment(kind, 0.1, faulty.references)
    for name in ("TOGGLE_FAULT_KIND", "TOGGLE_FAULT_TIME", "TOGGLE_FAULT_MIN_FE", "TOGGLE_FAULT_FE_VR"):
        monkeypatch.setenv(name, environment[name])
    monkeypatch.setenv("TOGGLE_FAULT_END", "0.15")
    run = dataclasses.replace(load_scenario(SCENARIOS / "fig4_nominal.yaml")[0], t_end=0.3)
    compiled, python = _both_loops(monkeypatch, _with_fmu(run, toggle_vsc["2.0"]), faulty)
    _same_outcome(compiled, python)
    assert not compiled.complete
    if kind == "chatter":
        assert len(compiled.record["retries"]) == 101 and compiled.record["loop"]["kind"] == "compiled"
        assert compiled.reason.startswith("plant FMU failed at t = 0.15 s: fmi2DoStep failed with status 2")
    else:
        assert compiled.record["loop"]["kind"] == "compiled"
        assert compiled.reason == "plant outputs became non-finite at t = 0.1005 s"  # the first sample read past 0.1 s


@pytest.mark.parametrize(
    ("coupling", "record", "rows", "reason"),
    [
        ("jacobi", False, 202, "plant outputs became non-finite at t = 0.1005 s"),
        (
            "gauss-seidel",
            True,
            201,
            "component 'plant': its output x_B is nan at t = 0.1005 s, measured by the controller FMU 'controller',"
            " which takes finite values only",
        ),
    ],
    ids=["jacobi", "system"],
)
def test_a_controller_fmus_measurement_that_is_not_finite_ends_the_run_before_it_is_set(
    coupling: str,
    record: bool,
    rows: int,
    reason: str,
    toggle_vsc: dict[str, Path],
    plant_fmu: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The plant's outputs NaN from 0.1 s: under Jacobi the controller FMU's inputs are set late,
    after row 0.1005 s is recorded, and the guard refuses them there; in a system (a `record:`
    list) the reason names the output and the controller. Both loops end at the same row with
    the same reason, and the controller FMU never sees the NaN."""
    from fault_plants import fault_environment, make_faulty_fmu

    from toggle_cosim.system.model import Port

    faulty = check_plant(make_faulty_fmu(plant_fmu, tmp_path / "Faulty.fmu"))
    environment = fault_environment("nan", 0.1, faulty.references)
    for name in ("TOGGLE_FAULT_KIND", "TOGGLE_FAULT_TIME", "TOGGLE_FAULT_MIN_FE", "TOGGLE_FAULT_FE_VR"):
        monkeypatch.setenv(name, environment[name])
    run = dataclasses.replace(load_scenario(SCENARIOS / "fig4_nominal.yaml")[0], t_end=0.3, coupling=coupling)
    if record:
        ports = (Port("plant", "x_B"), Port("controller", "iq_ref"))
        run = dataclasses.replace(run, system=dataclasses.replace(run.system, record=ports))
    run = _with_fmu(run, toggle_vsc["2.0"])
    monkeypatch.delenv("TOGGLE_COSIM_KERNEL", raising=False)
    compiled = check_and_simulate(run, faulty)
    monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "0")
    python = check_and_simulate(run, faulty)
    assert compiled.record["loop"]["kind"].endswith("compiled") and python.record["loop"]["kind"].endswith("python")
    _same_outcome(compiled, python)
    assert compiled.reason == reason
    assert len(compiled.trace.time) == rows and np.isnan(compiled.trace.column(compiled.trace.names[1])[-1]) == (
        rows == 202
    )


def test_progress_and_interrupts_as_for_the_builtin_law(
    toggle_vsc: dict[str, Path], plant_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The progress hook sees the run's progress in both forms (rising to its end), and a
    KeyboardInterrupt it raises at half the run stops both there (within a sample: the compiled
    loop reports after a stretch, the Python form before a sample), marked interrupted, with the
    same rows up to there."""
    run = _with_fmu(
        dataclasses.replace(load_scenario(SCENARIOS / "fig5_external_force.yaml")[0], t_end=0.4), toggle_vsc["3.0"]
    )
    plant = check_plant(plant_fmu)
    seen: dict[str, list[float]] = {"compiled": [], "python": []}
    for loop in seen:
        monkeypatch.setenv("TOGGLE_COSIM_KERNEL", "1" if loop == "compiled" else "0")
        outcome = check_and_simulate(run, plant, progress=seen[loop].append)
        assert outcome.complete and outcome.record["loop"]["kind"] == loop
    for fractions in seen.values():
        assert len(fractions) > 5 and fractions == sorted(fractions) and fractions[-1] >= 0.99

    def interrupt(fraction: float) -> None:
        if fraction >= 0.5:
            raise KeyboardInterrupt

    monkeypatch.delenv("TOGGLE_COSIM_KERNEL")
    compiled, python = _both_loops(monkeypatch, run, plant, progress=interrupt)
    assert compiled.interrupted and python.interrupted
    assert compiled.record["loop"]["kind"] == "compiled" and 0.5 * run.steps <= len(compiled.trace.time) < run.steps
    rows = min(len(compiled.trace.time), len(python.trace.time))  # the forms report progress a sample apart
    assert abs(len(compiled.trace.time) - len(python.trace.time)) <= 1
    assert np.array_equal(compiled.trace.data[:rows], python.trace.data[:rows])


def test_jacobi_coupling_runs_compiled_too(toggle_vsc: dict[str, Path], plant_fmu: Path) -> None:
    run = _with_fmu(
        dataclasses.replace(load_scenario(SCENARIOS / "fig4_nominal.yaml")[0], t_end=0.05), toggle_vsc["2.0"]
    )
    outcome = check_and_simulate(run, check_plant(plant_fmu), coupling="jacobi")
    assert outcome.complete and outcome.record["loop"]["kind"] == "compiled"
    assert ", jacobi, " in outcome.record["loop"]["reason"]
