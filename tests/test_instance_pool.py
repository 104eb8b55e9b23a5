"""A system's FMU components kept loaded from run to run (`cosim.execution.instance_pool`): a sweep's or a
tuning's host takes each component's instance from its pool and gives it back reset after a
complete case, freed after a failed one, so a case never sees what another left.

The press example (plant, sensor, die, controller) runs here with the fault shim as its plant:
a case whose die pushes hard enough (F_E >= 100 N) makes the plant's doStep answer fmi2Error, a
failed case; the others step as the plant does.
"""

from __future__ import annotations

import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from fault_plants import fault_environment

from toggle_cosim.cosim import master
from toggle_cosim.cosim.execution.instance_pool import InstancePool
from toggle_cosim.experiments.scenario import runs_from_document
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
PRESS = ROOT / "examples" / "press_system" / "press.yaml"
# the die's (x_c in m, k_c in N/m): a clean case's pushes up to about 18 N, a hard case's 200 N
CLEAN, HARD = (0.28, 1.0e3), (0.25, 1.0e4)
FAULT_FORCE = 100.0  # N: the shim's doStep answers fmi2Error once F_E reaches it
COMPONENTS = 3  # FMU components of the press (plant, sensor, die); its controller runs natively


def press_document(plant: Path, parts: dict[str, Path], die: tuple[float, float]) -> dict:
    """examples/press_system/press.yaml's paper variant, 0.3 s long, on `plant` and the built parts."""
    document = yaml.safe_load(PRESS.read_text(encoding="utf-8"))
    document["fmu"] = str(plant)
    document["t_end"] = 0.3
    document["components"]["sensor"]["fmu"] = str(parts["PositionSensor"])
    document["components"]["die"]["fmu"] = str(parts["DieLoad"])
    document["components"]["die"]["parameters"] = dict(zip(("x_c", "k_c"), die, strict=True))
    document["variants"] = {"paper": document["variants"]["paper"]}
    return document


@pytest.fixture
def armed_shim(shim_fmu: Path, monkeypatch: pytest.MonkeyPatch):  # noqa: ANN201 - the checked shim plant
    """The shim plant, its doStep failing (fmi2Error) from t = 0 wherever F_E >= FAULT_FORCE."""
    plant = check_plant(shim_fmu)
    for key, value in fault_environment("error", 0.0, plant.references, FAULT_FORCE).items():
        if key.startswith("TOGGLE_FAULT_"):
            monkeypatch.setenv(key, value)
    return plant


