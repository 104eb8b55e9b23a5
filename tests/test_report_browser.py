"""The HTML reports opened in a real browser: Debian's chromium (scripts/install-system-deps)
driven by Playwright, headless, with a fresh profile and no network use of its own. Each page
must load from file:// with no console error, draw the expected curves (Plotly's `gd.data` of
each figure), and react to the reader: choosing a variable in the dropdown redraws the plot, a
click on a sweep's heat-map cell shows that case's trace. A `references --html` run on a plant
whose slider mass is doubled (the references are the nominal ones) shows the failing x_B with
its funnel band, the samples outside it and the distance outside it. Pages of hostile names
(tests/hostile_names.py) keep their own title, open no image and no dialog, and show the names
as written in Plotly's legend, dropdown, axis, hover text and a clicked cell's title.

Without chromium or Playwright the tests are skipped with the reason, except under CI=true,
where they fail: CI installs both (TOGGLE_COSIM_CHROMIUM names another browser executable).
REPORT_SCREENSHOTS=FOLDER also writes the screenshots there (docs/assets/report.png is the
broken plant's report).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from hostile_names import ENTITY, HOSTILE, IMAGE, REASON, SCRIPT, hostile_runs, hostile_sweep

from toggle_cosim.cli import main
from toggle_cosim.files.traces import Trace, read_csv, select, write_csv

pytestmark = pytest.mark.slow  # pages opened in Chromium

ROOT = Path(__file__).resolve().parent.parent
# Debian's chromium; TOGGLE_COSIM_CHROMIUM names another Chromium-based browser (GitHub's Ubuntu
# runners have no chromium package but Google Chrome: .github/workflows/ci.yml sets it)
CHROMIUM = Path(os.environ.get("TOGGLE_COSIM_CHROMIUM") or "/usr/bin/chromium")
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ALL_DRAWN = "[...document.querySelectorAll('.js-plotly-plot')].every(g => g._fullLayout && g._fullData)"


def _unavailable() -> str | None:
    if not CHROMIUM.is_file():
        return f"{CHROMIUM} is missing (Debian's chromium: scripts/install-system-deps installs it)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed (the [test] extra)"
    return None


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    reason = _unavailable()
    if reason:
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI must open the reports in a browser: {reason}")
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright, tempfile.TemporaryDirectory(prefix="toggle-cosim-chromium-") as profile:
        context = playwright.chromium.launch_persistent_context(
            profile, executable_path=str(CHROMIUM), args=ARGS, headless=True, viewport={"width": 1280, "height": 900}
        )
        try:
            yield context
        finally:
            context.close()


class Page:
    """A report opened in the browser, with every console error, page error and dialog (an
    alert, which the page never opens) collected."""

    def __init__(self, context, path: Path) -> None:  # noqa: ANN001 - Playwright's BrowserContext
        self.page = context.new_page()
        self.page.set_default_timeout(10_000)
        self.errors: list[str] = []
        self.dialogs: list[str] = []
        self.page.on("console", lambda message: self.errors.append(message.text) if message.type == "error" else None)
        self.page.on("pageerror", lambda error: self.errors.append(str(error)))
        self.page.on("dialog", lambda dialog: (self.dialogs.append(dialog.message), dialog.dismiss()))
        self.page.goto(path.resolve().as_uri())
        self.page.wait_for_function(ALL_DRAWN, timeout=20_000)

    def curves(self, figure: str) -> list[dict]:
        """Each curve of the figure element `figure`: its name, meta, whether shown, point count."""
        return self.page.evaluate(
            """id => document.getElementById(id)._fullData.map(d => ({
                 name: d.name, meta: d.meta, visible: d.visible === true, points: d._length ?? (d.x || []).length}))""",
            figure,
        )

    def values(self, figure: str, name: str) -> list[float]:
        """The y values drawn by the shown curve `name` of the figure element `figure`."""
        return self.page.evaluate(
            "([id, name]) => Array.from(document.getElementById(id)._fullData"
            ".find(d => d.visible === true && d.name === name).y)",
            [figure, name],
        )

    def choose(self, figure: str, label: str) -> None:
        """Open the figure's dropdown and click `label`, as a reader does; return once it is drawn."""
        self.page.locator(f"#{figure} .updatemenu-header").click()
        button = self.page.locator(f"#{figure} .updatemenu-dropdown-button", has_text=label).first
        self.redrawn(figure, button.click)

    def redrawn(self, figure: str, action: Callable[[], object]) -> None:
        """Do `action` and wait until Plotly has drawn the figure element `figure` again (its
        plotly_afterplot event), not a fixed time."""
        self.page.evaluate(
            """id => { window.redrawn = false;
                       document.getElementById(id).once('plotly_afterplot', () => { window.redrawn = true; }); }""",
            figure,
        )
        action()
        self.page.wait_for_function("window.redrawn === true")

    def shot(self, path: Path, full_page: bool = False) -> Path:
        self.page.screenshot(path=str(path), full_page=full_page)
        folder = os.environ.get("REPORT_SCREENSHOTS")
        if folder:
            shutil.copyfile(path, Path(folder) / path.name)
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 20_000
        return path


