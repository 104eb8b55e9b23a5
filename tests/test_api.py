"""The public Python API (`import toggle_cosim as tc`), against the command line it stands beside.

* `tc.simulate` gives the trace `toggle-cosim run` writes, bit for bit, supervised and in-process;
* a plant that segfaults or aborts fails the supervised run with the reason, and this process
  (a notebook's kernel) goes on running;
* a scenario dict is validated as the same YAML file is: the same one-line ScenarioError;
* the DataFrame's units are the plant FMU's (the contract's units) and the controller's;
* `tc.compare` gives the command line's verdict; `tc.sweep` the rows the runs themselves give.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from fault_plants import fault_environment, make_faulty_fmu

import toggle_cosim as tc
from toggle_cosim.analysis.compare_command import run_compare
from toggle_cosim.cli import main
from toggle_cosim.control.protocol import ControlStep
from toggle_cosim.files.traces import read_csv
from toggle_cosim.plant.contract import CONTRACT, check_plant

ROOT = Path(__file__).resolve().parent.parent
FIG4 = ROOT / "scenarios" / "fig4_nominal.yaml"
# Fig. 4's stroke, gains and plant (mu = 0.2) for 0.3 s, in the faulty plant's layout of
# test_supervision: the fault comes at 0.1 s in runs with F_E >= 50 N ("hit"), never in "clean"
SHORT = {
    **{key: value for key, value in yaml.safe_load(FIG4.read_text()).items() if key not in ("fmu", "variants")},
    "name": "short",
    "t_end": 0.3,
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
    "variants": {"hit": {"plant": {"F_E": 60.0}}, "clean": {"plant": {"F_E": 0.0}}},
}
T_FAULT, ROWS_TO_FAULT = 0.1, 201  # samples t = 0 .. 0.1 s at T_s = 0.5 ms


# -- the package's one import --------------------------------------------------------------------


def test_importing_the_package_imports_none_of_the_api() -> None:
    """The command line imports `toggle_cosim` first thing: the API and its libraries load on use."""
    code = (
        "import sys, toggle_cosim as tc\n"
        "heavy = sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'pandas', 'fmpy')"
        " or m.startswith('toggle_cosim.api'))\n"
        "print(heavy)\n"
        "tc.simulate\n"
        "print('toggle_cosim.api.simulation' in sys.modules)\n"
    )
    lines = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert lines == ["[]", "True"]


def test_every_public_name_resolves_and_says_what_it_is() -> None:
    for name in tc.__all__:
        value = getattr(tc, name)
        if name != "__version__":
            assert (value.__doc__ or "").strip(), name
        assert name in dir(tc)
    with pytest.raises(AttributeError, match="no attribute 'simulatee'"):
        tc.simulatee  # noqa: B018
    from toggle_cosim.experiments.scenario import ScenarioError

    assert tc.ScenarioError is ScenarioError  # one class, whichever way it is imported


# -- scenarios ----------------------------------------------------------------------------------


def test_a_scenario_is_its_runs_by_variant_name() -> None:
    fig4 = tc.load_scenario(FIG4)
    assert fig4.name == "fig4_nominal" and list(fig4) == ["friction", "no_friction"]
    assert fig4["friction"].plant.mu == 0.2 and fig4["no_friction"].plant.mu == 0.0
    with pytest.raises(KeyError, match="no variant 'dry' .*it has: friction, no_friction"):
        fig4["dry"]
    with pytest.raises(ValueError, match="2 variants"):
        fig4.run  # noqa: B018
    single = tc.scenario({key: value for key, value in SHORT.items() if key != "variants"})
    assert list(single) == ["run"] and single.run is single["run"] and single.run.variant is None
    shorter = fig4.updated({"t_end": 0.25, "plant": {"F_E": 40.0}})
    assert [run.t_end for run in shorter.runs] == [0.25, 0.25]
    assert [run.plant.F_E for run in shorter.runs] == [40.0, 40.0]
    assert [run.plant.mu for run in shorter.runs] == [0.2, 0.0]  # the variants still apply
    assert fig4["friction"].t_end == 1.5  # the original is unchanged
    with pytest.raises(tc.ScenarioError, match=f"^{FIG4}: key t_end: "):
        fig4.updated({"t_end": -1})


BAD_DOCUMENTS = [
    ({**SHORT, "plant": {"mu": 3}}, "key plant.mu: 3 is out of range"),
    ({**SHORT, "plant": {"F_E": "heavy"}}, "key plant.F_E: 'heavy' is not of type number or mapping"),
    ({**SHORT, "plant": {"m_B": float("nan")}}, "key plant.m_B: nan is not a finite number"),
    ({**SHORT, "colour": "red"}, "unknown key colour"),
    ({key: value for key, value in SHORT.items() if key != "T_s"}, "missing key: 'T_s'"),
    ({**SHORT, "stroke": {"x_start": 0.2329, "x_target": 0.9}}, "key stroke.x_target (variant hit): 0.9 m is outside"),
    ({**SHORT, "variants": {"v": {"controller": {"law": "pid"}}}}, "key variants.v.controller.law: 'pid'"),
]


@pytest.mark.parametrize(("document", "expected"), BAD_DOCUMENTS, ids=[e for _, e in BAD_DOCUMENTS])
def test_a_bad_dict_gets_the_one_line_error_of_the_same_file(document: dict, expected: str, tmp_path: Path) -> None:
    with pytest.raises(tc.ScenarioError) as from_dict:
        tc.scenario(document)
    message = str(from_dict.value)
    assert expected in message and "\n" not in message
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    with pytest.raises(tc.ScenarioError) as from_file:
        tc.load_scenario(path)
    assert str(from_file.value) == f"{path}: {message}"


def test_what_is_not_a_scenario_dict_is_refused_in_one_line() -> None:
    with pytest.raises(tc.ScenarioError, match="^a scenario is a mapping of scenario keys .*not list$"):
        tc.scenario([SHORT])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="needs a Run"):
        tc.simulate("scenarios/fig4_nominal.yaml")  # type: ignore[arg-type]


def test_the_project_s_files_are_found(plant_fmu: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    shipped = tc.shipped_scenarios()
    assert list(shipped)[:3] == ["fig4_nominal", "fig5_external_force", "fig6_mass_variation"]
    assert all(path.is_file() for path in shipped.values())
    run = tc.load_scenario(shipped["fig5_external_force"])["friction"]
    assert tc.stored_reference(run) == ROOT / "scenarios/references/fig5_external_force/friction_ref.csv"
    assert tc.stored_reference(run).is_file()
    # a project folder with the FMU in place: found from a folder below it, not built again
    for folder in ("scenarios", "modelica/ToggleLSM", "fmus", "examples"):
        (tmp_path / folder).mkdir(parents=True)
    fmu = tmp_path / "fmus" / "ToggleLSM.fmu"
    shutil.copy(plant_fmu, fmu)
    source = tmp_path / "modelica" / "ToggleLSM" / "package.mo"
    source.write_text("package ToggleLSM end ToggleLSM;\n")
    built = fmu.stat().st_mtime
    os.utime(source, (built - 60, built - 60))
    builds = []
    monkeypatch.setattr("toggle_cosim.fmu_export.build_fmu", lambda *arguments: builds.append(arguments))
    monkeypatch.chdir(tmp_path / "examples")
    assert tc.plant_fmu() == fmu and builds == []
    os.utime(source, (built + 60, built + 60))  # the source changed after the build: build again
    assert tc.plant_fmu() == fmu and builds == [(tmp_path / "modelica" / "ToggleLSM", "ToggleLSM.Plant", fmu)]
    with pytest.raises(ValueError, match="not a shipped plant .*ToggleLSM.Plant, ToggleLSM.PlantNoGravity"):
        tc.plant_fmu("ToggleLSM.Other")


# -- simulate -----------------------------------------------------------------------------------


def test_the_api_s_traces_are_the_command_line_s_bit_for_bit(plant_fmu: Path, tmp_path: Path) -> None:
    """Supervised and in-process, every sample of every column equals what `toggle-cosim run`
    wrote for the same scenario (trace.csv keeps 17 digits: it reads back exactly)."""
    out = tmp_path / "out"
    done = CliRunner().invoke(main, ["run", str(FIG4), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    assert done.exit_code == 0, done.output
    fig4 = tc.load_scenario(FIG4)
    for variant, run in fig4.items():
        written = read_csv(out / "fig4_nominal" / variant / "trace.csv")
        record = json.loads((out / "fig4_nominal" / variant / "run.json").read_text())
        for supervised in (True, False):
            result = tc.simulate(run, plant_fmu, supervised=supervised)
            assert result.ok and result.status == "complete" and result.reason is None
            assert result.trace.names == written.names
            assert np.array_equal(result.trace.data, written.data), (variant, supervised)
            assert result.summary is not None and result.summary.as_dict() == record["summary"]
            assert result.record["samples"] == record["samples"] == 3001
            assert result.record["loop"] == record["loop"]
    result.write(tmp_path / "again")  # a Result writes the command line's trace file, byte for byte
    written = (out / "fig4_nominal" / "no_friction" / "trace.csv").read_bytes()
    assert (tmp_path / "again" / "trace.csv").read_bytes() == written


def test_the_dataframe_carries_the_plant_s_and_the_controller_s_units(plant_fmu: Path) -> None:
    fig4 = tc.load_scenario(FIG4).updated({"t_end": 0.05})
    result = tc.simulate(fig4["friction"], plant_fmu, supervised=False)
    frame = result.to_dataframe()
    units = frame.attrs["units"]
    assert list(frame.columns) == list(result.trace.names[1:]) and frame.index.name == "time"
    assert np.array_equal(frame.index.to_numpy(), result.trace.time)
    assert np.array_equal(frame.to_numpy(), result.trace.data[:, 1:])
    contract = {v.name: v.unit for v in CONTRACT if v.causality != "parameter" and v.name in frame.columns}
    assert {name: units[name] for name in contract} == contract  # the plant's units are the contract's
    assert units["time"] == "s"
    assert (units["e"], units["S"], units["phase"]) == ("m", "m/s", "1")  # e = x_B* − x_B, S = C e + ė
    assert set(units) == {"time", *frame.columns}
    levels = result.to_dataframe(multiindex=True).columns
    assert list(levels.names) == ["variable", "unit"]
    assert ("x_B", "m") in levels and ("iq_ref", "A") in levels and ("E_fric", "J") in levels
    theta = tc.scenario({**SHORT, "t_end": 0.05, "controller": {**SHORT["controller"], "objective": "theta1"}})
    angle = tc.simulate(theta["clean"], plant_fmu, supervised=False)
    assert (angle.units["e"], angle.units["S"]) == ("rad", "rad/s")  # e = θ1* − θ1, S = C e + dθ1/dt error


@pytest.fixture(scope="module")
def faulty_fmu(plant_fmu: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_faulty_fmu(plant_fmu, tmp_path_factory.mktemp("faulty") / "Faulty.fmu")


def _arm(kind: str, fmu: Path, monkeypatch: pytest.MonkeyPatch, mark: Path | None = None) -> None:
    environment = fault_environment(kind, T_FAULT, check_plant(fmu).references, min_F_E=50.0, mark=mark)
    for key, value in environment.items():
        monkeypatch.setenv(key, value)


@pytest.mark.parametrize(("kind", "reason"), [("segfault", "SIGSEGV"), ("abort", "SIGABRT")])
def test_a_crashing_plant_fails_the_run_not_this_process(
    kind: str, reason: str, faulty_fmu: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _arm(kind, faulty_fmu, monkeypatch)
    short = tc.scenario(SHORT)
    failed = tc.simulate(short["hit"], faulty_fmu, time_limit=10)
    assert failed.status == "failed" and not failed.ok
    assert f"the plant process was killed by {reason} at t = {T_FAULT:g} s" in failed.reason
    assert failed.trace.data.shape[0] == ROWS_TO_FAULT and np.all(np.isfinite(failed.trace.data))
    assert failed.record["status"] == "failed" and failed.record["reason"] == failed.reason
    assert failed.to_dataframe().index[-1] == pytest.approx(T_FAULT, abs=1e-12)
    clean = tc.simulate(short["clean"], faulty_fmu)  # this process lives on and runs the next one
    assert clean.ok and clean.trace.data.shape[0] == 601


def test_a_plant_error_in_process_is_a_failed_result(faulty_fmu: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _arm("error", faulty_fmu, monkeypatch)
    failed = tc.simulate(tc.scenario(SHORT)["hit"], faulty_fmu, supervised=False)
    assert failed.status == "failed" and "fmi2DoStep failed with status 3 (error)" in failed.reason


def test_an_interrupt_stops_the_run_and_keeps_its_partial_result(
    faulty_fmu: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The notebook's stop button sends SIGINT: the plant (here stuck in an endless loop in C)
    is killed, and the partial result travels with the exception. The signal is sent once the
    plant is in its loop (it marks the file first), from the progress callback, which the run
    calls at least every 0.1 s while it waits for the child."""
    marked = tmp_path / "in-the-loop"
    _arm("loop", faulty_fmu, monkeypatch, mark=marked)
    sent = []

    def stop_once_looping(fraction: float) -> None:
        if marked.exists() and not sent:
            sent.append(fraction)
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(tc.RunInterrupted) as stopped:
        tc.simulate(tc.scenario(SHORT)["hit"], faulty_fmu, time_limit=30, progress=stop_once_looping)
    assert sent and isinstance(stopped.value, KeyboardInterrupt)
    result = stopped.value.result
    assert result.status == "interrupted" and result.trace.data.shape[0] == ROWS_TO_FAULT


