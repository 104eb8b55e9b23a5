"""Plots of anything and the HTML report, without a browser (tests/test_report_browser.py opens
the pages): curves thinned for display keep every extreme; `plot RUN... --vars` overlays runs of
different scenarios and plants with the FMU's units; `--reference` draws the funnel band with
the samples outside it; an unknown variable is one line naming the run and what it has; the
report is one self-contained file whose size does not grow with the traces' length."""

from __future__ import annotations

import html
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hostile_names import (
    ENTITY,
    HOSTILE,
    IMAGE,
    PAGE_TAGS,
    QUOTES,
    REASON,
    SCRIPT,
    hostile_runs,
    hostile_sweep,
    page_tags,
    write_record,
    write_trace_csv,
)
from hypothesis import given, settings
from hypothesis import strategies as st

from toggle_cosim.analysis.display_points import thin, thin_indices
from toggle_cosim.cli import main
from toggle_cosim.files.traces import Trace, write_csv

ROOT = Path(__file__).resolve().parent.parent

# -- thinning for display -----------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=1, max_size=3000),
    st.integers(min_value=4, max_value=400),
)
def test_thinning_keeps_the_ends_and_every_extreme(values: list[float], limit: int) -> None:
    y = np.array(values)
    kept = thin_indices(y, limit)
    assert kept.size <= max(limit, 0) or y.size <= limit
    assert np.all(np.diff(kept) > 0) and kept[0] == 0 and kept[-1] == y.size - 1
    assert y[kept].max() == y.max() and y[kept].min() == y.min()
    if y.size <= limit:
        assert kept.size == y.size


def test_a_one_sample_spike_in_a_long_trace_survives_thinning() -> None:
    t = np.linspace(0.0, 1.5, 100_001)
    y = np.sin(2 * np.pi * t)
    y[61_234], y[7] = 5.0, -3.0  # single samples: a plain every-n-th decimation loses them
    t_shown, y_shown = thin(t, y, 1000)
    assert t_shown.size <= 1000 and 5.0 in y_shown and -3.0 in y_shown
    assert t_shown[np.argmax(y_shown)] == t[61_234]  # drawn where it happened
    assert y[::100].max() < 1.01  # what every-100th-sample decimation would have drawn


# -- runs on disk --------------------------------------------------------------------------------


def _write_run(folder: Path, scenario: str, variant: str, trace: Trace, fmu: Path | None = None) -> Path:
    run = folder / scenario / variant
    write_csv(run / "trace.csv", trace)
    record = {
        "scenario": scenario,
        "variant": variant,
        "fmu": {"path": str(fmu) if fmu else "/nowhere/Plant.fmu"},
        "status": "complete",
        "warnings": ["peak |i_q*| 12.3 A above the rated 10 A"],
        "loop": {"kind": "python", "reason": "the scenario's controller.python runs in Python at every sample"},
        "resolved": {"controller": {"law": "paper"}},
    }
    (run / "run.json").write_text(json.dumps(record))
    return folder / scenario


def _trace(names: tuple[str, ...], samples: int = 301, scale: float = 1.0) -> Trace:
    t = np.linspace(0.0, 1.5, samples)
    columns = [t] + [scale * (k + 1) * np.tanh(5 * t) for k in range(len(names) - 1)]
    return Trace(names, np.column_stack(columns))


PAPER_COLUMNS = ("time", "x_B", "v_B", "lambda1", "iq_ref")
FOREIGN_COLUMNS = ("time", "x_B", "v_B", "iq_ref", "F_E")


@pytest.fixture
def two_plants(tmp_path: Path, plant_fmu: Path) -> tuple[Path, Path]:
    """A run of our plant (units from its FMU) and one of a foreign plant without lambda1
    whose FMU is gone (no units)."""
    ours = _write_run(tmp_path / "out", "fig4_nominal", "friction", _trace(PAPER_COLUMNS), plant_fmu)
    foreign = _write_run(tmp_path / "out", "guided_mass", "friction", _trace(FOREIGN_COLUMNS, scale=0.5))
    return ours, foreign


