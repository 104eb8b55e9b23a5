"""The shell's integrator statistics as FMU variables: solver.steps, solver.rejectedSteps and
solver.events, local discrete integers (Integer in FMI 2.0, Int64 in FMI 3.0), cumulative
since instantiation. Reading them must not change the trace."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.fmi3 import FMU3Slave

ROOT = Path(__file__).resolve().parent.parent
NAMES = ("solver.steps", "solver.rejectedSteps", "solver.events")
DT, STEPS = 5e-4, 400


def _run(fmu, read_statistics: bool, version: str = "2.0"):
    """1 A for 0.2 s with friction; x_B and v_B after every step, and the statistics."""
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    types = {v.name: v.type for v in md.modelVariables}
    unzipped = extract(str(fmu))
    cls = FMU2Slave if version == "2.0" else FMU3Slave
    slave = cls(
        guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="stats"
    )
    slave.instantiate()
    if version == "2.0":
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
    else:
        slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    get_real = slave.getReal if version == "2.0" else slave.getFloat64
    set_real = slave.setReal if version == "2.0" else slave.setFloat64
    get_int = slave.getInteger if version == "2.0" else slave.getInt64
    stats_vr = [vr[name] for name in NAMES]
    trace, statistics = [], [get_int(stats_vr)]
    set_real([vr["iq_ref"]], [1.0])
    for k in range(STEPS):
        slave.doStep(k * DT, DT)
        trace.append(get_real([vr["x_B"], vr["v_B"]]))
        if read_statistics:
            statistics.append(get_int(stats_vr))
    statistics.append(get_int(stats_vr))
    slave.terminate()
    slave.freeInstance()
    slave.freeLibrary()
    shutil.rmtree(unzipped, ignore_errors=True)
    return np.array(trace), np.array(statistics), [types[name] for name in NAMES]


def test_statistics_are_cumulative_integers_and_do_not_change_the_trace(plant_fmu):
    quiet, ends, _ = _run(plant_fmu, read_statistics=False)
    watched, statistics, types = _run(plant_fmu, read_statistics=True)
    assert types == ["Integer"] * 3
    np.testing.assert_array_equal(watched, quiet)  # bit for bit
    np.testing.assert_array_equal(statistics[-1], ends[-1])
    assert list(statistics[0]) == [0, 0, 0]  # nothing integrated yet after initialisation
    assert np.all(np.diff(statistics, axis=0) >= 0)  # cumulative
    steps, rejected, events = statistics[-1]
    assert steps >= STEPS  # at least one accepted internal step per communication step
    assert 0 <= rejected < steps
    assert events > 0  # the friction sign events of the stroke


@pytest.mark.slow
def test_fmi3_statistics_are_int64_and_count_as_fmi2(plant_fmu, plant3_fmu):
    """FMI 3.0 serves them through fmi3GetInt64; the solver core is the one FMI 2.0 uses, so
    the same run counts the same steps, rejections and events."""
    trace3, statistics3, types = _run(plant3_fmu, read_statistics=True, version="3.0")
    trace2, statistics2, _ = _run(plant_fmu, read_statistics=True)
    assert types == ["Int64"] * 3
    np.testing.assert_array_equal(statistics3, statistics2)
    np.testing.assert_allclose(trace3, trace2, rtol=1e-12, atol=0)


@pytest.mark.parametrize("name", NAMES)
def test_statistics_are_declared_local_discrete(plant_fmu, name):
    md = read_model_description(str(plant_fmu))
    (variable,) = [v for v in md.modelVariables if v.name == name]
    assert (variable.causality, variable.variability) == ("local", "discrete")