def _run_folder(folder: Path, scenario: str, variant: str, trace: Trace) -> None:
    write_csv(folder / scenario / variant / "trace.csv", trace)
    record = {"scenario": scenario, "variant": variant, "status": "complete", "warnings": []}
    (folder / scenario / variant / "run.json").write_text(json.dumps(record))


def test_the_runs_overlay_draws_every_run_and_switches_variable(browser, tmp_path: Path) -> None:  # noqa: ANN001
    t = np.linspace(0.0, 1.5, 3001)
    for number, variant in enumerate(("a", "b", "c")):
        x = 0.2329 + 0.087 * (1 - np.exp(-(number + 2) * t))
        iq = 3.0 * np.exp(-(number + 1) * 5 * t)
        _run_folder(tmp_path / "out", "three", variant, Trace(("time", "x_B", "iq_ref"), np.column_stack([t, x, iq])))
    result = CliRunner().invoke(main, ["report", str(tmp_path / "out"), "--out", str(tmp_path / "report.html")])
    assert result.exit_code == 0, result.output

    page = Page(browser, tmp_path / "report.html")
    curves = page.curves("runs-overlay")
    assert len(curves) == 6  # 3 runs x 2 variables
    shown = [(c["name"], c["meta"]) for c in curves if c["visible"]]
    assert shown == [("three/a", "x_B"), ("three/b", "x_B"), ("three/c", "x_B")]
    assert all(c["points"] <= 1000 for c in curves)  # thinned for display

    page.choose("runs-overlay", "iq_ref")
    shown = [(c["name"], c["meta"]) for c in page.curves("runs-overlay") if c["visible"]]
    assert shown == [("three/a", "iq_ref"), ("three/b", "iq_ref"), ("three/c", "iq_ref")]
    drawn = page.page.locator("#runs-overlay .scatterlayer .trace").count()
    assert drawn == 3  # three curves on the screen, those of iq_ref
    peak = page.page.evaluate("Math.max(...document.getElementById('runs-overlay')._fullData[1].y)")
    assert peak == pytest.approx(3.0, rel=1e-6)  # the first run's iq_ref, its first sample kept
    assert page.errors == []
    page.shot(tmp_path / "report-runs.png")


def test_a_broken_plants_report_shows_the_funnel_and_the_excursion(
    browser,  # noqa: ANN001
    plant_fmu: Path,
    tmp_path: Path,
) -> None:
    """fig4's friction run with m_B = 8.86 kg instead of 4.43 against the stored nominal reference."""
    scenario = yaml.safe_load((ROOT / "scenarios" / "fig4_nominal.yaml").read_text())
    scenario["plant"]["m_B"] = 8.86  # the deliberate fault: twice the slider's mass
    scenario["variants"] = {"friction": scenario["variants"]["friction"]}
    scenario["fmu"] = str(plant_fmu)
    (tmp_path / "fig4_nominal.yaml").write_text(yaml.safe_dump(scenario))
    references = tmp_path / "references"
    shutil.copytree(ROOT / "scenarios" / "references" / "fig4_nominal", references / "fig4_nominal")
    stored = references / "fig4_nominal" / "friction_ref.csv"  # three of its variables: a short check
    write_csv(stored, select(read_csv(stored), ["time", "x_B", "v_B", "iq_ref"]))
    tolerances = yaml.safe_load((ROOT / "scenarios" / "references" / "tolerances.yaml").read_text())
    (references / "tolerances.yaml").write_text(yaml.safe_dump({"default": tolerances["default"]}))
    out = tmp_path / "out"
    command = ["references", str(tmp_path / "fig4_nominal.yaml"), "--folder", str(references)]
    result = CliRunner().invoke(main, [*command, "--out", str(out), "--html", "--jobs", "1"])
    assert result.exit_code == 1, result.output  # the run left its funnel
    assert f"reports: {out / 'junit.xml'}, {out / 'summary.md'}, {out / 'report.html'}" in result.output

    page = Page(browser, out / "report.html")
    curves = page.curves("comparison-0")
    shown = [c for c in curves if c["visible"]]
    assert {c["meta"] for c in shown} == {"x_B"}  # the first failing variable first
    names = [c["name"] for c in shown]
    assert names[0].startswith("funnel (±") and names[2:4] == ["reference", "run"]
    outside = shown[4]
    assert outside["name"].startswith("outside the funnel (") and outside["points"] > 10
    distance = max(page.values("comparison-0", "distance outside the funnel"))
    # doubling m_B slows the stroke: x_B lags its reference by about 2 mm in the first 0.1 s
    assert 1e-3 < distance < 5e-3
    title = page.page.locator("h3.fail").first.inner_text()
    assert title == "fig4_nominal/friction: FAIL"

    page.page.locator("#comparisons").scroll_into_view_if_needed()
    page.shot(tmp_path / "report.png")  # the docs' picture: x_B out of its funnel

    page.choose("comparison-0", "v_B (FAIL)")  # the failing variables in the trace's order
    assert {c["meta"] for c in page.curves("comparison-0") if c["visible"]} == {"v_B"}
    assert page.page.evaluate("document.getElementById('comparison-0')._fullLayout.yaxis.title.text") == "v_B [m/s]"
    assert page.errors == []


