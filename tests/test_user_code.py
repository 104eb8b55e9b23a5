"""User code a scenario names (docs/security.md, "What a scenario may run"): where it is imported
from, what is refused, and that nothing it does escapes the run it belongs to.

Behaviour checked:

* two scenario folders with a module of the same name each run their own (the command i_q* at
  t = 0 is each module's gain times the stroke), and a module's top level runs afresh for each
  run and each sweep case (a module-level counter is 1 in every case);
* a module beside the scenario, or a controller FMU, that is writable by group or others, sits
  in a folder others may write to, or is owned by another user is refused in one line naming
  the file, exit 2, before any run, nothing written;
* a factory that sleeps, calls os._exit(7), segfaults, raises SystemExit(0) or
  KeyboardInterrupt, a step that raises KeyboardInterrupt or SystemExit, and a module that
  changes directory at import: each fails (or, for the chdir, completes) its own run with the
  reason naming the controller, the command's process never imports the module, the outputs
  land where the command said, and the runs after it complete (exit 1, not 0, 7, 139 or 130);
* what we write about a failure is one line of at most a few hundred characters (a command that
  is a 10-million-element list, an exception of 50 MB), and what a run prints is relayed up to
  TOGGLE_COSIM_MAX_LOG, then one line saying how much was dropped;
* a string for a controller FMU's Real parameter is refused in one line before any run;
* a sweep survives a controller that kills its parent process (that case fails, the others
  run); a plant whose fmi2Reset answers Fatal is never called again (each case gets a new host);
* `simulate(supervised=False)` unzips into a run folder that is removed after the run;
* the figure worker of `paper` never imports from the current folder.
"""

from __future__ import annotations

import faulthandler
import json
import os
import re
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from fault_plants import fault_environment, make_faulty_fmu
from python_fmus import build_python_fmu

from toggle_cosim.cli import main
from toggle_cosim.files.traces import read_csv

X_START, X_TARGET = 0.2329, 0.3199
SCENARIO = {
    "t_end": 0.02,
    "T_s": 0.0005,
    "stroke": {"x_start": X_START, "x_target": X_TARGET},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
}
PROPORTIONAL = """
from toggle_cosim.control.protocol import ControlStep

GAIN = {gain}
CALLS = []  # module-level state: one entry per factory call since this module's top level ran


class Proportional:
    diagnostics = ("e",)

    def __init__(self, target, gain, calls):
        self.target, self.gain, self.calls = target, gain, calls

    def start(self, t0, measurement):
        return None

    def step(self, state, t, measurement):
        e = self.target - measurement["x_B"]
        return ControlStep(self.gain * e + 100.0 * (self.calls - 1), (float(self.calls),), state)


def make(context):
    CALLS.append(1)
    return Proportional(context.x_target, GAIN, len(CALLS))
"""
HOSTILE = """
import ctypes
import os
import time

from toggle_cosim.control.protocol import ControlStep


class Law:
    diagnostics = ("e",)

    def __init__(self, target, how):
        self.target, self.how = target, how

    def start(self, t0, measurement):
        return None

    def close(self):
        if self.how == "exit_close":
            raise SystemExit(3)

    def step(self, state, t, measurement):
        if t >= 0.005:
            if self.how == "kbi_step":
                raise KeyboardInterrupt
            if self.how == "exit_step":
                raise SystemExit(0)
            if self.how == "segv_step":
                ctypes.string_at(0)
            if self.how == "big_command":
                return ControlStep(list(range(10_000_000)), (0.0,), state)
            if self.how == "big_error":
                raise ValueError("x" * 50_000_000)
            if self.how == "kill_parent":
                os.kill(os.getppid(), 9)
                time.sleep(5)  # ended meanwhile: its process dies with its parent
        if self.how == "print":
            print("y" * 10_000, flush=True)
        e = self.target - measurement["x_B"]
        return ControlStep(40.0 * e, (e,), state)


def make(context, how="none"):
    if how == "sleep":
        time.sleep(600)
    if how == "exit7":
        os._exit(7)
    if how == "segv":
        ctypes.string_at(0)
    if how == "exit0":
        raise SystemExit(0)
    if how == "kbi":
        raise KeyboardInterrupt
    law = Law(context.x_target, how)
    if how == "many_diagnostics":
        law.diagnostics = tuple(f"d{i}" for i in range(20_000))
    return law
"""


