"""What the figures and the report show besides the curves (issue 35, pictures), on synthetic
data, without a plant or a browser:

* the paper's nine panels each carry an inset of the first 50 ms, where the transient is, and a
  curve equal to one drawn before it says so in the legend;
* a heat-map panel whose cells all hold one value has no colour bar but a note of the value;
  the maps' axes carry the units of the plant variables they sweep;
* the report's run-records table shows numbers to 5 significant digits and paths relative to
  the report's folder; a sweep page's trace panel starts on a case (no empty axes), with units;
* `plot --vars` labels the law's diagnostics e and S with units, as `Result` does.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from toggle_cosim.files.traces import Trace, write_csv

PAPER = ("time", "x_B", "iq_ref", "lambda1", "lambda2", "N23", "Ff23", "N34", "Ff34")


def _paper_trace(scale: float) -> Trace:
    t = np.linspace(0.0, 1.5, 3001)
    columns = [t]
    for k in range(len(PAPER) - 1):
        columns.append((k + 1) * (1.0 - np.exp(-t / 0.01)) * (scale if k else 1.0))  # x_B the same in both
    return Trace(PAPER, np.column_stack(columns))


def test_every_drawn_panel_has_an_inset_of_the_first_50_ms_and_identical_curves_say_so() -> None:
    import matplotlib.pyplot as plt

    from toggle_cosim.analysis.plots import nine_panel_axes

    figure = nine_panel_axes({"friction": _paper_trace(1.0), "no_friction": _paper_trace(0.9)}, "test", 0.32)
    try:
        panels = [ax for ax in figure.axes if ax.get_title().startswith("(")]
        assert len(panels) == 9
        for panel in panels:
            insets = [child for child in panel.child_axes]
            if panel.get_title() in ("(g) joint (2,5)", "(h) joint (5,6)", "(i) joint (1,2)"):
                assert not insets  # not an output of this plant: nothing to enlarge
                continue
            (inset,) = insets
            assert inset.get_xlim() == (0.0, 0.05) and inset.get_title() == "first 50 ms"
            assert all(line.get_xdata().max() <= 0.05 for line in inset.get_lines())
        position = next(ax for ax in panels if ax.get_title() == "(a) position of slider B")
        labels = position.get_legend().get_texts()
        assert [text.get_text() for text in labels][:2] == ["friction", "no_friction (identical to friction)"]
        current = next(ax for ax in panels if ax.get_title() == "(b) control input i_q*")
        assert [text.get_text() for text in current.get_legend().get_texts()] == ["friction", "no_friction"]
    finally:
        plt.close(figure)


@pytest.fixture
def captured_figures(monkeypatch: pytest.MonkeyPatch) -> list:
    """The figures that are saved, as they were when saved (write_heatmaps closes them after)."""
    from matplotlib.figure import Figure

    saved: list = []
    original = Figure.savefig

    def keep(self, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        saved.append([(ax.get_label(), ax.get_title(), ax.get_xlabel(), ax.get_ylabel()) for ax in self.axes])
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return saved


@pytest.mark.slow
def test_a_constant_heat_map_has_no_colour_bar_but_its_value(tmp_path: Path, captured_figures: list) -> None:
    from toggle_cosim.analysis.sweep_heatmaps import write_heatmaps

    rows = [
        {
            "plant.F_E": F_E,
            "plant.m_B": m_B,
            "variant": "friction",
            "status": "ok",
            "final_error_m": 1e-3 * F_E,
            "settling_time_s": 0.8 + m_B,
            "peak_iq_ref_A": 10.0,  # at the limit in every case: one value
            "overshoot_percent": 0.0,
            "fric_share_start": 0.1 * m_B,
            "fric_share_end": 0.2 * m_B,
        }
        for F_E in (0.0, 50.0, 100.0)
        for m_B in (4.43, 8.86)
    ]
    sweep = SimpleNamespace(
        heatmap=("plant.F_E", "plant.m_B"),
        axes=["plant.F_E", "plant.m_B"],
        variants=["friction"],
        output=tmp_path,
        name="s",
    )
    (path,) = write_heatmaps(pd.DataFrame(rows), sweep)
    assert path.is_file()
    (axes,) = captured_figures
    bars = [entry for entry in axes if entry[0] == "<colorbar>"]
    panels = [entry for entry in axes if entry[0] != "<colorbar>"]
    assert len(panels) == 6 and len(bars) == 4  # overshoot and peak current are constant: no bar
    titles = {title for _, title, _, _ in panels}
    assert "peak |i_q*| [A]\nconstant: 10" in titles and "overshoot [%]\nconstant: 0" in titles
    assert {(x, y) for _, _, x, y in panels} == {("plant.F_E [N]", "plant.m_B [kg]")}


def test_the_records_table_shows_short_numbers_and_paths_relative_to_the_report(tmp_path: Path) -> None:
    from toggle_cosim.analysis.html_report import records_section
    from toggle_cosim.analysis.run_files import LoadedRun

    record = {
        "status": "complete",
        "scenario_file": str(tmp_path / "scenarios" / "fig4_nominal.yaml"),
        "fmu": {"path": str(tmp_path / "fmus" / "ToggleLSM.fmu")},
        "wall_time_s": 1.2345678901234567,
        "samples": 3001,
    }
    trace = Trace(("time", "x_B"), np.zeros((2, 2)))
    body = records_section([LoadedRun("fig4_nominal/friction", trace, {}, record)], folder=tmp_path / "out").body
    table = body.split("</table>")[0]
    assert "<td>1.2346</td>" in table and "1.2345678901234567" not in table
    assert "<td>../scenarios/fig4_nominal.yaml</td>" in table and "<td>../fmus/ToggleLSM.fmu</td>" in table
    assert str(tmp_path) not in table
    assert "1.2345678901234567" in body  # the whole run.json, below the table, as it is


def test_a_sweep_page_starts_on_a_case_with_units() -> None:
    from toggle_cosim.analysis.html_report import SweepCase, sweep_section

    table = pd.DataFrame(
        [{"plant.F_E": F_E, "plant.m_B": 4.43, "status": "ok", "case_id": f"c{F_E:g}", "peak": 1.0} for F_E in (0, 50)]
    )
    t = np.linspace(0.0, 1.0, 11)
    traces = {f"c{F_E:g}": Trace(("time", "x_B", "iq_ref"), np.column_stack([t, t, t])) for F_E in (0, 50)}
    sweep = SweepCase("s", table, "plant.F_E", "plant.m_B", (), [("peak", "peak [A]", lambda v: v)], traces)
    body = sweep_section(sweep).body
    assert "plant.F_E [N]" in body and "plant.m_B [kg]" in body
    assert "x_B [m]" in body and "iq_ref [A]" in body
    assert "case c0: click a cell" in body
    shown = body.count('"meta":"c0","mode":"lines","name":"x_B","showlegend":false,"visible":true')
    hidden = body.count('"meta":"c50","mode":"lines","name":"x_B","showlegend":false,"visible":false')
    assert shown == 1 and hidden == 1


def test_plot_vars_gives_the_diagnostics_their_units(tmp_path: Path, plant_fmu: Path) -> None:
    """e in the unit of the regulated x_B, S in that of its rate v_B, as `Result.units` says."""
    from toggle_cosim.analysis.run_files import load_runs

    folder = tmp_path / "out" / "fig4_nominal" / "friction"
    names = ("time", "x_B", "v_B", "iq_ref", "S", "phase", "e")
    data = np.zeros((3, len(names)))
    data[:, 0] = [0.0, 0.0005, 0.001]
    write_csv(folder / "trace.csv", Trace(names, data))
    record = {"scenario": "fig4_nominal", "variant": "friction", "fmu": {"path": str(plant_fmu)}}
    record["resolved"] = {"controller": {"objective": "x_B"}}
    (folder / "run.json").write_text(json.dumps(record))
    (run,) = load_runs([folder])
    assert run.units["e"] == "m" and run.units["S"] == "m/s" and run.units["phase"] == "1"
