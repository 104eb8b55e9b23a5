"""A sweep and a tuning over a dozen axes with long names: every file name stays within the file
system's limit of 255 bytes (a heat map's name built from the other axes is cut and ends with a
hash; its figure and PNG say the whole), and sweep.json and tune.json are written. Two cases of
0.05 s each."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
import yaml
from PIL import Image
from test_tune import BASE

import toggle_cosim as tc
from toggle_cosim.experiments.sweep import run_sweep

pytestmark = pytest.mark.slow  # a sweep and a tuning over twelve axes

# ten plant parameters, each at the plant's own value (the dynamics are the base scenario's)
LONG_AXES = {
    "plant.parameters.mechanism.stickCompliance": 1e-12,
    "plant.parameters.mechanism.stickDecay": 1000.0,
    "plant.parameters.mechanism.baumgarte": 20.0,
    "plant.parameters.mechanism.phi": 2.897246558310587,
    "plant.parameters.mechanism.m_C": 1.5,
    "plant.parameters.mechanism.g": 9.81,
    "plant.parameters.motor.gamma0": 1.5707963267948966,
    "plant.parameters.motor.mu0": 1.25663706212e-06,
    "plant.parameters.motor.K_w1": 0.955,
    "plant.parameters.motor.alpha": 0.67,
}


def _write_sweep(folder: Path, plant_fmu: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    base = dict(BASE, fmu=str(plant_fmu), t_end=0.05)
    (folder / "base.yaml").write_text(yaml.safe_dump(base, sort_keys=False), encoding="utf-8")
    axes = {key: {"values": [value]} for key, value in LONG_AXES.items()}
    axes["plant.F_E"] = {"values": [0, 50]}
    axes["plant.m_B"] = {"values": [4.43]}
    sweep = {
        "base": "base.yaml",
        "variant": "friction",
        "axes": axes,
        "heatmap": {"x": "plant.F_E", "y": "plant.m_B"},
        "output": "out",
    }
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(sweep, sort_keys=False), encoding="utf-8")
    return path


def _names_fit(folder: Path) -> None:
    for _, folders, files in os.walk(folder):
        for name in [*folders, *files]:
            assert len(name.encode()) <= 255, name


def test_a_sweep_over_twelve_long_axes_writes_its_heat_map_and_sweep_json(tmp_path: Path, plant_fmu: Path) -> None:
    path = _write_sweep(tmp_path, plant_fmu)
    assert run_sweep(path, None, 1, plant_fmu, progress=False) == 0
    out = tmp_path / "out"
    manifest = json.loads((out / "sweep.json").read_text(encoding="utf-8"))
    assert len(manifest["heatmaps"]) == 1
    figure = out / manifest["heatmaps"][0]
    assert figure.is_file() and figure.name.startswith("heatmap_plant.parameters.mechanism.stickCompliance=1e-12_")
    _names_fit(out)
    description = Image.open(figure).text["Description"]  # the whole combination of the other axes
    assert all(f"{key} = " in description for key in LONG_AXES), description


def test_a_tuning_over_twelve_long_axes_writes_tune_json(tmp_path: Path, plant_fmu: Path) -> None:
    _write_sweep(tmp_path, plant_fmu)
    tuning = {
        "name": "long",
        "sweep": "sweep.yaml",
        "parameters": {"controller.C_I": {"low": 8, "high": 40}},
        "objective": {"metric": "final_error", "over": "worst"},
        "optimiser": {"sampler": "random", "trials": 1, "batch": 1, "seed": 1},
        "output": "tuned",
    }
    path = tmp_path / "tune.yaml"
    path.write_text(yaml.safe_dump(tuning, sort_keys=False), encoding="utf-8")
    result = tc.tune(path, workers=1, progress=False)
    out = tmp_path / "tuned"
    manifest = json.loads((out / "tune.json").read_text(encoding="utf-8"))
    assert manifest["tuning"] == "long" and manifest["trials"] == 1
    assert result.best is not None and (out / "maps.png").is_file()
    assert len(list((out / "map_start" / "heatmaps").glob("heatmap_*.png"))) == 1
    _names_fit(out)
