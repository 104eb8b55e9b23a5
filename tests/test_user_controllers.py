"""User controllers (docs/controllers.md): a scenario's controller.python factory, a python-control
system through its adapter, a subclass of the built-in VSC, run by `toggle-cosim run` and
`toggle-cosim sweep` and passed to `simulate` as live objects.

Behaviour checked: the recorded command i_q* is the user's law at every sample, recomputed here
from the recorded measurement by an independent evaluation of that law (the PD by its formula,
the PID by scipy's lfilter on the error with the transfer function's coefficients worked out
by hand, the limited VSC by the built-in law clipped); run.json names the Python loop and why;
a sweep's rows are those runs' figures; bad controller input is one line with exit 2 and
writes nothing, and a controller that fails mid-run fails its run with the reason.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from scipy.signal import lfilter

from toggle_cosim.cli import main
from toggle_cosim.control.controller import VSCController
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.cosim.controllers import builtin_controller
from toggle_cosim.cosim.isolation.supervision import simulate_supervised
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.experiments.sweep import read_results, run_sweep
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "controllers" / "user_controllers.yaml"
VARIANTS = ("pd", "pid", "limited_vsc")
T_SHORT = 0.4  # s: long enough for the VSC's reaching phase, the PID's integral and the 3 A limit


def _law_commands(run, trace) -> tuple[np.ndarray, np.ndarray]:
    """(the command the user's law gives at every recorded sample, evaluated here from the
    recorded outputs; the built-in VSC's command at the same samples)."""
    p = run.controller.parameters
    x_B, v_B = trace.column("x_B"), trace.column("v_B")
    builtin = builtin_controller(run)
    names = trace.names[1 : trace.names.index("iq_ref")]
    rows = [dict(zip(names, row[1 : 1 + len(names)], strict=True)) for row in trace.data]
    state = builtin.start(0.0, rows[0])
    vsc = []
    for k, measurement in enumerate(rows):
        result = builtin.step(state, k * run.T_s, measurement)
        vsc.append(result.command)
        state = result.state
    vsc = np.array(vsc)
    if run.variant == "pd":
        return p["Kp"] * (run.x_target - x_B) - p["Kd"] * v_B, vsc
    if run.variant == "pid":
        # C(z) = Kp + Ki T z/(z-1) + Kd (1-a)/T (z-1)/(z-a) over the common denominator (z-1)(z-a)
        T, a = run.T_s, math.exp(-run.T_s / p["T_f"])
        num = np.polyadd(
            np.polyadd(p["Kp"] * np.polymul([1, -1], [1, -a]), p["Ki"] * T * np.array([1, -a, 0])),
            p["Kd"] * (1 - a) / T * np.polymul([1, -1], [1, -1]),
        )
        return lfilter(num, np.polymul([1, -1], [1, -a]), run.x_target - x_B), vsc
    assert run.variant == "limited_vsc"
    return np.clip(vsc, -p["limit"], p["limit"]), vsc


def _check_user_law(run, trace, record) -> None:
    """The trace's command is the user's law at every sample, and not the built-in law."""
    expected, vsc = _law_commands(run, trace)
    got = trace.column("iq_ref")
    assert len(got) == run.steps + 1
    scale = max(float(np.max(np.abs(expected))), 1.0)
    assert np.max(np.abs(got - expected)) <= 1e-9 * scale, run.variant
    assert np.max(np.abs(got - vsc)) > 0.1, "the built-in law ran, not the user's"
    assert record["controller"]["python"] == run.controller.python
    if run.variant == "pid":  # a python-control system: its matrices in the compiled loop (test_compiled_lti)
        assert record["loop"]["kind"] == "compiled" and "(controller natively in C)" in record["loop"]["reason"]
        return
    assert record["loop"]["kind"] == "python"
    method = {"pd": "PDController.step", "limited_vsc": "LimitedVSC.step"}
    assert method[run.variant] in record["loop"]["reason"], record["loop"]


def _short_example(folder: Path) -> Path:
    """The shipped example scenario and its module, with t_end shortened, in `folder`."""
    document = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    document["t_end"] = T_SHORT
    document.pop("fmu")
    shutil.copy(EXAMPLE.parent / "my_controllers.py", folder / "my_controllers.py")
    path = folder / "user_controllers.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


def test_run_command_runs_each_user_law_at_every_sample(tmp_path: Path, plant_fmu: Path) -> None:
    """`toggle-cosim run` of the shipped example (full length): the PD, the python-control PID
    and the limited VSC each give their own command at all 3001 samples, on the Python loop."""
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(EXAMPLE), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    assert result.exit_code == 0, result.output
    for run in load_scenario(EXAMPLE):
        folder = out / run.scenario / run.variant
        record = json.loads((folder / "run.json").read_text(encoding="utf-8"))
        assert record["status"] == "complete"
        _check_user_law(run, read_csv(folder / "trace.csv"), record)
    limited = json.loads((out / "user_controllers" / "limited_vsc" / "run.json").read_text(encoding="utf-8"))
    assert limited["summary"]["peak_iq_ref_A"] == 3.0 and limited["summary"]["hitting_time_s"] > 0  # T_h exists
    pd = json.loads((out / "user_controllers" / "pd" / "run.json").read_text(encoding="utf-8"))
    assert pd["summary"]["hitting_time_s"] is None and pd["controller"]["diagnostics"] == ["e"]  # no T_h, S0


def test_sweep_runs_each_user_law(tmp_path: Path, plant_fmu: Path) -> None:
    """`toggle-cosim sweep` over the example's three variants under a 30 N load: every case ran the
    user's law (its row's figures are those of the same case run here, whose command is checked
    sample by sample), and the limited VSC's row is not the built-in VSC's."""
    base = _short_example(tmp_path)
    sweep = {"base": base.name, "axes": {"plant.F_E": {"values": [30.0]}}, "output": "out"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, plant_fmu, progress=False) == 0
    table = read_results(tmp_path / "out")
    assert len(table) == 3 and (table["status"] == "ok").all()
    plant = check_plant(plant_fmu)
    document = yaml.safe_load(base.read_text(encoding="utf-8"))
    for _, row in table.iterrows():
        case = {k: v for k, v in document.items() if k != "variants"}
        case["plant"] = {**case["plant"], "F_E": row["plant.F_E"]}
        case["controller"] = {**case["controller"], **document["variants"][row["variant"]]["controller"]}
        (run,) = runs_from_document(case, base)
        run = dataclasses.replace(run, variant=row["variant"])
        outcome = check_and_simulate(run, plant)
        _check_user_law(run, outcome.trace, outcome.record)
        assert row["peak_iq_ref_A"] == outcome.summary.peak_iq_ref_A
        assert row["final_error_m"] == outcome.summary.final_error_m
    builtin_doc = {k: v for k, v in document.items() if k != "variants"}
    builtin_doc["plant"] = {**builtin_doc["plant"], "F_E": 30.0}
    builtin = check_and_simulate(runs_from_document(builtin_doc)[0], plant)
    limited = table[table["variant"] == "limited_vsc"].iloc[0]
    assert builtin.summary.peak_iq_ref_A > 3.1 and limited["peak_iq_ref_A"] == 3.0


BAD_MODULE = '''
import math
from toggle_cosim.control.protocol import ControlStep

class NoStep:
    diagnostics = ()
    def start(self, t0, measurement):
        return None

class Fails:
    """Returns its command until t_bad, then `bad` (a value, or an exception to raise)."""
    diagnostics = ("e",)
    def __init__(self, bad, t_bad):
        self.bad, self.t_bad = bad, t_bad
    def start(self, t0, measurement):
        return None
    def step(self, state, t, measurement):
        e = 0.3199 - measurement["x_B"]
        if t >= self.t_bad:
            if self.bad == "raise":
                raise ZeroDivisionError("division by zero in the user's law")
            return ControlStep(float(self.bad), (e,), state)
        return ControlStep(10.0 * e, (e,), state)

def no_step(context):
    return NoStep()

def raises(context):
    raise RuntimeError("the gains file is missing")

def fails(context, bad, t_bad):
    return Fails(bad, t_bad)

def continuous(context):
    import control
    return control.tf([1.0], [1.0, 1.0])

def wrong_dt(context):
    import control
    return control.tf([1.0], [1.0, -0.5], 0.001)

def clashing(context):
    obj = Fails("nan", 1.0)
    obj.diagnostics = ("x_B",)
    return obj
'''


def _bad_scenario(folder: Path, controller: dict, **extra) -> Path:
    (folder / "user_laws.py").write_text(BAD_MODULE, encoding="utf-8")
    document = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    document.pop("variants")
    document.pop("fmu")
    document["t_end"] = 0.1
    document["controller"] = {**document["controller"], **controller}
    document.update(extra)
    path = folder / "bad.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("controller", "message"),
    [
        ({"python": "no_such_module:make"}, "key controller.python: cannot import 'no_such_module'"),
        ({"error": {"output": "x_B"}}, "key controller.error: only with controller.python"),
        ({"python": "not a module"}, "key controller.python"),
        # a python-control system (controller.error given): built in a supervised child before any run
        (
            {"python": "user_laws:continuous", "error": {"output": "x_B"}},
            "key controller.python: user_laws:continuous returned a continuous-time system (dt = 0); sample it at"
            " T_s = 0.0005 s",
        ),
        ({"python": "user_laws:wrong_dt", "error": {"output": "x_B"}}, "dt = 0.001 s, not the run's T_s = 0.0005 s"),
        ({"python": "user_laws:no_step", "error": {"output": "x_B"}}, "the error is for python-control systems only"),
        ({"python": "user_laws:raises", "error": {"output": "x_B"}}, "raised RuntimeError: the gains file is missing"),
    ],
)
def test_bad_controller_is_one_line_exit_2_before_any_run(
    tmp_path: Path, plant_fmu: Path, controller: dict, message: str
) -> None:
    """What the command checks before any run: without running the user's code, or, for a
    python-control system, by building it in a supervised child: one line, exit 2, nothing
    written, and the command's own process never imported the module."""
    before = set(sys.modules)
    path = _bad_scenario(tmp_path, controller)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(path), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2, result.output
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: ") and message in lines[0], lines
    assert "Traceback" not in result.output and not out.exists()
    assert not any(name.startswith(("user_laws", "toggle_cosim_scenario_")) for name in set(sys.modules) - before)