def test_what_the_plant_cannot_do_is_refused_before_the_run(plant_fmu: Path, tmp_path: Path) -> None:
    run = tc.scenario(SHORT)["clean"]
    with pytest.raises(tc.ContractError, match="no such FMU file"):
        tc.simulate(run, tmp_path / "missing.fmu")
    with pytest.raises(tc.ScenarioError, match="^short/clean: no fmu: key and no fmu argument"):
        tc.simulate(run)
    odd = tc.scenario({**SHORT, "plant": {"parameters": {"no_such_parameter": 1.0}}})
    with pytest.raises(tc.ScenarioError, match="plant.parameters.no_such_parameter .*has no variable"):
        tc.simulate(odd["clean"], plant_fmu)


# -- compare and sweep --------------------------------------------------------------------------


@pytest.mark.slow
def test_compare_gives_the_command_line_s_verdict(plant_fmu: Path, tmp_path: Path) -> None:
    fig4 = tc.load_scenario(FIG4)
    friction = tc.simulate(fig4["friction"], plant_fmu)
    same = tc.compare(friction, tc.stored_reference(fig4["friction"]))
    assert same and same.failed == () and same.solver is not None and not same.solver.changed
    assert max(same.max_deviation.values()) == 0.0  # the reference's samples, reproduced exactly
    # friction against the frictionless reference: the friction work E_fric cannot pass
    other = tc.stored_reference(fig4["no_friction"])
    differs = tc.compare(friction, other)
    assert not differs and "E_fric" in differs.failed and "x_B" not in differs.failed
    table = differs.to_dataframe()
    assert table.loc["E_fric", "unit"] == "J" and not table.loc["E_fric", "passed"]
    assert table.loc["E_fric", "max_deviation"] > table.loc["E_fric", "tolerance"]
    # the frictionless reference has E_fric = 0: the deviation is |E_fric| at its samples (every 10th)
    e_fric = friction.trace.column("E_fric")
    assert table.loc["E_fric", "max_deviation"] == np.max(np.abs(e_fric[np.r_[0:3001:10, 3000]]))
    friction.write(tmp_path / "run")
    assert run_compare(tmp_path / "run" / "trace.csv", other) == 1
    from_file = tc.compare(tmp_path / "run" / "trace.csv", other)
    assert from_file.failed == differs.failed and dict(from_file.max_deviation) == dict(differs.max_deviation)
    # two in-memory results: the built-in default tolerances
    assert tc.compare(friction, tc.simulate(fig4["friction"], plant_fmu, supervised=False))
    with pytest.raises(tc.CompareInputError, match="time ends at"):
        tc.compare(tc.simulate(fig4.updated({"t_end": 0.5})["friction"], plant_fmu), other)


