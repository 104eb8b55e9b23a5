"""Signals (`toggle_cosim.signals`): each kind's value at chosen times, the value a sample sees
exactly at an edge (every signal is continuous from the right: a step at τ is seen by the sample
at t = τ), CSV tables and their errors, and the scenario keys with their one-line errors."""

from __future__ import annotations

import copy
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from toggle_cosim.experiments.scenario import ScenarioError, load_scenario, merge_documents, runs_from_document
from toggle_cosim.signals import tables
from toggle_cosim.signals.definitions import (
    Constant,
    Pulse,
    Ramp,
    Signal,
    SignalError,
    Sine,
    Step,
    Table,
    describe,
    sample,
)
from toggle_cosim.signals.tables import read_table

ROOT = Path(__file__).resolve().parent.parent
BASE = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
BASE.pop("variants")
BASE["t_end"] = 1.0


def at(signal: Signal, *times: float) -> list[float]:
    return [float(v) for v in signal.at(np.array(times))]


def test_constant_is_its_value_at_every_sample_bit_for_bit() -> None:
    value = 100.0 / 3.0
    assert np.array_equal(sample(Constant(value), 3000, 0.0005), np.full(3001, value))


def test_step_is_offset_before_and_offset_plus_height_from_its_time_on() -> None:
    step = Step(height=100.0, start_time=0.25, offset=-5.0)
    assert at(step, 0.0, 0.2499, 0.25, 0.2501, 1.0) == [-5.0, -5.0, 95.0, 95.0, 95.0]


@pytest.mark.parametrize("T_s", [0.0005, 0.001, 0.0001, 0.0003])
def test_a_step_is_seen_first_by_the_sample_at_its_time(T_s: float) -> None:
    """Sample k sees u(t_k), t_k = k·T_s as the loop computes it: the step at 0.3 s lands at
    k = round(0.3 / T_s) whatever the rounding of k * T_s (0.3 is not a binary fraction)."""
    u = sample(Step(height=1.0, start_time=0.3), int(round(1.0 / T_s)), T_s)
    assert int(np.argmax(u == 1.0)) == int(round(0.3 / T_s))


def test_ramp_rises_linearly_over_its_duration_and_holds() -> None:
    ramp = Ramp(height=80.0, duration=0.4, start_time=0.5, offset=10.0)
    assert at(ramp, 0.0, 0.5, 0.6, 0.7, 0.9, 2.0) == pytest.approx([10.0, 10.0, 30.0, 50.0, 90.0, 90.0], abs=1e-12)


def test_pulse_is_high_on_the_first_width_of_each_period_for_count_pulses() -> None:
    pulse = Pulse(amplitude=50.0, period=0.2, width=0.05, start_time=0.1, offset=1.0, count=2)
    times = (0.0, 0.1, 0.1499, 0.15, 0.2999, 0.3, 0.3499, 0.35, 0.5, 0.52)
    assert at(pulse, *times) == [1.0, 51.0, 51.0, 1.0, 1.0, 51.0, 51.0, 1.0, 1.0, 1.0]
    endless = Pulse(amplitude=1.0, period=0.2, width=0.05)
    assert at(endless, 10.0, 10.05, 10.1) == [1.0, 0.0, 0.0]


def test_pulse_width_must_be_shorter_than_its_period() -> None:
    with pytest.raises(SignalError, match="width 0.2 s is not shorter than period 0.2 s"):
        Pulse(amplitude=1.0, period=0.2, width=0.2)


def test_sine_starts_at_its_start_time_with_its_phase() -> None:
    sine = Sine(amplitude=20.0, frequency=2.0, phase=math.pi / 2, start_time=0.5, offset=50.0)
    assert at(sine, 0.0, 0.4999, 0.5, 0.625, 0.75) == pytest.approx([50.0, 50.0, 70.0, 50.0, 30.0], abs=1e-9)


def test_linear_table_interpolates_and_hold_keeps_the_last_rows_value() -> None:
    times, values = (0.0, 0.5, 1.0), (0.0, 100.0, 40.0)
    linear, hold = Table(times, values, "linear"), Table(times, values, "hold")
    assert at(linear, 0.0, 0.25, 0.5, 0.75, 1.0) == [0.0, 50.0, 100.0, 70.0, 40.0]
    assert at(hold, 0.0, 0.4999, 0.5, 0.9999, 1.0) == [0.0, 0.0, 100.0, 100.0, 40.0]


