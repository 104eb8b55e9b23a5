"""A load that varies in time, through the master with the real plant FMU: sample k sends u(t_k)
(the trace's F_E column is the signal at the trace's times), the plant feels it over [t_k, t_k+1]
(its work against F_E grows by F_E[k]·Δx_B in that step), the compiled and the Python loop give
the same trace bit for bit, jacobi coupling delays the command but not the load, and a sweep
varies the step's time."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.scenario import load_scenario, runs_from_document
from toggle_cosim.plant.contract import check_plant
from toggle_cosim.signals.definitions import Step, sample

ROOT = Path(__file__).resolve().parent.parent
T_END, T_S = 0.4, 0.0005
STEP = {"kind": "step", "start_time": 0.1, "height": 100.0}
PULSES = {"kind": "pulse", "period": 0.1, "width": 0.03, "amplitude": 60.0, "start_time": 0.05, "offset": 10.0}


def _document(F_E: object, **extra: object) -> dict:
    document = yaml.safe_load((ROOT / "scenarios" / "step_load.yaml").read_text())
    document.pop("variants")
    document.update({"t_end": T_END, "plant": {**document["plant"], "F_E": F_E}, **extra})
    return document


def _run(F_E: object, **extra: object):
    return runs_from_document(_document(F_E, **extra), ROOT / "scenarios" / "step_load.yaml")[0]


@pytest.fixture(scope="module")
def plant(plant_fmu: Path):
    return check_plant(plant_fmu)


@pytest.fixture(scope="module")
def step_runs(plant) -> dict:
    """The step load in the compiled loop and in the Python loop (TOGGLE_COSIM_KERNEL=0)."""
    run = _run(STEP)
    with pytest.MonkeyPatch.context() as patch:
        patch.delenv("TOGGLE_COSIM_KERNEL", raising=False)
        compiled = check_and_simulate(run, plant)
        patch.setenv("TOGGLE_COSIM_KERNEL", "0")
        python = check_and_simulate(run, plant)
    return {"run": run, "compiled": compiled, "python": python}


def test_the_trace_records_the_signal_at_every_communication_point(step_runs: dict) -> None:
    outcome = step_runs["compiled"]
    assert outcome.complete and outcome.record["loop"]["kind"] == "compiled"
    trace = outcome.trace
    F_E = trace.column("F_E")
    assert np.array_equal(F_E, sample(Step(100.0, 0.1), step_runs["run"].steps, T_S))
    assert np.array_equal(F_E, np.where(trace.time >= 0.1, 100.0, 0.0))
    assert int(np.argmax(F_E > 0)) == 200  # the sample at t = 0.1 s is the first to send 100 N
    assert outcome.record["inputs"] == {"F_E": {"kind": "step", "height": 100.0, "start_time": 0.1, "offset": 0.0}}


def test_the_plant_feels_the_load_of_sample_k_over_its_step(step_runs: dict) -> None:
    """E_load = ∫ F_E v_B dt: over [t_k, t_k+1] it grows by F_E[k] (x_B[k+1] − x_B[k]), so the load
    sent at the step's sample (not the one before or after) is what the plant integrated."""
    trace = step_runs["compiled"].trace
    E, F, x = trace.column("E_load"), trace.column("F_E"), trace.column("x_B")
    dE, work = np.diff(E), F[:-1] * np.diff(x)
    assert np.all(E[:201] == 0.0)  # no work before the load arrives (sample 200 at t = 0.1 s)
    assert np.allclose(dE, work, rtol=1e-4, atol=1e-9)
    assert dE[200] > 1e-4 and abs(dE[200] - work[200]) < 1e-4 * dE[200]


