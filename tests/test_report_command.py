"""Plots of anything and the HTML report, without a browser (tests/test_report_browser.py opens
the pages): curves thinned for display keep every extreme; `plot RUN... --vars` overlays runs of
different scenarios and plants with the FMU's units; `--reference` draws the funnel band with
the samples outside it; an unknown variable is one line naming the run and what it has; the
report is one self-contained file whose size does not grow with the traces' length."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
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

    from toggle_cosim.analysis.sweep_heatmaps import PANELS

    for _, title, _, _ in PANELS:  # a map per figure of merit of the PNG maps, in the dropdown
        spelt = to_json_plotly(title)
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
