"""The example notebook runs on a real Jupyter kernel (nbclient, ipykernel) and ends in its figure.

The notebook's cell tagged "parameters" names the plant FMU and the output folder; as papermill
does, a cell after it sets them for the test (the session's FMU, a temporary folder), so the
notebook builds nothing and writes nothing into the project."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

pytestmark = pytest.mark.slow  # the notebooks on a Jupyter kernel

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK = ROOT / "examples" / "quickstart.ipynb"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _with_parameters(notebook: nbformat.NotebookNode, values: dict[str, str]) -> nbformat.NotebookNode:
    tagged = [i for i, cell in enumerate(notebook.cells) if "parameters" in cell.metadata.get("tags", [])]
    assert len(tagged) == 1, "the notebook needs one cell tagged 'parameters'"
    source = "\n".join(f"{name} = Path({value!r})" for name, value in values.items())
    notebook.cells.insert(tagged[0] + 1, nbformat.v4.new_code_cell(source, metadata={"tags": ["injected-parameters"]}))
    return notebook


def test_the_stored_notebook_is_clean() -> None:
    """Committed without outputs: what a reader runs is what the test runs."""
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(not cell.outputs and cell.execution_count is None for cell in code)


def test_the_quickstart_notebook_runs_and_draws_its_figure(plant_fmu: Path, tmp_path: Path) -> None:
    notebook = _with_parameters(nbformat.read(NOTEBOOK, as_version=4), {"FMU": str(plant_fmu), "OUT": str(tmp_path)})
    client = NotebookClient(
        notebook, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOK.parent)}}
    )
    client.execute()  # raises CellExecutionError (with the cell's traceback) if any cell fails
    errors = [output for cell in notebook.cells for output in cell.get("outputs", []) if output.output_type == "error"]
    assert errors == []
    last = notebook.cells[-1]
    images = [output for output in last.outputs if "image/png" in output.get("data", {})]
    assert len(images) == 1, json.dumps(last.outputs)[:2000]
    png = base64.b64decode(images[0]["data"]["image/png"])
    assert png.startswith(PNG_SIGNATURE) and len(png) > 10_000  # two panels of lines, not an empty canvas
    sweep_table = tmp_path / "sweep_F_E" / "results.parquet"
    assert sweep_table.is_file()  # the sweep wrote where it was told, not into the project


DESIGNING = ROOT / "examples" / "designing.ipynb"


def test_the_designing_notebook_is_clean() -> None:
    notebook = nbformat.read(DESIGNING, as_version=4)
    nbformat.validate(notebook)
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert code and all(not cell.outputs and cell.execution_count is None for cell in code)


def test_the_designing_notebook_trims_linearises_designs_and_checks(plant_fmu: Path, tmp_path: Path) -> None:
    """Trim, linearise, an LQR law from python-control, run on the nonlinear plant through the
    controller protocol: the notebook itself asserts that the law settles with |final error| < 10 µm
    under F_E = 100 N and friction; here, that it ran and drew its three figures."""
    notebook = _with_parameters(nbformat.read(DESIGNING, as_version=4), {"FMU": str(plant_fmu), "OUT": str(tmp_path)})
    client = NotebookClient(
        notebook, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(DESIGNING.parent)}}
    )
    client.execute()
    errors = [output for cell in notebook.cells for output in cell.get("outputs", []) if output.output_type == "error"]
    assert errors == []
    for name in ("design_trim.png", "design_bode.png", "design_closed_loop.png"):
        assert (tmp_path / name).read_bytes().startswith(PNG_SIGNATURE)
    printed = "".join(output.get("text", "") for cell in notebook.cells for output in cell.get("outputs", []))
    assert "friction-free" in printed and "LQR" in printed and "paper's VSC" in printed