def test_plot_vars_overlays_runs_of_two_plants_with_the_fmus_units(two_plants: tuple[Path, Path]) -> None:
    from toggle_cosim.analysis.run_files import load_runs
    from toggle_cosim.analysis.variable_figure import variables_figure

    ours, foreign = two_plants
    out = ours.parent / "overlay.png"
    result = CliRunner().invoke(main, ["plot", str(ours), str(foreign), "--vars", "x_B,iq_ref", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 10_000 and f"wrote {out}" in result.output

    runs = load_runs([ours, foreign])
    assert [run.label for run in runs] == ["fig4_nominal/friction", "guided_mass/friction"]
    assert runs[0].units["x_B"] == "m" and runs[0].units["iq_ref"] == "A"  # from the plant's modelDescription
    assert runs[1].units == {"time": "s"}  # its FMU is gone: no unit is made up
    figure = variables_figure(runs, ["x_B", "iq_ref"])
    axes = [ax for ax in figure.axes if ax.get_visible()]
    assert [ax.get_ylabel() for ax in axes] == ["x_B [m]", "iq_ref [A]"]
    for ax, name in zip(axes, ["x_B", "iq_ref"], strict=True):
        lines = {line.get_label(): line for line in ax.get_lines()}
        assert set(lines) == {"fig4_nominal/friction", "guided_mass/friction"}
        drawn = lines["guided_mass/friction"].get_ydata()
        assert np.array_equal(drawn, runs[1].trace.column(name))  # 301 samples: drawn as they are


@pytest.fixture
def three_controllers(tmp_path: Path) -> list[Path]:
    """The same scenario and variant run by three controllers, each into its own output folder."""
    trace = _trace(PAPER_COLUMNS)
    return [_write_run(tmp_path / name, "fig5_external_force", "friction", trace) for name in ("pid", "vsc", "lqr")]


def test_runs_of_the_same_scenario_and_variant_are_named_by_their_folders(three_controllers: list[Path]) -> None:
    """Where scenario/variant repeats, the legend shows the run's folder (the leading parts the
    runs share left out), not "(2)", "(3)"; the same folder given twice is told apart by place."""
    from toggle_cosim.analysis.run_files import load_runs

    runs = load_runs(three_controllers)
    assert [run.label for run in runs] == [
        "pid/fig5_external_force/friction",
        "vsc/fig5_external_force/friction",
        "lqr/fig5_external_force/friction",
    ]
    twice = load_runs([three_controllers[0], three_controllers[0]])
    assert [run.label for run in twice] == ["fig5_external_force/friction", "fig5_external_force/friction (2)"]


def test_plot_label_names_each_result_in_the_legend(three_controllers: list[Path]) -> None:
    """`plot --label` (one per RESULTS) and `tc.plot(..., labels=)` name the curves; a count
    other than one per result is one line, exit 2, and no figure."""
    import toggle_cosim as tc

    figure = tc.plot(three_controllers, vars="x_B", labels=["PID", "VSC", "LQR"])
    (ax,) = [ax for ax in figure.axes if ax.get_visible()]
    assert [line.get_label() for line in ax.get_lines()] == ["PID", "VSC", "LQR"]

    out = three_controllers[0].parent / "labelled.png"
    arguments = ["plot", *map(str, three_controllers), "--vars", "x_B", "--out", str(out)]
    labelled = [*arguments, "--label", "PID", "--label", "VSC", "--label", "LQR"]
    result = CliRunner().invoke(main, labelled)
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 10_000
    out.unlink()
    result = CliRunner().invoke(main, [*arguments, "--label", "PID", "--label", "VSC"])
    assert result.exit_code == 2 and not out.exists()
    (line,) = result.stderr.splitlines()
    assert "--label given 2 time(s) for 3 RESULTS" in line
    with pytest.raises(ValueError, match="2 label"):
        tc.plot(three_controllers, vars="x_B", labels=["PID", "VSC"])


def test_an_unknown_variable_names_the_run_and_what_it_has(two_plants: tuple[Path, Path]) -> None:
    ours, foreign = two_plants
    out = ours.parent / "overlay.png"
    result = CliRunner().invoke(main, ["plot", str(ours), str(foreign), "--vars", "x_B,lambda1", "--out", str(out)])
    assert result.exit_code == 2
    (line,) = result.stderr.splitlines()
    assert line == (
        f"error: {foreign / 'friction' / 'trace.csv'}: run 'guided_mass/friction' has no variable 'lambda1'; "
        "it has x_B, v_B, iq_ref, F_E"
    )
    assert not out.exists()
    bad = CliRunner().invoke(main, ["plot", str(ours), "--vars", "x_B,,v_B"])
    assert bad.exit_code == 2 and "an empty variable name" in bad.stderr


def test_without_vars_a_foreign_plant_gets_its_own_variables_not_the_papers_panels(
    two_plants: tuple[Path, Path],
) -> None:
    from toggle_cosim.analysis.run_files import load_runs
    from toggle_cosim.analysis.variable_figure import default_variables
    from toggle_cosim.cli.report_command import is_paper_plant

    ours, foreign = two_plants
    assert not is_paper_plant(foreign) and default_variables(load_runs([foreign])) == ["x_B", "v_B", "iq_ref", "F_E"]
    assert default_variables(load_runs([ours, foreign])) == ["x_B", "v_B", "iq_ref"]  # what both have
    result = CliRunner().invoke(main, ["plot", str(foreign)])
    assert result.exit_code == 0, result.output
    assert (foreign / "figure.png").stat().st_size > 10_000


def test_a_reference_is_drawn_with_its_funnel_and_the_samples_outside_it(tmp_path: Path) -> None:
    """x_B leaves a ramp's funnel by 5 mm for t in [0.5, 0.6] s: exactly those samples are marked."""
    from toggle_cosim.api.plotting import plot

    t = np.linspace(0.0, 1.5, 1501)
    reference = tmp_path / "ramp_ref.csv"
    write_csv(reference, Trace(("time", "x_B"), np.column_stack([t, 0.1 * t])))
    off = (t >= 0.5) & (t <= 0.6)
    run = _write_run(
        tmp_path / "out", "ramp", "off", Trace(("time", "x_B"), np.column_stack([t, 0.1 * t + 5e-3 * off]))
    )
    figure = plot(run, "x_B", reference)
    (ax,) = [ax for ax in figure.axes if ax.get_visible()]
    lines = {line.get_label(): line for line in ax.get_lines()}
    marked = lines["outside the funnel"].get_xdata()
    assert np.array_equal(marked, t[off])  # half-height 2e-3 x 0.15 m = 0.3 mm << 5 mm
    assert any(c.get_label().startswith("funnel (±0.0003,") for c in ax.collections)  # the band itself
    out = tmp_path / "band.png"
    result = CliRunner().invoke(main, ["plot", str(run), "--reference", str(reference), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.stat().st_size > 10_000


# -- the HTML report ------------------------------------------------------------------------------


def test_the_report_is_self_contained_and_its_size_does_not_grow_with_the_traces(tmp_path: Path) -> None:
    from plotly.offline import get_plotlyjs

    from toggle_cosim.analysis.html_report import OVERLAY_POINTS

    sizes = []
    for samples in (3_001, 30_001):
        folder = tmp_path / f"n{samples}"
        for variant in ("a", "b"):
            _write_run(folder, "long", variant, _trace(FOREIGN_COLUMNS, samples))
        out = folder / "report.html"
        result = CliRunner().invoke(main, ["report", str(folder), "--out", str(out)])
        assert result.exit_code == 0, result.output
        text = out.read_text()
        assert "<script src" not in text and get_plotlyjs()[:2000] in text  # plotly.js inside, no CDN
        sizes.append(len(text) - len(get_plotlyjs()))
    # 2 runs x 4 variables x 2 arrays x OVERLAY_POINTS float32 in base64, and the page around them
    assert sizes[1] < 2 * 4 * 2 * OVERLAY_POINTS * 4 * 4 / 3 + 60_000
    assert abs(sizes[1] - sizes[0]) < 0.05 * sizes[0]  # ten times the samples, the same page


def test_the_report_holds_the_run_records(tmp_path: Path) -> None:
    folder = _write_run(tmp_path / "out", "fig4_nominal", "friction", _trace(FOREIGN_COLUMNS))
    result = CliRunner().invoke(main, ["report", str(folder)])
    assert result.exit_code == 0, result.output
    text = (folder / "report.html").read_text()
    assert "python: the scenario&#x27;s controller.python runs in Python at every sample" in text
    assert "peak |i_q*| 12.3 A above the rated 10 A" in text and "law paper" in text


def test_the_report_refuses_a_link_and_names_the_missing_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = _write_run(tmp_path / "out", "s", "v", _trace(FOREIGN_COLUMNS))
    target = tmp_path / "elsewhere.html"
    target.write_text("keep me")
    link = tmp_path / "report.html"
    link.symlink_to(target)
    result = CliRunner().invoke(main, ["report", str(folder), "--out", str(link)])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1 and "a symbolic link" in result.stderr
    assert target.read_text() == "keep me" and link.is_symlink()
    missing = CliRunner().invoke(main, ["report", str(folder), "--vars", "x_B,nope"])
    assert missing.exit_code == 2 and "run 's/v' has no variable 'nope'" in missing.stderr
    assert not (folder / "report.html").exists()

    monkeypatch.setitem(sys.modules, "plotly", None)  # as if the [report] extra were not installed
    result = CliRunner().invoke(main, ["report", str(folder)])
    assert result.exit_code == 2
    assert result.stderr == (
        "error: toggle-cosim report needs the Python package 'plotly' of the extra [report]: "
        "pip install 'toggle-cosim[report]' (or 'toggle-cosim[all]')\n"
    )


@pytest.mark.slow
def test_sweep_html_writes_the_sweeps_page_with_its_kept_traces(plant_fmu: Path, tmp_path: Path) -> None:
    """A real 2 x 2 sweep with --keep-traces --html: the page has one heat map per figure of
    merit over F_E and m_B, and each case's x_B trace, ready for a click (the browser test
    clicks one)."""
    import re

    import yaml

    sweep = tmp_path / "sweep.yaml"
    document = {
        "base": str(ROOT / "scenarios" / "fig4_nominal.yaml"),
        "variant": "friction",
        "axes": {"plant.F_E": {"values": [0.0, 40.0]}, "plant.m_B": {"values": [4.43, 6.0]}},
        "output": str(tmp_path / "out"),
    }
    sweep.write_text(yaml.safe_dump(document))
    arguments = ["sweep", str(sweep), "--fmu", str(plant_fmu), "--workers", "1", "--quiet", "--keep-traces", "--html"]
    result = CliRunner().invoke(main, arguments)
    assert result.exit_code == 0, result.output
    page = tmp_path / "out" / "report.html"
    assert f"wrote {page}" in result.output
    text = page.read_text()
    cases = set(re.findall(r'"meta":"([0-9a-f]{16})"', text))
    assert len(cases) == 4  # every case's trace is in the page, by its case id
    from plotly.io.json import to_json_plotly  # as the page spells strings ("/" escaped)

    from toggle_cosim.analysis.page_text import page_text
    from toggle_cosim.analysis.sweep_heatmaps import PANELS

    for _, title, _, _ in PANELS:  # a map per figure of merit of the PNG maps, in the dropdown
        spelt = to_json_plotly(page_text(title))
        assert text.count(f'"name":{spelt}') == 1 and f'"label":{spelt}' in text
    assert '"xaxis":{"title":{"text":"plant.F_E[N]"}' in text.replace(" ", "")  # with its unit


def test_html_options_refuse_bad_input_before_any_run(tmp_path: Path) -> None:
    """`references --update --html` (an update checks nothing) and `sweep --html` whose page
    would land on a link: one line each, exit 2, before any case runs."""
    import yaml

    updated = CliRunner().invoke(
        main,
        ["references", str(ROOT / "scenarios" / "fig4_nominal.yaml"), "--update", "--html", "--folder", str(tmp_path)],
    )
    assert updated.exit_code == 2 and updated.stderr.startswith("error: --html reports a check against the references")
    assert list(tmp_path.iterdir()) == []

    target = tmp_path / "elsewhere.html"
    (tmp_path / "sweep").mkdir()
    (tmp_path / "sweep" / "report.html").symlink_to(target)
    sweep = tmp_path / "sweep.yaml"
    axes = {"plant.F_E": {"values": [0.0, 40.0]}}
    sweep.write_text(yaml.safe_dump({"base": str(ROOT / "scenarios" / "fig4_nominal.yaml"), "axes": axes,
                                     "output": str(tmp_path / "sweep")}))  # fmt: skip
    result = CliRunner().invoke(main, ["sweep", str(sweep), "--html", "--quiet"])
    assert result.exit_code == 2, result.output
    assert result.stderr == (
        f"error: {tmp_path / 'sweep' / 'report.html'}: is a symbolic link, not a regular file (a link is not "
        "followed); give another file name for the HTML report (--html)\n"
    )
    assert sorted(p.name for p in (tmp_path / "sweep").iterdir()) == ["report.html"] and not target.exists()


# -- names from the user's files in a page -------------------------------------------------------


@pytest.mark.parametrize("name", HOSTILE)
def test_page_text_and_script_json_hold_no_markup_and_read_back_as_written(name: str) -> None:
    import html

    from toggle_cosim.analysis.page_text import page_text, script_json

    shown = page_text(name)
    assert not set("<>\"'") & set(shown) and html.unescape(shown) == name
    assert "&quot;" not in shown  # Plotly decodes numeric references, not &quot;: it would show as typed
    assert "%{" not in shown  # nor is any of it read as a Plotly template
    literal = script_json(name)
    assert not set("<>&\u2028\u2029") & set(literal) and json.loads(literal) == name


def _shown_as_text(page: Path, figures: int) -> str:
    """The page's text outside its scripts, after checking that the page holds only its own
    elements (no <img>, no extra <script>) and its scripts no raw line separator."""
    parsed = page_tags(page)
    assert set(parsed.tags) <= PAGE_TAGS, set(parsed.tags) - PAGE_TAGS
    assert len(parsed.scripts) == 1 + figures  # plotly.js, then one per figure: no script was injected
    assert not any(set("\u2028\u2029") & set(script) for script in parsed.scripts[1:])
    assert "<img" not in page.read_text().lower()
    return "".join(parsed.text)


def test_hostile_names_in_a_runs_report_are_shown_as_text_never_as_markup(tmp_path: Path) -> None:
    """Folder, scenario, variant and variable names, warnings and a failure's reason holding
    </script>, an <img onerror>, an entity, quotes and line separators: the page shows each as
    written (in the failures, the verdicts, the records) and runs none of them."""
    results, references = hostile_runs(tmp_path)
    page = tmp_path / "report.html"
    arguments = ["report", str(results), "--references", str(references), "--out", str(page)]
    result = CliRunner().invoke(main, arguments)
    assert result.exit_code == 0, result.output
    text = _shown_as_text(page, figures=2)  # the comparison and the runs overlaid
    assert f"toggle-cosim report: {results}" in text  # the title, with the folder's name
    assert f"{SCRIPT}/{IMAGE}" in text and f"cmp/{QUOTES}{ENTITY}: FAIL" in text  # records, comparison
    assert all(name in text for name in HOSTILE)  # the variables in the verdict table
    assert text.count(REASON) >= 2  # the failures' table (and the records') give the reason


def test_a_run_json_naming_a_path_is_compared_with_no_file_outside_the_references(tmp_path: Path) -> None:
    """run.json's scenario and variant name a reference inside --references only: a scenario
    `..` (or one holding a /) would reach a CSV beside the folder, so that run is not compared."""
    results, references = hostile_runs(tmp_path)
    write_trace_csv(tmp_path / "outside_ref.csv", ["time", "x_B", *HOSTILE], 40)  # references/../outside_ref.csv
    write_trace_csv(results / "e" / "run" / "trace.csv", ["time", "x_B", *HOSTILE], 50)
    write_record(results / "e" / "run", "..", "outside", "complete")
    page = tmp_path / "report.html"
    result = CliRunner().invoke(main, ["report", str(results), "--references", str(references), "--out", str(page)])
    assert result.exit_code == 0, result.output
    text = _shown_as_text(page, figures=2)  # the one comparison inside the folder, and the overlay
    assert f"cmp/{QUOTES}{ENTITY}: FAIL" in text
    assert "../outside: FAIL" not in text and "../outside: PASS" not in text


def test_hostile_names_in_a_sweeps_report_are_shown_as_text_never_as_markup(tmp_path: Path) -> None:
    """A sweep named `</script>...` over an axis of that name with hostile values and case ids:
    the page runs none of it; the click script gets the axes' names as safe literals."""
    from toggle_cosim.analysis.page_text import page_text, script_json

    hostile_sweep(tmp_path / "sweep")
    result = CliRunner().invoke(main, ["report", str(tmp_path / "sweep")])
    assert result.exit_code == 0, result.output
    page = tmp_path / "sweep" / "report.html"
    text = _shown_as_text(page, figures=2)  # the heat map and its cases' traces
    assert f"sweep {SCRIPT}" in text
    click = page_tags(page).scripts[1]
    assert f"var cell = {script_json(page_text(SCRIPT))} + ' = '" in click


# -- runs that did not complete ------------------------------------------------------------------


def _failed_run(folder: Path, variant: str, samples: int | None) -> None:
    """A failed run: a trace of `samples` samples (0: a header only; None: no trace.csv)."""
    run = folder / "s" / variant
    run.mkdir(parents=True)
    if samples is not None:
        trace = _trace(FOREIGN_COLUMNS, samples) if samples else Trace(FOREIGN_COLUMNS, np.empty((0, 5)))
        write_csv(run / "trace.csv", trace)
    reason = f"plant: fmi2DoStep failed at t = 0 ({variant})"
    record = {"scenario": "s", "variant": variant, "status": "failed", "reason": reason, "samples": samples or 0}
    (run / "run.json").write_text(json.dumps(record))


def test_a_run_that_failed_before_its_first_sample_is_in_the_report_with_its_reason(tmp_path: Path) -> None:
    """A folder with a complete run and three failed ones (no trace file, a header only, a
    partial trace): the page lists each failed run with its reason and samples first, draws the
    complete and the partial run, and names the two it cannot draw."""
    folder = tmp_path / "out"
    _write_run(folder, "s", "complete", _trace(FOREIGN_COLUMNS))
    _failed_run(folder, "empty", 0)
    _failed_run(folder, "missing", None)
    _failed_run(folder, "partial", 120)
    result = CliRunner().invoke(main, ["report", str(folder), "--vars", "x_B,iq_ref"])
    assert result.exit_code == 0, result.output
    page = folder / "report.html"
    text = page.read_text()
    failures = text[text.index('<section id="failures">') : text.index('<section id="runs">')]
    for variant, samples in (("empty", 0), ("missing", 0), ("partial", 120)):
        assert (
            f'<tr class="fail"><td>s/{variant}</td><td>failed</td>'
            f"<td>plant: fmi2DoStep failed at t = 0 ({variant})</td><td>{samples}</td></tr>"
        ) in failures
    assert "s/complete" not in failures
    assert "<p>Not drawn (fewer than two samples): s/empty, s/missing.</p>" in text
    assert text.count('"name":"s\\u002fpartial"') == 2 and text.count('"name":"s\\u002fempty"') == 0  # x_B, iq_ref

    alone = CliRunner().invoke(main, ["report", str(folder / "s" / "empty")])
    assert alone.exit_code == 0, alone.output  # nothing to draw: the failure and its record
    text = (folder / "s" / "empty" / "report.html").read_text()
    assert 'id="failures"' in text and 'id="records"' in text and 'id="runs"' not in text


def test_a_complete_run_without_samples_is_still_refused(tmp_path: Path) -> None:
    """Only a run whose record says it failed may lack samples; a complete one with an empty
    trace is a broken folder: one line naming the file, exit 2, no page."""
    folder = tmp_path / "out"
    _write_run(folder, "s", "v", Trace(FOREIGN_COLUMNS, np.empty((0, 5))))
    result = CliRunner().invoke(main, ["report", str(folder)])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1
    assert "trace.csv: unreadable trace" in result.stderr and "(empty trace)" in result.stderr
    assert not (folder / "report.html").exists()


def test_a_run_whose_controller_cannot_be_built_is_in_both_pages_with_its_reason(
    plant_fmu: Path, tmp_path: Path
) -> None:
    """`run` of a controller whose factory raises writes a failed run with a header-only trace;
    `report` of that folder and `references --html` of that scenario list it with the reason."""
    import yaml

    (tmp_path / "broken.py").write_text("def make(context):\n    raise ValueError('no gains <b>given</b>')\n")
    scenario = {
        "name": "broken",
        "t_end": 0.02,
        "T_s": 0.0005,
        "stroke": {"x_start": 0.2329, "x_target": 0.3199},
        "plant": {"F_E": 0.0, "m_B": 4.43, "mu": 0.2},
        "controller": {"python": "broken:make"},
        "variants": {"v": {}},
    }
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(scenario))
    out = tmp_path / "out"
    ran = CliRunner().invoke(main, ["run", str(path), "--fmu", str(plant_fmu), "--out", str(out), "-q"])
    assert ran.exit_code == 1, ran.output
    assert (out / "broken" / "v" / "trace.csv").read_text().count("\n") == 1  # the header: no sample
    reason = json.loads((out / "broken" / "v" / "run.json").read_text())["reason"]
    assert "no gains <b>given</b>" in reason
    row = f'<tr class="fail"><td>broken/v</td><td>failed</td><td>{html.escape(reason)}</td><td>0</td></tr>'

    result = CliRunner().invoke(main, ["report", str(out)])
    assert result.exit_code == 0, result.output
    assert row.replace("&quot;", "&#34;") in (out / "report.html").read_text()

    (tmp_path / "references").mkdir()
    checked = tmp_path / "checked"
    arguments = ["references", str(path), "--fmu", str(plant_fmu), "--folder", str(tmp_path / "references")]
    result = CliRunner().invoke(main, [*arguments, "--out", str(checked), "--html"])
    assert result.exit_code == 1 and "broken/v: FAILED (" in result.output
    assert row.replace("&quot;", "&#34;") in (checked / "report.html").read_text()