@pytest.mark.parametrize(
    ("controller", "message"),
    [
        ({"python": "user_laws:nothing"}, "key controller.python: module 'user_laws' has no 'nothing'"),
        ({"python": "user_laws:raises"}, "user_laws:raises raised RuntimeError: the gains file is missing"),
        ({"python": "user_laws:fails", "parameters": {"Kp": 1.0}}, "raised TypeError"),
        ({"python": "user_laws:no_step"}, "user_laws.NoStep has no step() method"),
        ({"python": "user_laws:clashing"}, "diagnostic 'x_B' is already a column of the trace"),
        ({"python": "user_laws:wrong_dt"}, "key controller.error: missing"),
    ],
)
def test_a_controller_that_cannot_be_built_fails_its_run_in_one_line(
    tmp_path: Path, plant_fmu: Path, controller: dict, message: str
) -> None:
    """What only the user's code can tell (its factory's result, the protocol) is found in the
    run's child, which builds the controller: the run fails with the reason (exit 1), no sample
    recorded, and the command's own process never imported the module."""
    path = _bad_scenario(tmp_path, controller)
    out = tmp_path / "out"
    before = set(sys.modules)
    result = CliRunner().invoke(main, ["run", str(path), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    assert not any(name.startswith(("user_laws", "toggle_cosim_scenario_")) for name in set(sys.modules) - before)
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output and message in result.output
    record = json.loads((out / "user_controllers" / "run" / "run.json").read_text(encoding="utf-8"))
    assert record["status"] == "failed" and record["reason"].startswith("controller: ") and message in record["reason"]
    assert record["samples"] == 0


def test_bad_controller_in_a_sweep_is_exit_2_before_any_case(tmp_path: Path, plant_fmu: Path, capsys) -> None:
    path = _bad_scenario(tmp_path, {"python": "user_laws:raises"})
    sweep = {"base": path.name, "axes": {"plant.F_E": {"values": [0.0, 10.0]}}, "output": "out"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, plant_fmu, progress=False) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "case 0: key controller.python: user_laws:raises raised RuntimeError" in err[0], err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ("nan", "the controller's command at t = 0.05 s is nan, not a finite float"),
        ("inf", "the controller's command at t = 0.05 s is inf, not a finite float"),
        ("raise", "the controller's step raised at t = 0.05 s: ZeroDivisionError: division by zero in the user's law"),
    ],
)
def test_a_controller_that_fails_mid_run_fails_its_run_with_the_reason(
    tmp_path: Path, plant_fmu: Path, bad: str, message: str
) -> None:
    """Exit 1, the run failed with the reason, the trace kept up to the last good sample
    (t = 0.0495 s), nothing of the bad command sent to the plant; no traceback."""
    path = _bad_scenario(tmp_path, {"python": "user_laws:fails", "parameters": {"bad": bad, "t_bad": 0.05}})
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(path), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    assert result.exit_code == 1, result.output
    assert message in result.output and "Traceback" not in result.output
    record = json.loads((out / "user_controllers" / "run" / "run.json").read_text(encoding="utf-8"))
    assert record["status"] == "failed" and message in record["reason"]
    trace = read_csv(out / "user_controllers" / "run" / "trace.csv")
    assert trace.time[-1] == pytest.approx(0.0495, abs=1e-12) and np.all(np.isfinite(trace.column("iq_ref")))