def _sweep_folder(folder: Path) -> list[str]:
    """A sweep's output as `toggle-cosim sweep --keep-traces` leaves it: 3 x 2 cases, one failed."""
    import pandas as pd

    rows, traces = [], []
    t = np.linspace(0.0, 1.5, 1501)
    for index, (force, mass) in enumerate((f, m) for m in (4.43, 8.86) for f in (0.0, 50.0, 100.0)):
        case_id = f"case{index:02d}"
        rows.append(
            {
                "case": index,
                "case_id": case_id,
                "variant": "friction",
                "plant.F_E": force,
                "plant.m_B": mass,
                "status": "failed" if index == 5 else "ok",
                "final_error_m": 1e-4 * (index + 1),
                "settling_time_s": 0.2 + 0.01 * index,
                "peak_iq_ref_A": 3.0 + index,
            }
        )
        frame = pd.DataFrame({"case_id": case_id, "time": t, "x_B": 0.2329 + 0.01 * index * t, "iq_ref": index + 0 * t})
        traces.append(frame)
    folder.mkdir(parents=True)
    pd.DataFrame(rows).to_parquet(folder / "results.parquet")
    (folder / "traces").mkdir()
    pd.concat(traces).to_parquet(folder / "traces" / "batch-000001.parquet")
    manifest = {"sweep": "tiny", "axes": {"plant.F_E": [0.0, 50.0, 100.0], "plant.m_B": [4.43, 8.86]}}
    (folder / "sweep.json").write_text(json.dumps({**manifest, "variants": ["friction"], "sweep_file": None}))
    return [row["case_id"] for row in rows]


def test_a_sweep_cell_click_shows_that_cases_trace(browser, tmp_path: Path) -> None:  # noqa: ANN001
    cases = _sweep_folder(tmp_path / "sweep")
    result = CliRunner().invoke(main, ["report", str(tmp_path / "sweep")])
    assert result.exit_code == 0, result.output
    page = Page(browser, tmp_path / "sweep" / "report.html")
    assert page.curves("sweep-map-0")[0]["visible"]
    first = [(c["meta"], c["name"]) for c in page.curves("sweep-trace-0") if c["visible"]]
    assert first == [(cases[0], "x_B"), (cases[0], "iq_ref")]  # the first case's until a click: no empty axes
    empty = page.page.evaluate("Number.isNaN(Number(document.getElementById('sweep-map-0')._fullData[0].z[1][2]))")
    assert empty  # the failed case (F_E 100 N, m_B 8.86 kg) is an empty cell

    # the cell of F_E = 50 N, m_B = 8.86 kg (x index 1, y index 1), where Plotly drew it
    where = page.page.evaluate(
        """() => { const g = document.getElementById('sweep-map-0'), box = g.getBoundingClientRect();
                   const xa = g._fullLayout.xaxis, ya = g._fullLayout.yaxis;
                   return [box.left + xa._offset + xa.l2p(1), box.top + ya._offset + ya.l2p(1)]; }"""
    )
    page.redrawn("sweep-trace-0", lambda: page.page.mouse.click(*where))
    shown = [(c["meta"], c["name"]) for c in page.curves("sweep-trace-0") if c["visible"]]
    assert shown == [(cases[4], "x_B"), (cases[4], "iq_ref")]
    level = page.values("sweep-trace-0", "iq_ref")[0]
    assert level == 4.0  # case 4's own trace, not another's
    title = page.page.evaluate("document.getElementById('sweep-trace-0').layout.title.text")
    assert title == f"plant.F_E = 50, plant.m_B = 8.86 (case {cases[4]})"

    page.choose("sweep-map-0", "peak |i_q*| [A]")
    assert [c["visible"] for c in page.curves("sweep-map-0")] == [False, False, True]
    assert page.errors == []
    page.shot(tmp_path / "report-sweep-tiny.png", full_page=True)