def test_compiled_and_python_loops_give_the_same_trace_bit_for_bit(step_runs: dict, plant) -> None:
    compiled, python = step_runs["compiled"], step_runs["python"]
    assert python.record["loop"]["kind"] == "python"
    assert np.array_equal(compiled.trace.data, python.trace.data)
    run = _run(PULSES)
    with pytest.MonkeyPatch.context() as patch:
        patch.delenv("TOGGLE_COSIM_KERNEL", raising=False)
        a = check_and_simulate(run, plant)
        patch.setenv("TOGGLE_COSIM_KERNEL", "0")
        b = check_and_simulate(run, plant)
    assert a.complete and np.array_equal(a.trace.data, b.trace.data)
    assert np.array_equal(a.trace.column("F_E"), sample(run.plant.F_E, run.steps, T_S))


def test_jacobi_delays_the_command_but_sends_the_load_of_its_own_sample(step_runs: dict, plant) -> None:
    """Jacobi: the plant gets iq_ref of sample k − 1, and the load u(t_k) (a signal needs no
    exchange: its value at t_k is known at t_k)."""
    outcome = check_and_simulate(step_runs["run"], plant, coupling="jacobi")
    assert outcome.complete
    assert np.array_equal(outcome.trace.column("F_E"), step_runs["compiled"].trace.column("F_E"))
    E, F, x = (outcome.trace.column(name) for name in ("E_load", "F_E", "x_B"))
    assert np.allclose(np.diff(E), F[:-1] * np.diff(x), rtol=1e-4, atol=1e-9)
    assert not np.array_equal(outcome.trace.column("x_B"), step_runs["compiled"].trace.column("x_B"))


def test_a_constant_load_as_a_number_or_as_a_step_at_zero_gives_the_same_bits(plant) -> None:
    number = check_and_simulate(_run(100.0, t_end=0.1), plant)
    step = check_and_simulate(_run({"kind": "step", "start_time": 0.0, "height": 100.0}, t_end=0.1), plant)
    assert np.array_equal(number.trace.data, step.trace.data)


def test_the_shipped_step_load_runs_for_both_laws(plant) -> None:
    runs = load_scenario(ROOT / "scenarios" / "step_load.yaml")
    assert [run.variant for run in runs] == ["paper", "integral"]
    assert all(run.plant.F_E == Step(100.0, 0.25) for run in runs)


def test_a_sweep_varies_the_step_time(tmp_path: Path, plant_fmu: Path) -> None:
    from toggle_cosim.experiments.sweep import read_results, run_sweep
    from toggle_cosim.experiments.sweep_spec import load_sweep

    base = tmp_path / "base.yaml"
    document = _document(STEP, fmu=str(plant_fmu))
    document["t_end"] = 0.2
    base.write_text(yaml.safe_dump(document))
    sweep = tmp_path / "sweep.yaml"
    axes = {"plant.F_E.start_time": {"values": [0.05, 0.1]}, "plant.F_E.height": {"values": [50.0, 100.0]}}
    sweep.write_text(yaml.safe_dump({"base": "base.yaml", "axes": axes, "output": "out"}, sort_keys=False))
    spec = load_sweep(sweep)
    assert [case.document["plant"]["F_E"] for case in spec.cases[:2]] == [
        {**STEP, "start_time": 0.05, "height": 50.0},
        {**STEP, "start_time": 0.05, "height": 100.0},
    ]
    assert run_sweep(sweep, None, 1, plant_fmu, progress=False, keep_traces=True) == 0
    results = read_results(tmp_path / "out")
    assert len(results) == 4 and (results["status"] == "ok").all()
    assert results["plant.F_E"].isna().all()  # a signal has no one value; its swept keys are columns
    assert list(results["plant.F_E.start_time"]) == [0.05, 0.05, 0.1, 0.1]
    # an earlier, larger load stops the slider shorter: the final error grows with height, falls with time
    error = {(r["plant.F_E.start_time"], r["plant.F_E.height"]): r["final_error_m"] for _, r in results.iterrows()}
    assert error[(0.05, 100.0)] > error[(0.05, 50.0)] and error[(0.05, 100.0)] >= error[(0.1, 100.0)]