class Bang:
    """Not a VSCController, not a subclass of anything of ours: meets the protocol by its methods."""

    diagnostics = ("e", "count")

    def __init__(self, target: float) -> None:
        self.target = target

    def start(self, t0: float, measurement) -> int:  # noqa: ANN001
        return 0

    def step(self, state: int, t: float, measurement) -> ControlStep:  # noqa: ANN001
        e = self.target - measurement["x_B"]
        return ControlStep(2.0 if e > 0 else -2.0, (e, float(state)), state + 1)


@dataclasses.dataclass(frozen=True)
class FirstSampleKick(VSCController):
    """The issue's case: 10 A at the first sample, then the built-in law."""

    def step(self, state, t, measurement):  # noqa: ANN001, ANN201
        result = super().step(state, t, measurement)
        return dataclasses.replace(result, command=10.0) if t == 0.0 else result


@pytest.mark.parametrize("supervised", [False, True], ids=["in_process", "supervised"])
def test_live_controllers_passed_to_simulate(plant_fmu: Path, supervised: bool) -> None:
    """A live object of another class, and a subclass overriding step, given to simulate (and
    to the supervised child): each one's own command at every sample, its diagnostics as the
    trace's last columns, its state threaded through, the Python loop named in run.json."""
    plant = check_plant(plant_fmu)
    document = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    (run,) = runs_from_document({**{k: v for k, v in document.items() if k != "variants"}, "t_end": 0.1})
    go = (
        (lambda c: simulate_supervised(run, plant, controller=c))
        if supervised
        else (lambda c: check_and_simulate(run, plant, controller=c))
    )
    bang = go(Bang(run.x_target))
    assert bang.complete and bang.trace.names[-4:] == ("iq_ref", "F_E", "e", "count")
    e = run.x_target - bang.trace.column("x_B")
    assert np.array_equal(bang.trace.column("iq_ref"), np.where(e > 0, 2.0, -2.0))
    assert np.array_equal(bang.trace.column("count"), np.arange(run.steps + 1, dtype=float))
    assert bang.record["loop"]["kind"] == "python" and "Bang.step" in bang.record["loop"]["reason"]
    assert bang.summary.hitting_time_s is None and bang.summary.S0_m_per_s is None
    kick = go(FirstSampleKick(**vars(builtin_controller(run))))
    builtin = go(None)
    u, u0 = kick.trace.column("iq_ref"), builtin.trace.column("iq_ref")
    assert kick.record["loop"]["kind"] == "python" and "FirstSampleKick.step" in kick.record["loop"]["reason"]
    assert builtin.record["loop"]["kind"] == "compiled"
    assert u[0] == 10.0 != u0[0]
    trace, names = kick.trace, kick.trace.names[1 : kick.trace.names.index("iq_ref")]
    controller, state = builtin_controller(run), None
    for k, row in enumerate(trace.data):  # from the second sample on: the built-in law of the kicked run's state
        measurement = dict(zip(names, row[1 : 1 + len(names)], strict=True))
        state = controller.start(0.0, measurement) if state is None else state
        step = controller.step(state, k * run.T_s, measurement)
        state = step.state
        assert u[k] == (10.0 if k == 0 else step.command), k


