"""Parameter sweeps: cases, the results table, failures, resuming after a kill, Dask = local pool."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
import yaml

from toggle_cosim.experiments.sweep import METRICS, execute_sweep, load_sweep, read_results, run_sweep

pytestmark = pytest.mark.slow  # sweeps as commands: workers, Dask clusters, kills and resumes

ROOT = Path(__file__).resolve().parent.parent

BASE = {
    "name": "small",
    "description": "Fig. 4 stroke and gains, shortened",
    "t_end": 0.3,
    "T_s": 0.0005,
    "stroke": {"x_start": 0.2329, "x_target": 0.3199},
    "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2, "current_loop": "first_order"},
    "controller": {
        "objective": "x_B",
        "nominal_m_B": 4.43,
        "gains": {"C": 5, "Q": 4, "P": 50, "delta": 0.25, "beta": 65},
    },
}
AXES_8 = {
    "plant.F_E": {"values": [0, 50]},
    "plant.m_B": {"linspace": [4.43, 8.86, 2]},
    "plant.mu": {"values": [0.0, 0.2]},
}


def write_sweep(folder: Path, axes: dict, base: dict | None = None, **extra) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base.yaml").write_text(yaml.safe_dump(base or BASE, sort_keys=False), encoding="utf-8")
    document = {"base": "base.yaml", "axes": axes, "output": "out", **extra}
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def pool_run(tmp_path_factory, plant_fmu):
    """The 8-case sweep on the local process pool (the reference for the other tests)."""
    path = write_sweep(tmp_path_factory.mktemp("pool"), AXES_8, heatmap={"x": "plant.F_E", "y": "plant.m_B"})
    sweep = load_sweep(path)
    result = execute_sweep(sweep, fmu=plant_fmu, workers=2, progress=False)
    return sweep, result, read_results(sweep.output)


def test_table_has_one_row_per_case_with_its_parameters(pool_run):
    sweep, result, table = pool_run
    assert (result.total, result.skipped, result.ran, result.failed) == (8, 0, 8, 0)
    assert len(table) == 8 and table["case_id"].is_unique
    assert list(table["case"]) == list(range(8))
    expected = {(F_E, m_B, mu) for F_E in (0.0, 50.0) for m_B in (4.43, 8.86) for mu in (0.0, 0.2)}
    assert set(zip(table["plant.F_E"], table["plant.m_B"], table["plant.mu"], strict=True)) == expected
    assert (table["status"] == "ok").all() and table["reason"].isna().all()
    assert (table["t_end"] == 0.3).all() and (table["T_s"] == 0.0005).all()
    for column in ("final_error_m", "overshoot_percent", "peak_iq_ref_A", "E_in_J", "E_fric_J", "fric_share_start"):
        assert table[column].notna().all(), column
    assert (table.loc[table["plant.mu"] == 0.0, "E_fric_J"] == 0.0).all()
    assert (table.loc[table["plant.mu"] == 0.2, "E_fric_J"] > 0.0).all()
    # more load, more current
    heavy = table[(table["plant.F_E"] == 50.0)]["peak_iq_ref_A"].min()
    assert heavy > table[(table["plant.F_E"] == 0.0)]["peak_iq_ref_A"].max()
    assert not list((sweep.output / "parts").glob("*.parquet"))  # consolidated


def test_a_sweep_has_a_provenance_record_of_its_files_and_table(pool_run, plant_fmu):
    """provenance.srmd in the output folder names the sweep file, the base scenario and the plant
    by SHA3-256, with results.parquet as its data; every checksum matches."""
    from toggle_cosim.provenance import srmd

    sweep, _, _ = pool_run
    record = srmd.read_record(sweep.output / "provenance.srmd")
    assert [item.role for item in record.resources] == ["sweep", "scenario", "plant"]
    plant = record.resources[2]
    assert srmd.located(sweep.output / "provenance.srmd", plant.uri).resolve() == plant_fmu.resolve()
    assert record.data is not None and record.data.uri == "results.parquet"
    assert srmd.verify_record(sweep.output / "provenance.srmd") == []


def test_heat_maps_exist_one_per_other_axis_value(pool_run):
    sweep, result, _ = pool_run
    names = sorted(p.name for p in result.figures)
    assert names == ["heatmap_plant.mu=0.2.png", "heatmap_plant.mu=0.png"]
    for figure in result.figures:
        assert figure.is_file() and figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_heat_map_that_cannot_be_written_is_a_warning_and_sweep_json_is_written(tmp_path, plant_fmu, capsys):
    """A folder where one heat map goes: that map is not written (one warning line naming it),
    the other is, and the table and sweep.json (listing the written map only) are; exit 0."""
    axes = {"plant.F_E": {"values": [0, 50]}, "plant.m_B": {"values": [4.43]}, "plant.mu": {"values": [0.0, 0.2]}}
    path = write_sweep(tmp_path, axes, dict(BASE, t_end=0.05), heatmap={"x": "plant.F_E", "y": "plant.m_B"})
    blocked = tmp_path / "out" / "heatmaps" / "heatmap_plant.mu=0.png"
    blocked.mkdir(parents=True)
    assert run_sweep(path, None, 1, plant_fmu, progress=False) == 0
    manifest = json.loads((tmp_path / "out" / "sweep.json").read_text(encoding="utf-8"))
    assert manifest["heatmaps"] == ["heatmaps/heatmap_plant.mu=0.2.png"]
    assert len(read_results(tmp_path / "out")) == 4 and blocked.is_dir()
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 1 and str(blocked) in warnings[0] and "heat map not written" in warnings[0], warnings


def test_rerun_skips_everything_and_ids_are_stable(pool_run, plant_fmu):
    sweep, _, table = pool_run
    again = load_sweep(sweep.path)
    assert [c.case_id for c in again.cases] == list(table["case_id"])
    result = execute_sweep(again, fmu=plant_fmu, workers=2, progress=False)
    assert (result.skipped, result.ran) == (8, 0)
    assert read_results(sweep.output).equals(table)


def test_failed_case_is_recorded_and_the_sweep_goes_on(tmp_path, plant_fmu, capsys):
    axes = {"plant.parameters.mechanism.r3": {"values": [0.27, 0.05]}, "plant.F_E": {"values": [0, 50]}}
    path = write_sweep(tmp_path, axes)
    assert run_sweep(path, None, 2, plant_fmu, progress=False) == 1
    table = read_results(tmp_path / "out")
    assert len(table) == 4
    bad = table[table["plant.parameters.mechanism.r3"] == 0.05]
    good = table[table["plant.parameters.mechanism.r3"] == 0.27]
    assert (bad["status"] == "failed").all() and (good["status"] == "ok").all()
    for reason in bad["reason"]:
        assert "fmi2EnterInitializationMode" in reason and "not finite" in reason  # with the FMU's own log line
    assert bad["final_error_m"].isna().all() and good["final_error_m"].notna().all()
    out = capsys.readouterr().out
    assert "table: 2 ok, 2 failed, 0 not run, of 4 cases" in out


@pytest.mark.parametrize(
    ("axes", "extra", "message"),
    [
        ({"plant.F_X": {"values": [1]}}, {}, "axis plant.F_X: unknown scenario key 'F_X' under plant"),
        ({"plant.mu": {"values": [0.2, 1.5]}}, {}, "case 1 (plant.mu=1.5): key plant.mu: 1.5 is out of range"),
        (
            {"plant.mu": {"values": [0.2]}, "plant.F_E": {"values": [0, 1]}},
            {"mode": "zip"},
            "mode zip: every axis needs the same number",
        ),
        ({"plant.mu": {"values": [0.2, 0.2]}}, {}, "cases 0 and 1 are the same co-simulation"),
        ({"plant.mu": {"linspace": [0, 1]}}, {}, "key axes.plant.mu.linspace"),
        (
            {"plant.mu": {"values": [0.2]}},
            {"heatmap": {"x": "plant.mu", "y": "T_s"}},
            "key heatmap.y: 'T_s' is not an axis",
        ),
        ({"plant.parameters.nothing": {"values": [1.0]}}, {}, "the plant FMU has no variable 'nothing'"),
        ({"controller.gains": {"values": [1.0]}}, {}, "a group of keys"),
    ],
)
def test_bad_sweep_is_one_error_line_and_runs_nothing(tmp_path, plant_fmu, capsys, axes, extra, message):
    path = write_sweep(tmp_path, axes, **extra)
    assert run_sweep(path, None, 1, plant_fmu, progress=False) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {path}: ") and message in err[0], err
    assert not (tmp_path / "out").exists()  # bad input writes nothing


def test_random_axis_is_seeded_and_grid_and_zip_count_cases(tmp_path):
    axes = {"plant.F_E": {"random": {"low": 0, "high": 150, "n": 3, "seed": 7}}, "plant.m_B": {"values": [4.43, 5, 6]}}
    grid = load_sweep(write_sweep(tmp_path / "g", axes))
    zipped = load_sweep(write_sweep(tmp_path / "z", axes, mode="zip"))
    assert len(grid.cases) == 9 and len(zipped.cases) == 3
    assert grid.axes["plant.F_E"] == zipped.axes["plant.F_E"] == list(np.random.default_rng(7).uniform(0, 150, 3))
    assert [c.values for c in zipped.cases] == [
        {"plant.F_E": f, "plant.m_B": m} for f, m in zip(zipped.axes["plant.F_E"], [4.43, 5, 6], strict=True)
    ]
    # 5 and 5.0 are the same case
    again = load_sweep(write_sweep(tmp_path / "g2", {**axes, "plant.m_B": {"values": [4.43, 5.0, 6.0]}}))
    assert [c.case_id for c in again.cases] == [c.case_id for c in grid.cases]


def test_shipped_sweep_is_valid():
    sweep = load_sweep(ROOT / "scenarios" / "sweep_FE_mB.yaml")
    assert sweep.axes["plant.F_E"][0] == 0.0 and sweep.axes["plant.F_E"][-1] == 150.0
    assert sweep.axes["plant.m_B"][0] == 4.43 and sweep.axes["plant.m_B"][-1] == 8.86
    assert {c.parameters["plant.mu"] for c in sweep.cases} == {0.0, 0.2}
    assert sweep.heatmap == ("plant.F_E", "plant.m_B")


def test_killed_sweep_resumes_with_only_the_missing_cases(tmp_path, shim_fmu):
    """Rows are written in batches (here of 8 rows): a SIGKILL loses only the batch in flight, and
    the re-run runs only the cases not in a written batch. The kill comes once the first batch
    is written; the last four cases (F_E = 150 N, run last by the one worker) hold in fmi2DoStep
    behind the fault shim, so the sweep cannot have finished by then on any machine."""
    from fault_plants import fault_environment
    from process_events import wait_until

    from toggle_cosim.plant.contract import check_plant

    base = {**BASE, "t_end": 1.5}
    axes = {
        "plant.F_E": {"linspace": [0, 150, 32]},
        "plant.m_B": {"values": [4.43, 8.86]},
        "plant.mu": {"values": [0.0, 0.2]},
    }
    path = write_sweep(tmp_path, axes, base)
    parts = tmp_path / "out" / "parts"
    command = [sys.executable, "-m", "toggle_cosim.cli", "sweep", str(path), "--workers", "1", "--fmu", str(shim_fmu)]
    hold = fault_environment("", 0.0, check_plant(shim_fmu).references, 149.0, hold=tmp_path / "never")
    environment = {**hold, "TOGGLE_COSIM_SWEEP_BATCH_ROWS": "8"}
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True, env=environment
    )
    try:
        wait_until(lambda: list(parts.glob("batch-*.parquet")) or process.poll() is not None, "the first batch")
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the sweep and its plant hosts, no clean-up
        process.communicate()
    existing = {row["case_id"]: row for p in parts.glob("batch-*.parquet") for row in pq.read_table(p).to_pylist()}
    assert 1 <= len(existing) <= 124, f"{len(existing)} rows when killed"
    assert not (tmp_path / "out" / "results.parquet").exists()

    sweep = load_sweep(path)  # this process has no hold: every case runs the plant's own way
    result = execute_sweep(sweep, fmu=shim_fmu, workers=2, progress=False)
    assert result.skipped == len(existing)
    assert result.ran == 128 - len(existing)
    table = read_results(sweep.output)
    assert len(table) == 128 and set(table["case_id"]) == {c.case_id for c in sweep.cases}
    assert (table["status"] == "ok").all()
    for row in table.itertuples():  # the cases finished before the kill were not run again
        if row.case_id in existing:
            assert row.wall_s == existing[row.case_id]["wall_s"]
            assert row.final_error_m == existing[row.case_id]["final_error_m"]
    assert not parts.exists()  # consolidated


def test_a_worker_killed_from_outside_fails_only_its_case(tmp_path, plant_fmu):
    """SIGKILL to a plant host's pid: the case it was running is failed with the reason, a new
    host takes the next case, every other case is ok. The kill comes when the third case is
    handed back (nine are still to run), from the loop that collects them."""
    psutil = pytest.importorskip("psutil")
    base = {**BASE, "t_end": 1.5}
    path = write_sweep(tmp_path, {"plant.F_E": {"linspace": [0, 150, 12]}}, base)
    sweep = load_sweep(path)
    killed = []
    own = psutil.Process()
    before = {child.pid for child in own.children(recursive=True)}
    finished = []

    from toggle_cosim.experiments import sweep_exec

    original = sweep_exec.CaseRunner.service

    def counting(self, answer):
        result = original(self, answer)
        finished.append(result[0]["case_id"])
        if len(finished) == 3:
            host = next(child for child in own.children(recursive=False) if child.pid not in before)
            host.kill()
            killed.append(host.pid)
        return result

    sweep_exec.CaseRunner.service = counting
    try:
        result = execute_sweep(sweep, fmu=plant_fmu, workers=2, progress=False)
    finally:
        sweep_exec.CaseRunner.service = original
    assert killed, "no plant host to kill"
    table = read_results(sweep.output)
    assert len(table) == 12 and result.ran == 12
    failed = table[table["status"] != "ok"]
    assert len(failed) <= 1  # the host may have been between cases (then none failed)
    for reason in failed["reason"]:
        assert "killed by SIGKILL" in reason


def test_the_same_case_gives_the_same_bits_alone_first_and_after_others(tmp_path, plant_fmu):
    """A host keeps the plant loaded and resets its instance between cases: a case run alone,
    first in a host, after a complete case (a reset instance) and after a failed one (a new
    instance) gives the same trace, bit for bit."""
    from toggle_cosim.cosim.isolation.plant_host import wait_for_hosts
    from toggle_cosim.experiments.sweep_worker import CaseRunner
    from toggle_cosim.plant.contract import check_plant

    axes = {"plant.parameters.mechanism.r3": {"values": [0.27, 0.05]}, "plant.F_E": {"values": [0, 60]}}
    sweep = load_sweep(write_sweep(tmp_path, axes))
    plant = check_plant(plant_fmu)
    by_values = {(c.values["plant.parameters.mechanism.r3"], c.values["plant.F_E"]): c.payload() for c in sweep.cases}
    case, other, bad = by_values[(0.27, 60)], by_values[(0.27, 0)], by_values[(0.05, 0)]

    def traces(sequence):
        runner = CaseRunner(plant, plant.sha256, rows=1000, keep_traces=True)
        found = []
        try:
            for payload in sequence:
                runner.submit(payload)
                while runner.busy:
                    for _, answer in wait_for_hosts([runner.host]):
                        found.append(runner.service(answer))
        finally:
            runner.close()
        return found

    (alone,) = traces([case])
    first = traces([case, other])[0]
    after_ok, after_failed = (traces(s)[-1] for s in ([other, case], [bad, case]))
    assert alone[0]["status"] == "ok" and traces([bad])[0][0]["status"] == "failed"
    assert first[1] is not None and first[1].shape == (601, len(alone[1][0]))
    for row, trace in (first, after_ok, after_failed):
        assert trace.tobytes() == alone[1].tobytes()
        assert {k: row[k] for k in METRICS} == {k: alone[0][k] for k in METRICS}


def test_dask_local_cluster_gives_the_same_table_as_the_pool(pool_run, tmp_path, plant_fmu):
    distributed = pytest.importorskip("distributed")
    sweep, _, reference = pool_run
    dask_sweep = load_sweep(sweep.path, output=tmp_path / "dask")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        result = execute_sweep(dask_sweep, fmu=plant_fmu, scheduler=cluster.scheduler_address, progress=False)
    assert (result.ran, result.failed) == (8, 0)
    table = read_results(tmp_path / "dask")
    assert list(table["case_id"]) == list(reference["case_id"])
    parameters = ["case", "variant", *sweep.parameter_columns, "status", "fmu_sha256"]
    pd.testing.assert_frame_equal(table[parameters], reference[parameters])
    for column in (*METRICS, "samples"):
        np.testing.assert_allclose(
            table[column].to_numpy(float),
            reference[column].to_numpy(float),
            rtol=0,
            atol=1e-12,
            equal_nan=True,
            err_msg=column,
        )
    assert sorted(p.name for p in result.figures) == ["heatmap_plant.mu=0.2.png", "heatmap_plant.mu=0.png"]


PD_MODULE = """
from toggle_cosim.control.protocol import ControlStep


