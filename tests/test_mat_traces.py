"""Modelica result files (MAT v4, the layout Dymola and OpenModelica write) as comparison input.

The file is written here with scipy.io.savemat in the documented layout (Aclass, name,
description, dataInfo, data_1 for parameters, data_2 for trajectories, stored transposed,
"binTrans") and read back through BuildingsPy's reader: two libraries, one layout.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io

from toggle_cosim.analysis.compare_command import run_compare
from toggle_cosim.analysis.csv_traces import CompareInputError
from toggle_cosim.analysis.trace_formats import read_any_trace, read_mat_trace
from toggle_cosim.files.traces import Trace, write_csv


def _char_matrix(strings: list[str]) -> np.ndarray:
    """Strings as the columns of a character matrix (binTrans: one name per column)."""
    width = max(len(s) for s in strings)
    return np.ascontiguousarray(np.array([list(s.ljust(width)) for s in strings], dtype="U1").T)


def write_modelica_mat(
    path: Path, time: np.ndarray, trajectories: dict[str, np.ndarray], parameters: dict[str, float]
) -> Path:
    """A Dymola-style result file: variable 1 is Time (abscissa), then parameters (block 1),
    then trajectories (block 2); dataInfo row 0 = block, row 1 = column (1-based, signed)."""
    names = ["Time", *parameters, *trajectories]
    info = [[0, 1, 0, -1]]  # Time: the abscissa
    info += [[1, 2 + i, 0, -1] for i in range(len(parameters))]
    info += [[2, 2 + i, 0, -1] for i in range(len(trajectories))]
    data_1 = np.vstack([[time[0], time[-1]], *[[v, v] for v in parameters.values()]])
    data_2 = np.vstack([time, *trajectories.values()])
    scipy.io.savemat(
        str(path),
        {
            "Aclass": np.array(
                [list("Atrajectory"), list("1.1        "), list("           "), list("binTrans   ")], dtype="U1"
            ),
            "name": _char_matrix(names),
            "description": _char_matrix([f"description of {n}" for n in names]),
            "dataInfo": np.ascontiguousarray(np.array(info, dtype=np.int32).T),
            "data_1": data_1,
            "data_2": data_2,
        },
        format="4",
    )
    return path


T = np.linspace(0.0, 1.5, 301)


def test_a_modelica_result_file_reads_as_a_trace_with_parameters_as_constant_columns(tmp_path):
    x = 0.2329 + 0.05 * (1 - np.cos(np.pi * T / 1.5))
    path = write_modelica_mat(tmp_path / "Plant_res.mat", T, {"x_B": x, "v_B": np.gradient(x, T)}, {"m_B": 4.43})
    trace = read_mat_trace(path)
    assert trace.names[0] == "time"
    assert set(trace.names[1:]) == {"x_B", "v_B", "m_B"}
    np.testing.assert_array_equal(trace.time, T)
    np.testing.assert_array_equal(trace.column("x_B"), x)
    np.testing.assert_array_equal(trace.column("m_B"), np.full(T.size, 4.43))


def test_an_event_repeated_in_time_keeps_the_value_after_it(tmp_path):
    time = np.array([0.0, 0.5, 0.5, 1.0])
    path = write_modelica_mat(tmp_path / "event.mat", time, {"s": np.array([0.0, 0.0, 1.0, 1.0])}, {})
    trace = read_mat_trace(path)
    np.testing.assert_array_equal(trace.time, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(trace.column("s"), [0.0, 1.0, 1.0])


def test_compare_holds_a_csv_run_against_a_mat_reference_from_another_tool(tmp_path, capsys):
    x = np.sin(2 * np.pi * T / 1.5)
    mat = write_modelica_mat(tmp_path / "tool_res.mat", T, {"x_B": x}, {})
    fine = np.linspace(0.0, 1.5, 3001)
    write_csv(tmp_path / "trace.csv", Trace(("time", "x_B"), np.column_stack([fine, np.sin(2 * np.pi * fine / 1.5)])))
    assert run_compare(tmp_path / "trace.csv", mat) == 0
    write_csv(
        tmp_path / "off.csv", Trace(("time", "x_B"), np.column_stack([fine, 1.01 * np.sin(2 * np.pi * fine / 1.5)]))
    )
    assert run_compare(tmp_path / "off.csv", mat) == 1
    assert "x_B" in capsys.readouterr().out
    # the other way round: the tool's file as RESULT, with more variables than our reference has
    rich = write_modelica_mat(tmp_path / "rich_res.mat", T, {"x_B": x, "plant.der_x": np.cos(T)}, {"m_B": 4.43})
    assert run_compare(rich, tmp_path / "trace.csv") == 0
    assert capsys.readouterr().out.splitlines()[-2] == "1 variables: 1 passed, 0 failed"


def test_a_file_that_is_not_a_modelica_result_is_one_line_of_bad_input(tmp_path, capsys):
    plain = tmp_path / "plain.mat"
    scipy.io.savemat(str(plain), {"x": np.arange(3.0)}, format="4")
    with pytest.raises(CompareInputError, match="not a Modelica result file in the MAT v4 layout"):
        read_any_trace(plain)
    garbage = tmp_path / "garbage.mat"
    garbage.write_bytes(b"not a mat file at all")
    write_csv(tmp_path / "r.csv", Trace(("time", "a"), np.array([[0.0, 0.0], [1.0, 1.0]])))
    assert run_compare(tmp_path / "r.csv", garbage) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {garbage}: is not a Modelica result file") and len(err.splitlines()) == 1


@pytest.mark.parametrize("block", [1, 2])
def test_data_info_pointing_past_the_data_is_bad_input(tmp_path, capsys, block):
    """dataInfo names column 9 of data_1 or data_2, which have 2: one line, exit 2 (the
    comparison did not fail: the file is damaged)."""
    path = write_modelica_mat(tmp_path / "bad.mat", T, {"x_B": np.sin(T)}, {"m_B": 4.43})
    contents = scipy.io.loadmat(str(path))
    info = contents["dataInfo"].copy()
    info[1, 2 if block == 2 else 1] = 9  # the column of x_B (block 2) or of m_B (block 1)
    contents["dataInfo"] = info
    scipy.io.savemat(str(path), {k: v for k, v in contents.items() if not k.startswith("__")}, format="4")
    with pytest.raises(CompareInputError, match="is not a Modelica result file"):
        read_mat_trace(path)
    csv = tmp_path / "res.csv"
    write_csv(csv, Trace(("time", "x_B"), np.column_stack([T, np.sin(T)])))
    assert run_compare(csv, path) == 2
    _, err = capsys.readouterr()
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"error: {path}: ")