@pytest.mark.parametrize(
    ("times", "values", "message"),
    [
        ((0.0, 1.0, 0.5), (0, 1, 2), "row 3: time 0.5 comes before the time of row 2"),
        ((0.0, 1.0, 1.0), (0, 1, 2), "row 3: time 1.0 repeats the time of row 2"),
        ((0.0, 1.0), (0.0, math.nan), "row 2: .* is not finite"),
        ((0.0,), (1.0,), "at least 2 rows"),
    ],
)
def test_a_table_not_strictly_increasing_or_not_finite_is_refused(times, values, message) -> None:
    with pytest.raises(SignalError, match=message):
        Table(times, values)


def test_a_table_must_cover_the_run() -> None:
    Table((0.0, 1.5), (0.0, 1.0)).check_covers(1.5)
    with pytest.raises(SignalError, match="ends at t = 1 s, before the run's t_end = 1.5 s"):
        Table((0.0, 1.0), (0.0, 1.0)).check_covers(1.5)
    with pytest.raises(SignalError, match="starts at t = 0.1 s, after 0"):
        Table((0.1, 2.0), (0.0, 1.0)).check_covers(1.5)


def _csv(tmp_path: Path, text: str, name: str = "load.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_csv_table_reads_units_columns_and_records_its_hash(tmp_path: Path) -> None:
    import hashlib

    path = _csv(tmp_path, "time [s],other [V],F_E [N]\n0,9,0\n0.5,9,10\n1.0,9,20\n")
    table = read_table(path, "linear", "F_E")
    assert table.times.tolist() == [0.0, 0.5, 1.0] and table.values.tolist() == [0.0, 10.0, 20.0]
    assert table.source.column == "F_E" and table.source.unit == "N"
    assert table.source.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    assert describe(table)["sha256"] == table.source.sha256
    assert read_table(path, "hold", "F_E", column="other").values.tolist() == [9.0, 9.0, 9.0]
    two = _csv(tmp_path, "time,force\n0,1\n1,2\n", "two.csv")
    assert read_table(two, "hold", "F_E").source.unit is None  # the second of two columns, no unit


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time [s],F_E [N]\n0,0\n1,1\n0.5,2\n", "line 4: time 0.5 comes before the time of line 3"),
        ("time [s],F_E [N]\n0,0\n0,1\n", "line 3: time 0.0 repeats"),
        ("time [s],F_E [N]\n0,0\n1,inf\n", "line 3: .* is not finite"),
        ("time [s],F_E [N]\n0,0\n1,abc\n", "line 3: F_E 'abc' is not a number"),
        ("0,0\n1,1\n", "line 1 is not a header"),
        ("t,F_E\n0,0\n1,1\n", "the header is t, F_E: the first column must be time"),
        ("time [ms],F_E [N]\n0,0\n1,1\n", "the time column's unit is 'ms'"),
        ("time,a,b\n0,0,0\n1,1,1\n", "no column 'F_E' among a, b"),
        ("time,F_E\n0,0\n1\n", "line 3 has 1 fields, the header 2"),
        ("", "the file is empty"),
    ],
)
def test_csv_table_errors_name_the_file_and_the_line(tmp_path: Path, text: str, message: str) -> None:
    path = _csv(tmp_path, text)
    with pytest.raises(SignalError, match=f"^{path}: {message}"):
        read_table(path, "hold", "F_E")


def test_a_csv_table_is_read_once_into_read_only_float_arrays_its_runs_share(tmp_path: Path) -> None:
    path = _csv(tmp_path, "time [s],F_E [N]\n0,0\n0.5,10\n1.0,20\n")
    table = read_table(path, "linear", "F_E")
    assert table.times.dtype == np.float64 and not table.times.flags.writeable and not table.values.flags.writeable
    assert read_table(path, "linear", "F_E") is table  # unchanged: the same arrays, not a second copy
    path.write_text("time [s],F_E [N]\n0,0\n0.5,10\n1.0,20\n2.0,30\n", encoding="utf-8")
    assert read_table(path, "linear", "F_E").values.tolist() == [0.0, 10.0, 20.0, 30.0]  # changed: read again


@pytest.mark.parametrize("cell", ["5", '"5"'])  # numpy's parser, and the row-by-row reader (quotes)
def test_a_csv_table_over_the_row_limit_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cell: str) -> None:
    monkeypatch.setattr(tables, "TABLE_ROWS", 3)
    rows = "".join(f"{t},{cell}\n" for t in range(4))
    path = _csv(tmp_path, f"time [s],F_E [N]\n{rows}")
    with pytest.raises(SignalError, match=f"^{path}: more than 3 rows"):
        read_table(path, "hold", "F_E")
    assert read_table(_csv(tmp_path, f"time,F_E\n{rows[: rows.rindex('3,')]}", "three.csv"), "hold", "F_E")