def _scenario(folder: Path, name: str, controller: dict | None, **extra) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.yaml"
    document = {"name": name, **SCENARIO, **({"controller": controller} if controller else {}), **extra}
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    return path


def _run(*arguments: str) -> tuple[int, str]:
    result = CliRunner().invoke(main, ["run", *arguments])
    assert "Traceback" not in result.output, result.output
    return result.exit_code, result.output


def test_two_folders_with_one_module_name_each_run_their_own(tmp_path: Path, plant_fmu: Path) -> None:
    """a/samename.py (gain 12) and b/samename.py (gain 30) in one command: each run's command at
    t = 0 is its own gain times the stroke; run.json names the module as the scenario did."""
    paths = []
    for folder, gain in (("a", 12.0), ("b", 30.0)):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "samename.py").write_text(PROPORTIONAL.format(gain=gain), encoding="utf-8")
        paths.append(_scenario(tmp_path / folder, f"scen_{folder}", {"python": "samename:make"}))
    out = tmp_path / "out"
    code, output = _run(*map(str, paths), "--fmu", str(plant_fmu), "--out", str(out), "-q")
    assert code == 0, output
    for folder, gain in (("a", 12.0), ("b", 30.0)):
        trace = read_csv(out / f"scen_{folder}" / "run" / "trace.csv")
        assert trace.column("iq_ref")[0] == pytest.approx(gain * (X_TARGET - X_START), rel=1e-12)
        record = json.loads((out / f"scen_{folder}" / "run" / "run.json").read_text(encoding="utf-8"))
        assert record["controller"]["class"] == "samename.Proportional"


def test_module_state_does_not_carry_across_runs_or_sweep_cases(tmp_path: Path, plant_fmu: Path) -> None:
    """The module's top level runs again for every run and every sweep case: the factory's
    module-level counter is 1 in each (a count of 2 would add 100 A to the command, PROPORTIONAL),
    so every case's peak |i_q*| is the gain times the stroke."""
    from toggle_cosim.experiments.sweep import read_results, run_sweep

    (tmp_path / "counting.py").write_text(PROPORTIONAL.format(gain=20.0), encoding="utf-8")
    base = _scenario(tmp_path, "counting", {"python": "counting:make"})
    sweep = {"base": base.name, "axes": {"plant.F_E": {"values": [0.0, 5.0, 10.0]}}, "output": "swept"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, plant_fmu, progress=False, keep_traces=False) == 0
    table = read_results(tmp_path / "swept")
    assert list(table["status"]) == ["ok"] * 3
    assert np.allclose(table["peak_iq_ref_A"], 20.0 * (X_TARGET - X_START), rtol=1e-4)  # 100 A if it carried
    from toggle_cosim.cosim.controllers import controller_for
    from toggle_cosim.experiments.scenario import load_scenario

    (run,) = load_scenario(base)
    assert [controller_for(run).calls for _ in range(3)] == [1, 1, 1]  # in one process, one import each


@pytest.mark.parametrize("case", ["group_writable_file", "others_writable_folder", "other_owner", "fmu_other_owner"])
def test_code_others_could_have_written_is_refused_before_any_run(tmp_path: Path, plant_fmu: Path, case: str) -> None:
    folder = tmp_path / "shared"
    folder.mkdir()
    module = folder / "site_laws.py"
    module.write_text(PROPORTIONAL.format(gain=1.0), encoding="utf-8")
    module.chmod(0o644)
    controller: dict = {"python": "site_laws:make"}
    culprit = module
    if case == "group_writable_file":
        module.chmod(0o664)
    elif case == "others_writable_folder":
        folder.chmod(0o1777)  # a shared sticky folder such as /tmp
        culprit = folder
    else:
        if os.geteuid() != 0:
            pytest.skip("giving a file to another user needs root")
        if case == "fmu_other_owner":
            culprit = folder / "law.fmu"
            culprit.write_bytes(plant_fmu.read_bytes())
            controller = {"fmu": "law.fmu"}
        os.chown(culprit, 65534, 65534)
    path = _scenario(tmp_path / "scenarios", "shared", controller)
    path = path.rename(folder / path.name)
    out = tmp_path / "out"
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(out), "-q")
    lines = output.strip().splitlines()
    assert code == 2 and len(lines) == 1, output
    assert lines[0].startswith(f"error: {path}: key controller.") and str(culprit) in lines[0] and "refused" in lines[0]
    assert not out.exists()


