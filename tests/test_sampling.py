"""The funnel verdict does not depend on how the result and the reference were sampled.

Physics checked: the same co-simulation of fig4_nominal/friction, written at every controller
sample (T_s = 0.5 ms) or at every 3rd, 7th or 10th, must pass against itself in both directions,
across its discontinuities: the reaching -> sliding switch of the two-phase VSC (phase 0 -> 1 at
t = 0.0375 s, where i_q* jumps by 1 A), the sign changes of the switching command i_q* and of the
friction-carrying constraint force lambda1 and the load force F_C. A real change of the plant
(Coulomb coefficient mu 0.2 -> 0.25) or of the controller (gain C +5 %) must fail at every ratio.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim.analysis.compare import DEFAULT_TOLERANCE, Tolerance, compare_traces
from toggle_cosim.analysis.csv_traces import CompareInputError
from toggle_cosim.analysis.sampling import REFERENCE_GRID, RESULT_GRID, SpanMismatch, check_points
from toggle_cosim.cosim.master import check_and_simulate
from toggle_cosim.experiments.references import tolerances_for
from toggle_cosim.files.traces import Trace
from toggle_cosim.plant.contract import check_plant

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("sampling_table", ROOT / "benchmarks" / "sampling_table.py")
sampling_table = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(sampling_table)
decimated = sampling_table.decimated
RATIOS = (3, 7, 10)


# ----------------------------------------------------------------------------- synthetic signals

T = np.linspace(0.0, 1.0, 1001)
# a narrow peak (3 ms wide) between the samples of a 10 ms reference grid, and a step at t = 0.6045
PEAK = np.exp(-(((T - 0.255) / 0.0015) ** 2))
STEP = (T >= 0.6045).astype(float)


def test_a_peak_between_the_reference_samples_is_not_held_against_the_denser_result():
    full = Trace(("time", "p", "s"), np.column_stack([T, PEAK, STEP]))
    sparse = decimated(full, 10)  # samples at 0.25 and 0.26: the peak (1.0 at 0.255) is not in the reference
    comparison = compare_traces(full, sparse, {}, DEFAULT_TOLERANCE)
    assert comparison.passed and comparison.grid == REFERENCE_GRID
    # the other way round the funnel of the full trace holds every sample of the sparse one
    back = compare_traces(sparse, full, {}, DEFAULT_TOLERANCE)
    assert back.passed and back.grid == RESULT_GRID


def test_a_change_the_reference_can_show_still_fails_on_its_grid():
    full = Trace(("time", "p", "s"), np.column_stack([T, PEAK, STEP]))
    sparse = decimated(full, 10)
    moved = Trace(full.names, np.column_stack([T, PEAK, (T >= 0.62).astype(float)]))  # step 15 ms late
    comparison = compare_traces(moved, sparse, {}, DEFAULT_TOLERANCE)
    assert comparison.failed == ("s",)
    # at t = 0.61 the reference is 1 and the result still 0; the funnel's lower edge lags the
    # reference by the 1 ms half-width there (0.9 of the way up its 10 ms segment), less 2e-3
    assert comparison["s"].max_error == pytest.approx(0.9 - 2e-3)
    assert comparison["s"].time_of_max_error == pytest.approx(0.61)


def test_between_the_samples_of_both_traces_a_jump_may_lie_anywhere():
    """Step at t = 0.6045: a 7 ms result grid (offset 3 ms) and a 10 ms reference grid both
    straddle it; linear interpolation of either would put it at a different time, but the
    comparison takes each trace's interval between neighbouring samples there."""
    full = Trace(("time", "s"), np.column_stack([T, STEP]))
    coarse, other = decimated(full, 10), decimated(full, 7, 3)
    assert compare_traces(other, coarse, {}, DEFAULT_TOLERANCE).passed
    assert compare_traces(coarse, other, {}, DEFAULT_TOLERANCE).passed
    # a step 30 ms late is more than the samples can hide
    late = Trace(("time", "s"), np.column_stack([T, (T >= 0.6345).astype(float)]))
    assert not compare_traces(decimated(late, 7, 3), coarse, {}, DEFAULT_TOLERANCE).passed
    assert not compare_traces(decimated(late, 10), other, {}, DEFAULT_TOLERANCE).passed


def test_check_points_follow_the_sparser_trace_and_are_exact_where_grids_coincide():
    y = np.column_stack([np.sin(7 * T)])
    points = check_points(T, y, T[::10], 1e-3)
    assert points.grid == REFERENCE_GRID
    np.testing.assert_array_equal(points.time, T[::10])
    np.testing.assert_array_equal(points.values[:, 0], y[::10, 0])
    own = check_points(T[::10], y[::10], T, 1e-3)
    assert own.grid == RESULT_GRID
    np.testing.assert_array_equal(own.values[:, 0], y[::10, 0])


@pytest.mark.parametrize("start, stop", [(0.0, 0.9995), (0.0005, 1.0), (0.0, 1.0008), (-0.0009, 1.0)])
def test_a_time_span_within_the_time_tolerance_is_accepted(start, stop):
    grid = np.arange(start, stop + 1e-12, 5e-4)
    result = Trace(("time", "a"), np.column_stack([grid, np.sin(2 * np.pi * grid)]))
    reference = Trace(("time", "a"), np.column_stack([T, np.sin(2 * np.pi * T)]))
    comparison = compare_traces(result, reference, {}, Tolerance(atol=1e-9, rtol=2e-3, ttol=1e-3))
    assert comparison.passed