class PD:
    diagnostics = ("e",)

    def __init__(self, target, Kp, Kd):
        self.target, self.Kp, self.Kd = target, Kp, Kd

    def start(self, t0, measurement):
        return None

    def step(self, state, t, measurement):
        e = self.target - measurement["x_B"]
        return ControlStep(self.Kp * e - self.Kd * measurement["v_B"], (e,), state)


def make_pd(context, Kp, Kd):
    return PD(context.x_target, Kp, Kd)
"""


def test_dask_workers_in_another_folder_import_a_relative_sweeps_controller(tmp_path, plant_fmu, monkeypatch, capsys):
    """A sweep named by a relative path whose base scenario's controller.python module lies
    beside it: fresh Dask workers whose working directory is elsewhere find it (the base's
    folder travels as an absolute path), and every case is ok (every case used to fail, reported
    as "lost" by the cluster)."""
    distributed = pytest.importorskip("distributed")
    study = tmp_path / "study"
    base = {**BASE, "t_end": 0.1, "controller": {"python": "pd_here:make_pd", "parameters": {"Kp": 12.0, "Kd": 2.5}}}
    path = write_sweep(study, {"plant.F_E": {"values": [0.0, 20.0]}}, base=base)
    (study / "pd_here.py").write_text(PD_MODULE, encoding="utf-8")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # the workers start here
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None) as cluster:
        monkeypatch.chdir(tmp_path)  # the command runs here, with a relative sweep path
        code = run_sweep(Path("study") / path.name, cluster.scheduler_address, None, plant_fmu, progress=False)
        captured = capsys.readouterr()
        assert code == 0, captured.err
        table = read_results(study / "out")
        assert list(table["status"]) == ["ok", "ok"], table["reason"].tolist()


def test_a_case_whose_controller_cannot_be_built_on_a_worker_fails_with_its_whole_reason(tmp_path, plant_fmu):
    """What a Dask task returns when a case's controller.python cannot be imported there: a
    failed row whose reason names the module and the fix, whole (it was counted as a case the
    cluster "lost", with advice to re-run, cut off mid-word)."""
    from toggle_cosim.experiments.sweep_exec import _is_loss
    from toggle_cosim.experiments.sweep_worker import run_cases
    from toggle_cosim.plant.contract import check_plant

    base = {**BASE, "t_end": 0.1, "controller": {"python": "pd_absent:make_pd", "parameters": {"Kp": 12.0, "Kd": 2.5}}}
    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0.0, 20.0]}}, base=base)
    sweep = load_sweep(path)  # the module is not beside the base scenario: not on this worker either
    sha = check_plant(plant_fmu).sha256
    results = run_cases([case.payload() for case in sweep.cases], str(plant_fmu), sha)
    assert [row["status"] for row, _ in results] == ["failed", "failed"]
    for row, trace in results:
        assert trace is None
        assert "key controller.python: cannot import 'pd_absent'" in row["reason"]
        reason = row["reason"]
        assert "or on sys.path (PYTHONPATH)" in reason and reason.count("(") == reason.count(")"), reason  # whole
    assert not _is_loss(RuntimeError("a task's own error")) and _is_loss(TimeoutError())


def test_unreachable_scheduler_is_bad_input(tmp_path, plant_fmu, capsys):
    dask = pytest.importorskip("dask")
    # imported before dask.config.set: leaving a set that created the "distributed" section
    # deletes the section, with the defaults distributed's import put in it meanwhile
    pytest.importorskip("distributed")
    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0]}})
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        assert run_sweep(path, "tcp://127.0.0.1:9", None, plant_fmu, progress=False) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: cannot connect to the Dask scheduler at tcp://127.0.0.1:9")
    assert not (tmp_path / "out").exists()  # bad input writes nothing


def test_module_docstring_example_is_a_valid_sweep(tmp_path):
    import toggle_cosim.experiments.sweep_spec as module

    example = textwrap.dedent(module.__doc__.split("\n\n")[1])
    document = yaml.safe_load(example)
    document["base"] = str(ROOT / "scenarios" / "fig4_nominal.yaml")
    document["output"] = str(tmp_path / "out")
    path = tmp_path / "doc.yaml"
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    sweep = load_sweep(path)
    assert len(sweep.cases) == 2 * 16 * 3 * 5 * 2


def test_a_worker_without_the_fmu_file_uses_the_bytes_sent_along(tmp_path, plant_fmu):
    from toggle_cosim.experiments import sweep_worker
    from toggle_cosim.plant.contract import check_plant

    sha = check_plant(plant_fmu).sha256
    data = plant_fmu.read_bytes()
    sweep_worker._plants.clear()
    assert sweep_worker.resolve_plant(str(plant_fmu), sha, data).path == plant_fmu
    sweep_worker._plants.clear()
    elsewhere = sweep_worker.resolve_plant(str(tmp_path / "missing.fmu"), sha, data).path
    assert elsewhere != plant_fmu and elsewhere.read_bytes() == data
    assert elsewhere.stat().st_mode & 0o077 == 0 and elsewhere.parent.stat().st_mode & 0o077 == 0  # private
    stale = tmp_path / "stale.fmu"
    stale.write_bytes(b"not this plant")
    sweep_worker._plants.clear()
    assert sweep_worker.resolve_plant(str(stale), sha, data).path.read_bytes() == data
    sweep_worker._plants.clear()
    with pytest.raises(FileNotFoundError, match="is not on this machine: .*stale.fmu has SHA-256"):
        sweep_worker.resolve_plant(str(stale), sha, None)
    with pytest.raises(ValueError, match="do not have the sweep's SHA-256"):
        sweep_worker.resolve_plant(str(stale), sha, b"other bytes")
    sweep_worker._plants.clear()


def test_keep_traces_stores_every_case_readable_by_id(tmp_path, plant_fmu):
    """--keep-traces: one compressed Parquet dataset of every case's whole trace; the trace of a
    case read back by its id is the one a plain check_and_simulate() of that case records, bit for bit."""
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import runs_from_document
    from toggle_cosim.experiments.sweep_store import read_trace
    from toggle_cosim.plant.contract import check_plant

    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0, 60]}, "plant.mu": {"values": [0.0, 0.2]}})
    assert run_sweep(path, None, 2, plant_fmu, progress=False, keep_traces=True) == 0
    sweep = load_sweep(path)
    parts = list((sweep.output / "traces").glob("*.parquet"))
    assert parts and all(pq.ParquetFile(p).metadata.row_group(0).column(1).compression == "ZSTD" for p in parts)
    whole = pd.read_parquet(sweep.output / "traces")
    assert set(whole["case_id"].astype(str)) == {c.case_id for c in sweep.cases}
    plant = check_plant(plant_fmu)
    for case in (sweep.cases[0], sweep.cases[-1]):
        (run,) = runs_from_document(case.document)
        expected = check_and_simulate(run, plant).trace
        stored = read_trace(sweep.output, case.case_id)
        assert list(stored.columns) == list(expected.names)
        assert np.array_equal(stored.to_numpy(), expected.data)
    assert json_of(sweep.output)["traces"] == "traces"


def test_keep_traces_on_a_finished_sweep_runs_the_cases_without_a_trace(tmp_path, plant_fmu, capsys):
    """A sweep finished without --keep-traces, then run with it: every finished case lacks its
    trace, so each runs again and its trace is stored (it used to skip them all, exit 0, no
    trace); a third run has every trace and runs nothing. read_trace of a folder without
    traces, or of an unknown case, is one line naming the folder and the fix."""
    from toggle_cosim.experiments.sweep import SweepError, read_trace

    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0, 60]}})
    assert run_sweep(path, None, 2, plant_fmu, progress=False) == 0
    sweep = load_sweep(path)
    with pytest.raises(SweepError) as missing:
        read_trace(sweep.output, sweep.cases[0].case_id)
    assert str(missing.value) == (
        f"{sweep.output}: no traces stored here; run the sweep again with --keep-traces (finished cases "
        "without a trace run again to store it)"
    )
    capsys.readouterr()
    assert run_sweep(path, None, 2, plant_fmu, progress=False, keep_traces=True) == 0
    captured = capsys.readouterr()
    assert "--keep-traces: 2 finished cases have no stored trace; they run again to store it" in captured.err
    assert "ran 2 cases" in captured.out
    for case in sweep.cases:
        stored = read_trace(sweep.output, case.case_id)
        assert len(stored) == 601 and stored["time"].iloc[-1] == pytest.approx(0.3)
    assert run_sweep(path, None, 2, plant_fmu, progress=False, keep_traces=True) == 0
    assert "ran 0 cases" in capsys.readouterr().out
    with pytest.raises(SweepError, match="no trace of case 'nope' in traces/"):
        read_trace(sweep.output, "nope")
    assert len(read_results(sweep.output)) == 2


def json_of(folder: Path) -> dict:
    import json

    return json.loads((folder / "sweep.json").read_text())


def test_keep_traces_over_the_output_limit_is_refused_before_any_work(tmp_path, plant_fmu, capsys, monkeypatch):
    path = write_sweep(tmp_path, {"plant.F_E": {"linspace": [0, 100, 50]}})
    # 50 cases x 601 samples x 35 columns x 8 bytes = 8.4 MB; each case alone is 0.17 MB
    monkeypatch.setenv("TOGGLE_COSIM_MAX_OUTPUT", "5e6")
    assert run_sweep(path, None, 1, plant_fmu, progress=False, keep_traces=True) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "--keep-traces would store 50 traces" in err[0]
    assert "over the 0.01 GB output limit" in err[0]
    assert not (tmp_path / "out").exists()


def test_a_part_with_another_schema_is_unreadable_and_its_cases_run_again(tmp_path, plant_fmu, capsys):
    """A batch file with other columns (an earlier sweep file, a foreign writer) does not crash
    the consolidation: it is reported, set aside, and its cases run again."""
    import pyarrow as pa

    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0, 50]}})
    sweep = load_sweep(path)
    parts = sweep.output / "parts"
    parts.mkdir(parents=True)
    foreign = pa.table({"case_id": [sweep.cases[0].case_id], "status": ["ok"], "final_error_m": ["oops"]})
    pq.write_table(foreign, parts / "batch-00000000000000000001-1-000001.parquet")
    assert run_sweep(path, None, 1, plant_fmu, progress=False) == 0
    captured = capsys.readouterr()
    assert "warning: unreadable result files, their cases run again: batch-" in captured.err
    assert "(columns of another sweep)" in captured.err and "ran 2 cases" in captured.out
    table = read_results(sweep.output)
    assert len(table) == 2 and (table["status"] == "ok").all()


def _http_server():
    import http.server

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    server.daemon_threads = True  # a handler waiting for a request line that never comes
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, server.server_address[1]


def test_a_scheduler_that_is_not_dask_is_one_line_within_the_timeout(tmp_path, plant_fmu, capsys):
    """An HTTP server, or a server that accepts and never answers: one line, exit 2, nothing
    written, within the connect timeout (plus a second)."""
    import socket

    dask = pytest.importorskip("dask")
    pytest.importorskip("distributed")  # imported here, not timed below (seconds on a loaded machine)
    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0]}})
    server, http_port = _http_server()
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(5)
    try:
        for port in (http_port, silent.getsockname()[1]):
            started = time.monotonic()
            with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
                assert run_sweep(path, f"tcp://127.0.0.1:{port}", None, plant_fmu, progress=False) == 2
            assert time.monotonic() - started < 8
            err = capsys.readouterr().err.strip().splitlines()
            assert err[-1].startswith(f"error: cannot connect to the Dask scheduler at tcp://127.0.0.1:{port}")
            assert not any("Traceback" in line for line in err)
    finally:
        server.shutdown()
        silent.close()
    assert not (tmp_path / "out").exists()


def _held_under(pid: int, marks: Path) -> bool:
    """True once a process below `pid` (its plant host) holds a case: it has written its pid
    to `marks` (the fault shim's TOGGLE_FAULT_MARK) and is still there."""
    from toggle_cosim import process_tree

    held = {int(line) for line in marks.read_text().split()} if marks.exists() else set()
    return bool(held & process_tree.descendants(pid))


def test_cases_a_dead_dask_worker_took_with_it_are_not_run_and_a_rerun_does_them(
    tmp_path, shim_fmu, capsys, monkeypatch
):
    """A worker killed mid-sweep with no retries allowed: its cases are not run (not failed),
    one line says so, exit 1; the same command again runs exactly those. Every case holds in
    fmi2DoStep from 0.1 s (the fault shim) until the test releases it: the victim is killed
    while it holds one of its cases, then the rest are released and finish on the other worker."""
    distributed = pytest.importorskip("distributed")
    import dask
    from fault_plants import fault_environment

    from toggle_cosim.plant.contract import check_plant

    marks, release = tmp_path / "held", tmp_path / "release"
    references = check_plant(shim_fmu).references
    for key, value in fault_environment("", 0.1, references, hold=release, mark=marks).items():
        monkeypatch.setenv(key, value)  # before the cluster starts: its workers and their hosts inherit it
    base = {**BASE, "t_end": 1.5}
    path = write_sweep(tmp_path, {"plant.F_E": {"linspace": [0, 150, 16]}}, base)
    config = {"distributed.scheduler.allowed-failures": 0, "distributed.comm.timeouts.connect": "10s"}
    with (
        dask.config.set(config),
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        distributed.Client(cluster) as client,
    ):
        victim = sorted(client.scheduler_info()["workers"])[0]
        pid = client.run(os.getpid, workers=[victim])[victim]
        seen = []

        def kill_when_holding() -> None:
            deadline = time.monotonic() + 60  # hang guard: the victim takes a case at once
            while time.monotonic() < deadline and not _held_under(pid, marks):
                time.sleep(0.01)
            seen.append(_held_under(pid, marks))
            gone = os.pidfd_open(pid)
            try:
                os.kill(pid, signal.SIGKILL)
                select.select([gone], [], [], 60)  # the victim has exited: its case can no longer finish
            finally:
                os.close(gone)
                release.touch()

        killer = threading.Thread(target=kill_when_holding)
        killer.start()
        try:
            code = run_sweep(path, cluster.scheduler_address, None, shim_fmu, progress=False)
        finally:
            release.touch()  # whatever happened: no case stays held
            killer.join()
        captured = capsys.readouterr()
        assert seen == [True], "the victim never held a case"
        table = read_results(tmp_path / "out")
        assert code == 1 and 0 < len(table) < 16, (code, len(table), captured.err)
        assert (table["status"] == "ok").all()  # lost cases are not failed rows
        lost = 16 - len(table)
        assert f"warning: the Dask cluster lost {lost} cases" in captured.err
        assert f"{lost} not run, of 16 cases" in captured.out and "Traceback" not in captured.err
        assert run_sweep(path, cluster.scheduler_address, None, shim_fmu, progress=False) == 0
        assert f"ran {lost} cases" in capsys.readouterr().out


def test_a_small_address_space_limit_is_one_line(tmp_path, plant_fmu):
    """Under `ulimit -v 400000` pandas, pyarrow and matplotlib cannot load (or pyarrow hangs):
    the sweep says so in one line, exit 2, before it writes anything."""
    import resource

    path = write_sweep(tmp_path, {"plant.F_E": {"values": [0]}})

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (400_000 * 1024, resource.RLIM_INFINITY))

    command = [sys.executable, "-m", "toggle_cosim.cli", "sweep", str(path), "--fmu", str(plant_fmu), "-q"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=60, preexec_fn=limit, check=False)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: the address-space limit (ulimit -v) is 390 MiB")
    assert not (tmp_path / "out").exists()


def test_a_case_whose_last_diagnostic_turns_nan_keeps_every_sample(tmp_path, plant_fmu):
    """Issue 37, item 1, in a sweep's plant host: the case's row counts every sample and its kept
    trace holds them all, the NaN of its controller's last diagnostic (named e, as kept traces
    need the built-in law's S, phase, e) included."""
    from nan_values import FINITE, SAMPLES, nan_controller_scenario

    from toggle_cosim.experiments.sweep import read_trace

    base = nan_controller_scenario(tmp_path, 2, ("S", "phase", "e"))
    sweep = {"base": base.name, "axes": {"plant.F_E": {"values": [0.0]}}, "output": "out"}
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump(sweep), encoding="utf-8")
    assert run_sweep(tmp_path / "sweep.yaml", None, 1, plant_fmu, progress=False, keep_traces=True) == 0
    table = read_results(tmp_path / "out")
    assert len(table) == 1 and table["samples"].iloc[0] == SAMPLES
    trace = read_trace(tmp_path / "out", table["case_id"].iloc[0])
    assert len(trace) == SAMPLES
    e = trace["e"].to_numpy()
    assert np.all(np.isfinite(e[:FINITE])) and np.all(np.isnan(e[FINITE:]))