def test_cells_numpy_does_not_take_are_read_as_python_reads_them(tmp_path: Path) -> None:
    path = _csv(tmp_path, 'time,F_E\n\n0,"1_0"\n 1 , 2.5 \n')
    table = read_table(path, "hold", "F_E")
    assert table.times.tolist() == [0.0, 1.0] and table.values.tolist() == [10.0, 2.5]


def test_a_missing_or_unreadable_table_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(SignalError, match="no such CSV table"):
        read_table(tmp_path / "none.csv", "hold", "F_E")
    with pytest.raises(SignalError, match="is a directory"):
        read_table(tmp_path, "hold", "F_E")


# -- the scenario keys -------------------------------------------------------------------------


def _run(F_E: object, **extra: object):
    document = copy.deepcopy(BASE)
    document["plant"]["F_E"] = F_E
    document.update(extra)
    return runs_from_document(document, ROOT / "scenarios" / "x.yaml")[0]


def test_a_number_stays_a_constant_and_a_mapping_becomes_its_signal() -> None:
    assert _run(100.0).plant.F_E == 100.0
    assert _run({"kind": "step", "start_time": 0.5, "height": 80}).plant.F_E == Step(80.0, 0.5)
    points = _run({"kind": "points", "points": [[0, 0], [0.5, 10], [1.0, 10]]}).plant.F_E
    assert points == Table((0.0, 0.5, 1.0), (0.0, 10.0, 10.0), "linear")


def test_the_shipped_measured_table_covers_its_run_and_records_its_file() -> None:
    (run, _) = load_scenario(ROOT / "scenarios" / "measured_load.yaml")
    table = run.plant.F_E
    assert isinstance(table, Table) and table.interpolation == "hold" and table.source.unit == "N"
    assert table.times[0] == 0.0 and table.times[-1] >= run.t_end
    assert describe(table)["file"].endswith("measured_load.csv")


@pytest.mark.parametrize(
    ("F_E", "message"),
    [
        ({"kind": "jump", "height": 1}, r"key plant.F_E.kind: 'jump' is not allowed \(choose one of step, ramp"),
        ({"kind": "step", "height": 1, "start_time": 0.1, "width": 2}, "unknown key plant.F_E.width"),
        ({"kind": "step", "height": 1}, "missing key: 'start_time' is a required property"),
        ({"height": 1}, "missing key: 'kind' is a required property"),
        ({"kind": "pulse", "amplitude": 1, "period": 0.1, "width": 0.1}, "key plant.F_E: width 0.1 s is not shorter"),
        (
            {"kind": "table", "file": "none.csv", "interpolation": "hold"},
            "key plant.F_E: .*none.csv: no such CSV table",
        ),
        ({"kind": "table", "file": "x.csv"}, "missing key: 'interpolation' is a required property"),
        ({"kind": "points", "points": [[0, 0], [0.5, 1]]}, "key plant.F_E: the table ends at t = 0.5 s, before"),
        ({"kind": "points", "points": [[0, 0], [0, 1], [1, 1]]}, "key plant.F_E: row 2: time 0.0 repeats"),
        ("heavy", "key plant.F_E: 'heavy' is not of type number or mapping"),
    ],
)
def test_bad_signals_are_one_line_naming_the_key(F_E: object, message: str) -> None:
    with pytest.raises(ScenarioError, match=message) as caught:
        _run(F_E)
    assert "\n" not in str(caught.value)


def test_a_variant_with_another_kind_replaces_the_signal_and_one_of_the_same_kind_merges() -> None:
    base = {"plant": {"F_E": {"kind": "step", "start_time": 0.5, "height": 80}}}
    other = merge_documents(base, {"plant": {"F_E": {"kind": "ramp", "duration": 0.2, "height": 10}}})
    assert other["plant"]["F_E"] == {"kind": "ramp", "duration": 0.2, "height": 10}
    same = merge_documents(base, {"plant": {"F_E": {"height": 10}}})
    assert same["plant"]["F_E"] == {"kind": "step", "start_time": 0.5, "height": 10}


def test_the_docs_table_of_signal_kinds_names_every_key_the_schema_has() -> None:
    """docs/scenarios.md lists each kind with its keys: the generated schema's, no more, no fewer."""
    from toggle_cosim.signals.schema import KINDS, SCHEMA_KEYS

    text = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    for kind in KINDS:
        row = next(line for line in text.splitlines() if line.startswith(f"| `{kind}` |"))
        keys_cell = row.split("|")[2]
        named = set(re.findall(r"`(\w+)`", keys_cell)) - {"hold", "linear"}
        assert named == set(SCHEMA_KEYS[kind]), kind
