"""CI-facing behaviour of `toggle-cosim compare`: tolerance files found by place, the JUnit XML
report (parsed back with junitparser, counts checked), the Markdown summary, PNGs of failing
variables, solver statistics compared as data, and the GitHub workflow file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from junitparser import Failure, JUnitXml

from toggle_cosim.analysis.compare_command import run_compare
from toggle_cosim.analysis.reference_files import write_reference
from toggle_cosim.analysis.solver_stats import (
    compare_solver_statistics,
    read_statistics_file,
    statistics_path,
    write_statistics_file,
)
from toggle_cosim.analysis.tolerance_files import applicable_tolerance_files
from toggle_cosim.files.traces import Trace, write_csv, write_json
from toggle_cosim.plant.solver_statistics import NOT_EXPOSED, STATISTICS, read_solver_statistics

ROOT = Path(__file__).resolve().parent.parent
T = np.linspace(0.0, 1.0, 1001)


def _trace(**columns: np.ndarray) -> Trace:
    return Trace(("time", *columns), np.column_stack([T, *columns.values()]))


REFERENCE = _trace(a=np.sin(2 * np.pi * T), b=T**2, c=np.cos(3 * T))


@pytest.fixture
def layout(tmp_path: Path) -> dict[str, Path]:
    """references/<case>/M_ref.csv + .opt, and a result whose a and c are off (b is not)."""
    folder = tmp_path / "references" / "case"
    write_reference(REFERENCE, folder / "M", start=0.0, stop=1.0, step=1e-3, reltol=1e-6)
    result = tmp_path / "run" / "trace.csv"
    write_csv(result, _trace(a=np.sin(2 * np.pi * T) + 0.01, b=T**2, c=np.cos(3 * T) + 0.05))
    return {"reference": folder / "M_ref.csv", "result": result, "root": tmp_path}


# ----------------------------------------------------------------------------- tolerances by place


def test_tolerance_files_beside_the_reference_apply_without_a_flag(layout, capsys):
    reference, result = layout["reference"], layout["result"]
    assert run_compare(result, reference) == 1
    (reference.parent.parent / "tolerances.yaml").write_text("a: {atol: 0.02}\n")  # the collection's file
    capsys.readouterr()
    assert run_compare(result, reference) == 1  # c still off
    (reference.parent / "tolerances.yaml").write_text("c: {atol: 0.06}\n")  # the case's own file adds c
    capsys.readouterr()
    assert run_compare(result, reference) == 0
    out = capsys.readouterr().out
    assert f"tolerances: {reference.parent.parent / 'tolerances.yaml'}, {reference.parent / 'tolerances.yaml'}" in out
    assert applicable_tolerance_files(reference) == [
        reference.parent.parent / "tolerances.yaml",
        reference.parent / "tolerances.yaml",
    ]
    # --tolerances replaces both
    explicit = layout["root"] / "strict.yaml"
    explicit.write_text("default: {rtol: 1.0e-3}\n")
    assert run_compare(result, reference, explicit) == 1


def test_the_shipped_tolerances_apply_to_the_readme_command():
    files = applicable_tolerance_files(ROOT / "scenarios" / "references" / "fig4_nominal" / "friction_ref.csv")
    assert [path.resolve() for path in files] == [ROOT / "scenarios" / "references" / "tolerances.yaml"]


def test_a_result_within_the_time_tolerance_of_the_opt_span_passes(layout):
    short = layout["root"] / "short.csv"
    write_csv(short, Trace(REFERENCE.names, REFERENCE.data[:-1]))  # stops 1 ms early: ttol 1e-3 of 1 s
    assert run_compare(short, layout["reference"]) == 0


# ----------------------------------------------------------------------------- JUnit and Markdown


def test_junit_report_has_one_case_per_variable_and_failures_with_error_and_time(layout, capsys):
    junit, summary, out = (layout["root"] / "reports" / name for name in ("compare.xml", "summary.md", "plots"))
    assert run_compare(layout["result"], layout["reference"], None, out, junit=junit, summary=summary) == 1
    xml = JUnitXml.fromfile(str(junit))
    suites = list(xml)
    assert len(suites) == 1 and suites[0].name == "case/M"
    cases = {case.name: case for case in suites[0]}
    assert set(cases) == {"a", "b", "c"}
    assert (suites[0].tests, suites[0].failures, suites[0].errors, suites[0].skipped) == (3, 2, 0, 0)
    assert cases["b"].is_passed
    for name, error, when in (("a", 0.01 - 4e-3, 0.25), ("c", None, None)):
        (failure,) = cases[name].result
        assert isinstance(failure, Failure)
        assert failure.message.startswith("max error ") and " at t = " in failure.message
        if error is not None:
            assert failure.message.startswith(f"max error {error:.3e} at t = {when:.6g} s")
    # a PNG for each failing variable, linked from the Markdown table
    assert sorted(p.name for p in out.glob("*.png")) == ["a_funnel.png", "c_funnel.png"]
    text = summary.read_text()
    assert "| case/M | result samples | 3 | 1 | 2 | - | **FAIL** |" in text
    assert "[a_funnel.png](plots/a_funnel.png)" in text and "[c_funnel.png](plots/c_funnel.png)" in text
    assert "| case/M | a |" in text and "| case/M | b |" not in text


def test_a_passing_comparison_writes_a_report_without_failures(layout):
    junit = layout["root"] / "ok.xml"
    write_csv(layout["root"] / "same.csv", REFERENCE)
    assert run_compare(layout["root"] / "same.csv", layout["reference"], junit=junit) == 0
    xml = JUnitXml.fromfile(str(junit))
    assert (xml.tests, xml.failures) == (3, 0)


def test_a_report_path_that_is_a_folder_is_bad_input_and_nothing_is_written(layout, capsys):
    assert run_compare(layout["result"], layout["reference"], junit=layout["root"]) == 2
    err = capsys.readouterr().err
    expected = f"error: {layout['root']}: is a folder, not a regular file; give another file name for the JUnit report"
    assert err.startswith(expected)


# ----------------------------------------------------------------------------- solver statistics


def test_solver_statistics_compare_exactly_and_name_each_change():
    stored = {"solver.steps": 1200, "solver.rejectedSteps": 3, "solver.events": 12}
    assert compare_solver_statistics(stored, dict(stored)).status == "same"
    check = compare_solver_statistics(stored, {**stored, "solver.steps": 1260, "solver.events": 11})
    assert check.changed
    assert check.lines == ("solver.events: 12 -> 11 (-8.3%)", "solver.steps: 1200 -> 1260 (+5.0%)")
    assert compare_solver_statistics(None, stored).status == "unavailable"
    assert compare_solver_statistics(stored, NOT_EXPOSED).status == "unavailable"


def test_solver_statistics_change_warns_by_default_and_fails_with_the_flag(layout, capsys):
    reference, root = layout["reference"], layout["root"]
    run = root / "ok" / "trace.csv"
    write_csv(run, REFERENCE)
    write_statistics_file(
        statistics_path(reference), {"solver.steps": 100, "solver.rejectedSteps": 0, "solver.events": 4}
    )
    assert statistics_path(reference).name == "M_ref_solver.json"
    write_json(
        run.with_name("run.json"),
        {"solver_statistics": {"solver.steps": 100, "solver.rejectedSteps": 0, "solver.events": 4}},
    )
    assert run_compare(run, reference) == 0
    assert "solver: solver statistics unchanged" in capsys.readouterr().out
    write_json(
        run.with_name("run.json"),
        {"solver_statistics": {"solver.steps": 140, "solver.rejectedSteps": 0, "solver.events": 4}},
    )
    junit = root / "solver.xml"
    assert run_compare(run, reference, junit=junit) == 0
    assert "warning: solver.steps: 100 -> 140 (+40.0%)" in capsys.readouterr().out
    assert JUnitXml.fromfile(str(junit)).failures == 0
    assert run_compare(run, reference, junit=junit, fail_on_solver_change=True) == 1
    assert "FAIL: solver.steps: 100 -> 140 (+40.0%)" in capsys.readouterr().out
    xml = JUnitXml.fromfile(str(junit))
    assert (xml.tests, xml.failures) == (4, 1)  # three variables and the solver statistics


def test_a_malformed_statistics_file_names_itself(tmp_path):
    path = tmp_path / "M_ref_solver.json"
    path.write_text('{"solver.steps": "many"}')
    with pytest.raises(ValueError, match="M_ref_solver.json: solver statistics must be a mapping"):
        read_statistics_file(path)
    assert read_statistics_file(tmp_path / "none.json") is None


class _Variable:
    def __init__(self, name: str, reference: int) -> None:
        self.name, self.valueReference = name, reference


class _Description:
    def __init__(self, version: str, names: list[str]) -> None:
        self.fmiVersion = version
        self.modelVariables = [_Variable(name, 10 + i) for i, name in enumerate(names)]


class _Slave:
    """Answers getInteger (FMI 2.0) or getInt64 (FMI 3.0) from a table of value references."""

    def __init__(self, values: dict[int, int]) -> None:
        self.values = values

    def getInteger(self, refs):  # noqa: N802 - fmpy's name
        return [self.values[r] for r in refs]

    def getInt64(self, refs):  # noqa: N802
        return [self.values[r] for r in refs]


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_statistics_are_read_by_name_when_the_model_description_declares_them(version):
    description = _Description(version, ["x_B", *STATISTICS])
    counts = read_solver_statistics(_Slave({11: 900, 12: 2, 13: 7}), description)
    assert counts == {"solver.steps": 900, "solver.rejectedSteps": 2, "solver.events": 7}
    assert read_solver_statistics(_Slave({}), _Description(version, ["x_B"])) == NOT_EXPOSED


def test_the_plant_fmu_statistics_reach_the_run_record(plant_fmu):
    from toggle_cosim.cosim.master import check_and_simulate
    from toggle_cosim.experiments.scenario import load_scenario
    from toggle_cosim.plant.contract import check_plant

    plant = check_plant(plant_fmu)
    names = {v.name for v in plant.model_description.modelVariables}
    run = load_scenario(ROOT / "scenarios" / "fig4_nominal.yaml")[0]
    record = check_and_simulate(run, plant).record
    if not set(STATISTICS) & names:
        assert record["solver_statistics"] == NOT_EXPOSED
        pytest.skip("this plant FMU does not expose solver.steps/rejectedSteps/events (added by the export branch)")
    counts = record["solver_statistics"]
    assert set(counts) == set(STATISTICS) & names
    assert counts["solver.steps"] > 0 and all(value >= 0 for value in counts.values())


# ----------------------------------------------------------------------------- the workflow


def test_the_github_workflow_is_valid_yaml_and_runs_both_commands():
    document = yaml.safe_load((ROOT / ".github" / "workflows" / "ci.yml").read_text())
    assert document["name"] == "ci"
    steps = document["jobs"]["test"]["steps"]
    commands = [step.get("run", "") for step in steps]
    assert any(command.startswith("scripts/test") for command in commands)  # the README's test command
    assert any("toggle-cosim references" in command and "--junit" in command for command in commands)
    upload = next(step for step in steps if step.get("uses", "").startswith("actions/upload-artifact"))
    assert upload["if"] == "always()" and upload["with"]["path"] == "reports/"
    assert any("toggle-cosim references" in command and "--html" in command for command in commands)
    uploads = [step["with"]["path"] for step in steps if step.get("uses", "").startswith("actions/upload-artifact")]
    assert "reports/references/report.html" in uploads
    assert "scripts/test" in (ROOT / "README.md").read_text()
    assert json.dumps(document)  # plain data all through


HOSTILE = "x|<img src=q onerror=alert(1)>\n&y"


def test_names_from_traces_show_as_written_in_the_markdown_summary(tmp_path: Path) -> None:
    """A trace label and a variable name holding a cell separator, HTML and a line break stay
    inside their cells as text: the failing-variable row keeps its six cells, no raw tag or
    line break reaches the Markdown, and the plot's link cannot end early."""
    from toggle_cosim.analysis.ci_reports import CheckedTrace, markdown_summary
    from toggle_cosim.analysis.compare import Tolerance, compare_traces

    result = Trace(("time", HOSTILE), np.column_stack([T, np.sin(T) + 1.0]))
    reference = Trace(("time", HOSTILE), np.column_stack([T, np.sin(T)]))
    comparison = compare_traces(result, reference, {}, Tolerance(atol=1e-3, rtol=0.0, ttol=0.0))
    plot = tmp_path / "plots" / "a (b)|c.png"
    check = CheckedTrace(HOSTILE, comparison, plots={HOSTILE: plot})
    text = markdown_summary([check], link_base=tmp_path)
    assert "<img" not in text and "&lt;img src=q onerror=alert(1)&gt;" in text
    rows = [line for line in text.splitlines() if line.startswith("| x")]
    assert len(rows) == 2  # the trace's row and the failing variable's: no line break split them
    cells = rows[1].replace("\\|", "").split("|")
    assert len(cells) == 8, rows[1]  # six cells between the outer bars
    assert "(plots/a%20%28b%29%7Cc.png)" in rows[1]