@pytest.fixture(scope="module")
def press_parts_3(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The press example's sensor and die as FMI 3.0 Co-Simulation FMUs (fmi3Reset between runs)."""
    from toggle_cosim.fmu_export import build_fmu

    folder = tmp_path_factory.mktemp("press-parts-3")
    source = PRESS.parent
    return {
        name: build_fmu(source / f"{name}.mo", name, folder / f"{name}.fmu", "3.0", "cs").fmu.path
        for name in ("PositionSensor", "DieLoad")
    }


@pytest.mark.parametrize("version", ["2.0", pytest.param("3.0", marks=pytest.mark.slow)])  # FMI 3.0: the full suite
def test_a_press_case_gives_the_same_bits_alone_first_after_a_complete_and_after_a_failed_case(
    armed_shim, shim_fmu: Path, version: str, request: pytest.FixtureRequest
) -> None:
    """The same press case, every column bit for bit: alone (no pool), first in a pool (its
    components loaded), after a complete case (their instances reset, not loaded again) and after
    a failed case (the plant failing mid-run: every instance freed, made anew from the loaded
    binaries); with the sensor and the die as FMI 2.0 and as FMI 3.0 FMUs."""
    press_parts = request.getfixturevalue("press_parts" if version == "2.0" else "press_parts_3")
    (case,) = runs_from_document(press_document(shim_fmu, press_parts, CLEAN), PRESS)
    (hard,) = runs_from_document(press_document(shim_fmu, press_parts, HARD), PRESS)
    alone = master.check_and_simulate(case, armed_shim)
    assert alone.complete and alone.trace.data.shape == (case.steps + 1, len(alone.trace.names))
    pool = InstancePool()
    try:
        first = master.check_and_simulate(case, armed_shim, pool=pool)
        assert (pool.counts.loaded, pool.counts.reset, pool.counts.renewed) == (COMPONENTS, 0, 0)
        after_complete = master.check_and_simulate(case, armed_shim, pool=pool)
        assert (pool.counts.loaded, pool.counts.reset, pool.counts.renewed) == (COMPONENTS, COMPONENTS, 0)
        failed = master.check_and_simulate(hard, armed_shim, pool=pool)
        assert not failed.complete and "fmi2DoStep" in failed.reason
        after_failed = master.check_and_simulate(case, armed_shim, pool=pool)
        assert pool.counts.loaded == COMPONENTS and pool.counts.renewed == COMPONENTS
        assert not pool.fatal
    finally:
        pool.close()
    assert not pool.kept
    for outcome in (first, after_complete, after_failed):
        assert outcome.complete
        assert outcome.trace.names == alone.trace.names
        assert outcome.trace.data.tobytes() == alone.trace.data.tobytes()


def _payload(document: dict, index: int) -> dict:
    return {
        "index": index,
        "case_id": f"case{index}",
        "variant": "paper",
        "document": copy.deepcopy(document),
        "parameters": {"t_end": document["t_end"], "T_s": document["T_s"]},
        "source": str(PRESS),
    }


def test_a_sweep_host_keeps_a_systems_components_loaded_and_a_failed_case_leaves_the_next_clean(
    armed_shim, shim_fmu: Path, press_parts: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sweep's host (the server a plant host runs, called here in this process) loads the press
    system's FMUs at its first case and keeps them: the next cases reset them; a case whose plant
    fails frees them, and the case after it gives the rows and the trace of the case run first."""
    from toggle_cosim.experiments.sweep_worker import CaseServer, case_columns

    monkeypatch.setattr(sys, "stdout", sys.stdout)  # the server's log tee is undone after the test
    clean, hard = (press_document(shim_fmu, press_parts, die) for die in (CLEAN, HARD))
    server = CaseServer(armed_shim, armed_shim.sha256)
    rows = 601
    columns = len(case_columns(_payload(clean, 0), armed_shim))
    buffer = np.full(rows * columns, np.nan)
    count = np.zeros(1, dtype=np.int64)
    answers = []
    try:
        for index, document in enumerate((clean, clean, hard, clean)):
            row = server(_payload(document, index), buffer, count)
            answers.append((row, buffer[: rows * columns].copy()))
    finally:
        server.pool.close()
    (first, trace), (second, again), (failed, _), (after, last) = answers
    assert [row["status"] for row, _ in answers] == ["ok", "ok", "failed", "ok"], [r["reason"] for r, _ in answers]
    assert server.pool.counts.loaded == COMPONENTS  # loaded once, at the first case
    assert (server.pool.counts.reset, server.pool.counts.renewed) == (2 * COMPONENTS, COMPONENTS)
    assert not server.retired and "fmi2DoStep" in failed["reason"]
    metrics = [key for key in first if key.endswith(("_m", "_s", "_J", "_A")) and key != "wall_s"]
    assert metrics and all(first[key] == row[key] for row in (second, after) for key in metrics)
    assert again.tobytes() == trace.tobytes() and last.tobytes() == trace.tobytes()


def test_a_component_that_answers_fatal_to_reset_is_not_called_again_and_retires_its_host(
    shim_fmu: Path, press_parts: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """FMI allows no call to an FMU after Fatal: a plant whose fmi2Reset answers it (after a
    complete case) is dropped by the pool, never freed or called (the shim aborts the process on
    any later call), and the host retires so that the next case gets a new one."""
    from toggle_cosim.experiments.sweep_worker import RETIRED_KEY, CaseServer, case_columns

    plant = check_plant(shim_fmu)
    for key, value in fault_environment("resetfatal", 1e9, plant.references).items():
        if key.startswith("TOGGLE_FAULT_"):
            monkeypatch.setenv(key, value)
    monkeypatch.setattr(sys, "stdout", sys.stdout)
    document = press_document(shim_fmu, press_parts, CLEAN)
    server = CaseServer(plant, plant.sha256)
    columns = len(case_columns(_payload(document, 0), plant))
    buffer = np.full(601 * columns, np.nan)
    try:
        row = server(_payload(document, 0), buffer, np.zeros(1, dtype=np.int64))
    finally:
        server.pool.close()  # frees the sensor and the die; the plant is no longer in the pool
    assert row["status"] == "ok" and row.get(RETIRED_KEY) is True and server.retired
    assert server.pool.fatal and all(key[0] != plant.sha256 for key in server.pool.kept)


def test_a_pool_in_a_forked_child_does_not_use_its_parents_instances(tmp_path: Path) -> None:
    """A pool copied into a forked child (a plant host made after its parent ran cases) starts
    empty there: the parent's instances are neither used nor freed by the child."""
    import os

    from toggle_cosim.cosim.execution.instance_pool import Kept

    pool = InstancePool()
    pool.kept[("sha", "plant")] = Kept(object(), tmp_path, True)
    pool = dataclasses.replace(pool, pid=os.getpid() + 1)  # as a child sees its parent's pool
    assert pool.take("sha", "plant") is None and not pool.kept and tmp_path.is_dir()


def test_a_sweep_over_a_components_parameter_finds_its_columns_once(
    plant_fmu: Path, press_parts: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A system case's trace columns depend on its FMUs, connections and record list, not on its
    components' values: the cases of a sweep over the die's k_c share one probe of the columns
    (a supervised child per probe), the case with another sensor FMU gets its own."""
    from toggle_cosim.cosim.isolation import supervision
    from toggle_cosim.experiments import sweep_worker

    probed = []
    monkeypatch.setattr(sweep_worker, "_columns", {})
    monkeypatch.setattr(
        supervision, "probe_columns", lambda run, plant, limit, checked=None: probed.append(run) or ("time",)
    )
    plant = check_plant(plant_fmu)
    documents = [press_document(plant_fmu, press_parts, (0.28, k_c)) for k_c in (1e3, 2e3, 4e3)]
    other = copy.deepcopy(documents[0])
    other["components"]["sensor"]["fmu"] = str(press_parts["DieLoad"])
    for index, document in enumerate(documents):
        assert sweep_worker.case_columns(_payload(document, index), plant) == ("time",)
    assert len(probed) == 1
    sweep_worker.case_columns(_payload(other, 3), plant)
    assert len(probed) == 2


def test_a_press_case_whose_plant_crashes_its_host_leaves_the_next_case_clean(
    shim_fmu: Path, press_parts: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """In a sweep's plant hosts (forked children): a press case whose plant segfaults ends its
    host, a failed row naming the plant; the next case runs in a new host and gives the trace
    of the same case run before, in the first host, after a complete case."""
    from toggle_cosim.cosim.isolation.plant_host import wait_for_hosts
    from toggle_cosim.experiments.sweep_worker import CaseRunner

    plant = check_plant(shim_fmu)
    for key, value in fault_environment("segfault", 0.0, plant.references, FAULT_FORCE).items():
        if key.startswith("TOGGLE_FAULT_"):
            monkeypatch.setenv(key, value)
    clean, hard = (press_document(shim_fmu, press_parts, die) for die in (CLEAN, HARD))
    runner = CaseRunner(plant, plant.sha256, rows=601, keep_traces=True)
    found = []
    try:
        for index, document in enumerate((clean, clean, hard, clean)):
            runner.submit(_payload(document, index))
            while runner.busy:
                for _, answer in wait_for_hosts([runner.host]):
                    found.append(runner.service(answer))
    finally:
        runner.close()
    assert [row["status"] for row, _ in found] == ["ok", "ok", "failed", "ok"]
    assert runner.hosts_started == 2 and "'plant'" in found[2][0]["reason"]
    (_, first), (_, second), _, (_, last) = found
    assert first is not None and first.shape[0] == 601
    assert second.tobytes() == first.tobytes() and last.tobytes() == first.tobytes()