def test_unknown_signal_key_in_a_sweep_axis_is_refused(tmp_path: Path) -> None:
    from toggle_cosim.experiments.sweep_spec import SweepError, load_sweep

    base = tmp_path / "base.yaml"
    base.write_text(yaml.safe_dump(_document(copy.deepcopy(STEP))))
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": "base.yaml", "axes": {"plant.F_E.when": {"values": [0.1]}}}))
    with pytest.raises(SweepError, match="axis plant.F_E.when: unknown scenario key 'when' under plant.F_E"):
        load_sweep(sweep)


def test_a_csv_table_drives_the_run_and_run_json_names_its_file_and_hash(tmp_path: Path, plant_fmu: Path) -> None:
    """A hold table: sample k sends the value of the last row at or before t_k; run.json records
    the CSV's path, SHA-256, column and unit."""
    import hashlib
    import json

    from click.testing import CliRunner

    from toggle_cosim.cli import main

    table = tmp_path / "load.csv"
    table.write_text("time [s],F_E [N]\n0,0\n0.0512,30\n0.1,-10\n0.2,-10\n", encoding="utf-8")
    document = _document({"kind": "table", "file": "load.csv", "interpolation": "hold"}, fmu=str(plant_fmu))
    document["t_end"] = 0.2
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(document))
    ran = CliRunner().invoke(main, ["run", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "out"), "-q"])
    assert ran.exit_code == 0, ran.output
    folder = tmp_path / "out" / document["name"] / "run"
    from toggle_cosim.files.traces import read_csv

    trace = read_csv(folder / "trace.csv")
    t = trace.time
    expected = np.where(t >= 0.2, -10.0, np.where(t >= 0.1, -10.0, np.where(t >= 0.0512, 30.0, 0.0)))
    assert np.array_equal(trace.column("F_E"), expected)
    assert int(np.argmax(trace.column("F_E") == 30.0)) == 103  # 0.0512 s lies between samples 102 and 103
    record = json.loads((folder / "run.json").read_text())["inputs"]["F_E"]
    assert record["kind"] == "table" and record["interpolation"] == "hold" and record["unit"] == "N"
    assert record["sha256"] == hashlib.sha256(table.read_bytes()).hexdigest() and record["file"] == str(table)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time [s],F_E [N]\n0,0\n0.1,5\n0.05,5\n0.2,0\n", "line 4: time 0.05 comes before the time of line 3"),
        ("time [s],F_E [kN]\n0,0\n0.2,0.1\n", "gives column F_E in 'kN', the plant FMU's F_E is in 'N'"),
        ("time [s],F_E [N]\n0,0\n0.1,5\n", "the table ends at t = 0.1 s, before the run's t_end = 0.2 s"),
    ],
)
def test_a_bad_table_is_one_line_exit_2_and_nothing_written(
    tmp_path: Path, plant_fmu: Path, text: str, message: str
) -> None:
    from click.testing import CliRunner

    from toggle_cosim.cli import main

    (tmp_path / "load.csv").write_text(text, encoding="utf-8")
    document = _document({"kind": "table", "file": "load.csv", "interpolation": "linear"}, fmu=str(plant_fmu))
    document["t_end"] = 0.2
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(document))
    ran = CliRunner().invoke(main, ["run", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "out"), "-q"])
    assert ran.exit_code == 2
    lines = ran.output.strip().splitlines()
    assert (
        len(lines) == 1 and lines[0].startswith(f"error: {tmp_path / 's.yaml'}: key plant.F_E") and message in lines[0]
    )
    assert not (tmp_path / "out").exists()


def test_trim_refuses_a_load_that_varies_in_time() -> None:
    """An operating point holds slider B against one load: a step has none to hold against."""
    from toggle_cosim.design.trim import TrimError, external_force

    (run, _) = load_scenario(ROOT / "scenarios" / "step_load.yaml")
    with pytest.raises(TrimError, match="key plant.F_E: the load is a step in time; an operating point needs one"):
        external_force(run)
    assert external_force(_run(100.0)) == 100.0