def test_sweep_returns_the_rows_the_runs_give(plant_fmu: Path, tmp_path: Path) -> None:
    base = tmp_path / "short.yaml"
    base.write_text(yaml.safe_dump({**SHORT, "fmu": str(plant_fmu)}, sort_keys=False))
    sweep_file = tmp_path / "sweep.yaml"
    axes = {"plant.F_E": {"values": [0.0, 80.0]}}
    sweep_file.write_text(yaml.safe_dump({"base": "short.yaml", "variant": "clean", "axes": axes}))
    table = tc.sweep(sweep_file, output=tmp_path / "out", workers=1)
    assert list(table["plant.F_E"]) == [0.0, 80.0] and list(table["status"]) == ["ok", "ok"]
    assert table.attrs["output"] == str(tmp_path / "out") and (tmp_path / "out" / "results.parquet").is_file()
    for _, row in table.iterrows():  # each row's figures of merit are those of the same run, exactly
        case = {"variants": {"clean": {"plant": {"F_E": row["plant.F_E"]}}}}  # the variant sets F_E itself
        summary = tc.simulate(tc.load_scenario(base).updated(case)["clean"]).summary
        assert (row["final_error_m"], row["peak_iq_ref_A"]) == (summary.final_error_m, summary.peak_iq_ref_A)
    with pytest.raises(tc.SweepError, match=r"^\S*nope.yaml: no such sweep file$"):
        tc.sweep(tmp_path / "nope.yaml")