def test_a_package_beside_the_scenario_runs_with_its_relative_imports(tmp_path: Path, plant_fmu: Path) -> None:
    """`lawpack.laws:make` from lawpack/ beside the scenario, whose laws.py takes its gain from a
    sibling module by a relative import; a link to a module owned by another user is refused."""
    package = tmp_path / "lawpack"
    package.mkdir()
    (package / "__init__.py").write_text("", encoding="utf-8")
    (package / "gains.py").write_text("GAIN = 17.0\n", encoding="utf-8")
    (package / "laws.py").write_text(
        PROPORTIONAL.format(gain="GAIN").replace("GAIN = GAIN", "from .gains import GAIN"), encoding="utf-8"
    )
    path = _scenario(tmp_path, "packaged", {"python": "lawpack.laws:make"})
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(tmp_path / "out"), "-q")
    assert code == 0, output
    trace = read_csv(tmp_path / "out" / "packaged" / "run" / "trace.csv")
    assert trace.column("iq_ref")[0] == pytest.approx(17.0 * (X_TARGET - X_START), rel=1e-12)
    if os.geteuid() == 0:
        foreign = tmp_path / "foreign"
        foreign.mkdir()
        (foreign / "theirs.py").write_text(PROPORTIONAL.format(gain=1.0), encoding="utf-8")
        os.chown(foreign / "theirs.py", 65534, 65534)
        (tmp_path / "linked.py").symlink_to(foreign / "theirs.py")
        path = _scenario(tmp_path, "linked", {"python": "linked:make"})
        code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(tmp_path / "out2"), "-q")
        assert code == 2 and "is owned by user id 65534" in output and "refused" in output, output


def test_a_module_on_sys_path_is_not_checked_for_ownership(tmp_path: Path, plant_fmu: Path, monkeypatch) -> None:
    """The user's own environment (PYTHONPATH) is theirs: a module there runs, group-writable or not."""
    library = tmp_path / "library"
    library.mkdir()
    (library / "pathlaws.py").write_text(PROPORTIONAL.format(gain=15.0), encoding="utf-8")
    (library / "pathlaws.py").chmod(0o664)
    monkeypatch.syspath_prepend(str(library))
    path = _scenario(tmp_path / "scenarios", "from_path", {"python": "pathlaws:make"})
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(tmp_path / "out"), "-q")
    assert code == 0, output


@pytest.mark.slow
def test_user_code_that_ends_hangs_or_interrupts_fails_its_own_run_only(
    tmp_path: Path, plant_fmu: Path, monkeypatch
) -> None:
    """Each misbehaviour fails its run with a reason naming the controller; the runs after it
    run; the command's process never imports the module; a chdir at import moves no output."""
    (tmp_path / "work").mkdir()
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "work" / "hostile.py").write_text(
        HOSTILE + f"\nif os.environ.get('HOSTILE_CHDIR'):\n    os.chdir({str(tmp_path / 'elsewhere')!r})\n",
        encoding="utf-8",
    )
    reasons = {
        "sleep": r"building the controller's module or factory hostile:make \(controller\.python\) did not finish: "
        r"time limit 2\.\d* s exceeded",
        "exit7": r"hostile:make \(controller\.python\) ended the run's process with status 7 while it was imported",
        "segv": r"hostile:make \(controller\.python\) crashed the run's process while it was imported or built "
        r"\(killed by SIGSEGV\)",
        "exit0": r"key controller\.python: hostile:make raised SystemExit: 0",
        "kbi": r"key controller\.python: hostile:make raised KeyboardInterrupt",
        "kbi_step": r"controller failed: the controller's step raised at t = 0\.005 s: KeyboardInterrupt",
        "exit_step": r"controller failed: the controller's step raised at t = 0\.005 s: SystemExit: 0",
        "segv_step": r"controller: the controller's hostile:make \(controller\.python\) ended the run's process: it was "
        r"killed by SIGSEGV while it computed the sample at t = 0\.005 s",
    }
    variants = {how: {"controller": {"parameters": {"how": how}}} for how in [*reasons, "exit_close"]}
    variants["sleep"]["time_limit"] = 2.5  # it sleeps 600 s; the other runs keep the default limit (30 s)
    variants["after"] = {}
    path = _scenario(tmp_path / "work", "hostile", {"python": "hostile:make"}, variants=variants)
    monkeypatch.chdir(tmp_path / "work")
    monkeypatch.setenv("HOSTILE_CHDIR", "1")
    before = set(sys.modules)
    code, output = _run(path.name, "--fmu", str(plant_fmu), "--out", "out", "-q")
    assert not any(name.startswith(("hostile", "toggle_cosim_scenario_")) for name in set(sys.modules) - before)
    assert code == 1, output
    for how, reason in reasons.items():
        record = json.loads((tmp_path / "work" / "out" / "hostile" / how / "run.json").read_text(encoding="utf-8"))
        assert record["status"] == "failed" and re.search(reason, record["reason"]), (how, record["reason"])
        assert re.search(reason, output), how
    for complete in ("after", "exit_close"):  # a close() that raises SystemExit changes nothing of the run
        record = json.loads((tmp_path / "work" / "out" / "hostile" / complete / "run.json").read_text(encoding="utf-8"))
        assert record["status"] == "complete", record["reason"]
    assert list((tmp_path / "elsewhere").iterdir()) == []  # every module changed directory: no output went there