@pytest.mark.parametrize("start, stop", [(0.0, 0.998), (0.0015, 1.0), (0.0, 1.002)])
def test_a_time_span_beyond_the_time_tolerance_is_bad_input(start, stop):
    grid = np.linspace(start, stop, 800)
    result = Trace(("time", "a"), np.column_stack([grid, grid]))
    reference = Trace(("time", "a"), np.column_stack([T, T]))
    with pytest.raises(CompareInputError, match="more than the time tolerance"):
        compare_traces(result, reference, {}, Tolerance(atol=1e-9, rtol=2e-3, ttol=1e-3))
    with pytest.raises(SpanMismatch):
        check_points(grid, grid, T, 1e-3)


# ----------------------------------------------------------------------------- the co-simulation


@pytest.fixture(scope="module")
def runs(plant_fmu: Path) -> dict[str, Trace]:
    plant = check_plant(plant_fmu)
    run = sampling_table.nominal_run()
    traces = {"unchanged": check_and_simulate(run, plant).trace}
    for name, changed in sampling_table.perturbations(run).items():
        traces[name] = check_and_simulate(changed, plant).trace
    return traces


def _compare(result: Trace, reference: Trace):
    default, per_variable = tolerances_for(ROOT / "scenarios" / "references", "fig4_nominal")
    return compare_traces(result, reference, per_variable, default)


def test_the_nominal_run_crosses_the_events_the_ratios_must_survive(runs):
    trace = runs["unchanged"]
    phase = trace.column("phase")
    switch = trace.time[np.flatnonzero(np.diff(phase))[0] + 1]
    assert switch == pytest.approx(0.0375)  # reaching -> sliding
    for name in ("iq_ref", "lambda1", "F_C"):
        assert np.count_nonzero(np.diff(np.sign(trace.column(name)[1:]))) >= 1, name
    # the switch falls between the samples of the x7 and x10 grids
    assert 75 % 7 and 75 % 10


@pytest.mark.slow
@pytest.mark.parametrize("ratio", RATIOS)
@pytest.mark.parametrize("direction", ["result decimated", "reference decimated"])
def test_the_unchanged_run_passes_against_itself_at_every_ratio(runs, ratio, direction):
    full = runs["unchanged"]
    if direction == "result decimated":
        comparison = _compare(decimated(full, ratio), full)
    else:
        comparison = _compare(full, decimated(full, ratio))
    assert comparison.passed, comparison.failed


@pytest.mark.slow
@pytest.mark.parametrize("ratio, offset", [(7, 3), (3, 1)])
def test_grids_that_do_not_coincide_pass_too_and_still_catch_a_change(runs, ratio, offset):
    """A 3.5 ms grid against a 5 ms one: the jump of i_q* at the switch falls between samples of
    both, and each trace counts with the values between its neighbouring samples there."""
    full, changed = runs["unchanged"], runs["mu 0.2 -> 0.25"]
    assert _compare(decimated(full, ratio, offset), decimated(full, 10)).passed
    assert _compare(decimated(full, 10), decimated(full, ratio, offset)).passed
    assert "E_fric" in _compare(decimated(changed, ratio, offset), decimated(full, 10)).failed
    assert "E_fric" in _compare(decimated(changed, 10), decimated(full, ratio, offset)).failed


@pytest.mark.slow
@pytest.mark.parametrize("ratio", (1, *RATIOS))
@pytest.mark.parametrize("direction", ["result decimated", "reference decimated"])
@pytest.mark.parametrize("change", ["mu 0.2 -> 0.25", "gain C +5 %"])
def test_a_real_change_fails_at_every_ratio(runs, ratio, direction, change):
    full, changed = runs["unchanged"], runs[change]
    if direction == "result decimated":
        comparison = _compare(decimated(changed, ratio), full)
    else:
        comparison = _compare(changed, decimated(full, ratio))
    assert not comparison.passed
    failed = set(comparison.failed)
    if change.startswith("mu"):
        assert {"Ff12", "E_fric"} <= failed  # friction forces and energy scale with mu
    else:
        assert {"iq_ref", "S"} <= failed  # a steeper sliding line changes the command


@pytest.mark.slow
def test_the_readme_compare_command_passes_on_a_fresh_run_and_fails_a_changed_one(runs, tmp_path, capsys):
    """`toggle-cosim compare out/fig4_nominal/friction/trace.csv scenarios/references/fig4_nominal/
    friction_ref.csv`: the full-resolution run against the stored reference (every 10th sample),
    with the shipped tolerances.yaml found beside the reference."""
    from toggle_cosim.analysis.compare_command import run_compare
    from toggle_cosim.files.traces import write_csv

    reference = ROOT / "scenarios" / "references" / "fig4_nominal" / "friction_ref.csv"
    write_csv(tmp_path / "fresh" / "trace.csv", runs["unchanged"])
    assert run_compare(tmp_path / "fresh" / "trace.csv", reference) == 0
    out = capsys.readouterr().out
    assert "34 variables: 34 passed, 0 failed" in out and "checked at the reference samples" in out
    write_csv(tmp_path / "changed" / "trace.csv", runs["mu 0.2 -> 0.25"])
    assert run_compare(tmp_path / "changed" / "trace.csv", reference) == 1