def test_a_factory_parameter_is_a_sweep_axis(tmp_path: Path) -> None:
    """controller.parameters.<name> can be swept: one case per value, each case's document
    (what its worker builds the run from) carrying it, and the base scenario as its source."""
    from toggle_cosim.experiments.sweep import load_sweep

    base = _short_example(tmp_path)
    sweep = {"base": base.name, "variant": "pd", "axes": {"controller.parameters.Kp": {"values": [8.0, 16.0]}}}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    cases = load_sweep(tmp_path / "sweep.yaml").cases
    assert [case.document["controller"]["parameters"] for case in cases] == [
        {"Kp": 8.0, "Kd": 2.5},
        {"Kp": 16.0, "Kd": 2.5},
    ]
    assert all(Path(case.payload()["source"]) == base for case in cases)
    (run,) = runs_from_document(cases[1].document, base)
    assert run.controller.python == "my_controllers:make_pd" and run.controller.parameters["Kp"] == 16.0


def test_keep_traces_refuses_a_controller_with_other_columns_in_one_line(tmp_path: Path, plant_fmu: Path) -> None:
    """--keep-traces stores one trace table with the built-in law's columns: a sweep whose user
    controller records other diagnostics is refused before any case runs, naming the case."""
    base = _short_example(tmp_path)
    sweep = {"base": base.name, "axes": {"plant.F_E": {"values": [30.0]}}, "output": "out"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    result = CliRunner().invoke(
        main, ["sweep", str(tmp_path / "sweep.yaml"), "--fmu", str(plant_fmu), "--keep-traces", "--quiet"]
    )
    assert result.exit_code == 2, result.output
    assert "--keep-traces stores one trace table" in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "traces").exists()