def test_what_we_write_about_a_failure_and_relay_is_bounded(tmp_path: Path, plant_fmu: Path, monkeypatch) -> None:
    (tmp_path / "hostile.py").write_text(HOSTILE, encoding="utf-8")
    hows = ("big_command", "big_error", "print", "many_diagnostics")
    variants = {how: {"controller": {"parameters": {"how": how}}} for how in hows}
    path = _scenario(tmp_path, "bounded", {"python": "hostile:make"}, variants=variants)
    monkeypatch.setenv("TOGGLE_COSIM_MAX_LOG", "4K")
    monkeypatch.setenv("TOGGLE_COSIM_MAX_OUTPUT", "1000000")  # 41 samples x 20013 columns x 8 bytes is 6.6 MB
    out = tmp_path / "out"
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(out), "-q", "--jobs", "1")
    assert code == 1
    assert len(output) < 12_000, len(output)  # 4 KiB of the print run's 410 KB, four lines, the summary
    assert re.search(r"\.\.\. \d+ more bytes of the run's output .* were dropped: .* 4096 bytes", output)
    for how, said in (("big_command", "[0, 1, 2, 3, 4, 5, 6, 7, ...] (a list of 10000000)"), ("big_error", "xxxx")):
        record = json.loads((out / "bounded" / how / "run.json").read_text(encoding="utf-8"))
        assert said in record["reason"] and len(record["reason"]) <= 400, (how, len(record["reason"]))
        assert (out / "bounded" / how / "run.json").stat().st_size < 10_000
    assert re.search(r"ValueError: x+… \(500000\d\d characters in all\)", output)
    printed = json.loads((out / "bounded" / "print" / "run.json").read_text(encoding="utf-8"))
    assert printed["status"] == "complete"
    many = json.loads((out / "bounded" / "many_diagnostics" / "run.json").read_text(encoding="utf-8"))
    assert many["reason"].startswith("controller: the controller's 20000 diagnostics make the trace 41 samples x")
    assert "over the 0.00 GB output limit" in many["reason"] and many["samples"] == 0


CRASH_LAW = '''
import ctypes
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class CrashLaw(Fmi2Slave):
    """iq_ref = 40 (0.3199 - x_B); its doStep from t = 0.005 s dereferences a null pointer."""

    author = "toggle-cosim tests"
    description = "crashes"

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.x_B = 0.2329
        self.register_variable(Real("x_B", causality=Fmi2Causality.input))
        self.register_variable(Real("iq_ref", causality=Fmi2Causality.output, getter=lambda: 40.0 * (0.3199 - self.x_B)))

    def do_step(self, current_time: float, step_size: float) -> bool:
        if current_time >= 0.005:
            ctypes.string_at(0)
        return True
'''


