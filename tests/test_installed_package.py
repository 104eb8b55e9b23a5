"""The wheel built from this repository carries what the package needs outside its clone, and
the CI workflow template for a repository of one's own (templates/ci/toggle-cosim-references.yml)
has the steps it promises. The wheel installed into new environments, each extra alone, and the
template's steps run as written: tests/test_extras_alone.py."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.slow  # builds and installs the wheel

ROOT = Path(__file__).resolve().parents[1]
TEMPLATE = ROOT / "templates" / "ci" / "toggle-cosim-references.yml"


def test_the_wheel_carries_the_modelica_source_the_scenarios_and_the_licence(project_wheel: Path) -> None:
    wheel = project_wheel
    names = zipfile.ZipFile(wheel).namelist()
    assert "toggle_cosim/shipped/ToggleLSM/package.mo" in names
    assert "toggle_cosim/shipped/ToggleLSM/Plant.mo" in names
    assert "toggle_cosim/shipped/scenarios/fig4_nominal.yaml" in names
    assert "toggle_cosim/shipped/scenarios/measured_load.csv" in names  # a scenario's input table
    assert "toggle_cosim/shipped/scenarios/references/tolerances.yaml" in names
    assert "toggle_cosim/shipped/scenarios/references/fig4_nominal/friction_ref.csv" in names
    assert "toggle_cosim/py.typed" in names and "toggle_cosim/__main__.py" in names
    assert "toggle_cosim/fmi_ls_ref/schemas/fmi3LayeredStandardReferenceManifest.xsd" in names  # FMI-LS-REF
    assert any(name.endswith(".dist-info/licenses/LICENSE") for name in names)
    metadata = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "License-Expression: MIT" in metadata
    assert "Provides-Extra: build" in metadata and "Provides-Extra: all" in metadata
    from toggle_cosim import __version__

    assert f"Version: {__version__}\n" in metadata  # the one version, read from toggle_cosim.__version__


def test_the_ci_template_installs_builds_and_checks_references_with_folder() -> None:
    workflow = yaml.safe_load(TEMPLATE.read_text(encoding="utf-8"))
    runs = [step["run"] for step in workflow["jobs"]["references"]["steps"] if "run" in step]
    assert 'python -m pip install "toggle-cosim[build,ci] @ $TOGGLE_COSIM_SOURCE"' in runs[0]
    assert runs[1].startswith("toggle-cosim build --source")
    assert "toggle-cosim references" in runs[2] and "--folder" in runs[2] and "--junit" in runs[2]
    assert "--html" in runs[2]
    assert "toggle-cosim pack" in runs[3] and "toggle-cosim verify" in runs[3] and "--junit" in runs[3]
    assert "GITHUB_STEP_SUMMARY" in runs[4]
    uploads = [step for step in workflow["jobs"]["references"]["steps"] if "upload-artifact" in step.get("uses", "")]
    assert [step["with"]["path"] for step in uploads] == ["reports/", "reports/references/report.html"]