def test_a_page_of_hostile_names_runs_none_of_them_and_shows_them_as_written(browser, tmp_path: Path) -> None:  # noqa: ANN001
    """The runs and the sweep of tests/hostile_names.py (names holding </script><script>, an
    <img onerror>, an entity, quotes, line separators): each page loads with its own title, no
    image, no dialog, no error; Plotly's legend, axis and a clicked cell's title show the names
    as the files spell them."""
    results, references = hostile_runs(tmp_path)
    runs_page = tmp_path / "runs.html"
    arguments = ["report", str(results), "--references", str(references), "--out", str(runs_page)]
    assert CliRunner().invoke(main, arguments).exit_code == 0
    hostile_sweep(tmp_path / "sweep")
    assert CliRunner().invoke(main, ["report", str(tmp_path / "sweep")]).exit_code == 0

    page = Page(browser, runs_page)
    assert page.page.title() == f"toggle-cosim report: {results}"
    legend = page.page.evaluate("[...document.querySelectorAll('#runs-overlay .legendtext')].map(t => t.textContent)")
    assert legend == [f"{SCRIPT}/{IMAGE}", f"cmp/{HOSTILE[3]}{ENTITY}"]  # the two runs with samples
    page.page.locator("#runs-overlay .updatemenu-header").click()  # the dropdown of variables opens
    buttons = page.page.locator("#runs-overlay .updatemenu-dropdown-button .updatemenu-item-text")
    buttons.nth(len(HOSTILE)).wait_for()
    assert buttons.all_text_contents() == ["x_B", *HOSTILE]  # the variables, as the trace's header names them
    assert page.page.evaluate("document.images.length") == 0 and page.dialogs == [] and page.errors == []

    page = Page(browser, tmp_path / "sweep" / "report.html")
    assert page.page.title() == f"sweep {SCRIPT}"
    ticks = page.page.evaluate("[...document.querySelectorAll('#sweep-map-0 .xtick text')].map(t => t.textContent)")
    assert ticks == sorted(HOSTILE)  # the axis's values, as written
    cell = """([x, y]) => { const g = document.getElementById('sweep-map-0'), box = g.getBoundingClientRect();
                           const xa = g._fullLayout.xaxis, ya = g._fullLayout.yaxis;
                           return [box.left + xa._offset + xa.l2p(x), box.top + ya._offset + ya.l2p(y)]; }"""
    page.page.mouse.move(*page.page.evaluate(cell, [0, 1]))  # IMAGE and 2.0: case 6, the failed one
    hover = page.page.locator("#sweep-map-0 .hoverlayer .hovertext")
    hover.wait_for()
    lines = hover.locator("tspan").all_text_contents()
    assert lines[:2] == [f"{SCRIPT} = {IMAGE}", f"{IMAGE} = 2"] and f"status: failed: {REASON}" in lines
    # a click takes the point Plotly hovers: move onto the cell and wait for its hover label first
    # (as a reader's pointer does), then click; the panel shows the first kept case until then
    page.page.mouse.move(*page.page.evaluate(cell, [0, 0]))  # IMAGE and 1.0, case 1
    page.page.wait_for_function(
        "text => [...document.querySelectorAll('#sweep-map-0 .hoverlayer .hovertext tspan')]"
        ".some(t => t.textContent === text)",
        arg=f"{IMAGE} = 1",
    )
    page.page.mouse.click(*page.page.evaluate(cell, [0, 0]))
    clicked = f"{SCRIPT} = {IMAGE}, {IMAGE} = 1 (case {ENTITY}1{IMAGE})"
    shown = "document.querySelector('#sweep-trace-0 .gtitle').textContent"
    page.page.wait_for_function(f"title => {shown} === title", arg=clicked)
    assert page.page.evaluate(shown) == clicked
    assert page.page.evaluate("document.images.length") == 0 and page.dialogs == [] and page.errors == []