def test_a_controller_fmu_crash_names_the_controller(tmp_path: Path, plant_fmu: Path) -> None:
    """The controller FMU's doStep over [0.005, 0.0055] s segfaults (called at the sample
    0.0055 s, both couplings): the reason names the controller FMU, not the plant (a plant's own
    crash still names the plant: test_api, test_faults); the execution records a sample whole and
    says whose call it made."""
    fmu = build_python_fmu(CRASH_LAW, tmp_path, "CrashLaw")
    path = _scenario(
        tmp_path, "crash", {"fmu": fmu.name}, variants={"gauss_seidel": {}, "jacobi": {"coupling": "jacobi"}}
    )
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(tmp_path / "out"), "-q")
    assert code == 1, output
    for variant in ("gauss_seidel", "jacobi"):
        record = json.loads((tmp_path / "out" / "crash" / variant / "run.json").read_text(encoding="utf-8"))
        assert record["reason"] == (
            "controller: the controller FMU CrashLaw.fmu (controller.fmu) ended the run's process: it was killed by"
            " SIGSEGV while it computed the sample at t = 0.0055 s"
        ), record["reason"]
        assert "plant" not in record["reason"]


def test_a_string_for_a_controller_fmu_real_parameter_is_refused_before_any_run(
    tmp_path: Path, plant_fmu: Path
) -> None:
    from toggle_cosim.controller_fmu import build_controller_fmu

    fmu = build_controller_fmu(tmp_path / "ToggleVSC.fmu").path
    path = _scenario(tmp_path, "typed", {"fmu": fmu.name, "parameters": {"C": "five"}})
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(tmp_path / "out"), "-q")
    lines = output.strip().splitlines()
    assert code == 2 and len(lines) == 1, output
    assert "key controller.parameters.C: the controller FMU ToggleVSC.fmu's parameter 'C' is of type Real" in lines[0]
    assert "so give a number, not 'five'" in lines[0] and not (tmp_path / "out").exists()


