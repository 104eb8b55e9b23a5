"""Trace comparison with the funnel: pass/fail sets, error magnitudes, bad inputs, report, .opt files.

Every trace here spans t = 0..1 s in 1001 samples (1 ms apart), so a relative time tolerance
ttol is a half-width of ttol seconds and the expected errors follow from the funnel geometry.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from toggle_cosim.analysis.compare import (
    DEFAULT_TOLERANCE,
    Tolerance,
    compare_traces,
    format_table,
    load_tolerances,
    write_report,
)
from toggle_cosim.analysis.compare_command import run_compare
from toggle_cosim.analysis.csv_traces import CompareInputError, read_trace
from toggle_cosim.analysis.reference_files import read_options, read_reference, write_reference
from toggle_cosim.files.traces import Trace, read_csv, write_csv

T = np.linspace(0.0, 1.0, 1001)
SINE = np.sin(2 * np.pi * T)  # range 2, peak at t = 0.25
SMOOTH_STEP = 0.5 * (1 + np.tanh((T - 0.5) / 0.02))  # flat at both ends, steepest slope 25 /s at t = 0.5
RAMP = 2.0 * T
STEP = (T >= 0.5 - 1e-12).astype(float)  # 0 up to 0.499, 1 from 0.500


def trace(**columns: np.ndarray) -> Trace:
    return Trace(("time", *columns), np.column_stack([T, *columns.values()]))


def reference() -> Trace:
    return trace(a=SINE, b=SMOOTH_STEP, c=RAMP)


def by_name(comparison) -> dict[str, tuple[bool, float, float | None]]:
    return {v.name: (v.passed, v.max_error, v.time_of_max_error) for v in comparison.variables}


# ----------------------------------------------------------------------------- pass / fail


def test_identical_traces_pass_with_zero_error():
    comparison = compare_traces(reference(), reference(), {}, DEFAULT_TOLERANCE)
    assert comparison.passed
    assert comparison.failed == ()
    assert by_name(comparison) == {"a": (True, 0.0, None), "b": (True, 0.0, None), "c": (True, 0.0, None)}


def test_value_shift_beyond_atol_fails_that_variable_only():
    shifted = trace(a=SINE + 0.01, b=SMOOTH_STEP, c=RAMP)
    tube = Tolerance(atol=1e-3, rtol=0.0, ttol=1e-3)  # half-height 1e-3
    comparison = compare_traces(shifted, reference(), {"a": tube}, DEFAULT_TOLERANCE)
    assert not comparison.passed
    assert comparison.failed == ("a",)
    a = comparison["a"]
    assert a.half_height == pytest.approx(1e-3)
    # At the sine's peak the funnel is only the value tube: error = 0.01 - 1e-3.
    assert a.max_error == pytest.approx(0.01 - 1e-3, abs=1e-12)
    assert a.time_of_max_error == pytest.approx(0.25)
    assert {n: v[0] for n, v in by_name(comparison).items()} == {"a": False, "b": True, "c": True}
    assert comparison["b"].max_error == 0.0 and comparison["c"].max_error == 0.0


def test_value_tube_is_rtol_times_the_reference_range_when_larger_than_atol():
    shifted = trace(a=SINE + 0.01, b=SMOOTH_STEP, c=RAMP)
    comparison = compare_traces(shifted, reference(), {}, DEFAULT_TOLERANCE)  # rtol 2e-3 of range 2
    assert comparison["a"].half_height == pytest.approx(4e-3)
    assert comparison["a"].max_error == pytest.approx(0.01 - 4e-3, abs=1e-12)
    assert comparison.failed == ("a",)
    # A shift inside the tube passes.
    inside = compare_traces(trace(a=SINE + 3.9e-3, b=SMOOTH_STEP, c=RAMP), reference(), {}, DEFAULT_TOLERANCE)
    assert inside.passed and inside["a"].max_error == 0.0


@pytest.mark.parametrize("delay, passed", [(0.0005, True), (0.001, True), (0.003, False)])
def test_pure_time_shift_within_ttol_passes_beyond_fails(delay, passed):
    delayed = trace(b=0.5 * (1 + np.tanh((T - delay - 0.5) / 0.02)))
    tolerance = Tolerance(atol=1e-9, rtol=2e-3, ttol=1e-3)  # half-width 1 ms, half-height 2e-3
    comparison = compare_traces(delayed, reference(), {}, tolerance, variables=["b"])
    b = comparison["b"]
    assert b.half_width == pytest.approx(1e-3)
    assert b.passed is passed and comparison.passed is passed
    if passed:
        assert b.max_error == 0.0 and b.time_of_max_error is None
    else:
        # The funnel's lower edge lags the reference by 1 ms, the result by 3 ms: the largest gap is
        # f(s) - f(s - 2 ms) at the steepest slope = tanh(0.001/0.02) * 2 / 2, less the value tube.
        assert b.max_error == pytest.approx(math.tanh(0.05) - 2e-3, abs=1e-9)
        assert b.time_of_max_error == pytest.approx(0.502)


# ----------------------------------------------------------------------------- spikes in a step signal
# Step reference: 0 up to t = 0.499, 1 from t = 0.500. Half-width 1.5 ms, half-height 2e-3.
STEP_TOL = Tolerance(atol=1e-9, rtol=2e-3, ttol=1.5e-3)


def test_result_switching_one_sample_early_is_inside_the_time_tube():
    early = STEP.copy()
    early[499] = 1.0  # t = 0.499, 1 ms early < 1.5 ms
    comparison = compare_traces(trace(s=early), trace(s=STEP), {}, STEP_TOL)
    assert comparison.passed and comparison["s"].max_error == 0.0


def test_narrow_spike_in_the_result_fails_even_though_it_is_shorter_than_the_time_tolerance():
    # The funnel is built from the reference: on a flat stretch it is only ±2e-3 high, whatever the width.
    spiked = STEP.copy()
    spiked[300] = 0.5  # one sample at t = 0.300
    comparison = compare_traces(trace(s=spiked), trace(s=STEP), {}, STEP_TOL)
    assert comparison.failed == ("s",)
    assert comparison["s"].max_error == pytest.approx(0.5 - 2e-3, abs=1e-12)
    assert comparison["s"].time_of_max_error == pytest.approx(0.300)


def test_overshoot_at_the_step_fails_by_its_excess_over_the_upper_level():
    overshoot = STEP.copy()
    overshoot[499] = 1.5
    comparison = compare_traces(trace(s=overshoot), trace(s=STEP), {}, STEP_TOL)
    assert comparison["s"].max_error == pytest.approx(1.5 - (1 + 2e-3), abs=1e-12)
    assert comparison["s"].time_of_max_error == pytest.approx(0.499)


@pytest.mark.parametrize("samples, expected_error", [(1, 0.0), (2, 0.0), (3, 0.5 - 2e-3), (5, 1 - 2e-3)])
def test_reference_spike_narrower_than_the_time_tube_is_not_required_of_the_result(samples, expected_error):
    # The lower edge of the funnel under a pulse of the reference rises along (t_i + w) on the left
    # and falls along (t_j - w) on the right; when the pulse is narrower than the tube the two
    # edges cross below the pulse. Plateau of 2 samples (1 ms): they cross at -h, the pulse is
    # swallowed; 3 samples (2 ms): they cross half way up at t = 0.301; 5 samples: full height.
    pulse = STEP.copy()
    pulse[300 : 300 + samples] = 1.0
    comparison = compare_traces(trace(s=STEP), trace(s=pulse), {}, STEP_TOL)
    s = comparison["s"]
    assert s.max_error == pytest.approx(expected_error, abs=1e-9)
    assert s.passed is (expected_error == 0.0)
    if expected_error:
        assert s.time_of_max_error == pytest.approx(0.301 if samples == 3 else 0.302)


def test_result_on_another_time_grid_is_compared_at_its_own_samples():
    grid = np.linspace(0.0, 1.0, 777)
    other = Trace(("time", "a"), np.column_stack([grid, np.sin(2 * np.pi * grid)]))
    comparison = compare_traces(other, reference(), {}, DEFAULT_TOLERANCE, variables=["a"])
    assert comparison.passed
    assert comparison["a"].envelope.time.shape == (777,)


# ----------------------------------------------------------------------------- table


def test_table_has_one_line_per_variable():
    shifted = trace(a=SINE + 0.01, b=SMOOTH_STEP, c=RAMP)
    text = format_table(compare_traces(shifted, reference(), {}, DEFAULT_TOLERANCE))
    lines = text.splitlines()
    assert lines[0].split() == ["variable", "max", "error", "at", "t", "[s]", "result"]
    assert lines[1].split() == ["a", "6.000e-03", "0.25", "FAIL"]
    assert lines[2].split() == ["b", "0.000e+00", "-", "PASS"]
    assert lines[3].split() == ["c", "0.000e+00", "-", "PASS"]
    assert lines[4] == "3 variables: 2 passed, 1 failed"


# ----------------------------------------------------------------------------- run_compare and bad input


def write(path: Path, text: str | bytes) -> Path:
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text, encoding="utf-8")
    return path


GOOD = '"time","a"\n0,0\n0.5,1\n1,0\n'


@pytest.fixture
def files(tmp_path: Path):
    ref = write(tmp_path / "ref.csv", GOOD)
    res = write(tmp_path / "res.csv", GOOD)
    return tmp_path, res, ref


def test_run_compare_exit_codes_and_table(files, capsys):
    folder, res, ref = files
    assert run_compare(res, ref) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert out.splitlines()[1].split() == ["a", "0.000e+00", "-", "PASS"]
    write(res, '"time","a"\n0,0\n0.5,1.5\n1,0\n')
    assert run_compare(res, ref) == 1
    out, err = capsys.readouterr()
    assert err == "" and out.splitlines()[1].split()[-1] == "FAIL"


BAD_TRACES = {
    "missing": (None, "no such file"),
    "binary": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "binary file"),
    "latin1": ('"time","température"\n0,1\n1,2\n'.encode("latin-1"), "not UTF-8"),
    "semicolons": ('"time";"a"\n0;0\n1;1\n', "not commas"),
    "single column": ('"time"\n0\n1\n', "single column"),
    "no header": ("0,0\n1,1\n", "no header"),
    "ragged": ('"time","a"\n0,0\n0.5\n1,0\n', "line 3 has 1 values but the header has 2"),
    "non-numeric": ('"time","a"\n0,0\n0.5,abc\n1,0\n', "line 3, column 'a': 'abc' is not a number"),
    "nan time": ('"time","a"\n0,0\nnan,1\n1,0\n', "line 3: time 'nan' is not finite"),
    "no time": ('"t","a"\n0,0\n1,1\n', 'no "time" column'),
    "time not first": ('"a","time"\n0,0\n1,1\n', '"time" is column 2'),
    "time repeated": ('"time","a"\n0,0\n0.5,1\n0.5,2\n1,0\n', "not strictly increasing at line 4"),
    "time decreasing": ('"time","a"\n0,0\n0.5,1\n0.4,2\n1,0\n', "not strictly increasing at line 4"),
    "empty file": ("", "is empty"),
    "header only": ('"time","a"\n', "no data rows"),
    "one sample": ('"time","a"\n0,0\n', "single sample"),
    "duplicate column": ('"time","a","a"\n0,0,0\n1,1,1\n', "appears twice"),
}


@pytest.mark.parametrize("case", sorted(BAD_TRACES))
@pytest.mark.parametrize("role", ["result", "reference"])
def test_bad_trace_gives_one_error_line_exit_2_and_writes_nothing(case, role, files, capsys):
    folder, res, ref = files
    content, phrase = BAD_TRACES[case]
    bad = folder / "bad.csv"
    if content is not None:
        write(bad, content)
    with pytest.raises(CompareInputError, match=None) as caught:
        read_trace(bad)
    assert str(bad) in str(caught.value) and phrase in str(caught.value)
    assert "\n" not in str(caught.value)

    out_dir = folder / "report"
    args = (bad, ref) if role == "result" else (res, bad)
    assert run_compare(*args, None, out_dir) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert len(err.splitlines()) == 1 and err.endswith("\n")
    assert err.startswith(f"error: {bad}: ") and phrase in err
    assert not out_dir.exists()


def test_result_missing_reference_variables_names_them(tmp_path, capsys):
    ref = tmp_path / "ref.csv"
    write_csv(ref, reference())
    res = tmp_path / "res.csv"
    write_csv(res, trace(b=SMOOTH_STEP, extra=RAMP))
    with pytest.raises(CompareInputError, match=r"lacks 2 variable\(s\) of the reference: a, c;"):
        compare_traces(read_trace(res), read_trace(ref), {}, DEFAULT_TOLERANCE, result_label=str(res))
    assert run_compare(res, ref, None, tmp_path / "out") == 2
    out, err = capsys.readouterr()
    assert err.splitlines() == [f"error: {res}: lacks 2 variable(s) of the reference: a, c; write them to the result"]
    assert out == "" and not (tmp_path / "out").exists()


def test_result_over_another_time_span_is_bad_input(tmp_path, capsys):
    ref = write(tmp_path / "ref.csv", GOOD)
    res = write(tmp_path / "res.csv", '"time","a"\n0,0\n0.5,1\n0.9,0\n')
    assert run_compare(res, ref) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [
        f"error: {res}: time ends at 0.90000000000000002 s but the reference {ref} ends at 1 s, "
        "more than the time tolerance (0.001 s) apart; rerun over the reference's time span"
    ]


def test_report_dir_that_is_a_file_is_bad_input(files, capsys):
    folder, res, ref = files
    blocker = write(folder / "blocker", "x")
    assert run_compare(res, ref, None, blocker) == 2
    assert capsys.readouterr().err.startswith(f"error: {blocker}: exists and is not a directory")


# ----------------------------------------------------------------------------- tolerance files


def test_tolerance_file_merges_entries_with_default(tmp_path):
    path = write(tmp_path / "tol.yaml", "default: {rtol: 1e-2}\na: {atol: 0.5}\nb: {ttol: 5.0e-3, rtol: 0}\n")
    default, per_variable = load_tolerances(path)
    assert default == Tolerance(atol=1e-9, rtol=1e-2, ttol=1e-3)
    assert per_variable == {
        "a": Tolerance(atol=0.5, rtol=1e-2, ttol=1e-3),
        "b": Tolerance(atol=1e-9, rtol=0.0, ttol=5e-3),
    }


def test_tolerance_file_changes_the_verdict(tmp_path, capsys):
    ref = tmp_path / "ref.csv"
    res = tmp_path / "res.csv"
    write_csv(ref, reference())
    write_csv(res, trace(a=SINE + 0.01, b=SMOOTH_STEP, c=RAMP))
    assert run_compare(res, ref) == 1
    tol = write(tmp_path / "tol.yaml", "a: {atol: 0.02}\n")
    capsys.readouterr()
    assert run_compare(res, ref, tol) == 0


BAD_TOLERANCES = {
    "negative": ("a: {atol: -1}\n", "key 'a.atol': -1 is less than the minimum of 0"),
    "unknown key": ("a: {abstol: 1}\n", "key 'a': Additional properties are not allowed ('abstol' was unexpected)"),
    "relative above 1": ("default: {ttol: 2}\n", "key 'default.ttol': 2 is greater than the maximum of 1"),
    "not a mapping entry": ("a: 0.1\n", "key 'a': 0.1 is not of type 'object'"),
    "text value": ("a: {rtol: lots}\n", "key 'a.rtol': 'lots' is not of type 'number'"),
    "list": ("- a\n", "must be a mapping"),
    "yaml syntax": ("a: {atol: 1\n", "is not valid YAML"),
    "empty": ("", "is empty"),
    "unknown variable": ("zz: {atol: 1}\n", "key 'zz' is not a variable of the reference"),
}


@pytest.mark.parametrize("case", sorted(BAD_TOLERANCES))
def test_bad_tolerance_file_names_file_and_key(case, files, capsys):
    folder, res, ref = files
    text, phrase = BAD_TOLERANCES[case]
    tol = write(folder / "tol.yaml", text)
    assert run_compare(res, ref, tol, folder / "out") == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1
    assert err.startswith(f"error: {tol}: ") and phrase in err
    assert not (folder / "out").exists()


def test_missing_tolerance_file(files, capsys):
    folder, res, ref = files
    assert run_compare(res, ref, folder / "nope.yaml") == 2
    assert capsys.readouterr().err == f"error: {folder / 'nope.yaml'}: no such file; give the YAML tolerance file\n"


# ----------------------------------------------------------------------------- report


def test_report_writes_envelopes_and_png_only_for_failing_variables(tmp_path):
    shifted = trace(a=SINE + 0.01, b=SMOOTH_STEP, c=RAMP + 0.1)
    comparison = compare_traces(shifted, reference(), {}, DEFAULT_TOLERANCE)
    assert comparison.failed == ("a", "c")
    written = write_report(comparison, tmp_path / "out", shifted, reference())
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert names == ["a_funnel.csv", "a_funnel.png", "c_funnel.csv", "c_funnel.png", "summary.csv"]
    assert sorted(p.name for p in written) == names
    for name in ("a", "c"):
        assert (tmp_path / "out" / f"{name}_funnel.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        envelope = read_csv(tmp_path / "out" / f"{name}_funnel.csv")
        assert envelope.names == ("time", "result", "reference", "lower", "upper", "error")
        assert envelope.data.shape == (1001, 6)
        assert np.all(envelope.column("lower") <= envelope.column("upper"))
        assert envelope.column("error").max() == pytest.approx(comparison[name].max_error, abs=1e-15)
        np.testing.assert_array_equal(envelope.column("result"), shifted.column(name))
        np.testing.assert_allclose(envelope.column("reference"), reference().column(name))
        # Where the result lies above the funnel, the error is its distance to the upper edge.
        above = envelope.column("result") > envelope.column("upper")
        np.testing.assert_allclose(
            envelope.column("error")[above], (envelope.column("result") - envelope.column("upper"))[above], atol=1e-12
        )
    summary = (tmp_path / "out" / "summary.csv").read_text().splitlines()
    assert summary[0].startswith("variable,passed,max_error,time_of_max_error")
    assert [line.split(",")[:2] for line in summary[1:]] == [["a", "0"], ["b", "1"], ["c", "0"]]


def test_run_compare_writes_the_report_when_asked(tmp_path, capsys):
    ref = tmp_path / "ref.csv"
    res = tmp_path / "res.csv"
    write_csv(ref, reference())
    write_csv(res, trace(a=SINE, b=SMOOTH_STEP + 0.05, c=RAMP))
    assert run_compare(res, ref, None, tmp_path / "report") == 1
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == ["b_funnel.csv", "b_funnel.png", "summary.csv"]
    assert capsys.readouterr().out.splitlines()[-1] == f"report: 3 files in {tmp_path / 'report'}"


# ----------------------------------------------------------------------------- cross-check reference files


def test_reference_opt_round_trip(tmp_path):
    original = reference()
    csv_path, opt_path = write_reference(original, tmp_path / "Toggle", start=0.0, stop=1.0, step=1e-3, reltol=1e-4)
    assert (csv_path.name, opt_path.name) == ("Toggle_ref.csv", "Toggle_ref.opt")
    assert opt_path.read_text() == "StartTime, 0.0\nStopTime, 1.0\nStepSize, 0.001\nRelTol, 0.0001\n"
    for stem in (tmp_path / "Toggle", csv_path, opt_path):
        trace_back, options = read_reference(stem)
        assert options == {"StartTime": 0.0, "StopTime": 1.0, "StepSize": 1e-3, "RelTol": 1e-4}
        assert trace_back.names == original.names
        np.testing.assert_array_equal(trace_back.data, original.data)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["Toggle_ref.csv", "Toggle_ref.opt"]


def test_reads_cross_check_repository_style_options(tmp_path):
    path = write(
        tmp_path / "M_ref.opt",
        "StepSize,0.001\nStartTime,0\nStopTime,1.5   // in seconds\nRelTol,1e-4\nOutputIntervalLength,0.001\n"
        "SolverType, FixedStep\n\n",
    )
    assert read_options(path) == {
        "StepSize": 1e-3,
        "StartTime": 0.0,
        "StopTime": 1.5,
        "RelTol": 1e-4,
        "OutputIntervalLength": 1e-3,
        "SolverType": "FixedStep",
    }


@pytest.mark.parametrize(
    "text, phrase",
    [
        ("StartTime, 0\nStopTime, 1\nStepSize, 0.001\n", "lacks RelTol"),
        ("StartTime, 0\nStopTime, soon\nStepSize, 0.001\nRelTol, 1e-4\n", "StopTime is 'soon', not a number"),
        ("StartTime, 1\nStopTime, 1\nStepSize, 0.001\nRelTol, 1e-4\n", "is not after StartTime"),
        ("StartTime 0\nStopTime, 1\nStepSize, 0.001\nRelTol, 1e-4\n", "line 1 is not 'Name, value'"),
        ("StartTime, 0\nStartTime, 0\nStopTime, 1\nStepSize, 0.001\nRelTol, 1e-4\n", "StartTime is given twice"),
    ],
)
def test_bad_options_file(tmp_path, text, phrase):
    path = write(tmp_path / "M_ref.opt", text)
    with pytest.raises(CompareInputError) as caught:
        read_options(path)
    assert str(caught.value).startswith(f"{path}: ") and phrase in str(caught.value)


def test_write_reference_refuses_a_trace_not_spanning_start_to_stop(tmp_path):
    with pytest.raises(ValueError, match="not from StartTime"):
        write_reference(reference(), tmp_path / "M", start=0.0, stop=2.0, step=1e-3, reltol=1e-4)
    assert list(tmp_path.iterdir()) == []


def test_run_compare_checks_the_result_against_the_opt_span(tmp_path, capsys):
    write_reference(trace(a=SINE), tmp_path / "M", start=0.0, stop=1.0, step=1e-3, reltol=1e-4)
    early = tmp_path / "res.csv"
    write_csv(early, Trace(("time", "a"), np.column_stack([T[:501], SINE[:501]])))
    assert run_compare(early, tmp_path / "M_ref.csv") == 2
    assert capsys.readouterr().err.splitlines() == [
        f"error: {early}: time ends at 0.5 s but {tmp_path / 'M_ref.opt'} gives StopTime 1 s; "
        "run over the reference's time span"
    ]
    full = tmp_path / "full.csv"
    write_csv(full, trace(a=SINE))
    assert run_compare(full, tmp_path / "M_ref.csv") == 0
    # A reference that does not match its own options file is bad input too.
    write(tmp_path / "M_ref.opt", "StartTime, 0\nStopTime, 2\nStepSize, 0.001\nRelTol, 1e-4\n")
    capsys.readouterr()
    assert run_compare(full, tmp_path / "M_ref.csv") == 2
    assert capsys.readouterr().err.startswith(f"error: {tmp_path / 'M_ref.csv'}: time ends at 1 s")


def test_tolerance_rejects_negative_or_relative_above_one():
    with pytest.raises(ValueError):
        Tolerance(atol=-1.0, rtol=0.0, ttol=0.0)
    with pytest.raises(ValueError):
        Tolerance(atol=0.0, rtol=0.0, ttol=1.5)


@pytest.mark.parametrize(
    ("case", "phrase"),
    [
        ("device", "is not a regular file"),
        ("loop", "is a symbolic link in a loop"),
        ("folder", "is a directory"),
        ("dangling", "which does not exist"),
    ],
)
def test_a_tolerance_file_found_by_place_that_is_not_a_regular_file_is_bad_input(case, phrase, files, capsys):
    """tolerances.yaml beside the reference exists but cannot be read as a file: one line, exit
    2; it is never skipped for the defaults."""
    folder, res, ref = files
    place = folder / "tolerances.yaml"
    if case == "device":
        place.symlink_to("/dev/zero")
    elif case == "loop":
        place.symlink_to(folder / "tolerances.yaml")
    elif case == "folder":
        place.mkdir()
    else:
        place.symlink_to(folder / "absent.yaml")
    assert run_compare(res, ref) == 2
    out, err = capsys.readouterr()
    assert len(err.splitlines()) == 1 and "tolerances.yaml" in err and phrase in err, err


SHIPPED = sorted((Path(__file__).resolve().parent.parent / "scenarios" / "references").glob("*/*_ref.csv"))
# the fast set compares each scenario's first reference; the full suite every reference
FIRST_OF_SCENARIO = {min(p for p in SHIPPED if p.parent == folder) for folder in {p.parent for p in SHIPPED}}


@pytest.mark.parametrize(
    "reference",
    [
        pytest.param(p, id=f"{p.parent.name}/{p.stem}", marks=() if p in FIRST_OF_SCENARIO else pytest.mark.slow)
        for p in SHIPPED
    ],
)
def test_compare_of_a_shipped_reference_with_itself_passes(reference: Path, capsys):
    """Issue 37, item 11: a stored reference is decimated, its invariants were measured at every
    sample (T_s, its .opt StepSize): they are reported unchecked on it, not failed."""
    from toggle_cosim.analysis.invariants import invariants_path, load_invariants

    assert run_compare(reference, reference) == 0
    out = capsys.readouterr().out
    invariants = load_invariants(invariants_path(reference))
    assert out.count("not checked (the values are measured at every sample") == len(invariants)
    assert "FAIL" not in out


@pytest.fixture(scope="module")
def fig4_friction(plant_fmu: Path):
    """The run behind scenarios/references/fig4_nominal/friction_ref.csv, at every sample."""
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.plant.contract import check_plant

    root = Path(__file__).resolve().parent.parent
    run = next(r for r in load_scenario(root / "scenarios" / "fig4_nominal.yaml") if r.variant == "friction")
    outcome = check_and_simulate(run, check_plant(plant_fmu))
    assert outcome.complete
    return outcome.trace


def test_invariants_are_checked_at_every_sample_and_catch_a_changed_trace(fig4_friction, tmp_path, capsys):
    """The run's own trace (every sample) passes its reference's invariants; the same trace with
    the command chattering by ±5 mA more fails iq_total_variation_A_per_s (exit 1); the run
    thinned as record_every: 10 writes it leaves them unchecked."""
    reference = (
        Path(__file__).resolve().parent.parent / "scenarios" / "references" / "fig4_nominal" / "friction_ref.csv"
    )
    full = tmp_path / "full.csv"
    write_csv(full, fig4_friction)
    assert run_compare(full, reference) == 0
    out = capsys.readouterr().out
    assert "invariant iq_total_variation_A_per_s = " in out and out.count(": pass") == 3

    data = fig4_friction.data.copy()
    column = fig4_friction.names.index("iq_ref")
    data[:, column] += 0.005 * (-1.0) ** np.arange(data.shape[0])  # up to 20 A/s more variation at T_s = 0.5 ms
    chattering = tmp_path / "chattering.csv"
    write_csv(chattering, Trace(fig4_friction.names, data))
    assert run_compare(chattering, reference) == 1
    out = capsys.readouterr().out
    assert "invariant iq_total_variation_A_per_s" in out and "FAIL" in out.split("iq_total_variation_A_per_s")[1]

    thinned = tmp_path / "thinned.csv"
    write_csv(thinned, fig4_friction, every=10)
    assert run_compare(thinned, reference, junit=tmp_path / "junit.xml") == 0
    assert capsys.readouterr().out.count("not checked") == 3
    junit = (tmp_path / "junit.xml").read_text(encoding="utf-8")
    assert junit.count("<skipped") == 3 and "<failure" not in junit  # JUnit: skipped, not passed


def test_a_recorded_nan_reads_back_and_fails_only_a_compared_variable(files, capsys):
    """Issue 37, item 1: a run writes a NaN it records as `nan`; compare reads it back. In a
    column the reference does not have it is not compared (exit 0); in a compared variable it
    is one line naming the file, the sample, its time and the variable (exit 2)."""
    folder, _, ref = files
    reference = read_trace(ref)
    time = reference.time
    values = np.where(time >= 0.5, np.nan, 0.0)
    extra = folder / "extra.csv"
    write_csv(extra, Trace((*reference.names, "flag"), np.column_stack([reference.data, values])))
    assert "nan" in extra.read_text()
    assert np.array_equal(read_trace(extra).column("flag"), values, equal_nan=True)
    assert run_compare(extra, ref) == 0
    capsys.readouterr()
    compared = folder / "compared.csv"
    data = reference.data.copy()
    data[time >= 0.5, 1] = np.inf
    write_csv(compared, Trace(reference.names, data))
    assert run_compare(compared, ref) == 2
    out, err = capsys.readouterr()
    first = int(np.argmax(time >= 0.5))
    assert out == "" and len(err.splitlines()) == 1
    assert err.startswith(f"error: {compared}: sample {first + 1} (t = {time[first]:.6g} s), variable ")
    assert f"{reference.names[1]!r} is inf, not finite" in err