class _Proportional:
    """A user's controller meeting the protocol: i_q* = K (x* − x_B), its error recorded."""

    diagnostics = ("e",)  # the built-in law's name for its error: no unit may be guessed for it

    def __init__(self, gain: float, target: float) -> None:
        self.gain, self.target = gain, target

    def start(self, t0: float, measurement: object) -> None:
        return None

    def step(self, state: None, t: float, measurement: Mapping[str, float]) -> ControlStep:
        error = self.target - measurement["x_B"]
        return ControlStep(self.gain * error, (error,), state)


@pytest.mark.parametrize("supervised", [False, True], ids=["in-process", "supervised"])
def test_a_user_s_controller_object_gives_its_command_at_every_sample(plant_fmu: Path, supervised: bool) -> None:
    """simulate(controller=...) runs the user's law at every sample (never the compiled built-in
    law), the trace carries its own diagnostic, and run.json says the Python loop ran."""
    run = tc.load_scenario(FIG4).updated({"t_end": 0.05})["friction"]
    result = tc.simulate(run, plant_fmu, supervised=supervised, controller=_Proportional(20.0, run.x_target))
    frame = result.to_dataframe()
    assert result.status == "complete" and "e" in frame.columns and "S" not in frame.columns
    np.testing.assert_array_equal(frame["e"].to_numpy(), run.x_target - frame["x_B"].to_numpy())
    np.testing.assert_array_equal(frame["iq_ref"].to_numpy(), 20.0 * frame["e"].to_numpy())
    assert result.record["loop"]["kind"] == "python"
    assert "e" not in frame.attrs["units"] and frame.attrs["units"]["x_B"] == "m"  # the user's e has no unit