def test_a_sweep_survives_a_controller_that_kills_its_parent(tmp_path: Path, plant_fmu: Path) -> None:
    """The second case kills its process's parent, the third segfaults in its step: those cases
    fail (the crash naming the controller), the sweep's own process lives on, the other cases
    complete (exit 1: a case failed)."""
    (tmp_path / "hostile.py").write_text(HOSTILE, encoding="utf-8")
    base = _scenario(tmp_path, "killer", {"python": "hostile:make", "parameters": {"how": "none"}})
    axis = {"controller.parameters.how": {"values": ["none", "kill_parent", "segv_step", "print"]}}
    sweep = {"base": base.name, "axes": axis, "output": "swept"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    command = [sys.executable, "-m", "toggle_cosim", "sweep", "sweep.yaml", "--fmu", str(plant_fmu), "--workers", "1"]
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    from toggle_cosim.experiments.sweep import read_results

    table = read_results(tmp_path / "swept")
    assert list(table["status"]) == ["ok", "failed", "failed", "ok"]
    for case, signal_name in ((1, "SIGKILL"), (2, "SIGSEGV")):  # the controller named, not the plant
        assert table["reason"][case] == (
            f"controller: the controller's hostile:make (controller.python) ended the run's process: it was killed by"
            f" {signal_name} while it computed the sample at t = 0.005 s"
        ), table["reason"][case]


PARTING = """
import os
import signal
import time

import toggle_cosim.cosim.isolation.supervision as supervision
from toggle_cosim.control.protocol import ControlStep

_send = supervision._send


def _send_then_kill(fd, message):
    _send(fd, message)
    if message[0] == "outcome":  # the run's answer is out: now kill the process's parent
        os.kill(os.getppid(), signal.SIGKILL)
        time.sleep(5)  # ended meanwhile: its process dies with its parent


class Law:
    diagnostics = ()
    measured = ("x_B",)

    def start(self, t0, measurement):
        return None

    def step(self, state, t, measurement):
        return ControlStep(40.0 * (0.3199 - measurement["x_B"]), (), state)


def make(context):
    supervision._send = _send_then_kill  # in the run's child, where the factory is called
    return Law()
"""


def test_a_controller_that_kills_its_parent_after_the_answer_fails_its_run(tmp_path: Path, plant_fmu: Path) -> None:
    """The controller's code kills its process's parent (SIGKILL) right after the run's complete
    answer went out, the latest moment it can: the run is failed with the signal in the reason,
    not complete (docs/security.md), in the pair and as a system; the run after it completes."""
    (tmp_path / "parting.py").write_text(PARTING, encoding="utf-8")
    variants = {"pair": {}, "system": {"record": ["plant.x_B", "controller.iq_ref"]}}
    path = _scenario(tmp_path, "parting", {"python": "parting:make"})
    document = yaml.safe_load(path.read_text(encoding="utf-8"))
    system = {**document, "name": "parting_system", "record": variants["system"]["record"]}
    (tmp_path / "parting_system.yaml").write_text(yaml.safe_dump(system), encoding="utf-8")
    after = _scenario(tmp_path, "after", None)
    out = tmp_path / "out"
    code, output = _run(
        str(path), str(tmp_path / "parting_system.yaml"), str(after), "--fmu", str(plant_fmu), "--out", str(out), "-q"
    )
    assert code == 1, output
    for name in ("parting", "parting_system"):
        record = json.loads((out / name / "run" / "run.json").read_text(encoding="utf-8"))
        assert record["status"] == "failed", (name, record["reason"])
        assert record["reason"] == "the plant process was killed by SIGKILL after the run's last sample at t = 0.02 s"
    assert json.loads((out / "after" / "run" / "run.json").read_text(encoding="utf-8"))["status"] == "complete"


@pytest.mark.slow
@pytest.mark.parametrize(
    ("how", "said"),
    [
        ("segv", "crashed the run's process while it was imported or built (killed by SIGSEGV)"),
        ("exit0", "key controller.python: hostile:make raised SystemExit: 0"),
        ("sleep", "did not finish: time limit 1.5 s exceeded"),
    ],
)
def test_a_sweep_builds_its_controllers_in_a_child_before_any_case(
    tmp_path: Path, plant_fmu: Path, how: str, said: str
) -> None:
    """A factory that crashes, exits 0 or hangs stops the sweep before any case: one line, exit 2,
    nothing written, and the sweep's own process lives (exit 0 and 139 before)."""
    (tmp_path / "hostile.py").write_text(HOSTILE, encoding="utf-8")
    base = _scenario(tmp_path, "probed", {"python": "hostile:make", "parameters": {"how": how}})
    sweep = {"base": base.name, "axes": {"plant.F_E": {"values": [0.0, 10.0]}}, "output": "swept"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    command = [sys.executable, "-m", "toggle_cosim", "sweep", "sweep.yaml", "--fmu", str(plant_fmu), "--quiet"]
    limit = ["--case-timeout", "1.5"] if how == "sleep" else []  # it sleeps 600 s; the others end by themselves
    done = subprocess.run([*command, *limit], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, (done.returncode, done.stderr)
    assert lines[0].startswith("error: sweep.yaml: case 0: ") and said in lines[0], lines
    assert not (tmp_path / "swept").exists()


def test_a_plant_that_answers_fatal_to_reset_is_never_called_again(
    tmp_path: Path, plant_fmu: Path, monkeypatch
) -> None:
    """The shim's fmi2Reset answers Fatal and aborts at any later call: every case still completes,
    each on a new host (without the rule, the next call aborts the host and fails the case)."""
    from toggle_cosim.experiments.sweep import read_results, run_sweep
    from toggle_cosim.plant.contract import check_plant

    faulty = make_faulty_fmu(plant_fmu, tmp_path / "faulty.fmu")
    for name, value in fault_environment("resetfatal", 1e9, check_plant(faulty).references).items():
        if name.startswith("TOGGLE_"):
            monkeypatch.setenv(name, value)
    base = _scenario(tmp_path, "fatal_reset", None)
    sweep = {"base": base.name, "axes": {"plant.F_E": {"values": [0.0, 5.0, 10.0]}}, "output": "swept"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, faulty, progress=False) == 0
    assert list(read_results(tmp_path / "swept")["status"]) == ["ok"] * 3


def test_simulate_in_process_unzips_into_a_run_folder_it_removes(plant_fmu: Path) -> None:
    import toggle_cosim as tc
    from toggle_cosim.control.protocol import ControlStep
    from toggle_cosim.cosim.isolation.supervision import FOLDER_PREFIX
    from toggle_cosim.experiments.scenario import runs_from_document

    seen: list[str] = []

    class Watching:
        diagnostics = ()

        def start(self, t0, measurement):  # noqa: ANN001, ANN201
            seen.append(tempfile.gettempdir())
            return 0

        def step(self, state, t, measurement):  # noqa: ANN001, ANN201
            return ControlStep(0.0, (), state)

    (run,) = runs_from_document({"name": "watched", **SCENARIO}, None)
    result = tc.simulate(run, plant_fmu, supervised=False, controller=Watching())
    assert result.status == "complete" and len(seen) == 1
    folder = Path(seen[0])
    assert folder.name.startswith(f"{FOLDER_PREFIX}{os.getpid()}-") and not folder.exists()
    assert tempfile.gettempdir() != seen[0]


def test_an_in_process_run_that_crashes_leaves_a_folder_the_next_command_removes(
    tmp_path: Path, plant_fmu: Path, monkeypatch
) -> None:
    """A child process runs simulate(supervised=False) on a plant that segfaults at t = 0.01 s: the
    FMU's unzipped copy it leaves is in a run folder named by its process id, which
    `remove_stale_folders` (every command's first step) then removes."""
    import toggle_cosim as tc
    from toggle_cosim.cosim.isolation.supervision import FOLDER_PREFIX, remove_stale_folders
    from toggle_cosim.experiments.scenario import runs_from_document
    from toggle_cosim.plant.contract import check_plant

    faulty = make_faulty_fmu(plant_fmu, tmp_path / "faulty.fmu")
    for name, value in fault_environment("segfault", 0.01, check_plant(faulty).references).items():
        if name.startswith("TOGGLE_"):
            monkeypatch.setenv(name, value)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    (run,) = runs_from_document({"name": "crashing", **SCENARIO}, None)
    tc.simulate(run, faulty, supervised=True)  # the plant checked (and probed) here, before the fork
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork with threads: the child only runs the plant
        pid = os.fork()
    if pid == 0:  # pragma: no cover - the child dies in the plant
        faulthandler.disable()  # pytest's dump of the crash is not this test's output
        try:
            tc.simulate(run, faulty, supervised=False)
        finally:
            os._exit(0)
    _, status = os.waitpid(pid, 0)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == 11
    left = list(scratch.glob(f"{FOLDER_PREFIX}{pid}-*"))
    assert len(left) == 1 and any(left[0].rglob("modelDescription.xml"))
    assert remove_stale_folders(scratch) == left and not left[0].exists()


def test_the_figure_worker_never_imports_from_the_current_folder(tmp_path: Path, monkeypatch) -> None:
    from toggle_cosim.analysis.figure_worker import FigureWorker

    for name in ("toggle_cosim.py", "copyreg.py", "matplotlib.py"):
        (tmp_path / name).write_text(f"open({str(tmp_path / (name + '.ran'))!r}, 'w').close()\n", encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    worker = FigureWorker()
    worker.submit(tmp_path / "no_such_results")
    lines = worker.results()
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    assert list(tmp_path.glob("*.ran")) == []


def test_bounded_text_keeps_a_line_and_says_how_long_it_was() -> None:
    from toggle_cosim.messages import bounded_text, error_text, short_repr

    text = bounded_text("a\nb " + "c" * 1000)
    assert "\n" not in text and len(text) <= 400 and text.endswith("… (1004 characters in all)")
    assert bounded_text("short  text\n") == "short text"
    assert error_text(KeyboardInterrupt()) == "KeyboardInterrupt"
    assert short_repr(np.zeros(10**7)).endswith("(a ndarray of 10000000)")


def test_a_bad_output_cap_is_one_line_before_any_run(tmp_path: Path, plant_fmu: Path, monkeypatch) -> None:
    path = _scenario(tmp_path, "capped", None)
    monkeypatch.setenv("TOGGLE_COSIM_MAX_LOG", "-1")
    code, output = _run(str(path), "--fmu", str(plant_fmu), "--out", str(tmp_path / "out"), "-q")
    lines = output.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "TOGGLE_COSIM_MAX_LOG='-1': give a number of bytes" in lines[0], output
    assert not (tmp_path / "out").exists()