def test_an_object_that_is_not_a_controller_is_refused_in_one_line(plant_fmu: Path) -> None:
    run = tc.load_scenario(FIG4).updated({"t_end": 0.05})["friction"]
    with pytest.raises(tc.ScenarioError, match=r"^controller: .*has no start\(\) method") as caught:
        tc.simulate(run, plant_fmu, supervised=False, controller=object())
    assert "\n" not in str(caught.value)


def test_simulate_returns_every_sample_of_a_run_whose_last_diagnostic_turns_nan(plant_fmu: Path, tmp_path: Path):
    """Issue 37, item 1: `tc.simulate` (supervised, as by default) of a run whose controller's
    last diagnostic is NaN from t = 0.01 s: the result holds every sample, its record counts
    them, the NaN are there, and `Result.write` writes them all and reads back as written."""
    from nan_values import FINITE, SAMPLES, nan_controller_scenario

    run = next(iter(tc.load_scenario(nan_controller_scenario(tmp_path, 1)).values()))
    result = tc.simulate(run, plant_fmu)
    assert result.status == "complete"
    assert result.trace.data.shape[0] == result.record["samples"] == SAMPLES
    flag = result.trace.column("flag")
    assert np.all(flag[:FINITE] == 1.0) and np.all(np.isnan(flag[FINITE:]))
    assert len(result.to_dataframe()) == SAMPLES
    result.write(tmp_path / "written")
    written = read_csv(tmp_path / "written" / "trace.csv")
    assert np.array_equal(written.data, result.trace.data, equal_nan=True)
    assert json.loads((tmp_path / "written" / "run.json").read_text(encoding="utf-8"))["samples"] == SAMPLES
